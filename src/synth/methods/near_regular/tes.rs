//! TES, the Texture Evolution System of Wu, Zhang & He (2007): the baseline paper 000 improves on,
//! as reconstructed in docs/methods.md §2.11 (marked "TES (reconstructed)" in results).
//!
//! Individuals are axis-aligned blocks (the texel's bounding box) on a rectangular grid. Every
//! iteration each individual settles into the best of its 3×3 neighbouring cells, duels the
//! occupant, and may die when below average; fitness is always computed from pixels (no tables),
//! which is the cost profile the co-evolution paper compares against. Final seams are
//! Efros–Freeman cuts on the rectangular overlaps.

use super::grid::{F_PEN, Fill, GRID_PARAMS, Geometry, LatticeGrid, converged, texels};
use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::params::{self, Default, MethodConfig, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::boundary_cut::{horizontal_cut, vertical_cut};
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::overlap::{bytes_ssd, pixel_error};
use crate::synth::rng::Stream;
use std::time::Instant;

pub struct Tes;

const PARAMS: &[ParamSpec] = &[
    GRID_PARAMS[0],
    GRID_PARAMS[1],
    GRID_PARAMS[2],
    GRID_PARAMS[3],
    GRID_PARAMS[4],
    GRID_PARAMS[5],
    GRID_PARAMS[6],
    ParamSpec {
        name: "t_m",
        kind: ParamKind::Float { min: 0.0, max: 10.0 },
        default: Default::Float(0.02),
        doc: "termination threshold (as coevolution)",
    },
    ParamSpec {
        name: "window",
        kind: ParamKind::Int { min: 1, max: 1000 },
        default: Default::Int(5),
        doc: "averages in the termination window (M)",
    },
    ParamSpec { name: "iter_max", kind: ParamKind::Int { min: 1, max: 100_000 }, default: Default::Int(50), doc: "iteration cap" },
];

/// The parameters of `tes`, typed (job-file names in brackets).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TesConfig {
    /// The lattice and the output grid (`t1_x … t2_y`, `rows`, `cols`, `fill`).
    pub grid: LatticeGrid,
    /// Termination threshold, as co-evolution's (`t_m`).
    pub t_m: f64,
    /// Averages in the termination window (`window`).
    pub window: u32,
    /// Iteration cap (`iter_max`).
    pub iter_max: u32,
}

impl std::default::Default for TesConfig {
    fn default() -> TesConfig {
        TesConfig { grid: LatticeGrid::default(), t_m: 0.02, window: 5, iter_max: 50 }
    }
}

impl MethodConfig for TesConfig {
    const METHOD: &'static str = "tes";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = self.grid.to_params();
        v.extend([params::float("t_m", self.t_m), params::int("window", self.window), params::int("iter_max", self.iter_max)]);
        v
    }

    fn from_params(p: &Params) -> Result<TesConfig, SynthError> {
        Ok(TesConfig { grid: LatticeGrid::from_params(p)?, t_m: p.float("t_m")?, window: p.uint("window")?, iter_max: p.uint("iter_max")? })
    }
}

/// The sample's blocks and the pixel-level overlap fitness between them.
struct Blocks<'a> {
    sample: &'a RgbImage,
    /// The sample transposed (column `x` top to bottom is run `x`): a strip taller than wide is
    /// read as a few long runs of bytes instead of many short rows.
    columns: Vec<u8>,
    /// Top-left corner of each block in the sample.
    origin: Vec<(i64, i64)>,
    bw: i64,
    bh: i64,
    ovw: i64,
    ovh: i64,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    East,
    West,
    North,
    South,
}

impl Blocks<'_> {
    fn new(sample: &RgbImage, origin: Vec<(i64, i64)>, (bw, bh): (i64, i64), (ovw, ovh): (i64, i64)) -> Blocks<'_> {
        let (w, h) = (sample.width() as usize, sample.height() as usize);
        let raw = sample.as_raw();
        let mut columns = vec![0u8; w * h * 3];
        for x in 0..w {
            for y in 0..h {
                columns[(x * h + y) * 3..(x * h + y) * 3 + 3].copy_from_slice(&raw[(y * w + x) * 3..(y * w + x) * 3 + 3]);
            }
        }
        Blocks { sample, columns, origin, bw, bh, ovw, ovh }
    }

    fn inside(&self, x: i64, y: i64, w: i64, h: i64) -> bool {
        x >= 0 && y >= 0 && x + w <= self.sample.width() as i64 && y + h <= self.sample.height() as i64
    }

    /// Minus the mean pixel error of the `w × h` rectangles at `a` and `b` (both inside the
    /// sample); the error sum is an integer, so reading rows or columns gives the same value.
    fn mean_error(&self, a: (i64, i64), b: (i64, i64), w: i64, h: i64) -> f64 {
        let (sw, sh) = (self.sample.width() as usize, self.sample.height() as usize);
        let (a, b, w, h) = ((a.0 as usize, a.1 as usize), (b.0 as usize, b.1 as usize), w as usize, h as usize);
        let sum: u64 = if w >= h {
            let raw = self.sample.as_raw();
            let run = |(x, y): (usize, usize), dy: usize| &raw[((y + dy) * sw + x) * 3..((y + dy) * sw + x + w) * 3];
            (0..h).map(|dy| bytes_ssd(run(a, dy), run(b, dy))).sum()
        } else {
            let run = |(x, y): (usize, usize), dx: usize| &self.columns[((x + dx) * sh + y) * 3..((x + dx) * sh + y + h) * 3];
            (0..w).map(|dx| bytes_ssd(run(a, dx), run(b, dx))).sum()
        };
        -(sum as f64) / (w * h) as f64
    }

    /// Fitness of block `i` towards its neighbour `j` on `side`, from `i`'s point of view: the
    /// sample strip just outside `i`'s border against `j`'s facing strip. When `i`'s extension
    /// leaves the sample, the mirror comparison (`j`'s extension against `i`'s own border strip)
    /// is used; when both leave it, the penalty.
    fn fitness(&self, i: usize, j: usize, side: Side) -> (f64, bool) {
        let (oi, oj) = (self.origin[i], self.origin[j]);
        let (bw, bh, ow, oh) = (self.bw, self.bh, self.ovw, self.ovh);
        let (ext, facing, mirror_ext, mirror_own, w, h) = match side {
            Side::East => ((oi.0 + bw, oi.1), oj, (oj.0 - ow, oj.1), (oi.0 + bw - ow, oi.1), ow, bh),
            Side::West => ((oi.0 - ow, oi.1), (oj.0 + bw - ow, oj.1), (oj.0 + bw, oj.1), oi, ow, bh),
            Side::South => ((oi.0, oi.1 + bh), oj, (oj.0, oj.1 - oh), (oi.0, oi.1 + bh - oh), bw, oh),
            Side::North => ((oi.0, oi.1 - oh), (oj.0, oj.1 + bh - oh), (oj.0, oj.1 + bh), oi, bw, oh),
        };
        if self.inside(ext.0, ext.1, w, h) {
            (self.mean_error(ext, facing, w, h), false)
        } else if self.inside(mirror_ext.0, mirror_ext.1, w, h) {
            (self.mean_error(mirror_ext, mirror_own, w, h), false)
        } else {
            (F_PEN, true)
        }
    }
}

struct Grid {
    rows: usize,
    cols: usize,
    cell: Vec<usize>,
}

impl Grid {
    /// Degree-normalised fitness of block `k` placed at `(r, c)` with the current occupants around.
    fn fitness_at(&self, b: &Blocks, r: usize, c: usize, k: usize) -> (f64, bool) {
        let (mut f, mut pen, mut deg) = (0.0, false, 0u32);
        let mut add = |j: usize, side: Side| {
            let (v, p) = b.fitness(k, j, side);
            f += v;
            pen |= p;
            deg += 1;
        };
        if c + 1 < self.cols {
            add(self.cell[r * self.cols + c + 1], Side::East);
        }
        if c > 0 {
            add(self.cell[r * self.cols + c - 1], Side::West);
        }
        if r + 1 < self.rows {
            add(self.cell[(r + 1) * self.cols + c], Side::South);
        }
        if r > 0 {
            add(self.cell[(r - 1) * self.cols + c], Side::North);
        }
        if deg == 0 { (0.0, false) } else { (f * 4.0 / deg as f64, pen) }
    }

    fn mean(&self, b: &Blocks) -> (f64, f64) {
        let mut sum = 0.0;
        let mut min = f64::INFINITY;
        for r in 0..self.rows {
            for c in 0..self.cols {
                let (f, pen) = self.fitness_at(b, r, c, self.cell[r * self.cols + c]);
                sum += f;
                if !pen {
                    min = min.min(f);
                }
            }
        }
        (sum / (self.rows * self.cols) as f64, min)
    }

    /// Settling: the best of the 3×3 cells around `(r, c)` for the occupant of `(r, c)` (ties:
    /// its own cell, then row-major); then the duel with that cell's occupant.
    fn settle(&mut self, b: &Blocks, r: usize, c: usize) -> (usize, usize) {
        let k = self.cell[r * self.cols + c];
        let own = self.fitness_at(b, r, c, k).0;
        let mut best = (own, r, c);
        for nr in r.saturating_sub(1)..=(r + 1).min(self.rows - 1) {
            for nc in c.saturating_sub(1)..=(c + 1).min(self.cols - 1) {
                if (nr, nc) == (r, c) {
                    continue;
                }
                let f = self.fitness_at(b, nr, nc, k).0;
                if f > best.0 {
                    best = (f, nr, nc);
                }
            }
        }
        let (fi, br, bc) = best;
        if (br, bc) == (r, c) {
            return (r, c);
        }
        let j = self.cell[br * self.cols + bc];
        let fj = self.fitness_at(b, br, bc, j).0;
        if fi > fj {
            self.cell[br * self.cols + bc] = k;
            self.cell[r * self.cols + c] = j;
            (br, bc)
        } else {
            (r, c)
        }
    }
}

impl Method for Tes {
    fn name(&self) -> &'static str {
        TesConfig::METHOD
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn summary(&self) -> &'static str {
        "TES (reconstructed): bounding-box blocks that settle, duel and die; the baseline of paper 000 (docs/methods.md §2.11)"
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }
    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        match TesConfig::from_params(p) {
            Ok(cfg) => cfg.grid.check(sample),
            Err(e) => vec![e.into()],
        }
    }

    fn tileable(&self, _params: &Params, _sample: (u32, u32), _output: (u32, u32)) -> Result<(), String> {
        // The output is the sample's lattice (t1, t2) laid from one corner; it would wrap only
        // when the output size is a whole number of lattice periods, which t1 and t2 (found
        // per sample, generally oblique) almost never allow.
        Err("tes places texels on the sample's lattice, which does not wrap at the output's edges".into())
    }

    fn peak_memory(&self, _params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        // Measured (VmHWM of `texsyn run`, metal_tread_studs 256²): lattice extraction on the
        // sample (about 9 MB for 256²) and about 6.6 B per output pixel (output and its block
        // state); 1024²: 17 MB, 2048²: 37 MB in all (8 MB of it the process).
        crate::synth::method::linear_memory(sample, output, 7.0, 160.0, 2 << 20)
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let cfg = TesConfig::from_params(req.params)?;
        let sample = req.sample;
        let started = Instant::now();
        let (t1, t2, source) = cfg.grid.vectors(sample)?;
        let lattice_seconds = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let g = Geometry::new(t1, t2);
        let tex = texels(&g, sample.width() as i64, sample.height() as i64);
        let s = tex.len();
        if s < 2 {
            return Err(SynthError::Failed(format!(
                "the lattice t1 = {t1:?}, t2 = {t2:?} fits only {s} complete texel(s) in the sample; at least 2 are needed"
            )));
        }
        let (x0, x1, y0, y1) = g.bbox;
        let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
        let blocks = Blocks::new(
            sample,
            tex.iter().map(|&(x, y)| (x + x0, y + y0)).collect(),
            (bw, bh),
            (((bw as f64 / 6.0).round() as i64).max(2).min(bw), ((bh as f64 / 6.0).round() as i64).max(2).min(bh)),
        );
        let (rows, cols) = match (cfg.grid.rows, cfg.grid.cols) {
            (None, _) | (_, None) => ((req.height as u64).div_ceil(bh as u64) as usize, (req.width as u64).div_ceil(bw as u64) as usize),
            (Some(r), Some(c)) => (r as usize, c as usize),
        };
        if ((cols as i64) * bw < req.width as i64 || (rows as i64) * bh < req.height as i64) && cfg.grid.fill != Fill::Black {
            return Err(SynthError::Failed(format!(
                "the {rows}x{cols} grid of {bw}x{bh} blocks does not cover the {}x{} output; use more rows/cols, rows = cols = \"cover\", or fill = \"black\"",
                req.width, req.height
            )));
        }
        let mut init = Stream::new(req.seed, "tes/init");
        let mut grid = Grid { rows, cols, cell: (0..rows * cols).map(|_| init.below_usize(s)).collect() };
        let mut history = vec![grid.mean(&blocks).0];
        let iter_max = cfg.iter_max as usize;
        let m_window = cfg.window as usize;
        let t_m = cfg.t_m;
        let mut iterations = 0;
        for iter in 1..=iter_max {
            iterations = iter;
            let omega = iter_max as f64 / (iter + iter_max) as f64;
            // Eq. 5's average and minimum are those of the previous iteration (as in coevolution).
            let (f_bar, f_min) = (*history.last().expect("f̄"), grid.mean(&blocks).1);
            for r in 0..rows {
                for c in 0..cols {
                    let (nr, nc) = grid.settle(&blocks, r, c);
                    if (nr, nc) != (r, c) {
                        // The evicted occupant, now at (r, c), settles once more.
                        grid.settle(&blocks, r, c);
                    }
                    let k = grid.cell[nr * cols + nc];
                    let (fi, pen) = grid.fitness_at(&blocks, nr, nc, k);
                    if pen || fi < f_bar {
                        let u = if pen {
                            omega
                        } else {
                            let f_nor = if f_bar == f_min { 0.0 } else { ((fi - f_min) / (f_bar - f_min)).clamp(0.0, 1.0) };
                            omega / (1.0 + f_nor)
                        };
                        let mut st = Stream::new(req.seed, &format!("tes/iter={iter}/r={nr}/c={nc}"));
                        if st.uniform_f64() < u {
                            grid.cell[nr * cols + nc] = st.below_usize(s);
                        }
                    }
                }
            }
            history.push(grid.mean(&blocks).0);
            if iter > m_window && converged(&history, m_window, t_m) {
                break;
            }
        }
        let iter_seconds = started.elapsed().as_secs_f64();
        let (image, placement) = render(&blocks, &grid, req.width, req.height, req.placement).finish();
        let diagnostics = serde_json::json!({
            "lattice": { "t1": [g.t1.0, g.t1.1], "t2": [g.t2.0, g.t2.1], "source": source },
            "block": { "width": bw, "height": bh },
            "texels": s,
            "lattice_size": { "rows": rows, "cols": cols },
            "iterations": iterations,
            "mean_fitness": history,
        });
        Ok(Synthesis {
            image,
            seams: None,
            diagnostics,
            phases: vec![("lattice".into(), lattice_seconds), ("iterations".into(), iter_seconds)],
            extras: Vec::new(),
            placement,
        })
    }
}

/// Blocks on the grid, with minimum-error cuts (B3) where a block's extension overlaps its east
/// and south neighbours (extensions outside the sample leave a hard edge).
fn render(b: &Blocks, grid: &Grid, width: u32, height: u32, record: bool) -> Canvas {
    let (cw, ch) = (grid.cols as i64 * b.bw, grid.rows as i64 * b.bh);
    // At least the output's size: pixels beyond the blocks stay black (uncovered).
    let mut canvas = Canvas::new((cw as u32).max(width), (ch as u32).max(height), b.sample.dimensions(), record);
    let px = |o: (i64, i64), dx: i64, dy: i64| b.sample.get((o.0 + dx) as u32, (o.1 + dy) as u32);
    let at = |o: (i64, i64), dx: i64, dy: i64| ((o.0 + dx) as u32, (o.1 + dy) as u32);
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            let o = b.origin[grid.cell[r * grid.cols + c]];
            for dy in 0..b.bh {
                for dx in 0..b.bw {
                    let (sx, sy) = at(o, dx, dy);
                    canvas.copy((c as i64 * b.bw + dx) as u32, (r as i64 * b.bh + dy) as u32, b.sample, sx, sy);
                }
            }
        }
    }
    // Horizontal pairs: the west block's extension over the east block's first columns.
    for r in 0..grid.rows {
        for c in 0..grid.cols.saturating_sub(1) {
            let (oa, ob) = (b.origin[grid.cell[r * grid.cols + c]], b.origin[grid.cell[r * grid.cols + c + 1]]);
            let ext = (oa.0 + b.bw, oa.1);
            if !b.inside(ext.0, ext.1, b.ovw, b.bh) {
                continue;
            }
            let e: Vec<u32> =
                (0..b.bh).flat_map(|y| (0..b.ovw).map(move |x| (x, y))).map(|(x, y)| pixel_error(px(ext, x, y), px(ob, x, y))).collect();
            let cut = vertical_cut(&e, b.bh as usize, b.ovw as usize);
            for y in 0..b.bh {
                for x in 0..cut[y as usize] as i64 {
                    let (sx, sy) = at(ext, x, y);
                    canvas.copy(((c as i64 + 1) * b.bw + x) as u32, (r as i64 * b.bh + y) as u32, b.sample, sx, sy);
                }
            }
        }
    }
    // Vertical pairs after: the north block's extension over the south block's first rows.
    for r in 0..grid.rows.saturating_sub(1) {
        for c in 0..grid.cols {
            let (oa, ob) = (b.origin[grid.cell[r * grid.cols + c]], b.origin[grid.cell[(r + 1) * grid.cols + c]]);
            let ext = (oa.0, oa.1 + b.bh);
            if !b.inside(ext.0, ext.1, b.bw, b.ovh) {
                continue;
            }
            let e: Vec<u32> =
                (0..b.ovh).flat_map(|y| (0..b.bw).map(move |x| (x, y))).map(|(x, y)| pixel_error(px(ext, x, y), px(ob, x, y))).collect();
            let cut = horizontal_cut(&e, b.ovh as usize, b.bw as usize);
            for x in 0..b.bw {
                for y in 0..cut[x as usize] as i64 {
                    let (sx, sy) = at(ext, x, y);
                    canvas.copy((c as i64 * b.bw + x) as u32, ((r as i64 + 1) * b.bh + y) as u32, b.sample, sx, sy);
                }
            }
        }
    }
    canvas.into_top_left(width, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::params::{ParamValue, resolve};

    fn sample() -> RgbImage {
        RgbImage::from_fn(120, 96, |x, y| {
            let blob = (x % 20) as i32 - 10;
            let v = if blob * blob + ((y % 16) as i32 - 8).pow(2) < 30 { 200 } else { 40 + (x * 3 % 11) as u8 };
            [v, v / 2, 255 - v]
        })
    }

    #[test]
    fn runs_deterministically_with_the_requested_size() {
        let s = sample();
        let g: Vec<(String, ParamValue)> = vec![("t1_x".into(), ParamValue::Int(20)), ("t2_y".into(), ParamValue::Int(16))];
        let p = resolve(PARAMS, &g).unwrap();
        let req = Request {
            sample: &s,
            width: 100,
            height: 70,
            params: &p,
            seed: 3,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        };
        let a = Tes.synthesize(&req).unwrap();
        assert_eq!(a.image.dimensions(), (100, 70));
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(a.image, one.install(|| Tes.synthesize(&req).unwrap()).image);
        assert_eq!(a.diagnostics["block"]["width"], 20);
        let hist = a.diagnostics["mean_fitness"].as_array().unwrap();
        assert_eq!(hist.len(), a.diagnostics["iterations"].as_u64().unwrap() as usize + 1);
        // Blocks and cuts only ever copy sample pixels.
        let colours: std::collections::HashSet<[u8; 3]> = s.as_raw().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        assert!(a.image.as_raw().chunks_exact(3).all(|p| colours.contains(&[p[0], p[1], p[2]])));
    }

    #[test]
    fn natural_neighbours_fit_perfectly() {
        let s = sample();
        let blocks = Blocks::new(&s, vec![(0, 0), (20, 0), (0, 16)], (20, 16), (3, 3));
        assert_eq!(blocks.fitness(0, 1, Side::East), (0.0, false));
        assert_eq!(blocks.fitness(0, 2, Side::South), (0.0, false));
        assert!(blocks.fitness(1, 0, Side::East).0 < 0.0);
    }
}
