//! How much a texture repeats itself: the highest normalised autocorrelation of its gray levels at
//! shifts of [`MIN_SHIFT`] pixels or more (issue #30's measure of visible periodicity).
//!
//! A fill made of a few tiles reused many times correlates with itself at the tile period (with
//! two colours per edge, about half its pixels are copies of those a tile away), while a
//! non-repeating texture decorrelates within its grain size. Short shifts are left out because
//! every texture correlates with itself there; shifts go up to half the image each way, so that
//! every value averages over at least a quarter of the image.

use super::acf::{AcfForm, autocorrelation};
use super::centred_gray;
use crate::image::RgbImage;

/// The shortest shift (in pixels, the larger of `|dx|` and `|dy|`) the measure looks at.
pub const MIN_SHIFT: usize = 16;

/// The largest value of the overlap-mean gray autocorrelation (1 at the origin; B9's
/// `OverlapMean` form) over the shifts `(dx, dy)` with `max(|dx|, |dy|) ≥` [`MIN_SHIFT`] and
/// `|dx| ≤ W/2`, `|dy| ≤ H/2`. `None` for a constant image or one under `2·MIN_SHIFT + 2` pixels
/// on a side.
pub fn max_autocorrelation(img: &RgbImage) -> Option<f64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 2 * MIN_SHIFT + 2 || h < 2 * MIN_SHIFT + 2 {
        return None;
    }
    let (rx, ry) = (w / 2, h / 2);
    let acf = autocorrelation(&centred_gray(img), w, h, rx, ry, AcfForm::OverlapMean).ok()?;
    let mut best = f64::NEG_INFINITY;
    for dy in -(ry as i64)..=ry as i64 {
        for dx in -(rx as i64)..=rx as i64 {
            if dx.unsigned_abs().max(dy.unsigned_abs()) as usize >= MIN_SHIFT {
                best = best.max(acf.get(dx, dy));
            }
        }
    }
    best.is_finite().then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_periodic_image_repeats_and_noise_does_not() {
        let mut state = 12345u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 56) as u8
        };
        let random = RgbImage::from_fn(128, 128, |_, _| {
            let v = noise();
            [v, v, v]
        });
        let tile: Vec<u8> = (0..32 * 32).map(|_| noise()).collect();
        let periodic = RgbImage::from_fn(128, 128, |x, y| {
            let v = tile[((y % 32) * 32 + x % 32) as usize];
            [v, v, v]
        });
        assert!(max_autocorrelation(&random).unwrap() < 0.2);
        assert!(max_autocorrelation(&periodic).unwrap() > 0.99);
        assert_eq!(max_autocorrelation(&RgbImage::new(20, 20)), None);
    }
}
