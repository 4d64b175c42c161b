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
    let mut dx = vec![0.0; w * h];
    let mut sx = vec![0.0; w * h];
    for y in 0..h {
        let row = &gray[y * w..(y + 1) * w];
        for x in 0..w {
            let l = row[clamp_index(x as isize - 1, w)];
            let c = row[x];
            let r = row[clamp_index(x as isize + 1, w)];
            dx[y * w + x] = 0.5 * (r - l);
            sx[y * w + x] = 0.25 * l + 0.5 * c + 0.25 * r;
        }
    }
    let mut ix = vec![0.0; w * h];
    let mut iy = vec![0.0; w * h];
    for y in 0..h {
        let up = clamp_index(y as isize - 1, h) * w;
        let down = clamp_index(y as isize + 1, h) * w;
        let mid = y * w;
        for x in 0..w {
            ix[mid + x] = 0.25 * dx[up + x] + 0.5 * dx[mid + x] + 0.25 * dx[down + x];
            iy[mid + x] = 0.5 * (sx[down + x] - sx[up + x]);
        }
    }
    (ix, iy)
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
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let r = kernel.len() / 2;
    // Each output value is `0 + Σ_k kernel[k]·v_k` in tap order, whatever the row split across
    // threads, so the result does not depend on the thread count.
    let mut tmp = vec![0.0; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let row = &plane[y * w..(y + 1) * w];
        // The row with `r` replicated pixels on each side.
        let mut padded = Vec::with_capacity(w + 2 * r);
        padded.extend(std::iter::repeat_n(row[0], r));
        padded.extend_from_slice(row);
        padded.extend(std::iter::repeat_n(row[w - 1], r));
        for (x, o) in out.iter_mut().enumerate() {
            let mut acc = 0.0;
            for (&wt, &v) in kernel.iter().zip(&padded[x..x + kernel.len()]) {
                acc += wt * v;
            }
            *o = acc;
        }
    });
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
        for (k, &wt) in kernel.iter().enumerate() {
            let src = clamp_index(y as isize + k as isize - r as isize, h);
            for (a, &v) in o.iter_mut().zip(&tmp[src * w..(src + 1) * w]) {
                *a += wt * v;
            }
        }
    });
    out
}

/// The structure tensor of a gray plane (unit scale, row-major) with Gaussian window `σ`
/// (paper 003 eq. 12; default `σ = 1.5`).
pub fn structure_tensor(gray: &[f64], w: usize, h: usize, sigma: f64) -> StructureTensor {
    let (ix, iy) = sobel_gradients(gray, w, h);
    let kernel = gaussian_kernel(sigma);
    let xx: Vec<f64> = ix.iter().map(|&a| a * a).collect();
    let xy: Vec<f64> = ix.iter().zip(&iy).map(|(&a, &b)| a * b).collect();
    let yy: Vec<f64> = iy.iter().map(|&b| b * b).collect();
    StructureTensor {
        width: w,
        height: h,
        sxx: separable_blur(&xx, w, h, &kernel),
        sxy: separable_blur(&xy, w, h, &kernel),
        syy: separable_blur(&yy, w, h, &kernel),
    }
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
        if !self.is_valid(i) {
            return None;
        }
        let o = 0.5 * (2.0 * self.sxy[i]).atan2(self.sxx[i] - self.syy[i]).to_degrees();
        // atan2 may return −π (e.g. for y = −0.0), giving −90, which belongs to +90.
        Some(if o <= -90.0 { o + 180.0 } else { o })
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

/// Orientation bin of `o` (degrees, `(−90, 90]`) for `bins` bins over 180°: bin `k` is centred on
/// `−90° + k·(180°/bins)` and the bins wrap (§5.6: with 180 bins,
/// `k = floor(O + 90 + 0.5) mod 180`).
pub fn orientation_bin(o: f64, bins: usize) -> usize {
    let width = 180.0 / bins as f64;
    (((o + 90.0) / width + 0.5).floor() as i64).rem_euclid(bins as i64) as usize
}

/// Unweighted counts of the orientations of all valid pixels, in `bins` bins (§5.6).
pub fn orientation_counts(tensor: &StructureTensor, bins: usize) -> Vec<u64> {
    assert!(bins > 0, "need at least one orientation bin");
    let mut counts = vec![0u64; bins];
    for i in 0..tensor.len() {
        if let Some(o) = tensor.orientation_deg(i) {
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

    #[test]
    fn orientation_bins_wrap() {
        assert_eq!(orientation_bin(90.0, 180), 0);
        assert_eq!(orientation_bin(-89.6, 180), 0);
        assert_eq!(orientation_bin(-89.4, 180), 1);
        assert_eq!(orientation_bin(0.0, 180), 90);
        assert_eq!(orientation_bin(89.4, 180), 179);
        assert_eq!(orientation_bin(45.0, 180), 135);
        // Same rule as the §5.6 formula for every tenth of a degree.
        for t in -899..=900 {
            let o = t as f64 / 10.0;
            assert_eq!(orientation_bin(o, 180), ((o + 90.0 + 0.5).floor() as i64).rem_euclid(180) as usize);
        }
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
