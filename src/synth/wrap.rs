//! Whether a tileable output of a given size can keep a sample's lattice whole across its wrap.
//!
//! A wrapping output of `W × H` joins its right edge to its left and its bottom to its top: the
//! translations `(W, 0)` and `(0, H)`. The texels of a near-regular sample meet in phase there
//! only when both are (nearly) lattice vectors, `m·t1 + n·t2` with whole `m`, `n`. Otherwise the
//! wrap cuts texels apart however well the method joins pixels (a solar-panel grid at 420×336:
//! the wrap seam 11× as visible as the others), and the honest answer is the nearest sizes that
//! keep it (`texsyn advise --tileable WxH`, and a warning in the job's manifest entry).

use crate::synth::lattice::Lattice;

/// A combination `m·t1 + n·t2` whose off-axis component is at most this many pixels is taken
/// as the lattice's period along that axis. Whole-pixel vectors are up to half a pixel off in
/// each component (a brick course of 37 px reads as 38 and 36 on its two diagonals), so this
/// was their rounding; on the sub-pixel vectors ([`crate::synth::lattice::FineVectors`]) what
/// is left is the sample's own slant (a photograph a little off square), ignored here as before.
pub const AXIS_SHEAR_PX: f64 = 2.0;
/// A wrap within this many pixels of a whole number of periods keeps the texels. Half a pixel:
/// output sizes are whole pixels, so it is the smallest tolerance under which every whole number
/// of periods has a size that keeps it (`n` periods are always within half a pixel of a whole
/// size), and whole-pixel block positions already put texels up to half a pixel off their place
/// inside the output. The period is known to a few hundredths of a pixel (metal_tread_studs:
/// 26.7 px, fitted to 30-odd autocorrelation peaks), so twenty periods on the error stays under
/// this.
pub const WRAP_PHASE_PX: f64 = 0.5;
/// Combinations `m·t1 + n·t2` searched for an axis period: |m|, |n| up to this.
const MAX_COEFFICIENT: i64 = 8;

/// The lattice's periods across and down, to a fraction of a pixel ([`AXIS_SHEAR_PX`]), `None`
/// on an axis no small combination of the vectors follows (an oblique lattice: no wrap keeps it
/// along that axis).
pub fn axis_periods(l: &Lattice) -> (Option<f64>, Option<f64>) {
    let (t1, t2) = (l.fine.t1, l.fine.t2);
    let mut across: Option<f64> = None;
    let mut down: Option<f64> = None;
    let shorter = |p: Option<f64>, v: f64| Some(p.map_or(v, |p: f64| p.min(v)));
    for m in -MAX_COEFFICIENT..=MAX_COEFFICIENT {
        for n in -MAX_COEFFICIENT..=MAX_COEFFICIENT {
            let (mf, nf) = (m as f64, n as f64);
            let (x, y) = (mf * t1.0 + nf * t2.0, mf * t1.1 + nf * t2.1);
            if y.abs() <= AXIS_SHEAR_PX && x.abs() >= 4.0 {
                across = shorter(across, x.abs());
            }
            if x.abs() <= AXIS_SHEAR_PX && y.abs() >= 4.0 {
                down = shorter(down, y.abs());
            }
        }
    }
    (across, down)
}

/// Pixels between `side` and the nearest whole number (at least one) of `period`s (`side`
/// itself when there is no period: nothing fits).
fn phase(side: u32, period: Option<f64>) -> f64 {
    let side = f64::from(side);
    match period {
        Some(p) if side < p => p - side,
        Some(p) => {
            let r = side - (side / p).floor() * p;
            r.min(p - r)
        }
        None => side,
    }
}

/// The whole-pixel sizes nearest `side` that are within [`WRAP_PHASE_PX`] of a whole number of
/// periods, below and above (at least one period).
fn nearest_sides(side: u32, period: Option<f64>) -> Vec<u32> {
    let Some(p) = period else { return Vec::new() };
    let k = (f64::from(side) / p).floor();
    let below = (k.max(1.0) * p).round() as u32;
    let above = ((k + 1.0) * p).round() as u32;
    let mut v = vec![below, above];
    v.sort_by_key(|&s| (s.abs_diff(side), s));
    v.dedup();
    v
}

/// What a tileable `W × H` output does to the lattice across its wrap.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrapFit {
    pub size: (u32, u32),
    /// Both sides are within [`WRAP_PHASE_PX`] of a whole number of periods.
    pub continuous: bool,
    /// The lattice's periods across and down ([`axis_periods`], to 0.01 px), absent on an axis
    /// it has none.
    pub period_across: Option<f64>,
    pub period_down: Option<f64>,
    /// Pixels between each side and the nearest whole number of lattice periods along it (the
    /// side itself where the lattice has no period along that axis), to 0.01 px.
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
    let hundredths = |v: f64| (v * 100.0).round() / 100.0;
    WrapFit {
        size,
        continuous,
        period_across: across.map(hundredths),
        period_down: down.map(hundredths),
        phase_across: hundredths(pa),
        phase_down: hundredths(pd),
        nearest,
    }
}

/// The warning of a tileable job whose size breaks the lattice at its wrap, naming the nearest
/// sizes that keep it.
pub fn warning(l: &Lattice, size: (u32, u32)) -> Option<String> {
    let f = wrap_fit(l, size);
    if f.continuous {
        return None;
    }
    let sizes: Vec<String> = f.nearest.iter().map(|(w, h)| format!("{w}x{h}")).collect();
    let period = |p: Option<f64>| p.map_or("none".to_string(), |p| format!("{p:.2} px"));
    Some(format!(
        "a tileable {}x{} output breaks this sample's lattice (t1 = ({}, {}), t2 = ({}, {}); period across {}, down {}) at its wrap: texels meet {:.2} px out of phase across and {:.2} px down, however well the pixels join; {} keep{} whole texels across the wrap.",
        size.0,
        size.1,
        l.t1.0,
        l.t1.1,
        l.t2.0,
        l.t2.1,
        period(f.period_across),
        period(f.period_down),
        f.phase_across,
        f.phase_down,
        if sizes.is_empty() { "no size near it".to_string() } else { sizes.join(" or ") },
        if sizes.len() == 1 { "s" } else { "" }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::lattice::FineVectors;

    fn lattice(t1: (i64, i64), t2: (i64, i64)) -> Lattice {
        Lattice { t1, t2, peak1: 0.5, peak2: 0.5, candidates: 4, explained: 4, found_in: None, fine: FineVectors::exact(t1, t2) }
    }

    fn fine(t1: (f64, f64), t2: (f64, f64)) -> Lattice {
        let r = |v: (f64, f64)| (v.0.round() as i64, v.1.round() as i64);
        Lattice { fine: FineVectors { t1, t2, peaks: 20 }, ..lattice(r(t1), r(t2)) }
    }

    #[test]
    fn a_rectangular_lattice_wraps_at_multiples_of_its_periods() {
        let l = lattice((36, 0), (0, 72));
        assert_eq!(axis_periods(&l), (Some(36.0), Some(72.0)));
        assert!(wrap_fit(&l, (432, 360)).continuous);
        let f = wrap_fit(&l, (420, 336));
        assert!(!f.continuous);
        assert_eq!((f.phase_across, f.phase_down), (12.0, 24.0));
        assert_eq!(f.nearest, vec![(432, 360), (396, 360)]);
        let w = warning(&l, (420, 336)).unwrap();
        assert!(w.contains("432x360 or 396x360 keep whole texels"), "{w}");
        assert!(w.contains("period across 36.00 px, down 72.00 px"), "{w}");
    }

    #[test]
    fn a_period_between_whole_pixels_adds_up_over_the_wrap() {
        // metal_tread_studs: 27 px across in whole pixels, 26.7 px in fact, so 432 px is 16.2
        // periods (4.8 px out of phase) and 427 px is 16 (0.2 px).
        let studs = fine((26.7, 0.02), (-0.01, 26.0));
        let f = wrap_fit(&studs, (432, 312));
        assert!(!f.continuous, "{f:?}");
        assert_eq!((f.period_across, f.phase_across, f.phase_down), (Some(26.7), 4.8, 0.0));
        assert_eq!(f.nearest, vec![(427, 312), (454, 312)]);
        assert!(wrap_fit(&studs, (427, 312)).continuous);
        assert!(wrap_fit(&studs, (454, 338)).continuous);
        // Half a pixel is the tolerance: 3 periods are 80.1 px, 16 are 427.2 px.
        assert!(!wrap_fit(&studs, (81, 312)).continuous && wrap_fit(&studs, (80, 312)).continuous);
        assert!(!wrap_fit(&studs, (428, 312)).continuous);
        // The whole-pixel vectors alone would have called 432 continuous.
        assert!(wrap_fit(&lattice((27, 0), (0, 26)), (432, 312)).continuous);
        // Each nearest size is within the tolerance of its whole number of periods.
        for side in 100..700 {
            for s in nearest_sides(side, Some(26.7)) {
                assert!(phase(s, Some(26.7)) <= WRAP_PHASE_PX, "{side} -> {s}");
            }
        }
    }

    #[test]
    fn sheared_and_diagonal_lattices_use_their_axis_combinations() {
        // bricks_gray as measured: t1 + t2 = (74, 0) across, t2 − t1 = (−2, 48) down (rounding shear).
        let bricks = lattice((38, -24), (36, 24));
        assert_eq!(axis_periods(&bricks), (Some(74.0), Some(48.0)));
        assert!(wrap_fit(&bricks, (74 * 6, 48 * 8)).continuous);
        assert_eq!(wrap_fit(&bricks, (420, 336)).nearest, vec![(444, 336), (370, 336)]);
        // terracotta: t2 = (1, 84) is the vertical period with a pixel of shear.
        let terracotta = lattice((88, 0), (1, 84));
        assert!(warning(&terracotta, (88 * 4, 84 * 4)).is_none());
        assert!(!wrap_fit(&terracotta, (88 * 4 + 1, 84 * 4)).continuous, "a pixel off is out of phase");
        // A lattice with no near-axis combination cannot wrap in phase across at any size near.
        let oblique = lattice((40, 13), (7, 31));
        let f = wrap_fit(&oblique, (400, 400));
        assert!(!f.continuous);
    }
}
