//! Wider vector instructions where the processor has them, with the same bits.
//!
//! The crate is built for the baseline x86-64 (two doubles per vector register). Some hot loops
//! (the cross products of [`super::gram`], the creep filter of `effect::creep`) keep many
//! independent sums side by side; compiled for AVX2 (four doubles per register) they run
//! faster (the cross products of 56 columns on one core of the development machine: 13.4
//! against 9.3 GFlop/s). The network's kernels (`narx::kernel`) have AVX2 builds of their own.
//! [`wide`] runs a closure compiled for AVX2 when the processor reports it (checked once, then
//! cached by the standard library), else as built. Both versions do the same IEEE operations in the same
//! order on every lane (no fused multiply-add: Rust never contracts `a * b + c`), so the
//! results are the same bits on every machine.

/// Runs `f`, compiled for AVX2 where the processor has it. Mark the closure
/// `#[inline(always)]` (and the functions it calls in the hot loop): only code inlined into
/// the AVX2 build is compiled for it.
#[inline(always)]
pub fn wide<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if uses_avx2() {
            // SAFETY: the processor supports AVX2 (checked just above).
            return unsafe { avx2(f) };
        }
    }
    f()
}

/// Whether the AVX2 builds run here (same results, only faster): [`wide`] and the network's
/// kernels (`narx::kernel`).
pub fn uses_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wide_version_gives_the_same_bits() {
        let a: Vec<f64> = (0..1001).map(|i| (i as f64 * 0.37).sin()).collect();
        let b: Vec<f64> = (0..1001).map(|i| (i as f64 * 0.11).cos()).collect();
        let plain = crate::numeric::gram::dot(&a, &b);
        let wide = wide(|| crate::numeric::gram::dot(&a, &b));
        assert_eq!(plain.to_bits(), wide.to_bits());
    }
}
