//! Several samples (`samples = [...]`) and transformed copies (`augment = [...]`): the decoded
//! samples, masks and maps of a job packed into one atlas ([`crate::synth::atlas`]) that its
//! method searches as a single sample with a sample mask. The plan and `verify` both build it
//! here, from the files a job file or a record names, so that a re-run searches the same atlas.

use crate::batch::execute::LoadedSample;
use crate::synth::atlas::{Atlas, Augment};
use crate::synth::constraints::SampleMask;
use crate::synth::placement::MapKind;
use std::path::Path;

/// What a job with several samples or `augment` searches and renders from.
pub struct AtlasSamples {
    pub atlas: Atlas,
    /// The atlas of the samples: what the method searches and the output is rendered from.
    pub search: std::sync::Arc<LoadedSample>,
    /// Which atlas pixels may be copied: the pieces, less what each sample's mask forbids.
    pub mask: SampleMask,
    /// The first sample, which the job's metrics and advice compare with.
    pub first: std::sync::Arc<LoadedSample>,
    /// The job's companions packed like the samples (set by the plan once they are checked).
    pub companions: Vec<LoadedSample>,
}

impl AtlasSamples {
    /// Whether the masks leave a whole `block × block` block (the method's `block`) to copy.
    pub fn check_block(&self, block: Option<i64>) -> Result<(), SampleProblem> {
        let Some(block) = block else { return Ok(()) };
        let largest = self.mask.largest_block();
        if i64::from(largest) < block {
            return Err((
                "sample_mask",
                format!(
                    "the samples and their masks leave no whole {block}x{block} block (params.block) to copy; the largest block they allow is {largest}: use block = {largest} or less"
                ),
            ));
        }
        Ok(())
    }
}

/// A problem with a job's samples: the key it concerns and the message.
pub type SampleProblem = (&'static str, String);

/// Packs `samples` (each with its path and optional mask) and their `augment` copies;
/// `image_copyable` further restricts the first sample when it is an inpainting job's image (its
/// hole, or all of it when only other samples are copied from: [`image_copyable`]). Checks
/// that they share channels and precision, that each mask has its sample's size, and that the
/// masks leave something to copy ([`AtlasSamples::check_block`] checks the method's block once
/// its parameters are resolved for the atlas).
pub fn assemble(
    samples: &[(&Path, std::sync::Arc<LoadedSample>)],
    masks: &[Option<(&Path, &LoadedSample)>],
    augment: &[Augment],
    image_copyable: Option<&SampleMask>,
) -> Result<AtlasSamples, SampleProblem> {
    let (first_path, first) = &samples[0];
    for (path, s) in &samples[1..] {
        if s.describe() != first.describe() {
            return Err((
                "samples",
                format!(
                    "`{}` is {} but `{}` is {}; every sample must have the same channels and precision",
                    path.display(),
                    s.describe(),
                    first_path.display(),
                    first.describe()
                ),
            ));
        }
    }
    let mut sample_masks = Vec::new();
    for ((path, s), m) in samples.iter().zip(masks) {
        let Some((mask_path, m)) = m else {
            sample_masks.push(None);
            continue;
        };
        let (w, h) = m.image.dimensions();
        let size = s.image.dimensions();
        if (w, h) != size {
            return Err((
                "sample_mask",
                format!(
                    "sample mask `{}` is {w}x{h} but the sample `{}` is {}x{}; the mask must have the sample's size",
                    mask_path.display(),
                    path.display(),
                    size.0,
                    size.1
                ),
            ));
        }
        sample_masks.push(Some(SampleMask::from_image(&m.image)));
    }
    let sizes: Vec<(u32, u32)> = samples.iter().map(|(_, s)| s.image.dimensions()).collect();
    let atlas = Atlas::layout(&sizes, augment);
    let (w, h) = atlas.dimensions();
    let mask = SampleMask::new(
        w,
        h,
        atlas.allowed(|s, x, y| {
            sample_masks[s].as_ref().is_none_or(|m| m.allows(x, y)) && (s != 0 || image_copyable.is_none_or(|m| m.allows(x, y)))
        }),
    );
    if mask.allowed_pixels() == 0 {
        return Err(("sample_mask", "the sample masks are black everywhere: they leave nothing to copy (white = may be copied)".into()));
    }
    let natives: Vec<_> = samples.iter().map(|(_, s)| s.native_or_guide()).collect();
    let composed = atlas.compose(&natives.iter().map(|n| &**n).collect::<Vec<_>>(), MapKind::Color);
    Ok(AtlasSamples {
        atlas,
        search: std::sync::Arc::new(LoadedSample::from_native(composed)),
        mask,
        first: first.clone(),
        companions: Vec::new(),
    })
}

/// Another map of the samples (a companion of the single sample, a source guide) packed like
/// them: same pieces, normals turned with their piece.
pub fn pack_map(atlas: &Atlas, maps: &[&LoadedSample], kind: MapKind) -> LoadedSample {
    let natives: Vec<_> = maps.iter().map(|m| m.native_or_guide()).collect();
    LoadedSample::from_native(atlas.compose(&natives.iter().map(|n| &**n).collect::<Vec<_>>(), kind))
}

/// Which pixels of an inpainting job's image its fill may copy: those outside the hole, or none
/// when the job lists other samples without the image.
pub fn image_copyable(region: &crate::synth::constraints::FillRegion, copy_from_image: bool) -> SampleMask {
    let known = region.known();
    if copy_from_image {
        return known;
    }
    let (w, h) = known.dimensions();
    SampleMask::new(w, h, vec![false; w as usize * h as usize])
}
