//! Wider vector instructions where the processor has them, with the same bits.
//!
//! The crate is built for the baseline x86-64 (two doubles per vector register). Some hot loops
//! (the cross products of [`super::gram`], the creep filter of `effect::creep`) keep many
//! independent sums side by side; compiled for AVX2 (four doubles per register) they run
//! faster (the cross products of 56 columns on one core of the development machine: 13.4
//! against 9.3 GFlop/s). The network's kernels (`narx::kernel`) have AVX2 builds of their own.
//! [`wide`] runs a closure compiled for AVX2 when [`level`] allows it (the processor's widest
//! level, found once, capped by [`SIMD_VARIABLE`]), else as built. Every level does the same
//! IEEE operations in the same order on every lane (no fused multiply-add: Rust never
//! contracts `a * b + c`), so the results are the same bits on every machine.

/// The environment variable that caps the instructions used: `baseline` (the crate as built),
/// `avx2`, `avx512` or unset (the widest the processor has; another value is warned about). The results are the same bits at every
/// level; the switch is there to check that on one machine, and to time the levels.
pub const SIMD_VARIABLE: &str = "HYSTBENCH_SIMD";

/// The instruction sets the hot loops may use, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// The baseline x86-64 (or another architecture): two doubles per register.
    Baseline,
    /// AVX2: four doubles per register.
    Avx2,
    /// AVX-512F: eight doubles per register, 32 registers.
    Avx512,
}

/// The level in use: the processor's widest, capped by [`SIMD_VARIABLE`] (read once).
pub fn level() -> Level {
    static LEVEL: std::sync::OnceLock<Level> = std::sync::OnceLock::new();
    *LEVEL.get_or_init(|| {
        let cap = match std::env::var(SIMD_VARIABLE).as_deref() {
            Ok("baseline") => Level::Baseline,
            Ok("avx2") => Level::Avx2,
            Ok("avx512") | Ok("") | Err(_) => Level::Avx512,
            Ok(other) => {
                eprintln!(
                    "warning: {SIMD_VARIABLE}={other} is not one of baseline, avx2, avx512: \
                     the widest level the processor has is used"
                );
                Level::Avx512
            }
        };
        processor_level().min(cap)
    })
}

fn processor_level() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        // AVX-512 implies AVX2 on every processor made, but a virtual machine may mask one
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx2")
        {
            return Level::Avx512;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return Level::Avx2;
        }
    }
    Level::Baseline
}

/// Whether the AVX2 builds run here: [`wide`] and the network's kernels (`narx::kernel`).
pub fn uses_avx2() -> bool {
    level() >= Level::Avx2
}

/// Whether the AVX-512 kernels run here (the cross products' tiles, the resonator's lanes).
pub fn uses_avx512() -> bool {
    level() >= Level::Avx512
}

/// Runs `f`, compiled for AVX2 where the processor has it. Mark the closure
/// `#[inline(always)]` (and the functions it calls in the hot loop): only code inlined into
/// the AVX2 build is compiled for it.
#[inline(always)]
pub fn wide<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if uses_avx2() {
            // SAFETY: the processor supports AVX2 (`processor_level`).
            return unsafe { avx2(f) };
        }
    }
    f()
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
