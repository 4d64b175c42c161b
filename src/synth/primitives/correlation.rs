//! Pearson correlation of two lines (docs/methods.md B8, paper 003 eq. 7), with the degenerate-line
//! rules and the circular variant for hue.

/// Variance below which a line counts as constant.
pub const FLAT: f64 = 1e-12;

/// Pearson correlation from the two-pass pieces: means `m1, m2`, centred sums of squares `v1, v2`
/// and the centred cross sum `c`. Degenerate lines follow B8: both flat → 1 if the means agree
/// within 1/255, else 0; one flat → 0.
#[inline]
pub fn pearson_from(m1: f64, v1: f64, m2: f64, v2: f64, c: f64) -> f64 {
    match (v1 < FLAT, v2 < FLAT) {
        (true, true) => {
            if (m1 - m2).abs() <= 1.0 / 255.0 {
                1.0
            } else {
                0.0
            }
        }
        (true, false) | (false, true) => 0.0,
        (false, false) => c / (v1 * v2).sqrt(),
    }
}

/// Mean and centred sum of squares, two-pass in index order.
pub fn mean_and_ss(l: &[f64]) -> (f64, f64) {
    let n = l.len() as f64;
    let m = l.iter().sum::<f64>() / n;
    let ss = l.iter().map(|v| (v - m) * (v - m)).sum();
    (m, ss)
}

/// Pearson correlation of two equally long lines.
pub fn pearson(l1: &[f64], l2: &[f64]) -> f64 {
    let (m1, v1) = mean_and_ss(l1);
    let (m2, v2) = mean_and_ss(l2);
    let c = l1.iter().zip(l2).map(|(a, b)| (a - m1) * (b - m2)).sum();
    pearson_from(m1, v1, m2, v2, c)
}

/// Circular mean of angles given as fractions of a turn (`H/360`), and the sines of the
/// deviations from it (what the circular correlation multiplies).
pub fn circular_deviations(l: &[f64]) -> (f64, Vec<f64>) {
    let tau = std::f64::consts::TAU;
    let (s, c) = l.iter().fold((0.0, 0.0), |(s, c), v| (s + (tau * v).sin(), c + (tau * v).cos()));
    let mean = s.atan2(c);
    (mean, l.iter().map(|v| (tau * v - mean).sin()).collect())
}

/// Jammalamadaka–SenGupta circular correlation of two hue lines, same degenerate rules as
/// `pearson` (a line is flat when its summed squared sines are below `FLAT`; the "means agree"
/// test compares circular means).
pub fn circular(l1: &[f64], l2: &[f64]) -> f64 {
    let (m1, d1) = circular_deviations(l1);
    let (m2, d2) = circular_deviations(l2);
    let v1: f64 = d1.iter().map(|d| d * d).sum();
    let v2: f64 = d2.iter().map(|d| d * d).sum();
    let c: f64 = d1.iter().zip(&d2).map(|(a, b)| a * b).sum();
    let tau = std::f64::consts::TAU;
    let mut diff = (m1 - m2).abs() % tau;
    if diff > tau / 2.0 {
        diff = tau - diff;
    }
    pearson_from(0.0, v1, diff / tau, v2, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pearson_basics_and_degenerate_rules() {
        let a = [0.1, 0.2, 0.4, 0.3];
        let b: Vec<f64> = a.iter().map(|v| v * 0.5 + 0.2).collect();
        assert!((pearson(&a, &b) - 1.0).abs() < 1e-12);
        let neg: Vec<f64> = a.iter().map(|v| 1.0 - v).collect();
        assert!((pearson(&a, &neg) + 1.0).abs() < 1e-12);
        assert_eq!(pearson(&[0.5; 4], &[0.5; 4]), 1.0);
        assert_eq!(pearson(&[0.5; 4], &[0.9; 4]), 0.0);
        assert_eq!(pearson(&[0.5; 4], &a), 0.0);
    }

    #[test]
    fn circular_correlation_handles_wraparound() {
        // Hues straddling 0°/360°: linearly they look anti-correlated, circularly they agree.
        let a = [0.97, 0.99, 0.01, 0.03, 0.95];
        let b = [0.98, 0.005, 0.02, 0.04, 0.96];
        assert!(circular(&a, &b) > 0.99, "{}", circular(&a, &b));
        assert!(pearson(&a, &b) < 0.7, "{}", pearson(&a, &b));
    }
}
