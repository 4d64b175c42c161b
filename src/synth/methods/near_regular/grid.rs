//! The texel lattice both near-regular methods work on: its geometry (exact integer cell
//! membership, B11), the sample's complete texels `E_I`, the lattice and grid parameters they
//! share (given vectors or extraction, output rows and columns, what fills uncovered pixels), and
//! the termination test of paper 000 eq. 7. Co-evolution and TES both import from here and not
//! from each other.

use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::lattice::{GivenVectors, LatticeOptions, VECTOR_PARAMS, extract};
use crate::synth::params::{self, Choice, Default, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use rayon::prelude::*;

/// The worst possible mean error, recorded (and flagged) when no overlap fits in the sample.
pub const F_PEN: f64 = -195075.0;

crate::choice! {
    /// What output pixels the lattice does not cover become.
    pub enum Fill { Error = "error", Black = "black" }
}

/// The lattice and grid parameters of both methods (t1_x … t2_y, rows, cols, fill), declared once.
pub(crate) const GRID_PARAMS: [ParamSpec; 7] = [
    VECTOR_PARAMS[0],
    VECTOR_PARAMS[1],
    VECTOR_PARAMS[2],
    VECTOR_PARAMS[3],
    ParamSpec {
        name: "rows",
        kind: ParamKind::IntOr { min: 1, max: 4096, word: "cover" },
        default: Default::Str("cover"),
        doc: "output lattice rows (along t2), or \"cover\": enough to cover the output",
    },
    ParamSpec {
        name: "cols",
        kind: ParamKind::IntOr { min: 1, max: 4096, word: "cover" },
        default: Default::Str("cover"),
        doc: "output lattice columns (along t1), or \"cover\": enough to cover the output",
    },
    ParamSpec {
        name: "fill",
        kind: ParamKind::Choice(Fill::NAMES),
        default: Default::Str("error"),
        doc: "output pixels the lattice does not cover: an error, or black",
    },
];

/// The typed form of [`GRID_PARAMS`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeGrid {
    /// `t1_x … t2_y`: the lattice, or `None` to extract it from the sample.
    pub lattice: Option<GivenVectors>,
    /// `rows`: output lattice rows (along t2); `None` = "cover". Given with `cols` or not at all.
    pub rows: Option<u32>,
    /// `cols`: output lattice columns (along t1); `None` = "cover". Given with `rows` or not at all.
    pub cols: Option<u32>,
    /// `fill`: what uncovered output pixels become.
    pub fill: Fill,
}

impl std::default::Default for LatticeGrid {
    fn default() -> LatticeGrid {
        LatticeGrid { lattice: None, rows: None, cols: None, fill: Fill::Error }
    }
}

impl LatticeGrid {
    pub fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = GivenVectors::to_params(self.lattice);
        v.push(params::int_or("rows", self.rows.map(i64::from), "cover"));
        v.push(params::int_or("cols", self.cols.map(i64::from), "cover"));
        v.push(params::word("fill", self.fill));
        v
    }

    pub fn from_params(p: &Params) -> Result<LatticeGrid, SynthError> {
        let count = |name: &str| -> Result<Option<u32>, SynthError> {
            p.int_or_word(name)?.map(|n| u32::try_from(n).map_err(|_| SynthError::param(name, format!("{n} is not a count")))).transpose()
        };
        Ok(LatticeGrid { lattice: GivenVectors::from_params(p)?, rows: count("rows")?, cols: count("cols")?, fill: p.choice("fill")? })
    }

    /// The given lattice, or the one extracted from the sample, and which it was.
    pub fn vectors(&self, sample: &RgbImage) -> Result<((i64, i64), (i64, i64), &'static str), SynthError> {
        match self.lattice {
            Some(v) => Ok((v.t1, v.t2, "given")),
            None => {
                let l = extract(sample, &LatticeOptions::default())?;
                Ok((l.t1, l.t2, "extracted"))
            }
        }
    }

    /// The checks needing several values or the sample size.
    pub fn check(&self, sample: (u32, u32)) -> Vec<ParamError> {
        let mut errors = Vec::new();
        if let Some(GivenVectors { t1, t2 }) = self.lattice {
            if cross(t1, t2) == 0 {
                errors
                    .push(ParamError::new("t1_x", format!("t1 = {t1:?} and t2 = {t2:?} are parallel (or zero): they must span a lattice")));
            }
            let g_w = t1.0.abs() + t2.0.abs();
            let g_h = t1.1.abs() + t2.1.abs();
            if g_w > sample.0 as i64 || g_h > sample.1 as i64 {
                errors.push(ParamError::new(
                    "t1_x",
                    format!("a texel spanned by t1 = {t1:?}, t2 = {t2:?} does not fit in the {}x{} sample", sample.0, sample.1),
                ));
            }
        }
        if self.rows.is_none() != self.cols.is_none() {
            errors.push(ParamError::new("rows", "give both rows and cols as numbers, or neither (\"cover\": as many as cover the output)"));
        }
        errors
    }
}

pub(crate) fn cross(a: (i64, i64), b: (i64, i64)) -> i64 {
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

pub(crate) fn bbox_of(pts: &[(i64, i64)]) -> (i64, i64, i64, i64) {
    let mut b = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    for &(x, y) in pts {
        b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
    }
    b
}

/// Whether every pixel of `offsets` (given by their bbox) shifted by `o` lies in a `w × h` image.
pub(crate) fn fits(bbox: (i64, i64, i64, i64), o: (i64, i64), w: i64, h: i64) -> bool {
    o.0 + bbox.0 >= 0 && o.0 + bbox.1 < w && o.1 + bbox.2 >= 0 && o.1 + bbox.3 < h
}

/// The sample's texels `E_I` (§2.3): origins of the complete texels for the best lattice origin.
pub(crate) fn texels(g: &Geometry, w: i64, h: i64) -> Vec<(i64, i64)> {
    texels_within(g, g.bbox, w, h)
}

/// `E_I` for texels whose pixels span `bbox` (relative to their origin).
pub(crate) fn texels_within(g: &Geometry, bbox: (i64, i64, i64, i64), w: i64, h: i64) -> Vec<(i64, i64)> {
    let span = (w + h) / (g.t1.0.abs().max(g.t1.1.abs()).min(g.t2.0.abs().max(g.t2.1.abs())).max(1)) + 3;
    let list = |o: (i64, i64)| -> Vec<(i64, i64)> {
        let mut v = Vec::new();
        for n in -span..=span {
            for m in -span..=span {
                let p = g.point(m, n);
                let ok = (o.0 + p.0, o.1 + p.1);
                if fits(bbox, ok, w, h) {
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

/// Termination test of paper 000 eq. 7 (shared with TES): the last `window` averages vary by at
/// most `t_m` relative to their mean level, or the level is 0 (perfect fitness).
pub(crate) fn converged(history: &[f64], window: usize, t_m: f64) -> bool {
    let last = &history[history.len() - window..];
    let spread = last.iter().copied().fold(f64::NEG_INFINITY, f64::max) - last.iter().copied().fold(f64::INFINITY, f64::min);
    let level = (last.iter().sum::<f64>() / window as f64).abs();
    level == 0.0 || t_m - spread / level >= 0.0
}

#[cfg(test)]
mod tests {
    use super::super::coevolution::{CoevolutionConfig, Mask};
    use super::super::tes::TesConfig;
    use super::*;
    use crate::synth::method::Method;
    use crate::synth::params::{MethodConfig, resolve};

    fn specs(name: &str) -> &'static [ParamSpec] {
        crate::synth::methods::find(name).unwrap().params()
    }

    #[test]
    fn default_configs_are_the_tables_defaults() {
        for (name, given) in [("coevolution", CoevolutionConfig::default().to_params()), ("tes", TesConfig::default().to_params())] {
            assert_eq!(resolve(specs(name), &given).unwrap(), resolve(specs(name), &[]).unwrap(), "{name}");
        }
        assert_eq!(CoevolutionConfig::from_params(&resolve(specs("coevolution"), &[]).unwrap()).unwrap(), CoevolutionConfig::default());
        assert_eq!(TesConfig::from_params(&resolve(specs("tes"), &[]).unwrap()).unwrap(), TesConfig::default());
    }

    #[test]
    fn non_default_configs_round_trip_through_the_tables() {
        let grid =
            LatticeGrid { lattice: Some(GivenVectors { t1: (20, 0), t2: (6, 16) }), rows: Some(3), cols: Some(4), fill: Fill::Black };
        let c = CoevolutionConfig { grid, rho: 0.25, c_tol: 0.0, t_m: 0.5, window: 3, iter_max: 7, mask: Mask::Bresenham, r_mut: 2 };
        let d = CoevolutionConfig::default();
        assert!(c.grid != d.grid && c.rho != d.rho && c.c_tol != d.c_tol && c.t_m != d.t_m && c.window != d.window);
        assert!(c.iter_max != d.iter_max && c.mask != d.mask && c.r_mut != d.r_mut);
        let back = CoevolutionConfig::from_params(&resolve(specs("coevolution"), &c.to_params()).unwrap()).unwrap();
        assert_eq!(back, c);
        let t = TesConfig { grid, t_m: 0.1, window: 2, iter_max: 9 };
        assert_eq!(TesConfig::from_params(&resolve(specs("tes"), &t.to_params()).unwrap()).unwrap(), t);
    }

    #[test]
    fn a_bad_word_or_half_a_grid_is_a_problem_naming_its_key() {
        let mut p = resolve(specs("coevolution"), &[]).unwrap();
        p.0.insert("mask".into(), ParamValue::Str("zigzag".into()));
        let e = CoevolutionConfig::from_params(&p).unwrap_err();
        assert!(matches!(&e, SynthError::Param { key, .. } if key == "mask"), "{e}");
        let errors = crate::synth::methods::near_regular::coevolution::Coevolution.check(&p, (64, 64), (64, 64));
        assert_eq!(errors[0].key, "mask");
        let half = LatticeGrid { rows: Some(2), ..LatticeGrid::default() };
        assert_eq!(half.check((64, 64))[0].key, "rows");
    }
}
