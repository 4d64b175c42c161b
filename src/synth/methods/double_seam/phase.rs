//! Double-seam's lattice phase on a torus: when a tileable output's size keeps the sample's
//! lattice whole across the wrap, every block is kept in the first block's lattice phase, so the
//! texels run on through the wrap as they do inside. Apart from the search and the seams it
//! serves, because it is about the sample's lattice, not about matching lines.

use crate::image::RgbImage;

/// The sample's lattice when a tileable output's size keeps it whole across the wrap
/// ([`crate::synth::wrap::wrap_fit`], the lattice `texsyn advise` and the manifest's wrap warning
/// use): blocks are then kept to offsets (sample position − output position) within
/// [`LatticePhase::tolerance`] of a lattice vector from the first block's. The vectors are the
/// sub-pixel ones ([`crate::synth::lattice::FineVectors`]): blocks a dozen periods apart in the
/// sample stay in phase, and so does the wrap, which `wrap_fit` checks on the same vectors.
pub(super) struct LatticePhase {
    t1: (f64, f64),
    t2: (f64, f64),
    tolerance: f64,
    lattice: ((i64, i64), (i64, i64)),
}

impl LatticePhase {
    /// Phase tolerance in pixels (largest coordinate of the residual). A pixel: whole-pixel
    /// positions reach every lattice point within half a pixel, so every period offers a few
    /// candidates, and a texel drifts no more than that across the output. (It was a tenth of
    /// the shorter vector, 2.6 px on metal_tread_studs, while the vectors were whole pixels and
    /// the phase a few periods away was a pixel or two off anyway.)
    const TOLERANCE_PX: f64 = 1.0;

    pub(super) fn of(sample: &RgbImage, size: (u32, u32)) -> Option<LatticePhase> {
        let l = crate::synth::lattice::extract(sample, &crate::synth::lattice::LatticeOptions::default()).ok()?;
        if !crate::synth::wrap::wrap_fit(&l, size).continuous {
            return None;
        }
        Some(LatticePhase { t1: l.fine.t1, t2: l.fine.t2, tolerance: Self::TOLERANCE_PX, lattice: (l.t1, l.t2) })
    }

    /// Where the sample's lattice lands when the block at `pos` is pasted at `origin`: minus
    /// the offset (sample position − output position).
    pub(super) fn shift(pos: (i32, i32), origin: (i32, i32)) -> (f64, f64) {
        (f64::from(origin.0 - pos.0), f64::from(origin.1 - pos.1))
    }

    /// Whether the shift difference `d` is within the tolerance of a lattice vector (largest
    /// coordinate of the residual).
    pub(super) fn keeps(&self, d: (f64, f64)) -> bool {
        let (t1, t2) = (self.t1, self.t2);
        let (x, y) = d;
        let det = t1.0 * t2.1 - t1.1 * t2.0;
        let (a, b) = ((x * t2.1 - y * t2.0) / det, (t1.0 * y - t1.1 * x) / det);
        let mut best = f64::INFINITY;
        for m in [a.floor() - 1.0, a.floor(), a.floor() + 1.0, a.floor() + 2.0] {
            for n in [b.floor() - 1.0, b.floor(), b.floor() + 1.0, b.floor() + 2.0] {
                let (rx, ry) = (x - m * t1.0 - n * t2.0, y - m * t1.1 - n * t2.1);
                best = best.min(rx.abs().max(ry.abs()));
            }
        }
        best <= self.tolerance
    }

    pub(super) fn describe(&self) -> serde_json::Value {
        serde_json::json!({
            "how": "the output's size keeps the sample's lattice whole across the wrap: every block in the first block's lattice phase",
            "t1": [self.lattice.0.0, self.lattice.0.1],
            "t2": [self.lattice.1.0, self.lattice.1.1],
            "t1_fine": [self.t1.0, self.t1.1],
            "t2_fine": [self.t2.0, self.t2.1],
            "tolerance_px": (self.tolerance * 1000.0).round() / 1000.0,
        })
    }
}
