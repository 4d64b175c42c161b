//! Tileable outputs for the overlapping-block methods (quilting, patch sampling): the block grid
//! laid on a torus, so that the last column of blocks also overlaps the first and the last row the
//! first, and the output wraps left↔right and top↔bottom like any interior seam.
//!
//! It lives apart from `block_grid` so that the plain (cropped) path keeps its exact code and
//! pixels; what both methods need for the wrap is here once: which sizes can wrap, which sides of a
//! block already hold content, a wrapped read of that content for the overlap search, and a paste
//! that cuts or feathers on every side that meets old content.

use super::block_grid::OverlapRule;
use super::boundary_cut::{horizontal_cut, vertical_cut};
use super::canvas::Canvas;
use super::overlap::{Rect, error_surface, pixel_error};
use crate::image::RgbImage;
use crate::image::seam_grid::{SeamBand, SeamGrid};

/// A `cols × rows` grid of `block`-sided blocks at stride `block − overlap` on a torus of exactly
/// `cols·stride × rows·stride` pixels: block `(bi, bj)` covers `[bj·s, bj·s + block)` modulo the
/// width (likewise rows), so the last column's right `overlap` pixels lie on the first column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TorusGrid {
    pub block: u32,
    pub overlap: u32,
    pub cols: u32,
    pub rows: u32,
}

/// Which sides of a block meet content already on the torus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sides {
    pub left: bool,
    pub top: bool,
    pub right: bool,
    pub bottom: bool,
}

/// Whether `len` pixels wrap with this stride: a whole number of strides, at least two blocks (one
/// block would overlap itself).
fn wraps(len: u32, stride: u32) -> bool {
    len.is_multiple_of(stride) && len / stride >= 2
}

/// The nearest lengths that wrap, below (when there is one) and above; `len` itself when it wraps.
fn nearest(len: u32, stride: u32) -> (Option<u32>, u32) {
    if wraps(len, stride) {
        return (Some(len), len);
    }
    let below = len / stride * stride;
    ((below >= 2 * stride).then_some(below), (below + stride).max(2 * stride))
}

impl TorusGrid {
    /// The torus of a method that copies whole `block × block` patches of the sample (quilting,
    /// patch sampling): [`TorusGrid::new`] once the block fits in the sample.
    pub fn of_blocks(what: &str, block: u32, overlap: u32, sample: (u32, u32), output: (u32, u32)) -> Result<TorusGrid, String> {
        let smaller = sample.0.min(sample.1);
        if block > smaller {
            return Err(format!("block {block} does not fit in the {}x{} sample; use at most {smaller}", sample.0, sample.1));
        }
        TorusGrid::new(what, block, overlap, output.0, output.1, smaller)
    }

    /// The torus for a `width × height` output, or one sentence for the user saying why it cannot
    /// wrap and what would (`what` names the method; `max_block` is the largest block the sample
    /// allows, for suggesting another block size that fits the requested size).
    pub fn new(what: &str, block: u32, overlap: u32, width: u32, height: u32, max_block: u32) -> Result<TorusGrid, String> {
        if overlap == 0 || 2 * overlap > block {
            return Err(format!("tileable {what} needs an overlap in 1..={} for block {block}", block / 2));
        }
        let s = block - overlap;
        if wraps(width, s) && wraps(height, s) {
            return Ok(TorusGrid { block, overlap, cols: width / s, rows: height / s });
        }
        let (wl, wh) = nearest(width, s);
        let (hl, hh) = nearest(height, s);
        let mut options = Vec::new();
        if let (Some(w), Some(h)) = (wl, hl) {
            options.push(format!("{w}x{h}"));
        }
        options.push(format!("{wh}x{hh}"));
        // Another block with the same overlap, when one fits the size asked for: the user may
        // care more about the size than about the block.
        let other = (2 * overlap.max(2)..=max_block.min(4 * block))
            .filter(|&b| b != block && wraps(width, b - overlap) && wraps(height, b - overlap))
            .min_by_key(|&b| (b.abs_diff(block), b));
        let alternative = match other {
            Some(b) => format!(", or block = {b} for {width}x{height}"),
            None => String::new(),
        };
        Err(format!(
            "tileable {what} needs width and height multiples of block - overlap = {s} (at least 2 blocks each way); {} would work{alternative}",
            options.join(" or ")
        ))
    }

    pub fn stride(&self) -> u32 {
        self.block - self.overlap
    }

    /// The output, which is the whole torus.
    pub fn size(&self) -> (u32, u32) {
        (self.cols * self.stride(), self.rows * self.stride())
    }

    /// Torus position of block `(bi, bj)` (row, column).
    pub fn origin(&self, bi: u32, bj: u32) -> (u32, u32) {
        (bj * self.stride(), bi * self.stride())
    }

    /// Row-major index of block `(bi, bj)`, for per-block flags.
    pub fn index(&self, bi: u32, bj: u32) -> usize {
        (bi * self.cols + bj) as usize
    }

    /// Every block, row-major.
    pub fn raster(&self) -> Vec<(u32, u32)> {
        (0..self.rows).flat_map(|bi| (0..self.cols).map(move |bj| (bi, bj))).collect()
    }

    /// The blocks a block overlaps: its eight cyclic neighbours (fewer distinct ones on a torus of
    /// two blocks a side). Farther blocks never overlap it, since `overlap ≤ stride`.
    fn neighbours(&self, bi: u32, bj: u32) -> Vec<(u32, u32)> {
        let (r, c) = (self.rows, self.cols);
        let mut n: Vec<(u32, u32)> = [(r - 1, c - 1), (r - 1, 0), (r - 1, 1), (0, c - 1), (0, 1), (1, c - 1), (1, 0), (1, 1)]
            .iter()
            .map(|&(di, dj)| ((bi + di) % r, (bj + dj) % c))
            .filter(|&p| p != (bi, bj))
            .collect();
        n.sort_unstable();
        n.dedup();
        n
    }

    /// Which sides of `(bi, bj)` meet content, given which blocks are pasted (`done`, row-major).
    /// A diagonal neighbour's corner always lies in a side strip whose neighbour is done too in
    /// the orders used here (raster, [`TorusGrid::waves`]), so the sides say all there is.
    pub fn sides(&self, done: &[bool], bi: u32, bj: u32) -> Sides {
        let (r, c) = (self.rows, self.cols);
        Sides {
            left: done[self.index(bi, (bj + c - 1) % c)],
            right: done[self.index(bi, (bj + 1) % c)],
            top: done[self.index((bi + r - 1) % r, bj)],
            bottom: done[self.index((bi + 1) % r, bj)],
        }
    }

    /// The overlap of a block with these sides as disjoint rectangles relative to the block: the
    /// full-height left and right strips, and the top and bottom strips between them (for left and
    /// top alone, the plain grid's L).
    pub fn regions(&self, sides: Sides) -> Vec<Rect> {
        let (b, w) = (self.block, self.overlap);
        let mut regions = Vec::with_capacity(4);
        if sides.left {
            regions.push(Rect::new(0, 0, w, b));
        }
        let x0 = if sides.left { w } else { 0 };
        let x1 = if sides.right { b - w } else { b };
        if sides.top {
            regions.push(Rect::new(x0, 0, x1 - x0, w));
        }
        if sides.right {
            regions.push(Rect::new(b - w, 0, w, b));
        }
        if sides.bottom {
            regions.push(Rect::new(x0, b - w, x1 - x0, w));
        }
        regions
    }

    /// The `block × block` window of the torus under block `(bi, bj)`, read with wrapped
    /// coordinates: the overlap search and the cut compare a candidate with this at offset (0, 0).
    pub fn window(&self, image: &RgbImage, bi: u32, bj: u32) -> RgbImage {
        let (w, h) = self.size();
        let (ox, oy) = self.origin(bi, bj);
        RgbImage::from_fn(self.block, self.block, |x, y| image.get((ox + x) % w, (oy + y) % h))
    }

    /// Blocks in waves for parallel searches: a block's wave comes after those of all blocks it
    /// overlaps that precede it in the plain grid's wave order (`2·bi + bj`, then `bi`), so no two
    /// blocks of a wave overlap and the result is that of pasting in that order, on any number of
    /// threads. On a torus the wrapped neighbours delay some blocks by a wave or two.
    pub fn waves(&self) -> Vec<Vec<(u32, u32)>> {
        let mut order = self.raster();
        order.sort_by_key(|&(bi, bj)| (2 * bi + bj, bi));
        let mut wave: Vec<Option<usize>> = vec![None; order.len()];
        let mut waves: Vec<Vec<(u32, u32)>> = Vec::new();
        for &(bi, bj) in &order {
            let t = self.neighbours(bi, bj).iter().filter_map(|&(i, j)| wave[self.index(i, j)]).max().map_or(0, |m| m + 1);
            wave[self.index(bi, bj)] = Some(t);
            if waves.len() <= t {
                waves.resize(t + 1, Vec::new());
            }
            waves[t].push((bi, bj));
        }
        waves
    }

    /// Pastes the sample block at `src` as block `(bi, bj)`, meeting old content on `sides` by
    /// `rule`: a minimum-error cut on every such side (on the right and bottom mirrored, so the
    /// pixels beyond the cut keep the old content), feathering from every such side (the smallest
    /// ramp wins, as in the plain L), or a plain overwrite. Writes with wrapped coordinates.
    #[allow(clippy::too_many_arguments)]
    pub fn paste(&self, canvas: &mut Canvas, sample: &RgbImage, src: (u32, u32), bi: u32, bj: u32, sides: Sides, rule: OverlapRule) {
        let (b, ov) = (self.block as usize, self.overlap as usize);
        let (w, h) = self.size();
        let (ox, oy) = self.origin(bi, bj);
        // The new block's pixels: x in lo_x[y]..=hi_x[y] of each row, y in lo_y[x]..=hi_y[x] of each column.
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (vec![0usize; b], vec![b - 1; b], vec![0usize; b], vec![b - 1; b]);
        if rule == OverlapRule::Cut && sides != Sides::default() {
            let old = self.window(&canvas.image, bi, bj);
            let e = |x: usize, y: usize| pixel_error(sample.get(src.0 + x as u32, src.1 + y as u32), old.get(x as u32, y as u32));
            if sides.left {
                lo_x = vertical_cut(&error_surface(sample, src, &old, (0, 0), self.overlap, self.block), b, ov);
            }
            if sides.right {
                let mirrored: Vec<u32> = (0..b).flat_map(|y| (0..ov).map(move |k| (y, k))).map(|(y, k)| e(b - 1 - k, y)).collect();
                hi_x = vertical_cut(&mirrored, b, ov).into_iter().map(|m| b - 1 - m).collect();
            }
            if sides.top {
                lo_y = horizontal_cut(&error_surface(sample, src, &old, (0, 0), self.block, self.overlap), ov, b);
            }
            if sides.bottom {
                let mirrored: Vec<u32> = (0..ov).flat_map(|k| (0..b).map(move |x| (k, x))).map(|(k, x)| e(x, b - 1 - k)).collect();
                hi_y = horizontal_cut(&mirrored, ov, b).into_iter().map(|m| b - 1 - m).collect();
            }
        }
        for y in 0..b {
            for x in 0..b {
                let (sx, sy) = (src.0 + x as u32, src.1 + y as u32);
                let (cx, cy) = ((ox + x as u32) % w, (oy + y as u32) % h);
                if rule == OverlapRule::Feather {
                    // The distance into the overlap from the nearest side with old content.
                    let mut k = usize::MAX;
                    if sides.left && x < ov {
                        k = k.min(x);
                    }
                    if sides.top && y < ov {
                        k = k.min(y);
                    }
                    if sides.right && x >= b - ov {
                        k = k.min(b - 1 - x);
                    }
                    if sides.bottom && y >= b - ov {
                        k = k.min(b - 1 - y);
                    }
                    if k == usize::MAX {
                        canvas.copy(cx, cy, sample, sx, sy);
                    } else {
                        canvas.blend(cx, cy, sample, sx, sy, k as u32 + 1, self.overlap + 1);
                    }
                } else if lo_x[y] <= x && x <= hi_x[y] && lo_y[x] <= y && y <= hi_y[x] {
                    canvas.copy(cx, cy, sample, sx, sy);
                }
            }
        }
    }

    /// Seam bands of the output: every overlap band, boundaries included, the band where the wrap
    /// closes (the last column's right overlap, boundaries `0..=overlap`) among them.
    pub fn seam_grid(&self) -> SeamGrid {
        let bands = |count: u32| -> Vec<SeamBand> {
            (0..count)
                .map(|k| k * self.stride())
                .map(|start| SeamBand { start: start.max(1), len: if start == 0 { self.overlap } else { self.overlap + 1 } })
                .collect()
        };
        SeamGrid { columns: bands(self.cols), rows: bands(self.rows) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::rng::Stream;

    #[test]
    fn sizes_that_wrap_and_the_refusal_that_says_what_would() {
        let t = TorusGrid::new("quilting", 50, 8, 756, 504, 256).unwrap();
        assert_eq!((t.cols, t.rows, t.size()), (18, 12, (756, 504)));
        let e = TorusGrid::new("quilting", 50, 8, 768, 768, 256).unwrap_err();
        assert!(e.contains("block - overlap = 42") && e.contains("756x756 or 798x798"), "{e}");
        // 768 = 16·48: block 56 with overlap 8 fits.
        assert!(e.contains("block = 56 for 768x768"), "{e}");
        // One block a side would overlap itself.
        let e = TorusGrid::new("quilting", 50, 8, 42, 84, 256).unwrap_err();
        assert!(e.contains("84x84"), "{e}");
    }

    #[test]
    fn sides_and_regions_follow_what_is_done() {
        let t = TorusGrid::new("t", 20, 4, 64, 48, 64).unwrap();
        let mut done = vec![false; (t.rows * t.cols) as usize];
        assert_eq!(t.sides(&done, 0, 0), Sides::default());
        for (bi, bj) in t.raster() {
            done[t.index(bi, bj)] = true;
        }
        let all = t.sides(&done, 1, 3);
        assert_eq!(all, Sides { left: true, top: true, right: true, bottom: true });
        let r = t.regions(all);
        assert_eq!(r, vec![Rect::new(0, 0, 4, 20), Rect::new(4, 0, 12, 4), Rect::new(16, 0, 4, 20), Rect::new(4, 16, 12, 4)]);
        assert_eq!(r.iter().map(|r| r.area()).sum::<u64>(), 20 * 20 - 12 * 12);
        assert_eq!(t.regions(Sides { left: true, top: true, ..Sides::default() }), vec![Rect::new(0, 0, 4, 20), Rect::new(4, 0, 16, 4)]);
    }

    /// In raster order and in the wave order, the pixels of a block already covered are exactly
    /// its side strips: no lone corner that the cut or the feather would not see.
    #[test]
    fn filled_pixels_are_the_side_strips_in_both_orders() {
        for (cols, rows) in [(2, 2), (2, 3), (3, 2), (3, 3), (4, 3), (5, 3), (5, 4), (7, 5)] {
            let t = TorusGrid::new("t", 10, 3, cols * 7, rows * 7, 64).unwrap();
            let orders: [Vec<(u32, u32)>; 2] = [t.raster(), t.waves().concat()];
            for order in orders {
                let (w, h) = t.size();
                let mut filled = vec![false; (w * h) as usize];
                let mut done = vec![false; order.len()];
                for &(bi, bj) in &order {
                    let regions = t.regions(t.sides(&done, bi, bj));
                    let (ox, oy) = t.origin(bi, bj);
                    for y in 0..10 {
                        for x in 0..10 {
                            let in_region = regions.iter().any(|r| x >= r.x && x < r.x + r.w && y >= r.y && y < r.y + r.h);
                            let i = (((oy + y) % h) * w + (ox + x) % w) as usize;
                            assert_eq!(filled[i], in_region, "{cols}x{rows} block ({bi},{bj}) pixel ({x},{y})");
                        }
                    }
                    for y in 0..10 {
                        for x in 0..10 {
                            filled[(((oy + y) % h) * w + (ox + x) % w) as usize] = true;
                        }
                    }
                    done[t.index(bi, bj)] = true;
                }
            }
        }
    }

    #[test]
    fn no_two_blocks_of_a_wave_overlap() {
        for (cols, rows) in [(2, 2), (3, 3), (4, 2), (5, 3), (9, 6)] {
            let t = TorusGrid::new("t", 10, 3, cols * 7, rows * 7, 64).unwrap();
            let waves = t.waves();
            assert_eq!(waves[0], vec![(0, 0)]);
            assert_eq!(waves.iter().map(Vec::len).sum::<usize>(), (cols * rows) as usize);
            for wave in &waves {
                for &a in wave {
                    assert!(wave.iter().all(|&b| !t.neighbours(a.0, a.1).contains(&b)), "{cols}x{rows}: {wave:?}");
                }
            }
        }
    }

    #[test]
    fn a_cut_on_the_right_keeps_the_old_content_beyond_it() {
        // Old content everywhere; a block whose right strip disagrees with it except along one
        // column: the cut must follow that column and keep the old pixels right of it.
        let t = TorusGrid::new("t", 10, 4, 24, 12, 64).unwrap();
        let mut s = Stream::new(1, "test/torus");
        let sample = RgbImage::from_fn(10, 10, |x, _| if x == 7 { [9, 9, 9] } else { [200, s.below(50) as u8, 0] });
        let mut canvas = Canvas::new(24, 12, (10, 10), true);
        for y in 0..12 {
            for x in 0..24 {
                canvas.image.put(x, y, [9, 9, 9]);
            }
        }
        let sides = Sides { right: true, ..Sides::default() };
        t.paste(&mut canvas, &sample, (0, 0), 0, 2, sides, OverlapRule::Cut);
        // Block (0, 2) starts at x = 12 and wraps: its columns 8, 9 are output columns 20, 21;
        // column 10 onward is beyond the block.
        for y in 0..10 {
            assert_eq!(canvas.image.get(12 + 6, y)[0], 200, "new left of the cut");
            assert_eq!(canvas.image.get(12 + 8, y), [9, 9, 9], "old right of the cut");
        }
    }
}
