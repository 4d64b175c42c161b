//! Synthesis: the method interface, parameters, seeded random streams, lattice extraction, the
//! shared image primitives and the methods themselves.
//!
//! Everything here is a pure function of pixels, parameters and a seed; nothing reads files or
//! the clock (except phase timings, which are recorded apart from results). Sits on `image` and
//! `metrics` (autocorrelation), below the batch pipeline.

pub mod advice;
pub mod atlas;
pub mod constraints;
pub mod error;
pub mod lattice;
pub mod method;
pub mod methods;
pub mod params;
pub mod placement;
#[doc(hidden)]
pub mod primitives;
pub mod rng;
pub mod wrap;
