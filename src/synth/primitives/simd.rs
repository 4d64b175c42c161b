//! Wider vectors for hot loops, where the CPU has them.
//!
//! The crate is built for baseline x86-64, so the compiler may only use SSE2's 16-byte vectors
//! unless a function is compiled for more and called after a run-time check. [`with_avx2`] runs a
//! closure inside such a function: the closure's loops (and whatever is inlined into it) may then
//! use AVX2's 32-byte vectors. The arithmetic is the same either way: Rust never fuses a multiply
//! and an add on its own, and integer and IEEE operations give the same bits at any width, so
//! the results do not depend on the CPU (the tests compare against plain scalar references).

/// Whether this CPU has AVX2, detected once.
#[cfg(target_arch = "x86_64")]
pub fn has_avx2() -> bool {
    static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX2.get_or_init(|| std::arch::is_x86_feature_detected!("avx2"))
}

/// Runs `f`, compiled for AVX2 where the CPU has it. Only worth it for a closure that holds
/// (or inlines) a whole hot loop, marked `#[inline(always)]` so that it is compiled into the
/// AVX2 function rather than called from it: a call out of it runs baseline code. With
/// `zone_ssd`'s AVX2 kernel, this is the crate's only `unsafe` code.
#[allow(unsafe_code)]
#[inline]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        #[target_feature(enable = "avx2")]
        fn wide<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        // SAFETY: AVX2 was just found on this CPU, so the instructions `wide` is compiled with
        // exist; it has no other precondition.
        return unsafe { wide(f) };
    }
    f()
}

#[cfg(test)]
mod tests {
    use super::with_avx2;

    /// The same float loop gives the same bits inside and outside (whether or not this CPU has
    /// AVX2): no fused multiply-adds, no reassociation.
    #[test]
    fn a_float_loop_gives_the_same_bits_either_way() {
        let a: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.11).cos()).collect();
        let run = |a: &[f32], b: &[f32]| -> Vec<f32> { a.iter().zip(b).map(|(x, y)| x * y + x - y / 3.0).collect() };
        let plain = run(&a, &b);
        let wide = with_avx2(
            #[inline(always)]
            || run(&a, &b),
        );
        assert_eq!(plain.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), wide.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        assert_eq!(with_avx2(|| 41 + 1), 42);
    }
}
