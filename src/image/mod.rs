//! Images: the 8-bit RGB raster every method works on, decoding and encoding with limits, pixel
//! digests, and the description of where a method put its seams.
//!
//! The lowest layer after `digest`: it knows nothing of jobs, methods or metrics.

pub mod io;
pub mod raster;
pub mod seam_grid;

pub use raster::RgbImage;
