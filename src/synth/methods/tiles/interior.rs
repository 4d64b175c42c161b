//! Tile interiors of their own (issue #30): each tile keeps a narrow band along its edges from the
//! edge-colour patches (what makes neighbours match) and takes everything inside a closed seam from
//! a sample patch of its own.
//!
//! Why: in paper 001's tiles every pixel comes from one of the four edge-colour patches, so two
//! tiles whose edges share a colour share that patch over a quarter of their area. With `K`
//! colours a fill's autocorrelation at the tile period cannot fall below about `1/K`, while
//! quilting's falls to a few hundredths. With interiors of their own, only the band is shared,
//! so that floor is about `band area / K`, and the `K³` tiles of a set show `K³` distinct
//! interiors drawn all over the sample.
//!
//! Shared by both tile methods: a geometry is described only by its tile raster's side and each
//! pixel's depth (distance from the tile's outline, `-1` outside the tile), so the square Wang
//! tiles and the rhombus RW tiles use the same seam. The seam is a closed 8-connected shortest
//! path (B4's Dijkstra, [`shortest_path`]) through the ring of depths `d0 .. d1`, made closed by
//! cutting the ring along one column above the centre and joining the path's two ends through one
//! pixel of that column; what it encloses (a 4-connected flood from the core, which an 8-connected
//! path blocks) takes the tile's own patch. Pixels shallower than `d0`, the tile's edges among
//! them, never change, so every tiling that was valid stays valid and seamless at the tile edges.

use super::common::PixelError;
use crate::image::RgbImage;
use crate::synth::primitives::shortest_path::{flood4, shortest_path};
use crate::synth::rng::Stream;
use rayon::prelude::*;

/// The label of a pixel that comes from the tile's own patch (edge-patch labels are 0..=3).
pub const INTERIOR: u8 = 4;

/// How many random patch positions are tried per tile; the one that agrees best with the band over
/// the ring (sum of pixel errors) is kept, as quilting keeps a block that matches its overlap.
pub const CANDIDATES: usize = 8;

/// The ring, seam ends and core of one tile geometry: the same for every tile of a set.
#[derive(Clone, Debug)]
pub struct Ring {
    side: usize,
    /// Pixels of the ring minus the barrier column (where the seam may run).
    domain: Vec<bool>,
    /// Ring pixels, in raster order.
    ring: Vec<usize>,
    /// Pixels at depth `d1` or more: always interior.
    core: Vec<usize>,
    /// Pixels at depth `d0` or more: those the seam may give to the interior.
    inner: Vec<bool>,
    /// Where the seam starts, ends and closes (left of, right of and on the barrier column).
    start: usize,
    end: usize,
    close: usize,
    /// Top-left of the bounding box of the inner pixels, and its size: what one patch covers.
    origin: (i32, i32),
    extent: (u32, u32),
}

/// A tile's interior: the offset from its raster's pixels to the sample pixels they copy, and the
/// cost of its seam (sum of pixel errors along it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interior {
    pub offset: (i32, i32),
    pub cost: u64,
}

impl Ring {
    /// The ring of depths `d0 .. d1` of a `side × side` raster whose pixels have depths `depth`
    /// (`-1` outside the tile); `None` when the tile is too small for one (no core, or no place to
    /// close the seam).
    pub fn new(side: usize, depth: &[i32], d0: i32, d1: i32) -> Option<Ring> {
        assert_eq!(depth.len(), side * side, "depth plane size");
        if d0 < 1 || d1 <= d0 + 1 {
            return None;
        }
        let in_ring = |i: usize| depth[i] >= d0 && depth[i] < d1;
        let inner: Vec<bool> = depth.iter().map(|&d| d >= d0).collect();
        let core: Vec<usize> = (0..side * side).filter(|&i| depth[i] >= d1).collect();
        if core.is_empty() {
            return None;
        }
        let xs = (0..side * side).filter(|&i| inner[i]).map(|i| (i % side) as i32);
        let (x0, x1) = (xs.clone().min()?, xs.max()?);
        let ys = (0..side * side).filter(|&i| inner[i]).map(|i| (i / side) as i32);
        let (y0, y1) = (ys.clone().min()?, ys.max()?);
        // The barrier: the column through the middle, above the core.
        let cx = ((x0 + x1) / 2) as usize;
        let top_of_core = core.iter().filter(|&&i| i % side == cx).map(|&i| i / side).min()?;
        let mid = (d0 + d1) / 2;
        // Close the seam at the first barrier pixel at least half-way through the ring whose two
        // side neighbours are in the ring too.
        let close_y = (0..top_of_core).find(|&y| {
            let i = y * side + cx;
            depth[i] >= mid && in_ring(i) && cx > 0 && cx + 1 < side && in_ring(i - 1) && in_ring(i + 1)
        })?;
        let close = close_y * side + cx;
        let domain: Vec<bool> = (0..side * side).map(|i| in_ring(i) && !(i % side == cx && i / side < top_of_core)).collect();
        let ring = (0..side * side).filter(|&i| in_ring(i)).collect();
        Some(Ring {
            side,
            domain,
            ring,
            core,
            inner,
            start: close - 1,
            end: close + 1,
            close,
            origin: (x0, y0),
            extent: ((x1 - x0 + 1) as u32, (y1 - y0 + 1) as u32),
        })
    }

    /// Whether a patch of this ring's tiles fits in a `sample`-sized sample.
    pub fn fits(&self, sample: (u32, u32)) -> bool {
        self.extent.0 <= sample.0 && self.extent.1 <= sample.1
    }

    /// [`CANDIDATES`] patch corners for one tile, uniform over the sample (two draws each).
    pub fn draw(&self, st: &mut Stream, sample: (u32, u32)) -> Vec<(u32, u32)> {
        (0..CANDIDATES)
            .map(|_| {
                let x = st.below(u64::from(sample.0 - self.extent.0 + 1)) as u32;
                let y = st.below(u64::from(sample.1 - self.extent.1 + 1)) as u32;
                (x, y)
            })
            .collect()
    }

    /// Gives the tile (`raster`, RGB, and `labels`, both `side × side`) the interior of the
    /// candidate patch that agrees best with it over the ring (ties to the earliest), inside the
    /// closed seam. Pixels outside the seam, and every pixel shallower than `d0`, are unchanged.
    pub fn apply(&self, sample: &RgbImage, raster: &mut [u8], labels: &mut [u8], candidates: &[(u32, u32)], err: PixelError) -> Interior {
        let side = self.side;
        let offset_of = |c: (u32, u32)| (c.0 as i32 - self.origin.0, c.1 as i32 - self.origin.1);
        let patch = |off: (i32, i32), i: usize| sample.get(((i % side) as i32 + off.0) as u32, ((i / side) as i32 + off.1) as u32);
        let band = |raster: &[u8], i: usize| [raster[3 * i], raster[3 * i + 1], raster[3 * i + 2]];
        let ring_cost = |off: (i32, i32)| -> u64 { self.ring.iter().map(|&i| u64::from(err.eval(band(raster, i), patch(off, i)))).sum() };
        let best = candidates.iter().map(|&c| offset_of(c)).min_by_key(|&off| ring_cost(off)).expect("at least one candidate");
        let mut error = vec![0u32; side * side];
        for &i in &self.ring {
            error[i] = err.eval(band(raster, i), patch(best, i));
        }
        let mut target = vec![false; side * side];
        target[self.end] = true;
        let path = shortest_path(side, side, &self.domain, &error, self.start, &target).expect("the ring joins the seam's ends");
        let mut on_seam = vec![false; side * side];
        for &p in path.pixels.iter().chain([&self.close]) {
            on_seam[p] = true;
        }
        let enclosed = flood4(side, side, &self.core, |i| self.inner[i] && !on_seam[i]);
        for i in 0..side * side {
            if enclosed[i] || on_seam[i] {
                raster[3 * i..3 * i + 3].copy_from_slice(&patch(best, i));
                labels[i] = INTERIOR;
            }
        }
        let cost = path.pixels.iter().chain([&self.close]).map(|&p| u64::from(error[p])).sum();
        Interior { offset: best, cost }
    }
}

/// The ring of a tile with overlap `ov`: depths `1 .. ov + 1`. Only the outermost pixel line is
/// always the edge patches'; the seam runs anywhere in the `ov` pixels inside it, as wide as the
/// overlaps in which the methods' own cuts run.
pub fn band(ov: i32) -> (i32, i32) {
    (1, ov + 1)
}

/// Gives every tile its own interior ([`Ring::apply`]) in the ring `band` of a `side × side`
/// raster with pixel depths `depth`; `parts` lends a tile's raster, labels and interior offset.
/// Each tile's [`CANDIDATES`] patch positions come from stream `label` (seeded by the job seed), in
/// tile order, before any tile is cut, so the result does not depend on the thread count. `None`,
/// tiles unchanged, when the tile has no room for the ring or the sample none for a patch; else
/// the seams' total cost.
#[allow(clippy::too_many_arguments)]
pub fn give<T: Send>(
    tiles: &mut [T],
    side: usize,
    depth: &[i32],
    band: (i32, i32),
    sample: &RgbImage,
    err: PixelError,
    seed: u64,
    label: &str,
    parts: impl Fn(&mut T) -> (&mut [u8], &mut [u8], &mut Option<(i32, i32)>) + Sync,
) -> Option<u64> {
    let ring = Ring::new(side, depth, band.0, band.1)?;
    if !ring.fits(sample.dimensions()) {
        return None;
    }
    let mut st = Stream::new(seed, label);
    let draws: Vec<Vec<(u32, u32)>> = tiles.iter().map(|_| ring.draw(&mut st, sample.dimensions())).collect();
    let costs: Vec<u64> = tiles
        .par_iter_mut()
        .zip(draws.par_iter())
        .map(|(tile, candidates)| {
            let (raster, labels, interior) = parts(tile);
            let got = ring.apply(sample, raster, labels, candidates, err);
            *interior = Some(got.offset);
            got.cost
        })
        .collect();
    Some(costs.iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_depth(t: usize) -> Vec<i32> {
        (0..t * t)
            .map(|i| {
                let (x, y) = (i % t, i / t);
                x.min(y).min(t - 1 - x).min(t - 1 - y) as i32
            })
            .collect()
    }

    #[test]
    fn the_seam_encloses_the_core_and_never_touches_the_band() {
        let t = 32;
        let depth = square_depth(t);
        let ring = Ring::new(t, &depth, 2, 8).unwrap();
        let sample = RgbImage::from_fn(64, 64, |x, y| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 8) as u8]);
        let mut raster = vec![7u8; t * t * 3];
        let mut labels = vec![0u8; t * t];
        let mut st = Stream::new(1, "test");
        let cands = ring.draw(&mut st, (64, 64));
        let inter = ring.apply(&sample, &mut raster, &mut labels, &cands, PixelError::Squared);
        for i in 0..t * t {
            if depth[i] < 2 {
                assert_eq!((labels[i], &raster[3 * i..3 * i + 3]), (0, &[7u8, 7, 7][..]), "band pixel {i} unchanged");
            }
            if depth[i] >= 8 {
                assert_eq!(labels[i], INTERIOR, "core pixel {i}");
                let (x, y) = ((i % t) as i32 + inter.offset.0, (i / t) as i32 + inter.offset.1);
                assert_eq!(&raster[3 * i..3 * i + 3], &sample.get(x as u32, y as u32)[..]);
            }
        }
        // The interior is one region and the band outside it another: the seam is closed.
        let outside = flood4(t, t, &[0], |i| labels[i] != INTERIOR);
        assert!((0..t * t).all(|i| outside[i] == (labels[i] != INTERIOR)));
    }

    #[test]
    fn a_tile_too_small_for_a_ring_has_none() {
        assert!(Ring::new(8, &square_depth(8), 2, 8).is_none());
        assert!(Ring::new(32, &square_depth(32), 1, 2).is_none());
    }
}
