//! Structure tensor, local orientation, coherence and the complex orientation field
//! (docs/methods.md B10, paper 003 eqs. 12–15).
//!
//! Fixed evaluation order (so results are reproducible bit for bit):
//! - `Ix`: `d = ½·(g[x+1] − g[x−1])` along `x`, then `¼·d[y−1] + ½·d[y] + ¼·d[y+1]` along `y`;
//! - `Iy`: `s = ¼·g[x−1] + ½·g[x] + ¼·g[x+1]` along `x`, then `½·(s[y+1] − s[y−1])` along `y`;
//! - Gaussian smoothing: along `x` first, then along `y`, taps summed from `−r` to `+r`;
//! - every border replicates the edge pixel.

use rayon::prelude::*;
use rustfft::num_complex::Complex64;

/// Validity guard of B10: a pixel has an orientation iff `Sxx + Syy > VALID_TRACE_MIN`.
pub const VALID_TRACE_MIN: f64 = 1e-12;

/// The smoothed structure tensor `(Sxx, Sxy, Syy)` of a gray plane, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct StructureTensor {
    pub width: usize,
    pub height: usize,
    pub sxx: Vec<f64>,
    pub sxy: Vec<f64>,
    pub syy: Vec<f64>,
}

#[inline]
fn clamp_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// Sobel/8 gradients `(Ix, Iy)` of a gray plane with replicate borders (B10).
pub fn sobel_gradients(gray: &[f64], w: usize, h: usize) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(gray.len(), w * h, "plane length does not match {w}x{h}");
    if w == 0 || h == 0 {
        return (Vec::new(), Vec::new());
    }
    let (dx, sx) = sobel_rows(gray, w, h);
    let mut ix = vec![0.0; w * h];
    let mut iy = vec![0.0; w * h];
    sobel_columns(&dx, &sx, w, h, |y, ix_row, iy_row| {
        ix[y * w..(y + 1) * w].copy_from_slice(ix_row);
        iy[y * w..(y + 1) * w].copy_from_slice(iy_row);
    });
    (ix, iy)
}

/// The `x` halves of the Sobel/8 kernels, `d = ½·(g[x+1] − g[x−1])` and
/// `s = ¼·g[x−1] + ½·g[x] + ¼·g[x+1]`, of a non-empty plane.
fn sobel_rows(gray: &[f64], w: usize, h: usize) -> (Vec<f64>, Vec<f64>) {
    let mut dx = vec![0.0; w * h];
    let mut sx = vec![0.0; w * h];
    // Each row is read through a copy with its edge pixels replicated once on each side, so the
    // per-pixel loop has no border test and vectorises; the operations per value are the same.
    let mut padded = vec![0.0; w + 2];
    for ((row, dx_row), sx_row) in gray.chunks_exact(w).zip(dx.chunks_exact_mut(w)).zip(sx.chunks_exact_mut(w)) {
        padded[0] = row[0];
        padded[1..=w].copy_from_slice(row);
        padded[w + 1] = row[w - 1];
        let (l, c, r) = (&padded[..w], &padded[1..=w], &padded[2..]);
        for (((d, s), (&l, &c)), &r) in dx_row.iter_mut().zip(sx_row.iter_mut()).zip(l.iter().zip(c)).zip(r) {
            *d = 0.5 * (r - l);
            *s = 0.25 * l + 0.5 * c + 0.25 * r;
        }
    }
    (dx, sx)
}

/// The `y` halves of the Sobel/8 kernels over the planes of [`sobel_rows`]: calls
/// `row(y, Ix, Iy)` with each row of the gradients, top to bottom, so that a caller that only
/// needs something made of them does not keep two more planes.
fn sobel_columns(dx: &[f64], sx: &[f64], w: usize, h: usize, mut row: impl FnMut(usize, &[f64], &[f64])) {
    let mut ix = vec![0.0; w];
    let mut iy = vec![0.0; w];
    for y in 0..h {
        let up = clamp_index(y as isize - 1, h) * w;
        let down = clamp_index(y as isize + 1, h) * w;
        let mid = y * w;
        let (du, dm, dd) = (&dx[up..up + w], &dx[mid..mid + w], &dx[down..down + w]);
        let (su, sd) = (&sx[up..up + w], &sx[down..down + w]);
        for x in 0..w {
            ix[x] = 0.25 * du[x] + 0.5 * dm[x] + 0.25 * dd[x];
            iy[x] = 0.5 * (sd[x] - su[x]);
        }
        row(y, &ix, &iy);
    }
}

/// Normalised Gaussian taps for `σ`, radius `floor(4σ + 0.5)` (B10), indexed `0..=2r` for offsets
/// `−r..=r`; the normalising sum is taken in index order.
pub fn gaussian_kernel(sigma: f64) -> Vec<f64> {
    assert!(sigma > 0.0 && sigma.is_finite(), "σ must be positive");
    let r = (4.0 * sigma + 0.5).floor() as i64;
    let taps: Vec<f64> = (-r..=r).map(|i| (-((i * i) as f64) / (2.0 * sigma * sigma)).exp()).collect();
    let sum: f64 = taps.iter().fold(0.0, |a, &b| a + b);
    taps.into_iter().map(|t| t / sum).collect()
}

/// Separable convolution with a symmetric kernel, `x` then `y`, replicate borders.
pub fn separable_blur(plane: &[f64], w: usize, h: usize, kernel: &[f64]) -> Vec<f64> {
    assert_eq!(plane.len(), w * h, "plane length does not match {w}x{h}");
    let mut tmp = vec![0.0; w * h];
    let mut out = vec![0.0; w * h];
    blur_into(plane, w, h, kernel, &mut tmp, &mut out);
    out
}

/// [`separable_blur`] of `plane` into `out`, through `tmp` (both `w·h` long, any contents), so
/// that a caller blurring several planes reuses the same two buffers.
fn blur_into(plane: &[f64], w: usize, h: usize, kernel: &[f64], tmp: &mut [f64], out: &mut [f64]) {
    if w == 0 || h == 0 {
        return;
    }
    let r = kernel.len() / 2;
    // Each output value is `0 + Σ_k kernel[k]·v_k` in tap order, whatever the row split across
    // threads, so the result does not depend on the thread count.
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let row = &plane[y * w..(y + 1) * w];
        // The row with `r` replicated pixels on each side.
        let mut padded = Vec::with_capacity(w + 2 * r);
        padded.extend(std::iter::repeat_n(row[0], r));
        padded.extend_from_slice(row);
        padded.extend(std::iter::repeat_n(row[w - 1], r));
        // Tap by tap across the row (the row starts at zero): the same sum per value as a
        // per-pixel loop over the taps, but vectorised.
        out.fill(0.0);
        for (k, &wt) in kernel.iter().enumerate() {
            for (o, &v) in out.iter_mut().zip(&padded[k..k + w]) {
                *o += wt * v;
            }
        }
    });
    let tmp = &*tmp;
    out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
        o.fill(0.0);
        for (k, &wt) in kernel.iter().enumerate() {
            let src = clamp_index(y as isize + k as isize - r as isize, h);
            for (a, &v) in o.iter_mut().zip(&tmp[src * w..(src + 1) * w]) {
                *a += wt * v;
            }
        }
    });
}

/// The structure tensor of a gray plane (unit scale, row-major) with Gaussian window `σ`
/// (paper 003 eq. 12; default `σ = 1.5`).
///
/// The same values as blurring `Ix²`, `Ix·Iy` and `Iy²` made from [`sobel_gradients`], in five
/// planes instead of thirteen: the products are made row by row from the gradients, and the two
/// Sobel half-planes, dead once the products exist, serve as the blur's buffers.
pub fn structure_tensor(gray: &[f64], w: usize, h: usize, sigma: f64) -> StructureTensor {
    assert_eq!(gray.len(), w * h, "plane length does not match {w}x{h}");
    let kernel = gaussian_kernel(sigma);
    if w == 0 || h == 0 {
        return StructureTensor { width: w, height: h, sxx: Vec::new(), sxy: Vec::new(), syy: Vec::new() };
    }
    let (mut tmp, mut spare) = sobel_rows(gray, w, h);
    let mut sxx = vec![0.0; w * h];
    let mut sxy = vec![0.0; w * h];
    let mut syy = vec![0.0; w * h];
    sobel_columns(&tmp, &spare, w, h, |y, ix, iy| {
        let rows = y * w..(y + 1) * w;
        let (xx, xy, yy) = (&mut sxx[rows.clone()], &mut sxy[rows.clone()], &mut syy[rows]);
        for x in 0..w {
            xx[x] = ix[x] * ix[x];
            xy[x] = ix[x] * iy[x];
            yy[x] = iy[x] * iy[x];
        }
    });
    for plane in [&mut sxx, &mut sxy, &mut syy] {
        blur_into(plane, w, h, &kernel, &mut tmp, &mut spare);
        std::mem::swap(plane, &mut spare);
    }
    StructureTensor { width: w, height: h, sxx, sxy, syy }
}

impl StructureTensor {
    pub fn len(&self) -> usize {
        self.sxx.len()
    }
    pub fn is_empty(&self) -> bool {
        self.sxx.is_empty()
    }

    /// Whether pixel `i` (row-major) has an orientation: `Sxx + Syy > 1e−12`.
    pub fn is_valid(&self, i: usize) -> bool {
        self.sxx[i] + self.syy[i] > VALID_TRACE_MIN
    }

    /// Orientation `O = ½·atan2(2·Sxy, Sxx − Syy)` of the larger-eigenvalue eigenvector, in
    /// degrees in `(−90, 90]` (eq. 13); `None` where invalid.
    pub fn orientation_deg(&self, i: usize) -> Option<f64> {
        orientation_of(self.sxx[i], self.sxy[i], self.syy[i])
    }

    /// Coherence `C = (λ1 − λ2)/(λ1 + λ2) = sqrt((Sxx − Syy)² + 4·Sxy²)/(Sxx + Syy)` (eq. 15);
    /// `None` where invalid.
    pub fn coherence(&self, i: usize) -> Option<f64> {
        if !self.is_valid(i) {
            return None;
        }
        let d = self.sxx[i] - self.syy[i];
        let s = 2.0 * self.sxy[i];
        Some((d * d + s * s).sqrt() / (self.sxx[i] + self.syy[i]))
    }

    /// Complex orientation `V = C·e^{2jO} = ((Sxx − Syy) + 2j·Sxy)/(Sxx + Syy)` (eq. 14), `0`
    /// where invalid; row-major.
    pub fn complex_orientation(&self) -> Vec<Complex64> {
        (0..self.len())
            .map(|i| {
                if self.is_valid(i) {
                    let t = self.sxx[i] + self.syy[i];
                    Complex64::new((self.sxx[i] - self.syy[i]) / t, (2.0 * self.sxy[i]) / t)
                } else {
                    Complex64::new(0.0, 0.0)
                }
            })
            .collect()
    }
}

/// [`StructureTensor::orientation_deg`] of one pixel's `(Sxx, Sxy, Syy)`.
#[inline]
fn orientation_of(sxx: f64, sxy: f64, syy: f64) -> Option<f64> {
    (sxx + syy > VALID_TRACE_MIN).then(|| {
        let o = 0.5 * (2.0 * sxy).atan2(sxx - syy).to_degrees();
        // atan2 may return −π (e.g. for y = −0.0), giving −90, which belongs to +90.
        if o <= -90.0 { o + 180.0 } else { o }
    })
}

/// Orientation bin of `o` (degrees, `(−90, 90]`) for `bins` bins over 180°: bin `k` is centred on
/// `−90° + k·(180°/bins)` and the bins wrap (§5.6: with 180 bins,
/// `k = floor(O + 90 + 0.5) mod 180`).
pub fn orientation_bin(o: f64, bins: usize) -> usize {
    let width = 180.0 / bins as f64;
    let v = (o + 90.0) / width + 0.5;
    // For `v ≥ 0` (every `o` of the range) truncation is the floor, without a call to `floor`;
    // the division of `rem_euclid` is only needed for the one bin that wraps.
    let k = if v >= 0.0 { v as i64 } else { v.floor() as i64 };
    let bins = bins as i64;
    (if (0..bins).contains(&k) { k } else { k.rem_euclid(bins) }) as usize
}

/// Unweighted counts of the orientations of all valid pixels, in `bins` bins (§5.6).
pub fn orientation_counts(tensor: &StructureTensor, bins: usize) -> Vec<u64> {
    assert!(bins > 0, "need at least one orientation bin");
    let mut counts = vec![0u64; bins];
    for ((&sxx, &sxy), &syy) in tensor.sxx.iter().zip(&tensor.sxy).zip(&tensor.syy) {
        if let Some(o) = orientation_of(sxx, sxy, syy) {
            counts[orientation_bin(o, bins)] += 1;
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
        (0..w * h).map(|i| f((i % w) as f64, (i / w) as f64)).collect()
    }

    #[test]
    fn gaussian_kernel_has_radius_six_and_sums_to_one() {
        let k = gaussian_kernel(1.5);
        assert_eq!(k.len(), 13);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert_eq!(k[0], k[12]);
        assert!(k[6] > k[5] && k[5] > k[4]);
    }

    #[test]
    fn sobel_of_a_ramp_is_its_slope() {
        let (w, h) = (8, 6);
        let g = plane(w, h, |x, y| 0.1 * x + 0.03 * y);
        let (ix, iy) = sobel_gradients(&g, w, h);
        // Interior: exact slopes; borders use replicate padding (half the slope across the edge).
        let i = 3 * w + 4;
        assert!((ix[i] - 0.1).abs() < 1e-15 && (iy[i] - 0.03).abs() < 1e-15);
        assert!((ix[3 * w] - 0.05).abs() < 1e-15, "left border: {}", ix[3 * w]);
    }

    /// The definitions of B10 written plainly, one clamped tap at a time.
    fn reference_tensor(g: &[f64], w: usize, h: usize, sigma: f64) -> StructureTensor {
        let at = |p: &[f64], x: isize, y: isize| p[clamp_index(y, h) * w + clamp_index(x, w)];
        let mut dx = vec![0.0; w * h];
        let mut sx = vec![0.0; w * h];
        for i in 0..w * h {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            let (l, c, r) = (at(g, x - 1, y), at(g, x, y), at(g, x + 1, y));
            dx[i] = 0.5 * (r - l);
            sx[i] = 0.25 * l + 0.5 * c + 0.25 * r;
        }
        let mut ix = vec![0.0; w * h];
        let mut iy = vec![0.0; w * h];
        for i in 0..w * h {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            ix[i] = 0.25 * at(&dx, x, y - 1) + 0.5 * at(&dx, x, y) + 0.25 * at(&dx, x, y + 1);
            iy[i] = 0.5 * (at(&sx, x, y + 1) - at(&sx, x, y - 1));
        }
        let kernel = gaussian_kernel(sigma);
        let r = (kernel.len() / 2) as isize;
        let blur = |p: &[f64]| {
            let tmp: Vec<f64> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as isize, (i / w) as isize);
                    let mut acc = 0.0;
                    for (k, &wt) in kernel.iter().enumerate() {
                        acc += wt * at(p, x + k as isize - r, y);
                    }
                    acc
                })
                .collect();
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as isize, (i / w) as isize);
                    let mut acc = 0.0;
                    for (k, &wt) in kernel.iter().enumerate() {
                        acc += wt * at(&tmp, x, y + k as isize - r);
                    }
                    acc
                })
                .collect::<Vec<f64>>()
        };
        let prod = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(&a, &b)| a * b).collect::<Vec<f64>>();
        StructureTensor { width: w, height: h, sxx: blur(&prod(&ix, &ix)), sxy: blur(&prod(&ix, &iy)), syy: blur(&prod(&iy, &iy)) }
    }

    #[test]
    fn tensor_is_bit_identical_to_the_plain_definition() {
        // Noise with negative zeros and a plane narrower than the kernel, where every tap
        // is a border tap.
        for (w, h) in [(37, 23), (5, 9), (1, 1), (2, 17)] {
            let mut s = 7u64;
            let g: Vec<f64> = (0..w * h)
                .map(|i| {
                    s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    if i % 11 == 0 { -0.0 } else { (s >> 11) as f64 / (1u64 << 53) as f64 }
                })
                .collect();
            let got = structure_tensor(&g, w, h, 1.5);
            let want = reference_tensor(&g, w, h, 1.5);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            assert_eq!(bits(&got.sxx), bits(&want.sxx), "{w}x{h}");
            assert_eq!(bits(&got.sxy), bits(&want.sxy), "{w}x{h}");
            assert_eq!(bits(&got.syy), bits(&want.syy), "{w}x{h}");
        }
    }

    #[test]
    fn orientation_bins_wrap() {
        assert_eq!(orientation_bin(90.0, 180), 0);
        assert_eq!(orientation_bin(-89.6, 180), 0);
        assert_eq!(orientation_bin(-89.4, 180), 1);
        assert_eq!(orientation_bin(0.0, 180), 90);
        assert_eq!(orientation_bin(89.4, 180), 179);
        assert_eq!(orientation_bin(45.0, 180), 135);
        // Same rule as the §5.6 formula for every tenth of a degree, and as the general one
        // (floor, then wrap) for other bin counts and for angles outside the range.
        for t in -899..=900 {
            let o = t as f64 / 10.0;
            assert_eq!(orientation_bin(o, 180), ((o + 90.0 + 0.5).floor() as i64).rem_euclid(180) as usize);
        }
        for bins in [1, 7, 180, 360] {
            let width = 180.0 / bins as f64;
            for t in -4000..=4000 {
                let o = t as f64 / 13.0;
                let general = (((o + 90.0) / width + 0.5).floor() as i64).rem_euclid(bins as i64) as usize;
                assert_eq!(orientation_bin(o, bins), general, "{o} in {bins} bins");
            }
        }
        assert_eq!(orientation_bin(f64::NAN, 180), 0);
    }

    #[test]
    fn orientation_and_coherence_of_a_straight_grating() {
        let (w, h) = (40, 30);
        let g = plane(w, h, |x, _| 0.5 + 0.4 * (2.0 * std::f64::consts::PI * x / 8.0).sin());
        let t = structure_tensor(&g, w, h, 1.5);
        let v = t.complex_orientation();
        for (i, vi) in v.iter().enumerate() {
            assert_eq!(t.orientation_deg(i), Some(0.0));
            assert!((t.coherence(i).unwrap() - 1.0).abs() < 1e-12);
            assert!((vi - Complex64::new(1.0, 0.0)).norm() < 1e-12);
        }
        let g = plane(w, h, |_, y| 0.5 + 0.4 * (2.0 * std::f64::consts::PI * y / 8.0).sin());
        let t = structure_tensor(&g, w, h, 1.5);
        for i in 0..w * h {
            assert_eq!(t.orientation_deg(i), Some(90.0));
        }
    }

    #[test]
    fn orientation_range_is_half_open_at_minus_90() {
        // atan2(−0, negative) = −π would give −90°; it must be reported as +90°.
        let t = StructureTensor { width: 2, height: 1, sxx: vec![0.0, 1.0], sxy: vec![-0.0, -1e-300], syy: vec![1.0, 2.0] };
        assert_eq!(t.orientation_deg(0), Some(90.0));
        let o = t.orientation_deg(1).unwrap();
        assert!(o > -90.0 && o <= 90.0, "{o}");
        // A diagonal tensor: Sxx = Syy, Sxy > 0 → 45°; Sxy < 0 → −45°.
        let t = StructureTensor { width: 2, height: 1, sxx: vec![1.0, 1.0], sxy: vec![0.5, -0.5], syy: vec![1.0, 1.0] };
        assert_eq!(t.orientation_deg(0), Some(45.0));
        assert_eq!(t.orientation_deg(1), Some(-45.0));
        // Sxx = 2, Syy = 1, Sxy = ½: O = ½·atan2(1, 1) = 22.5°, C = √2/3, V = (1 + j)/3.
        let t = StructureTensor { width: 1, height: 1, sxx: vec![2.0], sxy: vec![0.5], syy: vec![1.0] };
        assert!((t.orientation_deg(0).unwrap() - 22.5).abs() < 1e-12);
        assert!((t.coherence(0).unwrap() - 2f64.sqrt() / 3.0).abs() < 1e-15);
        assert!((t.complex_orientation()[0] - Complex64::new(1.0 / 3.0, 1.0 / 3.0)).norm() < 1e-15);
    }

    #[test]
    fn constant_plane_has_no_valid_pixel() {
        let g = vec![0.3; 20 * 20];
        let t = structure_tensor(&g, 20, 20, 1.5);
        assert!((0..t.len()).all(|i| t.orientation_deg(i).is_none() && t.coherence(i).is_none()));
        assert!(t.complex_orientation().iter().all(|v| v.re == 0.0 && v.im == 0.0));
        assert_eq!(orientation_counts(&t, 180).iter().sum::<u64>(), 0);
    }
}
