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

mod phase;
use phase::LatticePhase;

pub struct DoubleSeam;

/// `level_penalty`'s default. The paper's criterion (0) ignores a line's brightness, so blocks of
/// another tone pass as consistent and leave steps (docs/methods.md §5, gap 5). Seen at 384² from
/// 256² on the 35 samples of the advice test: 3 to 5 remove most steps (a gray stone wall, cream
/// tiles, terracotta, a lit wall, a blotchy stone) and lower the seams' colour jumps by 4 % on
/// average (geometric mean of seam visibility against 0); 10 weighs tone over pattern, ends more
/// cracks and mortar lines at block edges (a carved wall, cream tiles) and raises the jumps by 2 %.
pub const DEFAULT_LEVEL_PENALTY: f64 = 4.0;

const PARAMS: &[ParamSpec] = &[
    ParamSpec { name: "block", kind: ParamKind::Int { min: 3, max: 4096 }, default: Default::Int(50), doc: "block side B" },
    ParamSpec {
        name: "overlap",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived {
            rule: "round(block / 6)",
            compute: |p| Some(ParamValue::Int(super::default_overlap(p.int("block").ok()?))),
        },
        doc: "virtual overlap g: grid stride is block − g (paper: 8 for B = 50, 17 for B = 100)",
    },
    ParamSpec {
        name: "aux_dist",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived { rule: "overlap", compute: |p| Some(ParamValue::Int(p.int("overlap").ok()?)) },
        doc: "spacing of the auxiliary seam line from the true one, 1..=overlap (overlap − 1 keeps it inside the window)",
    },
    ParamSpec {
        name: "alpha",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.25),
        doc: "weight of the hue correlation (alpha + beta + gamma = 1)",
    },
    ParamSpec {
        name: "beta",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.25),
        doc: "weight of the saturation correlation",
    },
    ParamSpec {
        name: "gamma",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.5),
        doc: "weight of the intensity correlation",
    },
    ParamSpec {
        name: "mu",
        kind: ParamKind::Float { min: 0.0, max: 1.0e6 },
        default: Default::Float(2.0),
        doc: "edge-mismatch penalty: F_i = D_HSI / (1 + mu·D_E)",
    },
    ParamSpec {
        name: "tau_f",
        kind: ParamKind::Float { min: -2.0, max: 2.0 },
        default: Default::Float(1.6),
        doc: "candidates need F ≥ min(tau_f, F_max − eps_f)",
    },
    ParamSpec {
        name: "eps_f",
        kind: ParamKind::Float { min: 0.0, max: 4.0 },
        default: Default::Float(0.05),
        doc: "near-best margin when no position reaches tau_f",
    },
    ParamSpec {
        name: "hue_mode",
        kind: ParamKind::Choice(HueMode::NAMES),
        default: Default::Str("linear"),
        doc: "linear: Pearson on H/360 (faithful); circular: circular correlation (hue is an angle)",
    },
    ParamSpec {
        name: "clamp_negative",
        kind: ParamKind::Bool,
        default: Default::Bool(false),
        doc: "use max(D_HSI, 0) so a negative correlation is not softened by the edge term",
    },
    ParamSpec {
        name: "level_penalty",
        kind: ParamKind::Float { min: 0.0, max: 1000.0 },
        default: Default::Float(DEFAULT_LEVEL_PENALTY),
        doc: "0 = faithful (paper 003). Pearson ignores brightness offsets, so blocks of another tone pass as consistent and leave colour steps; > 0 subtracts level_penalty·|mean I difference| per line (default 4)",
    },
];

crate::choice! {
    /// How hue, an angle, is correlated (`hue_mode`).
    pub enum HueMode {
        /// Pearson correlation of H / 360, as in the paper.
        Linear = "linear",
        /// Circular correlation.
        Circular = "circular",
    }
}

/// Double-seam splicing's parameters, typed: one field per entry of its parameter table.
#[derive(Clone, Debug, PartialEq)]
pub struct DoubleSeamConfig {
    /// `block`: block side B, in pixels (3..=4096, at most the sample's smaller side).
    pub block: u32,
    /// `overlap`: virtual overlap g, the grid stride being `block − g` (1..=2048, at most
    /// block / 2); `None`: derived, `round(block / 6)`.
    pub overlap: Option<u32>,
    /// `aux_dist`: spacing of the auxiliary seam line from the true one (1..=overlap); `None`:
    /// derived, equal to the overlap.
    pub aux_dist: Option<u32>,
    /// `alpha`: weight of the hue correlation (strictly between 0 and 1; alpha + beta + gamma = 1).
    pub alpha: f64,
    /// `beta`: weight of the saturation correlation.
    pub beta: f64,
    /// `gamma`: weight of the intensity correlation.
    pub gamma: f64,
    /// `mu`: edge-mismatch penalty, `F_i = D_HSI / (1 + mu·D_E)` (0..=1e6).
    pub mu: f64,
    /// `tau_f`: candidates need `F ≥ min(tau_f, F_max − eps_f)` (-2..=2).
    pub tau_f: f64,
    /// `eps_f`: near-best margin when no position reaches `tau_f` (0..=4).
    pub eps_f: f64,
    /// `hue_mode`: linear (faithful) or circular hue correlation.
    pub hue_mode: HueMode,
    /// `clamp_negative`: use `max(D_HSI, 0)`.
    pub clamp_negative: bool,
    /// `level_penalty`: subtract `level_penalty·|mean I difference|` per line; 0 is faithful
    /// (0..=1000). The default is [`DEFAULT_LEVEL_PENALTY`], not the paper's 0.
    pub level_penalty: f64,
}

impl std::default::Default for DoubleSeamConfig {
    fn default() -> DoubleSeamConfig {
        DoubleSeamConfig {
            block: 50,
            overlap: None,
            aux_dist: None,
            alpha: 0.25,
            beta: 0.25,
            gamma: 0.5,
            mu: 2.0,
            tau_f: 1.6,
            eps_f: 0.05,
            hue_mode: HueMode::Linear,
            clamp_negative: false,
            level_penalty: DEFAULT_LEVEL_PENALTY,
        }
    }
}

impl DoubleSeamConfig {
    /// The virtual overlap: the given one, else the derived default `round(block / 6)`.
    pub fn overlap_or_derived(&self) -> u32 {
        self.overlap.unwrap_or_else(|| super::default_overlap(i64::from(self.block)) as u32)
    }

    /// The auxiliary line's spacing: the given one, else the derived default (the overlap).
    pub fn aux_dist_or_derived(&self) -> u32 {
        self.aux_dist.unwrap_or_else(|| self.overlap_or_derived())
    }
}

impl MethodConfig for DoubleSeamConfig {
    const METHOD: &'static str = "double-seam";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = vec![params::int("block", self.block)];
        v.extend(self.overlap.map(|o| params::int("overlap", o)));
        v.extend(self.aux_dist.map(|a| params::int("aux_dist", a)));
        v.extend([
            params::float("alpha", self.alpha),
            params::float("beta", self.beta),
            params::float("gamma", self.gamma),
            params::float("mu", self.mu),
            params::float("tau_f", self.tau_f),
            params::float("eps_f", self.eps_f),
            params::word("hue_mode", self.hue_mode),
            params::boolean("clamp_negative", self.clamp_negative),
            params::float("level_penalty", self.level_penalty),
        ]);
        v
    }

    fn from_params(p: &Params) -> Result<DoubleSeamConfig, SynthError> {
        Ok(DoubleSeamConfig {
            block: p.uint("block")?,
            overlap: Some(p.uint("overlap")?),
            aux_dist: Some(p.uint("aux_dist")?),
            alpha: p.float("alpha")?,
            beta: p.float("beta")?,
            gamma: p.float("gamma")?,
            mu: p.float("mu")?,
            tau_f: p.float("tau_f")?,
            eps_f: p.float("eps_f")?,
            hue_mode: p.choice("hue_mode")?,
            clamp_negative: p.bool("clamp_negative")?,
            level_penalty: p.float("level_penalty")?,
        })
    }
}

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

/// [`choose`] bounds the candidates by FFT when more than 1/this of them survive the edge bound:
/// the I-channel transforms cost about as much as scoring that many in full.
const FFT_BEYOND: usize = 16;

/// [`choose`] computes the H and S cross sums too when more than 1/this of the candidates survive
/// the I-channel bounds: their correlations (two more inverse 1-D transforms per sample column and
/// row reached) cost about as much as scoring that many in full.
const FULL_BOUNDS_BEYOND: usize = 32;

/// Slack added to an upper bound of `F` before it may rule a candidate out: far above the few
/// ulps by which a computed Pearson correlation can exceed 1, far below any score difference
/// that matters.
const BOUND_SLACK: f64 = 1e-7;

/// Whether a candidate whose `F` is at most `bound` may reach `theta` (a NaN bound may).
fn may_reach(bound: f64, theta: f64) -> bool {
    (bound + BOUND_SLACK).partial_cmp(&theta) != Some(std::cmp::Ordering::Less)
}

/// How many candidates [`choose`] scores in full at once: independent sums to interleave.
const LANES: usize = 4;

/// The candidate set and the pick of one grid position: the same as [`score_lines`] followed by
/// [`pick`], without scoring every candidate in full where that is not needed. `hints` are
/// positions likely to score well (the natural continuations of the neighbours); they are scored
/// in full first, which bounds `F_max` from below and so `θ` from below. `D_HSI ≤ α + β + γ`
/// bounds each line's `F_i` by the edge term alone, from the edge mismatches (exact integers):
/// every candidate whose bound (plus [`BOUND_SLACK`]) stays under that `θ` is out (its `F` is
/// below `θ`, so it is neither a member nor the maximum), and the rest are scored in full. When
/// the bound rules out too few, [`FftBounds`] bounds every candidate. Every full score is
/// computed with the same operations in the same order as [`score_lines`] (per channel the cross
/// sums are independent sums in line order; the candidate's statistics come from the shape's
/// table or [`exact_line_stats`], the same bits), so `F_max`, `θ` and the set are bit for bit the
/// same. The table of every candidate's statistics is built only once some search has many
/// survivors: most searches score a handful.
/// Which candidate positions (the block's top-left corner in the sample) a block may take: those
/// whose copied pixels the sample mask allows, and on a tileable output that keeps a lattice, those
/// in the first block's lattice phase.
type Allowed<'a> = dyn Fn(i32, i32) -> bool + Sync + 'a;

/// Whether a block at `at` would show a turned or mirrored copy of a neighbour's pixels
/// ([`crate::synth::atlas::Atlas::twins`]).
fn twin_of(req: &Request, (x, y): (i32, i32), neighbours: &[(u32, u32)], block: u32) -> bool {
    x >= 0 && y >= 0 && req.constraints.is_twin((x as u32, y as u32), neighbours, block)
}

/// Picks (sample positions) as the twin test takes them.
fn non_negative(picks: impl Iterator<Item = (i32, i32)>) -> Vec<(u32, u32)> {
    picks.filter(|&(x, y)| x >= 0 && y >= 0).map(|(x, y)| (x as u32, y as u32)).collect()
}

#[allow(clippy::too_many_arguments)]
fn choose(
    prep: &Prepared,
    s: &Settings,
    shape: &Shape,
    out: &Canvas,
    origin: (i32, i32),
    hints: &[(i32, i32)],
    (seed, bi, bj): (u64, u32, u32),
    allowed: Option<&Allowed<'_>>,
) -> Result<((i32, i32), usize, f64), SynthError> {
    let (ls, (xs, ys)) = (&shape.ls, shape.ranges.clone());
    let ok = |x: i32, y: i32| allowed.is_none_or(|a| a(x, y));
    let everything = || -> Result<((i32, i32), usize, f64), SynthError> {
        let (positions, scores) = score_lines(prep, s, ls, (xs.clone(), ys.clone()), shape.exact(prep, s), out, origin);
        if allowed.is_none() {
            return pick(s, &positions, &scores, seed, bi, bj);
        }
        let (positions, scores): (Vec<(i32, i32)>, Vec<f64>) = positions.into_iter().zip(scores).filter(|(p, _)| ok(p.0, p.1)).unzip();
        if positions.is_empty() {
            return Err(SynthError::Failed(format!(
                "no candidate position at grid ({bi}, {bj}) is allowed (sample mask, lattice phase) with its seam lines in the sample"
            )));
        }
        pick(s, &positions, &scores, seed, bi, bj)
    };
    if s.circular {
        return everything();
    }
    let outs = [output_line(out, s, origin, &ls[0]), output_line(out, s, origin, &ls[1])];
    let nx = (xs.end() - xs.start() + 1) as usize;
    let (x0, y0) = (*xs.start(), *ys.start());
    let ny = (ys.end() - ys.start() + 1).max(0) as usize;
    let w = prep.w as i32;
    let ns = [ls[0].len() as f64, ls[1].len() as f64];
    // Line offsets relative to a candidate's (x, y) in the sample (y·w + x ≥ every negative one).
    let offsets: [Vec<isize>; 2] = [0, 1].map(|li| ls[li].iter().map(|&(c, r)| (r * w + c) as isize).collect());
    let base_of = |k: usize| ((y0 + (k / nx) as i32) * w + x0) as isize + (k % nx) as isize;
    let mismatches_of = |k: usize, li: usize| -> u32 {
        let base = base_of(k);
        let o = &outs[li];
        offsets[li].iter().zip(&o.edges).map(|(&off, &e1)| u32::from(e1 != prep.edges[(base + off) as usize])).sum()
    };
    // The full scores of LANES candidates at once, each in exactly score_lines' order of
    // operations (the lanes only interleave independent sums, so each is the same bits).
    let full_lanes = |ks: [usize; LANES], mism: [[u32; 2]; LANES]| -> [f64; LANES] {
        let bases = ks.map(base_of);
        let mut f = [0.0; LANES];
        for li in 0..2 {
            let o = &outs[li];
            // The shape's table when a search has needed it, else the same values computed here.
            let stx = match shape.exact.get() {
                Some(table) => ks.map(|k| table[li][k]),
                None => exact_line_stats(prep, &offsets[li], bases),
            };
            let mut d = [0.0; LANES];
            for (kk, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                let m2 = stx.map(|st| st[2 * kk]);
                let mut acc = [0.0; LANES];
                for (&c, &off) in o.centred[kk].iter().zip(&offsets[li]) {
                    for l in 0..LANES {
                        acc[l] += c * (plane[(bases[l] + off) as usize] - m2[l]);
                    }
                }
                for l in 0..LANES {
                    d[l] += s.weights[kk] * pearson_from(o.mean[kk], o.ss[kk], stx[l][2 * kk], stx[l][2 * kk + 1], acc[l]);
                }
            }
            for l in 0..LANES {
                if s.clamp {
                    d[l] = d[l].max(0.0);
                }
                let de = mism[l][li] as f64 / ns[li];
                f[l] += d[l] / (1.0 + s.mu * de);
                if s.level_penalty > 0.0 {
                    f[l] -= s.level_penalty * (o.mean[2] - stx[l][4]).abs();
                }
            }
        }
        f
    };
    let full = |k: usize, mism: [u32; 2]| -> f64 { full_lanes([k; LANES], [mism; LANES])[0] };
    // A lower bound of F_max from the hints, hence a lower bound of θ.
    let mut f_low = f64::NEG_INFINITY;
    for &(x, y) in hints {
        if xs.contains(&x) && ys.contains(&y) && ok(x, y) {
            let k = (y - y0) as usize * nx + (x - x0) as usize;
            f_low = f_low.max(full(k, [mismatches_of(k, 0), mismatches_of(k, 1)]));
        }
    }
    let theta_low = s.tau.min(f_low - s.eps);
    let cap = {
        let c = s.weights[0] + s.weights[1] + s.weights[2];
        if s.clamp { c.max(0.0) } else { c }
    };
    if nx == 0 || ny == 0 {
        return everything();
    }
    // Whether candidate `k` may be picked (all may without a restriction).
    let ok_k = |k: usize| ok(x0 + (k % nx) as i32, y0 + (k / nx) as i32);
    if allowed.is_some() && !(0..nx * ny).any(ok_k) {
        return everything();
    }
    // Edge mismatches of both lines for every candidate, by rows.
    let counters = [0, 1].map(|li| MismatchCounter::new(&ls[li], &offsets[li], &outs[li].edges));
    let mut mism = vec![[0u32; 2]; nx * ny];
    mism.par_chunks_mut(nx).enumerate().for_each_init(
        || (vec![0u32; nx], vec![0u32; nx]),
        |(sums, m), (row, dst)| {
            with_avx2(
                #[inline(always)]
                || {
                    for (li, counter) in counters.iter().enumerate() {
                        counter.row(prep, (x0, y0 + row as i32), base_of(row * nx) as usize, sums, m);
                        for (d, &v) in dst.iter_mut().zip(m.iter()) {
                            d[li] = v;
                        }
                    }
                },
            )
        },
    );
    // The level penalty is subtracted from every bound below (zero without one).
    let penalty = (s.level_penalty > 0.0).then(|| shape.bounds.penalty_low(s.level_penalty, [outs[0].mean[2], outs[1].mean[2]]));
    let penalty_of = |k: usize| penalty.as_ref().map_or(0.0, |p| p[k]);
    let mut survivors: Vec<usize> = Vec::new();
    let most_penalty = penalty.as_ref().map_or(0.0, |p| p.iter().copied().fold(0.0, f64::max));
    if theta_low > cap - most_penalty + BOUND_SLACK {
        // Below that a candidate with perfect lines (and the least penalty) can always reach θ:
        // the edge bound rules nothing out.
        // Each line's term depends on its mismatch count alone: one table per line, the same
        // bits as computing it per candidate.
        let edge_cap: [Vec<f64>; 2] = [0, 1].map(|li| (0..=ls[li].len()).map(|m| cap / (1.0 + s.mu * (m as f64 / ns[li]))).collect());
        survivors = mism
            .iter()
            .enumerate()
            .filter(|&(k, m)| may_reach(edge_cap[0][m[0] as usize] + edge_cap[1][m[1] as usize] - penalty_of(k), theta_low) && ok_k(k))
            .map(|(k, _)| k)
            .collect();
    }
    if survivors.is_empty() || survivors.len() * FFT_BEYOND > mism.len() {
        // The bounds from approximate scores: cross sums by FFT, within a rigorous margin; the
        // I channel first, all three where that leaves too many to score (all three at once
        // where most of this shape's earlier searches needed them).
        let mut fb = FftBounds::new(prep, s, ls, &outs, &shape.bounds, (x0, y0, nx, ny), &mism);
        let mut history = shape.fft_history.lock().expect("history");
        let penalise = |mut u: Vec<f64>| {
            if let Some(p) = &penalty {
                u.iter_mut().zip(p).for_each(|(u, p)| *u -= p);
            }
            if allowed.is_some() {
                // A position that may not be picked bounds nothing and survives nothing.
                u.iter_mut().enumerate().filter(|(k, _)| !ok_k(*k)).for_each(|(_, u)| *u = f64::NEG_INFINITY);
            }
            u
        };
        let mut u = penalise(if history.1 * 2 > history.0 { fb.all() } else { fb.intensity() });
        let mut hs = history.1 * 2 > history.0;
        loop {
            // The last of the largest, as `max_by` would pick.
            assert!(!u.is_empty(), "candidates");
            let mut best = 0;
            for (k, v) in u.iter().enumerate().skip(1) {
                if v.total_cmp(&u[best]) != std::cmp::Ordering::Less {
                    best = k;
                }
            }
            f_low = f_low.max(full(best, mism[best]));
            let theta_low = s.tau.min(f_low - s.eps);
            survivors = (0..u.len()).filter(|&k| may_reach(u[k], theta_low) && ok_k(k)).collect();
            if hs {
                break;
            }
            history.0 += 1;
            if survivors.len() <= mism.len() / FULL_BOUNDS_BEYOND {
                break;
            }
            history.1 += 1;
            u = penalise(fb.full());
            hs = true;
        }
    }
    if survivors.len() > mism.len() / 8 {
        // The table costs one pass per candidate; with the FFT bounds most searches score a few
        // hundred at most, so it pays only where one search leaves this many (at 1/64 it was
        // built for every shape on bricks and grass and cost more than it saved: bricks 512²
        // 0.40 → 0.34 s CPU).
        shape.exact(prep, s);
    }
    let scores: Vec<f64> = survivors
        .par_chunks(LANES * 16)
        .flat_map_iter(|part| {
            part.chunks(LANES).flat_map(|ks| {
                // A short last group repeats its last candidate.
                let lanes: [usize; LANES] = std::array::from_fn(|l| ks[l.min(ks.len() - 1)]);
                full_lanes(lanes, lanes.map(|k| mism[k])).into_iter().take(ks.len())
            })
        })
        .collect();
    let f_max = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let theta = s.tau.min(f_max - s.eps);
    let members: Vec<(i32, i32)> =
        survivors.iter().zip(&scores).filter(|(_, f)| **f >= theta).map(|(&k, _)| (x0 + (k % nx) as i32, y0 + (k / nx) as i32)).collect();
    if members.is_empty() {
        return everything();
    }
    let mut st = Stream::new(seed, &format!("seam/pick/bi={bi}/bj={bj}"));
    Ok((members[st.below_usize(members.len())], members.len(), f_max))
}

/// Upper bounds of `F`, from cross sums computed for all positions at once by FFT, in two
/// stages: [`FftBounds::intensity`] correlates only the I channel and bounds `ρ_H` and `ρ_S` by 1;
/// γ being the largest weight, that alone rules out most candidates where `θ` is high.
/// [`FftBounds::full`] adds the H and S cross sums for when too many survive. A line is a few
/// straight groups of pixels (one column or one row each), so its cross sums at every position
/// are a sum of 1-D correlations along columns or rows: one 1-D inverse transform per sample
/// column or row a candidate reaches, per pair of groups, from the sample's 1-D spectra
/// ([`Spectra`]), in single precision. The margin added per line and channel covers each group's
/// transform error ([`Spectra::error_per_norms`] times the largest column or row norm and the
/// group's kernel norm) and the rounding of the exact sums; degenerate lines take B8's values,
/// which do not depend on the cross sum.
struct FftBounds<'p> {
    prep: &'p Prepared<'p>,
    s: &'p Settings,
    outs: &'p [OutputLine; 2],
    bounds: &'p BoundStats,
    area: (i32, i32, usize, usize),
    mism: &'p [[u32; 2]],
    /// Each line's pixels grouped by column (vertical runs) and by row (the rest).
    groups: Vec<Group>,
    /// Per correlated (group, channel): where its correlations are (see [`FftBounds::correlate`]).
    terms: Vec<Term>,
    /// One plane-sized buffer per pair of terms (taken from `prep` and given back on drop).
    buffers: Vec<Vec<Complex32>>,
    /// Per line and channel: Σ centred and the error margin of the cross sum.
    sum_c: [[f64; 3]; 2],
    margin: [[f64; 3]; 2],
    /// Per line and channel 1/sqrt of the output side's sum of squares (0: a flat output line).
    inv_out: [[f64; 3]; 2],
    /// The edge factor 1/(1 + μ·m/n) of every mismatch count m.
    edge_factor: [Vec<f64>; 2],
}

/// The pixels of one line in one sample column (`vertical`, at window column `at`) or one row
/// (at window row `at`): `(j, i)` for line pixel `i` at offset `from + j` along it.
struct Group {
    li: usize,
    vertical: bool,
    at: i32,
    from: i32,
    pixels: Vec<(usize, usize)>,
}

/// One group's correlation with one channel: the real (or imaginary) part of `buffer`, laid out
/// by columns (`x·h + y`) for a vertical group, by rows for a horizontal one.
struct Term {
    group: usize,
    k: usize,
    buffer: usize,
    imag: bool,
}

impl<'p> FftBounds<'p> {
    fn new(
        prep: &'p Prepared<'p>,
        s: &'p Settings,
        ls: &'p [Vec<(i32, i32)>; 2],
        outs: &'p [OutputLine; 2],
        bounds: &'p BoundStats,
        area: (i32, i32, usize, usize),
        mism: &'p [[u32; 2]],
    ) -> FftBounds<'p> {
        let sp = &prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let mut groups: Vec<Group> = Vec::new();
        // (group, first offset along, first line pixel, length) of every run.
        let mut along = Vec::new();
        for (li, line) in ls.iter().enumerate() {
            let mut i = 0;
            for run in runs_of(line) {
                let (vertical, at, start) = if run.horizontal { (false, run.r, run.c) } else { (true, run.c, run.r) };
                let g = match groups.iter().position(|g| g.li == li && g.vertical == vertical && g.at == at) {
                    Some(g) => g,
                    None => {
                        groups.push(Group { li, vertical, at, from: start, pixels: Vec::new() });
                        groups.len() - 1
                    }
                };
                groups[g].from = groups[g].from.min(start);
                along.push((g, start, i, run.len));
                i += run.len as usize;
            }
        }
        for (g, start, i, len) in along {
            let skip = (start - groups[g].from) as usize;
            groups[g].pixels.extend((0..len as usize).map(|t| (skip + t, i + t)));
        }
        let mut sum_c = [[0.0; 3]; 2];
        let mut margin = [[0.0; 3]; 2];
        for li in 0..2 {
            for k in 0..3 {
                let c = &outs[li].centred[k];
                sum_c[li][k] = c.iter().sum::<f64>();
                let abs: f64 = c.iter().map(|v| v.abs()).sum();
                // The exact sums' rounding, as before the transforms were single precision.
                margin[li][k] = 1e-9 * (abs + 1e-3);
            }
        }
        // Each group's correlation errs by at most its transform's bound times the norms of the
        // sample column (row) and of the group's kernel ([`Spectra::error_per_norms`]).
        for g in &groups {
            let (n, peak_norm) = if g.vertical { (h, &sp.col_norms) } else { (w, &sp.row_norms) };
            for k in 0..3 {
                let kernel = g.pixels.iter().map(|&(_, i)| outs[g.li].centred[k][i].powi(2)).sum::<f64>().sqrt();
                margin[g.li][k] += Spectra::error_per_norms(n) * peak_norm[k] * kernel;
            }
        }
        let inv_out = [0, 1].map(|li| outs[li].ss.map(|v| if v >= FLAT { 1.0 / v.sqrt() } else { 0.0 }));
        let edge_factor: [Vec<f64>; 2] =
            [0, 1].map(|li| (0..=ls[li].len()).map(|m| 1.0 / (1.0 + s.mu * (m as f64 / ls[li].len() as f64))).collect());
        let buffers = std::mem::take(&mut *prep.fft_buffers.lock().expect("buffers"));
        FftBounds { prep, s, outs, bounds, area, mism, groups, terms: Vec::new(), buffers, sum_c, margin, inv_out, edge_factor }
    }

    /// Correlates every group with the channels `ks`: the terms in pairs of the same orientation,
    /// each pair one complex 1-D correlation per sample column (row) its candidates reach, the
    /// first term in the real part and the second in the imaginary part.
    fn correlate(&mut self, ks: &[usize]) {
        let prep = self.prep;
        let sp = &prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let (x0, y0, nx, ny) = self.area;
        let first = self.terms.len();
        let first_buffer = self.terms.iter().map(|t| t.buffer + 1).max().unwrap_or(0);
        let mut next = first_buffer;
        for vertical in [true, false] {
            let new: Vec<(usize, usize)> = (0..self.groups.len())
                .filter(|&g| self.groups[g].vertical == vertical)
                .flat_map(|g| ks.iter().map(move |&k| (g, k)))
                .collect();
            for pair in new.chunks(2) {
                for (t, &(group, k)) in pair.iter().enumerate() {
                    self.terms.push(Term { group, k, buffer: next, imag: t == 1 });
                }
                next += 1;
            }
        }
        while self.buffers.len() < next {
            self.buffers.push(vec![Complex32::new(0.0, 0.0); w * h]);
        }
        for b in first_buffer..next {
            let pair: Vec<&Term> = self.terms[first..].iter().filter(|u| u.buffer == b).collect();
            let g0 = &self.groups[pair[0].group];
            let vertical = g0.vertical;
            let (n, count, planes, fwd, inv) =
                if vertical { (h, w, &sp.cols, &sp.col[0], &sp.col[1]) } else { (w, h, &sp.rows, &sp.row[0], &sp.row[1]) };
            let half = n / 2 + 1;
            // The columns (rows) the candidates reach.
            let reach = |g: &Group| -> std::ops::Range<usize> {
                let start = g.at + if vertical { x0 } else { y0 };
                start as usize..start as usize + if vertical { nx } else { ny }
            };
            let mut lo = count;
            let mut hi = 0;
            let mut kernels: Vec<(usize, Vec<Complex32>)> = Vec::new();
            for term in &pair {
                let g = &self.groups[term.group];
                let r = reach(g);
                lo = lo.min(r.start);
                hi = hi.max(r.end);
                let mut z = vec![Complex32::new(0.0, 0.0); n];
                for &(j, i) in &g.pixels {
                    z[j].re = self.outs[g.li].centred[term.k][i] as f32;
                }
                fwd.process(&mut z);
                // Conjugated for a correlation, and scaled by 1/n for the unnormalised inverse
                // transform.
                let scale = 1.0 / n as f32;
                kernels.push((term.k, z[..half].iter().map(|v| v.conj() * scale).collect::<Vec<_>>()));
            }
            let out = &mut self.buffers[b][lo * n..hi * n];
            out.par_chunks_mut(n * 16).enumerate().for_each_init(
                || vec![0.0f32; 4 * half],
                |scratch, (ci, chunk)| {
                    with_avx2(
                        #[inline(always)]
                        || {
                            for (cj, dst) in chunk.chunks_exact_mut(n).enumerate() {
                                let line = lo + ci * 16 + cj;
                                let (ka, fa) = (&kernels[0].1, &planes[kernels[0].0][line * half..(line + 1) * half]);
                                let b = kernels.get(1).map(|(k, kb)| (&planes[*k][line * half..(line + 1) * half], &kb[..]));
                                hermitian_products(fa, ka, b, dst, scratch);
                            }
                        },
                    );
                    inv.process(chunk);
                },
            );
        }
    }

    /// The cross sums of candidate rows `row0..row0 + rows`, per line and channel correlated,
    /// term by term into `cross[li][k][r·nx + x]`: a vertical term's values lie down a column of its
    /// buffer, so they are read a column run at a time.
    #[inline(always)]
    fn cross_sums(&self, row0: usize, rows: usize, cross: &mut [[Vec<f64>; 3]; 2]) {
        let (x0, y0, nx, _) = self.area;
        let sp = &self.prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let y = y0 + row0 as i32;
        // Only the sums some term adds to are read (the others' channels are not bounded).
        for term in &self.terms {
            cross[self.groups[term.group].li][term.k][..nx * rows].fill(0.0);
        }
        for term in &self.terms {
            let g = &self.groups[term.group];
            let buf = &self.buffers[term.buffer];
            let acc = &mut cross[g.li][term.k][..nx * rows];
            let add = |part: fn(&Complex32) -> f64, acc: &mut [f64]| {
                if g.vertical {
                    let (col, r) = ((x0 + g.at) as usize, (y + g.from) as usize);
                    for x in 0..nx {
                        let run = &buf[(col + x) * h + r..(col + x) * h + r + rows];
                        for (a, v) in acc[x..].iter_mut().step_by(nx).zip(run) {
                            *a += part(v);
                        }
                    }
                } else {
                    for (rr, acc) in acc.chunks_exact_mut(nx).enumerate() {
                        let at = (y + rr as i32 + g.at) as usize * w + (x0 + g.from) as usize;
                        for (a, v) in acc.iter_mut().zip(&buf[at..at + nx]) {
                            *a += part(v);
                        }
                    }
                }
            };
            if term.imag {
                add(|v| f64::from(v.im), acc);
            } else {
                add(|v| f64::from(v.re), acc);
            }
        }
    }

    /// The bounds of one row of candidates from its cross sums `cross[li][k]`, with the H and S
    /// channels when `hs` (else `ρ_H, ρ_S ≤ 1`).
    #[inline(always)]
    fn bound_row(&self, row: usize, hs: bool, u: &mut [f64], cross: [[&[f64]; 3]; 2], d: &mut [f64]) {
        let nx = self.area.2;
        let cap = 1.0 + 1e-9;
        let mism = &self.mism[row * nx..(row + 1) * nx];
        u.fill(0.0);
        for li in 0..2 {
            let ef = &self.edge_factor[li];
            // The part of D_HSI not bounded per candidate: ρ ≤ 1 for the channels not correlated.
            let d0 = if hs { 0.0 } else { (self.s.weights[0] + self.s.weights[1]) * cap };
            let channels = if hs { 0..3 } else { 2..3 };
            d.fill(d0);
            for k in channels {
                let (io, sc, mg, wk) = (self.inv_out[li][k], self.sum_c[li][k], self.margin[li][k], self.s.weights[k]);
                let inv_his = self.bounds.inv_hi(li, row, k);
                // ρ is 1 for two flat lines with close means and 0 for one flat line (B8);
                // otherwise c/sqrt(v1·v2), at most 1.
                if io == 0.0 {
                    for (dd, &inv_hi) in d.iter_mut().zip(inv_his) {
                        *dd += wk * if inv_hi == f64::INFINITY { cap } else { 0.0 };
                    }
                } else {
                    // The cross sum is Σ c·(v − m2) = Σ c·(v − μ) + (μ − m2)·Σ c, the transforms
                    // giving the first term (μ the plane's mean), and Σ c (the output line's
                    // centred values) is all but zero: |μ − m2|·|Σ c| ≤ peak·|Σ c| joins the
                    // margin, so the candidate's mean is not needed.
                    let mg = (mg + self.prep.spectra.peaks[k] * sc.abs()) * io;
                    for ((dd, &c), &inv_hi) in d.iter_mut().zip(cross[li][k]).zip(inv_his) {
                        let c = c * io + mg;
                        let rho = (c * inv_hi * if c >= 0.0 { 1.0 } else { 1.0 - INV_SPREAD }).min(cap);
                        *dd += wk * if inv_hi == f64::INFINITY { cap } else { rho };
                    }
                }
            }
            for ((uu, dd), m) in u.iter_mut().zip(&*d).zip(mism) {
                let dd = if self.s.clamp { dd.max(0.0) } else { *dd };
                *uu += dd * ef[m[li] as usize];
            }
        }
    }

    /// Bounds of every candidate, row-major, from the I channel alone, or from all three after
    /// [`FftBounds::intensity`] when `hs`.
    fn bounds(&self, hs: bool) -> Vec<f64> {
        let (_, _, nx, ny) = self.area;
        let mut u = vec![0.0; nx * ny];
        const ROWS: usize = 16;
        u.par_chunks_mut(nx * ROWS).enumerate().for_each_init(
            || ([0, 1].map(|_| [0, 1, 2].map(|_| vec![0.0; nx * ROWS])), vec![0.0; nx]),
            |(cross, d), (chunk, us)| {
                with_avx2(
                    #[inline(always)]
                    || {
                        let rows = us.len() / nx;
                        self.cross_sums(chunk * ROWS, rows, cross);
                        for (r, u) in us.chunks_exact_mut(nx).enumerate() {
                            let c = [0, 1].map(|li| [0, 1, 2].map(|k| &cross[li][k][r * nx..(r + 1) * nx]));
                            self.bound_row(chunk * ROWS + r, hs, u, c, d);
                        }
                    },
                )
            },
        );
        u
    }

    /// Bounds of every candidate from the I channel alone.
    fn intensity(&mut self) -> Vec<f64> {
        self.correlate(&[2]);
        self.bounds(false)
    }

    /// Bounds of every candidate from all three channels (after [`FftBounds::intensity`]).
    fn full(&mut self) -> Vec<f64> {
        self.correlate(&[0, 1]);
        self.bounds(true)
    }

    /// Bounds of every candidate from all three channels at once.
    fn all(&mut self) -> Vec<f64> {
        self.correlate(&[0, 1, 2]);
        self.bounds(true)
    }
}

impl Drop for FftBounds<'_> {
    fn drop(&mut self) {
        *self.prep.fft_buffers.lock().expect("buffers") = std::mem::take(&mut self.buffers);
    }
}

/// `dst = A + i·B` for `A = fa·ka` and `B = fb·kb` (pointwise; `B = 0` without `b`), from
/// frequencies `0..=n/2` of four spectra of real sequences (`n = dst.len()`): `A` and `B` are
/// then spectra of real sequences too, so frequency `n − j` is `conj(A_j) + i·conj(B_j)` and each
/// product is computed for half of the frequencies only. The products go through `scratch`
/// (at least `4·(n/2 + 1)` values) as separate real and imaginary parts, so that every loop runs
/// on whole vectors, the mirrored half's reversed order included.
#[inline(always)]
fn hermitian_products(
    fa: &[Complex32],
    ka: &[Complex32],
    b: Option<(&[Complex32], &[Complex32])>,
    dst: &mut [Complex32],
    scratch: &mut [f32],
) {
    let n = dst.len();
    let half = n / 2 + 1;
    let (ar, rest) = scratch.split_at_mut(half);
    let (ai, rest) = rest.split_at_mut(half);
    let (br, rest) = rest.split_at_mut(half);
    let bi = &mut rest[..half];
    let product = |f: &[Complex32], k: &[Complex32], re: &mut [f32], im: &mut [f32]| {
        for (((re, im), f), k) in re.iter_mut().zip(im.iter_mut()).zip(&f[..half]).zip(&k[..half]) {
            *re = f.re * k.re - f.im * k.im;
            *im = f.re * k.im + f.im * k.re;
        }
    };
    product(fa, ka, ar, ai);
    match b {
        Some((fb, kb)) => product(fb, kb, br, bi),
        None => {
            br.fill(0.0);
            bi.fill(0.0);
        }
    }
    let (lower, upper) = dst.split_at_mut(half);
    for (j, lo) in lower.iter_mut().enumerate() {
        *lo = Complex32::new(ar[j] - bi[j], ai[j] + br[j]);
    }
    // Frequencies 1..=mirrored have their partner n − j in the upper part, in reverse order;
    // 0 and (for even n) n/2 are their own.
    let mirrored = n - half;
    for (i, up) in upper.iter_mut().enumerate() {
        let j = mirrored - i;
        *up = Complex32::new(ar[j] + bi[j], br[j] - ai[j]);
    }
}

/// The sample's H, S and I planes, less their means, as 1-D spectra of every column and every
/// row, in single precision, with the plans. The bounds only need the cross sums within a proven
/// margin, and single precision halves the memory the correlations stream through and doubles the
/// lanes of each vector operation; centring keeps the planes' large constant part (and with it
/// the rounding error) out of the transforms.
struct Spectra {
    w: usize,
    h: usize,
    /// `cols[k][x·(h/2 + 1) + v]`: frequency `v` of column `x` of plane `k` (H, S, I), for
    /// `v ≤ h/2` (the rest are their conjugates: the planes are real).
    cols: [Vec<Complex32>; 3],
    /// `rows[k][y·(w/2 + 1) + u]`: frequency `u ≤ w/2` of row `y`.
    rows: [Vec<Complex32>; 3],
    /// The largest Euclidean norm of a centred column (row) of each plane.
    col_norms: [f64; 3],
    row_norms: [f64; 3],
    /// The largest absolute value in each centred plane.
    peaks: [f64; 3],
    /// Forward and inverse plans along columns (length `h`) and rows (length `w`).
    col: [Arc<dyn Fft<f32>>; 2],
    row: [Arc<dyn Fft<f32>>; 2],
}

impl Spectra {
    fn new(planes: &HsiPlanes, w: usize, h: usize) -> Spectra {
        // The spectra are computed in double precision and rounded once.
        let mut planner = FftPlanner::<f64>::new();
        let (col64, row64) = (planner.plan_fft_forward(h), planner.plan_fft_forward(w));
        let mut planner = FftPlanner::<f32>::new();
        let col = [planner.plan_fft_forward(h), planner.plan_fft_inverse(h)];
        let row = [planner.plan_fft_forward(w), planner.plan_fft_inverse(w)];
        let centred = [&planes.h, &planes.s, &planes.i].map(|p| {
            let mean = p.iter().sum::<f64>() / p.len() as f64;
            p.iter().map(|v| v - mean).collect::<Vec<f64>>()
        });
        let single = |z: &[Complex64], n: usize| -> Vec<Complex32> {
            z.chunks_exact(n).flat_map(|c| &c[..n / 2 + 1]).map(|v| Complex32::new(v.re as f32, v.im as f32)).collect()
        };
        let cols = [0, 1, 2].map(|k| {
            let p = &centred[k];
            let mut z: Vec<Complex64> = (0..w).flat_map(|x| (0..h).map(move |y| Complex64::new(p[y * w + x], 0.0))).collect();
            col64.process(&mut z);
            single(&z, h)
        });
        let rows = [0, 1, 2].map(|k| {
            let mut z: Vec<Complex64> = centred[k].iter().map(|&v| Complex64::new(v, 0.0)).collect();
            row64.process(&mut z);
            single(&z, w)
        });
        let col_norms =
            centred.each_ref().map(|p| (0..w).map(|x| (0..h).map(|y| p[y * w + x] * p[y * w + x]).sum::<f64>().sqrt()).fold(0.0, f64::max));
        let row_norms =
            centred.each_ref().map(|p| p.chunks_exact(w).map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt()).fold(0.0, f64::max));
        let peaks = centred.each_ref().map(|p| p.iter().fold(0.0, |m: f64, v| m.max(v.abs())));
        Spectra { w, h, cols, rows, col_norms, row_norms, peaks, col, row }
    }

    /// A bound of the absolute error of one single-precision correlation of length `n` (a column
    /// or row `x` with a kernel `k`: the kernel's transform, the product with `x`'s rounded
    /// spectrum, the inverse transform) per `‖x‖₂·‖k‖₂`. A transform of length `n` errs by at most
    /// `log₂(n)·η` relative to its output's 2-norm (Higham, *Accuracy and Stability of Numerical
    /// Algorithms*, §24.1; `η ≈ 7u` for single precision's `u = 2⁻²⁴` with accurate twiddles).
    /// Through the product (`‖X‖∞ ≤ √n·‖x‖₂`, the same for `k`) and the scaled inverse transform
    /// that gives at most `(2·log₂(n)·η + 6u)·√n` for any one output; this takes
    /// `64·u·log₂(n)·√n`, over four times that (transforms of lengths with large prime factors
    /// take a few more steps).
    fn error_per_norms(n: usize) -> f64 {
        let u = f64::from(f32::EPSILON) / 2.0;
        let log = (n as f64).log2().max(1.0);
        64.0 * u * log * (n as f64).sqrt()
    }
}

/// How far [`Prepared::edges`] extends past the sample: one register block of [`MismatchCounter::row`].
const EDGE_PAD: usize = 32;

/// The edge mismatches of one line at every candidate. With `n₁` edge pixels on the output line
/// and `S` on the candidate's, the mismatches are `n₁ + S − 2·T`, `T` the candidate's edge bits
/// under the line's edge pixels, or equally `n₁ − S + 2·Z` over its non-edge pixels: `S` is a few
/// prefix-sum lookups per run ([`Prefixes::add_edge_run`]), so only the smaller of the two pixel
/// sets is read per candidate, at most half the line.
struct MismatchCounter {
    runs: Vec<Run>,
    /// The line offsets of the pixels summed, and whether they are the edge pixels.
    summed: Vec<isize>,
    ones: bool,
    n1: u32,
}

impl MismatchCounter {
    fn new(line: &[(i32, i32)], offsets: &[isize], edges: &[u8]) -> MismatchCounter {
        let n1 = edges.iter().filter(|&&e| e == 1).count();
        let ones = 2 * n1 <= edges.len();
        let summed = offsets.iter().zip(edges).filter(|&(_, &e)| (e == 1) == ones).map(|(&o, _)| o).collect();
        MismatchCounter { runs: runs_of(line), summed, ones, n1: n1 as u32 }
    }

    /// The mismatches of `m.len()` consecutive candidates from `(x, y)`, whose line pixels are at
    /// sample index `base` plus each offset (`sums`: scratch of the same length).
    #[inline(always)]
    fn row(&self, prep: &Prepared, (x, y): (i32, i32), base: usize, sums: &mut [u32], m: &mut [u32]) {
        const LANES: usize = 32;
        let n = m.len();
        sums.fill(0);
        for run in &self.runs {
            prep.prefixes.add_edge_run(run, x, y, sums);
        }
        // Counted in 8 bits, LANES candidates at a time in registers, in runs of pixels short
        // enough not to overflow; the last block reads past the row into the padding.
        for x in (0..n).step_by(LANES) {
            let mut count = [0u32; LANES];
            for part in self.summed.chunks(u8::MAX as usize) {
                let mut acc = [0u8; LANES];
                for &off in part {
                    let b = (base as isize + off) as usize + x;
                    let bits: &[u8; LANES] = prep.edges[b..b + LANES].try_into().expect("lanes");
                    for (a, &e) in acc.iter_mut().zip(bits) {
                        *a += e;
                    }
                }
                for (c, &a) in count.iter_mut().zip(&acc) {
                    *c += u32::from(a);
                }
            }
            let lanes = LANES.min(n - x);
            for ((mm, &s), &c) in m[x..x + lanes].iter_mut().zip(&sums[x..x + lanes]).zip(&count) {
                *mm = if self.ones { self.n1 + s - 2 * c } else { self.n1 + 2 * c - s };
            }
        }
    }
}

/// [`score_all`] for given lines and position ranges.
fn score_lines(
    prep: &Prepared,
    s: &Settings,
    ls: &[Vec<(i32, i32)>; 2],
    (xs, ys): Ranges,
    stats: &[LineStats; 2],
    out: &Canvas,
    origin: (i32, i32),
) -> (Vec<(i32, i32)>, Vec<f64>) {
    let outs = [output_line(out, s, origin, &ls[0]), output_line(out, s, origin, &ls[1])];
    let nx = (xs.end() - xs.start() + 1) as usize;
    let x0 = *xs.start();
    let w = prep.w as i32;
    let rows: Vec<i32> = ys.collect();
    let scores: Vec<f64> = rows
        .par_iter()
        .enumerate()
        .flat_map_iter(|(row_index, &y)| {
            let mut f = vec![0.0; nx];
            for (li, line) in ls.iter().enumerate() {
                let o = &outs[li];
                let st = &stats[li][row_index * nx..(row_index + 1) * nx];
                let mut cross = [vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]];
                let mut mismatches = vec![0u32; nx];
                if s.circular {
                    // Slow path: a sine per pixel.
                    for (i, &(c, r)) in line.iter().enumerate() {
                        let base = ((y + r) * w + x0 + c) as usize;
                        for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                            let ci = o.centred[k][i];
                            let row = &plane[base..base + nx];
                            for ((a, v), stx) in cross[k].iter_mut().zip(row).zip(st) {
                                *a += if k == 0 { ci * (TAU * v - stx[0]).sin() } else { ci * (v - stx[2 * k]) };
                            }
                        }
                        let e1 = o.edges[i];
                        for (m, e2) in mismatches.iter_mut().zip(&prep.edges[base..base + nx]) {
                            *m += u32::from(e1 != *e2);
                        }
                    }
                } else {
                    let offsets: Vec<usize> = line.iter().map(|&(c, r)| ((y + r) * w + x0 + c) as usize).collect();
                    cross_row(prep, o, st, &offsets, &mut cross, &mut mismatches);
                }
                let n = line.len() as f64;
                for x in 0..nx {
                    let stx = &st[x];
                    let mut d = 0.0;
                    for k in 0..3 {
                        let rho = if k == 0 && s.circular {
                            let mut diff = (o.mean[0] - stx[0]).abs() % TAU;
                            if diff > TAU / 2.0 {
                                diff = TAU - diff;
                            }
                            pearson_from(0.0, o.ss[0], diff / TAU, stx[1], cross[0][x])
                        } else {
                            pearson_from(o.mean[k], o.ss[k], stx[2 * k], stx[2 * k + 1], cross[k][x])
                        };
                        d += s.weights[k] * rho;
                    }
                    if s.clamp {
                        d = d.max(0.0);
                    }
                    let de = mismatches[x] as f64 / n;
                    f[x] += d / (1.0 + s.mu * de);
                    if s.level_penalty > 0.0 {
                        f[x] -= s.level_penalty * (o.mean[2] - stx[4]).abs();
                    }
                }
            }
            f
        })
        .collect();
    let positions = rows.iter().flat_map(|&y| (0..nx as i32).map(move |dx| (x0 + dx, y))).collect();
    (positions, scores)
}

/// The linear-hue cross sums and edge mismatches of one line at `cross[k].len()` consecutive
/// candidates (`offsets`: the line's sample indices for the first of them). Candidates in
/// register blocks of LANES, line pixels in index order inside: the same sums in the same order
/// as the two-pass formula, without round-tripping accumulators through memory for every pixel.
fn cross_row(prep: &Prepared, o: &OutputLine, st: &[[f64; 6]], offsets: &[usize], cross: &mut [Vec<f64>; 3], mismatches: &mut [u32]) {
    const LANES: usize = 8;
    let nx = mismatches.len();
    let mut x = 0;
    while x < nx {
        let lanes = LANES.min(nx - x);
        let mut m2 = [[0.0f64; LANES]; 3];
        for l in 0..lanes {
            for k in 0..3 {
                m2[k][l] = st[x + l][2 * k];
            }
        }
        let mut acc = [[0.0f64; LANES]; 3];
        let mut mism = [0u32; LANES];
        for (i, &base) in offsets.iter().enumerate() {
            let b = base + x;
            for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                let ci = o.centred[k][i];
                if lanes == LANES {
                    let v: &[f64; LANES] = plane[b..b + LANES].try_into().expect("lanes");
                    for l in 0..LANES {
                        acc[k][l] += ci * (v[l] - m2[k][l]);
                    }
                } else {
                    for l in 0..lanes {
                        acc[k][l] += ci * (plane[b + l] - m2[k][l]);
                    }
                }
            }
            let e1 = o.edges[i];
            for (m, e2) in mism[..lanes].iter_mut().zip(&prep.edges[b..b + lanes]) {
                *m += u32::from(e1 != *e2);
            }
        }
        for l in 0..lanes {
            for k in 0..3 {
                cross[k][x + l] = acc[k][l];
            }
            mismatches[x + l] = mism[l];
        }
        x += lanes;
    }
}

#[cfg(test)]
mod tests;
