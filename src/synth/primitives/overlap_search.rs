//! Exhaustive, exact best-match search for block methods: the SSD between the already-synthesised
//! overlap and the sample at *every* candidate position, and the set of candidates within a
//! tolerance of the best.
//!
//! Why it is fast: `SSD(p) = ΣS²(p) − 2·Σ S(p+q)·T(q) + ΣT²`. The first term comes exactly from an
//! integral image, the last is a constant, and the cross term for all positions at once is one
//! correlation, computed with FFTs (the sample's spectrum once per job, two forward and one
//! inverse 2-D FFT per block). Why it is still exact (docs/methods.md §6): the FFT values are only
//! used to find a small superset of the answer with a rigorous error margin; every member of that
//! superset is then re-scored with integer arithmetic (B1), and the minimum and the tolerance set
//! are decided on those exact integers. So the result is identical to brute force on every machine,
//! whatever FFT code path the CPU selects.

use super::overlap::{Rect, rect_ssd};
use crate::image::RgbImage;
use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Candidates whose exact SSD is within `(1 + tolerance)` of the minimum, in row-major order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Candidates {
    pub min_ssd: u64,
    /// `(x, y, ssd)` of each candidate, row-major (`y` outer, `x` inner).
    pub members: Vec<(u32, u32, u64)>,
}

/// The set rule shared by the fast and the brute-force paths (decided on exact integers).
#[inline]
fn within(ssd: u64, min: u64, tolerance: f64) -> bool {
    (ssd as f64) <= (1.0 + tolerance) * (min as f64)
}

/// Precomputed spectra of one sample for blocks of one size.
pub struct OverlapSearch<'a> {
    sample: &'a RgbImage,
    block_w: u32,
    block_h: u32,
    /// Spectrum of the complex plane R + iG, stored transposed (see `fft2`).
    spec_rg: Vec<Complex64>,
    /// Spectrum of the B plane, transposed.
    spec_b: Vec<Complex64>,
    /// Integral image of ΣR²+G²+B², `(W+1) × (H+1)`.
    integral_sq: Vec<u64>,
    /// √ of the sample's total energy, for the FFT error margin.
    sample_norm: f64,
    fft_row: Arc<dyn Fft<f64>>,
    fft_col: Arc<dyn Fft<f64>>,
    ifft_row: Arc<dyn Fft<f64>>,
    ifft_col: Arc<dyn Fft<f64>>,
    /// Reused buffers: allocating megabytes per block costs more than the FFTs.
    work: Workspace,
    /// ΣS² over each region set seen so far, per candidate position (exact integers as f64).
    sum_sq_maps: Vec<(Vec<Rect>, Vec<f64>)>,
}

#[derive(Default)]
struct Workspace {
    /// Template planes, only the first `block_h` rows (the rest of the plane is zero).
    rows_rg: Vec<Complex64>,
    rows_b: Vec<Complex64>,
    /// Transposed spectra of the templates (entries `block_h..H` of every row are the zero rows).
    spec_rg: Vec<Complex64>,
    spec_b: Vec<Complex64>,
    /// Product spectrum, then the correlation in row-major layout.
    product: Vec<Complex64>,
    plane: Vec<Complex64>,
    approx: Vec<f64>,
}

impl<'a> OverlapSearch<'a> {
    /// Prepares the search of `block_w × block_h` blocks in `sample` (which must be at least that big).
    pub fn new(sample: &'a RgbImage, block_w: u32, block_h: u32) -> OverlapSearch<'a> {
        let (w, h) = sample.dimensions();
        assert!(block_w <= w && block_h <= h, "block larger than the sample");
        let mut planner = FftPlanner::<f64>::new();
        let fft_row = planner.plan_fft_forward(w as usize);
        let fft_col = planner.plan_fft_forward(h as usize);
        let ifft_row = planner.plan_fft_inverse(w as usize);
        let ifft_col = planner.plan_fft_inverse(h as usize);
        let n = w as usize * h as usize;
        let raw = sample.as_raw();
        let mut rg = Vec::with_capacity(n);
        let mut b = Vec::with_capacity(n);
        for p in raw.chunks_exact(3) {
            rg.push(Complex64::new(p[0] as f64, p[1] as f64));
            b.push(Complex64::new(p[2] as f64, 0.0));
        }
        let mut search = OverlapSearch {
            sample,
            block_w,
            block_h,
            spec_rg: Vec::new(),
            spec_b: Vec::new(),
            integral_sq: integral_of_squares(sample),
            sample_norm: 0.0,
            fft_row,
            fft_col,
            ifft_row,
            ifft_col,
            work: Workspace::default(),
            sum_sq_maps: Vec::new(),
        };
        search.spec_rg = search.fft2(rg, h as usize);
        search.spec_b = search.fft2(b, h as usize);
        search.sample_norm = (search.integral_sq[search.integral_sq.len() - 1] as f64).sqrt();
        search
    }

    fn positions(&self) -> (u32, u32) {
        (self.sample.width() - self.block_w + 1, self.sample.height() - self.block_h + 1)
    }

    /// Forward 2-D FFT of a `W × H` plane whose rows `nonzero_rows..H` are zero (they are skipped).
    /// The result is left transposed (`H`-long rows, one per column frequency): products of two
    /// spectra in the same layout are all that is needed, and `ifft2` undoes the transposition.
    fn fft2(&self, mut plane: Vec<Complex64>, nonzero_rows: usize) -> Vec<Complex64> {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        process_rows(&self.fft_row, &mut plane[..w * nonzero_rows], w);
        let mut t = transpose(&plane, w, h);
        process_rows(&self.fft_col, &mut t, h);
        t
    }

    fn region_sum_sq(&self, x: u32, y: u32, r: &Rect) -> u64 {
        let stride = self.sample.width() as usize + 1;
        let (x0, y0) = ((x + r.x) as usize, (y + r.y) as usize);
        let (x1, y1) = (x0 + r.w as usize, y0 + r.h as usize);
        let ii = &self.integral_sq;
        ii[y1 * stride + x1] + ii[y0 * stride + x0] - ii[y0 * stride + x1] - ii[y1 * stride + x0]
    }

    /// Exact SSD of the candidate at `(x, y)`: the block's `regions` (disjoint rectangles relative
    /// to the block origin) against `target` at `origin`.
    pub fn exact_ssd(&self, x: u32, y: u32, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> u64 {
        regions.iter().map(|r| rect_ssd(self.sample, x + r.x, y + r.y, target, origin.0 + r.x, origin.1 + r.y, r.w, r.h)).sum()
    }

    /// Every candidate position's exact SSD by direct summation (row-major). The reference the fast
    /// path is tested against; also the fallback when there are no regions.
    pub fn all_ssd_direct(&self, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> Vec<u64> {
        let (nx, ny) = self.positions();
        (0..ny)
            .into_par_iter()
            .flat_map_iter(|y| (0..nx).map(move |x| (x, y)).collect::<Vec<_>>())
            .map(|(x, y)| self.exact_ssd(x, y, target, origin, regions))
            .collect()
    }

    /// The candidate set by brute force.
    pub fn candidates_direct(&self, target: &RgbImage, origin: (u32, u32), regions: &[Rect], tolerance: f64) -> Candidates {
        let (nx, _) = self.positions();
        let all = self.all_ssd_direct(target, origin, regions);
        let min = all.iter().copied().min().expect("at least one candidate");
        let members = all
            .iter()
            .enumerate()
            .filter(|(_, s)| within(**s, min, tolerance))
            .map(|(i, s)| ((i as u32) % nx, (i as u32) / nx, *s))
            .collect();
        Candidates { min_ssd: min, members }
    }

    /// The candidate set, fast and exact (see the module comment). `regions` are disjoint
    /// rectangles inside the block; `target` holds the already-synthesised pixels at
    /// `origin + region`.
    pub fn candidates(&mut self, target: &RgbImage, origin: (u32, u32), regions: &[Rect], tolerance: f64) -> Candidates {
        let total_area: u64 = regions.iter().map(|r| r.area()).sum();
        if total_area == 0 {
            return self.candidates_direct(target, origin, regions, tolerance);
        }
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let (nx, ny) = self.positions();
        let (nxu, nyu) = (nx as usize, ny as usize);
        let rows = self.block_h as usize;
        let map_index = self.sum_sq_map(regions);
        let mut work = std::mem::take(&mut self.work);
        if work.spec_rg.len() != w * h {
            work.rows_rg = vec![Complex64::new(0.0, 0.0); w * rows];
            work.rows_b = vec![Complex64::new(0.0, 0.0); w * rows];
            work.spec_rg = vec![Complex64::new(0.0, 0.0); w * h];
            work.spec_b = vec![Complex64::new(0.0, 0.0); w * h];
            work.product = vec![Complex64::new(0.0, 0.0); w * h];
            work.plane = vec![Complex64::new(0.0, 0.0); w * h];
            work.approx = vec![0.0; nxu * nyu];
        }
        // Template planes: the target's overlap pixels at their block offsets, zero elsewhere.
        work.rows_rg.fill(Complex64::new(0.0, 0.0));
        work.rows_b.fill(Complex64::new(0.0, 0.0));
        let mut sum_t2: u64 = 0;
        for r in regions {
            for dy in 0..r.h {
                for dx in 0..r.w {
                    let p = target.get(origin.0 + r.x + dx, origin.1 + r.y + dy);
                    let i = (r.y + dy) as usize * w + (r.x + dx) as usize;
                    work.rows_rg[i] = Complex64::new(p[0] as f64, p[1] as f64);
                    work.rows_b[i] = Complex64::new(p[2] as f64, 0.0);
                    sum_t2 += p.iter().map(|&c| c as u64 * c as u64).sum::<u64>();
                }
            }
        }
        // Forward 2-D FFTs of the templates: rows (only the non-zero ones), then columns.
        for (plane, spec) in [(&mut work.rows_rg, &mut work.spec_rg), (&mut work.rows_b, &mut work.spec_b)] {
            process_rows(&self.fft_row, plane, w);
            // The column pass of the previous block filled whole rows: clear their zero tails.
            for row in spec.chunks_exact_mut(h) {
                row[rows..].fill(Complex64::new(0.0, 0.0));
            }
            transpose_into(plane, w, rows, spec, h);
            process_rows(&self.fft_col, spec, h);
        }
        // Σ_c S_c ⋆ T_c = Re IFFT( F(R+iG)·conj F(Tr+iTg) + F(B)·conj F(Tb) ).
        for (((p, s1), t1), (s2, t2)) in
            work.product.iter_mut().zip(&self.spec_rg).zip(&work.spec_rg).zip(self.spec_b.iter().zip(&work.spec_b))
        {
            *p = s1 * t1.conj() + s2 * t2.conj();
        }
        // Inverse: columns, then only the rows that hold candidate positions.
        process_rows(&self.ifft_col, &mut work.product, h);
        transpose_into(&work.product, h, w, &mut work.plane[..nyu * w], w);
        process_rows(&self.ifft_row, &mut work.plane[..nyu * w], w);
        let scale = 1.0 / (w * h) as f64;

        // approx(p) = ΣS²(p) − 2·corr(p) + ΣT², within `margin` of the exact SSD. The margin is a
        // generous bound on the FFT's absolute error (the usual one is ~1e-16·log n·‖S‖‖T‖).
        let margin = 1e-9 * self.sample_norm * (sum_t2 as f64).sqrt() * ((w * h) as f64).log2().max(1.0) + 1.0;
        let sum_sq = &self.sum_sq_maps[map_index].1;
        let plane = &work.plane;
        work.approx.par_chunks_mut(nxu).enumerate().for_each(|(y, row)| {
            let corr = &plane[y * w..y * w + nxu];
            let s2 = &sum_sq[y * nxu..(y + 1) * nxu];
            for ((a, c), s) in row.iter_mut().zip(corr).zip(s2) {
                *a = s - 2.0 * c.re * scale + sum_t2 as f64;
            }
        });
        let amin = work.approx.iter().copied().fold(f64::INFINITY, f64::min);
        let threshold = (1.0 + tolerance) * (amin + margin) + margin;
        let approx = &work.approx;
        let this = &*self;
        let rechecked: Vec<(u32, u32, u64)> = (0..ny)
            .into_par_iter()
            .flat_map_iter(|y| {
                let row = &approx[y as usize * nxu..(y as usize + 1) * nxu];
                row.iter()
                    .enumerate()
                    .filter(|(_, a)| **a <= threshold)
                    .map(|(x, _)| (x as u32, y, this.exact_ssd(x as u32, y, target, origin, regions)))
                    .collect::<Vec<_>>()
            })
            .collect();
        self.work = work;
        let min = rechecked.iter().map(|c| c.2).min().expect("the best candidate is always rechecked");
        let members = rechecked.into_iter().filter(|c| within(c.2, min, tolerance)).collect();
        Candidates { min_ssd: min, members }
    }

    /// Index of the ΣS² map for this region set, computing it the first time (exactly, from the
    /// integral image; there are only a handful of distinct region sets per job).
    fn sum_sq_map(&mut self, regions: &[Rect]) -> usize {
        if let Some(i) = self.sum_sq_maps.iter().position(|(r, _)| r == regions) {
            return i;
        }
        let (nx, ny) = self.positions();
        let map: Vec<f64> = (0..ny)
            .flat_map(|y| (0..nx).map(move |x| (x, y)))
            .map(|(x, y)| regions.iter().map(|r| self.region_sum_sq(x, y, r)).sum::<u64>() as f64)
            .collect();
        self.sum_sq_maps.push((regions.to_vec(), map));
        self.sum_sq_maps.len() - 1
    }
}

fn process_rows(fft: &Arc<dyn Fft<f64>>, data: &mut [Complex64], len: usize) {
    // Fixed-size chunks: each row's transform is independent of how rows are grouped.
    const ROWS_PER_TASK: usize = 16;
    data.par_chunks_mut(len * ROWS_PER_TASK).for_each(|chunk| fft.process(chunk));
}

fn transpose(src: &[Complex64], w: usize, h: usize) -> Vec<Complex64> {
    let mut dst = vec![Complex64::new(0.0, 0.0); w * h];
    transpose_into(src, w, h, &mut dst, h);
    dst
}

/// Writes the transpose of the `w × h` row-major `src` into `dst`, whose rows are `dst_stride`
/// long: `dst[x·dst_stride + y] = src[y·w + x]` for `y < min(h, dst_stride)`; other entries of
/// `dst` are left untouched. Also used to read only the first rows of a transposed result.
fn transpose_into(src: &[Complex64], w: usize, h: usize, dst: &mut [Complex64], dst_stride: usize) {
    const T: usize = 16;
    let h_used = h.min(dst_stride);
    let rows_out = dst.len() / dst_stride;
    let w_used = w.min(rows_out);
    for by in (0..h_used).step_by(T) {
        for bx in (0..w_used).step_by(T) {
            for x in bx..(bx + T).min(w_used) {
                let d = &mut dst[x * dst_stride..x * dst_stride + dst_stride];
                for y in by..(by + T).min(h_used) {
                    d[y] = src[y * w + x];
                }
            }
        }
    }
}

fn integral_of_squares(img: &RgbImage) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let stride = w + 1;
    let mut ii = vec![0u64; stride * (h + 1)];
    for y in 0..h {
        let row = img.row(y as u32);
        let mut run = 0u64;
        for x in 0..w {
            let p = &row[x * 3..x * 3 + 3];
            run += p.iter().map(|&c| c as u64 * c as u64).sum::<u64>();
            ii[(y + 1) * stride + x + 1] = ii[y * stride + x + 1] + run;
        }
    }
    ii
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::rng::Stream;

    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = Stream::new(seed, "test/noise");
        RgbImage::from_fn(w, h, |_, _| [s.below(256) as u8, s.below(256) as u8, s.below(256) as u8])
    }

    #[test]
    fn fast_candidates_equal_brute_force() {
        for (sw, sh, b, ov, tol, seed) in [(64, 48, 12, 3, 0.1, 1), (37, 41, 10, 4, 0.0, 2), (50, 50, 16, 5, 0.5, 3)] {
            let sample = noise(sw, sh, seed);
            // The target is partly a copy of the sample so that there is a strong best match.
            let mut target = noise(60, 60, seed + 10);
            for y in 0..b {
                for x in 0..ov {
                    target.put(20 + x, 20 + y, sample.get(5 + x, 7 + y));
                }
            }
            let regions = [Rect::new(0, 0, ov, b), Rect::new(ov, 0, b - ov, ov)];
            let mut search = OverlapSearch::new(&sample, b, b);
            let fast = search.candidates(&target, (20, 20), &regions, tol);
            let slow = search.candidates_direct(&target, (20, 20), &regions, tol);
            assert_eq!(fast, slow, "{sw}x{sh} block {b}");
        }
    }

    #[test]
    fn a_reused_search_stays_exact_across_blocks_and_region_sets() {
        let sample = noise(70, 64, 21);
        let target = noise(120, 120, 22);
        let mut search = OverlapSearch::new(&sample, 20, 20);
        let shapes: [&[Rect]; 3] =
            [&[Rect::new(0, 0, 5, 20)], &[Rect::new(0, 0, 20, 5)], &[Rect::new(0, 0, 5, 20), Rect::new(5, 0, 15, 5)]];
        for k in 0..9u32 {
            let regions = shapes[(k % 3) as usize];
            let origin = (k * 9, 100 - k * 7);
            let fast = search.candidates(&target, origin, regions, 0.05 * k as f64);
            assert_eq!(fast, search.candidates_direct(&target, origin, regions, 0.05 * k as f64), "call {k}");
        }
    }

    #[test]
    fn a_unique_exact_match_is_found_with_zero_error() {
        let sample = noise(40, 40, 9);
        let target = sample.crop(10, 12, 20, 20);
        let regions = [Rect::new(0, 0, 4, 12), Rect::new(4, 0, 8, 4)];
        let mut search = OverlapSearch::new(&sample, 12, 12);
        let c = search.candidates(&target, (0, 0), &regions, 0.1);
        assert_eq!(c.min_ssd, 0);
        assert_eq!(c.members, vec![(10, 12, 0)]);
    }

    #[test]
    fn integral_image_sums_match_direct_sums() {
        let img = noise(9, 7, 4);
        let search = OverlapSearch::new(&img, 3, 3);
        let r = Rect::new(1, 2, 3, 2);
        let direct: u64 = (0..2)
            .flat_map(|dy| (0..3).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| img.get(2 + 1 + dx, 1 + 2 + dy).iter().map(|&c| c as u64 * c as u64).sum::<u64>())
            .sum();
        assert_eq!(search.region_sum_sq(2, 1, &r), direct);
    }
}
