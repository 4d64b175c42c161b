//! Co-evolution near-regular texture synthesis (paper 000, docs/methods.md §2.3–2.7).
//!
//! Near-regular textures (bricks, tiles, weaves) must keep their texel lattice. Individuals are
//! the sample's parallelogram texels spanned by the lattice vectors `t1, t2` (found by
//! `crate::synth::lattice` or given by the job); the output lattice is split by the parity of `r + c` into
//! two populations that evolve alternately, each being the other's fixed environment, so every
//! individual of one parity can be updated in parallel; and all pairwise overlap fitness values are
//! precomputed in two tables `H` and `V`, so an iteration is table look-ups. Overlaps are feathered
//! at render time.
//!
//! **Texel pixels (`mask`).** By default (`mask = "exact"`) a texel is exactly its lattice cell
//! (B11: `q` belongs to cell `floor(α), floor(β)`, exact integer arithmetic): cells partition the
//! plane, so every output pixel comes from exactly one individual and each texel has exactly
//! `D = cross(t1, t2)` pixels. That is what the paper's rasterisation approximates, and it is the
//! default because it has no holes, no double coverage and no dependence on how a line-drawing
//! algorithm rounds. `mask = "bresenham"` reproduces the paper's mask (§2.3 deviation note): the
//! Bresenham paths `L1` from 0 to `t1` and `L2` from 0 to `t2` (both end points included), the set
//! of sums `p + q` (`p ∈ L1`, `q ∈ L2`), then the same sums shifted one pixel right to plug the
//! holes left where both coordinates step at once. That mask covers the closed parallelogram plus
//! one column, so neighbouring masks overlap by a pixel or two near the edges (and its rounding
//! moves slanted edges by up to half a pixel); overlapping pixels go to the later individual
//! (individuals are painted in row-major lattice order, so east covers west and south covers north).
//! What the option changes, and what it does not:
//! - `E_I`: a texel belongs to the sample set only if its whole mask lies inside the sample (the mask
//!   is what gets copied), so the lattice origin and `s` may differ from the exact rule.
//! - Rendering: masks are painted in row-major order, later over earlier; lattice-border individuals
//!   cover one or two more pixel rows/columns than their cells.
//! - Not the overlap strips `Ω_h(σ)`, `Ω_v(σ)`, the tables `H`, `V` or the feathering: the strips are
//!   defined in lattice coordinates (§2.4) relative to an individual's origin, not by its pixel set,
//!   so they stay exact; feathering still runs after the texels are painted and overwrites the strips.
//!   With the default feathering most edge pixels end up inside a strip, so the two masks differ
//!   only near edges that no strip covers (penalised pairs, shifted strips, lattice corners and the
//!   lattice's outer border).
//!
//! **Mutation (`r_mut`, §2.7.1, off by default).** After evolution each individual, triggered with
//! probability `u(I)` of eq. 5 (the final `f̄`, `f_min` over the non-penalised individuals of the
//! whole lattice and the last iteration's `ω`, all from the evolved state; one `uniform_f64` from
//! stream `coevo/mutate/r={r}/c={c}`), evaluates every integer sample origin within the disc of
//! radius `r_mut` around its own (those whose texel fits in the sample) and moves to the fittest
//! (non-penalised ones first, ties row-major). A moved individual is no longer a lattice-aligned
//! texel, so its fitness is computed from pixels with the table's overlap rule (first shift that
//! fits; penalty otherwise). Even individuals move first against their odd neighbours, then odd ones
//! against the (possibly moved) even ones: each individual's own fitness never decreases when it
//! moves (its old origin is a candidate), every lattice edge has one odd and one even end so the
//! total edge fitness never decreases either, and the result does not depend on thread count.
use super::grid::{F_PEN, Fill, GRID_PARAMS, Geometry, LatticeGrid, bbox_of, converged, fits, texels_within};
use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::params::{self, Choice, Default, MethodConfig, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::overlap::pixel_error;
use crate::synth::rng::Stream;
use rayon::prelude::*;
use std::time::Instant;

pub struct Coevolution;

const PARAMS: &[ParamSpec] = &[
    GRID_PARAMS[0],
    GRID_PARAMS[1],
    GRID_PARAMS[2],
    GRID_PARAMS[3],
    GRID_PARAMS[4],
    GRID_PARAMS[5],
    GRID_PARAMS[6],
    ParamSpec {
        name: "rho",
        kind: ParamKind::Float { min: 0.0, max: 0.5 },
        default: Default::Float(1.0 / 6.0),
        doc: "overlap width as a fraction of the texel (at least 2 px)",
    },
    ParamSpec {
        name: "c_tol",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.05),
        doc: "candidate tolerance: 0 keeps only the best-fitting samples, larger trades seams for variety",
    },
    ParamSpec {
        name: "t_m",
        kind: ParamKind::Float { min: 0.0, max: 10.0 },
        default: Default::Float(0.02),
        doc: "termination: stop when the relative spread of the last `window` averages is at most t_m",
    },
    ParamSpec {
        name: "window",
        kind: ParamKind::Int { min: 1, max: 1000 },
        default: Default::Int(5),
        doc: "averages in the termination window (M)",
    },
    ParamSpec { name: "iter_max", kind: ParamKind::Int { min: 1, max: 100_000 }, default: Default::Int(50), doc: "iteration cap" },
    ParamSpec {
        name: "mask",
        kind: ParamKind::Choice(Mask::NAMES),
        default: Default::Str("exact"),
        doc: "texel pixels: exact lattice cells (no holes, no overlap), or the paper's Bresenham mask (line paths along t1 and t2 summed, then shifted 1 px right; the later individual covers the earlier)",
    },
    ParamSpec {
        name: "r_mut",
        kind: ParamKind::Int { min: 0, max: 64 },
        default: Default::Int(0),
        doc: "mutation radius in px: after evolution each individual, with probability u(I) (eq. 5), moves its sample origin to the fittest one within this disc; 0 = off (the paper's setting)",
    },
];

crate::choice! {
    /// Which pixels an individual paints: its exact lattice cell, or the paper's Bresenham mask.
    pub enum Mask { Exact = "exact", Bresenham = "bresenham" }
}

/// The parameters of `coevolution`, typed (job-file names in brackets).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoevolutionConfig {
    /// The lattice and the output grid (`t1_x … t2_y`, `rows`, `cols`, `fill`).
    pub grid: LatticeGrid,
    /// Overlap width as a fraction of the texel (`rho`, 0..=0.5, default 1/6).
    pub rho: f64,
    /// Candidate tolerance (`c_tol`, 0..=1, default 0.05).
    pub c_tol: f64,
    /// Termination threshold on the relative spread of the last `window` averages (`t_m`).
    pub t_m: f64,
    /// Averages in the termination window (`window`, M).
    pub window: u32,
    /// Iteration cap (`iter_max`).
    pub iter_max: u32,
    /// Texel pixels (`mask`).
    pub mask: Mask,
    /// Mutation radius in pixels, 0 = off (`r_mut`).
    pub r_mut: u32,
}

impl std::default::Default for CoevolutionConfig {
    fn default() -> CoevolutionConfig {
        CoevolutionConfig {
            grid: LatticeGrid::default(),
            rho: 1.0 / 6.0,
            c_tol: 0.05,
            t_m: 0.02,
            window: 5,
            iter_max: 50,
            mask: Mask::Exact,
            r_mut: 0,
        }
    }
}

impl MethodConfig for CoevolutionConfig {
    const METHOD: &'static str = "coevolution";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = self.grid.to_params();
        v.extend([
            params::float("rho", self.rho),
            params::float("c_tol", self.c_tol),
            params::float("t_m", self.t_m),
            params::int("window", self.window),
            params::int("iter_max", self.iter_max),
            params::word("mask", self.mask),
            params::int("r_mut", self.r_mut),
        ]);
        v
    }

    fn from_params(p: &Params) -> Result<CoevolutionConfig, SynthError> {
        Ok(CoevolutionConfig {
            grid: LatticeGrid::from_params(p)?,
            rho: p.float("rho")?,
            c_tol: p.float("c_tol")?,
            t_m: p.float("t_m")?,
            window: p.uint("window")?,
            iter_max: p.uint("iter_max")?,
            mask: p.choice("mask")?,
            r_mut: p.uint("r_mut")?,
        })
    }
}

/// The Bresenham path from `(0, 0)` to `v`, both ends included: one pixel per step `i = 0..=n` of
/// the major axis (`n = max(|v.x|, |v.y|)`), the minor coordinate `i·m/n` rounded half towards the
/// start (what the classic error-term loop with `D > 0` draws), with `v`'s signs.
pub(crate) fn bresenham_line(v: (i64, i64)) -> Vec<(i64, i64)> {
    let (ax, ay) = (v.0.abs(), v.1.abs());
    let n = ax.max(ay);
    if n == 0 {
        return vec![(0, 0)];
    }
    let minor = |i: i64, m: i64| (2 * i * m + n - 1) / (2 * n);
    (0..=n)
        .map(|i| if ax >= ay { (i * v.0.signum(), minor(i, ay) * v.1.signum()) } else { (minor(i, ax) * v.0.signum(), i * v.1.signum()) })
        .collect()
}

/// The paper's texel mask (§2.3), as offsets from the texel origin in row-major order: the sums
/// `p + q` of the Bresenham paths `p ∈ L1` (0 → t1) and `q ∈ L2` (0 → t2), then the same sums
/// shifted one pixel right.
pub(crate) fn bresenham_mask(t1: (i64, i64), t2: (i64, i64)) -> Vec<(i64, i64)> {
    let (l1, l2) = (bresenham_line(t1), bresenham_line(t2));
    let xs = [0, t1.0, t2.0, t1.0 + t2.0];
    let ys = [0, t1.1, t2.1, t1.1 + t2.1];
    let (x0, y0) = (*xs.iter().min().unwrap(), *ys.iter().min().unwrap());
    let (w, h) = (xs.iter().max().unwrap() - x0 + 2, ys.iter().max().unwrap() - y0 + 1);
    let mut m = vec![false; (w * h) as usize];
    for shift in [0, 1] {
        for p in &l1 {
            for q in &l2 {
                m[((p.1 + q.1 - y0) * w + p.0 + q.0 + shift - x0) as usize] = true;
            }
        }
    }
    (0..w * h).filter(|&i| m[i as usize]).map(|i| (i % w + x0, i / w + y0)).collect()
}

/// The pixels an individual paints, relative to its origin: the exact cell or the Bresenham mask.
pub(crate) struct Shape {
    pub offsets: Vec<(i64, i64)>,
    pub bbox: (i64, i64, i64, i64),
    /// Whether `offsets` is the exact cell (a partition: rendering can look each pixel's cell up).
    pub exact: bool,
}

impl Shape {
    pub fn new(g: &Geometry, mask: Mask) -> Shape {
        if mask == Mask::Bresenham {
            let offsets = bresenham_mask(g.t1, g.t2);
            let bbox = bbox_of(&offsets);
            Shape { offsets, bbox, exact: false }
        } else {
            Shape { offsets: g.cell.clone(), bbox: g.bbox, exact: true }
        }
    }
}

/// One precomputed fitness table (`H` or `V`): value, penalty flag and the shift used.
pub(crate) struct Table {
    pub s: usize,
    pub f: Vec<f64>,
    pub pen: Vec<bool>,
    pub shift: Vec<u16>,
}

/// The overlap strips of one direction for each shift `k` (σ = k/L), as offsets relative to the
/// later individual's origin.
pub(crate) struct Strips {
    pub rho: f64,
    pub l: i64,
    pub by_shift: Vec<(Vec<(i64, i64)>, (i64, i64, i64, i64))>,
    pub horizontal: bool,
}

impl Strips {
    pub fn new(g: &Geometry, rho: f64, horizontal: bool) -> Strips {
        let t = if horizontal { g.t1 } else { g.t2 };
        let l = t.0.abs().max(t.1.abs()).max(1);
        let rho = rho.max(2.0 / l as f64);
        let kmax = (rho * l as f64).ceil() as i64;
        // Scan the box of the cells on both sides of the shared edge.
        let back = if horizontal { (-g.t1.0, -g.t1.1) } else { (-g.t2.0, -g.t2.1) };
        let (x0, x1, y0, y1) = g.bbox;
        let scan = (x0.min(x0 + back.0), x1.max(x1 + back.0), y0.min(y0 + back.1), y1.max(y1 + back.1));
        let by_shift = (0..=kmax)
            .map(|k| {
                let sigma = k as f64 / l as f64;
                let mut v = Vec::new();
                for y in scan.2..=scan.3 {
                    for x in scan.0..=scan.1 {
                        let (a, b) = g.coords((x, y));
                        let (along, across) = if horizontal { (a, b) } else { (b, a) };
                        if along >= sigma - rho && along < sigma && (0.0..1.0).contains(&across) {
                            v.push((x, y));
                        }
                    }
                }
                let bb = bbox_of(&v);
                (v, bb)
            })
            .collect();
        Strips { rho, l, by_shift, horizontal }
    }
}

/// The overlap rule of §2.4 for the individual at sample origin `oa` west of (north of) the one at
/// `ob`, from pixels: the fitness at the first shift `k` whose strips lie inside the sample, and
/// `k`; `None` when no shift fits (penalised).
pub(crate) fn overlap_fitness(sample: &RgbImage, step: (i64, i64), strips: &Strips, oa: (i64, i64), ob: (i64, i64)) -> Option<(f64, u16)> {
    let (w, h) = (sample.width() as i64, sample.height() as i64);
    let base_a = (oa.0 + step.0, oa.1 + step.1);
    for (k, (strip, bb)) in strips.by_shift.iter().enumerate() {
        if strip.is_empty() || !fits(*bb, base_a, w, h) || !fits(*bb, ob, w, h) {
            continue;
        }
        let d: u64 = strip
            .iter()
            .map(|&(x, y)| {
                let pa = sample.get((base_a.0 + x) as u32, (base_a.1 + y) as u32);
                let pb = sample.get((ob.0 + x) as u32, (ob.1 + y) as u32);
                pixel_error(pa, pb) as u64
            })
            .sum();
        return Some((-(d as f64) / strip.len() as f64, k as u16));
    }
    None
}

/// Builds `H` (horizontal) or `V` (vertical): entry `[a][b]` is the fitness of `a` west of (north
/// of) `b`, with the first shift that keeps both strips inside the sample.
pub(crate) fn build_table(sample: &RgbImage, g: &Geometry, texels: &[(i64, i64)], strips: &Strips) -> Table {
    let s = texels.len();
    let step = if strips.horizontal { g.t1 } else { g.t2 };
    let rows: Vec<Vec<(f64, bool, u16)>> = (0..s)
        .into_par_iter()
        .map(|a| {
            (0..s)
                .map(|b| match overlap_fitness(sample, step, strips, texels[a], texels[b]) {
                    Some((f, k)) => (f, false, k),
                    None => (F_PEN, true, 0),
                })
                .collect()
        })
        .collect();
    let mut t = Table { s, f: Vec::with_capacity(s * s), pen: Vec::with_capacity(s * s), shift: Vec::with_capacity(s * s) };
    for row in rows {
        for (f, p, k) in row {
            t.f.push(f);
            t.pen.push(p);
            t.shift.push(k);
        }
    }
    t
}

/// Where the output lattice sits: its size and the output position of cell (0, 0)'s origin.
pub(crate) fn place(g: &Geometry, grid: &LatticeGrid, width: u32, height: u32) -> (usize, usize, (i64, i64)) {
    let (rows, cols) = (i64::from(grid.rows.unwrap_or(0)), i64::from(grid.cols.unwrap_or(0)));
    if rows == 0 || cols == 0 {
        let corners = [(0, 0), (width as i64 - 1, 0), (0, height as i64 - 1), (width as i64 - 1, height as i64 - 1)];
        let cells: Vec<(i64, i64)> = corners.iter().map(|&c| g.cell_of(c)).collect();
        let (m0, m1) = (cells.iter().map(|c| c.0).min().unwrap(), cells.iter().map(|c| c.0).max().unwrap());
        let (n0, n1) = (cells.iter().map(|c| c.1).min().unwrap(), cells.iter().map(|c| c.1).max().unwrap());
        ((n1 - n0 + 1) as usize, (m1 - m0 + 1) as usize, g.point(m0, n0))
    } else {
        let corners = [g.point(0, 0), g.point(cols, 0), g.point(0, rows), g.point(cols, rows)];
        let p0 = (-corners.iter().map(|c| c.0).min().unwrap(), -corners.iter().map(|c| c.1).min().unwrap());
        (rows as usize, cols as usize, p0)
    }
}

/// Copies each individual's texel (sample origin `origins[r·cols + c]`) into the output; pixels
/// no individual covers are an error unless `fill_black`. Exact cells are looked up per pixel
/// (B11); a Bresenham mask is painted individual by individual in row-major order, later over
/// earlier.
#[allow(clippy::too_many_arguments)]
pub(crate) fn render(
    sample: &RgbImage,
    g: &Geometry,
    shape: &Shape,
    origins: &[(i64, i64)],
    rows: usize,
    cols: usize,
    p0: (i64, i64),
    width: u32,
    height: u32,
    fill_black: bool,
    record: bool,
) -> Result<Canvas, SynthError> {
    let mut out = Canvas::new(width, height, sample.dimensions(), record);
    let mut uncovered = 0u64;
    if shape.exact {
        for y in 0..height as i64 {
            for x in 0..width as i64 {
                let rel = (x - p0.0, y - p0.1);
                let (m, n) = g.cell_of(rel);
                if m < 0 || n < 0 || m >= cols as i64 || n >= rows as i64 {
                    uncovered += 1;
                    continue;
                }
                let o = origins[n as usize * cols + m as usize];
                let c = g.point(m, n);
                let q = (rel.0 - c.0, rel.1 - c.1);
                out.copy(x as u32, y as u32, sample, (o.0 + q.0) as u32, (o.1 + q.1) as u32);
            }
        }
    } else {
        let (w, h) = (width as i64, height as i64);
        let mut covered = vec![false; (w * h) as usize];
        for r in 0..rows {
            for c in 0..cols {
                let o = origins[r * cols + c];
                let at = g.point(c as i64, r as i64);
                for &q in &shape.offsets {
                    let (x, y) = (p0.0 + at.0 + q.0, p0.1 + at.1 + q.1);
                    if x < 0 || y < 0 || x >= w || y >= h {
                        continue;
                    }
                    out.copy(x as u32, y as u32, sample, (o.0 + q.0) as u32, (o.1 + q.1) as u32);
                    covered[(y * w + x) as usize] = true;
                }
            }
        }
        uncovered = covered.iter().filter(|&&b| !b).count() as u64;
    }
    if uncovered > 0 && !fill_black {
        return Err(SynthError::Failed(format!(
            "the {rows}x{cols} lattice leaves {uncovered} of the {width}x{height} output pixels uncovered; use more rows/cols, rows = cols = \"cover\", or fill = \"black\""
        )));
    }
    Ok(out)
}

/// The strip shift of every neighbour pair, indexed by the earlier individual's position
/// (`r·cols + c`); `None` where there is no later neighbour or the pair is penalised (no strip).
/// Pairs of unmoved individuals read the table; a pair with a mutated individual applies the same
/// rule to pixels.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pair_shifts(
    sample: &RgbImage,
    g: &Geometry,
    table: &Table,
    strips: &Strips,
    assign: &[usize],
    origins: &[(i64, i64)],
    moved: &[bool],
    rows: usize,
    cols: usize,
) -> Vec<Option<u16>> {
    let step = if strips.horizontal { g.t1 } else { g.t2 };
    (0..rows * cols)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let (rb, cb) = if strips.horizontal { (r, c + 1) } else { (r + 1, c) };
            if rb >= rows || cb >= cols {
                return None;
            }
            let j = rb * cols + cb;
            if moved[i] || moved[j] {
                return overlap_fitness(sample, step, strips, origins[i], origins[j]).map(|x| x.1);
            }
            let e = assign[i] * table.s + assign[j];
            if table.pen[e] { None } else { Some(table.shift[e]) }
        })
        .collect()
}

/// Feathers every neighbour pair's overlap strip (B5 general strip), horizontal pairs first.
/// `pairs` holds, per direction, the shifts of [`pair_shifts`] and the strips.
#[allow(clippy::too_many_arguments)]
pub(crate) fn feather_strips(
    out: &mut Canvas,
    sample: &RgbImage,
    g: &Geometry,
    origins: &[(i64, i64)],
    rows: usize,
    cols: usize,
    p0: (i64, i64),
    pairs: [(&[Option<u16>], &Strips); 2],
) {
    for (shifts, strips) in pairs {
        let step = if strips.horizontal { g.t1 } else { g.t2 };
        let n_steps = (strips.rho * strips.l as f64).ceil().max(1.0) as u32;
        for r in 0..rows {
            for c in 0..cols {
                let (rb, cb) = if strips.horizontal { (r, c + 1) } else { (r + 1, c) };
                let Some(k) = shifts[r * cols + c] else { continue };
                let k = k as usize;
                let sigma = k as f64 / strips.l as f64;
                let origin_b = g.point(cb as i64, rb as i64);
                let (oa, ob) = (origins[r * cols + c], origins[rb * cols + cb]);
                for &q in &strips.by_shift[k].0 {
                    let (x, y) = (p0.0 + origin_b.0 + q.0, p0.1 + origin_b.1 + q.1);
                    if x < 0 || y < 0 || x >= out.width() as i64 || y >= out.height() as i64 {
                        continue;
                    }
                    let va = ((oa.0 + step.0 + q.0) as u32, (oa.1 + step.1 + q.1) as u32);
                    let vb = ((ob.0 + q.0) as u32, (ob.1 + q.1) as u32);
                    let (al, be) = g.coords(q);
                    let along = if strips.horizontal { al } else { be };
                    let tau = ((along - sigma + strips.rho) / strips.rho).clamp(0.0, 1.0 - 1e-12);
                    let kk = ((tau * n_steps as f64).floor() as u32).min(n_steps - 1);
                    // feather::blend(va, vb, new_weight(kk, n_steps)), recorded as a copy and a blend.
                    out.copy(x as u32, y as u32, sample, va.0, va.1);
                    out.blend(x as u32, y as u32, sample, vb.0, vb.1, kk + 1, n_steps + 1);
                }
            }
        }
    }
}

/// Degree-normalised fitness of sample `k` at `(r, c)` given the current assignment, and whether
/// any term is a penalty.
#[inline]
fn fitness(hv: (&Table, &Table), assign: &[usize], rows: usize, cols: usize, r: usize, c: usize, k: usize) -> (f64, bool) {
    let (h, v) = hv;
    let s = h.s;
    let (mut f, mut pen, mut deg) = (0.0, false, 0u32);
    let mut add = |t: &Table, a: usize, b: usize| {
        f += t.f[a * s + b];
        pen |= t.pen[a * s + b];
        deg += 1;
    };
    if c > 0 {
        add(h, assign[r * cols + c - 1], k);
    }
    if c + 1 < cols {
        add(h, k, assign[r * cols + c + 1]);
    }
    if r > 0 {
        add(v, assign[(r - 1) * cols + c], k);
    }
    if r + 1 < rows {
        add(v, k, assign[(r + 1) * cols + c]);
    }
    if deg == 0 { (0.0, false) } else { (f * 4.0 / deg as f64, pen) }
}

fn mean_fitness(hv: (&Table, &Table), assign: &[usize], rows: usize, cols: usize) -> f64 {
    let mut sum = 0.0;
    for r in 0..rows {
        for c in 0..cols {
            sum += fitness(hv, assign, rows, cols, r, c, assign[r * cols + c]).0;
        }
    }
    sum / (rows * cols) as f64
}

/// Eq. 5: the probability that an individual with degree-normalised fitness `fi` (penalised or
/// not) is updated, given the system average `f_bar`, the smallest non-penalised fitness `f_min`
/// and the weight `omega`.
fn update_probability((fi, pen): (f64, bool), f_bar: f64, f_min: f64, omega: f64) -> f64 {
    if pen {
        omega
    } else if fi <= f_bar {
        let f_nor = if f_bar == f_min { 0.0 } else { ((fi - f_min) / (f_bar - f_min)).clamp(0.0, 1.0) };
        omega / (1.0 + f_nor)
    } else {
        0.0
    }
}

/// What the mutation step (§2.7.1) works on.
pub(crate) struct Mutation<'a> {
    pub sample: &'a RgbImage,
    pub g: &'a Geometry,
    pub shape: &'a Shape,
    pub strips: (&'a Strips, &'a Strips),
    pub rows: usize,
    pub cols: usize,
    pub radius: i64,
}

impl Mutation<'_> {
    /// Degree-normalised fitness (and penalty) of an individual at sample origin `o` placed at
    /// `(r, c)`, from pixels, with its neighbours at `origins`: the terms, their order and the
    /// normalisation of [`fitness`], so an unmoved individual among unmoved ones scores exactly its
    /// table value.
    pub fn fitness(&self, origins: &[(i64, i64)], r: usize, c: usize, o: (i64, i64)) -> (f64, bool) {
        let (sh, sv) = self.strips;
        let (rows, cols) = (self.rows, self.cols);
        let (mut f, mut pen, mut deg) = (0.0, false, 0u32);
        let mut add = |x: Option<(f64, u16)>| {
            match x {
                Some((v, _)) => f += v,
                None => {
                    f += F_PEN;
                    pen = true;
                }
            }
            deg += 1;
        };
        if c > 0 {
            add(overlap_fitness(self.sample, self.g.t1, sh, origins[r * cols + c - 1], o));
        }
        if c + 1 < cols {
            add(overlap_fitness(self.sample, self.g.t1, sh, o, origins[r * cols + c + 1]));
        }
        if r > 0 {
            add(overlap_fitness(self.sample, self.g.t2, sv, origins[(r - 1) * cols + c], o));
        }
        if r + 1 < rows {
            add(overlap_fitness(self.sample, self.g.t2, sv, o, origins[(r + 1) * cols + c]));
        }
        if deg == 0 { (0.0, false) } else { (f * 4.0 / deg as f64, pen) }
    }

    /// The moves of the triggered individuals of one parity (`(r + c) % 2 == parity`), whose
    /// neighbours (the other parity) stay fixed: each takes the fittest integer origin within the
    /// disc of `radius` around its own whose texel fits in the sample (non-penalised candidates
    /// first; ties: the first in row-major order). Returns `(position, new origin)` for those that
    /// move, in position order.
    pub fn moves(&self, origins: &[(i64, i64)], triggered: &[bool], parity: usize) -> Vec<(usize, (i64, i64))> {
        let (w, h) = (self.sample.width() as i64, self.sample.height() as i64);
        let rad = self.radius;
        let disc: Vec<(i64, i64)> =
            (-rad..=rad).flat_map(|dy| (-rad..=rad).map(move |dx| (dx, dy))).filter(|&(dx, dy)| dx * dx + dy * dy <= rad * rad).collect();
        (0..self.rows * self.cols)
            .into_par_iter()
            .filter(|&i| triggered[i] && (i / self.cols + i % self.cols) % 2 == parity)
            .filter_map(|i| {
                let (r, c) = (i / self.cols, i % self.cols);
                let o0 = origins[i];
                let scored: Vec<((i64, i64), (f64, bool))> = disc
                    .iter()
                    .map(|d| (o0.0 + d.0, o0.1 + d.1))
                    .filter(|&o| fits(self.shape.bbox, o, w, h))
                    .map(|o| (o, self.fitness(origins, r, c, o)))
                    .collect();
                let any_ok = scored.iter().any(|x| !x.1.1);
                let best = (0..scored.len())
                    .filter(|&k| !any_ok || !scored[k].1.1)
                    .max_by(|&a, &b| scored[a].1.0.partial_cmp(&scored[b].1.0).unwrap().then(b.cmp(&a)))
                    .expect("the own origin is a candidate");
                (scored[best].0 != o0).then_some((i, scored[best].0))
            })
            .collect()
    }
}

impl Method for Coevolution {
    fn name(&self) -> &'static str {
        CoevolutionConfig::METHOD
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn summary(&self) -> &'static str {
        "paper 000: co-evolution of parallelogram texels on the sample's lattice (odd/even populations, H/V tables)"
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }
    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        match CoevolutionConfig::from_params(p) {
            Ok(cfg) => cfg.grid.check(sample),
            Err(e) => vec![e.into()],
        }
    }

    fn tileable(&self, _params: &Params, _sample: (u32, u32), _output: (u32, u32)) -> Result<(), String> {
        // The output is the sample's lattice (t1, t2) laid from one corner; it would wrap only
        // when the output size is a whole number of lattice periods, which t1 and t2 (found
        // per sample, generally oblique) almost never allow.
        Err("coevolution places texels on the sample's lattice, which does not wrap at the output's edges".into())
    }

    fn peak_memory(&self, _params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        // Measured (VmHWM of `texsyn run`, bricks_gray 256²): lattice extraction on the sample
        // (FFT autocorrelation, about 9 MB for 256²) and about 3.5 B per output pixel; 1024²:
        // 17 MB, 2048²: 28 MB in all (8 MB of it the process).
        crate::synth::method::linear_memory(sample, output, 4.0, 160.0, 2 << 20)
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let cfg = CoevolutionConfig::from_params(req.params)?;
        let sample = req.sample;
        let started = Instant::now();
        let (t1, t2, source) = cfg.grid.vectors(sample)?;
        let lattice_seconds = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let g = Geometry::new(t1, t2);
        let (w, h) = (sample.width() as i64, sample.height() as i64);
        let shape = Shape::new(&g, cfg.mask);
        let texels = texels_within(&g, shape.bbox, w, h);
        let s = texels.len();
        if s < 2 {
            return Err(SynthError::Failed(format!(
                "the lattice t1 = {t1:?}, t2 = {t2:?} fits only {s} complete texel(s) in the sample; at least 2 are needed"
            )));
        }
        let rho = cfg.rho;
        let (sh, sv) = (Strips::new(&g, rho, true), Strips::new(&g, rho, false));
        let (th, tv) = (build_table(sample, &g, &texels, &sh), build_table(sample, &g, &texels, &sv));
        let tables_seconds = started.elapsed().as_secs_f64();
        let iter_started = Instant::now();
        let (rows, cols, p0) = place(&g, &cfg.grid, req.width, req.height);
        let hv = (&th, &tv);

        // Initialisation: random even individuals, greedy odd ones.
        let mut assign = vec![0usize; rows * cols];
        let mut init = Stream::new(req.seed, "coevo/init");
        for r in 0..rows {
            for c in 0..cols {
                if (r + c) % 2 == 0 {
                    assign[r * cols + c] = init.below_usize(s);
                }
            }
        }
        let greedy: Vec<(usize, usize)> = (0..rows * cols)
            .into_par_iter()
            .filter(|i| (i / cols + i % cols) % 2 == 1)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                let scored: Vec<(f64, bool)> = (0..s).map(|k| fitness(hv, &assign, rows, cols, r, c, k)).collect();
                let any_ok = scored.iter().any(|x| !x.1);
                let best = (0..s)
                    .filter(|&k| !any_ok || !scored[k].1)
                    .max_by(|&a, &b| scored[a].0.partial_cmp(&scored[b].0).unwrap().then(b.cmp(&a)))
                    .expect("s ≥ 2");
                (i, best)
            })
            .collect();
        for (i, k) in greedy {
            assign[i] = k;
        }
        let mut history = vec![mean_fitness(hv, &assign, rows, cols)];
        let iter_max = cfg.iter_max as usize;
        let m_window = cfg.window as usize;
        let (c_tol, t_m) = (cfg.c_tol, cfg.t_m);
        let mut iterations = 0;
        for iter in 1..=iter_max {
            iterations = iter;
            let parity = iter % 2; // odd iterations update odd individuals
            let omega = iter_max as f64 / (iter + iter_max) as f64;
            let f_bar = *history.last().expect("f̄⁰");
            let active: Vec<usize> = (0..rows * cols).filter(|i| (i / cols + i % cols) % 2 == parity).collect();
            let current: Vec<(f64, bool)> =
                active.iter().map(|&i| fitness(hv, &assign, rows, cols, i / cols, i % cols, assign[i])).collect();
            let f_min = current.iter().filter(|x| !x.1).map(|x| x.0).fold(f64::INFINITY, f64::min);
            let updates: Vec<(usize, usize)> = active
                .par_iter()
                .zip(current.par_iter())
                .filter_map(|(&i, &(fi, pen))| {
                    let (r, c) = (i / cols, i % cols);
                    let u = update_probability((fi, pen), f_bar, f_min, omega);
                    let mut st = Stream::new(req.seed, &format!("coevo/update/iter={iter}/r={r}/c={c}"));
                    if st.uniform_f64() >= u {
                        return None;
                    }
                    let scored: Vec<(f64, bool)> = (0..s).map(|k| fitness(hv, &assign, rows, cols, r, c, k)).collect();
                    let any_ok = scored.iter().any(|x| !x.1);
                    let eligible = |k: &usize| !any_ok || !scored[*k].1;
                    let fmin = (0..s).filter(eligible).map(|k| scored[k].0).fold(f64::INFINITY, f64::min);
                    let fmax = (0..s).filter(eligible).map(|k| scored[k].0).fold(f64::NEG_INFINITY, f64::max);
                    let threshold = c_tol * fmin + (1.0 - c_tol) * fmax;
                    let cands: Vec<usize> = (0..s).filter(eligible).filter(|&k| scored[k].0 >= threshold).collect();
                    Some((i, cands[st.below_usize(cands.len())]))
                })
                .collect();
            for (i, k) in updates {
                assign[i] = k;
            }
            history.push(mean_fitness(hv, &assign, rows, cols));
            if iter > m_window && converged(&history, m_window, t_m) {
                break;
            }
        }
        let iter_seconds = iter_started.elapsed().as_secs_f64();

        // Mutation (§2.7.1): off unless r_mut > 0.
        let n = rows * cols;
        let mut origins: Vec<(i64, i64)> = assign.iter().map(|&k| texels[k]).collect();
        let mut moved = vec![false; n];
        let r_mut = i64::from(cfg.r_mut);
        let mut mutation = None;
        if r_mut > 0 {
            let omega = iter_max as f64 / (iterations + iter_max) as f64;
            let f_bar = *history.last().expect("f̄");
            let current: Vec<(f64, bool)> = (0..n).map(|i| fitness(hv, &assign, rows, cols, i / cols, i % cols, assign[i])).collect();
            let f_min = current.iter().filter(|x| !x.1).map(|x| x.0).fold(f64::INFINITY, f64::min);
            let triggered: Vec<bool> = (0..n)
                .map(|i| {
                    let u = update_probability(current[i], f_bar, f_min, omega);
                    Stream::new(req.seed, &format!("coevo/mutate/r={}/c={}", i / cols, i % cols)).uniform_f64() < u
                })
                .collect();
            let m = Mutation { sample, g: &g, shape: &shape, strips: (&sh, &sv), rows, cols, radius: r_mut };
            for parity in [0, 1] {
                for (i, o) in m.moves(&origins, &triggered, parity) {
                    origins[i] = o;
                    moved[i] = true;
                }
            }
            let after = (0..n).map(|i| m.fitness(&origins, i / cols, i % cols, origins[i]).0).sum::<f64>() / n as f64;
            mutation = Some(serde_json::json!({
                "radius": r_mut,
                "triggered": triggered.iter().filter(|&&b| b).count(),
                "moved": moved.iter().filter(|&&b| b).count(),
                "mean_fitness": after,
            }));
        }

        let mut canvas =
            render(sample, &g, &shape, &origins, rows, cols, p0, req.width, req.height, cfg.grid.fill == Fill::Black, req.placement)?;
        let ph = pair_shifts(sample, &g, &th, &sh, &assign, &origins, &moved, rows, cols);
        let pv = pair_shifts(sample, &g, &tv, &sv, &assign, &origins, &moved, rows, cols);
        feather_strips(&mut canvas, sample, &g, &origins, rows, cols, p0, [(&ph, &sh), (&pv, &sv)]);
        let (image, placement) = canvas.finish();
        let mut diagnostics = serde_json::json!({
            "lattice": { "t1": [g.t1.0, g.t1.1], "t2": [g.t2.0, g.t2.1], "source": source },
            "texels": s,
            "lattice_size": { "rows": rows, "cols": cols },
            "iterations": iterations,
            "mean_fitness": history,
            "penalised_entries": { "H": th.pen.iter().filter(|&&b| b).count(), "V": tv.pen.iter().filter(|&&b| b).count() },
        });
        // Keys for the non-default options only, so default jobs keep their records.
        if !shape.exact {
            diagnostics["mask"] = serde_json::json!({ "kind": "bresenham", "pixels": shape.offsets.len(), "cell_pixels": g.d });
        }
        if let Some(m) = mutation {
            diagnostics["mutation"] = m;
        }
        Ok(Synthesis {
            image,
            seams: None,
            diagnostics,
            phases: vec![("lattice".into(), lattice_seconds), ("tables".into(), tables_seconds), ("iterations".into(), iter_seconds)],
            extras: Vec::new(),
            placement,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::grid::{cross, texels};
    use super::*;
    use crate::synth::params::resolve;

    fn params(given: &[(&str, ParamValue)]) -> Params {
        let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        resolve(PARAMS, &g).unwrap()
    }

    /// A periodic texture on the lattice (20, 0), (6, 16), each texel's blob shaded differently.
    fn periodic() -> RgbImage {
        let (t1, t2) = ((20i64, 0i64), (6i64, 16i64));
        let d = cross(t1, t2) as f64;
        RgbImage::from_fn(120, 120, |x, y| {
            let (x, y) = (x as i64, y as i64);
            let a = cross((x, y), t2) as f64 / d;
            let b = cross(t1, (x, y)) as f64 / d;
            let (fa, fb) = (a - a.floor() - 0.5, b - b.floor() - 0.5);
            let v = if fa * fa + fb * fb < 0.07 { 210 } else { 50 };
            [v, v / 2, 255 - v]
        })
    }

    #[test]
    fn cells_partition_the_plane_exactly() {
        let g = Geometry::new((20, 0), (6, 16));
        assert_eq!(g.cell.len() as i64, g.d);
        for y in -30..30 {
            for x in -30..30 {
                let (m, n) = g.cell_of((x, y));
                let c = g.point(m, n);
                assert!(g.cell.contains(&(x - c.0, y - c.1)));
            }
        }
    }

    #[test]
    fn natural_neighbours_have_zero_cost_and_parities_balance() {
        let img = periodic();
        let g = Geometry::new((20, 0), (6, 16));
        let tex = texels(&g, 120, 120);
        let sh = Strips::new(&g, 1.0 / 6.0, true);
        let th = build_table(&img, &g, &tex, &sh);
        for (a, &oa) in tex.iter().enumerate() {
            if let Some(b) = tex.iter().position(|&ob| ob == (oa.0 + 20, oa.1)) {
                assert!(!th.pen[a * tex.len() + b]);
                assert_eq!(th.f[a * tex.len() + b], 0.0);
            }
        }
        // Σ_odd F = Σ_even F for the unnormalised sums (every edge has one odd and one even end).
        let sv = Strips::new(&g, 1.0 / 6.0, false);
        let tv = build_table(&img, &g, &tex, &sv);
        let (rows, cols) = (4, 5);
        let mut st = Stream::new(1, "t");
        let assign: Vec<usize> = (0..rows * cols).map(|_| st.below_usize(tex.len())).collect();
        let (mut odd, mut even) = (0.0, 0.0);
        for r in 0..rows {
            for c in 0..cols {
                let k = assign[r * cols + c];
                let mut f = 0.0;
                if c > 0 {
                    f += th.f[assign[r * cols + c - 1] * tex.len() + k];
                }
                if c + 1 < cols {
                    f += th.f[k * tex.len() + assign[r * cols + c + 1]];
                }
                if r > 0 {
                    f += tv.f[assign[(r - 1) * cols + c] * tex.len() + k];
                }
                if r + 1 < rows {
                    f += tv.f[k * tex.len() + assign[(r + 1) * cols + c]];
                }
                if (r + c) % 2 == 1 { odd += f } else { even += f }
            }
        }
        assert!((odd - even).abs() < 1e-6 * odd.abs().max(1.0), "{odd} vs {even}");
    }

    #[test]
    fn a_periodic_sample_is_reproduced_with_perfect_fitness() {
        let img = periodic();
        let p = params(&[
            ("t1_x", ParamValue::Int(20)),
            ("t2_x", ParamValue::Int(6)),
            ("t2_y", ParamValue::Int(16)),
            ("c_tol", ParamValue::Float(0.0)),
        ]);
        let out = Coevolution
            .synthesize(&Request {
                sample: &img,
                width: 90,
                height: 70,
                params: &p,
                seed: 4,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap();
        assert_eq!(out.image.dimensions(), (90, 70));
        let hist = out.diagnostics["mean_fitness"].as_array().unwrap();
        assert_eq!(hist.last().unwrap().as_f64(), Some(0.0), "{hist:?}");
        // The output is periodic on the same lattice.
        for y in 0..50 {
            for x in 0..60 {
                assert_eq!(out.image.get(x, y), out.image.get(x + 20, y), "({x},{y})");
            }
        }
    }

    #[test]
    fn deterministic_across_thread_counts_and_extracts_the_lattice() {
        let img = periodic();
        let p = params(&[]);
        let req = Request {
            sample: &img,
            width: 64,
            height: 64,
            params: &p,
            seed: 9,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        };
        let a = Coevolution.synthesize(&req).unwrap();
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let b = one.install(|| Coevolution.synthesize(&req).unwrap());
        assert_eq!(a.image, b.image);
        assert_eq!(a.diagnostics["lattice"]["source"], "extracted");
    }

    #[test]
    fn clear_errors() {
        let p = params(&[("t1_x", ParamValue::Int(10)), ("t2_x", ParamValue::Int(20)), ("rows", ParamValue::Int(3))]);
        let errs = Coevolution.check(&p, (100, 100), (50, 50));
        let text: Vec<String> = errs.iter().map(|e| e.message.clone()).collect();
        assert!(text.iter().any(|m| m.contains("parallel")), "{text:?}");
        assert!(text.iter().any(|m| m.contains("rows and cols")), "{text:?}");
        let mut st = Stream::new(3, "noise");
        let noise = RgbImage::from_fn(64, 64, |_, _| [st.below(256) as u8, st.below(256) as u8, st.below(256) as u8]);
        let e = Coevolution
            .synthesize(&Request {
                sample: &noise,
                width: 40,
                height: 40,
                params: &params(&[]),
                seed: 1,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("no lattice found; give t1/t2"), "{e}");
        let small = params(&[
            ("t1_x", ParamValue::Int(20)),
            ("t2_x", ParamValue::Int(6)),
            ("t2_y", ParamValue::Int(16)),
            ("rows", ParamValue::Int(2)),
            ("cols", ParamValue::Int(2)),
        ]);
        let e = Coevolution
            .synthesize(&Request {
                sample: &periodic(),
                width: 200,
                height: 200,
                params: &small,
                seed: 1,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("uncovered"), "{e}");
    }

    /// The default pixels are those of the blessed golden jobs, whether `mask` and `r_mut` are left
    /// out or given as their defaults (the options must not change existing jobs).
    #[test]
    fn defaults_and_r_mut_0_reproduce_the_golden_pixels() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        for name in ["weave_gray", "tiles_terracotta"] {
            let (sample, _) =
                crate::image::io::read_rgb8(&root.join(format!("jobs/samples/{name}.png")), crate::image::io::DecodeLimits::default())
                    .unwrap();
            let golden: serde_json::Value =
                serde_json::from_slice(&std::fs::read(root.join(format!("golden/coevolution/{name}.json"))).unwrap()).unwrap();
            let want =
                golden[format!("coevolution/{name}.toml")][format!("coevolution/{name}.png")]["sha256"].as_str().unwrap().to_string();
            for p in [params(&[]), params(&[("r_mut", ParamValue::Int(0)), ("mask", ParamValue::Str("exact".into()))])] {
                let out = Coevolution
                    .synthesize(&Request {
                        sample: &sample,
                        width: 384,
                        height: 384,
                        params: &p,
                        seed: 7,
                        placement: false,
                        tileable: false,
                        constraints: std::default::Default::default(),
                    })
                    .unwrap();
                assert_eq!(crate::image::io::rgb_pixel_digest(&out.image).sha256, want, "{name}");
                assert!(out.diagnostics.get("mask").is_none() && out.diagnostics.get("mutation").is_none());
            }
        }
    }

    /// Slanted lattices (and one axis-aligned) of the kinds the bundled samples have.
    const LATTICES: [((i64, i64), (i64, i64)); 6] =
        [((20, 0), (6, 16)), ((60, 12), (0, 48)), ((36, 24), (-38, 24)), ((25, 7), (-5, 21)), ((17, -9), (8, 19)), ((27, 0), (0, 26))];

    /// Distance from `p` to the boundary of the closed parallelogram spanned by `t1`, `t2` at 0.
    fn distance_to_edges(g: &Geometry, p: (i64, i64)) -> f64 {
        let corners = [(0, 0), g.t1, (g.t1.0 + g.t2.0, g.t1.1 + g.t2.1), g.t2];
        (0..4)
            .map(|i| {
                let (a, b) = (corners[i], corners[(i + 1) % 4]);
                let (dx, dy) = ((b.0 - a.0) as f64, (b.1 - a.1) as f64);
                let t = ((((p.0 - a.0) as f64) * dx + ((p.1 - a.1) as f64) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
                ((a.0 as f64 + t * dx - p.0 as f64).powi(2) + (a.1 as f64 + t * dy - p.1 as f64).powi(2)).sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn bresenham_mask_has_no_holes_and_differs_from_the_cell_only_near_edges() {
        for (t1, t2) in LATTICES {
            let g = Geometry::new(t1, t2);
            let mask = bresenham_mask(g.t1, g.t2);
            let set: std::collections::HashSet<(i64, i64)> = mask.iter().copied().collect();
            assert_eq!(set.len(), mask.len());
            let (x0, x1, y0, y1) = bbox_of(&[(0, 0), g.t1, g.t2, (g.t1.0 + g.t2.0, g.t1.1 + g.t2.1)]);
            for y in y0 - 3..=y1 + 3 {
                for x in x0 - 3..=x1 + 3 {
                    let (a, b) = (cross((x, y), g.t2), cross(g.t1, (x, y)));
                    let closed = (0..=g.d).contains(&a) && (0..=g.d).contains(&b);
                    let in_cell = (0..g.d).contains(&a) && (0..g.d).contains(&b);
                    // No holes: every pixel of the closed parallelogram is in the mask.
                    assert!(!closed || set.contains(&(x, y)), "{t1:?} {t2:?}: hole at ({x}, {y})");
                    // Mask and exact cell differ only within 1.5 px of the edges.
                    if set.contains(&(x, y)) != in_cell {
                        assert!(distance_to_edges(&g, (x, y)) <= 1.5, "{t1:?} {t2:?}: ({x}, {y}) differs far from the edges");
                    }
                }
            }
        }
        // The second pass matters: the sums alone leave holes on the staggered bricks lattice.
        let g = Geometry::new((36, 24), (-38, 24));
        let (l1, l2) = (bresenham_line(g.t1), bresenham_line(g.t2));
        let sums: std::collections::HashSet<(i64, i64)> = l1.iter().flat_map(|p| l2.iter().map(move |q| (p.0 + q.0, p.1 + q.1))).collect();
        assert!(g.cell.iter().any(|c| !sums.contains(c)));
        // Paths: one pixel per major step, both ends included, rounding half towards the start.
        assert_eq!(bresenham_line((4, 2)), [(0, 0), (1, 0), (2, 1), (3, 1), (4, 2)]);
        assert_eq!(bresenham_line((-2, 4)), [(0, 0), (0, 1), (-1, 2), (-1, 3), (-2, 4)]);
    }

    /// A sample whose every pixel differs (so any change of source shows).
    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut st = Stream::new(seed, "noise");
        RgbImage::from_fn(w, h, |_, _| [st.below(256) as u8, st.below(256) as u8, st.below(256) as u8])
    }

    #[test]
    fn bresenham_rendering_differs_from_exact_only_near_edges() {
        let sample = noise(160, 160, 5);
        for (t1, t2) in [((20, 0), (6, 16)), ((25, 7), (-5, 21)), ((17, -9), (8, 19))] {
            let g = Geometry::new(t1, t2);
            let (exact, bres) = (Shape::new(&g, Mask::Exact), Shape::new(&g, Mask::Bresenham));
            let tex = texels_within(&g, bres.bbox, 160, 160);
            assert!(tex.len() >= 4);
            let (rows, cols) = (5, 6);
            let mut st = Stream::new(2, "assign");
            let origins: Vec<(i64, i64)> = (0..rows * cols).map(|_| tex[st.below_usize(tex.len())]).collect();
            let corners = [g.point(0, 0), g.point(cols as i64, 0), g.point(0, rows as i64), g.point(cols as i64, rows as i64)];
            let p0 = (-corners.iter().map(|c| c.0).min().unwrap(), -corners.iter().map(|c| c.1).min().unwrap());
            let (w, h) = (
                corners.iter().map(|c| c.0 + p0.0).max().unwrap() as u32 + 3,
                corners.iter().map(|c| c.1 + p0.1).max().unwrap() as u32 + 3,
            );
            let a = render(&sample, &g, &exact, &origins, rows, cols, p0, w, h, true, false).unwrap().image;
            let b = render(&sample, &g, &bres, &origins, rows, cols, p0, w, h, true, false).unwrap().image;
            let mut differing = 0;
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    if a.get(x as u32, y as u32) == b.get(x as u32, y as u32) {
                        continue;
                    }
                    differing += 1;
                    let rel = (x - p0.0, y - p0.1);
                    let (m, n) = g.cell_of(rel);
                    let c = g.point(m, n);
                    let d = distance_to_edges(&g, (rel.0 - c.0, rel.1 - c.1));
                    assert!(d <= 1.5, "{t1:?} {t2:?}: ({x}, {y}) differs {d:.2} px from the cell edges");
                }
            }
            assert!(differing > 0, "{t1:?} {t2:?}: the masks made no difference");
        }
    }

    #[test]
    fn bresenham_mask_is_thread_independent_and_recorded() {
        let img = noise(120, 120, 8);
        for lattice in [[20, 0, 6, 16], [25, 7, -5, 21]] {
            let names = ["t1_x", "t1_y", "t2_x", "t2_y"];
            let mut given: Vec<(&str, ParamValue)> = names.iter().zip(lattice).map(|(n, v)| (*n, ParamValue::Int(v))).collect();
            let exact = params(&given);
            given.push(("mask", ParamValue::Str("bresenham".into())));
            let p = params(&given);
            let req = Request {
                sample: &img,
                width: 80,
                height: 70,
                params: &p,
                seed: 3,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            };
            let a = Coevolution.synthesize(&req).unwrap();
            let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            assert_eq!(a.image, one.install(|| Coevolution.synthesize(&req).unwrap()).image);
            assert_eq!(a.diagnostics["mask"]["kind"], "bresenham");
            assert!(a.diagnostics["mask"]["pixels"].as_i64().unwrap() > a.diagnostics["mask"]["cell_pixels"].as_i64().unwrap());
            let e = Coevolution.synthesize(&Request { params: &exact, ..req }).unwrap();
            assert_ne!(a.image, e.image);
        }
    }

    /// A periodic sample with noise, so texels differ and nearby origins can fit better.
    fn noisy_periodic() -> RgbImage {
        let base = periodic();
        let mut st = Stream::new(11, "jitter");
        RgbImage::from_fn(120, 120, |x, y| base.get(x, y).map(|v| v.saturating_add(st.below(40) as u8)))
    }

    #[test]
    fn mutation_never_lowers_an_individuals_fitness() {
        let img = noisy_periodic();
        for mask in ["exact", "bresenham"] {
            let g = Geometry::new((20, 0), (6, 16));
            let shape = Shape::new(&g, Mask::parse(mask).unwrap());
            let tex = texels_within(&g, shape.bbox, 120, 120);
            let (sh, sv) = (Strips::new(&g, 1.0 / 6.0, true), Strips::new(&g, 1.0 / 6.0, false));
            let (th, tv) = (build_table(&img, &g, &tex, &sh), build_table(&img, &g, &tex, &sv));
            let (rows, cols) = (4, 5);
            let mut st = Stream::new(4, "assign");
            let assign: Vec<usize> = (0..rows * cols).map(|_| st.below_usize(tex.len())).collect();
            let mut origins: Vec<(i64, i64)> = assign.iter().map(|&k| tex[k]).collect();
            let m = Mutation { sample: &img, g: &g, shape: &shape, strips: (&sh, &sv), rows, cols, radius: 3 };
            // From pixels, an unmoved lattice scores exactly its table fitness.
            for i in 0..rows * cols {
                let (r, c) = (i / cols, i % cols);
                assert_eq!(m.fitness(&origins, r, c, origins[i]), fitness((&th, &tv), &assign, rows, cols, r, c, assign[i]));
            }
            // Σ over the lattice edges (each once), from pixels.
            let edges = |o: &[(i64, i64)]| -> f64 {
                let mut sum = 0.0;
                for r in 0..rows {
                    for c in 0..cols {
                        if c + 1 < cols {
                            sum += overlap_fitness(&img, g.t1, &sh, o[r * cols + c], o[r * cols + c + 1]).map_or(F_PEN, |x| x.0);
                        }
                        if r + 1 < rows {
                            sum += overlap_fitness(&img, g.t2, &sv, o[r * cols + c], o[(r + 1) * cols + c]).map_or(F_PEN, |x| x.0);
                        }
                    }
                }
                sum
            };
            let triggered = vec![true; rows * cols];
            let mut moved = 0;
            for parity in [0, 1] {
                let before = edges(&origins);
                let moves = m.moves(&origins, &triggered, parity);
                let mut next = origins.clone();
                for &(i, o) in &moves {
                    let (r, c) = (i / cols, i % cols);
                    assert_eq!((r + c) % 2, parity);
                    assert!((o.0 - origins[i].0).pow(2) + (o.1 - origins[i].1).pow(2) <= 9);
                    let (old, new) = (m.fitness(&origins, r, c, origins[i]), m.fitness(&origins, r, c, o));
                    assert!((old.1 && !new.1) || (old.1 == new.1 && new.0 >= old.0), "{mask}: ({r}, {c}) {old:?} -> {new:?}");
                    next[i] = o;
                }
                moved += moves.len();
                origins = next;
                assert!(edges(&origins) >= before, "{mask}: the edge sum fell");
            }
            assert!(moved > 0, "{mask}: nothing moved; the test proves nothing");
        }
    }

    /// A near-regular sample: smooth stripes whose phases change from cell to cell, so a texel's
    /// best partner is often slightly off the lattice (what mutation is for).
    fn phased() -> RgbImage {
        let g = Geometry::new((20, 0), (6, 16));
        let mut st = Stream::new(12, "phases");
        let phases: Vec<(f64, f64)> = (0..100).map(|_| (st.uniform_range(0.0, 6.3), st.uniform_range(0.0, 6.3))).collect();
        RgbImage::from_fn(120, 120, |x, y| {
            let (m, n) = g.cell_of((x as i64, y as i64));
            let (a, b) = phases[((m.rem_euclid(10)) * 10 + n.rem_euclid(10)) as usize];
            let v = 128.0 + 80.0 * (x as f64 * 0.9 + a).sin() + 40.0 * (y as f64 * 0.7 + b).sin();
            let v = v.clamp(0.0, 255.0) as u8;
            [v, 255 - v, v / 2]
        })
    }

    #[test]
    fn mutation_is_thread_independent_and_recorded() {
        let img = phased();
        let lattice = [("t1_x", ParamValue::Int(20)), ("t2_x", ParamValue::Int(6)), ("t2_y", ParamValue::Int(16))];
        let off = params(&lattice);
        let mut given = lattice.to_vec();
        given.push(("r_mut", ParamValue::Int(3)));
        let on = params(&given);
        let req = Request {
            sample: &img,
            width: 90,
            height: 80,
            params: &on,
            seed: 6,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        };
        let a = Coevolution.synthesize(&req).unwrap();
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(a.image, one.install(|| Coevolution.synthesize(&req).unwrap()).image);
        let mutation = &a.diagnostics["mutation"];
        assert_eq!(mutation["radius"], 3);
        assert!(mutation["moved"].as_u64().unwrap() > 0, "{mutation}");
        assert!(mutation["moved"].as_u64() <= mutation["triggered"].as_u64());
        // Evolution is unchanged (mutation runs after it); only the moved individuals differ.
        let b = Coevolution.synthesize(&Request { params: &off, ..req }).unwrap();
        assert_eq!(a.diagnostics["mean_fitness"], b.diagnostics["mean_fitness"]);
        assert_ne!(a.image, b.image);
    }
}
