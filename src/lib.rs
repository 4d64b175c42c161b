//! texsyn: reproducible texture synthesis driven by TOML job files.

pub mod batch;
pub mod digest;
mod error;
pub mod image;
pub mod metrics;
pub mod report;
pub mod synth;

pub use image::RgbImage;
pub use error::{Error, Result};
