//! The synthesis methods, one file each, behind one interface.
//!
//! A method is a pure function of (sample pixels, resolved parameters, seed, output size): it
//! never sees file names, formats or the clock. That is what lets the runner cache, verify and
//! re-run results from the manifest alone. Adding a method means adding a file here and one line
//! in [`registry`]; the job model, scheduler and manifest do not change.

pub mod double_seam;
pub mod near_regular;
pub mod patch_sampling;
pub mod quilting;
pub mod tiles;

use crate::image::RgbImage;
use crate::synth::method::Method;
use crate::synth::params::{MethodConfig, ParamError, Params};
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::overlap_search::{Candidates, OverlapSearch};

crate::choice! {
    /// How an exact exhaustive block search scores every sample position (quilting's `search`,
    /// patch sampling's `engine`). Both give the same candidates, hence the same pixels.
    pub enum Engine {
        /// FFT correlation, then an exact integer re-check of the near-best positions.
        Fft = "fft",
        /// Brute-force SSD sums at every position.
        Direct = "direct",
    }
}

impl Engine {
    /// The tolerance set of `search` for the block at `origin` of `canvas`, computed this way.
    pub(crate) fn candidates(
        self,
        search: &mut OverlapSearch,
        canvas: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        tolerance: f64,
    ) -> Candidates {
        match self {
            Engine::Fft => search.candidates(canvas, origin, regions, tolerance),
            Engine::Direct => search.candidates_direct(canvas, origin, regions, tolerance),
        }
    }
}

/// The square-block methods' default overlap, `round(block / 6)` and at least 1: the derived
/// default of their `overlap` parameter, and what a config's `overlap: None` means.
pub(crate) fn default_overlap(block: i64) -> i64 {
    ((block as f64) / 6.0).round().max(1.0) as i64
}

/// Reads a method's typed config in [`Method::check`]: a parameter that cannot be read becomes
/// the check's only error, naming its key.
pub(crate) fn read_config<C: MethodConfig>(p: &Params) -> Result<C, Vec<ParamError>> {
    C::from_params(p).map_err(|e| vec![e.into()])
}

/// The checks every square-block method shares: the block fits in the sample and the overlap
/// (real or virtual) is at most half the block.
pub(crate) fn check_block_and_overlap(block: u32, overlap: u32, sample: (u32, u32)) -> Vec<ParamError> {
    let mut errors = Vec::new();
    let smaller = sample.0.min(sample.1);
    if block > smaller {
        errors.push(ParamError::new(
            "block",
            format!("block {block} is larger than the sample ({}x{}); use at most {smaller}", sample.0, sample.1),
        ));
    }
    if overlap > block / 2 {
        errors.push(ParamError::new(
            "overlap",
            format!("overlap {overlap} is more than half the block ({block}); use at most {}", block / 2),
        ));
    }
    errors
}

/// Every available method, in listing order.
pub fn registry() -> &'static [&'static dyn Method] {
    &[
        &quilting::Quilting,
        &double_seam::DoubleSeam,
        &patch_sampling::PatchSampling,
        &near_regular::coevolution::Coevolution,
        &near_regular::tes::Tes,
        &tiles::wang_tiles::WangTiles,
        &tiles::rw_tiles::RwTiles,
    ]
}

/// The method called `name`.
pub fn find(name: &str) -> Option<&'static dyn Method> {
    registry().iter().copied().find(|m| m.name() == name)
}

/// The names of all methods, for error messages.
pub fn names() -> Vec<&'static str> {
    registry().iter().map(|m| m.name()).collect()
}
