//! texsyn: reproducible texture synthesis driven by TOML job files.
//!
//! The crate is a library; the `texsyn` binary is a thin command-line layer over it. A newcomer's
//! map: `job` reads and validates job files, `runner` schedules them and keeps the output
//! directory consistent, `manifest` records provenance, `imageio` decodes and encodes images,
//! `methods` holds one file per synthesis method, `primitives` the image building blocks they
//! share, `rng` the seeded random streams and `digest` the hashing and canonical JSON.

pub mod digest;
pub mod metrics;
pub mod raster;
pub mod rng;
pub mod seamgrid;

pub use raster::RgbImage;
