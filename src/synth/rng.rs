//! Seeded random streams (docs/methods.md B2).
//!
//! Every random draw in texsyn comes from a stream derived from the job seed and a stable ASCII
//! label such as `"quilt/pick/bi=3/bj=5"`. Giving each purpose and each parallel work item its own
//! labelled stream is what makes pixels independent of thread count and scheduling. The derivation
//! and the two drawing primitives are fixed here (not taken from `rand`'s distributions, whose
//! algorithms may change between versions) so they can be re-implemented anywhere.

use rand_core::Rng;
use rand_pcg::Pcg64;

/// SplitMix64's output function applied once to `x`.
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// 64-bit FNV-1a over the bytes of `label`.
pub fn fnv1a_64(label: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in label.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// One independent random stream.
pub struct Stream {
    rng: Pcg64,
}

impl Stream {
    /// The stream for `(seed, label)`.
    pub fn new(seed: u64, label: &str) -> Stream {
        let h = fnv1a_64(label);
        let state = ((splitmix64(seed) as u128) << 64) | splitmix64(seed ^ h) as u128;
        Stream { rng: Pcg64::new(state, h as u128) }
    }

    /// Raw 64-bit output.
    pub fn next_u64(&mut self) -> u64 {
        self.rng.next_u64()
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub fn uniform_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// `lo + (hi − lo)·u`, `u` uniform in `[0, 1)`.
    pub fn uniform_range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform_f64()
    }

    /// Unbiased integer in `[0, n)` by Lemire's multiply-and-reject method. Panics if `n == 0`.
    pub fn below(&mut self, n: u64) -> u64 {
        assert!(n > 0, "below(0)");
        let mut m = self.next_u64() as u128 * n as u128;
        let mut low = m as u64;
        if low < n {
            let threshold = n.wrapping_neg() % n;
            while low < threshold {
                m = self.next_u64() as u128 * n as u128;
                low = m as u64;
            }
        }
        (m >> 64) as u64
    }

    /// `below` for `usize` counts.
    pub fn below_usize(&mut self, n: usize) -> usize {
        self.below(n as u64) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_and_splitmix_match_reference_values() {
        // FNV-1a test vectors from the reference implementation.
        assert_eq!(fnv1a_64(""), 0xcbf29ce484222325);
        assert_eq!(fnv1a_64("a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a_64("foobar"), 0x85944171f73967e8);
        // SplitMix64 output for state 0 (first output of the reference generator seeded with 0).
        assert_eq!(splitmix64(0), 0xe220a8397b1dcdaf);
    }

    #[test]
    fn streams_are_reproducible_and_label_dependent() {
        let a: Vec<u64> = (0..4)
            .map({
                let mut s = Stream::new(7, "x");
                move |_| s.next_u64()
            })
            .collect();
        let b: Vec<u64> = (0..4)
            .map({
                let mut s = Stream::new(7, "x");
                move |_| s.next_u64()
            })
            .collect();
        let c: Vec<u64> = (0..4)
            .map({
                let mut s = Stream::new(7, "y");
                move |_| s.next_u64()
            })
            .collect();
        let d: Vec<u64> = (0..4)
            .map({
                let mut s = Stream::new(8, "x");
                move |_| s.next_u64()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
    }

    #[test]
    fn below_is_in_range_and_roughly_uniform() {
        let mut s = Stream::new(1, "below");
        let mut counts = [0u32; 6];
        for _ in 0..60_000 {
            counts[s.below(6) as usize] += 1;
        }
        for c in counts {
            assert!((9_000..11_000).contains(&c), "{counts:?}");
        }
        assert_eq!(s.below(1), 0);
        let u = s.uniform_f64();
        assert!((0.0..1.0).contains(&u));
    }

    #[test]
    fn stream_derivation_is_pinned() {
        // Pins the derivation so an accidental change (which would change every image) is caught.
        let mut s = Stream::new(7, "quilt/first");
        let first = s.next_u64();
        let mut again = Stream::new(7, "quilt/first");
        assert_eq!(first, again.next_u64());
        assert_eq!(first, PINNED_FIRST_DRAW);
    }

    const PINNED_FIRST_DRAW: u64 = 16478264901275159544;
}
