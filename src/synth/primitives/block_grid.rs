//! The raster grid of overlapping square blocks shared by image quilting and patch sampling:
//! how many blocks cover an output, where each one's overlap with earlier blocks lies, how a
//! block is pasted over that overlap (boundary cut, feathering or plain overwrite), and where the
//! seams can be for the seam-visibility metric.

use super::boundary_cut::{horizontal_cut, vertical_cut};
use super::canvas::Canvas;
use super::overlap::{Rect, error_surface};
use crate::image::RgbImage;
use crate::image::seam_grid::{SeamBand, SeamGrid};

/// Blocks of side `block` at stride `block − overlap`, enough to cover an output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockGrid {
    pub block: u32,
    pub overlap: u32,
    pub cols: u32,
    pub rows: u32,
}

impl BlockGrid {
    /// The fewest blocks covering `width × height` (the canvas is cropped to it afterwards).
    pub fn new(block: u32, overlap: u32, width: u32, height: u32) -> BlockGrid {
        let stride = block - overlap;
        let count = |len: u32| if len <= block { 1 } else { (len - overlap).div_ceil(stride) };
        BlockGrid { block, overlap, cols: count(width), rows: count(height) }
    }

    pub fn stride(&self) -> u32 {
        self.block - self.overlap
    }

    /// The canvas the blocks fill: `n·B − (n−1)·overlap` per side.
    pub fn canvas(&self) -> (u32, u32) {
        (self.cols * self.stride() + self.overlap, self.rows * self.stride() + self.overlap)
    }

    /// Canvas position of block `(bi, bj)` (row, column).
    pub fn origin(&self, bi: u32, bj: u32) -> (u32, u32) {
        (bj * self.stride(), bi * self.stride())
    }

    /// The overlap of block `(bi, bj)` with earlier blocks, as disjoint rectangles relative to the
    /// block: the left strip, the top strip, or their L-shaped union.
    pub fn overlap_regions(&self, bi: u32, bj: u32) -> Vec<Rect> {
        let (b, w) = (self.block, self.overlap);
        let mut regions = Vec::with_capacity(2);
        if bj > 0 {
            regions.push(Rect::new(0, 0, w, b));
        }
        if bi > 0 {
            let x0 = if bj > 0 { w } else { 0 };
            regions.push(Rect::new(x0, 0, b - x0, w));
        }
        regions
    }

    /// The blocks in fronts that may be searched together: every block a block's search reads
    /// (the earlier blocks over its area) lies in an earlier front, and blocks of one front never
    /// overlap, so searching a front at once and pasting it in any order gives exactly the raster
    /// order's canvas. Block `(bi, bj)` goes to front `bj + 2·bi`: its upper-right neighbour
    /// `(bi − 1, bj + 1)` reaches into its top overlap, so one front per anti-diagonal would not
    /// do. Needs `overlap ≤ block / 2` (blocks two strides apart do not meet); otherwise each
    /// block is its own front, in raster order.
    pub fn fronts(&self) -> Vec<Vec<(u32, u32)>> {
        if 2 * self.overlap > self.block {
            return (0..self.rows).flat_map(|bi| (0..self.cols).map(move |bj| vec![(bi, bj)])).collect();
        }
        let mut fronts = vec![Vec::new(); (self.cols + 2 * self.rows - 2) as usize];
        for bi in 0..self.rows {
            for bj in 0..self.cols {
                fronts[(bj + 2 * bi) as usize].push((bi, bj));
            }
        }
        fronts.retain(|f| !f.is_empty());
        fronts
    }

    /// Seam bands of the cropped `width × height` output: each overlap band, boundaries included.
    pub fn seam_grid(&self, width: u32, height: u32) -> SeamGrid {
        let bands = |count: u32, limit: u32| -> Vec<SeamBand> {
            (1..count)
                .map(|k| k * self.stride())
                .filter(|&start| start < limit)
                .map(|start| SeamBand { start: start.max(1), len: (self.overlap + 1).min(limit - start) })
                .collect()
        };
        SeamGrid { columns: bands(self.cols, width), rows: bands(self.rows, height) }
    }
}

/// How a new block meets the output over its overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverlapRule {
    /// Minimum-error boundary cut (B3; the L case as two independent cuts).
    Cut,
    /// Liang et al.'s linear ramp (B5), the minimum of the two ramps in the corner.
    Feather,
    /// The new block overwrites the overlap.
    Overwrite,
}

/// Where a pasted block starts to show over its overlap: for each row, the first column taken
/// from the new block; for each column, the first row (all zero without a cut).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockCuts {
    first_col: Vec<usize>,
    first_row: Vec<usize>,
}

/// The cuts of the `block × block` sample patch at `src` pasted at `dst` of `image`. They read
/// only `image` under the block, so blocks that do not meet can have theirs found concurrently.
#[allow(clippy::too_many_arguments)]
pub fn block_cuts(
    image: &RgbImage,
    sample: &RgbImage,
    src: (u32, u32),
    dst: (u32, u32),
    block: u32,
    overlap: u32,
    left: bool,
    top: bool,
    rule: OverlapRule,
) -> BlockCuts {
    let (b, ov) = (block as usize, overlap as usize);
    let mut cuts = BlockCuts { first_col: vec![0usize; b], first_row: vec![0usize; b] };
    if rule == OverlapRule::Cut && left {
        cuts.first_col = vertical_cut(&error_surface(sample, src, image, dst, overlap, block), b, ov);
    }
    if rule == OverlapRule::Cut && top {
        cuts.first_row = horizontal_cut(&error_surface(sample, src, image, dst, block, overlap), ov, b);
    }
    cuts
}

/// Pastes the `block × block` sample patch at `src` onto the canvas at `dst`; `left`/`top` say
/// which overlaps exist.
#[allow(clippy::too_many_arguments)]
pub fn paste_block(
    canvas: &mut Canvas,
    sample: &RgbImage,
    src: (u32, u32),
    dst: (u32, u32),
    block: u32,
    overlap: u32,
    left: bool,
    top: bool,
    rule: OverlapRule,
) {
    let cuts = block_cuts(&canvas.image, sample, src, dst, block, overlap, left, top, rule);
    paste_with_cuts(canvas, sample, src, dst, block, overlap, left, top, rule, &cuts);
}

/// [`paste_block`] with its cuts already found by [`block_cuts`] on the same canvas.
#[allow(clippy::too_many_arguments)]
pub fn paste_with_cuts(
    canvas: &mut Canvas,
    sample: &RgbImage,
    src: (u32, u32),
    dst: (u32, u32),
    block: u32,
    overlap: u32,
    left: bool,
    top: bool,
    rule: OverlapRule,
    cuts: &BlockCuts,
) {
    let (first_col, first_row) = (&cuts.first_col, &cuts.first_row);
    for y in 0..block {
        for x in 0..block {
            let (sx, sy) = (src.0 + x, src.1 + y);
            let (cx, cy) = (dst.0 + x, dst.1 + y);
            let in_left = left && x < overlap;
            let in_top = top && y < overlap;
            if rule == OverlapRule::Feather && (in_left || in_top) {
                // The weight of the new block is the smaller of the two ramps (B5): both are
                // `(k + 1) / (overlap + 1)`, so the smaller k decides.
                let mut k = u32::MAX;
                if in_left {
                    k = k.min(x);
                }
                if in_top {
                    k = k.min(y);
                }
                canvas.blend(cx, cy, sample, sx, sy, k + 1, overlap + 1);
            } else if x as usize >= first_col[y as usize] && y as usize >= first_row[x as usize] {
                canvas.copy(cx, cy, sample, sx, sy);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::primitives::feather;

    #[test]
    fn fronts_keep_the_raster_order_of_every_overlapping_pair() {
        for (block, overlap, w, h) in [(40, 10, 512, 512), (50, 8, 300, 120), (20, 10, 90, 70), (21, 11, 80, 80), (30, 5, 30, 200)] {
            let g = BlockGrid::new(block, overlap, w, h);
            let front_of: std::collections::HashMap<(u32, u32), usize> =
                g.fronts().iter().enumerate().flat_map(|(f, blocks)| blocks.iter().map(move |&b| (b, f))).collect();
            assert_eq!(front_of.len(), (g.rows * g.cols) as usize);
            let blocks: Vec<(u32, u32)> = (0..g.rows).flat_map(|bi| (0..g.cols).map(move |bj| (bi, bj))).collect();
            for (k, &a) in blocks.iter().enumerate() {
                for &b in &blocks[k + 1..] {
                    let (oa, ob) = (g.origin(a.0, a.1), g.origin(b.0, b.1));
                    let meet = oa.0.abs_diff(ob.0) < block && oa.1.abs_diff(ob.1) < block;
                    if meet {
                        assert!(front_of[&a] < front_of[&b], "{block}/{overlap}: {a:?} and {b:?}");
                    }
                }
            }
        }
        // Fronts hold several blocks when they can.
        assert!(BlockGrid::new(40, 10, 512, 512).fronts().iter().any(|f| f.len() > 4));
    }

    #[test]
    fn grid_covers_the_output_with_the_fewest_blocks() {
        // 9 blocks of 50 with overlap 8 give 9·50 − 8·8 = 386 (paper 003's protocol).
        let g = BlockGrid::new(50, 8, 386, 386);
        assert_eq!((g.cols, g.rows), (9, 9));
        assert_eq!(g.canvas(), (386, 386));
        let g = BlockGrid::new(40, 10, 512, 100);
        assert!(g.canvas().0 >= 512 && g.canvas().0 - 30 < 512);
        assert_eq!(BlockGrid::new(50, 8, 20, 50).cols, 1);
        assert_eq!(g.origin(2, 3), (90, 60));
    }

    #[test]
    fn overlap_regions_are_the_strips_or_the_l() {
        let g = BlockGrid::new(20, 4, 100, 100);
        assert!(g.overlap_regions(0, 0).is_empty());
        assert_eq!(g.overlap_regions(0, 1), vec![Rect::new(0, 0, 4, 20)]);
        assert_eq!(g.overlap_regions(1, 0), vec![Rect::new(0, 0, 20, 4)]);
        assert_eq!(g.overlap_regions(1, 1), vec![Rect::new(0, 0, 4, 20), Rect::new(4, 0, 16, 4)]);
    }

    #[test]
    fn seam_bands_follow_the_block_grid() {
        let g = BlockGrid::new(50, 8, 386, 386);
        let s = g.seam_grid(386, 386);
        assert_eq!(s.columns.len(), 8);
        assert_eq!(s.columns[0], SeamBand { start: 42, len: 9 });
    }

    #[test]
    fn overwrite_copies_and_feather_blends_only_the_overlap() {
        let sample = RgbImage::from_fn(10, 10, |_, _| [200, 200, 200]);
        let mut canvas = Canvas::new(10, 10, (10, 10), true);
        paste_block(&mut canvas, &sample, (0, 0), (0, 0), 6, 2, true, false, OverlapRule::Feather);
        assert_eq!(canvas.image.get(0, 0), feather::blend([0, 0, 0], [200, 200, 200], feather::new_weight(0, 2)));
        assert_eq!(canvas.image.get(2, 0), [200, 200, 200]);
        let mut c2 = Canvas::new(10, 10, (10, 10), false);
        paste_block(&mut c2, &sample, (0, 0), (0, 0), 6, 2, true, true, OverlapRule::Overwrite);
        assert_eq!(c2.image.get(0, 0), [200, 200, 200]);
    }
}
