//! Exhaustive, exact best-match search for block methods: the SSD between the already-synthesised
//! overlap and the sample at *every* candidate position, and the set of candidates within a
//! tolerance of the best.
//!
//! Why it is fast: `SSD(p) = ΣS²(p) − 2·Σ S(p+q)·T(q) + ΣT²`. The first term comes exactly from an
//! integral image, the last is a constant, and the cross term for all positions at once is one
//! correlation, computed with FFTs: the sample's three channel spectra once per job; per block,
//! the template's three real channels forward and one real inverse. Every plane is real, so only
//! half of each spectrum is kept (`kx ≤ W/2`), and two real rows share one complex row transform. Why it is still exact (docs/methods.md §6): the FFT values are only
//! used to find a small superset of the answer with a rigorous error margin; every member of that
//! superset is then re-scored with integer arithmetic (B1), and the minimum and the tolerance set
//! are decided on those exact integers. So the result is identical to brute force on every machine,
//! whatever FFT code path the CPU selects.

use super::overlap::{Rect, rect_ssd};
use super::simd::with_avx2;
use crate::image::RgbImage;
use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::borrow::Cow;
use std::sync::Arc;

/// How many ΣS² maps (one per distinct region set) a search keeps.
const MAX_CACHED_MAPS: usize = 16;

/// From how many rectangles a single search whose region set has no cached ΣS² map takes ΣS² by
/// FFT, correlating the per-pixel ΣS² with the regions' mask, instead of making the map: a hole
/// fill's region sets are dozens of row runs, new at every block, and the map costs a pass over
/// every position per corner; a grid method's few region sets keep their exact maps.
const MASK_BY_FFT_FROM: usize = 8;

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
    /// Borrowed from the method, or owned when the searched image is one the caller made (a
    /// pyramid's coarse level, `primitives::pyramid_search`).
    sample: Cow<'a, RgbImage>,
    block_w: u32,
    block_h: u32,
    /// What does not depend on the block size (spectra, integral image, plans), shared by the
    /// searches of one sample for blocks of other sizes ([`OverlapSearch::for_block`]).
    shared: Arc<Spectra>,
    /// Reused buffers: allocating megabytes per block costs more than the FFTs.
    work: Workspace,
    /// One more workspace per concurrent task of `candidates_many`, kept between calls.
    spare_work: Vec<Workspace>,
    /// ΣS² over each region set seen so far, per candidate position (exact integers as f64).
    sum_sq_maps: Vec<(Vec<Rect>, Vec<f64>)>,
    /// The positions a candidate may come from (row-major flags; a sample mask), or all.
    allowed: Option<Vec<bool>>,
}

/// The block-size-independent part of an [`OverlapSearch`]: one sample's spectra, integral image
/// and FFT plans. Searches for blocks of different sizes over one sample (an inpainting's fill
/// and its border polish) share it instead of transforming the sample again.
struct Spectra {
    /// Half spectra of the R, G and B planes, laid out as `forward_real` leaves them.
    spec: Vec<Complex64>,
    /// Integral image of ΣR²+G²+B², `(W+1) × (H+1)`.
    integral_sq: Vec<u64>,
    /// √ of the sample's total energy, for the FFT error margin.
    sample_norm: f64,
    fft_row: Arc<dyn Fft<f64>>,
    fft_col: Arc<dyn Fft<f64>>,
    ifft_row: Arc<dyn Fft<f64>>,
    ifft_col: Arc<dyn Fft<f64>>,
    /// Whether every sample pixel is gray (R = G = B), as guided synthesis's guides are: against
    /// a gray template the three channels' correlations are equal, so one is computed, tripled.
    gray: bool,
    /// The half spectrum of the per-pixel ΣS² plane (R²+G²+B²) and its norm, for ΣS² by FFT
    /// ([`MASK_BY_FFT_FROM`]); made the first time it is needed.
    spec_sq: std::sync::OnceLock<(Vec<Complex64>, f64)>,
}

#[derive(Default)]
struct Workspace {
    /// The template's R, G and B planes, only the first `block_h` rows (the rest is zero).
    planes: Vec<f64>,
    /// Template row pairs packed as one complex row each, for the forward row transforms, and
    /// their transpose.
    pairs: Vec<Complex64>,
    by_frequency: Vec<Complex64>,
    /// Output row pairs, likewise, for the inverse row transforms.
    rows: Vec<Complex64>,
    /// The summed cross-correlation's half spectrum, transformed back along columns.
    product: Vec<Complex64>,
    /// Template columns (one per plane, up to four) and the column transforms' scratch.
    column: Vec<Complex64>,
    fft_scratch: Vec<Complex64>,
    approx: Vec<f64>,
}

impl<'a> OverlapSearch<'a> {
    /// Prepares the search of `block_w × block_h` blocks in `sample` (which must be at least that big).
    pub fn new(sample: &'a RgbImage, block_w: u32, block_h: u32) -> OverlapSearch<'a> {
        OverlapSearch::of(Cow::Borrowed(sample), block_w, block_h)
    }

    /// [`OverlapSearch::new`] over an image the search keeps.
    pub fn owning(sample: RgbImage, block_w: u32, block_h: u32) -> OverlapSearch<'static> {
        OverlapSearch::of(Cow::Owned(sample), block_w, block_h)
    }

    fn of(sample: Cow<'a, RgbImage>, block_w: u32, block_h: u32) -> OverlapSearch<'a> {
        let (w, h) = sample.dimensions();
        assert!(block_w <= w && block_h <= h, "block larger than the sample");
        let mut planner = FftPlanner::<f64>::new();
        let fft_row = planner.plan_fft_forward(w as usize);
        let fft_col = planner.plan_fft_forward(h as usize);
        let ifft_row = planner.plan_fft_inverse(w as usize);
        let ifft_col = planner.plan_fft_inverse(h as usize);
        let (wu, hu) = (w as usize, h as usize);
        let mut planes = vec![0.0; 3 * wu * hu];
        for (i, p) in sample.as_raw().chunks_exact(3).enumerate() {
            for (c, &v) in p.iter().enumerate() {
                planes[c * wu * hu + i] = v as f64;
            }
        }
        let integral_sq = integral_of_squares(&sample);
        let gray = sample.as_raw().chunks_exact(3).all(|p| p[0] == p[1] && p[1] == p[2]);
        let sample_norm = (integral_sq[integral_sq.len() - 1] as f64).sqrt();
        let mut search = OverlapSearch {
            sample,
            block_w,
            block_h,
            shared: Arc::new(Spectra {
                spec: Vec::new(),
                integral_sq,
                sample_norm,
                fft_row,
                fft_col,
                ifft_row,
                ifft_col,
                gray,
                spec_sq: std::sync::OnceLock::new(),
            }),
            work: Workspace::default(),
            spare_work: Vec::new(),
            sum_sq_maps: Vec::new(),
            allowed: None,
        };
        let mut spec = vec![Complex64::new(0.0, 0.0); 3 * (wu / 2 + 1) * hu];
        search.forward_real(&planes, hu, &mut Vec::new(), &mut spec, true);
        Arc::get_mut(&mut search.shared).expect("not shared yet").spec = spec;
        search
    }

    /// The search of `block_w × block_h` blocks over the same sample, sharing its spectra (no
    /// transform of the sample again); unrestricted, with its own caches and workspace.
    pub fn for_block(&self, block_w: u32, block_h: u32) -> OverlapSearch<'a> {
        let (w, h) = self.sample.dimensions();
        assert!(block_w <= w && block_h <= h, "block larger than the sample");
        OverlapSearch {
            sample: self.sample.clone(),
            block_w,
            block_h,
            shared: Arc::clone(&self.shared),
            work: Workspace::default(),
            spare_work: Vec::new(),
            sum_sq_maps: Vec::new(),
            allowed: None,
        }
    }

    /// Restricts the candidate sets ([`OverlapSearch::candidates`] and the like) to the positions
    /// flagged in `allowed` (row-major over the block positions; at least one), as a sample mask
    /// asks. The minimum and the tolerance set are those of the allowed positions alone.
    pub fn restrict_to(&mut self, allowed: Vec<bool>) {
        let (nx, ny) = self.positions();
        assert_eq!(allowed.len(), nx as usize * ny as usize, "one flag per block position");
        assert!(allowed.contains(&true), "at least one allowed position");
        self.allowed = Some(allowed);
    }

    /// Whether a candidate may come from `(x, y)`.
    fn allows(&self, x: u32, y: u32) -> bool {
        self.allowed.as_ref().is_none_or(|a| a[(y * self.positions().0 + x) as usize])
    }

    /// The searched image.
    pub fn sample(&self) -> &RgbImage {
        &self.sample
    }

    fn positions(&self) -> (u32, u32) {
        (self.sample.width() - self.block_w + 1, self.sample.height() - self.block_h + 1)
    }

    /// Row transforms of three real `W`-wide planes (`planes`: channel, then row, then column),
    /// two real rows `a`, `b` per complex row `a + ib`; `half_spectrum_at` separates them.
    fn transform_row_pairs(&self, planes: &[f64], pairs: &mut Vec<Complex64>, parallel: bool) {
        let w = self.sample.width() as usize;
        // Every entry of `pairs` is written below, so it is only resized, never cleared.
        pairs.resize((planes.len() / w).div_ceil(2) * w, Complex64::new(0.0, 0.0));
        for (p, row) in pairs.chunks_exact_mut(w).enumerate() {
            let a = &planes[2 * p * w..(2 * p + 1) * w];
            match planes.get((2 * p + 1) * w..(2 * p + 2) * w) {
                Some(b) => row.iter_mut().zip(a.iter().zip(b)).for_each(|(z, (&a, &b))| *z = Complex64::new(a, b)),
                None => row.iter_mut().zip(a).for_each(|(z, &a)| *z = Complex64::new(a, 0.0)),
            }
        }
        process_rows(&self.shared.fft_row, pairs, w, parallel);
    }

    /// Half spectra (`kx ≤ W/2`) of three real `W × H` planes given by their first
    /// `nonzero_rows` rows (`planes`: channel, then row, then column; the other rows are zero),
    /// left in `spec` as channel, then `kx`, then `ky`: one contiguous column per frequency, which
    /// is the layout the column transforms need and all that products of spectra need.
    fn forward_real(&self, planes: &[f64], nonzero_rows: usize, pairs: &mut Vec<Complex64>, spec: &mut [Complex64], parallel: bool) {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let half = w / 2 + 1;
        let real_rows = planes.len() / w;
        self.transform_row_pairs(planes, pairs, parallel);
        for column in spec.chunks_exact_mut(h) {
            column[nonzero_rows..].fill(Complex64::new(0.0, 0.0));
        }
        // Scattered into columns a few frequencies at a time, so that the writes stay in cache.
        const FREQUENCIES_PER_PASS: usize = 16;
        for k0 in (0..half).step_by(FREQUENCIES_PER_PASS) {
            for r in 0..real_rows {
                let (channel, y) = (r / nonzero_rows, r % nonzero_rows);
                let base = channel * half * h + y;
                for k in k0..(k0 + FREQUENCIES_PER_PASS).min(half) {
                    spec[base + k * h] = half_spectrum_at(pairs, w, r, k);
                }
            }
        }
        process_rows(&self.shared.fft_col, spec, h, parallel);
    }

    /// Column `kx` of the summed cross-correlation's half spectrum, `Σ_c Ŝ_c·conj T̂_c` (over the
    /// first `channels`), into `out` (the caller transforms it back along `y`); `by_frequency` holds the template's row-pair
    /// transforms transposed (all pairs at frequency 0, then at 1, …), so a column reads two runs. The template's column of each channel is
    /// transformed in `columns` (room for four) just before the product: a few columns at a time stay in cache,
    /// where whole template spectra would not.
    fn correlate_column(
        &self,
        by_frequency: &[Complex64],
        rows: usize,
        channels: usize,
        mask: bool,
        kx: usize,
        out: &mut [Complex64],
        columns: &mut [Complex64],
        fft_scratch: &mut [Complex64],
    ) {
        // Its loops with AVX2's wider vectors where the CPU has them (the same bits either way).
        with_avx2(
            #[inline(always)]
            || self.correlate_column_here(by_frequency, rows, channels, mask, kx, out, columns, fft_scratch),
        )
    }

    /// [`OverlapSearch::correlate_column`]'s work.
    #[inline(always)]
    fn correlate_column_here(
        &self,
        by_frequency: &[Complex64],
        rows: usize,
        channels: usize,
        mask: bool,
        kx: usize,
        out: &mut [Complex64],
        columns: &mut [Complex64],
        fft_scratch: &mut [Complex64],
    ) {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let plane = (w / 2 + 1) * h;
        let pair_count = by_frequency.len() / w;
        let at = &by_frequency[kx * pair_count..(kx + 1) * pair_count];
        let mirrored = &by_frequency[(w - kx) % w * pair_count..((w - kx) % w + 1) * pair_count];
        let planes = channels + usize::from(mask);
        for (c, column) in columns.chunks_exact_mut(h).take(planes).enumerate() {
            for (y, v) in column[..rows].iter_mut().enumerate() {
                let r = c * rows + y;
                let (z, m) = (at[r / 2], mirrored[r / 2].conj());
                *v = if r % 2 == 1 { (z - m) * Complex64::new(0.0, -0.5) } else { (z + m) * 0.5 };
            }
            column[rows..].fill(Complex64::new(0.0, 0.0));
            self.shared.fft_col.process_with_scratch(column, fft_scratch);
        }
        // One pass over the column for all planes, summed in channel order, then the mask's
        // plane: −½ · (ΣS² ⋆ mask), so that the caller's −2 × the sum gives +ΣS² over the regions.
        // (The same operations in the same order as a pass per plane, so the same bits.)
        // Every slice is cut to `h` first, so that the indexed loops need no bounds checks.
        let sample = |c: usize| &self.shared.spec[c * plane + kx * h..c * plane + (kx + 1) * h];
        let template = |c: usize| &columns[c * h..(c + 1) * h];
        let out = &mut out[..h];
        match (channels, mask) {
            (1, false) => out.iter_mut().zip(sample(0).iter().zip(template(0))).for_each(|(o, (s, t))| *o = s * t.conj()),
            (3, _) => {
                let (s0, s1, s2) = (sample(0), sample(1), sample(2));
                let (t0, t1, t2) = (template(0), template(1), template(2));
                if mask {
                    let (sq, t3) = (&self.spec_sq().0[kx * h..(kx + 1) * h], template(3));
                    for y in 0..h {
                        let mut v = s0[y] * t0[y].conj();
                        v += s1[y] * t1[y].conj();
                        v += s2[y] * t2[y].conj();
                        v -= sq[y] * t3[y].conj() * 0.5;
                        out[y] = v;
                    }
                } else {
                    for y in 0..h {
                        let mut v = s0[y] * t0[y].conj();
                        v += s1[y] * t1[y].conj();
                        v += s2[y] * t2[y].conj();
                        out[y] = v;
                    }
                }
            }
            _ => unreachable!("one gray channel, or three with or without the mask"),
        }
    }

    /// [`OverlapSearch::spec_sq`]'s spectrum and norm, made on first use.
    fn spec_sq(&self) -> &(Vec<Complex64>, f64) {
        self.shared.spec_sq.get_or_init(|| {
            let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
            let plane: Vec<f64> =
                self.sample.as_raw().chunks_exact(3).map(|p| p.iter().map(|&c| f64::from(c) * f64::from(c)).sum()).collect();
            let norm = plane.iter().map(|v| v * v).sum::<f64>().sqrt();
            let mut spec = vec![Complex64::new(0.0, 0.0); (w / 2 + 1) * h];
            self.forward_real(&plane, h, &mut Vec::new(), &mut spec, false);
            (spec, norm)
        })
    }

    #[cfg(test)]
    fn region_sum_sq(&self, x: u32, y: u32, r: &Rect) -> u64 {
        let stride = self.sample.width() as usize + 1;
        let (x0, y0) = ((x + r.x) as usize, (y + r.y) as usize);
        let (x1, y1) = (x0 + r.w as usize, y0 + r.h as usize);
        let ii = &self.shared.integral_sq;
        ii[y1 * stride + x1] + ii[y0 * stride + x0] - ii[y0 * stride + x1] - ii[y1 * stride + x0]
    }

    /// Exact SSD of the candidate at `(x, y)`: the block's `regions` (disjoint rectangles relative
    /// to the block origin) against `target` at `origin`.
    pub fn exact_ssd(&self, x: u32, y: u32, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> u64 {
        regions.iter().map(|r| rect_ssd(&self.sample, x + r.x, y + r.y, target, origin.0 + r.x, origin.1 + r.y, r.w, r.h)).sum()
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
        let allowed = |i: usize| self.allowed.as_ref().is_none_or(|a| a[i]);
        let min = all.iter().enumerate().filter(|(i, _)| allowed(*i)).map(|(_, s)| *s).min().expect("at least one candidate");
        let members = all
            .iter()
            .enumerate()
            .filter(|(i, s)| allowed(*i) && within(**s, min, tolerance))
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
        // A grid method sees a handful of region sets; a hole fill sees a new one per block. Past
        // a bound the cache starts again, so that its memory stays a few maps. (Only here, between
        // searches: the batched searches hold indices into it while they run.)
        let cached = self.sum_sq_maps.iter().any(|(r, _)| r == regions);
        let map_index = if !cached && regions.len() >= MASK_BY_FFT_FROM {
            None
        } else {
            if self.sum_sq_maps.len() >= MAX_CACHED_MAPS && !cached {
                self.sum_sq_maps.clear();
            }
            Some(self.sum_sq_map(regions))
        };
        let mut work = std::mem::take(&mut self.work);
        let parallel = rayon::current_num_threads() > 1;
        let found = self.search_fft(&mut work, target, origin, regions, map_index, tolerance, parallel);
        self.work = work;
        found
    }

    /// Every position's approximate SSD (row-major, by FFT correlation) and the bound on its
    /// error, for a search that weighs this error with another before deciding among positions
    /// on exact values ([`OverlapSearch::exact_ssd`]), as guided synthesis does. All zero with a
    /// zero bound when `regions` are empty.
    pub fn approximate_all(&mut self, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> (Vec<f64>, f64) {
        let (nx, ny) = self.positions();
        match self.approximate_in_place(target, origin, regions) {
            Some((approx, margin)) => (approx.to_vec(), margin),
            None => (vec![0.0; nx as usize * ny as usize], 0.0),
        }
    }

    /// [`OverlapSearch::approximate_all`] without the copy: the map lives in the search's
    /// workspace until its next search. `None` when `regions` are empty (every SSD is zero then).
    pub fn approximate_in_place(&mut self, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> Option<(&[f64], f64)> {
        if regions.iter().map(|r| r.area()).sum::<u64>() == 0 {
            return None;
        }
        if self.sum_sq_maps.len() >= MAX_CACHED_MAPS && !self.sum_sq_maps.iter().any(|(r, _)| r == regions) {
            self.sum_sq_maps.clear();
        }
        let map_index = self.sum_sq_map(regions);
        let mut work = std::mem::take(&mut self.work);
        let parallel = rayon::current_num_threads() > 1;
        let margin = self.approximate(&mut work, target, origin, regions, Some(map_index), parallel);
        self.work = work;
        Some((&self.work.approx, margin))
    }

    /// `ka · SSD_a + kb · SSD_b` at every position, approximately, into `out`, and the bound on
    /// its error: two searches' maps ([`OverlapSearch::approximate_in_place`]) weighed and summed,
    /// as guided synthesis weighs its texture and guide errors. The correlations are weighed and
    /// summed in the frequency domain, so that one inverse transform serves both (the searches
    /// must be over images of one size, for blocks of one size; the regions must not be empty).
    /// The result differs from weighing the two maps by rounding only; the bound is the weighed
    /// sum of theirs, which is generous (see [`OverlapSearch::approximate`]).
    #[allow(clippy::too_many_arguments)]
    pub fn approximate_weighted(
        a: &mut OverlapSearch,
        ka: f64,
        (target_a, origin_a, regions_a): (&RgbImage, (u32, u32), &[Rect]),
        b: &mut OverlapSearch,
        kb: f64,
        (target_b, origin_b, regions_b): (&RgbImage, (u32, u32), &[Rect]),
        out: &mut Vec<f64>,
    ) -> f64 {
        assert_eq!(a.sample.dimensions(), b.sample.dimensions(), "searches over images of one size");
        assert_eq!((a.block_w, a.block_h), (b.block_w, b.block_h), "searches for blocks of one size");
        let maps = [a.cached_sum_sq_map(regions_a), b.cached_sum_sq_map(regions_b)];
        let parallel = rayon::current_num_threads() > 1;
        let (mut wa, mut wb) = (std::mem::take(&mut a.work), std::mem::take(&mut b.work));
        let (t2a, channels_a) = a.template(&mut wa, target_a, origin_a, regions_a, false, parallel);
        let (t2b, channels_b) = b.template(&mut wb, target_b, origin_b, regions_b, false, parallel);
        let (w, h) = (a.sample.width() as usize, a.sample.height() as usize);
        let rows = a.block_h as usize;
        // Each product carries its weight and its channel factor (3 for one gray channel).
        let (fa, fb) = (ka * (3 / channels_a) as f64, kb * (3 / channels_b) as f64);
        let zero = Complex64::new(0.0, 0.0);
        let scratch_len =
            [&a.shared.fft_col, &a.shared.ifft_col, &b.shared.fft_col].iter().map(|f| f.get_inplace_scratch_len()).max().unwrap_or(0);
        let (pairs_a, pairs_b) = (&wa.by_frequency, &wb.by_frequency);
        let (sa, sb) = (&*a, &*b);
        let column_back =
            |kx: usize, out: &mut [Complex64], other: &mut [Complex64], columns: &mut [Complex64], scratch: &mut [Complex64]| {
                sa.correlate_column(pairs_a, rows, channels_a, false, kx, out, columns, scratch);
                sb.correlate_column(pairs_b, rows, channels_b, false, kx, other, columns, scratch);
                out.iter_mut().zip(other.iter()).for_each(|(o, p)| *o = *o * fa + *p * fb);
                sa.shared.ifft_col.process_with_scratch(out, scratch);
            };
        if parallel {
            wa.product.par_chunks_mut(h).enumerate().for_each_init(
                || (vec![zero; h], vec![zero; 4 * h], vec![zero; scratch_len]),
                |(other, columns, scratch), (kx, out)| column_back(kx, out, other, columns, scratch),
            );
        } else {
            wa.column.resize(4 * h, zero);
            wa.fft_scratch.resize(scratch_len, zero);
            wb.column.resize(h, zero);
            for (kx, out) in wa.product.chunks_exact_mut(h).enumerate() {
                column_back(kx, out, &mut wb.column, &mut wa.column, &mut wa.fft_scratch);
            }
        }
        a.rows_back(&mut wa, parallel);
        let scale = 1.0 / (w * h) as f64;
        let nxu = a.positions().0 as usize;
        let (s2a, s2b) = (&a.sum_sq_maps[maps[0]].1, &b.sum_sq_maps[maps[1]].1);
        let (ca, cb) = (t2a as f64, t2b as f64);
        out.clear();
        out.resize(s2a.len(), 0.0);
        let corr_rows = &wa.rows;
        let approx_row = |(y, row): (usize, &mut [f64])| {
            let corr = &corr_rows[y / 2 * w..y / 2 * w + nxu];
            let (sa, sb) = (&s2a[y * nxu..(y + 1) * nxu], &s2b[y * nxu..(y + 1) * nxu]);
            let second = y % 2 == 1;
            for (((o, c), sa), sb) in row.iter_mut().zip(corr).zip(sa).zip(sb) {
                let c = if second { c.im } else { c.re };
                *o = ka * (sa + ca) + kb * (sb + cb) - 2.0 * c * scale;
            }
        };
        if parallel {
            out.par_chunks_mut(nxu).enumerate().for_each(approx_row);
        } else {
            out.chunks_mut(nxu).enumerate().for_each(approx_row);
        }
        let margin = ka * a.margin(t2a) + kb * b.margin(t2b);
        a.work = wa;
        b.work = wb;
        margin
    }

    /// [`OverlapSearch::sum_sq_map`] for one search between others: past a bound the cache starts
    /// again (as in [`OverlapSearch::candidates`]).
    fn cached_sum_sq_map(&mut self, regions: &[Rect]) -> usize {
        assert!(regions.iter().map(|r| r.area()).sum::<u64>() > 0, "regions to compare");
        if self.sum_sq_maps.len() >= MAX_CACHED_MAPS && !self.sum_sq_maps.iter().any(|(r, _)| r == regions) {
            self.sum_sq_maps.clear();
        }
        self.sum_sq_map(regions)
    }

    /// The row-major flags of the positions a candidate may come from, if restricted.
    pub fn allowed_positions(&self) -> Option<&[bool]> {
        self.allowed.as_deref()
    }

    /// Whether a candidate may come from `(x, y)` (a restriction set by [`OverlapSearch::restrict_to`]).
    pub fn may_copy(&self, x: u32, y: u32) -> bool {
        self.allows(x, y)
    }

    /// The candidate sets of several blocks against the same `target`, each `(origin, regions)`
    /// as in [`OverlapSearch::candidates`], in the order given. Blocks are searched concurrently,
    /// one per task rather than one split across tasks: a single 256² search is too small to share
    /// well. Each set is decided on exact integers, so it is the same whatever the thread count.
    pub fn candidates_many(&mut self, target: &RgbImage, queries: &[((u32, u32), Vec<Rect>)], tolerance: f64) -> Vec<Candidates> {
        let maps: Vec<Option<usize>> = queries
            .iter()
            .map(|(_, regions)| (regions.iter().map(|r| r.area()).sum::<u64>() > 0).then(|| self.sum_sq_map(regions)))
            .collect();
        let tasks = rayon::current_num_threads().clamp(1, queries.len().max(1));
        let per_task = queries.len().div_ceil(tasks).max(1);
        let mut pool = std::mem::take(&mut self.spare_work);
        pool.resize_with(queries.len().div_ceil(per_task), Workspace::default);
        let this = &*self;
        let search_chunk = |work: &mut Workspace, queries: &[((u32, u32), Vec<Rect>)], maps: &[Option<usize>]| -> Vec<Candidates> {
            queries
                .iter()
                .zip(maps)
                .map(|((origin, regions), map)| match map {
                    Some(m) => this.search_fft(work, target, *origin, regions, Some(*m), tolerance, false),
                    None => this.candidates_direct(target, *origin, regions, tolerance),
                })
                .collect()
        };
        let found: Vec<Vec<Candidates>> = if pool.len() <= 1 {
            pool.iter_mut().map(|work| search_chunk(work, queries, &maps)).collect()
        } else {
            pool.par_iter_mut()
                .zip(queries.par_chunks(per_task).zip(maps.par_chunks(per_task)))
                .map(|(work, (queries, maps))| search_chunk(work, queries, maps))
                .collect()
        };
        self.spare_work = pool;
        found.into_iter().flatten().collect()
    }

    /// The `count` positions of smallest exact SSD for each of several blocks, each given as its
    /// own small `target` image with its `regions` at the origin, in the order given; ties are
    /// broken by position (`y`, then `x`), so the result is the same whatever the thread count.
    /// What a coarse-to-fine search starts from (`primitives::pyramid_search`).
    pub fn best_many(&mut self, queries: &[(RgbImage, Vec<Rect>)], count: usize) -> Vec<Vec<(u32, u32, u64)>> {
        let maps: Vec<Option<usize>> = queries
            .iter()
            .map(|(_, regions)| (regions.iter().map(|r| r.area()).sum::<u64>() > 0).then(|| self.sum_sq_map(regions)))
            .collect();
        let tasks = rayon::current_num_threads().clamp(1, queries.len().max(1));
        let per_task = queries.len().div_ceil(tasks).max(1);
        let mut pool = std::mem::take(&mut self.spare_work);
        pool.resize_with(queries.len().div_ceil(per_task), Workspace::default);
        // One block alone splits its transforms across the pool instead.
        let parallel = queries.len() == 1 && rayon::current_num_threads() > 1;
        let this = &*self;
        let search_chunk = |work: &mut Workspace, queries: &[(RgbImage, Vec<Rect>)], maps: &[Option<usize>]| {
            queries
                .iter()
                .zip(maps)
                .map(|((target, regions), map)| match map {
                    Some(m) => this.best_fft(work, target, (0, 0), regions, *m, count, parallel),
                    None => {
                        let nx = this.positions().0;
                        let all = this.all_ssd_direct(target, (0, 0), regions);
                        let mut found: Vec<(u32, u32, u64)> =
                            all.into_iter().enumerate().map(|(i, s)| (i as u32 % nx, i as u32 / nx, s)).collect();
                        found.sort_by_key(|&(x, y, ssd)| (ssd, y, x));
                        found.truncate(count);
                        found
                    }
                })
                .collect::<Vec<_>>()
        };
        let found: Vec<Vec<Vec<(u32, u32, u64)>>> = if pool.len() <= 1 {
            pool.iter_mut().map(|work| search_chunk(work, queries, &maps)).collect()
        } else {
            pool.par_iter_mut()
                .zip(queries.par_chunks(per_task).zip(maps.par_chunks(per_task)))
                .map(|(work, (queries, maps))| search_chunk(work, queries, maps))
                .collect()
        };
        self.spare_work = pool;
        found.into_iter().flatten().collect()
    }

    /// One block's FFT search with the ΣS² map `map_index` (`None`: ΣS² by FFT); `parallel` splits its transforms and
    /// re-check across the pool (same result either way).
    fn search_fft(
        &self,
        work: &mut Workspace,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        map_index: Option<usize>,
        tolerance: f64,
        parallel: bool,
    ) -> Candidates {
        let margin = self.approximate(work, target, origin, regions, map_index, parallel);
        let amin = smallest(&work.approx, self.allowed.as_deref());
        let threshold = (1.0 + tolerance) * (amin + margin) + margin;
        let rechecked = self.recheck(&work.approx, threshold, target, origin, regions, parallel);
        let min = rechecked.iter().map(|c| c.2).min().expect("the best candidate is always rechecked");
        let members = rechecked.into_iter().filter(|c| within(c.2, min, tolerance)).collect();
        Candidates { min_ssd: min, members }
    }

    /// The `count` positions of smallest exact SSD, ordered by (SSD, y, x): the approximate map
    /// bounds which positions can be among them (every position whose approximation is within
    /// twice the FFT margin of the `count`-th smallest), and those are re-scored exactly.
    fn best_fft(
        &self,
        work: &mut Workspace,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        map_index: usize,
        count: usize,
        parallel: bool,
    ) -> Vec<(u32, u32, u64)> {
        let margin = self.approximate(work, target, origin, regions, Some(map_index), parallel);
        let allowed = |i: usize| self.allowed.as_ref().is_none_or(|a| a[i]);
        let mut order: Vec<f64> = work.approx.iter().enumerate().filter(|&(i, _)| allowed(i)).map(|(_, &a)| a).collect();
        if order.is_empty() {
            return Vec::new();
        }
        let k = count.clamp(1, order.len()) - 1;
        let kth = *order.select_nth_unstable_by(k, f64::total_cmp).1;
        let mut found = self.recheck(&work.approx, kth + 2.0 * margin, target, origin, regions, parallel);
        found.sort_by_key(|&(x, y, ssd)| (ssd, y, x));
        found.truncate(count);
        found
    }

    /// Every position whose approximate SSD is at most `threshold`, with its exact SSD, row-major;
    /// only positions the search may copy from. Why here and not after: the threshold comes from
    /// the allowed positions, and the forbidden ones may match far better (a hole's own image,
    /// when the fill copies from another photo, sits in the atlas beside it): re-scoring them
    /// all made a 256² inpainting from another sample take 1.1 s instead of 0.08 s.
    fn recheck(
        &self,
        approx: &[f64],
        threshold: f64,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        parallel: bool,
    ) -> Vec<(u32, u32, u64)> {
        let (nx, ny) = self.positions();
        let nxu = nx as usize;
        // Few positions pass: a row is scanned a run of positions at a time, without a branch
        // per position (so that it vectorises), and only a run holding one is looked into.
        const RUN: usize = 8;
        let recheck_row = |y: u32| {
            let row = &approx[y as usize * nxu..(y as usize + 1) * nxu];
            let mut found = Vec::new();
            for (r, run) in row.chunks(RUN).enumerate() {
                if run.iter().fold(false, |any, &a| any | (a <= threshold)) {
                    let passing = run.iter().enumerate().filter(|(_, a)| **a <= threshold).map(|(i, _)| (r * RUN + i) as u32);
                    found.extend(passing.filter(|&x| self.allows(x, y)).map(|x| (x, y, self.exact_ssd(x, y, target, origin, regions))));
                }
            }
            found
        };
        if parallel { (0..ny).into_par_iter().flat_map_iter(recheck_row).collect() } else { (0..ny).flat_map(recheck_row).collect() }
    }

    /// Fills `work.approx` with every position's approximate SSD (FFT correlation) and returns the
    /// bound on its error. ΣS² comes from the map `map_index`, exactly, or with `None` from the
    /// FFT as well (ΣS² ⋆ mask, with its own bound added to the margin).
    fn approximate(
        &self,
        work: &mut Workspace,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        map_index: Option<usize>,
        parallel: bool,
    ) -> f64 {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let rows = self.block_h as usize;
        let mask = map_index.is_none();
        let (sum_t2, channels) = self.template(work, target, origin, regions, mask, parallel);
        if mask {
            self.spec_sq();
        }
        // Σ_c S_c ⋆ T_c has the half spectrum Σ_c Ŝ_c·conj T̂_c; it is formed and transformed
        // back along columns one column at a time.
        let zero = Complex64::new(0.0, 0.0);
        let scratch_len = self.shared.fft_col.get_inplace_scratch_len().max(self.shared.ifft_col.get_inplace_scratch_len());
        let pairs = &work.by_frequency;
        let column_back = |kx: usize, out: &mut [Complex64], columns: &mut [Complex64], scratch: &mut [Complex64]| {
            self.correlate_column(pairs, rows, channels, mask, kx, out, columns, scratch);
            self.shared.ifft_col.process_with_scratch(out, scratch);
        };
        if parallel {
            work.product.par_chunks_mut(h).enumerate().for_each_init(
                || (vec![zero; 4 * h], vec![zero; scratch_len]),
                |(columns, scratch), (kx, out)| column_back(kx, out, columns, scratch),
            );
        } else {
            work.column.resize(4 * h, zero);
            work.fft_scratch.resize(scratch_len, zero);
            for (kx, out) in work.product.chunks_exact_mut(h).enumerate() {
                column_back(kx, out, &mut work.column, &mut work.fft_scratch);
            }
        }
        self.rows_back(work, parallel);
        let scale = (3 / channels) as f64 / (w * h) as f64;

        // approx(p) = ΣS²(p) − 2·corr(p) + ΣT², within `margin` of the exact SSD. The margin is a
        // generous bound on the FFT's absolute error (the usual one is ~1e-16·log n·‖S‖‖T‖).
        let mut margin = self.margin(sum_t2);
        if mask {
            // ΣS² ⋆ mask's own error, bounded as the cross term's (the mask's norm is √area).
            let area: u64 = regions.iter().map(|r| r.area()).sum();
            margin += 1e-9 * self.spec_sq().1 * (area as f64).sqrt() * ((w * h) as f64).log2().max(1.0) + 1.0;
        }
        let nxu = self.positions().0 as usize;
        let sum_sq = map_index.map(|m| &self.sum_sq_maps[m].1);
        let pairs = &work.rows;
        let approx_row = |(y, row): (usize, &mut [f64])| {
            let corr = &pairs[y / 2 * w..y / 2 * w + nxu];
            let second = y % 2 == 1;
            match sum_sq {
                Some(sum_sq) => {
                    let s2 = &sum_sq[y * nxu..(y + 1) * nxu];
                    for ((a, c), s) in row.iter_mut().zip(corr).zip(s2) {
                        let c = if second { c.im } else { c.re };
                        *a = s - 2.0 * c * scale + sum_t2 as f64;
                    }
                }
                None => {
                    for (a, c) in row.iter_mut().zip(corr) {
                        let c = if second { c.im } else { c.re };
                        *a = -2.0 * c * scale + sum_t2 as f64;
                    }
                }
            }
        };
        if parallel {
            work.approx.par_chunks_mut(nxu).enumerate().for_each(approx_row);
        } else {
            work.approx.chunks_mut(nxu).enumerate().for_each(approx_row);
        }
        margin
    }

    /// The bound on the FFT's error for a template of energy `sum_t2` (see [`OverlapSearch::approximate`]).
    fn margin(&self, sum_t2: u64) -> f64 {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        1e-9 * self.shared.sample_norm * (sum_t2 as f64).sqrt() * ((w * h) as f64).log2().max(1.0) + 1.0
    }

    /// The template's row transforms for a block at `origin` of `target` over `regions`, left in
    /// `work.by_frequency` (see [`OverlapSearch::correlate_column`]); returns the template's energy
    /// ΣT² and how many channels the correlation needs (1 when template and sample are gray).
    fn template(
        &self,
        work: &mut Workspace,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        mask: bool,
        parallel: bool,
    ) -> (u64, usize) {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let (nx, ny) = self.positions();
        let (nxu, nyu) = (nx as usize, ny as usize);
        let rows = self.block_h as usize;
        let half = w / 2 + 1;
        if work.product.len() != half * h {
            work.planes = vec![0.0; 4 * rows * w];
            work.product = vec![Complex64::new(0.0, 0.0); half * h];
            work.approx = vec![0.0; nxu * nyu];
        }
        // Template planes: the target's overlap pixels at their block offsets, zero elsewhere (the
        // planes are kept zero between blocks: only the pixels written here are cleared after).
        let mut sum_t2: u64 = 0;
        let mut template_gray = true;
        for r in regions {
            for dy in 0..r.h {
                for dx in 0..r.w {
                    let p = target.get(origin.0 + r.x + dx, origin.1 + r.y + dy);
                    let i = (r.y + dy) as usize * w + (r.x + dx) as usize;
                    for (c, &v) in p.iter().enumerate() {
                        work.planes[c * rows * w + i] = v as f64;
                    }
                    template_gray &= p[0] == p[1] && p[1] == p[2];
                    sum_t2 += p.iter().map(|&c| c as u64 * c as u64).sum::<u64>();
                }
            }
            if mask {
                for dy in 0..r.h as usize {
                    let i = 3 * rows * w + (r.y as usize + dy) * w + r.x as usize;
                    work.planes[i..i + r.w as usize].fill(1.0);
                }
            }
        }
        // A gray template on a gray sample: Σ_c S_c ⋆ T_c = 3 · S_0 ⋆ T_0, one channel's work.
        // (The value differs from the three channels' sum by rounding only, well inside `margin`.)
        // The mask's plane follows the three colour planes.
        let channels = if self.shared.gray && template_gray && !mask { 1 } else { 3 };
        self.transform_row_pairs(&work.planes[..(channels + usize::from(mask)) * rows * w], &mut work.pairs, parallel);
        for r in regions {
            for c in 0..3 + usize::from(mask) {
                for dy in 0..r.h as usize {
                    let i = c * rows * w + (r.y as usize + dy) * w + r.x as usize;
                    work.planes[i..i + r.w as usize].fill(0.0);
                }
            }
        }
        let pair_count = work.pairs.len() / w;
        work.by_frequency.resize(work.pairs.len(), Complex64::new(0.0, 0.0));
        transpose_into(&work.pairs, w, pair_count, &mut work.by_frequency, pair_count);
        (sum_t2, channels)
    }

    /// The correlation's rows from its columns transformed back (`work.product`), transformed
    /// back along rows into `work.rows`: row pair `p` holds real rows `2p` (re) and `2p + 1` (im).
    fn rows_back(&self, work: &mut Workspace, parallel: bool) {
        let (w, h) = (self.sample.width() as usize, self.sample.height() as usize);
        let nyu = self.positions().1 as usize;
        let half = w / 2 + 1;
        // Then the rows that hold candidate positions, two real rows `y1`, `y2` per complex row:
        // its spectrum is X₁(k) + i·X₂(k), each X completed by X(W−k) = X̄(k).
        let row_pairs = nyu.div_ceil(2);
        // Every entry is written below (`k` and its mirror cover the row): resized, never cleared.
        work.rows.resize(row_pairs * w, Complex64::new(0.0, 0.0));
        let i_unit = Complex64::new(0.0, 1.0);
        // A few row pairs at a time, so that the writes stay in cache.
        const PAIRS_PER_PASS: usize = 8;
        for (band, rows_out) in work.rows.chunks_mut(PAIRS_PER_PASS * w).enumerate() {
            let first = band * PAIRS_PER_PASS;
            for k in 0..half {
                let column = &work.product[k * h..(k + 1) * h];
                let mirror = w - k;
                for (p, row) in rows_out.chunks_exact_mut(w).enumerate() {
                    let y = 2 * (first + p);
                    let a = column[y];
                    let b = column.get(y + 1).copied().unwrap_or(Complex64::new(0.0, 0.0));
                    row[k] = a + i_unit * b;
                    if k > 0 && mirror >= half {
                        row[mirror] = a.conj() + i_unit * b.conj();
                    }
                }
            }
        }
        process_rows(&self.shared.ifft_row, &mut work.rows, w, parallel);
    }

    /// Index of the ΣS² map for this region set, computing it the first time (exactly, from the
    /// integral image; there are only a handful of distinct region sets per job).
    fn sum_sq_map(&mut self, regions: &[Rect]) -> usize {
        if let Some(i) = self.sum_sq_maps.iter().position(|(r, _)| r == regions) {
            return i;
        }

        // The regions' union as signed corners of the integral image: each rectangle is
        // `+ii(x1, y1) + ii(x0, y0) − ii(x1, y0) − ii(x0, y1)`, and corners that rectangles share
        // cancel (a hole fill's regions are row runs, dozens per block, whose ends mostly stay in
        // place from one row to the next: about a third of their corners remain). Then a whole
        // row of positions per corner, one contiguous slice of the integral image, so the sums
        // vectorise. Exact integers: the same map as region by region.
        let mut corners: std::collections::BTreeMap<(usize, usize), i64> = std::collections::BTreeMap::new();
        for r in regions {
            let (x0, y0, x1, y1) = (r.x as usize, r.y as usize, (r.x + r.w) as usize, (r.y + r.h) as usize);
            for (corner, sign) in [((y1, x1), 1), ((y0, x0), 1), ((y0, x1), -1), ((y1, x0), -1)] {
                *corners.entry(corner).or_insert(0) += sign;
            }
        }
        corners.retain(|_, c| *c != 0);
        let (nx, ny) = self.positions();
        let (nxu, stride) = (nx as usize, self.sample.width() as usize + 1);
        let ii = &self.shared.integral_sq;
        // Row by row in integers, each row then stored as f64 (the same exact values, without a
        // second map-sized array).
        let mut map = vec![0.0f64; nxu * ny as usize];
        let mut row = vec![0i64; nxu];
        for (y, out) in map.chunks_exact_mut(nxu).enumerate() {
            row.fill(0);
            for (&(cy, cx), &coefficient) in &corners {
                let from = (y + cy) * stride + cx;
                let corner_row = &ii[from..from + nxu];
                match coefficient {
                    1 => row.iter_mut().zip(corner_row).for_each(|(o, &v)| *o += v as i64),
                    -1 => row.iter_mut().zip(corner_row).for_each(|(o, &v)| *o -= v as i64),
                    k => row.iter_mut().zip(corner_row).for_each(|(o, &v)| *o += k * v as i64),
                }
            }
            out.iter_mut().zip(&row).for_each(|(o, &v)| *o = v as f64);
        }
        self.sum_sq_maps.push((regions.to_vec(), map));
        self.sum_sq_maps.len() - 1
    }
}

/// The smallest of `values` (of those flagged in `allowed`, when given), `∞` if none. In lanes, so
/// that it vectorises: the smallest value is the same whatever the order it is sought in.
fn smallest(values: &[f64], allowed: Option<&[bool]>) -> f64 {
    const LANES: usize = 8;
    let min = |a: f64, b: f64| if b < a { b } else { a };
    with_avx2(
        #[inline(always)]
        || {
            let mut lanes = [f64::INFINITY; LANES];
            let chunks = values.chunks_exact(LANES);
            let rest = chunks.remainder();
            match allowed {
                None => {
                    for chunk in chunks {
                        lanes.iter_mut().zip(chunk).for_each(|(l, &v)| *l = min(*l, v));
                    }
                    rest.iter().zip(&mut lanes).for_each(|(&v, l)| *l = min(*l, v));
                }
                Some(allowed) => {
                    let flags = allowed.chunks_exact(LANES);
                    let rest_flags = flags.remainder();
                    for (chunk, flags) in chunks.zip(flags) {
                        lanes
                            .iter_mut()
                            .zip(chunk.iter().zip(flags))
                            .for_each(|(l, (&v, &a))| *l = min(*l, if a { v } else { f64::INFINITY }));
                    }
                    rest.iter().zip(rest_flags).zip(&mut lanes).for_each(|((&v, &a), l)| *l = min(*l, if a { v } else { f64::INFINITY }));
                }
            }
            lanes.into_iter().fold(f64::INFINITY, min)
        },
    )
}

/// Real row `r`'s spectrum at frequency `k`, from the row-pair transforms `pairs` (rows `W`
/// long): `A(k) = (Z(k) + Z̄(W−k)) / 2` for the first row of a pair, `B(k) = (Z(k) − Z̄(W−k)) / 2i`
/// for the second.
#[inline]
fn half_spectrum_at(pairs: &[Complex64], w: usize, r: usize, k: usize) -> Complex64 {
    let z = &pairs[r / 2 * w..(r / 2 + 1) * w];
    let mirrored = z[(w - k) % w].conj();
    if r % 2 == 1 { (z[k] - mirrored) * Complex64::new(0.0, -0.5) } else { (z[k] + mirrored) * 0.5 }
}

fn process_rows(fft: &Arc<dyn Fft<f64>>, data: &mut [Complex64], len: usize, parallel: bool) {
    // Fixed-size chunks: each row's transform is independent of how rows are grouped.
    const ROWS_PER_TASK: usize = 16;
    if parallel {
        data.par_chunks_mut(len * ROWS_PER_TASK).for_each(|chunk| fft.process(chunk));
    } else {
        fft.process(data);
    }
}

/// Writes the transpose of the `w × h` row-major `src` into `dst`, whose rows are `dst_stride`
/// long: `dst[x·dst_stride + y] = src[y·w + x]`. In tiles, so that reads and writes stay in cache.
fn transpose_into(src: &[Complex64], w: usize, h: usize, dst: &mut [Complex64], dst_stride: usize) {
    const T: usize = 16;
    for by in (0..h).step_by(T) {
        for bx in (0..w).step_by(T) {
            for x in bx..(bx + T).min(w) {
                let d = &mut dst[x * dst_stride..x * dst_stride + dst_stride];
                for y in by..(by + T).min(h) {
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
    fn a_restricted_search_finds_the_best_allowed_position_and_never_a_forbidden_one() {
        let (b, ov) = (10, 3);
        let sample = noise(48, 40, 7);
        let mut target = noise(40, 40, 8);
        for y in 0..b {
            for x in 0..b {
                target.put(10 + x, 10 + y, sample.get(5 + x, 7 + y));
            }
        }
        let regions = [Rect::new(0, 0, ov, b), Rect::new(ov, 0, b - ov, ov)];
        let (nx, ny) = (48 - b + 1, 40 - b + 1);
        // Forbid the exact match and everything left of x = 4.
        let allowed: Vec<bool> = (0..ny).flat_map(|y| (0..nx).map(move |x| (x, y))).map(|(x, y)| x >= 4 && (x, y) != (5, 7)).collect();
        let mut search = OverlapSearch::new(&sample, b, b);
        assert_eq!(search.candidates(&target, (10, 10), &regions, 0.0).members[0], (5, 7, 0));
        search.restrict_to(allowed.clone());
        for tol in [0.0, 0.3] {
            let fast = search.candidates(&target, (10, 10), &regions, tol);
            let slow = search.candidates_direct(&target, (10, 10), &regions, tol);
            assert_eq!(fast, slow);
            assert!(fast.min_ssd > 0);
            assert!(fast.members.iter().all(|&(x, y, _)| allowed[(y * nx + x) as usize]), "{fast:?}");
            // The minimum is the smallest allowed one.
            let all = search.all_ssd_direct(&target, (10, 10), &regions);
            let best = all.iter().zip(&allowed).filter(|(_, a)| **a).map(|(s, _)| *s).min().unwrap();
            assert_eq!(fast.min_ssd, best);
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
    fn a_search_sharing_spectra_for_another_block_equals_its_own() {
        // The spectra made for 20² blocks serve 9² ones (restricted or not, by the region sets'
        // exact maps and by the mask's FFT): the same sets as a search made for 9², and brute force.
        let sample = noise(61, 57, 31);
        let target = noise(90, 90, 32);
        let first = OverlapSearch::new(&sample, 20, 20);
        let allowed: Vec<bool> = (0..53 * 49).map(|i| i % 7 != 3).collect();
        for restricted in [false, true] {
            let mut shared = first.for_block(9, 9);
            let mut own = OverlapSearch::new(&sample, 9, 9);
            if restricted {
                shared.restrict_to(allowed.clone());
                own.restrict_to(allowed.clone());
            }
            let runs: Vec<Rect> = (0..9).map(|j| Rect::new(j % 3, j, 4 + j % 5, 1)).collect();
            for (k, regions) in [vec![Rect::new(0, 0, 3, 9)], vec![Rect::new(0, 0, 3, 9), Rect::new(3, 0, 6, 3)], runs].iter().enumerate() {
                let origin = (5 + 11 * k as u32, 60 - 13 * k as u32);
                let fast = shared.candidates(&target, origin, regions, 0.1);
                assert_eq!(fast, own.candidates(&target, origin, regions, 0.1), "regions {k}, restricted {restricted}");
                assert_eq!(fast, own.candidates_direct(&target, origin, regions, 0.1), "regions {k}, restricted {restricted}");
            }
        }
    }

    #[test]
    fn many_blocks_at_once_equal_one_at_a_time_on_any_pool() {
        // An odd width exercises the half spectrum without a Nyquist column; the empty region set
        // takes the brute-force path.
        let sample = noise(45, 38, 31);
        let target = noise(90, 90, 32);
        let queries: Vec<((u32, u32), Vec<Rect>)> = vec![
            ((3, 4), vec![Rect::new(0, 0, 4, 14)]),
            ((30, 2), vec![Rect::new(0, 0, 14, 4)]),
            ((12, 40), vec![Rect::new(0, 0, 4, 14), Rect::new(4, 0, 10, 4)]),
            ((60, 61), vec![]),
            ((70, 9), vec![Rect::new(0, 0, 4, 14), Rect::new(4, 0, 10, 4)]),
        ];
        let mut search = OverlapSearch::new(&sample, 14, 14);
        let one_by_one: Vec<Candidates> = queries.iter().map(|(o, r)| search.candidates_direct(&target, *o, r, 0.2)).collect();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let many = pool.install(|| search.candidates_many(&target, &queries, 0.2));
            assert_eq!(many, one_by_one, "{threads} threads");
        }
    }

    #[test]
    fn the_smallest_value_is_found_in_lanes() {
        let values: Vec<f64> = (0..37).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        let flags: Vec<bool> = (0..37).map(|i| i % 3 != 0).collect();
        for n in [0, 1, 7, 8, 9, 16, 37] {
            let all = values[..n].iter().copied().fold(f64::INFINITY, f64::min);
            let some = values[..n].iter().zip(&flags).filter(|(_, a)| **a).map(|(v, _)| *v).fold(f64::INFINITY, f64::min);
            assert_eq!(smallest(&values[..n], None), all);
            assert_eq!(smallest(&values[..n], Some(&flags[..n])), some);
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

    #[test]
    fn the_sum_of_squares_map_is_every_positions_sum_over_its_regions() {
        let img = noise(23, 17, 9);
        let mut search = OverlapSearch::new(&img, 8, 6);
        // Row runs of several widths, as a hole fill's are (two of them stacked on one start, so
        // that corners cancel), and a block-high strip.
        let regions = [Rect::new(0, 0, 8, 1), Rect::new(2, 1, 3, 1), Rect::new(2, 2, 4, 1), Rect::new(7, 3, 1, 1), Rect::new(0, 4, 2, 2)];
        let index = search.sum_sq_map(&regions);
        let (nx, ny) = search.positions();
        for y in 0..ny {
            for x in 0..nx {
                let direct: u64 = regions.iter().map(|r| search.region_sum_sq(x, y, r)).sum();
                assert_eq!(search.sum_sq_maps[index].1[(y * nx + x) as usize], direct as f64, "({x}, {y})");
            }
        }
    }

    #[test]
    fn gray_and_weighted_approximations_stay_within_their_bounds() {
        let sample = noise(48, 40, 7);
        let gray = RgbImage::from_fn(48, 40, |x, y| [sample.get(x, y)[1]; 3]);
        let target = noise(30, 30, 8);
        let gray_target = RgbImage::from_fn(30, 30, |x, y| [target.get(x, y)[0]; 3]);
        let (regions, whole) = ([Rect::new(0, 0, 3, 10), Rect::new(3, 0, 7, 3)], [Rect::new(0, 0, 10, 10)]);
        let mut texture = OverlapSearch::new(&sample, 10, 10);
        let mut guide = OverlapSearch::new(&gray, 10, 10);
        // A gray template on a gray sample takes the one-channel path.
        let (approx, margin) = guide.approximate_all(&gray_target, (5, 6), &whole);
        let exact_guide = guide.all_ssd_direct(&gray_target, (5, 6), &whole);
        for (a, e) in approx.iter().zip(&exact_guide) {
            assert!((a - *e as f64).abs() <= margin, "{a} against {e}, margin {margin}");
        }
        // A colour template on the gray sample takes the three channels.
        let (approx, margin) = guide.approximate_all(&target, (1, 2), &whole);
        for (a, e) in approx.iter().zip(guide.all_ssd_direct(&target, (1, 2), &whole)) {
            assert!((a - e as f64).abs() <= margin, "{a} against {e}, margin {margin}");
        }
        let (kt, kg) = (0.3 / 90.0, 0.7 / 300.0);
        let mut weighted = Vec::new();
        let margin = OverlapSearch::approximate_weighted(
            &mut texture,
            kt,
            (&target, (2, 3), &regions),
            &mut guide,
            kg,
            (&gray_target, (5, 6), &whole),
            &mut weighted,
        );
        let exact_texture = texture.all_ssd_direct(&target, (2, 3), &regions);
        assert_eq!(weighted.len(), exact_texture.len());
        for (i, a) in weighted.iter().enumerate() {
            let e = kt * exact_texture[i] as f64 + kg * exact_guide[i] as f64;
            assert!((a - e).abs() <= margin, "{a} against {e}, margin {margin}");
        }
    }

    #[test]
    fn many_row_runs_take_the_sum_of_squares_by_fft_and_stay_exact() {
        let sample = noise(50, 44, 11);
        let mut target = noise(40, 40, 12);
        // A strong best match: the target's block at (6, 5) is partly the sample's at (17, 9).
        for y in 0..12 {
            for x in 0..12 {
                target.put(6 + x, 5 + y, sample.get(17 + x, 9 + y));
            }
        }
        // Row runs around a round hole, as a hole fill's: more than MASK_BY_FFT_FROM of them.
        let regions: Vec<Rect> = (0..12u32)
            .flat_map(|j| {
                let half = (36i64 - (j as i64 - 6).pow(2)).max(0).isqrt() as u32;
                let (a, b) = (6u32.saturating_sub(half), (6 + half).min(12));
                [(0, a), (b, 12)].into_iter().filter(|(x0, x1)| x1 > x0).map(move |(x0, x1)| Rect::new(x0, j, x1 - x0, 1))
            })
            .collect();
        assert!(regions.len() >= MASK_BY_FFT_FROM);
        for tolerance in [0.0, 0.2] {
            let mut search = OverlapSearch::new(&sample, 12, 12);
            let fast = search.candidates(&target, (6, 5), &regions, tolerance);
            assert!(search.sum_sq_maps.is_empty(), "ΣS² came from the FFT, not a map");
            assert_eq!(fast, search.candidates_direct(&target, (6, 5), &regions, tolerance));
            assert_eq!(fast.min_ssd, 0);
        }
    }
}
