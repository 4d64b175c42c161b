//! texsyn: reproducible texture synthesis driven by TOML job files.
//!
//! The crate is a library; the `texsyn` binary is a thin command-line layer over it. A newcomer's
//! map: `job` reads and validates job files, `runner` schedules them and keeps the output
//! directory consistent, `manifest` records provenance, `imageio` decodes and encodes images,
//! `methods` holds one file per synthesis method, `primitives` the image building blocks they
//! share, `metrics` the objective quality measures, `rng` the seeded random streams and `digest`
//! the hashing and canonical JSON.

pub mod digest;
pub mod golden;
pub mod imageio;
pub mod job;
pub mod lattice;
pub mod manifest;
pub mod methods;
pub mod metrics;
pub mod outdir;
pub mod params;
pub mod primitives;
pub mod progress;
pub mod raster;
pub mod report;
pub mod rng;
pub mod runner;
pub mod seamgrid;
pub mod tileset;
pub mod verify;

pub use raster::RgbImage;
