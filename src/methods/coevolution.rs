//! Co-evolution near-regular texture synthesis (paper 000, methods.md §2.3–2.7).
//!
//! Near-regular textures (bricks, tiles, weaves) must keep their texel lattice. Individuals are
//! the sample's parallelogram texels spanned by the lattice vectors `t1, t2` (found by
//! `crate::lattice` or given by the job); the output lattice is split by the parity of `r + c` into
//! two populations that evolve alternately, each being the other's fixed environment, so every
//! individual of one parity can be updated in parallel; and all pairwise overlap fitness values are
//! precomputed in two tables `H` and `V`, so an iteration is table look-ups. Overlaps are feathered
//! at render time.

use super::{Method, Request, Synthesis};
use crate::RgbImage;
use crate::lattice::{LatticeOptions, extract};
use crate::params::{Default, ParamError, ParamKind, ParamSpec, Params};
use crate::primitives::feather;
use crate::primitives::overlap::pixel_error;
use crate::rng::Stream;
use rayon::prelude::*;
use std::time::Instant;

pub struct Coevolution;

/// The worst possible mean error, recorded (and flagged) when no overlap fits in the sample.
pub const F_PEN: f64 = -195075.0;

pub(crate) const LATTICE_PARAMS: [ParamSpec; 7] = [
    ParamSpec { name: "t1_x", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t1 (x); t1 = t2 = 0 (default) extracts the lattice from the sample" },
    ParamSpec { name: "t1_y", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t1 (y)" },
    ParamSpec { name: "t2_x", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t2 (x)" },
    ParamSpec { name: "t2_y", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t2 (y)" },
    ParamSpec { name: "rows", kind: ParamKind::Int { min: 0, max: 4096 }, default: Default::Int(0), doc: "output lattice rows (along t2); 0 = enough to cover the output" },
    ParamSpec { name: "cols", kind: ParamKind::Int { min: 0, max: 4096 }, default: Default::Int(0), doc: "output lattice columns (along t1); 0 = enough to cover the output" },
    ParamSpec { name: "fill", kind: ParamKind::Choice(&["error", "black"]), default: Default::Str("error"), doc: "output pixels the lattice does not cover: an error, or black" },
];

const PARAMS: &[ParamSpec] = &[
    LATTICE_PARAMS[0],
    LATTICE_PARAMS[1],
    LATTICE_PARAMS[2],
    LATTICE_PARAMS[3],
    LATTICE_PARAMS[4],
    LATTICE_PARAMS[5],
    LATTICE_PARAMS[6],
    ParamSpec { name: "rho", kind: ParamKind::Float { min: 0.0, max: 0.5 }, default: Default::Float(1.0 / 6.0), doc: "overlap width as a fraction of the texel (at least 2 px)" },
    ParamSpec { name: "c_tol", kind: ParamKind::Float { min: 0.0, max: 1.0 }, default: Default::Float(0.05), doc: "candidate tolerance: 0 keeps only the best-fitting samples, larger trades seams for variety" },
    ParamSpec { name: "t_m", kind: ParamKind::Float { min: 0.0, max: 10.0 }, default: Default::Float(0.02), doc: "termination: stop when the relative spread of the last `window` averages is at most t_m" },
    ParamSpec { name: "window", kind: ParamKind::Int { min: 1, max: 1000 }, default: Default::Int(5), doc: "averages in the termination window (M)" },
    ParamSpec { name: "iter_max", kind: ParamKind::Int { min: 1, max: 100_000 }, default: Default::Int(50), doc: "iteration cap" },
];

fn cross(a: (i64, i64), b: (i64, i64)) -> i64 {
    a.0 * b.1 - a.1 * b.0
}

/// The lattice geometry of one job (B11: exact integer membership).
pub(crate) struct Geometry {
    pub t1: (i64, i64),
    pub t2: (i64, i64),
    pub d: i64,
    /// The `D` pixels of cell (0, 0), row-major.
    pub cell: Vec<(i64, i64)>,
    /// Bounding box of `cell`: (xmin, xmax, ymin, ymax).
    pub bbox: (i64, i64, i64, i64),
}

impl Geometry {
    pub fn new(t1: (i64, i64), t2: (i64, i64)) -> Geometry {
        let (t1, t2) = if cross(t1, t2) < 0 { (t1, (-t2.0, -t2.1)) } else { (t1, t2) };
        let d = cross(t1, t2);
        let xs = [0, t1.0, t2.0, t1.0 + t2.0];
        let ys = [0, t1.1, t2.1, t1.1 + t2.1];
        let (x0, x1) = (*xs.iter().min().unwrap(), *xs.iter().max().unwrap());
        let (y0, y1) = (*ys.iter().min().unwrap(), *ys.iter().max().unwrap());
        let mut cell = Vec::new();
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (a, b) = (cross((x, y), t2), cross(t1, (x, y)));
                if (0..d).contains(&a) && (0..d).contains(&b) {
                    cell.push((x, y));
                }
            }
        }
        let bbox = bbox_of(&cell);
        Geometry { t1, t2, d, cell, bbox }
    }

    /// Lattice cell of an integer offset.
    pub fn cell_of(&self, p: (i64, i64)) -> (i64, i64) {
        (cross(p, self.t2).div_euclid(self.d), cross(self.t1, p).div_euclid(self.d))
    }

    pub fn point(&self, m: i64, n: i64) -> (i64, i64) {
        (m * self.t1.0 + n * self.t2.0, m * self.t1.1 + n * self.t2.1)
    }

    /// Coordinates along t1 and t2 as fractions (for strip rules).
    pub fn coords(&self, q: (i64, i64)) -> (f64, f64) {
        (cross(q, self.t2) as f64 / self.d as f64, cross(self.t1, q) as f64 / self.d as f64)
    }
}

fn bbox_of(pts: &[(i64, i64)]) -> (i64, i64, i64, i64) {
    let mut b = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    for &(x, y) in pts {
        b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
    }
    b
}

/// Whether every pixel of `offsets` (given by their bbox) shifted by `o` lies in a `w × h` image.
fn fits(bbox: (i64, i64, i64, i64), o: (i64, i64), w: i64, h: i64) -> bool {
    o.0 + bbox.0 >= 0 && o.0 + bbox.1 < w && o.1 + bbox.2 >= 0 && o.1 + bbox.3 < h
}

/// The sample's texels `E_I` (§2.3): origins of the complete texels for the best lattice origin.
pub(crate) fn texels(g: &Geometry, w: i64, h: i64) -> Vec<(i64, i64)> {
    let span = (w + h) / (g.t1.0.abs().max(g.t1.1.abs()).min(g.t2.0.abs().max(g.t2.1.abs())).max(1)) + 3;
    let list = |o: (i64, i64)| -> Vec<(i64, i64)> {
        let mut v = Vec::new();
        for n in -span..=span {
            for m in -span..=span {
                let p = g.point(m, n);
                let ok = (o.0 + p.0, o.1 + p.1);
                if fits(g.bbox, ok, w, h) {
                    v.push(ok);
                }
            }
        }
        v
    };
    // Best origin: most complete texels; ties smallest o.y, then o.x.
    let mut order: Vec<(i64, i64)> = g.cell.clone();
    order.sort_by_key(|&(x, y)| (y, x));
    let counts: Vec<usize> = order.par_iter().map(|&o| list(o).len()).collect();
    let best = (0..order.len()).max_by(|&i, &j| counts[i].cmp(&counts[j]).then(j.cmp(&i))).expect("cell is not empty");
    list(order[best])
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

/// Builds `H` (horizontal) or `V` (vertical): entry `[a][b]` is the fitness of `a` west of (north
/// of) `b`, with the first shift that keeps both strips inside the sample.
pub(crate) fn build_table(sample: &RgbImage, g: &Geometry, texels: &[(i64, i64)], strips: &Strips) -> Table {
    let s = texels.len();
    let (w, h) = (sample.width() as i64, sample.height() as i64);
    let step = if strips.horizontal { g.t1 } else { g.t2 };
    let rows: Vec<Vec<(f64, bool, u16)>> = (0..s)
        .into_par_iter()
        .map(|a| {
            let oa = texels[a];
            let base_a = (oa.0 + step.0, oa.1 + step.1);
            (0..s)
                .map(|b| {
                    let ob = texels[b];
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
                        return (-(d as f64) / strip.len() as f64, false, k as u16);
                    }
                    (F_PEN, true, 0)
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

/// Lattice vectors from the params, or extracted from the sample.
pub(crate) fn lattice_vectors(p: &Params, sample: &RgbImage) -> Result<((i64, i64), (i64, i64), &'static str), String> {
    let t1 = (p.int("t1_x"), p.int("t1_y"));
    let t2 = (p.int("t2_x"), p.int("t2_y"));
    if t1 == (0, 0) && t2 == (0, 0) {
        let l = extract(sample, &LatticeOptions::default())?;
        Ok((l.t1, l.t2, "extracted"))
    } else {
        Ok((t1, t2, "given"))
    }
}

pub(crate) fn check_lattice_params(p: &Params, sample: (u32, u32)) -> Vec<ParamError> {
    let mut errors = Vec::new();
    let t1 = (p.int("t1_x"), p.int("t1_y"));
    let t2 = (p.int("t2_x"), p.int("t2_y"));
    let given = t1 != (0, 0) || t2 != (0, 0);
    if given && cross(t1, t2) == 0 {
        errors.push(ParamError::new("t1_x", format!("t1 = {t1:?} and t2 = {t2:?} are parallel (or zero): they must span a lattice")));
    }
    if given {
        let g_w = t1.0.abs() + t2.0.abs();
        let g_h = t1.1.abs() + t2.1.abs();
        if g_w > sample.0 as i64 || g_h > sample.1 as i64 {
            errors.push(ParamError::new("t1_x", format!("a texel spanned by t1 = {t1:?}, t2 = {t2:?} does not fit in the {}x{} sample", sample.0, sample.1)));
        }
    }
    if (p.int("rows") == 0) != (p.int("cols") == 0) {
        errors.push(ParamError::new("rows", "give both rows and cols, or neither (0 = cover the output)"));
    }
    errors
}

/// Where the output lattice sits: its size and the output position of cell (0, 0)'s origin.
pub(crate) fn place(g: &Geometry, p: &Params, width: u32, height: u32) -> (usize, usize, (i64, i64)) {
    let (rows, cols) = (p.int("rows"), p.int("cols"));
    if rows == 0 {
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

/// Copies each cell's texel into the output; `None` pixels are outside the lattice.
pub(crate) fn render(
    sample: &RgbImage,
    g: &Geometry,
    texels: &[(i64, i64)],
    assign: &[usize],
    rows: usize,
    cols: usize,
    p0: (i64, i64),
    width: u32,
    height: u32,
    fill_black: bool,
) -> Result<RgbImage, String> {
    let mut out = RgbImage::new(width, height);
    let mut uncovered = 0u64;
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            let rel = (x - p0.0, y - p0.1);
            let (m, n) = g.cell_of(rel);
            if m < 0 || n < 0 || m >= cols as i64 || n >= rows as i64 {
                uncovered += 1;
                continue;
            }
            let o = texels[assign[n as usize * cols + m as usize]];
            let c = g.point(m, n);
            let q = (rel.0 - c.0, rel.1 - c.1);
            out.put(x as u32, y as u32, sample.get((o.0 + q.0) as u32, (o.1 + q.1) as u32));
        }
    }
    if uncovered > 0 && !fill_black {
        return Err(format!(
            "the {rows}x{cols} lattice leaves {uncovered} of the {width}x{height} output pixels uncovered; use more rows/cols, rows = cols = 0, or fill = \"black\""
        ));
    }
    Ok(out)
}

/// Feathers every neighbour pair's overlap strip (B5 general strip), horizontal pairs first.
#[allow(clippy::too_many_arguments)]
pub(crate) fn feather_strips(
    out: &mut RgbImage,
    sample: &RgbImage,
    g: &Geometry,
    texels: &[(i64, i64)],
    assign: &[usize],
    rows: usize,
    cols: usize,
    p0: (i64, i64),
    tables: [(&Table, &Strips); 2],
) {
    for (table, strips) in tables {
        let step = if strips.horizontal { g.t1 } else { g.t2 };
        let n_steps = (strips.rho * strips.l as f64).ceil().max(1.0) as u32;
        for r in 0..rows {
            for c in 0..cols {
                let (rb, cb) = if strips.horizontal { (r, c + 1) } else { (r + 1, c) };
                if rb >= rows || cb >= cols {
                    continue;
                }
                let (a, b) = (assign[r * cols + c], assign[rb * cols + cb]);
                let e = a * table.s + b;
                if table.pen[e] {
                    continue;
                }
                let k = table.shift[e] as usize;
                let sigma = k as f64 / strips.l as f64;
                let origin_b = g.point(cb as i64, rb as i64);
                let (oa, ob) = (texels[a], texels[b]);
                for &q in &strips.by_shift[k].0 {
                    let (x, y) = (p0.0 + origin_b.0 + q.0, p0.1 + origin_b.1 + q.1);
                    if x < 0 || y < 0 || x >= out.width() as i64 || y >= out.height() as i64 {
                        continue;
                    }
                    let va = sample.get((oa.0 + step.0 + q.0) as u32, (oa.1 + step.1 + q.1) as u32);
                    let vb = sample.get((ob.0 + q.0) as u32, (ob.1 + q.1) as u32);
                    let (al, be) = g.coords(q);
                    let along = if strips.horizontal { al } else { be };
                    let tau = ((along - sigma + strips.rho) / strips.rho).clamp(0.0, 1.0 - 1e-12);
                    let kk = ((tau * n_steps as f64).floor() as u32).min(n_steps - 1);
                    out.put(x as u32, y as u32, feather::blend(va, vb, feather::new_weight(kk, n_steps)));
                }
            }
        }
    }
}

/// Termination test of paper 000 eq. 7 (shared with TES): the last `window` averages vary by at
/// most `t_m` relative to their mean level, or the level is 0 (perfect fitness).
pub(crate) fn converged(history: &[f64], window: usize, t_m: f64) -> bool {
    let last = &history[history.len() - window..];
    let spread = last.iter().copied().fold(f64::NEG_INFINITY, f64::max) - last.iter().copied().fold(f64::INFINITY, f64::min);
    let level = (last.iter().sum::<f64>() / window as f64).abs();
    level == 0.0 || t_m - spread / level >= 0.0
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

impl Method for Coevolution {
    fn name(&self) -> &'static str {
        "coevolution"
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
        check_lattice_params(p, sample)
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, String> {
        let p = req.params;
        let sample = req.sample;
        let started = Instant::now();
        let (t1, t2, source) = lattice_vectors(p, sample)?;
        let g = Geometry::new(t1, t2);
        let (w, h) = (sample.width() as i64, sample.height() as i64);
        let texels = texels(&g, w, h);
        let s = texels.len();
        if s < 2 {
            return Err(format!("the lattice t1 = {t1:?}, t2 = {t2:?} fits only {s} complete texel(s) in the sample; at least 2 are needed"));
        }
        let rho = p.float("rho");
        let (sh, sv) = (Strips::new(&g, rho, true), Strips::new(&g, rho, false));
        let (th, tv) = (build_table(sample, &g, &texels, &sh), build_table(sample, &g, &texels, &sv));
        let tables_seconds = started.elapsed().as_secs_f64();
        let iter_started = Instant::now();
        let (rows, cols, p0) = place(&g, p, req.width, req.height);
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
        let iter_max = p.int("iter_max") as usize;
        let m_window = p.int("window") as usize;
        let (c_tol, t_m) = (p.float("c_tol"), p.float("t_m"));
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
                    let u = if pen {
                        omega
                    } else if fi <= f_bar {
                        let f_nor = if f_bar == f_min { 0.0 } else { ((fi - f_min) / (f_bar - f_min)).clamp(0.0, 1.0) };
                        omega / (1.0 + f_nor)
                    } else {
                        0.0
                    };
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
        let mut image = render(sample, &g, &texels, &assign, rows, cols, p0, req.width, req.height, p.str("fill") == "black")?;
        feather_strips(&mut image, sample, &g, &texels, &assign, rows, cols, p0, [(&th, &sh), (&tv, &sv)]);
        let diagnostics = serde_json::json!({
            "lattice": { "t1": [g.t1.0, g.t1.1], "t2": [g.t2.0, g.t2.1], "source": source },
            "texels": s,
            "lattice_size": { "rows": rows, "cols": cols },
            "iterations": iterations,
            "mean_fitness": history,
            "penalised_entries": { "H": th.pen.iter().filter(|&&b| b).count(), "V": tv.pen.iter().filter(|&&b| b).count() },
        });
        Ok(Synthesis {
            image,
            seams: None,
            diagnostics,
            phases: vec![("tables".into(), tables_seconds), ("iterations".into(), iter_seconds)],
            extras: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{ParamValue, resolve};

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
            [v, (v / 2) as u8, 255 - v]
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
                if c > 0 { f += th.f[assign[r * cols + c - 1] * tex.len() + k]; }
                if c + 1 < cols { f += th.f[k * tex.len() + assign[r * cols + c + 1]]; }
                if r > 0 { f += tv.f[assign[(r - 1) * cols + c] * tex.len() + k]; }
                if r + 1 < rows { f += tv.f[k * tex.len() + assign[(r + 1) * cols + c]]; }
                if (r + c) % 2 == 1 { odd += f } else { even += f }
            }
        }
        assert!((odd - even).abs() < 1e-6 * odd.abs().max(1.0), "{odd} vs {even}");
    }

    #[test]
    fn a_periodic_sample_is_reproduced_with_perfect_fitness() {
        let img = periodic();
        let p = params(&[("t1_x", ParamValue::Int(20)), ("t2_x", ParamValue::Int(6)), ("t2_y", ParamValue::Int(16)), ("c_tol", ParamValue::Float(0.0))]);
        let out = Coevolution.synthesize(&Request { sample: &img, width: 90, height: 70, params: &p, seed: 4 }).unwrap();
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
        let req = Request { sample: &img, width: 64, height: 64, params: &p, seed: 9 };
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
        let e = Coevolution.synthesize(&Request { sample: &noise, width: 40, height: 40, params: &params(&[]), seed: 1 }).unwrap_err();
        assert!(e.contains("no lattice found; give t1/t2"), "{e}");
        let small = params(&[("t1_x", ParamValue::Int(20)), ("t2_x", ParamValue::Int(6)), ("t2_y", ParamValue::Int(16)), ("rows", ParamValue::Int(2)), ("cols", ParamValue::Int(2))]);
        let e = Coevolution.synthesize(&Request { sample: &periodic(), width: 200, height: 200, params: &small, seed: 1 }).unwrap_err();
        assert!(e.contains("uncovered"), "{e}");
    }
}
