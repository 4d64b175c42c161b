//! What an output must respect besides its sample, parameters and seed: which pixels of the
//! sample may be copied at all (a sample mask, `sample_mask` in a job file), and which pixels of
//! an image are to be filled while every other one stays (inpainting, `[inpaint]`).
//!
//! A photo sample often holds things that must never appear in the output: a watermark, a
//! border, a lamp post, a scale bar. A method that copies blocks honours a mask by copying only
//! blocks whose every pixel the mask allows, so no output pixel can come from a forbidden one.
//! The mask is decided here once (which block positions are allowed, the largest block that
//! fits), so that every method and the job checks use the same rule.

/// Which sample pixels may be copied: `true` = allowed (white in the mask image).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SampleMask {
    width: u32,
    height: u32,
    allowed: Vec<bool>,
}

impl SampleMask {
    /// A `width × height` mask from row-major flags (`true` = may be copied).
    pub fn new(width: u32, height: u32, allowed: Vec<bool>) -> SampleMask {
        assert_eq!(allowed.len(), width as usize * height as usize, "one flag per pixel");
        SampleMask { width, height, allowed }
    }

    /// A mask from an image's gray levels: a pixel at least half white may be copied.
    pub fn from_gray(width: u32, height: u32, gray: impl Fn(u32, u32) -> u8) -> SampleMask {
        let allowed = (0..height).flat_map(|y| (0..width).map(move |x| (x, y))).map(|(x, y)| gray(x, y) >= 128).collect();
        SampleMask::new(width, height, allowed)
    }

    /// A mask from an image: a pixel whose mean of R, G and B is at least half white may be
    /// copied (a black-and-white mask, or a gray one thresholded at 128).
    pub fn from_image(image: &crate::image::RgbImage) -> SampleMask {
        SampleMask::from_gray(image.width(), image.height(), |x, y| {
            let [r, g, b] = image.get(x, y);
            ((u16::from(r) + u16::from(g) + u16::from(b)) / 3) as u8
        })
    }

    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub fn allows(&self, x: u32, y: u32) -> bool {
        self.allowed[(y * self.width + x) as usize]
    }

    /// How many pixels may be copied.
    pub fn allowed_pixels(&self) -> u64 {
        self.allowed.iter().filter(|&&a| a).count() as u64
    }

    /// For every position of a `block_w × block_h` block in the sample, row-major over
    /// `(W − block_w + 1) × (H − block_h + 1)`: whether the mask allows all of its pixels. From an
    /// integral image of the forbidden pixels, so it costs one pass whatever the block.
    pub fn block_positions(&self, block_w: u32, block_h: u32) -> Vec<bool> {
        let (w, h) = (self.width as usize, self.height as usize);
        let (bw, bh) = (block_w as usize, block_h as usize);
        if bw == 0 || bh == 0 || bw > w || bh > h {
            return Vec::new();
        }
        let stride = w + 1;
        let mut forbidden = vec![0u32; stride * (h + 1)];
        for y in 0..h {
            let mut row = 0;
            for x in 0..w {
                row += u32::from(!self.allowed[y * w + x]);
                forbidden[(y + 1) * stride + x + 1] = forbidden[y * stride + x + 1] + row;
            }
        }
        let (nx, ny) = (w - bw + 1, h - bh + 1);
        let mut out = Vec::with_capacity(nx * ny);
        for y in 0..ny {
            for x in 0..nx {
                let count = forbidden[(y + bh) * stride + x + bw] + forbidden[y * stride + x]
                    - forbidden[y * stride + x + bw]
                    - forbidden[(y + bh) * stride + x];
                out.push(count == 0);
            }
        }
        out
    }

    /// The side of the largest square block whose every pixel the mask allows (0 when none).
    pub fn largest_block(&self) -> u32 {
        // The classic recurrence: the largest allowed square ending at (x, y) is one more than
        // the smallest of those ending left, above and diagonally.
        let w = self.width as usize;
        let mut previous = vec![0u32; w];
        let mut current = vec![0u32; w];
        let mut best = 0;
        for y in 0..self.height as usize {
            for x in 0..w {
                current[x] = if !self.allowed[y * w + x] {
                    0
                } else if x == 0 || y == 0 {
                    1
                } else {
                    1 + previous[x].min(previous[x - 1]).min(current[x - 1])
                };
                best = best.max(current[x]);
            }
            std::mem::swap(&mut previous, &mut current);
        }
        best
    }
}

/// The pixels of an image to fill (`true`; white in an inpaint mask); every other pixel is
/// known and stays as it is, bit for bit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FillRegion {
    width: u32,
    height: u32,
    fill: Vec<bool>,
}

impl FillRegion {
    /// A `width × height` region from row-major flags (`true` = to fill).
    pub fn new(width: u32, height: u32, fill: Vec<bool>) -> FillRegion {
        assert_eq!(fill.len(), width as usize * height as usize, "one flag per pixel");
        FillRegion { width, height, fill }
    }

    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub fn fills(&self, x: u32, y: u32) -> bool {
        self.fill[(y * self.width + x) as usize]
    }

    /// How many pixels are to be filled.
    pub fn count(&self) -> u64 {
        self.fill.iter().filter(|&&f| f).count() as u64
    }

    /// The smallest rectangle `[x0, x1) × [y0, y1)` holding every pixel to fill, or `None`.
    pub fn bounds(&self) -> Option<(u32, u32, u32, u32)> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if self.fills(x, y) {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
                }
            }
        }
        (x1 > 0).then_some((x0, y0, x1, y1))
    }

    /// The largest rectangle `(x, y, w, h)` of known pixels (the largest area; the first found
    /// in raster order of its bottom-right corner on ties), or `None` when every pixel is to be
    /// filled: the part of a damaged image that shows its texture as it is.
    pub fn largest_known_rect(&self) -> Option<(u32, u32, u32, u32)> {
        let (w, h) = (self.width as usize, self.height as usize);
        // Per column, how many known pixels end at this row; then the largest rectangle under
        // that histogram, by a stack of rising bars.
        let mut heights = vec![0usize; w];
        let mut best: Option<(usize, usize, usize, usize, usize)> = None;
        for y in 0..h {
            for (x, run) in heights.iter_mut().enumerate() {
                *run = if self.fill[y * w + x] { 0 } else { *run + 1 };
            }
            let mut stack: Vec<usize> = Vec::new();
            for x in 0..=w {
                let bar = if x < w { heights[x] } else { 0 };
                while let Some(&top) = stack.last() {
                    if heights[top] < bar {
                        break;
                    }
                    stack.pop();
                    let left = stack.last().map_or(0, |&l| l + 1);
                    let (rw, rh) = (x - left, heights[top]);
                    if rw * rh > best.map_or(0, |b| b.4) {
                        best = Some((left, y + 1 - rh, rw, rh, rw * rh));
                    }
                }
                stack.push(x);
            }
        }
        best.map(|(x, y, rw, rh, _)| (x as u32, y as u32, rw as u32, rh as u32))
    }

    /// The known pixels as a sample mask: what a fill may copy from when the image is its own
    /// sample (the pixels to fill hold what must go: a logo, a cable, a hole).
    pub fn known(&self) -> SampleMask {
        SampleMask::new(self.width, self.height, self.fill.iter().map(|f| !f).collect())
    }
}

/// How much of a later pass's target is the previous pass's luminance ([`Guide::after_pass`]):
/// measured 0.25, 0.35 and 0.5 on grass, pebbles and cork onto the rings target (seeds 2, 5, 9);
/// the gray KL was about the same for all three, and the correlation with the target fell with
/// more (pebbles 0.930, 0.912, 0.887).
pub const PREVIOUS_PASS_SHARE: f64 = 0.25;

/// Guided synthesis (`[guide]`, texture transfer): a gray map of the output's size saying where
/// it should be dark or light, the sample's own gray map, and how much the guide weighs against
/// the texture's continuity (0 = not at all, 1 = only the guide). Both maps are kept as gray RGB
/// images so that the block search that scores the texture scores them too.
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    pub target: crate::image::RgbImage,
    pub source: crate::image::RgbImage,
    pub weight: f64,
    /// Passes of Efros and Freeman's iteration: each pass with blocks a third smaller, which must
    /// agree with the previous pass as well as with the new overlap, so that the texture is refined
    /// under the guide's layout; the guide keeps its `weight` in every pass. With luminance guides
    /// the previous pass is part of the target ([`Guide::after_pass`]); with a given `source`
    /// each block is matched over its whole area against it. 1: a single pass.
    pub passes: u32,
    /// The source guide is the sample's own luminance (no `source` given): the guides then say
    /// where the output is light or dark, and are compared at a block's scale
    /// ([`Guide::at_block_scale`]). A `source` the job gives is compared as it is.
    pub luminance: bool,
}

impl Guide {
    /// The guides compared as local brightness, for blocks of `block` pixels: both blurred (a
    /// Gaussian of σ = block / 8) and spread back to the sample's luminance mean and spread.
    ///
    /// Pixel by pixel, a flat target level is matched best by the sample's flattest blocks, so the
    /// search preferred low-contrast patches (and the same few of them): a transfer came out
    /// washed out and repetitive, its gray histogram far from the sample's (paper 003's gray KL
    /// 0.18 on pebbles, three times Embark's). Matched as local brightness, any block whose
    /// surroundings have the wanted level fits, whatever its detail. Only for luminance guides:
    /// a source guide the job gives is the user's own correspondence and is left as it is.
    pub fn at_block_scale(&self, block: u32) -> Guide {
        let sigma = f64::from(block) / 8.0;
        if !self.luminance || sigma < 0.5 {
            return self.clone();
        }
        let kernel = crate::metrics::orientation::gaussian_kernel(sigma);
        let plane = |img: &crate::image::RgbImage| -> Vec<f64> { img.as_raw().chunks_exact(3).map(|p| f64::from(p[0])).collect() };
        let (mean, spread) = mean_and_spread(&plane(&self.source));
        let smooth = |img: &crate::image::RgbImage| {
            let (w, h) = img.dimensions();
            let blurred = crate::metrics::orientation::separable_blur(&plane(img), w as usize, h as usize, &kernel);
            let (m, s) = mean_and_spread(&blurred);
            let scale = if s > 1e-9 { spread / s } else { 0.0 };
            crate::image::RgbImage::from_fn(w, h, |x, y| {
                let g = (mean + (blurred[(y * w + x) as usize] - m) * scale).round().clamp(0.0, 255.0) as u8;
                [g, g, g]
            })
        };
        Guide { target: smooth(&self.target), source: smooth(&self.source), ..self.clone() }
    }

    /// The guide of a pass after the first of Efros and Freeman's iteration, for luminance guides
    /// at `block`'s scale (this guide's, [`Guide::at_block_scale`]): the target moved
    /// [`PREVIOUS_PASS_SHARE`] of the way to the previous pass's own light and dark, taken as the
    /// target was (its luminance moved to the sample's, then at `block`'s scale).
    ///
    /// Efros and Freeman match each new block pixel by pixel against the previous pass under
    /// it. Over a whole block of texture that favours the flattest blocks (a flat block is off a
    /// textured one by its spread, another textured block by twice that), and every pass narrowed
    /// the output's gray levels further: paper 003's gray KL against the sample was 0.02, 0.05 and
    /// 0.12 after passes 1, 2 and 3 on grass. Compared as local brightness, the previous pass still
    /// keeps the later ones to its layout, and a block is matched pixel by pixel only where it
    /// joins this pass's blocks (its overlap). After three passes onto the rings target: gray KL
    /// 0.123 → 0.073 (grass), 0.057 → 0.033 (pebbles), 0.091 → 0.054 (cork), the correlation
    /// with the target as before (0.975 → 0.970, 0.918 → 0.930, 0.947 → 0.948).
    pub fn after_pass(&self, previous: &crate::image::RgbImage, sample: &crate::image::RgbImage, block: u32) -> Guide {
        let (w, h) = self.target.dimensions();
        assert_eq!(previous.dimensions(), (w, h), "the previous pass has the output's size");
        let before = Guide::from_images(previous, sample, self.weight, 1, true).at_block_scale(block).target;
        let target = crate::image::RgbImage::from_fn(w, h, |x, y| {
            let (t, p) = (f64::from(self.target.get(x, y)[0]), f64::from(before.get(x, y)[0]));
            let g = (t + (p - t) * PREVIOUS_PASS_SHARE).round().clamp(0.0, 255.0) as u8;
            [g, g, g]
        });
        Guide { target, ..self.clone() }
    }

    /// The target guide over a `width × height` canvas that may reach past it (blocks a search
    /// reads whole): wrapped when the output is `tileable` (a torus), else its edge going on.
    pub fn target_beyond(&self, width: u32, height: u32, tileable: bool) -> crate::image::RgbImage {
        let (w, h) = self.target.dimensions();
        crate::image::RgbImage::from_fn(width, height, |x, y| {
            if tileable { self.target.get(x % w, y % h) } else { self.target.get(x.min(w - 1), y.min(h - 1)) }
        })
    }

    /// The luminance of `source` (the sample's guide, or the sample) and of `target`, the target's
    /// levels moved to the source's mean and spread: a photo much darker or flatter than the
    /// sample would otherwise match only its darkest or most uniform blocks.
    pub fn from_images(
        target: &crate::image::RgbImage,
        source: &crate::image::RgbImage,
        weight: f64,
        passes: u32,
        luminance: bool,
    ) -> Guide {
        let luma = |img: &crate::image::RgbImage| -> Vec<f64> {
            img.as_raw()
                .chunks_exact(3)
                .map(|p| (299.0 * f64::from(p[0]) + 587.0 * f64::from(p[1]) + 114.0 * f64::from(p[2])) / 1000.0)
                .collect()
        };
        let (t, s) = (luma(target), luma(source));
        let ((tm, ts), (sm, ss)) = (mean_and_spread(&t), mean_and_spread(&s));
        let scale = if ts > 1e-9 { ss / ts } else { 0.0 };
        let gray = |img: &crate::image::RgbImage, v: &[f64], map: &dyn Fn(f64) -> f64| {
            crate::image::RgbImage::from_fn(img.width(), img.height(), |x, y| {
                let g = map(v[(y * img.width() + x) as usize]).round().clamp(0.0, 255.0) as u8;
                [g, g, g]
            })
        };
        Guide { target: gray(target, &t, &|x| sm + (x - tm) * scale), source: gray(source, &s, &|x| x), weight, passes, luminance }
    }
}

/// The mean and the standard deviation of `v`, summed in index order.
fn mean_and_spread(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    (mean, (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt())
}

/// The constraints of one request; the default is none.
#[derive(Clone, Copy, Debug, Default)]
pub struct Constraints<'a> {
    /// Only these sample pixels may be copied (the sample's size).
    pub sample_mask: Option<&'a SampleMask>,
    /// Inpainting: the sample is the image to repair, the output has its size, and only these
    /// pixels are made; every other output pixel is the image's own (its placement is itself).
    /// With an `atlas` the image is its first piece, at (0, 0) and untransformed, and the sample
    /// mask (the atlas's) already forbids the hole in it and in its turned copies.
    pub fill: Option<&'a FillRegion>,
    /// Guided synthesis: blocks are chosen for how well they continue the texture and how well
    /// the sample's guide under them matches the target guide under their place.
    pub guide: Option<&'a Guide>,
    /// Several samples or turned copies packed into the sample: a method keeps a block from
    /// continuing its neighbour with a turned or mirrored copy of the same pixels
    /// ([`Atlas::twins`]).
    pub atlas: Option<&'a crate::synth::atlas::Atlas>,
}

impl Constraints<'_> {
    /// `members` (block positions) less those that are twins of a neighbour's block
    /// (`neighbours`, positions of `block`-sized blocks); `None` when every one is.
    pub fn without_twins(&self, members: &[(u32, u32, u64)], neighbours: &[(u32, u32)], block: u32) -> Option<Vec<(u32, u32, u64)>> {
        let kept: Vec<(u32, u32, u64)> = members.iter().copied().filter(|&(x, y, _)| !self.is_twin((x, y), neighbours, block)).collect();
        (!kept.is_empty()).then_some(kept)
    }

    /// Whether a `block`-sized block at `at` would show a turned or mirrored copy of the pixels
    /// of a neighbour's block ([`crate::synth::atlas::Atlas::twins`]); never without copies.
    pub fn is_twin(&self, at: (u32, u32), neighbours: &[(u32, u32)], block: u32) -> bool {
        self.atlas.filter(|a| a.has_copies()).is_some_and(|a| neighbours.iter().any(|&n| a.twins(at, n, block)))
    }

    /// The block positions a `block_w × block_h` block may be copied from
    /// ([`SampleMask::block_positions`]), or `None` when every position may be.
    pub fn block_positions(&self, block_w: u32, block_h: u32) -> Option<Vec<bool>> {
        self.copyable().map(|m| m.block_positions(block_w, block_h))
    }

    /// Which sample pixels may be copied: those the sample mask allows and, when inpainting,
    /// that are not to be filled (an atlas's mask says both). `None` when every pixel may be.
    pub fn copyable(&self) -> Option<SampleMask> {
        if self.atlas.is_some() {
            return self.sample_mask.cloned();
        }
        match (self.sample_mask, self.fill) {
            (None, None) => None,
            (Some(m), None) => Some(m.clone()),
            (None, Some(f)) => Some(f.known()),
            (Some(m), Some(f)) => {
                let known = f.known();
                Some(SampleMask::new(m.width, m.height, m.allowed.iter().zip(&known.allowed).map(|(a, b)| *a && *b).collect()))
            }
        }
    }
}

/// The `n`-th allowed position (row-major) of a `positions_x`-wide grid of flags.
pub fn nth_allowed(allowed: &[bool], positions_x: u32, n: u64) -> Option<(u32, u32)> {
    let i = allowed.iter().enumerate().filter(|(_, a)| **a).nth(n as usize)?.0 as u32;
    Some((i % positions_x, i / positions_x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask(rows: &[&str]) -> SampleMask {
        let allowed = rows.iter().flat_map(|r| r.chars().map(|c| c == '#')).collect();
        SampleMask::new(rows[0].len() as u32, rows.len() as u32, allowed)
    }

    #[test]
    fn luminance_guides_are_compared_as_local_brightness_and_given_guides_as_they_are() {
        use crate::image::RgbImage;
        // A checkerboard of 2-px squares, darker on the left half: its detail is finer than the
        // block's scale, its left-right shading is not.
        let sample = RgbImage::from_fn(64, 32, |x, y| {
            let base = if x < 32 { 70 } else { 170 };
            let g = if (x / 2 + y / 2) % 2 == 0 { base - 50 } else { base + 50 };
            [g as u8; 3]
        });
        let target = RgbImage::from_fn(48, 48, |x, _| [(x * 5) as u8; 3]);
        let guide = Guide::from_images(&target, &sample, 0.7, 3, true);
        let scaled = guide.at_block_scale(32);
        let plane = |img: &RgbImage| img.as_raw().chunks_exact(3).map(|p| f64::from(p[0])).collect::<Vec<_>>();
        let (m0, s0) = mean_and_spread(&plane(&guide.source));
        for img in [&scaled.source, &scaled.target] {
            let (m, s) = mean_and_spread(&plane(img));
            assert!((m - m0).abs() < 2.0 && (s - s0).abs() < 3.0, "mean and spread kept: {m:.1}/{s:.1} against {m0:.1}/{s0:.1}");
        }
        // The checks are gone from the source (neighbours within a few levels, not 100 apart),
        // its halves still apart; the target's ramp still rises.
        let px = |img: &RgbImage, x, y| i32::from(img.get(x, y)[0]);
        assert!((px(&scaled.source, 10, 10) - px(&scaled.source, 12, 10)).abs() < 10);
        assert!(px(&scaled.source, 56, 16) - px(&scaled.source, 8, 16) > 100);
        assert!(px(&scaled.target, 40, 20) > px(&scaled.target, 8, 20) + 100);
        assert_eq!(scaled.weight, 0.7);
        assert_eq!(scaled.passes, 3);
        // A source guide the job gave is the user's correspondence: left as it is.
        let given = Guide::from_images(&target, &sample, 0.7, 3, false);
        assert_eq!(given.at_block_scale(32), given);
        // Blocks too small for a blur: as they are.
        assert_eq!(guide.at_block_scale(3), guide);
    }

    #[test]
    fn a_later_pass_target_moves_a_quarter_of_the_way_to_the_previous_pass() {
        use crate::image::RgbImage;
        let sample = RgbImage::from_fn(64, 64, |x, y| [((x * 3 + y) % 200 + 20) as u8; 3]);
        // A flat target; the previous pass dark on its left, light on its right.
        let target = RgbImage::from_fn(48, 32, |_, _| [120; 3]);
        let previous = RgbImage::from_fn(48, 32, |x, _| [if x < 24 { 40 } else { 200 }; 3]);
        let guide = Guide::from_images(&target, &sample, 0.7, 3, true).at_block_scale(16);
        let after = guide.after_pass(&previous, &sample, 16);
        let before = Guide::from_images(&previous, &sample, 0.7, 1, true).at_block_scale(16).target;
        for (x, y) in [(2, 5), (20, 16), (24, 16), (45, 30)] {
            let (t, p) = (f64::from(guide.target.get(x, y)[0]), f64::from(before.get(x, y)[0]));
            assert_eq!(f64::from(after.target.get(x, y)[0]), (t + (p - t) * PREVIOUS_PASS_SHARE).round(), "at ({x}, {y})");
        }
        assert!(after.target.get(2, 16)[0] < guide.target.get(2, 16)[0], "darker where the previous pass was dark");
        assert!(after.target.get(45, 16)[0] > guide.target.get(45, 16)[0], "lighter where it was light");
        assert_eq!((&after.source, after.weight, after.passes, after.luminance), (&guide.source, 0.7, 3, true));
    }

    #[test]
    fn the_largest_known_rectangle_is_the_largest_one_with_no_pixel_to_fill() {
        // Brute force over every rectangle of small pseudo-random masks.
        let mut state = 12345u64;
        for _ in 0..40 {
            let (w, h) = (1 + (state % 9) as u32, 1 + (state / 9 % 7) as u32);
            let fill: Vec<bool> = (0..w * h)
                .map(|_| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    state >> 61 == 0
                })
                .collect();
            let region = FillRegion::new(w, h, fill);
            let mut best = 0;
            for y0 in 0..h {
                for x0 in 0..w {
                    for y1 in y0 + 1..=h {
                        for x1 in x0 + 1..=w {
                            if (y0..y1).all(|y| (x0..x1).all(|x| !region.fills(x, y))) {
                                best = best.max((x1 - x0) * (y1 - y0));
                            }
                        }
                    }
                }
            }
            match region.largest_known_rect() {
                Some((x, y, rw, rh)) => {
                    assert_eq!(rw * rh, best, "{w}x{h}");
                    assert!((y..y + rh).all(|yy| (x..x + rw).all(|xx| !region.fills(xx, yy))), "{w}x{h}: the rectangle holds no hole");
                }
                None => assert_eq!(best, 0),
            }
        }
    }
    #[test]
    fn a_block_position_is_allowed_only_when_every_pixel_is() {
        let m = mask(&["###.", "###.", "####", "#.##"]);
        assert_eq!(m.block_positions(2, 2), vec![true, true, false, true, true, false, false, false, true]);
        assert_eq!(m.block_positions(3, 3), vec![true, false, false, false]);
        assert!(m.block_positions(5, 1).is_empty());
        assert_eq!(m.largest_block(), 3);
        assert_eq!(m.allowed_pixels(), 13);
        assert_eq!(nth_allowed(&m.block_positions(2, 2), 3, 4), Some((2, 2)));
        assert_eq!(mask(&["..", ".."]).largest_block(), 0);
    }

    #[test]
    fn gray_levels_from_half_white_up_are_allowed() {
        let m = SampleMask::from_gray(3, 1, |x, _| [0, 127, 128][x as usize]);
        assert_eq!(m.allowed, vec![false, false, true]);
    }
}
