//! An inpainting job's fill region, made from its mask image or from one of its image's own
//! channels and checked the same way for a run (`plan`) and for a re-run from a manifest
//! (`verify`): the mask has the image's size, leaves something to copy, and leaves room for a
//! whole block.

use crate::batch::execute::LoadedSample;
use crate::batch::job::MaskChannel;
use crate::image::io::Samples;
use crate::synth::constraints::{FillRegion, SampleMask};
use crate::synth::params::Choice;
use std::path::Path;

/// Where the fill region comes from, decoded.
pub enum MaskSource<'a> {
    /// `mask = "…"`: white (at least half) = fill.
    File { path: &'a Path, loaded: &'a LoadedSample },
    /// `channel = "…"`: the image's channel below half = fill (`a`: the transparent pixels).
    Channel(MaskChannel),
}

impl MaskSource<'_> {
    /// The job-file key a problem with the mask is reported at.
    pub fn key(&self) -> &'static str {
        match self {
            MaskSource::File { .. } => "inpaint.mask",
            MaskSource::Channel(_) => "inpaint.channel",
        }
    }

    /// What goes into the content key and the output spec: the mask's pixels, or the channel's
    /// name (the image's pixels are the sample's, already in the key).
    pub fn spec(&self) -> serde_json::Value {
        match self {
            MaskSource::File { loaded, .. } => serde_json::json!({ "mask": { "pixels": loaded.pixel_digest } }),
            MaskSource::Channel(c) => serde_json::json!({ "channel": c.name() }),
        }
    }
}

/// The fill region of `image` (at `image_path`, for messages), checked: of the image's size,
/// not everything, and (with the method's `block`) leaving a whole block outside it that
/// `sample_mask` (when given) also allows. `Err` is the message for [`MaskSource::key`].
pub fn fill_region(
    image: &LoadedSample,
    image_path: &Path,
    source: &MaskSource,
    block: Option<i64>,
    sample_mask: Option<&SampleMask>,
) -> Result<FillRegion, String> {
    let (w, h) = image.image.dimensions();
    let region = match source {
        MaskSource::File { path, loaded } => {
            let (mw, mh) = loaded.image.dimensions();
            if (mw, mh) != (w, h) {
                return Err(format!(
                    "inpaint mask `{}` is {mw}x{mh} but the image `{}` is {w}x{h}; the mask must have the image's size",
                    path.display(),
                    image_path.display()
                ));
            }
            let fill =
                loaded.image.as_raw().chunks_exact(3).map(|p| (u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2])) / 3 >= 128).collect();
            FillRegion::new(w, h, fill)
        }
        MaskSource::Channel(c) => FillRegion::new(w, h, channel_below_half(image, image_path, *c)?),
    };
    if region.count() == u64::from(w) * u64::from(h) {
        let what = match source {
            MaskSource::File { path, .. } => format!("inpaint mask `{}` is white everywhere", path.display()),
            MaskSource::Channel(c) => format!("channel `{}` of `{}` marks every pixel", c.name(), image_path.display()),
        };
        return Err(format!("{what}: the whole image would be filled and nothing is left to copy from (white = fill)"));
    }
    if let Some(block) = block {
        let copyable = crate::synth::constraints::Constraints { sample_mask, fill: Some(&region), guide: None, atlas: None }
            .copyable()
            .expect("a fill region restricts");
        let largest = copyable.largest_block();
        if i64::from(largest) < block {
            return Err(format!(
                "the image outside the inpaint mask{} leaves no whole {block}x{block} block (params.block) to copy from; the largest block \
                 it leaves is {largest}: use block = {largest} or less, or fill less",
                if sample_mask.is_some() { " and inside the sample mask" } else { "" }
            ));
        }
    }
    Ok(region)
}

/// Per pixel, whether the image's channel `c` is below half of its range (for a float image,
/// below 0.5).
fn channel_below_half(image: &LoadedSample, image_path: &Path, c: MaskChannel) -> Result<Vec<bool>, String> {
    let native = image.native_or_guide();
    let channels = native.channels as usize;
    let index = match (c, channels) {
        (MaskChannel::A, 2) => 1,
        (MaskChannel::A, 4) => 3,
        (MaskChannel::A, _) => {
            return Err(format!(
                "image `{}` has no alpha channel ({}); use `mask = \"…\"`, or a channel it has (r, g, b)",
                image_path.display(),
                image.describe()
            ));
        }
        // A gray image's r, g and b are its gray.
        (_, 1 | 2) => 0,
        (MaskChannel::R, _) => 0,
        (MaskChannel::G, _) => 1,
        (MaskChannel::B, _) => 2,
    };
    let below: Vec<bool> = match &native.samples {
        Samples::U8(v) => v.iter().skip(index).step_by(channels).map(|&x| x < 128).collect(),
        Samples::U16(v) => v.iter().skip(index).step_by(channels).map(|&x| x < 32768).collect(),
        Samples::F32(v) => v.iter().skip(index).step_by(channels).map(|&x| x < 0.5).collect(),
    };
    Ok(below)
}
