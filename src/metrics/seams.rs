//! Seam visibility: colour jumps at a block method's seam bands versus everywhere else.
//!
//! The jump across a pixel boundary is `|ΔR| + |ΔG| + |ΔB|` between the two adjacent pixels
//! (horizontal neighbours for a column boundary, vertical neighbours for a row boundary). Column
//! boundary `k` (between pixel columns `k − 1` and `k`, `1 ≤ k ≤ W − 1`) is a seam boundary for all
//! its `H` pixel pairs when `k` lies in one of the grid's column bands; row boundaries likewise.
//! Band entries outside `1..W` (`1..H`) are ignored. The value is
//! `mean jump over seam pairs / mean jump over all other pairs`, pooling both orientations; sums
//! and counts are exact integers.

use crate::image::RgbImage;
use crate::image::seam_grid::{SeamBand, SeamGrid};

fn band_mask(bands: &[SeamBand], n: usize) -> Vec<bool> {
    // mask[k] for boundary k in 0..=n; only 1..n are real boundaries.
    let mut mask = vec![false; n + 1];
    for b in bands {
        let start = b.start as u64;
        let end = (start + b.len as u64).min(n as u64);
        for k in start..end {
            mask[k as usize] = true;
        }
    }
    mask
}

#[inline]
fn jump(a: &[u8], b: &[u8]) -> u64 {
    (0..3).map(|c| (a[c] as i32 - b[c] as i32).unsigned_abs() as u64).sum()
}

/// Totals of the jumps: `(seam sum, seam pairs, other sum, other pairs)`.
pub fn seam_jump_totals(img: &RgbImage, grid: &SeamGrid) -> (u64, u64, u64, u64) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let cols = band_mask(&grid.columns, w);
    let rows = band_mask(&grid.rows, h);
    let (mut ss, mut sn, mut os, mut on) = (0u64, 0u64, 0u64, 0u64);
    for y in 0..h {
        let row = img.row(y as u32);
        for k in 1..w {
            let j = jump(&row[(k - 1) * 3..k * 3], &row[k * 3..k * 3 + 3]);
            if cols[k] {
                ss += j;
                sn += 1;
            } else {
                os += j;
                on += 1;
            }
        }
    }
    for (k, &is_seam) in rows.iter().enumerate().take(h).skip(1) {
        let above = img.row(k as u32 - 1);
        let below = img.row(k as u32);
        for x in 0..w {
            let j = jump(&above[x * 3..x * 3 + 3], &below[x * 3..x * 3 + 3]);
            if is_seam {
                ss += j;
                sn += 1;
            } else {
                os += j;
                on += 1;
            }
        }
    }
    (ss, sn, os, on)
}

/// Mean jump at the grid's seam boundaries divided by the mean jump at all other boundaries
/// (1 = seams invisible). `None` when there is no seam boundary inside the image, no other
/// boundary, or the other boundaries' mean jump is zero.
pub fn seam_visibility(output: &RgbImage, grid: &SeamGrid) -> Option<f64> {
    let (ss, sn, os, on) = seam_jump_totals(output, grid);
    if sn == 0 || on == 0 || os == 0 {
        return None;
    }
    Some((ss as f64 / sn as f64) / (os as f64 / on as f64))
}

/// How visible the wrap of a tileable output is: the mean jump across the wrap boundaries (last
/// column to first, last row to first: the seams of a 2×2 tiling) divided by the mean jump at all
/// boundaries inside the image (1 = the wrap looks like any other neighbour pair). Compare it
/// with [`seam_visibility`] of the method's interior seams. `None` for an image under 2×2 or
/// without any jump inside.
pub fn wrap_visibility(output: &RgbImage) -> Option<f64> {
    let (w, h) = (output.width() as usize, output.height() as usize);
    if w < 2 || h < 2 {
        return None;
    }
    let (mut ws, mut wn) = (0u64, 0u64);
    for y in 0..h {
        let row = output.row(y as u32);
        ws += jump(&row[(w - 1) * 3..w * 3], &row[0..3]);
        wn += 1;
    }
    let (first, last) = (output.row(0), output.row(h as u32 - 1));
    for x in 0..w {
        ws += jump(&last[x * 3..x * 3 + 3], &first[x * 3..x * 3 + 3]);
        wn += 1;
    }
    let (ss, sn, os, on) = seam_jump_totals(output, &SeamGrid { columns: Vec::new(), rows: Vec::new() });
    let (all_sum, all_pairs) = (ss + os, sn + on);
    if all_pairs == 0 || all_sum == 0 {
        return None;
    }
    Some((ws as f64 / wn as f64) / (all_sum as f64 / all_pairs as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_visibility_sees_a_broken_wrap() {
        // A horizontal ramp wraps with a jump of the whole range; a periodic pattern does not.
        let ramp = RgbImage::from_fn(16, 8, |x, _| [(x * 16) as u8; 3]);
        assert!(wrap_visibility(&ramp).unwrap() > 5.0);
        // A triangle wave of period 8: every horizontal step, the wrap included, is 30 levels.
        let periodic = RgbImage::from_fn(16, 8, |x, _| [((x % 8) as i32 - 4).unsigned_abs() as u8 * 30; 3]);
        assert!(wrap_visibility(&periodic).unwrap() <= 1.0);
    }

    fn grid(cols: &[(u32, u32)], rows: &[(u32, u32)]) -> SeamGrid {
        SeamGrid {
            columns: cols.iter().map(|&(start, len)| SeamBand { start, len }).collect(),
            rows: rows.iter().map(|&(start, len)| SeamBand { start, len }).collect(),
        }
    }

    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = seed;
        RgbImage::from_fn(w, h, |_, _| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let v = (s >> 40) as u32;
            [v as u8, (v >> 8) as u8, (v >> 16) as u8]
        })
    }

    #[test]
    fn no_seams_gives_about_one() {
        let img = noise(200, 200, 9);
        let g = grid(&[(40, 3), (80, 3), (120, 3)], &[(40, 3), (80, 3), (120, 3)]);
        let v = seam_visibility(&img, &g).unwrap();
        assert!((v - 1.0).abs() < 0.05, "{v}");
    }

    #[test]
    fn hard_step_along_a_band_is_visible() {
        // A smooth horizontal ramp with a hard step of 100 at column 50 (boundary 50).
        let img = RgbImage::from_fn(100, 60, |x, y| {
            let v = (x / 4 + y / 8) as u8 + if x >= 50 { 100 } else { 0 };
            [v, v, v]
        });
        let g = grid(&[(49, 3)], &[]);
        let v = seam_visibility(&img, &g).unwrap();
        assert!(v > 20.0, "{v}");
    }

    #[test]
    fn exact_value_and_undefined_cases() {
        // 3 × 2 image: column boundary 1 jumps by 3·10 per row, boundary 2 by 0, rows equal.
        let img = RgbImage::from_fn(3, 2, |x, _| if x == 0 { [0, 0, 0] } else { [10, 10, 10] });
        // Seam pairs: boundary 1 (2 pairs, 30 each); others: boundary 2 (2 × 0) + rows (3 × 0).
        assert_eq!(seam_visibility(&img, &grid(&[(1, 1)], &[])), None, "other jumps are all zero");
        let img = RgbImage::from_fn(3, 2, |x, y| [(x * 10) as u8, 0, (y * 4) as u8]);
        // Seam: boundary 1 → 2 pairs of 10. Others: boundary 2 → 2 pairs of 10, rows → 3 pairs of 4.
        let v = seam_visibility(&img, &grid(&[(1, 1)], &[])).unwrap();
        assert_eq!(v, 10.0 / (32.0 / 5.0));
        // No band inside the image / no grid bands at all.
        assert_eq!(seam_visibility(&img, &grid(&[(0, 1), (3, 5)], &[])), None);
        assert_eq!(seam_visibility(&img, &SeamGrid::default()), None);
    }
}
