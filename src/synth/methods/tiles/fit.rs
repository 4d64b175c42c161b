//! Tileable tile fills at sizes that are not a whole number of tiles.
//!
//! A tiling wraps on a torus of whole tiles (`period`); an output of another size shows that torus
//! with a few columns (rows) left out, or a few shown twice, spread evenly over the period and put
//! where a tile copies one continuous patch of the sample (a Wang tile's last column, on the
//! diamond it shares with its neighbour; the middle of an RW sub-block, away from its seams). A
//! left-out column is a one-pixel step inside that patch, a repeated one a one-pixel stretch:
//! nothing like a seam, and the output still wraps, because the torus does, and every tile still
//! meets its neighbours on their shared edge colours. Sizes that are whole tiles are untouched.
//!
//! It imports nothing from the tile family: [`super::align`] sizes `tile = "auto"` by it and
//! [`super::common`] renders through it.

use crate::image::seam_grid::{SeamBand, SeamGrid};

/// How many columns (rows) out of a hundred `tile = "auto"` lets a fit leave out or repeat when
/// no size divides the output: 3 %, one every 33 pixels or more.
pub const AUTO_FIT_TOLERANCE: f64 = 0.03;

/// The torus of whole `unit`-pixel tiles a `len`-pixel axis is shown from: the nearer of the
/// whole numbers of tiles below and above it (ties to the larger, leaving columns out rather
/// than repeating them), never fewer than one tile.
pub fn period(len: u32, unit: u32) -> u32 {
    let below = (len / unit).max(1) * unit;
    let above = len.div_ceil(unit).max(1) * unit;
    if len - below.min(len) < above - len { below } else { above }
}

/// The share of a `len`-pixel axis's columns a fit to `unit`-pixel tiles changes (0 when the
/// tiles divide it).
pub fn cost(len: u32, unit: u32) -> f64 {
    let p = period(len, unit);
    f64::from(p.abs_diff(len)) / f64::from(p)
}

/// The larger of both axes' [`cost`].
pub fn cost2((w, h): (u32, u32), unit: u32) -> f64 {
    cost(w, unit).max(cost(h, unit))
}

/// Whether a tileable `len`-pixel axis can be shown from a torus of `unit`-pixel tiles: a whole
/// number of them, or at least two (then less than half of any tile's columns change).
pub fn fits(len: u32, unit: u32) -> bool {
    len.is_multiple_of(unit) || len >= 2 * unit
}

/// Where columns (rows) may be left out or repeated: every `step` pixels of the torus, at
/// `phase` within the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slots {
    pub step: u32,
    pub phase: u32,
}

/// An output of `size` shown from the torus `period` of whole tiles: per output column (row),
/// the torus column (row) it shows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fit {
    pub period: (u32, u32),
    pub xs: Vec<u32>,
    pub ys: Vec<u32>,
}

/// One axis: the torus coordinates of a `len`-pixel axis shown from `p` pixels, changing
/// `|p − len|` of them at evenly spread slots (or, when there are more changes than slots, at
/// evenly spread columns).
fn axis(len: u32, p: u32, slots: Slots) -> Vec<u32> {
    let d = p.abs_diff(len) as u64;
    let mut changed = vec![false; p as usize];
    if d > 0 {
        let n = u64::from(p / slots.step);
        for j in 0..d {
            let at = if d <= n {
                let s = (2 * j + 1) * n / (2 * d);
                s * u64::from(slots.step) + u64::from(slots.phase)
            } else {
                (2 * j + 1) * u64::from(p) / (2 * d)
            };
            changed[at as usize] = true;
        }
    }
    let mut out = Vec::with_capacity(len as usize);
    for v in 0..p {
        let c = changed[v as usize];
        if p > len && c {
            continue;
        }
        out.push(v);
        if p < len && c {
            out.push(v);
        }
    }
    debug_assert_eq!(out.len(), len as usize);
    out
}

impl Fit {
    /// The fit of a tileable `size` to `unit`-pixel tiles, or `None` when the tiles divide it
    /// (the torus is then the output itself, as it always was). `size` must [`fits`].
    pub fn new(size: (u32, u32), unit: u32, slots: Slots) -> Option<Fit> {
        if size.0.is_multiple_of(unit) && size.1.is_multiple_of(unit) {
            return None;
        }
        let period = (period(size.0, unit), period(size.1, unit));
        Some(Fit { period, xs: axis(size.0, period.0, slots), ys: axis(size.1, period.1, slots) })
    }

    /// The output size.
    pub fn size(&self) -> (u32, u32) {
        (self.xs.len() as u32, self.ys.len() as u32)
    }

    /// Seam bands of the torus moved to the output's columns (rows): a band covers the output
    /// pixels that show its torus pixels.
    pub fn seams(&self, torus: &SeamGrid) -> SeamGrid {
        let map = |bands: &[SeamBand], to: &[u32]| -> Vec<SeamBand> {
            bands
                .iter()
                .filter_map(|b| {
                    let start = to.partition_point(|&v| v < b.start);
                    let end = to.partition_point(|&v| v < b.start + b.len);
                    (end > start).then_some(SeamBand { start: start as u32, len: (end - start) as u32 })
                })
                .collect()
        };
        SeamGrid { columns: map(&torus.columns, &self.xs), rows: map(&torus.rows, &self.ys) }
    }

    /// The manifest's record of the fit (`diagnostics.tileable_fit`): the torus, and per axis the
    /// torus columns (rows) left out or shown twice.
    pub fn describe(&self, unit: u32) -> serde_json::Value {
        let axis = |to: &[u32], p: u32| {
            let len = to.len() as u32;
            let changed: Vec<u32> = if p > len {
                let mut shown = vec![false; p as usize];
                to.iter().for_each(|&v| shown[v as usize] = true);
                (0..p).filter(|&v| !shown[v as usize]).collect()
            } else {
                to.windows(2).filter(|w| w[0] == w[1]).map(|w| w[0]).collect()
            };
            let what = if p > len { "left_out" } else { "repeated" };
            serde_json::json!({ "tiles": p / unit, "torus": p, what: changed })
        };
        serde_json::json!({
            "how": "the tiling wraps on a torus of whole tiles; the output shows it with these columns and rows left out or repeated (one pixel each, inside a tile, spread evenly)",
            "x": axis(&self.xs, self.period.0),
            "y": axis(&self.ys, self.period.1),
        })
    }
}

/// Renders output rows `y0..` (whole rows of the fitted output, `ch` values per pixel) from a
/// renderer of the torus's rows (`render(v0, rows)` fills torus rows `v0..` of `period.0` pixels).
pub fn render_rows<T: Copy + Default + Send + Sync>(fit: &Fit, y0: u32, rows: &mut [T], ch: usize, render: impl Fn(u32, &mut [T])) {
    use rayon::prelude::*;
    let w = fit.xs.len() * ch;
    let n = rows.len() / w.max(1);
    if n == 0 {
        return;
    }
    let ys = &fit.ys[y0 as usize..y0 as usize + n];
    let (v0, v1) = (ys[0], ys[n - 1]);
    let pw = fit.period.0 as usize * ch;
    let mut torus = vec![T::default(); (v1 - v0 + 1) as usize * pw];
    render(v0, &mut torus);
    rows.par_chunks_mut(w).zip(ys.par_iter()).for_each(|(row, &vy)| {
        let src = &torus[(vy - v0) as usize * pw..][..pw];
        for (x, &vx) in fit.xs.iter().enumerate() {
            let s = vx as usize * ch;
            row[x * ch..x * ch + ch].copy_from_slice(&src[s..s + ch]);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_tiles_are_not_fitted_and_other_sizes_change_few_columns_at_the_slots() {
        let slots = Slots { step: 64, phase: 63 };
        assert_eq!(Fit::new((512, 320), 64, slots), None);
        let f = Fit::new((1001, 601), 64, slots).unwrap();
        assert_eq!(f.period, (1024, 576));
        assert_eq!(f.size(), (1001, 601));
        // 23 columns left out of 16 tiles: spread over the columns, one pixel at a time.
        let left: Vec<u32> = (0..1024).filter(|v| !f.xs.contains(v)).collect();
        assert_eq!(left.len(), 23);
        assert!(f.xs.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] <= 2), "one pixel at a time");
        // 25 rows repeated over 9 tiles: more than one a tile, spread over the rows.
        assert!(f.ys.windows(2).all(|w| w[1] >= w[0] && w[1] - w[0] <= 1));
        assert_eq!(f.ys.windows(2).filter(|w| w[0] == w[1]).count(), 25);
        assert_eq!(f.describe(64)["y"]["repeated"].as_array().unwrap().len(), 25);
        assert_eq!(f.describe(64)["x"]["tiles"], 16);
        // Four columns out of 16 tiles: each a tile's last one, spread evenly.
        let few = Fit::new((1020, 1024), 64, slots).unwrap();
        let left: Vec<u32> = (0..1024).filter(|v| !few.xs.contains(v)).collect();
        assert_eq!(left, vec![191, 447, 703, 959]);
        assert_eq!(few.ys, (0..1024).collect::<Vec<u32>>());
        let one = Fit::new((1000, 600), 66, slots).unwrap();
        assert_eq!(one.period, (990, 594));
        assert!(fits(128, 64) && fits(64, 64) && fits(129, 64) && !fits(127, 64) && !fits(100, 64));
        assert_eq!(cost(1000, 50), 0.0);
        assert!((cost(1001, 64) - 23.0 / 1024.0).abs() < 1e-12);
    }

    #[test]
    fn seams_follow_the_columns_shown() {
        let f = Fit { period: (8, 4), xs: vec![0, 1, 2, 4, 5, 6, 7], ys: vec![0, 1, 1, 2, 3] };
        let torus = SeamGrid {
            columns: vec![SeamBand { start: 3, len: 1 }, SeamBand { start: 4, len: 2 }],
            rows: vec![SeamBand { start: 1, len: 2 }],
        };
        let s = f.seams(&torus);
        assert_eq!(s.columns, vec![SeamBand { start: 3, len: 2 }]);
        assert_eq!(s.rows, vec![SeamBand { start: 1, len: 3 }]);
        let mut out = vec![0u32; 7 * 5];
        render_rows(&f, 0, &mut out, 1, |v0, rows: &mut [u32]| {
            for (i, px) in rows.iter_mut().enumerate() {
                *px = (v0 + (i / 8) as u32) * 100 + (i % 8) as u32;
            }
        });
        assert_eq!(&out[7 * 2..7 * 3], &[100, 101, 102, 104, 105, 106, 107]);
        assert_eq!(&out[7 * 4..7 * 5], &[300, 301, 302, 304, 305, 306, 307]);
    }
}
