//! Histograms and the Kullback–Leibler divergence (docs/methods.md B10, §5.6 items 1–2).

use crate::image::RgbImage;

/// The `ε` of B10: a guard against empty `Q` bins.
pub const KL_EPSILON: f64 = 1e-10;

/// Number of gray-level bins (§5.6 item 1).
pub const GRAY_BINS: usize = 256;

/// Gray level of a pixel, `floor(255·g + 0.5)` with `g = (R+G+B)/(3·255)` (§5.6 item 1).
///
/// Computed exactly in integers: `255·g = s/3` with `s = R+G+B`, whose fractional part is 0, ⅓ or
/// ⅔, never ½, so `floor(s/3 + ½) = (s + 1) / 3` (integer division) with no rounding doubt.
#[inline]
pub fn gray_level(p: [u8; 3]) -> usize {
    (p[0] as usize + p[1] as usize + p[2] as usize + 1) / 3
}

/// Counts of the 256 gray levels of an image.
pub fn gray_counts(img: &RgbImage) -> Vec<u64> {
    let mut counts = vec![0u64; GRAY_BINS];
    for p in img.as_raw().chunks_exact(3) {
        counts[gray_level([p[0], p[1], p[2]])] += 1;
    }
    counts
}

/// A histogram normalised to sum 1 (`count / total` per bin); all zero when there are no entries.
pub fn normalise(counts: &[u64]) -> Vec<f64> {
    let total: u64 = counts.iter().sum();
    if total == 0 {
        return vec![0.0; counts.len()];
    }
    counts.iter().map(|&c| c as f64 / total as f64).collect()
}

/// `D_KL(P‖Q) = Σ_{i: P_i > 0} P_i · ln((P_i + ε)/(Q_i + ε))` with `ε = 1e−10` (B10), natural log,
/// no renormalisation, summed in bin order; NaN if either histogram is all zero.
pub fn kl_divergence(p: &[f64], q: &[f64]) -> f64 {
    kl_divergence_eps(p, q, KL_EPSILON)
}

/// [`kl_divergence`] with an explicit `ε`. Panics if the histograms differ in length.
pub fn kl_divergence_eps(p: &[f64], q: &[f64], eps: f64) -> f64 {
    assert_eq!(p.len(), q.len(), "histograms of different lengths");
    if p.iter().all(|&v| v == 0.0) || q.iter().all(|&v| v == 0.0) {
        return f64::NAN;
    }
    let mut sum = 0.0f64;
    for (&pi, &qi) in p.iter().zip(q) {
        if pi > 0.0 {
            sum += pi * ((pi + eps) / (qi + eps)).ln();
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_gray_level_equals_the_float_formula() {
        for s in 0..=765usize {
            let p = [(s / 3) as u8, ((s + 1) / 3) as u8, s.div_ceil(3) as u8];
            assert_eq!(p.iter().map(|&v| v as usize).sum::<usize>(), s);
            let g = (p[0] as f64 + p[1] as f64 + p[2] as f64) / (3.0 * 255.0);
            let float_level = (255.0 * g + 0.5).floor() as usize;
            assert_eq!(gray_level(p), float_level, "s = {s}");
        }
    }

    #[test]
    fn kl_of_identical_histograms_is_zero() {
        let p = normalise(&[3, 0, 5, 2]);
        assert_eq!(kl_divergence(&p, &p), 0.0);
    }

    #[test]
    fn kl_by_hand() {
        // P = (½, ½, 0), Q = (0, ½, ½): only the first bin contributes.
        let p = [0.5, 0.5, 0.0];
        let q = [0.0, 0.5, 0.5];
        let expect = 0.5 * ((0.5 + 1e-10) / 1e-10f64).ln();
        assert!((kl_divergence(&p, &q) - expect).abs() < 1e-12);
        // P = (¾, ¼), Q = (¼, ¾).
        let p = [0.75, 0.25];
        let q = [0.25, 0.75];
        let expect = 0.75 * (0.75f64 / 0.25).ln() + 0.25 * (0.25f64 / 0.75).ln();
        assert!((kl_divergence(&p, &q) - expect).abs() < 1e-9);
    }

    #[test]
    fn kl_with_an_empty_histogram_is_nan() {
        assert!(kl_divergence(&[0.0, 0.0], &[0.5, 0.5]).is_nan());
        assert!(kl_divergence(&[0.5, 0.5], &[0.0, 0.0]).is_nan());
        assert_eq!(normalise(&[0, 0, 0]), vec![0.0; 3]);
    }
}
