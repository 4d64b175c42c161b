//! Which methods fit a sample, and what to set when the defaults will not look right.
//!
//! Each paper claims good results "for a variety of textures"; in practice the tile methods
//! scramble structured samples, feathering ghosts strong edges and the near-regular methods need a
//! lattice. A user who keeps the defaults should hear that before reading the picture, so the
//! same analysis backs `texsyn advise SAMPLE` and the `warnings` of a run's jobs. It looks at three
//! things that are cheap to measure and explain: whether the sample has a lattice (the extraction
//! the near-regular methods use), how strongly its local orientations agree, and — failing both —
//! calls it stochastic, where every method is fine and nothing is said unless the sample's
//! features are large next to a tile (then the unaligned tiles repeat them as a patchwork).

use crate::image::RgbImage;
use crate::metrics::{MetricParams, centred_gray, orientation_acf};
use crate::synth::lattice::{self, Lattice, LatticeOptions};
use crate::synth::methods::default_overlap;
use crate::synth::methods::double_seam::DEFAULT_LEVEL_PENALTY;
use crate::synth::params::{ParamValue, Params};
use serde::Serialize;

/// Orientation coherence from which a sample without a lattice counts as oriented (see
/// [`orientation_coherence`]). Measured on the bundled samples and material sets: cork, grass,
/// gravel, hedge, plaster, pebbles, rock and weathered wood 0.01–0.11, where every method looks
/// right; cobblestones, a cracked stone wall, flagstones and wood grain 0.16–0.21, where tiles
/// cut at random places break the structure.
pub const ORIENTED_FROM: f64 = 0.14;

/// What kind of texture a sample is, for the methods' purposes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// A lattice of repeated texels (bricks, tiles, tread plate).
    NearRegular,
    /// No lattice, but strongly oriented structure (wood grain, fibres, slates).
    Oriented,
    /// Neither: grass, sand, gravel, plaster.
    Stochastic,
    /// Too small or uniform to say anything.
    Flat,
}

/// The description of a sample.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Analysis {
    pub width: u32,
    pub height: u32,
    pub kind: Kind,
    /// The lattice, if one was found.
    pub lattice: Option<Lattice>,
    /// Why no lattice was found (`None` when one was).
    pub no_lattice: Option<String>,
    /// Orientation coherence at 8–16 px: 0 (none) … 1 (one orientation everywhere).
    pub orientation: f64,
    /// With a lattice: how well the sample repeats along TES's rectangular grid ([`GridRepeat`]).
    pub grid_repeat: Option<GridRepeat>,
    /// With a lattice: how the sample repeats along `t1`, `t2`, `t1 + t2` and `t1 − t2` ([`VectorRepeat`]).
    pub along_vectors: Vec<VectorRepeat>,
    /// How far the mean tone of [`TONE_LINE`]-pixel lines varies, over how much the lines vary
    /// within themselves (the standard deviation of their means over their median standard
    /// deviation): what double-seam's Pearson correlations cannot see ([`TONE_SPREAD_FROM`]).
    pub tone_spread: f64,
    /// `(block, fraction)` for every even block side from 8 to half the sample's shorter side: the
    /// fraction of `block × block/6` overlap bands whose contrast is under [`FLAT_BAND_CONTRAST`] of
    /// the sample's ([`FLAT_BANDS_MAX`]). Left out of `advise --json` (a long table); the advice
    /// quotes the fraction at the job's block.
    #[serde(skip)]
    pub flat_bands: Vec<(i64, f64)>,
    /// `(side, share)` for box sides 4, 8, 16, 32 and 64 up to a quarter of the sample's shorter
    /// side: the share of the sample's colour variance left in the means of `side × side` windows,
    /// i.e. carried by features that large ([`LARGE_FEATURES_FROM`]).
    pub large_features: Vec<(i64, f64)>,
    /// How far apart two pixels must be before their gray levels stop looking alike: the smallest
    /// distance at which the gray autocorrelation, averaged over directions, falls under 1/2, in
    /// the sample's pixels ([`FEATURE_PER_BLOCK`]). A quarter of the analysed shorter side when it
    /// stays above 1/2 that far (a lower bound then); 0 for a flat sample.
    pub correlation_length: i64,
    /// With a lattice: how the sample's [`BLOTCH_SIDE`]-pixel window means repeat along `t1` and
    /// `t2` (the larger normalised correlation): whether its large features follow the lattice
    /// ([`BLOTCH_REPEAT`]).
    pub large_features_repeat: Option<f64>,
}

/// TES abuts the texel's bounding box on a rectangular grid, so its blocks join in phase only
/// where the sample repeats a box width across and a box height down as well as it repeats along
/// its lattice. Normalised correlations of the gray plane with itself shifted by those steps.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridRepeat {
    /// The texel's bounding box in pixels, `(width, height)`: TES's block.
    pub block: (i64, i64),
    /// The correlation a block width across, `(width, 0)`.
    pub across: f64,
    /// The correlation a block height down, `(0, height)`.
    pub down: f64,
    /// The weaker of the correlations at `t1` and `t2`.
    pub along_lattice: f64,
    /// How far the box steps miss the lattice: the larger distance, in pixels, from `(width, 0)`
    /// and `(0, height)` to their nearest lattice vectors.
    pub miss_px: f64,
}

/// TES's grid counts as out of phase when its box steps miss the lattice by more than
/// [`PHASE_TOLERANCE`] of the shorter lattice vector (as tiles do), or when the sample repeats a
/// box step less than this fraction of how well it repeats along its lattice. Seen at 384² from
/// 256²: TES dislocates rows on a weave (steps 12 px off a 48 px vector; correlation −0.51 against
/// 0.75), city bricks (32 px off a 71 px vector: bricks chopped), red bricks (12 px off 55 px) and
/// a staggered roof (3 px off, but 0.21 down against 0.56: its rows are sharp); it looks like its
/// samples where both hold (tread plate, tiles, terracotta, a clay roof, a brick road, a stone
/// wall, beige bricks: at most 0.15 of the vector off, correlation ratios 0.68–1.06).
pub const GRID_REPEAT_MIN: f64 = 0.5;

/// Box sides at which [`Analysis::large_features`] is measured.
const LARGE_FEATURE_SIDES: [usize; 5] = [4, 8, 16, 32, 64];

/// Tiles (Wang or RW, not aligned to a lattice) are cut from a few sample patches (two per edge
/// colour: 4 with `colors = 2`, up to 16 with the default, and with the default `interior` one of
/// its own inside each tile, whose seam with the edge band runs near the tile outline, which on
/// a 512² fill of mossy rock (issue #30) still shows the tile grid); where the sample's features are large
/// next to a tile, each patch carries a blotch of its own, every tile shows the blotches of its
/// patches at the same places on the tile grid, and the output becomes a regular patchwork of
/// them. More colours vary which blotches meet (the fill repeats less), not where they sit. The
/// threshold was judged with two colours and is kept for more: the grid of blotches stays. Measured as the colour-variance share left in the
/// means of windows a quarter of the tile wide ([`Analysis::large_features`]); seen at 384² from
/// 256², tile 64 (windows of 16): weathered wood 0.39, mossy stone 0.39, sand 0.38, gray and brown
/// rock 0.37 and 0.51, a mossy rock 0.34, rock 0.34 and ground 0.30 come out as a visible grid of
/// repeated blotches (quilting looks right); cork, grass, gravel, hedge, pebbles, plaster, dirt,
/// lava and a dirt-brick wall at most 0.27 look right (their repeats are fine-grained).
pub const LARGE_FEATURES_FROM: f64 = 0.285;

/// Patch sampling's swarm search (cpso, pso) on a stochastic sample whose windows half a block
/// across carry this share of its colour variance or more ([`Analysis::large_features`]) is told to
/// search exhaustively. Seen at 384² from 256², block 30 (windows of 16): paving stones 0.33
/// (joints fade to a few stubs; gray-histogram KL to the sample 0.16, exhaustive 0.05), a wall lit
/// from one side 0.84 (its dark half is gone; KL 3.1 against 0.26), mossy stone 0.39, weathered
/// wood 0.39 and brown rock 0.51 (washed out, KL 0.06–0.16 against 0.001–0.08): the exhaustive
/// search with `tolerance = 0` keeps them, at about twice the time. cork, grass, gravel, hedge,
/// pebbles and plaster, at most 0.16, look right with the swarm. As [`LARGE_FEATURES_FROM`], the
/// same measure's bound for tiles.
pub const SWARM_DRIFT_FROM: f64 = LARGE_FEATURES_FROM;

/// The window side at which a lattice sample's large features are checked against its lattice.
pub const BLOTCH_SIDE: usize = 16;

/// A lattice whose large features do not follow it: the lattice comes from fine structure (a
/// stone grain on a texture that was itself tiled) while blotches over it fall anywhere. Texels
/// and tiles cut on the lattice then cut the blotches at their edges. A sample counts as such
/// when [`BLOTCH_SIDE`]-px windows carry at least [`BLOTCH_SHARE`] of its colour variance and
/// their means repeat along neither lattice vector better than [`BLOTCH_REPEAT`]. Seen on a
/// purple stone (share 0.54, repeat 0.11 at 384² from 256²: TES, both tile methods and, faintly,
/// co-evolution cut its blotches at straight edges). Every other lattice sample either repeats its
/// window means along a lattice vector (terracotta 0.38 at share 0.46, red bricks 0.58 at 0.37)
/// or has smaller large features (a brick road 0.38 at repeat 0.09, which looks right).
pub const BLOTCH_SHARE: f64 = 0.45;
pub const BLOTCH_REPEAT: f64 = 0.2;

/// A block methods' block is too small for the sample's features when the sample's
/// [`Analysis::correlation_length`] is more than this fraction of it, and of the method's default
/// block: an upscaled or close-up photo, whose joints, stones or veins are as large as a block, so
/// each block holds a piece of one feature and the output strings pieces together instead of whole
/// features. The bundled samples and material albedos (256², as photographed or reduced) measure
/// 1–5 px (0.10 of the default 50-px block at most), the eighteen structured fixtures 1–14 px
/// except a wall lit from one side (52 px, its light falling off across the sample); the same
/// samples enlarged 4× measure 5–25 px, and the real photos at their own scale that issue 32
/// measured (bench pyramid, photos part) 20–70 px. Patch sampling's 30-px default block on a
/// brown rock of 8 px (0.27) looks right (tests/it/advice.rs), hence the bound just above.
pub const FEATURE_PER_BLOCK: f64 = 0.3;
/// The block that fits a sample's features: this many times its correlation length, the
/// smallest ratio seen to look right (patch sampling's 30-px block on the 8-px brown rock, 3.75×;
/// the default 50-px block is 10× or more on every bundled sample). Seen at 768² on weathered
/// wood enlarged 4× (26 px): blocks of 104 keep its cracks longer and its blotches whole, where
/// blocks of 50 mix them; 8× (208) looked no better. Not a rule for every photo: on a close-up of
/// leaf veins (1920×1200, 70 px, its broad light and dark bands carry the length) blocks of 50
/// already continue the veins, and blocks of 280 or 560 leave visible seams, so the warning says
/// what it measured and the user judges.
pub const BLOCK_PER_CORRELATION_LENGTH: i64 = 4;

/// [`Analysis::correlation_length`] of a centred gray plane.
fn correlation_length(gray: &[f64], w: usize, h: usize) -> i64 {
    let r = w.min(h) / 4;
    if r < 1 {
        return 0;
    }
    let Ok(acf) = crate::metrics::acf::autocorrelation(gray, w, h, r, r, crate::metrics::acf::AcfForm::OverlapMean) else {
        return 0;
    };
    // Ring sums by rounded distance, in a fixed order.
    let mut sums = vec![(0.0f64, 0u32); r + 1];
    let ri = r as i64;
    for dy in -ri..=ri {
        for dx in -ri..=ri {
            let d = ((dx * dx + dy * dy) as f64).sqrt().round() as usize;
            if d <= r {
                sums[d].0 += acf.get(dx, dy);
                sums[d].1 += 1;
            }
        }
    }
    sums.iter().enumerate().skip(1).find(|(_, (s, n))| *s < 0.5 * f64::from(*n)).map_or(ri, |(d, _)| d as i64)
}

/// [`Analysis::large_features`] at [`LARGE_FEATURE_SIDES`] up to a quarter of the shorter side
/// ([`RgbImage::large_feature_shares`]).
fn large_feature_shares(img: &RgbImage) -> Vec<(i64, f64)> {
    let quarter = img.width().min(img.height()) as usize / 4;
    let sides: Vec<usize> = LARGE_FEATURE_SIDES.into_iter().filter(|&s| s <= quarter).collect();
    img.large_feature_shares(&sides).into_iter().map(|(b, l)| (b as i64, l)).collect()
}

/// The normalised correlation of `plane` (`w × h`, row-major) with itself shifted by `(dx, dy)`,
/// over the pixels both cover; 0 when they cover none or one side is flat.
fn self_correlation(plane: &[f64], w: usize, h: usize, (dx, dy): (i64, i64)) -> f64 {
    let (adx, ady) = (dx.unsigned_abs() as usize, dy.unsigned_abs() as usize);
    if adx >= w || ady >= h {
        return 0.0;
    }
    let (ow, oh) = (w - adx, h - ady);
    let (ax, bx) = if dx >= 0 { (adx, 0) } else { (0, adx) };
    let (ay, by) = if dy >= 0 { (ady, 0) } else { (0, ady) };
    let n = (ow * oh) as f64;
    let (mut sa, mut sb) = (0.0, 0.0);
    for y in 0..oh {
        sa += plane[(y + ay) * w + ax..(y + ay) * w + ax + ow].iter().sum::<f64>();
        sb += plane[(y + by) * w + bx..(y + by) * w + bx + ow].iter().sum::<f64>();
    }
    let (ma, mb) = (sa / n, sb / n);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for y in 0..oh {
        let ra = &plane[(y + ay) * w + ax..(y + ay) * w + ax + ow];
        let rb = &plane[(y + by) * w + bx..(y + by) * w + bx + ow];
        for (&a, &b) in ra.iter().zip(rb) {
            let (a, b) = (a - ma, b - mb);
            ab += a * b;
            aa += a * a;
            bb += b * b;
        }
    }
    if aa <= 0.0 || bb <= 0.0 { 0.0 } else { ab / (aa * bb).sqrt() }
}

/// The seam length at which [`Analysis::tone_spread`] is measured: double-seam's default block.
pub const TONE_LINE: usize = 50;

/// Tone spread from which double-seam given the paper's `level_penalty = 0` is told to set it
/// (its default, [`DEFAULT_LEVEL_PENALTY`], weighs tone already). Its Pearson correlations
/// ignore a line's mean tone, so where tone varies between regions more than within lines, a block
/// of another tone passes as consistent and leaves a step. Seen at 384² from 256²: two-tone floor
/// tiles (1.32), large cream tiles (5.5), a wall lit from one side (2.95) and a framed tile grid
/// (1.63) come out with hard tone steps at block edges, and look right with a level penalty (10
/// then; the cream tiles and the lit wall checked again at the default 4);
/// every other bundled sample and fixture is at most 1.14 (terracotta, which looks right),
/// stochastic ones at most 0.82.
pub const TONE_SPREAD_FROM: f64 = 1.25;

/// An overlap band counts as flat when its gray standard deviation is below this fraction of the
/// whole sample's: it matches any other flat band, so it says nothing about what joins there.
pub const FLAT_BAND_CONTRAST: f64 = 0.15;

/// The fraction of flat overlap bands ([`Analysis::flat_bands`]) from which the patch methods are
/// told to use larger blocks, and the fraction the suggested block brings it to. Seen at 384² from
/// 256² with block 50: large floor tiles (0.21 flat), cream tiles (0.27) and a wire grid on black
/// (0.31) come out with merged tiles and bars that end in mid-air, as blocks inside one tile's plain
/// interior or in the black match anywhere; at the block that brings them to 0.1 they look right.
/// Every bundled sample and fixture is at most 0.15 (perspective bricks), stochastic ones 0.01.
pub const FLAT_BANDS_MAX: f64 = 0.2;
pub const FLAT_BANDS_OK: f64 = 0.1;

/// Windowed gray statistics from summed-area tables: what the patch methods' seams and overlap
/// bands see of the sample.
struct Contrast {
    w: usize,
    h: usize,
    /// Summed-area tables of gray and gray², `(w + 1) × (h + 1)`.
    sum: Vec<f64>,
    sq: Vec<f64>,
    /// The whole sample's gray standard deviation.
    spread: f64,
}

impl Contrast {
    /// Of the centred gray plane `gray` (`w × h`).
    fn of(gray: &[f64], w: usize, h: usize) -> Self {
        let (mut sum, mut sq) = (vec![0.0; (w + 1) * (h + 1)], vec![0.0; (w + 1) * (h + 1)]);
        for y in 0..h {
            let (mut row, mut row_sq) = (0.0, 0.0);
            for x in 0..w {
                let g = gray[y * w + x];
                row += g;
                row_sq += g * g;
                sum[(y + 1) * (w + 1) + x + 1] = sum[y * (w + 1) + x + 1] + row;
                sq[(y + 1) * (w + 1) + x + 1] = sq[y * (w + 1) + x + 1] + row_sq;
            }
        }
        let n = (w * h) as f64;
        let spread = (sq[(w + 1) * (h + 1) - 1] / n).max(0.0).sqrt();
        Contrast { w, h, sum, sq, spread }
    }

    /// Mean and standard deviation of the `bw × bh` window at `(x, y)`.
    fn window(&self, x: usize, y: usize, bw: usize, bh: usize) -> (f64, f64) {
        let at = |t: &[f64]| {
            let (a, b) = (y * (self.w + 1), (y + bh) * (self.w + 1));
            t[b + x + bw] - t[b + x] - t[a + x + bw] + t[a + x]
        };
        let n = (bw * bh) as f64;
        let mean = at(&self.sum) / n;
        (mean, (at(&self.sq) / n - mean * mean).max(0.0).sqrt())
    }

    /// The larger normalised correlation, along `t1` and `t2`, of the means of `side × side`
    /// windows inside the sample; `None` for a sample under twice that side.
    fn window_means_repeat(&self, side: usize, l: &Lattice) -> Option<f64> {
        if self.w < 2 * side || self.h < 2 * side {
            return None;
        }
        let (mw, mh) = (self.w - side + 1, self.h - side + 1);
        let means: Vec<f64> = (0..mh).flat_map(|y| (0..mw).map(move |x| (x, y))).map(|(x, y)| self.window(x, y, side, side).0).collect();
        Some(self_correlation(&means, mw, mh, l.t1).max(self_correlation(&means, mw, mh, l.t2)))
    }

    /// `len × thick` bands along rows and `thick × len` bands along columns, on a grid of about
    /// 64 positions across the bands and 32 along them (fixed, so the result is deterministic).
    fn bands(&self, len: usize, thick: usize) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        for (across, along, horizontal) in [(self.h, self.w, true), (self.w, self.h, false)] {
            if len > along || thick > across {
                continue;
            }
            let (step_across, step_along) = ((across / 64).max(1), (along / 32).max(1));
            for a in (0..=across - thick).step_by(step_across) {
                for b in (0..=along - len).step_by(step_along) {
                    out.push(if horizontal { self.window(b, a, len, thick) } else { self.window(a, b, thick, len) });
                }
            }
        }
        out
    }

    /// The spread of [`TONE_LINE`]-pixel lines' mean tones over their median standard deviation
    /// (floored at 1 % of the sample's, so a sample of flat lines does not divide by zero).
    fn tone_spread(&self) -> f64 {
        let lines = self.bands(TONE_LINE.min(self.w.min(self.h)), 1);
        if lines.is_empty() || self.spread <= 0.0 {
            return 0.0;
        }
        let n = lines.len() as f64;
        let mean = lines.iter().map(|l| l.0).sum::<f64>() / n;
        let tones = (lines.iter().map(|l| (l.0 - mean).powi(2)).sum::<f64>() / n).sqrt();
        let mut sd: Vec<f64> = lines.iter().map(|l| l.1).collect();
        sd.sort_by(f64::total_cmp);
        tones / sd[sd.len() / 2].max(0.01 * self.spread)
    }

    /// For every even block side from 8 to half the sample's shorter side: the fraction of its
    /// overlap bands (block × the default overlap of block / 6) without contrast.
    fn flat_bands(&self) -> Vec<(i64, f64)> {
        let room = self.w.min(self.h) / 2;
        (8..=room)
            .step_by(2)
            .map(|block| {
                let bands = self.bands(block, (default_overlap(block as i64) as usize).max(2));
                let flat = bands.iter().filter(|b| b.1 < FLAT_BAND_CONTRAST * self.spread).count();
                (block as i64, flat as f64 / bands.len().max(1) as f64)
            })
            .collect()
    }
}

/// [`GridRepeat`] of a sample on its lattice.
fn grid_repeat(gray: &[f64], w: usize, h: usize, l: &Lattice) -> GridRepeat {
    use crate::synth::methods::near_regular::grid::Geometry;
    use crate::synth::methods::tiles::align::{Alignment, residual_px};
    let (x0, x1, y0, y1) = Geometry::new(l.t1, l.t2).bbox;
    let block = (x1 - x0 + 1, y1 - y0 + 1);
    let at = |v| self_correlation(gray, w, h, v);
    let miss_px = Alignment::new(l.t1, l.t2, "extracted").map_or(f64::INFINITY, |al| residual_px(&al, [(block.0, 0), (0, block.1)]));
    GridRepeat { block, across: at((block.0, 0)), down: at((0, block.1)), along_lattice: at(l.t1).min(at(l.t2)), miss_px }
}

/// A lattice vector along which the gray plane repeats ([`RIDGE_REPEATS`]) while the edges that
/// cross it do not ([`RIDGE_CROSSING`]) is no period: the sample is uniform along it (courses of
/// a wall, planks, columns of bricks), and the joints across it (blocks, planks and bricks of
/// random lengths) fall anywhere. The lattice extraction still finds a peak on such a ridge of the
/// autocorrelation, or a lattice with a short vector along it, and texels or tiles cut on it chop
/// the rows. Seen at 384² from 256²: a sandstone wall of random-length blocks (gray 0.77 along
/// (48, 0), crossing edges 0.09), wooden planks (0.54 along (4, 117), −0.01), the bundled gray
/// bricks standing in tilted columns (0.57 along t1 − t2 = (2, −48), 0.01) and a grey block wall
/// (0.77, 0.10): coevolution, TES and both tile methods break courses and columns, chop planks and
/// end mortar lines in mid-air; quilting looks right. Every other lattice vector among the bundled
/// samples, fixtures and held-out textures has crossing edges of at least 0.16 wherever gray
/// repeats at 0.5 or more (red bricks along a course, (80, 0): 0.52 / 0.16), and is at most 0.40
/// in gray where its crossing edges are under 0.12 (a clay roof, a stone wall, a brick road).
pub const RIDGE_REPEATS: f64 = 0.5;
pub const RIDGE_CROSSING: f64 = 0.12;

/// How the sample repeats along one lattice vector.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VectorRepeat {
    pub vector: (i64, i64),
    /// The gray plane's normalised correlation with itself shifted by the vector, or by a quarter,
    /// half or three quarters of it, whichever is highest: how uniform the sample is that way.
    pub gray: f64,
    /// The same for the magnitude of the gray gradient along the vector (the edges that cross
    /// it), at the best of the vector and its eight neighbours (lattice vectors are rounded).
    pub crossing_edges: f64,
}

impl VectorRepeat {
    fn is_ridge(&self) -> bool {
        self.gray >= RIDGE_REPEATS && self.crossing_edges < RIDGE_CROSSING
    }
}

/// [`VectorRepeat`] of `t1`, `t2`, `t1 + t2` and `t1 − t2` on the centred gray plane: the ridge can
/// lie along a diagonal of the cell (columns of vertical bricks on a lattice of half-brick steps).
fn vector_repeats(gray: &[f64], w: usize, h: usize, l: &Lattice) -> Vec<VectorRepeat> {
    // A [1 2 1]/4 blur each way keeps single-pixel noise out of the gradient; central differences
    // then give the gradient, both clamped at the border.
    let at = |p: &[f64], x: isize, y: isize| p[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize];
    let blur = |p: &[f64], (dx, dy): (isize, isize)| -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                (at(p, x - dx, y - dy) + 2.0 * at(p, x, y) + at(p, x + dx, y + dy)) / 4.0
            })
            .collect()
    };
    let smooth = blur(&blur(gray, (1, 0)), (0, 1));
    let diff = |(dx, dy): (isize, isize)| -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                (at(&smooth, x + dx, y + dy) - at(&smooth, x - dx, y - dy)) / 2.0
            })
            .collect()
    };
    let (gx, gy) = (diff((1, 0)), diff((0, 1)));
    let (sum, difference) = ((l.t1.0 + l.t2.0, l.t1.1 + l.t2.1), (l.t1.0 - l.t2.0, l.t1.1 - l.t2.1));
    [l.t1, l.t2, sum, difference]
        .into_iter()
        .map(|t| {
            let n = vector_length(t);
            let (ux, uy) = (t.0 as f64 / n, t.1 as f64 / n);
            let crossing: Vec<f64> = gx.iter().zip(&gy).map(|(&x, &y)| (x * ux + y * uy).abs()).collect();
            let crossing_edges = (-1..=1)
                .flat_map(|j| (-1..=1).map(move |i| (t.0 + i, t.1 + j)))
                .map(|v| self_correlation(&crossing, w, h, v))
                .fold(f64::NEG_INFINITY, f64::max);
            // A quarter of the way is enough where the vector leans off the ridge (planks at
            // (4, 117): 0.54 at (1, 29), 0.14 at the vector itself).
            let gray = (1..=4)
                .map(|k| self_correlation(gray, w, h, (((k * t.0) as f64 / 4.0).round() as i64, ((k * t.1) as f64 / 4.0).round() as i64)))
                .fold(f64::NEG_INFINITY, f64::max);
            VectorRepeat { vector: t, gray, crossing_edges }
        })
        .collect()
}

impl Analysis {
    /// One line: `near-regular: lattice t1 = (32, 0), t2 = (16, 24) …`.
    pub fn describe(&self) -> String {
        match (self.kind, &self.lattice) {
            (Kind::Flat, _) => "nothing to analyse: the sample is too small or has no contrast".into(),
            (_, Some(l)) => format!(
                "near-regular: lattice t1 = ({}, {}), t2 = ({}, {}) (texel {} px², explains {} of {} autocorrelation peaks); \
                 orientation coherence {:.3}",
                l.t1.0,
                l.t1.1,
                l.t2.0,
                l.t2.1,
                l.determinant(),
                l.explained,
                l.candidates,
                self.orientation
            ),
            (Kind::Oriented, None) => format!("oriented, no lattice: orientation coherence {:.3} (≥ {ORIENTED_FROM})", self.orientation),
            _ => format!("stochastic: no lattice and orientation coherence {:.3} (< {ORIENTED_FROM})", self.orientation),
        }
    }

    /// The length of the shorter lattice vector, in pixels.
    pub fn shortest_vector(&self) -> Option<f64> {
        let l = self.lattice.as_ref()?;
        Some(vector_length(l.t1).min(vector_length(l.t2)))
    }

    /// The view the lattice was found in when the gray plane showed none, if the sample is also
    /// strongly oriented: such a lattice is weak (on irregular stone-block walls it is a grid that
    /// does not follow the joints), and the oriented structure is what tiles and texels break.
    pub fn weak_lattice_on_oriented(&self) -> Option<&'static str> {
        self.lattice.as_ref().and_then(|l| l.found_in).filter(|_| self.orientation >= ORIENTED_FROM)
    }

    /// A lattice vector that is a ridge rather than a period ([`RIDGE_REPEATS`]).
    pub fn ridge(&self) -> Option<&VectorRepeat> {
        self.along_vectors.iter().find(|v| v.is_ridge())
    }

    /// The fraction of flat overlap bands at `block` (at the nearest even side below it, within
    /// the table); `None` for a sample too small for blocks of 8.
    pub fn flat_bands_at(&self, block: i64) -> Option<f64> {
        self.flat_bands.iter().take_while(|e| e.0 <= block.max(8)).last().map(|e| e.1)
    }

    /// The smallest block above `block` whose overlap bands are at most [`FLAT_BANDS_OK`] flat,
    /// or the largest the sample allows (half its shorter side).
    pub fn block_with_contrast(&self, block: i64) -> Option<i64> {
        let last = self.flat_bands.last()?.0;
        Some(self.flat_bands.iter().find(|e| e.0 > block && e.1 <= FLAT_BANDS_OK).map_or(last, |e| e.0))
    }

    /// [`Analysis::large_features`] at the largest measured side up to `side`.
    pub fn large_features_at(&self, side: i64) -> Option<f64> {
        self.large_features.iter().take_while(|e| e.0 <= side).last().map(|e| e.1)
    }

    /// [`Analysis::large_features`] at the measured side nearest `side` (by ratio, ties to the
    /// larger), with that side.
    pub fn large_features_near(&self, side: i64) -> Option<(i64, f64)> {
        let off = |s: i64| (s as f64 / side.max(1) as f64).ln().abs();
        self.large_features.iter().copied().min_by(|a, b| off(a.0).total_cmp(&off(b.0)).then(b.0.cmp(&a.0)))
    }

    /// Large features that do not follow the lattice ([`BLOTCH_SHARE`]): the share they carry.
    pub fn blotches_off_lattice(&self) -> Option<f64> {
        let share = self.large_features_at(BLOTCH_SIDE as i64)?;
        (share >= BLOTCH_SHARE && self.large_features_repeat? < BLOTCH_REPEAT).then_some(share)
    }

    /// The length of the longer lattice vector, in pixels.
    pub fn longest_vector(&self) -> Option<f64> {
        let l = self.lattice.as_ref()?;
        Some(vector_length(l.t1).max(vector_length(l.t2)))
    }
}

fn vector_length(v: (i64, i64)) -> f64 {
    ((v.0 * v.0 + v.1 * v.1) as f64).sqrt()
}

/// How far local orientations agree with themselves 8 to 16 pixels away: the largest value of
/// the orientation autocorrelation (the metrics' `A_v`) on that ring. Long edges, cracks, grain
/// and stone outlines keep it high; grass, gravel and plaster lose it within a few pixels, and so
/// do pebbles, whose outlines are short and point every way.
fn orientation_coherence(img: &RgbImage) -> f64 {
    let Some(acf) = orientation_acf(img, &MetricParams::default()) else { return 0.0 };
    let r = acf.rx().min(acf.ry()) as i64;
    let (inner, outer) = (8.0f64.min(r as f64 / 2.0), 16.0f64.min(r as f64));
    let mut best = 0.0f64;
    for dy in -r..=r {
        for dx in -r..=r {
            let d = ((dx * dx + dy * dy) as f64).sqrt();
            if d >= inner && d <= outer {
                best = best.max(acf.get(dx, dy));
            }
        }
    }
    best
}

/// Analyses a sample (8-bit view, as the methods' searches see it).
/// Samples of more pixels than this (1024²) are analysed on a reduced copy: a camera photo's
/// analysis at full resolution took about 7 s and 1.2 GB at 12 MP (FFTs of the gray plane,
/// summed-area tables), more than its synthesis with the coarse-to-fine search, and outside the
/// memory model. Bundled samples (at most 256²) are analysed as they are.
pub const ANALYSIS_PIXELS: u64 = 1024 * 1024;

/// What a sample is ([`Analysis`]). A sample of more than [`ANALYSIS_PIXELS`] is first halved
/// (2×2 means, as the coarse-to-fine search's pyramid, an odd last row or column dropped) until it
/// has at most that many; lengths found on the reduced copy (lattice vectors, blocks, window sides)
/// are scaled back to the sample's pixels, so the advice speaks of the sample as given.
/// Deterministic: the reduction depends on the pixels only. Measures of features smaller than the
/// reduction (window sides under 4 reduced pixels) are not available then.
pub fn analyse(img: &RgbImage) -> Analysis {
    let (_, halvings) = analysed_size(img.dimensions());
    if halvings == 0 {
        return analyse_as_is(img);
    }
    let mut small = crate::synth::primitives::pyramid_search::reduce(img);
    for _ in 1..halvings {
        small = crate::synth::primitives::pyramid_search::reduce(&small);
    }
    let a = analyse_as_is(&small);
    drop(small);
    scaled(a, 1 << halvings, img.dimensions())
}

/// The size a sample of `size` is analysed at, and how many times it is halved to get there.
fn analysed_size((mut w, mut h): (u32, u32)) -> ((u32, u32), u32) {
    let mut halvings = 0;
    while u64::from(w) * u64::from(h) > ANALYSIS_PIXELS && w >= 16 && h >= 16 {
        (w, h, halvings) = (w / 2, h / 2, halvings + 1);
    }
    ((w, h), halvings)
}

/// The peak memory of [`analyse`] on a sample of `size`, beside the sample itself: the reduced
/// copies (the last halving holds its input and its output), the centred gray plane and the
/// lattice extraction ([`lattice::peak_memory`]), its largest phase (the orientation field, the
/// contrast tables and the ridge test's planes, each a few planes of the analysed size, come and go
/// before or after it). The memory model counts it as a phase of every job, which the plan
/// analyses; at 12 MP (analysed at 1000 × 750) about 140 MB.
pub fn peak_memory(size: (u32, u32)) -> u64 {
    let ((w, h), halvings) = analysed_size(size);
    let px = u64::from(w) * u64::from(h);
    let reduced = if halvings > 0 { 3 * px + 3 * 4 * px } else { 0 };
    reduced + 8 * px + lattice::peak_memory(w as usize, h as usize)
}

/// An analysis of a copy reduced `f` times, in the pixels of the `(width, height)` sample.
fn scaled(a: Analysis, f: i64, (width, height): (u32, u32)) -> Analysis {
    let v = |(x, y): (i64, i64)| (x * f, y * f);
    Analysis {
        width,
        height,
        lattice: a.lattice.map(|l| Lattice { t1: v(l.t1), t2: v(l.t2), fine: l.fine.scaled(f as f64), ..l }),
        grid_repeat: a.grid_repeat.map(|g| GridRepeat { block: v(g.block), miss_px: g.miss_px * f as f64, ..g }),
        along_vectors: a.along_vectors.into_iter().map(|r| VectorRepeat { vector: v(r.vector), ..r }).collect(),
        flat_bands: a.flat_bands.into_iter().map(|(b, s)| (b * f, s)).collect(),
        large_features: a.large_features.into_iter().map(|(b, s)| (b * f, s)).collect(),
        correlation_length: a.correlation_length * f,
        ..a
    }
}

/// [`analyse`] at the sample's own resolution.
fn analyse_as_is(img: &RgbImage) -> Analysis {
    let (width, height) = img.dimensions();
    let flat = |why: &str| Analysis {
        width,
        height,
        kind: Kind::Flat,
        lattice: None,
        no_lattice: Some(why.into()),
        orientation: 0.0,
        grid_repeat: None,
        along_vectors: Vec::new(),
        tone_spread: 0.0,
        flat_bands: Vec::new(),
        large_features: Vec::new(),
        correlation_length: 0,
        large_features_repeat: None,
    };
    if width < 8 || height < 8 {
        return flat("the sample is smaller than 8 × 8 pixels");
    }
    let first = img.get(0, 0);
    if img.as_raw().chunks_exact(3).all(|p| p == first) {
        return flat("the sample is one flat colour");
    }
    let orientation = orientation_coherence(img);
    let (w, h) = (width as usize, height as usize);
    let gray = centred_gray(img);
    let (lattice, no_lattice) = match lattice::extract_centred(&gray, w, h, &LatticeOptions::default()) {
        Ok(l) => (Some(l), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let kind = if lattice.is_some() {
        Kind::NearRegular
    } else if orientation >= ORIENTED_FROM {
        Kind::Oriented
    } else {
        Kind::Stochastic
    };
    let grid_repeat = lattice.as_ref().map(|l| grid_repeat(&gray, w, h, l));
    let along_vectors = lattice.as_ref().map_or_else(Vec::new, |l| vector_repeats(&gray, w, h, l));
    let contrast = Contrast::of(&gray, w, h);
    Analysis {
        width,
        height,
        kind,
        no_lattice,
        orientation,
        grid_repeat,
        along_vectors,
        tone_spread: contrast.tone_spread(),
        flat_bands: contrast.flat_bands(),
        large_features: large_feature_shares(img),
        correlation_length: correlation_length(&gray, w, h),
        large_features_repeat: lattice.as_ref().and_then(|l| contrast.window_means_repeat(BLOTCH_SIDE, l)),
        lattice,
    }
}

/// Aligned tiles look right only when the tiles' translation vectors are (nearly) lattice
/// vectors: a phase residual above this fraction of the shorter lattice vector cuts texels apart.
pub const PHASE_TOLERANCE: f64 = crate::synth::methods::tiles::align::PHASE_TOLERANCE;

/// Texels (lattice cells, by area) a tile must hold for an aligned tiling to keep the sample's
/// variety. Seen at 384² from 256²: tiles of about one texel repeat a few texels in a regular
/// pattern (a slate roof, terracotta and red bricks whose texels differ in tone, split along the
/// tiles' cuts); from about two texels on (terracotta and red bricks with rw-tiles, tread plate,
/// a brick road) they look right.
pub const MIN_TEXELS_PER_TILE: f64 = 1.5;

/// Quilting needs a block of at least 1/this of the shorter lattice vector. Seen at 384² from 256²
/// with the default block of 50: terracotta floor tiles (84 px, 1.68 blocks) lose their grout
/// (blocks inside one tile's plain interior match anywhere; tiles merge), right at block 90; city
/// bricks (1.42), beige bricks (1.28), red bricks (1.10) and a stone wall (1.06) look right.
pub const QUILTING_TEXEL_PER_BLOCK: f64 = 1.5;

/// A tile job's phase on the sample's lattice ([`tile_phase`]).
struct TilePhase {
    /// The tile size the job uses: its `tile`, or what `tile = "auto"` chooses on this sample.
    tile: i64,
    /// Whether `tile` is `auto`'s choice.
    auto: bool,
    /// The phase residual at `tile`, in pixels.
    now: f64,
    /// The tile size (that fits the sample) with the smallest residual, and that residual.
    best: (i64, f64),
    /// What `tile = "auto"` chooses on this sample, when it finds a size in phase.
    auto_pick: Option<i64>,
    /// How many texels one tile holds (its area over the lattice cell's).
    texels: f64,
}

/// For a tile method with alignment on (`auto` or `lattice`) and the sample's lattice: the tile
/// size the job uses (`tile = "auto"` resolved as the method resolves it), its phase residual,
/// and the tile size (that fits the sample) with the smallest.
fn tile_phase(a: &Analysis, method: &str, p: &Params) -> Option<TilePhase> {
    use crate::synth::methods::tiles::{align, rw_tiles::RwAlign, wang_tiles::WangAlign};
    let l = a.lattice.as_ref()?;
    let overlap = int(p, "overlap")?;
    let al = align::Alignment::new(l.t1, l.t2, "extracted").ok()?;
    let side = i64::from(a.width.min(a.height));
    let wang = method == "wang-tiles";
    let (sample, ov) = ((a.width, a.height), u32::try_from(overlap).ok()?);
    let auto =
        if wang { WangAlign::auto_tile(Some(&al), sample, ov, None, None) } else { RwAlign::auto_tile(Some(&al), sample, ov, None, None) };
    // `auto` records a residual only when it found a size in phase.
    let auto_pick = auto.record.get("residual_px").map(|_| auto.tile);
    let (tile, auto) = match (int(p, "tile"), word(p, "tile")) {
        (Some(t), _) => (t, false),
        (None, Some(align::AUTO_TILE)) => (auto.tile, true),
        _ => return None,
    };
    let (vectors, sizes): (fn(i64) -> [align::V; 2], Vec<i64>) = if wang {
        (WangAlign::vectors, (8.max(2 * overlap)..=side - overlap).filter(|t| t % 2 == 0).collect())
    } else {
        (RwAlign::vectors, (8.max(2 * overlap + 4)..=2 * (side - overlap)).filter(|t| t % 2 == 0).collect())
    };
    let now = align::residual_px(&al, vectors(tile));
    let best = *align::suggest(&al, sizes.into_iter(), vectors, tile, 1).first()?;
    let [u, v] = vectors(tile);
    let texels = ((u.0 * v.1 - u.1 * v.0).abs() as f64) / l.determinant().abs().max(1) as f64;
    Some(TilePhase { tile, auto, now, best, auto_pick, texels })
}

/// A method's fit to a sample.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "verdict", rename_all = "kebab-case")]
pub enum Fit {
    Fits,
    /// Fits once these parameters are set (`("align", "lattice")`), because…
    FitsWith {
        set: Vec<(String, String)>,
        because: String,
    },
    /// Not for this sample, because…; use this method instead.
    NotFor {
        because: String,
        instead: &'static str,
    },
}

/// The method's default `block`, if it has one.
fn default_block(method: &str) -> Option<i64> {
    let spec = crate::synth::methods::find(method)?.params().iter().find(|s| s.name == "block")?;
    match spec.default {
        crate::synth::params::Default::Int(v) => Some(v),
        _ => None,
    }
}

fn int(p: &Params, name: &str) -> Option<i64> {
    match p.get(name)? {
        ParamValue::Int(v) => Some(*v),
        _ => None,
    }
}

fn word<'p>(p: &'p Params, name: &str) -> Option<&'p str> {
    match p.get(name)? {
        ParamValue::Str(s) => Some(s),
        _ => None,
    }
}

/// Whether the job gave its own lattice (`t1_x` … `t2_y`): then extraction is not needed.
fn lattice_given(p: &Params) -> bool {
    ["t1_x", "t1_y", "t2_x", "t2_y"].iter().any(|k| int(p, k).is_some_and(|v| v != 0))
}

/// How `method` with these (resolved) parameters fits the analysed sample.
pub fn fit(a: &Analysis, method: &str, p: &Params) -> Fit {
    if a.kind == Kind::Flat {
        return Fit::Fits;
    }
    match method {
        "quilting" | "double-seam" | "patch-sampling" => {
            let mut set = Vec::new();
            let mut why: Vec<String> = Vec::new();
            // Feathering ghosts long coherent edges (bricks' mortar, grain, cracks); on studs,
            // tiles of low coherence and stochastic samples it looks right.
            if method == "patch-sampling" && a.orientation >= ORIENTED_FROM && word(p, "blend") == Some("feather") {
                set.push(("blend".to_string(), "cut".to_string()));
                why.push("feathering blends misaligned edges of a structured sample into ghosts".into());
            }
            // The swarm misses the exact continuations of the neighbouring patches on a lattice
            // (rows of a roof or a wall drift); scoring them keeps the rows.
            if method == "patch-sampling" && a.kind == Kind::NearRegular && p.get("continuations") == Some(&ParamValue::Bool(false)) {
                set.push(("continuations".to_string(), "true".to_string()));
                why.push("the swarm misses the exact continuations of neighbouring patches on a lattice, so rows drift".into());
            }
            // A swarm finds the broad basins of a sample's plain areas (where many positions match
            // roughly) and misses the narrow matches that continue its joints and edges; where large
            // features carry much of the sample, the output drifts into the plain areas. An
            // exhaustive search takes the best match wherever it lies ([`SWARM_DRIFT_FROM`]).
            if method == "patch-sampling"
                && a.kind == Kind::Stochastic
                && matches!(word(p, "search"), Some("cpso" | "pso"))
                && let Some(block) = int(p, "block")
                && let Some((side, share)) = a.large_features_near(block / 2).filter(|&(_, s)| s >= SWARM_DRIFT_FROM)
            {
                set.push(("search".to_string(), "exhaustive".to_string()));
                set.push(("tolerance".to_string(), "0".to_string()));
                why.push(format!(
                    "{:.0} % of the sample's colour variance is in features {side} px and more across: the swarm settles where \
                     plain areas match many positions roughly and misses the narrow matches that continue joints and edges, so \
                     the output drifts into the plain areas (joints fade, tones go missing)",
                    100.0 * share
                ));
            }
            // Pearson correlations ignore a line's mean tone: where tone varies between regions
            // more than within lines, blocks of another tone pass as consistent.
            if method == "double-seam" && a.tone_spread >= TONE_SPREAD_FROM && p.float("level_penalty").ok() == Some(0.0) {
                set.push(("level_penalty".to_string(), DEFAULT_LEVEL_PENALTY.to_string()));
                why.push(format!(
                    "its correlations ignore brightness, and the mean tone of this sample's {TONE_LINE}-px lines varies {:.1}× as \
                     much as the lines themselves, so blocks of another tone pass as consistent and leave steps",
                    a.tone_spread
                ));
            }
            if method == "double-seam"
                && let Some((aux, better)) = aux_line_in_phase(a, p)
            {
                set.push(("aux_dist".to_string(), better.to_string()));
                why.push(format!(
                    "its auxiliary seam line, {aux} px from the true one, is a lattice translate of it (the sample repeats every \
                     few pixels), so both lines can lie on the same bar and miss the other direction's phase"
                ));
            }
            let mut wanted_block = None;
            if let Some(block) = int(p, "block") {
                // Double-seam (which judges a block by two seam lines) and patch sampling (a swarm
                // search, then a feathered zone) keep whole texels only when a block holds one.
                // Quilting's exhaustive overlap search finds in-phase continuations with blocks a
                // little smaller than the texel, but not with much smaller ones (QUILTING_TEXEL_PER_BLOCK).
                // A lattice of fine grain under blotches that ignore it says nothing of the texel.
                if let Some(texel) = a.longest_vector().filter(|_| a.blotches_off_lattice().is_none()) {
                    let shortest = a.shortest_vector().unwrap_or(texel);
                    let room = i64::from(a.width.min(a.height)) / 2;
                    let wanted = ((texel.ceil() as i64 + 1) / 2 * 2).min(room);
                    let quilting = method == "quilting";
                    let too_small = if quilting { shortest > QUILTING_TEXEL_PER_BLOCK * block as f64 } else { (block as f64) < shortest };
                    if too_small && wanted > block {
                        wanted_block = Some(wanted);
                        why.push(if quilting {
                            format!(
                                "blocks of {block} px are under two thirds of the sample's texel (lattice vectors of {shortest:.0} and \
                                 {texel:.0} px): they fit inside one texel's plain interior, where any overlap matches, and the joints \
                                 between texels go missing"
                            )
                        } else {
                            format!(
                                "blocks of {block} px are smaller than the sample's texel (lattice vectors of {shortest:.0} and {texel:.0} \
                                 px), so they join pieces of texels out of phase"
                            )
                        });
                    }
                }
                // Overlaps (or seam lines) inside flat areas match any other flat area, so tiles
                // merge and edges end in mid-air; larger blocks reach the structure.
                if let (Some(flat), Some(wanted)) = (a.flat_bands_at(block), a.block_with_contrast(block))
                    && flat >= FLAT_BANDS_MAX
                    && wanted > block
                {
                    wanted_block = Some(wanted_block.unwrap_or(0).max(wanted));
                    why.push(format!(
                        "{:.0} % of this sample's {block}-px overlap bands have almost no contrast, and overlaps inside flat areas \
                         match anywhere, so shapes merge and edges end in mid-air",
                        100.0 * flat
                    ));
                }
            }
            // Features as large as a block: each block holds a piece of one, and the output strings
            // pieces together (FEATURE_PER_BLOCK). Said only where the sample holds the block that
            // fits; a sample whose features are as large as itself has no block to offer.
            if let Some(block) = int(p, "block")
                && let Some(default) = default_block(method)
                && a.correlation_length as f64 > FEATURE_PER_BLOCK * block.max(default) as f64
                && let fits = BLOCK_PER_CORRELATION_LENGTH * a.correlation_length
                && fits <= i64::from(a.width.min(a.height)) / 2
            {
                wanted_block = Some(wanted_block.unwrap_or(0).max(fits));
                why.push(format!(
                    "the sample's features are large for {block}-px blocks (an upscaled or close-up photo?): its gray levels stay \
                     alike over {} px (autocorrelation above 1/2), so each block holds a piece of one feature and the output strings \
                     pieces together instead of whole features; blocks of {fits} px ({BLOCK_PER_CORRELATION_LENGTH} × that) hold \
                     them (or reduce the sample; smooth shading alone needs no larger block)",
                    a.correlation_length
                ));
            }
            if let Some(b) = wanted_block {
                set.push(("block".to_string(), b.to_string()));
            }
            if set.is_empty() { Fit::Fits } else { Fit::FitsWith { set, because: why.join("; ") } }
        }
        "coevolution" | "tes" => {
            let shortest = a.shortest_vector().unwrap_or(f64::INFINITY);
            let out_of_phase = a
                .grid_repeat
                .as_ref()
                .filter(|g| g.miss_px > PHASE_TOLERANCE * shortest || g.across.min(g.down) < GRID_REPEAT_MIN * g.along_lattice);
            if let (Some(view), false) = (a.weak_lattice_on_oriented(), lattice_given(p)) {
                Fit::NotFor {
                    because: format!(
                        "its lattice was found only in the sample's {view}, not in its gray levels, and the sample is strongly \
                         oriented (coherence {:.3}): texels cut on that lattice will not line up",
                        a.orientation
                    ),
                    instead: "quilting",
                }
            } else if let (Some(r), false) = (a.ridge(), lattice_given(p)) {
                Fit::NotFor { because: ridge_reason(r, "texels cut on that lattice"), instead: "quilting" }
            } else if let (Some(share), false) = (a.blotches_off_lattice(), lattice_given(p)) {
                Fit::NotFor { because: blotch_reason(share, "texels"), instead: "quilting" }
            } else if let (Some(g), "tes", false) = (out_of_phase, method, lattice_given(p)) {
                let (step, name, r) = if g.across <= g.down { (g.block.0, "across", g.across) } else { (g.block.1, "down", g.down) };
                let why = if g.miss_px > PHASE_TOLERANCE * shortest {
                    format!("its steps miss the sample's lattice by {:.1} px", g.miss_px)
                } else {
                    format!(
                        "this sample does not repeat along that grid: its correlation {step} px {name} is {r:.2}, against {:.2} \
                         along its lattice",
                        g.along_lattice
                    )
                };
                Fit::NotFor {
                    because: format!(
                        "TES abuts the texel's {}×{} px bounding boxes on a rectangular grid, and {why}, so blocks join out of \
                         phase and rows break",
                        g.block.0, g.block.1
                    ),
                    instead: "coevolution",
                }
            } else if a.lattice.is_some() || lattice_given(p) {
                Fit::Fits
            } else {
                Fit::NotFor {
                    because: format!(
                        "it needs a lattice of repeated texels and none was found ({})",
                        a.no_lattice.as_deref().unwrap_or("no lattice")
                    ),
                    instead: "quilting",
                }
            }
        }
        "wang-tiles" | "rw-tiles" => with_tone_candidates(
            a,
            p,
            match a.kind {
                _ if let Some(view) = a.weak_lattice_on_oriented() => Fit::NotFor {
                    because: format!(
                        "its lattice was found only in the sample's {view}, and tiles cut on a weak lattice break the sample's oriented \
                     structure at every tile edge"
                    ),
                    instead: "quilting",
                },
                _ if let Some(r) = a.ridge().filter(|_| !lattice_given(p)) => {
                    Fit::NotFor { because: ridge_reason(r, "tiles cut on it, aligned or not,"), instead: "quilting" }
                }
                _ if let Some(share) = a.blotches_off_lattice().filter(|_| !lattice_given(p)) => {
                    Fit::NotFor { because: blotch_reason(share, "tiles"), instead: "quilting" }
                }
                Kind::NearRegular if word(p, "align") == Some("none") => Fit::FitsWith {
                    set: vec![("align".into(), "lattice".into())],
                    because: "tiles cut at random positions scramble the texels of a lattice; aligned tiles keep them in phase".into(),
                },
                // `tile = "auto"` (the default) picks an in-phase size when one fits the sample with a
                // lattice cell to spare: then nothing is said. A given size out of phase, or `auto`
                // finding none and keeping 64, is warned about, naming the size that misses least.
                Kind::NearRegular => match tile_phase(a, method, p) {
                    Some(ph) if ph.now > PHASE_TOLERANCE * a.shortest_vector().unwrap_or(f64::INFINITY) => {
                        let (tile, now, (best, best_residual)) = (ph.tile, ph.now, ph.best);
                        let at = if ph.auto {
                            format!(
                                "no tile size that leaves a lattice cell to spare in the sample is in phase with its lattice, so tile = \"auto\" \
                             keeps {tile}, whose translations miss the lattice by {now:.1} px"
                            )
                        } else {
                            format!("at tile {tile} the tiles' translations miss the sample's lattice by {now:.1} px")
                        };
                        let or_auto = match ph.auto_pick {
                            Some(t) if !ph.auto => format!(" (leaving tile out, its default \"auto\" picks {t} here)"),
                            _ => String::new(),
                        };
                        // No size that fits the sample is in phase either: suggesting the one
                        // that misses least would send the user to another broken tiling.
                        if best_residual > PHASE_TOLERANCE * a.shortest_vector().unwrap_or(f64::INFINITY) {
                            Fit::NotFor {
                                because: format!(
                                    "{at}, and no tile size that fits this {}×{} sample is in phase with its lattice (the nearest, tile \
                                     {best}, misses it by {best_residual:.1} px): even aligned tiles cut texels out of phase",
                                    a.width, a.height
                                ),
                                instead: "coevolution",
                            }
                        } else {
                            Fit::FitsWith {
                                set: vec![("tile".into(), best.to_string())],
                                because: format!(
                                    "{at}: even aligned tiles cut texels out of phase; tile {best} misses it by {best_residual:.1} px{or_auto}"
                                ),
                            }
                        }
                    }
                    // In phase, but about one texel per tile (`auto` found no size spanning more in
                    // phase in this sample): the tiling repeats a handful of texels in a regular
                    // pattern, and where texels differ in tone the tiles' cuts split them visibly.
                    Some(ph) if ph.texels < MIN_TEXELS_PER_TILE => Fit::NotFor {
                        because: format!(
                            "tiles of {} px hold only {:.1} texels, and no larger size in phase with the lattice fits this {}×{} sample, \
                         so the tiling repeats a few texels in a regular pattern",
                            ph.tile, ph.texels, a.width, a.height
                        ),
                        instead: "quilting",
                    },
                    _ => Fit::Fits,
                },
                Kind::Oriented => Fit::NotFor {
                    because: "tiles cut at random positions break the sample's oriented structure at every tile edge".into(),
                    instead: "quilting",
                },
                // Unaligned tiles are `auto`'s fallback size unless given (`auto` keeps it without a lattice).
                Kind::Stochastic
                    if let tile = int(p, "tile").unwrap_or(crate::synth::methods::tiles::align::FALLBACK_TILE)
                        && let Some(share) = a.large_features_at(tile / 4).filter(|&s| s >= LARGE_FEATURES_FROM) =>
                {
                    Fit::NotFor {
                        because: format!(
                            "{:.0} % of the sample's colour variance is in features {} px and more across, and every {tile}-px \
                             tile joins patches with different ones along the same lines of the tile grid (its edge patches, \
                             two per edge colour, and its own interior), so the tiling shows them in a visible regular \
                             patchwork (more colors vary which meet, not where{})",
                            100.0 * share,
                            tile / 4,
                            if p.get("tone") == Some(&ParamValue::Str("off".into())) {
                                ""
                            } else {
                                "; toned interiors, tone, soften the steps of shade along its lines, not what each patch holds"
                            }
                        ),
                        instead: "quilting",
                    }
                }
                _ => Fit::Fits,
            },
        ),
        _ => Fit::Fits,
    }
}

/// Why a lattice method is not for a sample whose large features do not follow its lattice
/// ([`BLOTCH_SHARE`]).
fn blotch_reason(share: f64, pieces: &str) -> String {
    format!(
        "its lattice comes from fine structure, while the blotches that carry {:.0} % of its colour variance ({BLOTCH_SIDE} px \
         and more across) do not repeat with it, so {pieces} cut on that lattice cut the blotches at straight edges",
        100.0 * share
    )
}

/// Why a lattice method is not for a sample whose lattice vector is a ridge ([`RIDGE_REPEATS`]).
fn ridge_reason(r: &VectorRepeat, cut: &str) -> String {
    format!(
        "the sample repeats along its lattice vector ({}, {}) only because it is uniform that way (gray correlation {:.2}), \
         not because it is periodic: the edges that cross it do not repeat (correlation {:.2}), as with courses of \
         random-length blocks or planks, and {cut} chop them and end their joints in mid-air",
        r.vector.0, r.vector.1, r.gray, r.crossing_edges
    )
}

/// Double-seam judges a block by a true seam line and an auxiliary one `aux_dist` pixels further
/// into the existing output. On a lattice finer than that distance (a wire grid repeating every
/// 4 px), the auxiliary line can be a lattice translate of the true line: it sees the same thing,
/// and where both fall on a bar the other direction's phase goes unseen (seen on such a grid at
/// 384² from 256²: blocks with rows out of phase for 2 of 4 seeds at `aux_dist` 8 = two periods,
/// none at 6 = one and a half). Returns the job's `aux_dist` and the distance within the overlap
/// that lies farthest from every lattice translate (ties to the larger) when the job's lies within
/// a pixel of one.
fn aux_line_in_phase(a: &Analysis, p: &Params) -> Option<(i64, i64)> {
    use crate::synth::methods::tiles::align::{Alignment, residual_px};
    let l = a.lattice.as_ref()?;
    let (aux, overlap) = (int(p, "aux_dist")?, int(p, "overlap")?);
    let al = Alignment::new(l.t1, l.t2, "extracted").ok()?;
    let off_lattice = |d: i64| residual_px(&al, [(d, 0), (d, 0)]).min(residual_px(&al, [(0, d), (0, d)]));
    if aux < 1 || off_lattice(aux) >= 1.0 {
        return None;
    }
    let better = (1..=overlap).max_by(|&x, &y| off_lattice(x).total_cmp(&off_lattice(y)).then(x.cmp(&y)))?;
    (off_lattice(better) >= 1.0).then_some((aux, better))
}

/// Tile methods draw their tiles' patches at random (`patch_candidates = 1`, the papers'). On a
/// sample whose tone varies between regions ([`TONE_SPREAD_FROM`]) the tiles mix light and dark
/// patches, and the tiling repeats that patchwork in a visible pattern; building 16 choices and
/// keeping the one whose cuts cost least picks patches that agree. Seen at 384² from 256²: a wall
/// lit from one side (rw-tiles: dark and light blotches tiled; wang-tiles: faint) and a framed tile
/// grid (rw-tiles: broken grout), both right with `patch_candidates = 16`.
fn with_tone_candidates(a: &Analysis, p: &Params, fit: Fit) -> Fit {
    if a.tone_spread < TONE_SPREAD_FROM || int(p, "patch_candidates") != Some(1) {
        return fit;
    }
    let why = format!(
        "its patches are drawn at random from a sample whose tone varies between regions ({TONE_LINE}-px lines' mean tone \
         varies {:.1}× as much as the lines themselves), so the tiling repeats a patchwork of tones",
        a.tone_spread
    );
    let set = ("patch_candidates".to_string(), "16".to_string());
    match fit {
        Fit::Fits => Fit::FitsWith { set: vec![set], because: why },
        Fit::FitsWith { set: mut s, because } => {
            s.push(set);
            Fit::FitsWith { set: s, because: format!("{because}; {why}") }
        }
        not_for => not_for,
    }
}

/// The warning sentence for a job, if its method and parameters do not fit its sample. A
/// near-regular method on a sample without a lattice is not warned about: it refuses the job
/// itself, with the reason, and a warning would only repeat it. On a weak lattice it runs, and
/// is warned about.
pub fn warning(a: &Analysis, method: &str, p: &Params) -> Option<String> {
    if matches!(method, "coevolution" | "tes") && a.lattice.is_none() {
        return None;
    }
    match fit(a, method, p) {
        Fit::Fits => None,
        Fit::FitsWith { set, because } => {
            let set: Vec<String> = set.iter().map(|(k, v)| format!("{k} = {}", toml_value(v))).collect();
            Some(format!("{method} will not look right on this {} sample: {because}; set {}.", kind_word(a.kind), set.join(", ")))
        }
        Fit::NotFor { because, instead } => {
            Some(format!("{method} does not suit this {} sample: {because}; use {instead} instead.", kind_word(a.kind)))
        }
    }
}

fn toml_value(v: &str) -> String {
    if v.parse::<f64>().is_ok() || v == "true" || v == "false" { v.to_string() } else { format!("\"{v}\"") }
}

pub fn kind_word(k: Kind) -> &'static str {
    match k {
        Kind::NearRegular => "near-regular",
        Kind::Oriented => "oriented",
        Kind::Stochastic => "stochastic",
        Kind::Flat => "flat",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(pairs: &[(&str, ParamValue)]) -> Params {
        Params(pairs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect())
    }

    /// A brick-like pattern with a 16 × 8 texel.
    fn bricks() -> RgbImage {
        RgbImage::from_fn(96, 96, |x, y| {
            let row = y / 8;
            let xs = (x + if row % 2 == 1 { 8 } else { 0 }) % 16;
            if y % 8 == 0 || xs == 0 { [40, 40, 40] } else { [180, 90, 60] }
        })
    }

    /// A blob per cell of the lattice `t1`, `t2` (with an off-centre mark, so cells are not symmetric).
    fn blobs(t1: (f64, f64), t2: (f64, f64)) -> RgbImage {
        let det = t1.0 * t2.1 - t1.1 * t2.0;
        RgbImage::from_fn(192, 192, |x, y| {
            let (x, y) = (x as f64, y as f64);
            let (u, v) = ((x * t2.1 - y * t2.0) / det, (t1.0 * y - t1.1 * x) / det);
            let (u, v) = (u - u.floor() - 0.5, v - v.floor() - 0.5);
            let d = u * u + v * v;
            if d < 0.06 {
                [220, 200, 180]
            } else if (u - 0.3).abs() < 0.08 && (v + 0.3).abs() < 0.08 {
                [90, 140, 60]
            } else {
                [40, 50, 70]
            }
        })
    }

    #[test]
    fn a_big_sample_is_analysed_reduced_in_its_own_pixels() {
        // The bricks (16×8 px texels) drawn 4× larger on 1536² pixels (over ANALYSIS_PIXELS):
        // analysed on a copy reduced 2×, with lattice vectors and sizes in the sample's pixels.
        let small = RgbImage::from_fn(384, 384, |x, y| bricks().get(x % 96, y % 96));
        let big = RgbImage::from_fn(1536, 1536, |x, y| small.get(x / 4, y / 4));
        let (a, b) = (analyse(&small), analyse(&big));
        assert_eq!((b.width, b.height), (1536, 1536));
        let (la, lb) = (a.lattice.expect("lattice of the small copy"), b.lattice.expect("lattice of the big one"));
        assert_eq!((lb.t1, lb.t2), ((la.t1.0 * 4, la.t1.1 * 4), (la.t2.0 * 4, la.t2.1 * 4)));
        assert_eq!(b.large_features.first().map(|e| e.0), Some(8), "{:?}", b.large_features);
        assert!(b.flat_bands.iter().all(|e| e.0 % 4 == 0));
    }

    #[test]
    fn quilting_is_told_a_block_when_texels_are_much_larger_than_its_blocks() {
        let a = analyse(&blobs((30.0, 0.0), (0.0, 32.0)));
        let block = |b: i64| params(&[("block", ParamValue::Int(b))]);
        // Flat colours: the flat-band rule asks for more than a texel; the texel rule for 32.
        let w = warning(&a, "quilting", &block(16)).expect("blocks of 16 on a 30 px texel");
        assert!(w.contains("under two thirds of the sample's texel") && suggested_block(&w) >= 32, "{w}");
        let w = warning(&a, "quilting", &block(32)).unwrap_or_default();
        assert!(!w.contains("texel"), "a block of 32 keeps the joints: {w}");
        // Double-seam and patch sampling want a whole texel per block.
        let w = warning(&a, "double-seam", &block(24)).expect("blocks of 24 on a 30 px texel");
        assert!(w.contains("smaller than the sample's texel") && suggested_block(&w) >= 32, "{w}");
    }

    /// The `block = N` a warning suggests.
    fn suggested_block(w: &str) -> i64 {
        let tail = &w[w.find("block = ").expect("suggests a block") + 8..];
        tail[..tail.find(|c: char| !c.is_ascii_digit()).unwrap_or(tail.len())].parse().unwrap()
    }

    /// A deterministic value in `0..amplitude` per pixel.
    fn noise(x: u32, y: u32, amplitude: u32) -> u8 {
        let h = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)).wrapping_mul(2_654_435_761);
        ((h >> 16) % amplitude) as u8
    }

    #[test]
    fn double_seam_and_tiles_are_told_to_weigh_tone_where_regions_differ_in_tone() {
        // A dark half and a light half with the same fine grain (a wall lit from one side): lines
        // correlate whatever their tone, so Pearson alone would join dark blocks to light ones.
        let two_tone = RgbImage::from_fn(256, 256, |x, y| {
            let base = if y < 128 { 60 } else { 170 };
            let v = base + noise(x, y, 24);
            [v, v, v]
        });
        let a = analyse(&two_tone);
        assert!(a.tone_spread >= TONE_SPREAD_FROM, "{}", a.tone_spread);
        let w = warning(&a, "double-seam", &params(&[("level_penalty", ParamValue::Float(0.0))])).expect("two tones");
        assert!(w.contains("set level_penalty = 4"), "{w}");
        let given = params(&[("level_penalty", ParamValue::Float(10.0))]);
        assert!(warning(&a, "double-seam", &given).is_none_or(|w| !w.contains("level_penalty")));
        // Unaligned tiles would repeat the two halves as a patchwork whatever the candidates:
        // not for this sample.
        for method in ["wang-tiles", "rw-tiles"] {
            for candidates in [1, 16] {
                let w = warning(&a, method, &params(&[("patch_candidates", ParamValue::Int(candidates))])).expect("two tones");
                assert!(w.contains("visible regular patchwork") && w.contains("use quilting"), "{w}");
            }
        }
        // A brick wall lit from one side: aligned tiles keep the bricks, and drawing patches at
        // random would tile a patchwork of the two tones; they are told to choose among candidates.
        let lit = RgbImage::from_fn(128, 128, |x, y| {
            let row = y / 8;
            let xs = (x + if row % 2 == 1 { 8 } else { 0 }) % 16;
            let v: u8 = if y % 8 == 0 || xs == 0 { 40 } else { 150 };
            let v = if y < 64 { v / 2 } else { v } + noise(x, y, 8);
            [v, v, v]
        });
        let a = analyse(&lit);
        assert!(a.lattice.is_some() && a.tone_spread >= TONE_SPREAD_FROM, "{a:?}");
        for method in ["wang-tiles", "rw-tiles"] {
            let w = warning(
                &a,
                method,
                &params(&[("patch_candidates", ParamValue::Int(1)), ("overlap", ParamValue::Int(4)), ("tile", ParamValue::Int(32))]),
            )
            .expect("two tones");
            assert!(w.contains("set patch_candidates = 16"), "{w}");
        }
        // One tone, the same grain: nothing to say.
        let grain = RgbImage::from_fn(128, 128, |x, y| {
            let v = 100 + noise(x, y, 24);
            [v, v, v]
        });
        let a = analyse(&grain);
        assert!(a.tone_spread < TONE_SPREAD_FROM, "{}", a.tone_spread);
        assert_eq!(warning(&a, "double-seam", &params(&[("level_penalty", ParamValue::Float(0.0))])), None);
        assert_eq!(warning(&a, "rw-tiles", &params(&[("patch_candidates", ParamValue::Int(1))])), None);
    }

    /// Soft round blotches of `radius` px at pseudo-random places over a fine grain, or over
    /// `under` where given.
    fn blotches(size: u32, radius: f64, under: impl Fn(u32, u32) -> u8) -> RgbImage {
        let centres: Vec<(f64, f64)> = (0..(size as f64 / radius).powi(2) as u32 / 3)
            .map(|i| {
                // splitmix64's finaliser: places with no pattern a lattice could find.
                let mix = |mut z: u64| {
                    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
                    z ^ (z >> 31)
                };
                let h = mix(u64::from(i).wrapping_mul(0x9E37_79B9_7F4A_7C15));
                ((h % u64::from(size)) as f64, ((h >> 32) % u64::from(size)) as f64)
            })
            .collect();
        RgbImage::from_fn(size, size, |x, y| {
            let near =
                centres.iter().map(|&(cx, cy)| ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt()).fold(f64::INFINITY, f64::min);
            let lift = (70.0 * (1.0 - near / radius)).max(0.0) as u8;
            let v = under(x, y) + lift;
            [v, v / 2 + 40, v]
        })
    }

    #[test]
    fn unaligned_tiles_are_told_off_where_features_are_large_next_to_a_tile() {
        let tiles = params(&[("patch_candidates", ParamValue::Int(1))]);
        // Blotches of 20 px over grain: each 64-px tile carries its own, repeated as a patchwork.
        let large = analyse(&blotches(256, 20.0, |x, y| 60 + noise(x, y, 40)));
        assert_eq!(large.kind, Kind::Stochastic);
        assert!(large.large_features_at(16).unwrap() >= LARGE_FEATURES_FROM, "{:?}", large.large_features);
        for method in ["wang-tiles", "rw-tiles"] {
            let w = warning(&large, method, &tiles).expect("large features");
            assert!(w.contains("visible regular patchwork") && w.contains("use quilting"), "{w}");
        }
        // Quilting searches every placement: nothing to say.
        assert_eq!(warning(&large, "quilting", &params(&[("block", ParamValue::Int(48))])), None);
        // Patch sampling's swarm drifts into the plain areas between large features: it is told
        // to search exhaustively, and nothing is said once it does.
        let swarm = |search: &str| params(&[("block", ParamValue::Int(30)), ("search", ParamValue::Str(search.into()))]);
        for search in ["cpso", "pso"] {
            let w = warning(&large, "patch-sampling", &swarm(search)).expect("large features");
            assert!(w.contains("swarm settles") && w.contains("set search = \"exhaustive\", tolerance = 0"), "{w}");
        }
        assert_eq!(warning(&large, "patch-sampling", &swarm("exhaustive")), None);
        // Blotches of 3 px: fine grain, no warning.
        let fine = analyse(&blotches(256, 3.0, |x, y| 60 + noise(x, y, 40)));
        assert_eq!(warning(&fine, "patch-sampling", &swarm("cpso")), None);
        assert!(fine.large_features_at(16).unwrap() < LARGE_FEATURES_FROM, "{:?}", fine.large_features);
        for method in ["wang-tiles", "rw-tiles"] {
            assert_eq!(warning(&fine, method, &tiles), None);
        }
    }

    #[test]
    fn a_lattice_of_fine_grain_under_blotches_that_ignore_it_is_told_off() {
        // A grid of thin lines every 40 px under blotches at random places.
        let grid = |x: u32, y: u32| if x % 40 < 2 || y % 40 < 2 { 40 } else { 70 };
        let a = analyse(&blotches(256, 18.0, grid));
        assert!(a.lattice.is_some(), "{:?}", a.no_lattice);
        assert!(a.blotches_off_lattice().is_some(), "{:?} {:?}", a.large_features, a.large_features_repeat);
        for method in ["coevolution", "tes", "wang-tiles", "rw-tiles"] {
            let w = warning(&a, method, &params(&[])).expect("blotches");
            assert!(w.contains("do not repeat with it") && w.contains("use quilting"), "{method}: {w}");
        }
        // Given a lattice, the user has chosen it.
        let given = params(&[("t1_x", ParamValue::Int(40)), ("t2_y", ParamValue::Int(40))]);
        assert!(warning(&a, "coevolution", &given).is_none_or(|w| !w.contains("do not repeat with it")));
        // The same bricks without blotches: their lattice holds everything.
        let plain = analyse(&RgbImage::from_fn(256, 256, |x, y| {
            let v = grid(x, y) + noise(x, y, 8);
            [v, v / 2 + 40, v]
        }));
        assert!(plain.lattice.is_some() && plain.blotches_off_lattice().is_none(), "{:?}", plain.large_features);
    }

    #[test]
    fn double_seam_is_told_an_auxiliary_line_off_a_fine_lattice() {
        // A wire grid: bars every 4 px across, every 16 px down (with grain, so no band is flat).
        let grid = RgbImage::from_fn(128, 128, |x, y| {
            let v = if x % 4 == 0 || y % 16 == 0 { 200 } else { 30 } + noise(x, y, 8);
            [v, v, v]
        });
        let a = analyse(&grid);
        assert!(a.lattice.is_some(), "{}", a.describe());
        let job = |aux: i64| params(&[("aux_dist", ParamValue::Int(aux)), ("overlap", ParamValue::Int(8)), ("block", ParamValue::Int(50))]);
        let w = warning(&a, "double-seam", &job(8)).expect("8 px = two periods");
        assert!(w.contains("set aux_dist = 6"), "{w}");
        assert!(warning(&a, "double-seam", &job(6)).is_none_or(|w| !w.contains("aux_dist")));
        // A lattice coarser than the overlap: the auxiliary line is never in phase.
        let coarse = analyse(&blobs((30.0, 0.0), (0.0, 32.0)));
        assert_eq!(aux_line_in_phase(&coarse, &job(8)), None);
    }

    #[test]
    fn patch_methods_are_told_a_larger_block_where_overlaps_fall_in_flat_areas() {
        // Thin diagonal bars 64 px apart on black: most small bands see only black.
        let bars = RgbImage::from_fn(192, 192, |x, y| if (x + y) % 64 < 6 { [200, 200, 200] } else { [0, 0, 0] });
        let a = analyse(&bars);
        let flat = a.flat_bands_at(24).unwrap();
        assert!(flat >= FLAT_BANDS_MAX, "{flat}");
        for method in ["quilting", "double-seam", "patch-sampling"] {
            let w = warning(&a, method, &params(&[("block", ParamValue::Int(24))])).expect("flat bands");
            assert!(w.contains("have almost no contrast"), "{method}: {w}");
            let b = suggested_block(&w);
            assert!(b > 24 && a.flat_bands_at(b).unwrap() <= FLAT_BANDS_OK, "{method}: block {b}: {:?}", a.flat_bands_at(b));
        }
        // Grain everywhere: no band is flat.
        let grain = analyse(&RgbImage::from_fn(192, 192, |x, y| {
            let v = 100 + noise(x, y, 40);
            [v, v, v]
        }));
        assert_eq!(grain.flat_bands_at(24), Some(0.0));
    }

    #[test]
    fn tes_is_told_off_where_its_rectangular_grid_misses_the_lattice() {
        // Sheared: the texel's bounding box is 30 px wide, and (30, 0) is no lattice vector.
        let sheared = analyse(&blobs((30.0, 12.0), (0.0, 32.0)));
        assert!(sheared.lattice.is_some(), "{}", sheared.describe());
        let g = sheared.grid_repeat.clone().expect("a lattice has a grid repeat");
        assert!(g.across.min(g.down) < GRID_REPEAT_MIN * g.along_lattice, "{g:?}");
        match fit(&sheared, "tes", &params(&[])) {
            Fit::NotFor { because, instead } => {
                assert_eq!(instead, "coevolution");
                assert!(because.contains("rectangular grid"), "{because}");
            }
            other => panic!("tes on a sheared lattice: {other:?}"),
        }
        assert_eq!(fit(&sheared, "coevolution", &params(&[])), Fit::Fits);
        // Rectangular: the grid is the lattice, and TES fits.
        let square = analyse(&blobs((30.0, 0.0), (0.0, 32.0)));
        let g = square.grid_repeat.clone().expect("grid repeat");
        assert!(g.across.min(g.down) > 0.9 * g.along_lattice, "{g:?}");
        assert_eq!(fit(&square, "tes", &params(&[])), Fit::Fits);
        // A lattice the job gives is the user's call.
        let given = params(&[("t1_x", ParamValue::Int(30)), ("t1_y", ParamValue::Int(12)), ("t2_y", ParamValue::Int(32))]);
        assert_eq!(fit(&sheared, "tes", &given), Fit::Fits);
    }

    /// Courses 12 px high under a dark mortar line, each with joints at its own pseudo-random
    /// places (`random`), or every 20 px in a running bond (not random).
    fn courses(random: bool) -> RgbImage {
        let mut state = 7u32;
        let mut joints: Vec<Vec<u32>> = Vec::new();
        for row in 0..10 {
            let mut xs = Vec::new();
            let mut x = if random { 0 } else { (row % 2) * 10 };
            while x < 120 {
                xs.push(x);
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                x += if random { 9 + (state >> 16) % 31 } else { 20 };
            }
            joints.push(xs);
        }
        RgbImage::from_fn(
            120,
            120,
            |x, y| {
                if y % 12 == 0 || joints[(y / 12) as usize].contains(&x) { [60, 50, 40] } else { [200, 170, 110] }
            },
        )
    }

    fn lattice(t1: (i64, i64), t2: (i64, i64)) -> Lattice {
        Lattice {
            t1,
            t2,
            peak1: 0.5,
            peak2: 0.5,
            candidates: 16,
            explained: 16,
            found_in: None,
            fine: crate::synth::lattice::FineVectors::exact(t1, t2),
        }
    }

    #[test]
    fn a_lattice_vector_along_courses_of_random_joints_is_a_ridge() {
        let repeats = |img: &RgbImage, l: &Lattice| vector_repeats(&centred_gray(img), 120, 120, l);
        // Along the courses the gray plane repeats, but the joints crossing (20, 0) do not.
        let random = repeats(&courses(true), &lattice((20, 0), (0, 12)));
        assert!(random[0].is_ridge(), "{random:?}");
        assert!(!random[1].is_ridge(), "the mortar lines repeat down: {random:?}");
        // In a running bond they do: (20, 0) is a period.
        let bond = repeats(&courses(false), &lattice((20, 0), (10, 12)));
        assert!(bond.iter().all(|v| !v.is_ridge() && v.crossing_edges > 0.5), "{bond:?}");

        // A ridge sends the lattice methods to quilting, unless the job gives its lattice.
        let mut a = analyse(&bricks());
        assert!(a.ridge().is_none() && a.lattice.is_some(), "{}", a.describe());
        a.along_vectors = random;
        for method in ["coevolution", "tes", "wang-tiles", "rw-tiles"] {
            match fit(&a, method, &params(&[])) {
                Fit::NotFor { because, instead } => {
                    assert_eq!(instead, "quilting");
                    assert!(because.contains("(20, 0) only because it is uniform that way"), "{because}");
                }
                other => panic!("{method} on a ridge: {other:?}"),
            }
        }
        let given = params(&[("t1_x", ParamValue::Int(16)), ("t2_x", ParamValue::Int(8)), ("t2_y", ParamValue::Int(8))]);
        assert!(!matches!(fit(&a, "tes", &given), Fit::NotFor { .. }));
        assert_eq!(fit(&a, "quilting", &params(&[])), Fit::Fits);
    }

    #[test]
    fn flat_and_tiny_samples_have_nothing_to_analyse() {
        assert_eq!(analyse(&RgbImage::from_fn(4, 4, |x, _| [x as u8; 3])).kind, Kind::Flat);
        let flat = analyse(&RgbImage::from_fn(64, 64, |_, _| [9, 9, 9]));
        assert_eq!(flat.kind, Kind::Flat);
        assert!(flat.describe().contains("nothing to analyse"));
        assert_eq!(warning(&flat, "wang-tiles", &params(&[("align", ParamValue::Str("none".into()))])), None);
    }

    #[test]
    fn a_lattice_gets_aligned_tiles_in_phase_and_cut_blending() {
        let a = analyse(&bricks());
        assert_eq!(a.kind, Kind::NearRegular, "{}", a.describe());
        let w = warning(&a, "rw-tiles", &params(&[("align", ParamValue::Str("none".into()))])).expect("tiles warn");
        assert!(w.contains("align = \"lattice\""), "{w}");
        // Wang tiles of 64 px translate by (64, 0), (0, 64): lattice vectors of a 16 × 8 brick bond.
        let tile =
            |t: i64| params(&[("align", ParamValue::Str("auto".into())), ("tile", ParamValue::Int(t)), ("overlap", ParamValue::Int(8))]);
        assert_eq!(warning(&a, "wang-tiles", &tile(64)), None);
        let w = warning(&a, "wang-tiles", &tile(58)).expect("a tile out of phase with the lattice warns");
        assert!(w.contains("set tile = "), "{w}");
        // The default, `tile = "auto"`, picks an in-phase size itself: nothing to say.
        let auto =
            params(&[("align", ParamValue::Str("auto".into())), ("tile", ParamValue::Str("auto".into())), ("overlap", ParamValue::Int(8))]);
        assert_eq!(warning(&a, "wang-tiles", &auto), None);
        assert_eq!(warning(&a, "rw-tiles", &auto), None);
        assert_eq!(warning(&a, "coevolution", &params(&[])), None);
        // Quilting's search keeps texels whole with any block: no advice to change it.
        assert_eq!(warning(&a, "quilting", &params(&[("block", ParamValue::Int(12))])), None);
        let w = warning(&a, "patch-sampling", &params(&[("blend", ParamValue::Str("feather".into()))])).expect("feathering warns");
        assert!(w.contains("blend = \"cut\""), "{w}");
        let w = warning(&a, "patch-sampling", &params(&[("continuations", ParamValue::Bool(false))])).expect("the swarm alone warns");
        assert!(w.contains("continuations = true"), "{w}");
        assert_eq!(warning(&a, "patch-sampling", &params(&[("continuations", ParamValue::Bool(true))])), None);
        // Blocks smaller than the texel (lattice vectors (8, ±8)): the methods that cannot
        // search their way back into phase are told a block that holds one.
        let w = warning(&a, "double-seam", &params(&[("block", ParamValue::Int(8))])).expect("small blocks warn");
        assert!(w.contains("set block = 12"), "{w}");
        assert_eq!(warning(&a, "double-seam", &params(&[("block", ParamValue::Int(12))])), None);
        let w = warning(&a, "patch-sampling", &params(&[("block", ParamValue::Int(6)), ("blend", ParamValue::Str("cut".into()))]))
            .expect("small patches warn");
        assert!(w.contains("set block = 12"), "{w}");
    }

    #[test]
    fn tiles_of_about_one_texel_are_advised_against() {
        // 36 px tiles with dark grout in a 112 px sample: no tile of two texels fits with a cell to
        // spare, so aligned tiles hold one texel each.
        let big = RgbImage::from_fn(112, 112, |x, y| {
            let grain = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503).wrapping_mul(2654435761)) >> 27;
            if x % 36 < 3 || y % 36 < 3 { [30, 30, 30] } else { [150 + grain as u8, 90, 40] }
        });
        let a = analyse(&big);
        assert_eq!(a.kind, Kind::NearRegular, "{}", a.describe());
        let auto =
            params(&[("align", ParamValue::Str("auto".into())), ("tile", ParamValue::Str("auto".into())), ("overlap", ParamValue::Int(8))]);
        let w = warning(&a, "wang-tiles", &auto).expect("one texel per tile warns");
        assert!(w.contains("hold only 1.0 texels") && w.contains("use quilting"), "{w}");
        // The bricks' 128 px² texels fit many times into a 64 px tile: nothing to say.
        let bricks = analyse(&bricks());
        assert_eq!(warning(&bricks, "wang-tiles", &auto), None);
    }

    #[test]
    fn without_a_lattice_the_near_regular_methods_are_advised_against_unless_given_one() {
        // Deterministic noise: no lattice, no orientation.
        let mut s = 12345u32;
        let noise = RgbImage::from_fn(96, 96, |_, _| {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let v = (s >> 24) as u8;
            [v, v, v]
        });
        let a = analyse(&noise);
        assert_eq!(a.kind, Kind::Stochastic, "{}", a.describe());
        match fit(&a, "tes", &params(&[])) {
            Fit::NotFor { because, instead } => assert!(because.contains("needs a lattice") && instead == "quilting", "{because}"),
            other => panic!("tes on noise: {other:?}"),
        }
        assert_eq!(fit(&a, "tes", &params(&[("t1_x", ParamValue::Int(20)), ("t2_y", ParamValue::Int(20))])), Fit::Fits);
        assert_eq!(warning(&a, "tes", &params(&[])), None, "the job refuses itself; no warning repeats it");
        for m in ["quilting", "double-seam", "wang-tiles", "rw-tiles"] {
            assert_eq!(warning(&a, m, &params(&[("align", ParamValue::Str("none".into())), ("block", ParamValue::Int(32))])), None, "{m}");
        }
        assert_eq!(warning(&a, "patch-sampling", &params(&[("blend", ParamValue::Str("feather".into()))])), None);
    }
}
