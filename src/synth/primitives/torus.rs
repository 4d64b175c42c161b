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

/// A `cols × rows` grid of `block`-sided blocks on a torus of exactly `width × height` pixels:
/// column `bj` starts at `xs[bj]` and covers `[xs[bj], xs[bj] + block)` modulo the width (rows
/// likewise), so the last column's right overlap lies on the first column.
///
/// When the size is a whole number of strides `block − overlap`, the blocks are evenly spaced at
/// that stride, as in the plain grid. Any other size is fitted ([`fit_axis`]): the blocks are
/// spaced one pixel closer here and there, spread evenly, so some overlaps are a pixel wider than
/// asked for. That keeps the method's look (the block, and overlaps within a pixel of the one
/// asked for) at every size, the powers of two artists use included, instead of refusing them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TorusGrid {
    pub block: u32,
    /// The overlap asked for: the widest spacing leaves this much.
    pub overlap: u32,
    pub cols: u32,
    pub rows: u32,
    xs: Vec<u32>,
    ys: Vec<u32>,
    width: u32,
    height: u32,
}

/// Which sides of a block meet content already on the torus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sides {
    pub left: bool,
    pub top: bool,
    pub right: bool,
    pub bottom: bool,
}

/// The block origins along one axis of `len` pixels, spaced at most `max_spacing` apart (the
/// stride asked for) and at least `⌈block / 2⌉` (overlaps of at most half a block, which the
/// methods' fronts and waves rely on), or `None` when no two or more blocks fit that way.
///
/// The count is the fewest blocks whose spacing stays within `max_spacing`: `⌈len / stride⌉`.
/// The `len mod count` wider spacings are spread evenly (the k-th spacing is wider when
/// `⌊(k + 1)·r / n⌋` steps up), so the overlaps never differ by more than a pixel from each other.
pub fn fit_axis(len: u32, block: u32, max_spacing: u32) -> Option<Vec<u32>> {
    let min_spacing = block.div_ceil(2);
    if max_spacing == 0 || max_spacing < min_spacing {
        return None;
    }
    let n = len.div_ceil(max_spacing).max(2);
    let (q, r) = (len / n, len % n);
    if q < min_spacing {
        return None;
    }
    let (n64, r64) = (u64::from(n), u64::from(r));
    let mut origins = Vec::with_capacity(n as usize);
    let mut x = 0;
    for k in 0..u64::from(n) {
        origins.push(x);
        let wider = (k + 1) * r64 / n64 > k * r64 / n64;
        x += q + u32::from(wider);
    }
    debug_assert_eq!(x, len);
    Some(origins)
}

impl TorusGrid {
    /// The torus of a method that copies whole `block × block` patches of the sample (quilting,
    /// patch sampling): [`TorusGrid::new`] once the block fits in the sample.
    pub fn of_blocks(what: &str, block: u32, overlap: u32, sample: (u32, u32), output: (u32, u32)) -> Result<TorusGrid, String> {
        let smaller = sample.0.min(sample.1);
        if block > smaller {
            return Err(format!("block {block} does not fit in the {}x{} sample; use at most {smaller}", sample.0, sample.1));
        }
        TorusGrid::new(what, block, overlap, output.0, output.1)
    }

    /// The torus for a `width × height` output at stride `block − overlap` or a little less, or
    /// one sentence for the user saying why it cannot wrap and the smallest size that would
    /// (`what` names the method).
    pub fn new(what: &str, block: u32, overlap: u32, width: u32, height: u32) -> Result<TorusGrid, String> {
        if overlap == 0 || 2 * overlap > block {
            return Err(format!("tileable {what} needs an overlap in 1..={} for block {block}", block / 2));
        }
        let s = block - overlap;
        match (fit_axis(width, block, s), fit_axis(height, block, s)) {
            (Some(xs), Some(ys)) => Ok(TorusGrid { block, overlap, cols: xs.len() as u32, rows: ys.len() as u32, xs, ys, width, height }),
            _ => {
                // Two blocks a side, each overlapping the other by at most half a block.
                let least = 2 * block.div_ceil(2);
                Err(format!(
                    "tileable {what} needs at least two blocks each way, {least} pixels a side for block {block}; {}x{} would work, or a smaller block",
                    width.max(least),
                    height.max(least)
                ))
            }
        }
    }

    /// Whether the blocks are evenly spaced at `block − overlap`, as on the plain grid (the size
    /// is a whole number of strides), rather than fitted to the size.
    pub fn is_even(&self) -> bool {
        let s = self.block - self.overlap;
        self.width == self.cols * s && self.height == self.rows * s
    }

    /// Records a fitted grid in a method's diagnostics as `tileable_grid` ([`TorusGrid::describe`]),
    /// so the manifest says how the size was met; an even grid adds nothing (its manifests stay
    /// as they were before sizes were fitted).
    pub fn record_fit(&self, diagnostics: &mut serde_json::Value) {
        if !self.is_even() {
            diagnostics["tileable_grid"] = self.describe();
        }
    }

    /// What the fit did: the spacings and overlaps used per axis.
    pub fn describe(&self) -> serde_json::Value {
        let axis = |origins: &[u32], len: u32| {
            let n = origins.len();
            let spacings: Vec<u32> = (0..n).map(|k| Self::spacing_in(origins, len, k)).collect();
            let (lo, hi) = (spacings.iter().min().copied().unwrap_or(0), spacings.iter().max().copied().unwrap_or(0));
            serde_json::json!({
                "blocks": n,
                "spacing": if lo == hi { serde_json::json!(lo) } else { serde_json::json!([lo, hi]) },
                "overlap": if lo == hi { serde_json::json!(self.block - lo) } else { serde_json::json!([self.block - hi, self.block - lo]) },
            })
        };
        serde_json::json!({
            "fitted": !self.is_even(),
            "x": axis(&self.xs, self.width),
            "y": axis(&self.ys, self.height),
        })
    }

    fn spacing_in(origins: &[u32], len: u32, k: usize) -> u32 {
        origins.get(k + 1).copied().unwrap_or(len) - origins[k]
    }

    /// Pixels from column `bj`'s origin to the next column's (the last one's to the wrap).
    pub fn spacing_x(&self, bj: u32) -> u32 {
        Self::spacing_in(&self.xs, self.width, bj as usize)
    }

    /// Pixels from row `bi`'s origin to the next row's.
    pub fn spacing_y(&self, bi: u32) -> u32 {
        Self::spacing_in(&self.ys, self.height, bi as usize)
    }

    /// The overlap between column `bj` and the next one (the last and the first: the wrap).
    pub fn overlap_x(&self, bj: u32) -> u32 {
        self.block - self.spacing_x(bj)
    }

    /// The overlap between row `bi` and the next one.
    pub fn overlap_y(&self, bi: u32) -> u32 {
        self.block - self.spacing_y(bi)
    }

    /// The column whose span `[xs[bj], xs[bj + 1])` holds `x` (`0 ≤ x < width`).
    pub fn column_at(&self, x: u32) -> u32 {
        (self.xs.partition_point(|&o| o <= x) - 1) as u32
    }

    /// The row whose span holds `y`.
    pub fn row_at(&self, y: u32) -> u32 {
        (self.ys.partition_point(|&o| o <= y) - 1) as u32
    }

    /// The output, which is the whole torus.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The overlap widths of block `(bi, bj)` with its neighbours: left, top, right, bottom.
    fn side_widths(&self, bi: u32, bj: u32) -> [u32; 4] {
        let (r, c) = (self.rows, self.cols);
        [self.overlap_x((bj + c - 1) % c), self.overlap_y((bi + r - 1) % r), self.overlap_x(bj), self.overlap_y(bi)]
    }

    /// Torus position of block `(bi, bj)` (row, column).
    pub fn origin(&self, bi: u32, bj: u32) -> (u32, u32) {
        (self.xs[bj as usize], self.ys[bi as usize])
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
    /// two blocks a side). Farther blocks never overlap it, since every spacing is at least half a
    /// block.
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

    /// The overlap of block `(bi, bj)` with these sides as disjoint rectangles relative to the
    /// block: the full-height left and right strips, and the top and bottom strips between them
    /// (for left and top alone, the plain grid's L). Each strip is as wide as that side's overlap.
    pub fn regions(&self, bi: u32, bj: u32, sides: Sides) -> Vec<Rect> {
        let b = self.block;
        let [wl, wt, wr, wb] = self.side_widths(bi, bj);
        let mut regions = Vec::with_capacity(4);
        if sides.left {
            regions.push(Rect::new(0, 0, wl, b));
        }
        let x0 = if sides.left { wl } else { 0 };
        let x1 = if sides.right { b - wr } else { b };
        if sides.top {
            regions.push(Rect::new(x0, 0, x1 - x0, wt));
        }
        if sides.right {
            regions.push(Rect::new(b - wr, 0, wr, b));
        }
        if sides.bottom {
            regions.push(Rect::new(x0, b - wb, x1 - x0, wb));
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
        let b = self.block as usize;
        let [wl, wt, wr, wb] = self.side_widths(bi, bj);
        let (wl, wt, wr, wb) = (wl as usize, wt as usize, wr as usize, wb as usize);
        let (w, h) = self.size();
        let (ox, oy) = self.origin(bi, bj);
        // The new block's pixels: x in lo_x[y]..=hi_x[y] of each row, y in lo_y[x]..=hi_y[x] of each column.
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (vec![0usize; b], vec![b - 1; b], vec![0usize; b], vec![b - 1; b]);
        if rule == OverlapRule::Cut && sides != Sides::default() {
            let old = self.window(&canvas.image, bi, bj);
            let e = |x: usize, y: usize| pixel_error(sample.get(src.0 + x as u32, src.1 + y as u32), old.get(x as u32, y as u32));
            if sides.left {
                lo_x = vertical_cut(&error_surface(sample, src, &old, (0, 0), wl as u32, self.block), b, wl);
            }
            if sides.right {
                let mirrored: Vec<u32> = (0..b).flat_map(|y| (0..wr).map(move |k| (y, k))).map(|(y, k)| e(b - 1 - k, y)).collect();
                hi_x = vertical_cut(&mirrored, b, wr).into_iter().map(|m| b - 1 - m).collect();
            }
            if sides.top {
                lo_y = horizontal_cut(&error_surface(sample, src, &old, (0, 0), self.block, wt as u32), wt, b);
            }
            if sides.bottom {
                let mirrored: Vec<u32> = (0..wb).flat_map(|k| (0..b).map(move |x| (k, x))).map(|(k, x)| e(x, b - 1 - k)).collect();
                hi_y = horizontal_cut(&mirrored, wb, b).into_iter().map(|m| b - 1 - m).collect();
            }
        }
        for y in 0..b {
            for x in 0..b {
                let (sx, sy) = (src.0 + x as u32, src.1 + y as u32);
                let (cx, cy) = ((ox + x as u32) % w, (oy + y as u32) % h);
                if rule == OverlapRule::Feather {
                    // The new block's weight from the nearest side with old content: the ramp
                    // `(k + 1) / (overlap + 1)` of each side, the smallest one winning (with even
                    // spacing all sides share the denominator, so the smaller k decides).
                    let mut weight: Option<(usize, usize)> = None;
                    let mut consider = |k: usize, width: usize| {
                        let (num, den) = (k + 1, width + 1);
                        if weight.is_none_or(|(n, d)| num * d < n * den) {
                            weight = Some((num, den));
                        }
                    };
                    if sides.left && x < wl {
                        consider(x, wl);
                    }
                    if sides.top && y < wt {
                        consider(y, wt);
                    }
                    if sides.right && x >= b - wr {
                        consider(b - 1 - x, wr);
                    }
                    if sides.bottom && y >= b - wb {
                        consider(b - 1 - y, wb);
                    }
                    match weight {
                        None => canvas.copy(cx, cy, sample, sx, sy),
                        Some((num, den)) => canvas.blend(cx, cy, sample, sx, sy, num as u32, den as u32),
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
        let bands = |origins: &[u32], overlap: &dyn Fn(u32) -> u32| -> Vec<SeamBand> {
            let n = origins.len() as u32;
            origins
                .iter()
                .enumerate()
                .map(|(k, &start)| {
                    // The band where column k starts overlaps the column before it.
                    let ov = overlap((k as u32 + n - 1) % n);
                    SeamBand { start: start.max(1), len: if start == 0 { ov } else { ov + 1 } }
                })
                .collect()
        };
        SeamGrid { columns: bands(&self.xs, &|k| self.overlap_x(k)), rows: bands(&self.ys, &|k| self.overlap_y(k)) }
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::rng::Stream;

    #[test]
    fn whole_strides_keep_the_even_grid_and_other_sizes_are_fitted() {
        let t = TorusGrid::new("quilting", 50, 8, 756, 504).unwrap();
        assert_eq!((t.cols, t.rows, t.size()), (18, 12, (756, 504)));
        assert!(t.is_even());
        assert_eq!(t.origin(2, 3), (126, 84));
        // 512 is not a multiple of 42: 13 columns, spacings 39 and 40, overlaps 10 and 11.
        for (w, h) in [(512, 512), (1024, 1024), (384, 320), (1000, 600), (2048, 2048), (100, 101)] {
            let t = TorusGrid::new("quilting", 50, 8, w, h).unwrap();
            assert_eq!(t.size(), (w, h));
            let xs: Vec<u32> = (0..t.cols).map(|k| t.spacing_x(k)).collect();
            let ys: Vec<u32> = (0..t.rows).map(|k| t.spacing_y(k)).collect();
            assert_eq!(xs.iter().sum::<u32>(), w);
            assert_eq!(ys.iter().sum::<u32>(), h);
            for v in [&xs, &ys] {
                let (lo, hi) = (*v.iter().min().unwrap(), *v.iter().max().unwrap());
                assert!(hi <= 42 && hi - lo <= 1 && lo >= 25, "{w}x{h}: {v:?}");
            }
            assert_eq!(t.is_even(), w % 42 == 0 && h % 42 == 0);
        }
        let t = TorusGrid::new("quilting", 50, 8, 512, 512).unwrap();
        assert_eq!(t.cols, 13);
        assert_eq!(t.describe()["x"]["overlap"], serde_json::json!([10, 11]));
        assert_eq!(t.column_at(0), 0);
        assert_eq!(t.column_at(t.origin(0, 5).0), 5);
        assert_eq!(t.column_at(t.origin(0, 5).0 - 1), 4);
        assert_eq!(t.column_at(511), 12);
        // Two blocks a side is the least: 50 pixels for block 50 (overlap 25 each way).
        assert_eq!(TorusGrid::new("quilting", 50, 8, 50, 50).unwrap().cols, 2);
        let e = TorusGrid::new("quilting", 50, 8, 49, 84).unwrap_err();
        assert!(e.contains("50 pixels a side") && e.contains("50x84 would work"), "{e}");
    }

    #[test]
    fn fitted_axes_spread_the_wider_spacings() {
        assert_eq!(fit_axis(84, 50, 42), Some(vec![0, 42]));
        assert_eq!(fit_axis(85, 50, 42), Some(vec![0, 28, 56]));
        assert_eq!(fit_axis(10, 3, 2), Some(vec![0, 2, 4, 6, 8]));
        let o = fit_axis(100, 20, 17).unwrap();
        assert_eq!(o.len(), 6);
        let spacings: Vec<u32> = o.windows(2).map(|w| w[1] - w[0]).chain([100 - o[5]]).collect();
        assert_eq!(spacings, vec![16, 17, 17, 16, 17, 17]);
        assert_eq!(fit_axis(19, 20, 17), None);
    }

    #[test]
    fn sides_and_regions_follow_what_is_done() {
        let t = TorusGrid::new("t", 20, 4, 64, 48).unwrap();
        let mut done = vec![false; (t.rows * t.cols) as usize];
        assert_eq!(t.sides(&done, 0, 0), Sides::default());
        for (bi, bj) in t.raster() {
            done[t.index(bi, bj)] = true;
        }
        let all = t.sides(&done, 1, 3);
        assert_eq!(all, Sides { left: true, top: true, right: true, bottom: true });
        let r = t.regions(1, 3, all);
        assert_eq!(r, vec![Rect::new(0, 0, 4, 20), Rect::new(4, 0, 12, 4), Rect::new(16, 0, 4, 20), Rect::new(4, 16, 12, 4)]);
        assert_eq!(r.iter().map(|r| r.area()).sum::<u64>(), 20 * 20 - 12 * 12);
        assert_eq!(
            t.regions(1, 3, Sides { left: true, top: true, ..Sides::default() }),
            vec![Rect::new(0, 0, 4, 20), Rect::new(4, 0, 16, 4)]
        );
    }

    /// In raster order and in the wave order, the pixels of a block already covered are exactly
    /// its side strips: no lone corner that the cut or the feather would not see.
    #[test]
    fn filled_pixels_are_the_side_strips_in_both_orders() {
        let evenly = [(2, 2), (2, 3), (3, 2), (3, 3), (4, 3), (5, 3), (5, 4), (7, 5)].map(|(c, r)| (c * 7, r * 7));
        let fitted = [(17, 14), (24, 31), (38, 23), (50, 51)];
        for (width, height) in evenly.into_iter().chain(fitted) {
            let t = TorusGrid::new("t", 10, 3, width, height).unwrap();
            let (cols, rows) = (t.cols, t.rows);
            let orders: [Vec<(u32, u32)>; 2] = [t.raster(), t.waves().concat()];
            for order in orders {
                let (w, h) = t.size();
                let mut filled = vec![false; (w * h) as usize];
                let mut done = vec![false; order.len()];
                for &(bi, bj) in &order {
                    let regions = t.regions(bi, bj, t.sides(&done, bi, bj));
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
        for (width, height) in [(14, 14), (21, 21), (28, 14), (35, 21), (63, 42), (17, 14), (38, 23), (64, 45)] {
            let t = TorusGrid::new("t", 10, 3, width, height).unwrap();
            let (cols, rows) = (t.cols, t.rows);
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
        let t = TorusGrid::new("t", 10, 4, 24, 12).unwrap();
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
