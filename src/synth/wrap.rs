//! Whether a tileable output of a given size can keep a sample's lattice whole across its wrap.
//!
//! A wrapping output of `W × H` joins its right edge to its left and its bottom to its top: the
//! translations `(W, 0)` and `(0, H)`. The texels of a near-regular sample meet in phase there
//! only when both are (nearly) lattice vectors, `m·t1 + n·t2` with whole `m`, `n`. Otherwise the
//! wrap cuts texels apart however well the method joins pixels (a solar-panel grid at 420×336:
//! the wrap seam 11× as visible as the others), and the honest answer is the nearest sizes that
//! keep it (`texsyn advise --tileable WxH`, and a warning in the job's manifest entry).

use crate::synth::lattice::Lattice;

/// Measured lattice vectors are whole pixels, each up to half a pixel off in each component (a
/// brick course of 37 px reads as 38 and 36 on its two diagonals). A combination `m·t1 + n·t2`
/// whose off-axis component is at most this many pixels is taken as the lattice's period along
/// that axis: the shear is the measurement's rounding, not the sample's.
pub const AXIS_SHEAR_PX: i64 = 2;
/// A wrap that misses a whole number of periods by at most this many pixels keeps the texels.
pub const WRAP_PHASE_PX: u32 = 1;
/// Combinations `m·t1 + n·t2` searched for an axis period: |m|, |n| up to this.
const MAX_COEFFICIENT: i64 = 8;

/// The lattice's periods across and down ([`AXIS_SHEAR_PX`]), `None` on an axis no small
/// combination of the vectors follows (an oblique lattice: no wrap keeps it along that axis).
pub fn axis_periods(l: &Lattice) -> (Option<u32>, Option<u32>) {
    let mut across: Option<u32> = None;
    let mut down: Option<u32> = None;
    for m in -MAX_COEFFICIENT..=MAX_COEFFICIENT {
        for n in -MAX_COEFFICIENT..=MAX_COEFFICIENT {
            let (x, y) = (m * l.t1.0 + n * l.t2.0, m * l.t1.1 + n * l.t2.1);
            if y.abs() <= AXIS_SHEAR_PX && x.abs() >= 4 {
                across = Some(across.map_or(x.unsigned_abs() as u32, |p| p.min(x.unsigned_abs() as u32)));
            }
            if x.abs() <= AXIS_SHEAR_PX && y.abs() >= 4 {
                down = Some(down.map_or(y.unsigned_abs() as u32, |p| p.min(y.unsigned_abs() as u32)));
            }
        }
    }
    (across, down)
}

/// Pixels between `side` and the nearest whole number of `period`s (`side` itself when there is
/// no period: nothing fits).
fn phase(side: u32, period: Option<u32>) -> u32 {
    match period {
        Some(p) => {
            let r = side % p;
            if side < p { p - side } else { r.min(p - r) }
        }
        None => side,
    }
}

/// The whole numbers of periods nearest `side`, below and above (at least one period).
fn nearest_sides(side: u32, period: Option<u32>) -> Vec<u32> {
    let Some(p) = period else { return Vec::new() };
    let below = (side / p).max(1) * p;
    let above = (side / p + 1) * p;
    let mut v = vec![below, above];
    v.sort_by_key(|&s| (s.abs_diff(side), s));
    v.dedup();
    v
}

/// What a tileable `W × H` output does to the lattice across its wrap.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrapFit {
    pub size: (u32, u32),
    /// Both translations are lattice vectors within the tolerance.
    pub continuous: bool,
    /// Pixels between each side and the nearest whole number of lattice periods along it (the
    /// side itself where the lattice has no period along that axis).
    pub phase_across: f64,
    pub phase_down: f64,
    /// The nearest sizes that keep the lattice whole: at or below and at or above on each axis,
    /// combined (smaller first), without repeats.
    pub nearest: Vec<(u32, u32)>,
}

/// [`WrapFit`] of a `size` wrap over the lattice.
pub fn wrap_fit(l: &Lattice, size: (u32, u32)) -> WrapFit {
    let (across, down) = axis_periods(l);
    let (pa, pd) = (phase(size.0, across), phase(size.1, down));
    let continuous = pa <= WRAP_PHASE_PX && pd <= WRAP_PHASE_PX;
    let mut nearest = Vec::new();
    if !continuous {
        let ws = if pa <= WRAP_PHASE_PX { vec![size.0] } else { nearest_sides(size.0, across) };
        let hs = if pd <= WRAP_PHASE_PX { vec![size.1] } else { nearest_sides(size.1, down) };
        let mut all: Vec<(u32, u32)> = ws.iter().flat_map(|&w| hs.iter().map(move |&h| (w, h))).collect();
        all.sort_by_key(|&(w, h)| (w.abs_diff(size.0) + h.abs_diff(size.1), (w, h)));
        nearest = all.into_iter().take(2).collect();
    }
    WrapFit { size, continuous, phase_across: f64::from(pa), phase_down: f64::from(pd), nearest }
}

/// The warning of a tileable job whose size breaks the lattice at its wrap, naming the nearest
/// sizes that keep it.
pub fn warning(l: &Lattice, size: (u32, u32)) -> Option<String> {
    let f = wrap_fit(l, size);
    if f.continuous {
        return None;
    }
    let sizes: Vec<String> = f.nearest.iter().map(|(w, h)| format!("{w}x{h}")).collect();
    Some(format!(
        "a tileable {}x{} output breaks this sample's lattice (t1 = ({}, {}), t2 = ({}, {})) at its wrap: texels meet {:.0} px out of phase across and {:.0} px down, however well the pixels join; {} keep{} whole texels across the wrap.",
        size.0,
        size.1,
        l.t1.0,
        l.t1.1,
        l.t2.0,
        l.t2.1,
        f.phase_across,
        f.phase_down,
        if sizes.is_empty() { "no size near it".to_string() } else { sizes.join(" or ") },
        if sizes.len() == 1 { "s" } else { "" }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(t1: (i64, i64), t2: (i64, i64)) -> Lattice {
        Lattice { t1, t2, peak1: 0.5, peak2: 0.5, candidates: 4, explained: 4, found_in: None }
    }

    #[test]
    fn a_rectangular_lattice_wraps_at_multiples_of_its_periods() {
        let l = lattice((36, 0), (0, 72));
        assert_eq!(axis_periods(&l), (Some(36), Some(72)));
        assert!(wrap_fit(&l, (432, 360)).continuous);
        let f = wrap_fit(&l, (420, 336));
        assert!(!f.continuous);
        assert_eq!((f.phase_across, f.phase_down), (12.0, 24.0));
        assert_eq!(f.nearest, vec![(432, 360), (396, 360)]);
        let w = warning(&l, (420, 336)).unwrap();
        assert!(w.contains("432x360 or 396x360 keep whole texels"), "{w}");
    }

    #[test]
    fn sheared_and_diagonal_lattices_use_their_axis_combinations() {
        // bricks_gray as measured: t1 + t2 = (74, 0) across, t2 − t1 = (−2, 48) down (rounding shear).
        let bricks = lattice((38, -24), (36, 24));
        assert_eq!(axis_periods(&bricks), (Some(74), Some(48)));
        assert!(wrap_fit(&bricks, (74 * 6, 48 * 8)).continuous);
        assert_eq!(wrap_fit(&bricks, (420, 336)).nearest, vec![(444, 336), (370, 336)]);
        // terracotta: t2 = (1, 84) is the vertical period with a pixel of shear.
        let terracotta = lattice((88, 0), (1, 84));
        assert!(warning(&terracotta, (88 * 4, 84 * 4)).is_none());
        assert!(wrap_fit(&terracotta, (88 * 4 + 1, 84 * 4 - 1)).continuous, "a pixel off is in phase");
        // A lattice with no near-axis combination cannot wrap in phase across at any size near.
        let oblique = lattice((40, 13), (7, 31));
        let f = wrap_fit(&oblique, (400, 400));
        assert!(!f.continuous);
    }
}
