//! The block search of guided synthesis and texture transfer (Efros & Freeman 2001, §3): a
//! block's error weighs how well it continues the texture (its overlap with what is already
//! made) against how well the sample's guide under it matches the target guide where it goes.
//!
//! Both errors come from the exact search's FFT correlations, weighed and summed before one
//! inverse transform (`OverlapSearch::approximate_weighted`), with the weighed sum of their
//! rigorous error bounds: that bounds which positions can be within the tolerance of the best, and
//! only those are scored exactly. The choice is made on exact integer
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
    /// The weighted approximate errors of the last search, kept to reuse its memory.
    combined: Vec<f64>,
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
        GuidedSearch::of(OverlapSearch::new(sample, block, block), OverlapSearch::new(source, block, block), target, block, weight, allowed)
    }

    /// [`GuidedSearch::new`] from the searches of the sample and of its guide for `block`-sized
    /// blocks (made by [`OverlapSearch::new`] or shared by [`OverlapSearch::for_block`]).
    pub(crate) fn of(
        mut texture: OverlapSearch<'a>,
        mut by_guide: OverlapSearch<'a>,
        target: &'a RgbImage,
        block: u32,
        weight: f64,
        allowed: Option<Vec<bool>>,
    ) -> GuidedSearch<'a> {
        if let Some(a) = allowed {
            texture.restrict_to(a.clone());
            by_guide.restrict_to(a);
        }
        GuidedSearch { texture, guide: by_guide, target, weight, block, combined: Vec::new() }
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
        // The weighted approximation of every position, into a buffer kept between blocks (the
        // maps stay in the searches' workspaces). Without an overlap the texture term is zero.
        // With an overlap, both correlations are weighed and summed before one inverse transform.
        let mut combined = std::mem::take(&mut self.combined);
        let margin = if area == 0 {
            let (guide, guide_margin) = self.guide.approximate_in_place(self.target, place, &whole).expect("a whole block is never empty");
            combined.clear();
            combined.extend(guide.iter().map(|&g| k_guide * g));
            k_guide * guide_margin
        } else {
            OverlapSearch::approximate_weighted(
                &mut self.texture,
                k_texture,
                (canvas, origin, regions),
                &mut self.guide,
                k_guide,
                (self.target, place, &whole),
                &mut combined,
            )
        };
        let nx = (self.texture.sample().width() - b + 1) as usize;
        let allowed = self.texture.allowed_positions();
        let best = match allowed {
            None => combined.iter().copied().fold(f64::INFINITY, f64::min),
            Some(a) => combined.iter().zip(a).filter(|(_, a)| **a).map(|(v, _)| *v).fold(f64::INFINITY, f64::min),
        };
        let threshold = (1.0 + tolerance) * (best + margin) + margin;
        let exact: Vec<(u32, u32, f64)> = combined
            .iter()
            .enumerate()
            .filter(|&(i, &v)| v <= threshold && allowed.is_none_or(|a| a[i]))
            .map(|(i, _)| {
                let (x, y) = ((i % nx) as u32, (i / nx) as u32);
                let t = self.texture.exact_ssd(x, y, canvas, origin, regions) as f64;
                let g = self.guide.exact_ssd(x, y, self.target, place, &whole) as f64;
                (x, y, k_texture * t + k_guide * g)
            })
            .collect();
        self.combined = combined;
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
        let guide = Guide::from_images(&target, &sample, 1.0, 1, true);
        // A flat target has no spread: it sits at the sample's mean level, between the halves.
        assert!(guide.target.get(0, 0)[0] > 100 && guide.target.get(0, 0)[0] < 150);
        let light = RgbImage::from_fn(10, 10, |x, _| if x < 5 { [0; 3] } else { [255; 3] });
        let guide = Guide::from_images(&light, &sample, 1.0, 1, true);
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

    #[test]
    fn the_candidates_are_those_of_brute_force() {
        let mut s = crate::synth::rng::Stream::new(5, "test/guided");
        let sample = RgbImage::from_fn(40, 36, |x, _| [(x * 6) as u8 + s.below(20) as u8, s.below(256) as u8, s.below(256) as u8]);
        let target = RgbImage::from_fn(30, 30, |x, y| [(x * 8) as u8, (y * 8) as u8, 90]);
        let guide = Guide::from_images(&target, &sample, 0.6, 1, true);
        let canvas = RgbImage::from_fn(30, 30, |x, y| sample.get(x + 3, y + 2));
        let (b, origin, place) = (9, (7, 8), (4, 5));
        let whole = [Rect::new(0, 0, b, b)];
        for regions in [vec![], vec![Rect::new(0, 0, 3, b), Rect::new(3, 0, b - 3, 3)], whole.to_vec()] {
            for tolerance in [0.0, 0.1] {
                let mut search = GuidedSearch::new(&sample, &guide.source, &guide.target, b, 0.6, None);
                let picks = search.candidates(&canvas, origin, &regions, place, tolerance);
                let area: u64 = regions.iter().map(|r| r.area()).sum();
                let kt = if area == 0 { 0.0 } else { 0.4 / (3.0 * area as f64) };
                let kg = 0.6 / (3.0 * f64::from(b * b));
                let mut all = Vec::new();
                for y in 0..sample.height() - b + 1 {
                    for x in 0..sample.width() - b + 1 {
                        let t = search.texture.exact_ssd(x, y, &canvas, origin, &regions) as f64;
                        let g = search.guide.exact_ssd(x, y, &guide.target, place, &whole) as f64;
                        all.push((x, y, kt * t + kg * g));
                    }
                }
                let min = all.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
                let brute: Vec<(u32, u32)> = all.iter().filter(|c| c.2 <= (1.0 + tolerance) * min).map(|c| (c.0, c.1)).collect();
                assert_eq!(picks, brute, "regions {regions:?}, tolerance {tolerance}");
            }
        }
    }
}
