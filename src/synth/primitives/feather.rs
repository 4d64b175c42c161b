//! Feathering weights for overlaps (docs/methods.md B5): Liang et al.'s linear ramp.

/// Weight of the new block at overlap index `k` (0 = the edge next to the old content) in an
/// overlap `width` pixels wide: `(k + 1) / (width + 1)`.
#[inline]
pub fn new_weight(k: u32, width: u32) -> f64 {
    (k + 1) as f64 / (width + 1) as f64
}

/// `(1 − α)·old + α·new` per channel, rounded with `floor(v + 0.5)` and clamped to 0..=255.
#[inline]
pub fn blend(old: [u8; 3], new: [u8; 3], alpha_new: f64) -> [u8; 3] {
    let mix = |o: u8, n: u8| {
        let v = (1.0 - alpha_new) * o as f64 + alpha_new * n as f64;
        // The floor without calling `floor` (a library call on baseline x86-64, which cost tone
        // matching more than the rest of its blend): for `v + 0.5 ≥ 0` the cast truncates to the
        // floor, and below 0 both clamp to 0.
        (v + 0.5).clamp(0.0, 255.0) as u8
    };
    [mix(old[0], new[0]), mix(old[1], new[1]), mix(old[2], new[2])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_ramp_strictly_inside_zero_one() {
        let w: Vec<f64> = (0..4).map(|k| new_weight(k, 4)).collect();
        assert_eq!(w, vec![0.2, 0.4, 0.6, 0.8]);
    }

    #[test]
    fn blend_rounds_half_up() {
        assert_eq!(blend([0, 10, 255], [255, 11, 0], 0.5), [128, 11, 128]);
        assert_eq!(blend([7, 7, 7], [200, 0, 3], 0.0), [7, 7, 7]);
    }
}
