//! Four-direction Sobel gradient magnitude and its Otsu threshold (docs/methods.md B7, paper 003
//! eqs. 2–5): the binary edge map whose agreement across a seam paper 003's criterion rewards.

/// Gradient magnitude `sqrt(G0² + G45² + G90² + G135²)` of a unit-scale plane, replicate borders.
pub fn sobel4(plane: &[f64], w: usize, h: usize) -> Vec<f64> {
    let at = |x: isize, y: isize| plane[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize];
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h as isize {
        for x in 0..w as isize {
            // P[i][j]: row i = 1..3 top→bottom, column j = 1..3 left→right.
            let p = |i: isize, j: isize| at(x + j - 2, y + i - 2);
            let g0 = (p(3, 1) + 2.0 * p(3, 2) + p(3, 3)) - (p(1, 1) + 2.0 * p(1, 2) + p(1, 3));
            let g90 = (p(1, 3) + 2.0 * p(2, 3) + p(3, 3)) - (p(1, 1) + 2.0 * p(2, 1) + p(3, 1));
            let g45 = (p(2, 3) + 2.0 * p(3, 3) + p(3, 2)) - (p(1, 2) + 2.0 * p(1, 1) + p(2, 1));
            let g135 = (p(1, 2) + 2.0 * p(1, 3) + p(2, 3)) - (p(2, 1) + 2.0 * p(3, 1) + p(3, 2));
            out.push((g0 * g0 + g45 * g45 + g90 * g90 + g135 * g135).sqrt());
        }
    }
    out
}

/// Otsu's threshold on a 256-bin histogram over `[0, max]`: the binary map (1 = strong edge, the
/// bins above the threshold). All zero when the plane is flat.
pub fn otsu_edges(g: &[f64]) -> Vec<u8> {
    let max = g.iter().copied().fold(0.0, f64::max);
    if max <= 0.0 {
        return vec![0; g.len()];
    }
    let bin = |v: f64| ((256.0 * v / max).floor() as usize).min(255);
    let mut count = [0u64; 256];
    let mut sum = [0f64; 256];
    for &v in g {
        let b = bin(v);
        count[b] += 1;
        sum[b] += v;
    }
    let n = g.len() as f64;
    let total: f64 = sum.iter().sum();
    let (mut best_t, mut best_f) = (0usize, f64::NEG_INFINITY);
    let (mut c1, mut s1) = (0u64, 0f64);
    for t in 0..255 {
        c1 += count[t];
        s1 += sum[t];
        let c2 = g.len() as u64 - c1;
        if c1 == 0 || c2 == 0 {
            continue;
        }
        let (r1, r2) = (c1 as f64 / n, c2 as f64 / n);
        let (u1, u2) = (s1 / c1 as f64, (total - s1) / c2 as f64);
        let u = r1 * u1 + r2 * u2;
        let f = r1 * (u1 - u) * (u1 - u) + r2 * (u2 - u) * (u2 - u);
        if f > best_f {
            best_f = f;
            best_t = t;
        }
    }
    g.iter().map(|&v| u8::from(bin(v) > best_t)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn otsu_separates_two_levels() {
        let g: Vec<f64> = (0..100).map(|i| if i % 3 == 0 { 0.9 } else { 0.1 }).collect();
        let e = otsu_edges(&g);
        for (v, b) in g.iter().zip(&e) {
            assert_eq!(*b, u8::from(*v > 0.5));
        }
        assert!(otsu_edges(&[0.0; 10]).iter().all(|&b| b == 0));
    }

    #[test]
    fn sobel_sees_a_vertical_step_and_not_a_flat_plane() {
        let (w, h) = (8, 6);
        let plane: Vec<f64> = (0..w * h).map(|k| if k % w >= 4 { 1.0 } else { 0.0 }).collect();
        let g = sobel4(&plane, w, h);
        assert!(g[2 * w + 4] > 1.0 && g[2 * w + 3] > 1.0);
        assert_eq!(g[2 * w], 0.0);
        assert!(sobel4(&[0.3; 20], 5, 4).iter().all(|&v| v == 0.0));
    }
}
