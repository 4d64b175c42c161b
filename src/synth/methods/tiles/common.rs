//! What the two tile methods share beyond the Wang-tile colouring ([`super::wang`]) and the
//! lattice alignment ([`super::align`]): the per-pixel cut cost, the `patch_candidates` choice
//! among random patch draws, the `export_tiles` parameter, reading their typed configs, and
//! rendering a filled tiling whole or strip by strip.
//!
//! It sits below both methods and below the tile-set modules, so that `wang-tiles` does not have to
//! borrow these from `rw-tiles` (or the reverse) and the family's imports only go one way.

use super::wang::Tiling;
use crate::image::RgbImage;
use crate::synth::method::{Request, STRIP_ROWS, Strips, Synthesis, linear_memory};
use crate::synth::params::{Default, ParamKind, ParamSpec};
use crate::synth::primitives::overlap::pixel_error;
use std::time::Instant;

/// A tile set that renders a tiling's output rows: what both tile methods fill with.
pub trait TileRenderer: Send + Sync + 'static {
    /// Renders output rows `y0..` into `rows` (whole rows of a `width`-wide output).
    fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]);
}

/// [`crate::synth::method::Method::synthesize`] of a tile method from its fill: the output
/// rendered whole, the rendering time added to the `fill` phase.
pub fn render_whole(filled: (Synthesis, impl TileRenderer, Tiling), req: &Request) -> Synthesis {
    let (mut synthesis, tiles, tiling) = filled;
    let t = Instant::now();
    let mut image = RgbImage::new(req.width, req.height);
    tiles.render_rows(&tiling, req.width, 0, image.as_raw_mut());
    synthesis.image = image;
    if let Some(fill) = synthesis.phases.iter_mut().find(|p| p.0 == "fill") {
        fill.1 += t.elapsed().as_secs_f64();
    }
    synthesis
}

/// [`crate::synth::method::Method::synthesize_strips`] of a tile method from its fill.
pub fn render_in_strips(filled: (Synthesis, impl TileRenderer, Tiling), req: &Request) -> Strips {
    let (synthesis, tiles, tiling) = filled;
    let width = req.width;
    Strips { synthesis, render: Box::new(move |y0, rows| tiles.render_rows(&tiling, width, y0, rows)), sources: None }
}

/// Peak memory of a tile fill rendered in strips: the tile set (built from sample-sized cost
/// planes), the tiling (one byte per tile) and one strip of output rows.
pub fn strip_peak_memory(sample: (u32, u32), output: (u32, u32)) -> u64 {
    let strip = u64::from(output.0) * u64::from(STRIP_ROWS) * 3;
    linear_memory(sample, output, 0.01, 64.0, 4 << 20) + strip
}

/// The `export_tiles` parameter of both tile methods.
pub const EXPORT_TILES_PARAM: ParamSpec = ParamSpec {
    name: "export_tiles",
    kind: ParamKind::Bool,
    default: Default::Bool(false),
    doc: "also write the tile set next to the output: one RGBA PNG per tile and index.json (edge colours, placement), in `{output}.tiles/`; `texsyn tiles render` renders any size from it",
};

crate::choice! {
    /// Per-pixel cut cost (B1, or its square root): the `pixel_error` parameter of both methods.
    pub enum PixelError {
        /// The squared RGB distance (eq. 3).
        Squared = "squared",
        /// `round(1024·sqrt(e))`: the Euclidean distance in fixed point with 10 fractional bits
        /// (IEEE `sqrt` is correctly rounded, so this is exact and platform independent).
        Euclidean = "euclidean",
    }
}

impl PixelError {
    #[inline]
    pub fn eval(self, a: [u8; 3], b: [u8; 3]) -> u32 {
        let e = pixel_error(a, b);
        match self {
            PixelError::Squared => e,
            PixelError::Euclidean => ((e as f64).sqrt() * 1024.0).round() as u32,
        }
    }
}

/// Mean squared deviation from the mean colour (summed over R, G, B) of the `w × h` rectangle at
/// `(x, y)`: its contrast, in the units of B1's pixel error. Exact integer sums.
pub fn contrast(sample: &RgbImage, (x, y): (u32, u32), w: u32, h: u32) -> f64 {
    let n = (w as u64 * h as u64) as f64;
    let mut sum = [0u64; 3];
    let mut sq = [0u64; 3];
    for yy in y..y + h {
        for xx in x..x + w {
            let p = sample.get(xx, yy);
            for c in 0..3 {
                sum[c] += p[c] as u64;
                sq[c] += p[c] as u64 * p[c] as u64;
            }
        }
    }
    (0..3).map(|c| sq[c] as f64 / n - (sum[c] as f64 / n) * (sum[c] as f64 / n)).sum()
}

/// Whether every patch of a candidate is representative for `patch_candidates`: its contrast is
/// at least half the whole sample's. Without this rule the cheapest seams come from flat patches
/// (nothing to cut through), which turns a brick wall into plain bricks.
pub fn representative(sample: &RgbImage, corners: &[(u32, u32)], side: u32) -> bool {
    let whole = contrast(sample, (0, 0), sample.width(), sample.height());
    corners.iter().all(|&p| contrast(sample, p, side, side) >= 0.5 * whole)
}

/// The candidate kept by `patch_candidates`: the smallest seam cost among the representative
/// candidates (all candidates if none is), ties to the earliest.
pub fn pick_candidate(costs: &[u64], representative: &[bool]) -> usize {
    let any = representative.iter().any(|&r| r);
    (0..costs.len()).filter(|&c| !any || representative[c]).min_by_key(|&c| (costs[c], c)).expect("at least one candidate")
}

/// One candidate's four patches, two per edge class: `([A₀, A₁], [B₀, B₁])` (Wang: the N/S and
/// E/W diamond centres; RW: the "/" and "\" sub-block corners).
pub type Patches = ([(u32, u32); 2], [(u32, u32); 2]);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euclidean_error_is_the_fixed_point_square_root() {
        let (a, b) = ([10, 20, 30], [13, 24, 30]);
        assert_eq!(PixelError::Squared.eval(a, b), 25);
        assert_eq!(PixelError::Euclidean.eval(a, b), 5 * 1024);
    }

    #[test]
    fn candidates_prefer_representative_then_cheap_then_early() {
        assert_eq!(pick_candidate(&[5, 3, 3, 9], &[true, false, true, true]), 2);
        assert_eq!(pick_candidate(&[5, 3, 3], &[false, false, false]), 1);
        let flat = RgbImage::from_fn(8, 8, |x, _| if x < 4 { [0, 0, 0] } else { [200, 200, 200] });
        assert!(representative(&flat, &[(2, 0)], 4));
        assert!(!representative(&flat, &[(0, 0)], 4));
    }
}
