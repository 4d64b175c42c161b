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

use crate::synth::method::Method;
use crate::synth::params::ParamError;

/// The checks every square-block method shares: the block fits in the sample and the overlap
/// (real or virtual) is at most half the block.
pub(crate) fn check_block_and_overlap(block: i64, overlap: i64, sample: (u32, u32)) -> Vec<ParamError> {
    let mut errors = Vec::new();
    let smaller = sample.0.min(sample.1) as i64;
    if block > smaller {
        errors.push(ParamError::new(
            "block",
            format!("block {block} is larger than the sample ({}x{}); use at most {smaller}", sample.0, sample.1),
        ));
    }
    if overlap * 2 > block {
        errors.push(ParamError::new("overlap", format!("overlap {overlap} is more than half the block ({block}); use at most {}", block / 2)));
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
