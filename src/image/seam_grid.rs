//! Where a grid-based method may have left seams, so metrics can look there.
//!
//! Block methods (quilting, patch sampling, non-overlapping splicing) know where their blocks
//! meet; the seam-visibility metric compares colour jumps at those places with jumps elsewhere.

use serde::{Deserialize, Serialize};

/// A band of pixel boundaries: boundary `k` is the one between pixel `k − 1` and pixel `k`
/// (columns for vertical seams, rows for horizontal ones); the band covers `start..start + len`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SeamBand {
    pub start: u32,
    pub len: u32,
}

/// The seam bands of an output image, in output pixel coordinates.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SeamGrid {
    /// Bands of column boundaries (vertical seam lines), sorted by `start`.
    pub columns: Vec<SeamBand>,
    /// Bands of row boundaries (horizontal seam lines), sorted by `start`.
    pub rows: Vec<SeamBand>,
}
