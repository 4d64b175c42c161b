//! The block search of guided synthesis and texture transfer (Efros & Freeman 2001, §3): a
//! block's error weighs how well it continues the texture (its overlap with what is already
//! made) against how well the sample's guide under it matches the target guide where it goes.
//!
//! Both errors come from the exact search's FFT correlations (`OverlapSearch::approximate_all`),
//! each with its rigorous error bound; the weighted sum bounds which positions can be within the
//! tolerance of the best, and only those are scored exactly. The choice is made on exact integer
//! sums combined in a fixed order, so the pixels are the same on every machine and thread count.
//!
//! The two errors are made comparable per pixel and channel: the overlap's sum over its area, the
//! guide's over the whole block. `weight` is the guide's share: 0 ignores it, 1 follows only it.

use crate::image::RgbImage;
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::overlap_search::OverlapSearch;

/// The guided search over one sample for `block × block` blocks.
pub(crate) struct GuidedSearch<'a> {
    texture: OverlapSearch<'a>,
    guide: OverlapSearch<'a>,
    target: &'a RgbImage,
    weight: f64,
    block: u32,
}

impl<'a> GuidedSearch<'a> {
    /// The search of `sample`, whose guide is `source`, towards the target guide `target` (at
    /// least as large as the canvas), copying only from `allowed` positions when given.
    pub(crate) fn new(
        sample: &'a RgbImage,
        source: &'a RgbImage,
        target: &'a RgbImage,
        block: u32,
        weight: f64,
        allowed: Option<Vec<bool>>,
    ) -> GuidedSearch<'a> {
        let mut texture = OverlapSearch::new(sample, block, block);
        let mut by_guide = OverlapSearch::new(source, block, block);
        if let Some(a) = allowed {
            texture.restrict_to(a.clone());
            by_guide.restrict_to(a);
        }
        GuidedSearch { texture, guide: by_guide, target, weight, block }
    }

    /// The positions whose weighted error is within `(1 + tolerance)` of the best, row-major:
    /// `regions` of `canvas` at `origin` are the overlap (none for the first block), and the
    /// target guide is read at `place` (the block's place in the output).
    pub(crate) fn candidates(
        &mut self,
        canvas: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        place: (u32, u32),
        tolerance: f64,
    ) -> Vec<(u32, u32)> {
        let b = self.block;
        let whole = [Rect::new(0, 0, b, b)];
        let area: u64 = regions.iter().map(|r| r.area()).sum();
        let k_texture = if area == 0 { 0.0 } else { (1.0 - self.weight) / (3.0 * area as f64) };
        let k_guide = self.weight / (3.0 * f64::from(b) * f64::from(b));
        let (texture, texture_margin) = self.texture.approximate_all(canvas, origin, regions);
        let (guide, guide_margin) = self.guide.approximate_all(self.target, place, &whole);
        let nx = self.texture.sample().width() - b + 1;
        let margin = k_texture * texture_margin + k_guide * guide_margin;
        let combined = |i: usize| k_texture * texture[i] + k_guide * guide[i];
        let allowed = |i: usize| self.texture.may_copy(i as u32 % nx, i as u32 / nx);
        let best = (0..texture.len()).filter(|&i| allowed(i)).map(combined).fold(f64::INFINITY, f64::min);
        let threshold = (1.0 + tolerance) * (best + margin) + margin;
        let exact: Vec<(u32, u32, f64)> = (0..texture.len())
            .filter(|&i| allowed(i) && combined(i) <= threshold)
            .map(|i| {
                let (x, y) = (i as u32 % nx, i as u32 / nx);
                let t = self.texture.exact_ssd(x, y, canvas, origin, regions) as f64;
                let g = self.guide.exact_ssd(x, y, self.target, place, &whole) as f64;
                (x, y, k_texture * t + k_guide * g)
            })
            .collect();
        let min = exact.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
        exact.into_iter().filter(|c| c.2 <= (1.0 + tolerance) * min).map(|c| (c.0, c.1)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::constraints::Guide;

    #[test]
    fn the_guide_alone_picks_the_block_whose_guide_matches_and_the_texture_alone_ignores_it() {
        // A sample dark on the left half and light on the right; the target asks for light.
        let sample = RgbImage::from_fn(40, 20, |x, y| if x < 20 { [20 + (y % 3) as u8, 20, 20] } else { [230, 230 - (y % 3) as u8, 230] });
        let target = RgbImage::from_fn(10, 10, |_, _| [255, 255, 255]);
        let guide = Guide::from_images(&target, &sample, 1.0, 1);
        // A flat target has no spread: it sits at the sample's mean level, between the halves.
        assert!(guide.target.get(0, 0)[0] > 100 && guide.target.get(0, 0)[0] < 150);
        let light = RgbImage::from_fn(10, 10, |x, _| if x < 5 { [0; 3] } else { [255; 3] });
        let guide = Guide::from_images(&light, &sample, 1.0, 1);
        let mut search = GuidedSearch::new(&sample, &guide.source, &guide.target, 10, 1.0, None);
        // The right half of the target is light: a block placed there comes from the light half.
        let picks = search.candidates(&RgbImage::new(10, 10), (0, 0), &[], (0, 0), 0.0);
        assert!(!picks.is_empty());
        let light_target = Guide { target: RgbImage::from_fn(10, 10, |_, _| [230; 3]), ..guide.clone() };
        let mut search = GuidedSearch::new(&sample, &light_target.source, &light_target.target, 10, 1.0, None);
        for (x, _) in search.candidates(&RgbImage::new(10, 10), (0, 0), &[], (0, 0), 0.0) {
            assert!(x >= 20, "a light target takes a light block, not x = {x}");
        }
        // Weight 0: the guide is ignored, and the texture overlap decides.
        let mut search = GuidedSearch::new(&sample, &light_target.source, &light_target.target, 10, 0.0, None);
        let canvas = RgbImage::from_fn(10, 10, |_, y| [20 + (y % 3) as u8, 20, 20]);
        for (x, _) in search.candidates(&canvas, (0, 0), &[Rect::new(0, 0, 3, 10)], (0, 0), 0.0) {
            assert!(x + 3 <= 20, "the dark overlap takes a dark block, not x = {x}");
        }
    }
}
