//! Non-overlapping splicing by the double-seam consistency criterion (paper 003, docs/methods.md §5).
//!
//! Blocks sit on the same grid as image quilting (stride `block − overlap`), but the overlap is
//! only *virtual*: a candidate block is judged by how well two lines agree with the output already
//! there — the true seam (the last existing column/row before the pasted part) and an auxiliary
//! line `aux_dist` further in — using Pearson correlations of the H, S and I sequences and the
//! agreement of a binary edge map. The chosen block is pasted verbatim, without blending or a cut.
//! Comparing two lines instead of a whole overlap is the paper's speed argument.

use crate::image::RgbImage;
use crate::image::seam_grid::{SeamBand, SeamGrid};
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::params::{self, Choice, Default, MethodConfig, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::block_grid::BlockGrid;
use crate::synth::primitives::canvas::Canvas as PixelCanvas;
use crate::synth::primitives::color::HsiPlanes;
use crate::synth::primitives::correlation::{FLAT, pearson_from};
use crate::synth::primitives::edges::{otsu_edges, sobel4};
use crate::synth::primitives::simd::with_avx2;
use crate::synth::primitives::torus::TorusGrid;
use crate::synth::rng::Stream;
use rayon::prelude::*;
use rustfft::num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};
use std::f64::consts::TAU;
use std::sync::Arc;

mod config;
mod phase;
mod search;
pub use config::{DEFAULT_LEVEL_PENALTY, DoubleSeamConfig};
use config::{HueMode, PARAMS};
use phase::LatticePhase;
use search::*;

pub struct DoubleSeam;

/// Which neighbours a grid position has.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Case {
    /// First row: left neighbour only.
    Horizontal,
    /// First column: upper neighbour only.
    Vertical,
    L,
}

/// The window offsets of the true and the auxiliary seam lines (docs/methods.md §5.3).
fn lines(case: Case, block: i32, g: i32, a: i32) -> [Vec<(i32, i32)>; 2] {
    match case {
        Case::Horizontal => [(0..block).map(|r| (g - 1, r)).collect(), (0..block).map(|r| (a, r)).collect()],
        Case::Vertical => [(0..block).map(|c| (c, g - 1)).collect(), (0..block).map(|c| (c, a)).collect()],
        Case::L => [
            (g - 1..block).map(|r| (g - 1, r)).chain((g..block).map(|c| (c, g - 1))).collect(),
            (a..block).map(|r| (a, r)).chain((a + 1..block).map(|c| (c, a))).collect(),
        ],
    }
}

/// The sample, pre-processed once: HSI planes and the binary edge map (B6, B7).
struct Prepared<'a> {
    rgb: &'a RgbImage,
    w: usize,
    planes: HsiPlanes,
    /// The edge bits, followed by [`EDGE_PAD`] zeros so that [`edge_mismatch_row`] may read whole
    /// register blocks past the last candidate of a row.
    edges: Vec<u8>,
    /// The planes' spectra, for [`FftBounds`].
    spectra: Spectra,
    /// Run sums of the planes, for [`BoundStats`].
    prefixes: Prefixes,
    /// [`FftBounds`]' buffers, kept from one grid position to the next.
    fft_buffers: std::sync::Mutex<Vec<Vec<Complex32>>>,
}

impl<'a> Prepared<'a> {
    fn of(rgb: &'a RgbImage) -> Prepared<'a> {
        let (w, h) = (rgb.width() as usize, rgb.height() as usize);
        let planes = HsiPlanes::of(rgb);
        let mut edges = otsu_edges(&sobel4(&planes.i, w, h));
        let prefixes = Prefixes::new(&planes, &edges, w, h);
        edges.resize(w * h + EDGE_PAD, 0);
        let spectra = Spectra::new(&planes, w, h);
        Prepared { rgb, w, planes, edges, spectra, prefixes, fft_buffers: std::sync::Mutex::new(Vec::new()) }
    }
}

/// Row and column prefix sums of the sample's H, S and I planes and of their squares: the sum of
/// any quantity over a run of a line is two lookups, so the bounds' candidate statistics
/// ([`BoundStats`]) cost a few operations per candidate instead of a pass over the line.
struct Prefixes {
    w: usize,
    h: usize,
    /// `rows[q][y·(w+1) + x]`: the sum of quantity `q` (H, S, I, H², S², I²) over row `y`, columns `0..x`.
    rows: [Vec<f64>; 6],
    /// `cols[q][y·w + x]`: the sum over column `x`, rows `0..y` (row-major, so the run sums of
    /// consecutive candidates are consecutive differences).
    cols: [Vec<f64>; 6],
    /// The same two layouts for the edge bits, as exact counts.
    edge_rows: Vec<u32>,
    edge_cols: Vec<u32>,
}

impl Prefixes {
    fn new(planes: &HsiPlanes, edges: &[u8], w: usize, h: usize) -> Prefixes {
        let value = |q: usize, i: usize| {
            let v = [&planes.h, &planes.s, &planes.i][q % 3][i];
            if q < 3 { v } else { v * v }
        };
        let rows = std::array::from_fn(|q| {
            let mut p = vec![0.0; (w + 1) * h];
            for y in 0..h {
                for x in 0..w {
                    p[y * (w + 1) + x + 1] = p[y * (w + 1) + x] + value(q, y * w + x);
                }
            }
            p
        });
        let cols = std::array::from_fn(|q| {
            let mut p = vec![0.0; (h + 1) * w];
            for y in 0..h {
                for x in 0..w {
                    p[(y + 1) * w + x] = p[y * w + x] + value(q, y * w + x);
                }
            }
            p
        });
        let mut edge_rows = vec![0; (w + 1) * h];
        let mut edge_cols = vec![0; (h + 1) * w];
        for y in 0..h {
            for x in 0..w {
                let e = u32::from(edges[y * w + x]);
                edge_rows[y * (w + 1) + x + 1] = edge_rows[y * (w + 1) + x] + e;
                edge_cols[(y + 1) * w + x] = edge_cols[y * w + x] + e;
            }
        }
        Prefixes { w, h, rows, cols, edge_rows, edge_cols }
    }

    /// Adds the number of edge pixels on `run` placed at candidates `(x0 + j, y)` to `acc[j]`.
    #[inline(always)]
    fn add_edge_run(&self, run: &Run, x0: i32, y: i32, acc: &mut [u32]) {
        let (c, r) = ((x0 + run.c) as usize, (y + run.r) as usize);
        let (len, n) = (run.len as usize, acc.len());
        let (start, end) = if run.horizontal {
            let row = &self.edge_rows[r * (self.w + 1)..];
            (&row[c..c + n], &row[c + len..c + len + n])
        } else {
            (&self.edge_cols[r * self.w + c..r * self.w + c + n], &self.edge_cols[(r + len) * self.w + c..(r + len) * self.w + c + n])
        };
        for ((a, e), s) in acc.iter_mut().zip(end).zip(start) {
            *a += e - s;
        }
    }

    /// Adds the sum of quantity `q` over `run` placed at candidates `(x0 + j, y)` to `acc[j]`.
    fn add_run(&self, q: usize, run: &Run, x0: i32, y: i32, acc: &mut [f64]) {
        let (c, r) = ((x0 + run.c) as usize, (y + run.r) as usize);
        let (len, n) = (run.len as usize, acc.len());
        let (start, end) = if run.horizontal {
            let row = &self.rows[q][r * (self.w + 1)..];
            (&row[c..c + n], &row[c + len..c + len + n])
        } else {
            let cols = &self.cols[q];
            (&cols[r * self.w + c..r * self.w + c + n], &cols[(r + len) * self.w + c..(r + len) * self.w + c + n])
        };
        for ((a, e), s) in acc.iter_mut().zip(end).zip(start) {
            *a += e - s;
        }
    }

    /// A bound of the absolute error of a sum of `runs` run sums of any quantity (every value is in
    /// `[0, 1]`): each prefix is a recursive sum of at most `L = max(w, h)` terms, so its error is
    /// at most `L²·u` (`u` the unit roundoff); a run sum is a difference of two, and the runs'
    /// sums are added up, each step rounding once more. Doubled for safety.
    fn error(&self, runs: usize, n: usize) -> f64 {
        let l = self.w.max(self.h) as f64;
        2.0 * f64::EPSILON * (runs as f64 * (2.0 * l * l + l) + n as f64)
    }
}

/// A straight piece of a line: `len` pixels from window offset `(c, r)`, along the row
/// (`horizontal`) or down the column.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Run {
    c: i32,
    r: i32,
    len: i32,
    horizontal: bool,
}

/// A line's pixels as maximal runs in line order (a lone pixel is a horizontal run of one).
fn runs_of(line: &[(i32, i32)]) -> Vec<Run> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < line.len() {
        let (c, r) = line[i];
        let along = |step: (i32, i32)| {
            let mut j = i;
            while j + 1 < line.len() && line[j + 1] == (line[j].0 + step.0, line[j].1 + step.1) {
                j += 1;
            }
            j - i + 1
        };
        let (across, down) = (along((1, 0)), along((0, 1)));
        let (len, horizontal) = if down > across { (down, false) } else { (across, true) };
        runs.push(Run { c, r, len: len as i32, horizontal });
        i += len;
    }
    runs
}

/// Per candidate and line, what [`FftBounds`] needs of the candidate side: per channel an upper
/// bound `inv_hi` of `1/sqrt(centred sum of squares)`, from run sums (so not the exact two-pass
/// value the scores use, but within a proven error), `∞` for a line whose sum of squares may be
/// too small to tell from flat. The true value also lies above `inv_hi·(1 − INV_SPREAD)`.
/// Laid out by candidate row, then channel, then candidate, so that [`FftBounds`] reads each
/// channel of a row as one contiguous slice.
struct BoundStats {
    nx: usize,
    lines: [Vec<f64>; 2],
    /// Per line, every candidate's mean intensity from run sums (row-major), within
    /// `mean_err[li]` of the exact mean the scores use: what bounds the level penalty from below.
    mean_i: [Vec<f64>; 2],
    mean_err: [f64; 2],
}

/// The relative width of [`BoundStats`]' intervals. A line not marked flat has `lo > 1e3·err_ss`
/// for the interval `[lo, hi] = [ss·(1 − 1e-9) − err_ss, ss·(1 + 1e-9) + err_ss]` holding its
/// centred sum of squares, so `hi/lo < 1 + 2.01e-3` and `1/sqrt(hi) > (1/sqrt(lo))·(1 − 1.01e-3)`:
/// the true `1/sqrt` is at least `inv_hi·(1 − INV_SPREAD)`.
const INV_SPREAD: f64 = 1.01e-3;

impl BoundStats {
    fn new(prep: &Prepared, ls: &[Vec<(i32, i32)>; 2], (xs, ys): Ranges) -> BoundStats {
        let pre = &prep.prefixes;
        let (x0, nx) = (*xs.start(), (xs.end() - xs.start() + 1).max(0) as usize);
        let (y0, ny) = (*ys.start(), (ys.end() - ys.start() + 1).max(0) as usize);
        let mut mean_i: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        let mut mean_err = [0.0; 2];
        let lines = [0, 1].map(|li| {
            let runs = runs_of(&ls[li]);
            let n = ls[li].len() as f64;
            let err = pre.error(runs.len(), ls[li].len());
            // The exact mean is a sum in line order over n: it and this one each err by at most
            // err / n (plus the division's rounding, far below); doubled.
            mean_err[li] = 2.0 * err / n + 4.0 * f64::EPSILON;
            let mut means = vec![0.0; nx * ny];
            // The mean's error is err / n; the centred sum of squares S2 − S1²/n then errs by at
            // most err (S2) + 3·err (S1 ≤ n) plus its own roundings (relative, 1e-9 is far above).
            let err_ss = 4.0 * err;
            // Below this a line may be flat (pearson's FLAT) or too close to it for the interval to be tight.
            let floor = (1e3 * err_ss).max(1e-9);
            let mut fields = vec![0.0; 3 * nx * ny];
            if nx > 0 {
                fields.par_chunks_mut(3 * nx).zip(means.par_chunks_mut(nx)).enumerate().for_each(|(row, (fs, ms))| {
                    let y = y0 + row as i32;
                    let (mut s1, mut s2) = (vec![0.0; nx], vec![0.0; nx]);
                    for (k, inv_hi) in fs.chunks_exact_mut(nx).enumerate() {
                        s1.fill(0.0);
                        s2.fill(0.0);
                        for run in &runs {
                            pre.add_run(k, run, x0, y, &mut s1);
                            pre.add_run(k + 3, run, x0, y, &mut s2);
                        }
                        for ((ih, &s1), &s2) in inv_hi.iter_mut().zip(&s1).zip(&s2) {
                            let lo = (s2 - s1 * s1 / n) * (1.0 - 1e-9) - err_ss;
                            *ih = if lo <= floor { f64::INFINITY } else { 1.0 / lo.sqrt() };
                        }
                        if k == 2 {
                            for (m, &s1) in ms.iter_mut().zip(&s1) {
                                *m = s1 / n;
                            }
                        }
                    }
                });
            }
            mean_i[li] = means;
            fields
        });
        BoundStats { nx, lines, mean_i, mean_err }
    }

    /// A lower bound, per candidate, of the level penalty `λ·Σ|mean I(output line) − mean I(candidate
    /// line)|` that the full score subtracts, given the output lines' mean intensities: an upper
    /// bound of `F` without it stays one with it subtracted. Without it the bounds of a search with
    /// a penalty are loose by the penalty itself, and most candidates survive to be scored in
    /// full (double-seam at 512² from pebbles: 0.3 → 1.1 s with `level_penalty = 10`, 0.4 s with the bound).
    fn penalty_low(&self, lambda: f64, out_means: [f64; 2]) -> Vec<f64> {
        const CHUNK: usize = 4096;
        let mut low = vec![0.0; self.mean_i[0].len()];
        low.par_chunks_mut(CHUNK).zip(self.mean_i[0].par_chunks(CHUNK)).zip(self.mean_i[1].par_chunks(CHUNK)).for_each(
            |((low, m0), m1)| {
                for ((l, &m0), &m1) in low.iter_mut().zip(m0).zip(m1) {
                    let line = |li: usize, m: f64| ((out_means[li] - m).abs() - self.mean_err[li]).max(0.0);
                    // The full score's products and differences round relatively: 1e-12 is far above.
                    *l = lambda * (line(0, m0) + line(1, m1)) * (1.0 - 1e-12);
                }
            },
        );
        low
    }

    /// Channel `k`'s `inv_hi` of line `li` at candidate row `row`.
    fn inv_hi(&self, li: usize, row: usize, k: usize) -> &[f64] {
        &self.lines[li][(3 * row + k) * self.nx..(3 * row + k + 1) * self.nx]
    }
}

/// The exact candidate-side statistics of one line (linear hue) at the candidates whose line
/// pixels are `base + offsets`, for each of `bases`: the same sums in the same order as
/// [`candidate_stats_in`], so the same bits (the candidates' sums interleaved, each in line order).
fn exact_line_stats<const L: usize>(prep: &Prepared, offsets: &[isize], bases: [isize; L]) -> [[f64; 6]; L] {
    let n = offsets.len() as f64;
    let mut st = [[0.0; 6]; L];
    for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
        let mut sum = [0.0; L];
        for &off in offsets {
            for l in 0..L {
                sum[l] += plane[(bases[l] + off) as usize];
            }
        }
        let m = sum.map(|v| v / n);
        let mut ss = [0.0; L];
        for &off in offsets {
            for l in 0..L {
                let d = plane[(bases[l] + off) as usize] - m[l];
                ss[l] += d * d;
            }
        }
        for l in 0..L {
            st[l][2 * k] = m[l];
            st[l][2 * k + 1] = ss[l];
        }
    }
    st
}

/// One kind of grid position's lines and candidates (a case of the plain grid, a ring shape of the
/// torus), with the candidate-side data its searches share: the bounds' statistics, and the exact
/// statistics of every candidate only when a search scores every candidate.
struct Shape {
    ls: [Vec<(i32, i32)>; 2],
    ranges: Ranges,
    bounds: BoundStats,
    exact: std::sync::OnceLock<[LineStats; 2]>,
    /// How this shape's FFT bounds went: searches begun with the I channel alone, and those of
    /// them that needed the H and S cross sums too. Where most did, later searches correlate all
    /// three channels at once and skip the I-only pass.
    fft_history: std::sync::Mutex<(usize, usize)>,
}

impl Shape {
    fn new(prep: &Prepared, ls: [Vec<(i32, i32)>; 2], ranges: Ranges) -> Shape {
        let bounds = BoundStats::new(prep, &ls, ranges.clone());
        Shape { ls, ranges, bounds, exact: std::sync::OnceLock::new(), fft_history: std::sync::Mutex::new((0, 0)) }
    }

    fn exact(&self, prep: &Prepared, s: &Settings) -> &[LineStats; 2] {
        self.exact.get_or_init(|| {
            [candidate_stats_in(prep, s, self.ranges.clone(), &self.ls[0]), candidate_stats_in(prep, s, self.ranges.clone(), &self.ls[1])]
        })
    }
}

/// Per candidate position, the candidate side of one line: mean and centred sum of squares of H,
/// S and I (for circular hue: circular mean and Σ sin² instead), computed once per job and case.
type LineStats = Vec<[f64; 6]>;

/// The config in the form the scoring uses.
#[derive(Debug, PartialEq)]
struct Settings {
    block: i32,
    g: i32,
    a: i32,
    weights: [f64; 3],
    mu: f64,
    tau: f64,
    eps: f64,
    circular: bool,
    clamp: bool,
    level_penalty: f64,
}

impl Settings {
    fn of(cfg: &DoubleSeamConfig) -> Settings {
        let (g, aux) = (i64::from(cfg.overlap_or_derived()), i64::from(cfg.aux_dist_or_derived()));
        Settings {
            block: cfg.block as i32,
            g: g as i32,
            a: (g - 1 - aux) as i32,
            weights: [cfg.alpha, cfg.beta, cfg.gamma],
            mu: cfg.mu,
            tau: cfg.tau_f,
            eps: cfg.eps_f,
            circular: cfg.hue_mode == HueMode::Circular,
            clamp: cfg.clamp_negative,
            level_penalty: cfg.level_penalty,
        }
    }
}

impl Method for DoubleSeam {
    fn name(&self) -> &'static str {
        DoubleSeamConfig::METHOD
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn summary(&self) -> &'static str {
        "paper 003: non-overlapping splicing chosen by double-seam consistency in HSI space"
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }

    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        let cfg: DoubleSeamConfig = match super::read_config(p) {
            Ok(c) => c,
            Err(e) => return e,
        };
        let (block, g, aux) = (i64::from(cfg.block), i64::from(cfg.overlap_or_derived()), i64::from(cfg.aux_dist_or_derived()));
        let smaller = sample.0.min(sample.1) as i64;
        let mut errors = super::check_block_and_overlap(cfg.block, cfg.overlap_or_derived(), sample);
        if aux > g {
            errors.push(ParamError::new(
                "aux_dist",
                format!("aux_dist {aux} exceeds the overlap ({g}): the auxiliary line must lie in existing output"),
            ));
        }
        let a = g - 1 - aux;
        if block <= smaller && a < 0 && block - a > smaller {
            errors.push(ParamError::new(
                "aux_dist",
                format!("with aux_dist = overlap the auxiliary line needs the sample to be wider than the block ({block}); use aux_dist = {} or a smaller block", g - 1),
            ));
        }
        for (w, v) in [("alpha", cfg.alpha), ("beta", cfg.beta), ("gamma", cfg.gamma)] {
            if v <= 0.0 || v >= 1.0 {
                errors.push(ParamError::new(w, format!("{w} must be strictly between 0 and 1, got {v}")));
            }
        }
        let sum = cfg.alpha + cfg.beta + cfg.gamma;
        if (sum - 1.0).abs() > 1e-9 {
            errors.push(ParamError::new("alpha", format!("alpha + beta + gamma must be 1, got {sum}")));
        }
        errors
    }

    fn peak_memory(&self, _params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        // Measured (VmHWM of `texsyn run -j 2`, bricks_gray 256², block 50): per output pixel the
        // canvas and its per-pixel seam and cost planes, about 31 B. Per sample pixel, the FFT
        // buffers kept for the job and, on samples whose hue or saturation lines are flat (bricks),
        // the full per-case statistics tables: 67 MiB in all at 512², 79 MiB at 768², 124 MiB at
        // 1536². Since then the spectra are per column and per row (+48 B), and a torus's ring
        // lines (two columns and two rows each) need up to twelve FFT buffers instead of six (+96 B).
        crate::synth::method::linear_memory(sample, output, 40.0, 464.0, 16 << 20)
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let s = Settings::of(&DoubleSeamConfig::from_params(req.params)?);
        let sample = req.sample;
        let (sw, sh) = (sample.width() as i32, sample.height() as i32);
        if s.block > sw || s.block > sh {
            return Err(SynthError::Failed(format!("block {} does not fit in the {sw}x{sh} sample", s.block)));
        }
        let prep = Prepared::of(sample);
        let mask = MaskPositions::of(req, s.block as u32)?;
        if req.tileable {
            return synthesize_torus(req, &s, &prep, &mask);
        }
        let (block, g) = (s.block as u32, s.g as u32);
        // The quilting grid; the overlap is only virtual here.
        let grid = BlockGrid::new(block, g, req.width, req.height);
        let (stride, cols, rows) = (grid.stride(), grid.cols, grid.rows);
        let (cw, ch) = grid.canvas();
        let mut out = Canvas::new(cw, ch, sample.dimensions(), req.placement);
        let mut shapes: Vec<(Case, Shape)> = Vec::new();
        let mut picks = vec![(0i32, 0i32); (rows * cols) as usize];
        let mut set_sizes = Vec::new();
        let mut f_max_sum = 0.0;
        for bi in 0..rows {
            for bj in 0..cols {
                let (ox, oy) = grid.origin(bi, bj);
                let (x, y) = if bi == 0 && bj == 0 {
                    mask.first(req.seed)
                } else {
                    let case = if bi == 0 {
                        Case::Horizontal
                    } else if bj == 0 {
                        Case::Vertical
                    } else {
                        Case::L
                    };
                    if !shapes.iter().any(|(c, _)| *c == case) {
                        shapes.push((case, Shape::new(&prep, lines(case, s.block, s.g, s.a), admissible(&prep, &s, case))));
                    }
                    let shape = &shapes.iter().find(|(c, _)| *c == case).expect("computed").1;
                    // The natural continuations of the left and the upper neighbour.
                    let mut hints = Vec::new();
                    if bj > 0 {
                        let (px, py) = picks[(bi * cols + bj - 1) as usize];
                        hints.push((px + stride as i32, py));
                    }
                    if bi > 0 {
                        let (px, py) = picks[((bi - 1) * cols + bj) as usize];
                        hints.push((px, py + stride as i32));
                    }
                    let origin = (ox as i32, oy as i32);
                    // Never the turned or mirrored copy of a neighbour's own pixels (several
                    // samples' atlas with `augment`): it would paste a symmetric motif.
                    let (i, j, n) = (i64::from(bi), i64::from(bj), i64::from(cols));
                    let neighbours = non_negative(
                        [(i, j - 1), (i - 1, j - 1), (i - 1, j), (i - 1, j + 1)]
                            .into_iter()
                            .filter(|&(i, j)| i >= 0 && j >= 0 && j < n)
                            .map(|(i, j)| picks[(i * n + j) as usize]),
                    );
                    let allowed = |x: i32, y: i32| mask.allows(x, y) && !twin_of(req, (x, y), &neighbours, s.block as u32);
                    let twins_possible = req.constraints.atlas.is_some_and(|a| a.has_copies());
                    let restrict: Option<&Allowed<'_>> = if mask.positions.is_some() || twins_possible { Some(&allowed) } else { None };
                    let (pick, size, f_max) = choose(&prep, &s, shape, &out, origin, &hints, (req.seed, bi, bj), restrict)?;
                    set_sizes.push(size);
                    f_max_sum += f_max;
                    pick
                };
                picks[(bi * cols + bj) as usize] = (x, y);
                let c0 = if bj > 0 { g } else { 0 };
                let r0 = if bi > 0 { g } else { 0 };
                out.paste(&prep, (x as u32, y as u32), (ox, oy), c0..block, r0..block);
            }
        }
        let (image, placement) = out.rgb.into_top_left(req.width, req.height).finish();
        let band = |count: u32, limit: u32| -> Vec<SeamBand> {
            (1..count).map(|k| k * stride + g).filter(|&b| b < limit).map(|start| SeamBand { start, len: 1 }).collect()
        };
        let seams = SeamGrid { columns: band(cols, req.width), rows: band(rows, req.height) };
        let n = set_sizes.len().max(1) as f64;
        let diagnostics = serde_json::json!({
            "blocks": { "cols": cols, "rows": rows },
            "mean_candidates": set_sizes.iter().sum::<usize>() as f64 / n,
            "mean_f_max": f_max_sum / n,
        });
        Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
    }

    fn tileable(&self, p: &Params, sample: (u32, u32), output: (u32, u32)) -> Result<(), String> {
        let s = Settings::of(&DoubleSeamConfig::from_params(p).map_err(|e| e.to_string())?);
        torus_of(&s, sample, output).map(|_| ())
    }

    fn honours_sample_mask(&self) -> bool {
        true
    }
}

// Tileable double-seam splicing. On a torus every block pastes only its `(B − g)²` part
// `[g, B)²` (the first block too), at stride `B − g`, so the pasted parts tile the output exactly
// once and the last column's part ends where the first column's begins. At a size that is not a
// whole number of strides the torus spaces some blocks a pixel closer (`TorusGrid`'s fit), and
// those paste the narrower part `[g, g + spacing)` so the parts still tile the output. The choice keeps the
// paper's criterion: two one-pixel lines per block, the true seam (the existing pixels next to the
// pasted part) and the auxiliary line `aux_dist` further out, each scored by the HSI correlations
// and edge agreement of eqs. 6-10. Where the plain grid has those lines on the left and top only,
// here they run on every side that already holds content: for the last column also the right
// (the first column of the row, through the wrap), for the last row also the bottom. Each line
// is one sequence around the pasted square (as the plain L case joins its left and top parts), so
// a candidate is judged on how well it continues into all its neighbours at once. (Scoring the
// wrapped sides as separate sequences and taking the worst part's F was tried and made the seams
// where the wrap closes more visible: 1.47 times the other seams' visibility on average over the
// seven test samples and three seeds, against 1.11 with the joined ring.) Being outside
// the pasted part, right and bottom lines read the candidate's sample pixels just beyond the
// block, so the wrapped blocks need a sample a little larger than the block.

/// The torus a tileable output is made on, or why there is none.
fn torus_of(s: &Settings, sample: (u32, u32), output: (u32, u32)) -> Result<TorusGrid, String> {
    let smaller = sample.0.min(sample.1) as i32;
    let (b, g, d) = (s.block, s.g, s.g - 1 - s.a);
    // A block with lines on all four sides reads the sample from g − 1 − aux to B + aux.
    let need = b + d + 1 + (d + 1 - g).max(0);
    if need > smaller {
        return Err(format!(
            "tileable double-seam reads {need} sample pixels around a wrapped block (block {b} and the seam lines {d} beyond it on both sides), more than the {}x{} sample has; use a smaller block or aux_dist",
            sample.0, sample.1
        ));
    }
    TorusGrid::new("double-seam", b as u32, g as u32, output.0, output.1)
}

/// The true and the auxiliary line of block `(bi, bj)` on the torus: the rings `d = 0` and
/// `d = aux_dist` around the pasted square `[g, B)²` (offsets relative to the block origin), each
/// the ring's pixels that already hold content, in a fixed order (top, left, right, bottom).
fn torus_lines(torus: &TorusGrid, done: &[bool], s: &Settings, bi: u32, bj: u32) -> [Vec<(i32, i32)>; 2] {
    let (w, h) = torus.size();
    let (w, h, g) = (w as i32, h as i32, s.g);
    let (ox, oy) = torus.origin(bi, bj);
    // The pasted part ends where the next block's begins.
    let (end_c, end_r) = (g + torus.spacing_x(bj) as i32, g + torus.spacing_y(bi) as i32);
    // Output pixel (x, y) is pasted by the block whose part `[g, g + spacing)²` covers it.
    let filled = |c: i32, r: i32| {
        let x = torus.column_at((ox as i32 + c - g).rem_euclid(w) as u32);
        let y = torus.row_at((oy as i32 + r - g).rem_euclid(h) as u32);
        done[torus.index(y, x)]
    };
    let ring = |d: i32| -> Vec<(i32, i32)> {
        let (lo, hi_c, hi_r) = (g - 1 - d, end_c + d, end_r + d);
        let top = (lo..=hi_c).map(|c| (c, lo));
        let left = (lo + 1..hi_r).map(|r| (lo, r));
        let right = (lo + 1..hi_r).map(|r| (hi_c, r));
        let bottom = (lo..=hi_c).map(|c| (c, hi_r));
        top.chain(left).chain(right).chain(bottom).filter(|&(c, r)| filled(c, r)).collect()
    };
    [ring(0), ring(g - 1 - s.a)]
}

/// The candidate positions whose sample pixels cover both lines and the block.
fn line_ranges(prep: &Prepared, s: &Settings, ls: &[Vec<(i32, i32)>; 2]) -> Ranges {
    let (sw, sh) = (prep.w as i32, (prep.planes.i.len() / prep.w) as i32);
    let all = || ls.iter().flatten();
    let min_c = all().map(|p| p.0).min().unwrap_or(0).min(0);
    let min_r = all().map(|p| p.1).min().unwrap_or(0).min(0);
    let max_c = all().map(|p| p.0).max().unwrap_or(0).max(s.block - 1);
    let max_r = all().map(|p| p.1).max().unwrap_or(0).max(s.block - 1);
    (-min_c..=sw - 1 - max_c, -min_r..=sh - 1 - max_r)
}

fn synthesize_torus(req: &Request, s: &Settings, prep: &Prepared, mask: &MaskPositions) -> Result<Synthesis, SynthError> {
    let sample = req.sample;
    let torus = torus_of(s, sample.dimensions(), (req.width, req.height)).map_err(SynthError::Failed)?;
    // A lattice the output's size keeps whole across the wrap: every block in the first block's
    // lattice phase, so the texels run on through the wrap as they do inside.
    let phase = LatticePhase::of(sample, (req.width, req.height));
    let mut first_shift = (0.0, 0.0);
    let mut phase_missed = 0usize;
    let g = s.g as u32;
    let (w, h) = torus.size();
    let mut out = Canvas::new(w, h, sample.dimensions(), req.placement);
    let mut done = vec![false; (torus.rows * torus.cols) as usize];
    let mut picks = vec![(0i32, 0i32); done.len()];
    // Line statistics per line shape: a handful of shapes per job (first row, interior, last
    // column, last row, ...).
    let mut shapes: Vec<Shape> = Vec::new();
    let mut set_sizes = Vec::new();
    let mut f_max_sum = 0.0;
    for (bi, bj) in torus.raster() {
        let (ox, oy) = torus.origin(bi, bj);
        let (x, y) = if bi == 0 && bj == 0 {
            let (x, y) = mask.first(req.seed);
            first_shift = LatticePhase::shift((x, y), (ox as i32, oy as i32));
            (x, y)
        } else {
            let ls = torus_lines(&torus, &done, s, bi, bj);
            let k = match shapes.iter().position(|shape| shape.ls == ls) {
                Some(k) => k,
                None => {
                    let ranges = line_ranges(prep, s, &ls);
                    shapes.push(Shape::new(prep, ls, ranges));
                    shapes.len() - 1
                }
            };
            let shape = &shapes[k];
            // The natural continuations of the neighbours already there (through the wrap too).
            let (r, c) = (torus.rows, torus.cols);
            let (left, up) = ((bj + c - 1) % c, (bi + r - 1) % r);
            let mut hints = Vec::new();
            for (ni, nj, dx, dy) in [
                (bi, left, torus.spacing_x(left) as i32, 0),
                (up, bj, 0, torus.spacing_y(up) as i32),
                (bi, (bj + 1) % c, -(torus.spacing_x(bj) as i32), 0),
                ((bi + 1) % r, bj, 0, -(torus.spacing_y(bi) as i32)),
            ] {
                if done[torus.index(ni, nj)] {
                    let (px, py) = picks[torus.index(ni, nj)];
                    hints.push((px + dx, py + dy));
                }
            }
            let origin = (ox as i32, oy as i32);
            let neighbours = non_negative(
                [r - 1, 0, 1]
                    .into_iter()
                    .flat_map(|di| [c - 1, 0, 1].into_iter().map(move |dj| ((bi + di) % r, (bj + dj) % c)))
                    .filter(|&(ni, nj)| (ni, nj) != (bi, bj) && done[torus.index(ni, nj)])
                    .map(|(ni, nj)| picks[torus.index(ni, nj)]),
            );
            let allowed = |x: i32, y: i32| {
                mask.allows(x, y)
                    && phase.as_ref().is_none_or(|p| {
                        let d = LatticePhase::shift((x, y), origin);
                        p.keeps((d.0 - first_shift.0, d.1 - first_shift.1))
                    })
                    && !twin_of(req, (x, y), &neighbours, s.block as u32)
            };
            let twins_possible = req.constraints.atlas.is_some_and(|a| a.has_copies());
            let restrict: Option<&Allowed<'_>> =
                if mask.positions.is_some() || phase.is_some() || twins_possible { Some(&allowed) } else { None };
            let masked = |x: i32, y: i32| mask.allows(x, y);
            let mask_only: Option<&Allowed<'_>> = if mask.positions.is_some() { Some(&masked) } else { None };
            let (pick, size, f_max) = match choose(prep, s, shape, &out, origin, &hints, (req.seed, bi, bj), restrict) {
                // No position in the lattice phase lies where this block's seam lines fit (a
                // lattice cell large next to the sample): the block goes without the phase.
                Err(_) if phase.is_some() => {
                    phase_missed += 1;
                    choose(prep, s, shape, &out, origin, &hints, (req.seed, bi, bj), mask_only)?
                }
                r => r?,
            };
            set_sizes.push(size);
            f_max_sum += f_max;
            pick
        };
        out.paste(prep, (x as u32, y as u32), (ox, oy), g..g + torus.spacing_x(bj), g..g + torus.spacing_y(bi));
        done[torus.index(bi, bj)] = true;
        picks[torus.index(bi, bj)] = (x, y);
    }
    let (image, placement) = out.rgb.finish();
    // Each pasted part starts at its block's origin + g; block 0's is where the wrap closes.
    let seams = SeamGrid {
        columns: (0..torus.cols).map(|k| SeamBand { start: torus.origin(0, k).0 + g, len: 1 }).collect(),
        rows: (0..torus.rows).map(|k| SeamBand { start: torus.origin(k, 0).1 + g, len: 1 }).collect(),
    };
    let n = set_sizes.len().max(1) as f64;
    let mut diagnostics = serde_json::json!({
        "blocks": { "cols": torus.cols, "rows": torus.rows },
        "tileable": true,
        "mean_candidates": set_sizes.iter().sum::<usize>() as f64 / n,
        "mean_f_max": f_max_sum / n,
    });
    torus.record_fit(&mut diagnostics);
    if let Some(p) = &phase {
        diagnostics["lattice_phase"] = p.describe();
        diagnostics["lattice_phase"]["blocks_out_of_phase"] = serde_json::json!(phase_missed);
    }
    Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
}

/// The block positions a request's sample mask allows (every pixel of the block, a superset of
/// what any block pastes), or every position when it has none.
struct MaskPositions {
    /// Row-major over `(W − B + 1) × (H − B + 1)`; `None` when every position is allowed.
    positions: Option<Vec<bool>>,
    cols: i32,
    rows: i32,
}

impl MaskPositions {
    fn of(req: &Request, block: u32) -> Result<MaskPositions, SynthError> {
        let (cols, rows) = (req.sample.width() as i32 - block as i32 + 1, req.sample.height() as i32 - block as i32 + 1);
        let Some(mask) = req.constraints.copyable() else { return Ok(MaskPositions { positions: None, cols, rows }) };
        let positions = mask.block_positions(block, block);
        if !positions.contains(&true) {
            return Err(SynthError::param(
                "block",
                format!(
                    "the sample mask leaves no whole {block}x{block} block to copy; the largest block it allows is {}",
                    mask.largest_block()
                ),
            ));
        }
        Ok(MaskPositions { positions: Some(positions), cols, rows })
    }

    fn allows(&self, x: i32, y: i32) -> bool {
        self.positions.as_ref().is_none_or(|v| x >= 0 && y >= 0 && x < self.cols && y < self.rows && v[(y * self.cols + x) as usize])
    }

    /// The first block's position (stream `seam/first`): uniform over the sample, or over the
    /// allowed positions with a mask.
    fn first(&self, seed: u64) -> (i32, i32) {
        let mut st = Stream::new(seed, "seam/first");
        match &self.positions {
            None => {
                let x = st.below(self.cols as u64) as i32;
                let y = st.below(self.rows as u64) as i32;
                (x, y)
            }
            Some(v) => {
                let n = v.iter().filter(|&&a| a).count();
                let k = v.iter().enumerate().filter(|(_, a)| **a).nth(st.below_usize(n)).expect("an allowed position").0 as i32;
                (k % self.cols, k / self.cols)
            }
        }
    }
}

/// The candidate set `F ≥ min(tau_f, F_max − eps_f)` and one member drawn from it: the position,
/// the set's size and `F_max`.
fn pick(
    s: &Settings,
    positions: &[(i32, i32)],
    scores: &[f64],
    seed: u64,
    bi: u32,
    bj: u32,
) -> Result<((i32, i32), usize, f64), SynthError> {
    let f_max = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let theta = s.tau.min(f_max - s.eps);
    let members: Vec<(i32, i32)> = positions.iter().zip(scores).filter(|(_, f)| **f >= theta).map(|(p, _)| *p).collect();
    if members.is_empty() {
        return Err(SynthError::Failed(format!("no candidate position at grid ({bi}, {bj}) (all scores undefined)")));
    }
    let mut st = Stream::new(seed, &format!("seam/pick/bi={bi}/bj={bj}"));
    Ok((members[st.below_usize(members.len())], members.len(), f_max))
}

/// The output being built: RGB plus the HSI values and edge bits of the pasted sample pixels
/// (the output's edge map is never recomputed, §5.2).
struct Canvas {
    rgb: PixelCanvas,
    w: usize,
    rows: usize,
    h: Vec<f64>,
    s: Vec<f64>,
    i: Vec<f64>,
    e: Vec<u8>,
}

impl Canvas {
    fn new(w: u32, h: u32, sample: (u32, u32), record: bool) -> Canvas {
        let n = w as usize * h as usize;
        Canvas {
            rgb: PixelCanvas::new(w, h, sample, record),
            w: w as usize,
            rows: h as usize,
            h: vec![0.0; n],
            s: vec![0.0; n],
            i: vec![0.0; n],
            e: vec![0; n],
        }
    }

    /// Copies columns `cols` and rows `rows` of the sample block at `src` to the block at `dst`.
    fn paste(&mut self, prep: &Prepared, src: (u32, u32), dst: (u32, u32), cols: std::ops::Range<u32>, rows: std::ops::Range<u32>) {
        // Wrapped, for a torus; the plain canvas holds every block, so there it changes nothing.
        let dxs: Vec<u32> = cols.clone().map(|c| (dst.0 + c) % self.w as u32).collect();
        for r in rows {
            let dy = (dst.1 + r) % self.rows as u32;
            for (c, &dx) in cols.clone().zip(&dxs) {
                let (sx, sy) = (src.0 + c, src.1 + r);
                self.rgb.copy(dx, dy, prep.rgb, sx, sy);
                let si = sy as usize * prep.w + sx as usize;
                let di = dy as usize * self.w + dx as usize;
                self.h[di] = prep.planes.h[si];
                self.s[di] = prep.planes.s[si];
                self.i[di] = prep.planes.i[si];
                self.e[di] = prep.edges[si];
            }
        }
    }
}

/// Candidate positions as inclusive ranges of `x` and `y`.
type Ranges = (std::ops::RangeInclusive<i32>, std::ops::RangeInclusive<i32>);

/// Admissible candidate positions of a case, as inclusive ranges of `x` and `y`.
fn admissible(prep: &Prepared, s: &Settings, case: Case) -> Ranges {
    let (sw, sh) = (prep.w as i32, (prep.planes.i.len() / prep.w) as i32);
    let lo = (-s.a).max(0);
    let x0 = if matches!(case, Case::Horizontal | Case::L) { lo } else { 0 };
    let y0 = if matches!(case, Case::Vertical | Case::L) { lo } else { 0 };
    (x0..=sw - s.block, y0..=sh - s.block)
}

/// Candidate-side statistics of one line at every admissible position (row-major).
#[cfg(test)]
fn candidate_stats(prep: &Prepared, s: &Settings, case: Case, line: &[(i32, i32)]) -> LineStats {
    candidate_stats_in(prep, s, admissible(prep, s, case), line)
}

/// [`candidate_stats`] over given position ranges. Candidates in blocks of LANES along a row,
/// each candidate's sums in line order as a two-pass mean and centred sum of squares.
fn candidate_stats_in(prep: &Prepared, s: &Settings, (xs, ys): Ranges, line: &[(i32, i32)]) -> LineStats {
    const LANES: usize = 8;
    let n = line.len() as f64;
    let w = prep.w as i32;
    let ys: Vec<i32> = ys.collect();
    let (x0, nx) = (*xs.start(), (xs.end() - xs.start() + 1).max(0) as usize);
    ys.par_iter()
        .flat_map_iter(|&y| {
            let offsets: Vec<usize> = line.iter().map(|&(c, r)| ((y + r) * w + x0 + c) as usize).collect();
            let mut row = vec![[0.0; 6]; nx];
            for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                if k == 0 && s.circular {
                    for (x, out) in row.iter_mut().enumerate() {
                        let (sn, cs) =
                            offsets.iter().fold((0.0, 0.0), |(a, b), &i| (a + (TAU * plane[i + x]).sin(), b + (TAU * plane[i + x]).cos()));
                        let m = sn.atan2(cs);
                        let ss: f64 = offsets.iter().map(|&i| (TAU * plane[i + x] - m).sin().powi(2)).sum();
                        out[0] = m;
                        out[1] = ss;
                    }
                    continue;
                }
                let mut x = 0;
                while x < nx {
                    let lanes = LANES.min(nx - x);
                    let mut sum = [0.0f64; LANES];
                    for &i in &offsets {
                        for l in 0..lanes {
                            sum[l] += plane[i + x + l];
                        }
                    }
                    let mut m = [0.0f64; LANES];
                    for l in 0..lanes {
                        m[l] = sum[l] / n;
                    }
                    let mut ss = [0.0f64; LANES];
                    for &i in &offsets {
                        for l in 0..lanes {
                            let d = plane[i + x + l] - m[l];
                            ss[l] += d * d;
                        }
                    }
                    for l in 0..lanes {
                        row[x + l][2 * k] = m[l];
                        row[x + l][2 * k + 1] = ss[l];
                    }
                    x += lanes;
                }
            }
            row
        })
        .collect()
}

/// The output side of one line: per channel the centred values (or hue sines), mean and sum of
/// squares, plus the edge bits.
struct OutputLine {
    centred: [Vec<f64>; 3],
    mean: [f64; 3],
    ss: [f64; 3],
    edges: Vec<u8>,
}

fn output_line(out: &Canvas, s: &Settings, origin: (i32, i32), line: &[(i32, i32)]) -> OutputLine {
    // Wrapped, for a torus; on the plain canvas every line pixel is inside, so this is the identity.
    let (w, h) = (out.w as i32, out.rows as i32);
    let idx: Vec<usize> =
        line.iter().map(|&(c, r)| ((origin.1 + r).rem_euclid(h) as usize) * out.w + (origin.0 + c).rem_euclid(w) as usize).collect();
    let n = line.len() as f64;
    let mut centred: [Vec<f64>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    let mut mean = [0.0; 3];
    let mut ss = [0.0; 3];
    for (k, plane) in [&out.h, &out.s, &out.i].into_iter().enumerate() {
        if k == 0 && s.circular {
            let (sn, cs) = idx.iter().fold((0.0, 0.0), |(a, b), &i| (a + (TAU * plane[i]).sin(), b + (TAU * plane[i]).cos()));
            let m = sn.atan2(cs);
            centred[0] = idx.iter().map(|&i| (TAU * plane[i] - m).sin()).collect();
            mean[0] = m;
        } else {
            let m = idx.iter().map(|&i| plane[i]).sum::<f64>() / n;
            centred[k] = idx.iter().map(|&i| plane[i] - m).collect();
            mean[k] = m;
        }
        ss[k] = centred[k].iter().map(|v| v * v).sum();
    }
    OutputLine { centred, mean, ss, edges: idx.iter().map(|&i| out.e[i]).collect() }
}

/// `F = F_1 + F_2` at every admissible position, row-major, evaluated in parallel by rows; each
/// value's arithmetic is fixed, so the result does not depend on the thread count.
#[cfg(test)]
fn score_all(
    prep: &Prepared,
    s: &Settings,
    case: Case,
    stats: &[LineStats; 2],
    out: &Canvas,
    origin: (i32, i32),
) -> (Vec<(i32, i32)>, Vec<f64>) {
    score_lines(prep, s, &lines(case, s.block, s.g, s.a), admissible(prep, s, case), stats, out, origin)
}

#[cfg(test)]
mod tests;
