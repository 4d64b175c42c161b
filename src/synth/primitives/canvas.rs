//! The output being composed, together with where each of its pixels came from.
//!
//! Methods write through a [`Canvas`] instead of into a bare image, so that the placement
//! (`synth::placement`) is recorded by the same calls that make the pixels and cannot drift from
//! them. When the job does not need the placement, recording is off and costs a branch.

use super::feather;
use crate::image::RgbImage;
use crate::synth::placement::Placement;

/// An 8-bit RGB image under construction and, optionally, its placement.
pub struct Canvas {
    pub image: RgbImage,
    pub placement: Option<Placement>,
}

impl Canvas {
    /// A black `width × height` canvas over a sample of `sample` size; `record` keeps the placement.
    pub fn new(width: u32, height: u32, sample: (u32, u32), record: bool) -> Canvas {
        Canvas { image: RgbImage::new(width, height), placement: record.then(|| Placement::new(width, height, sample)) }
    }

    pub fn width(&self) -> u32 {
        self.image.width()
    }
    pub fn height(&self) -> u32 {
        self.image.height()
    }

    /// Pixel `(x, y)` becomes sample pixel `(sx, sy)`.
    #[inline]
    pub fn copy(&mut self, x: u32, y: u32, sample: &RgbImage, sx: u32, sy: u32) {
        self.image.put(x, y, sample.get(sx, sy));
        if let Some(p) = &mut self.placement {
            p.copy(x, y, sx, sy);
        }
    }

    /// Pixel `(x, y)` is feathered towards sample pixel `(sx, sy)` with weight `num / den`
    /// ([`feather::blend`]).
    #[inline]
    pub fn blend(&mut self, x: u32, y: u32, sample: &RgbImage, sx: u32, sy: u32, num: u32, den: u32) {
        let alpha = f64::from(num) / f64::from(den);
        self.image.put(x, y, feather::blend(self.image.get(x, y), sample.get(sx, sy), alpha));
        if let Some(p) = &mut self.placement {
            p.blend(x, y, sx, sy, num, den);
        }
    }

    /// Pixel `(x, y)` takes what pixel `from` holds (content and provenance).
    #[inline]
    pub fn copy_pixel(&mut self, x: u32, y: u32, from: (u32, u32)) {
        self.image.put(x, y, self.image.get(from.0, from.1));
        if let Some(p) = &mut self.placement {
            p.copy_pixel(x, y, from);
        }
    }

    /// The top-left `w × h`, image and placement alike.
    pub fn into_top_left(self, w: u32, h: u32) -> Canvas {
        Canvas { image: self.image.into_top_left(w, h), placement: self.placement.map(|p| p.into_top_left(w, h)) }
    }

    /// The image and the placement, for a method's [`crate::synth::method::Synthesis`].
    pub fn finish(self) -> (RgbImage, Option<Placement>) {
        (self.image, self.placement)
    }
}
