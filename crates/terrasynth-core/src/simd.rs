//! CPU feature detection and the one mechanism that runs a numeric kernel in AVX2 and AVX-512
//! builds ([`Isa::run`]): matching's dot products and scan, the pursuit's next-atom scan, the
//! amplifier's patch measures and blend strips, the gradient reconstruction, the D8 row update
//! and [`add_scaled`]. Those kernels compile the same Rust loops with the wider vectors enabled —
//! the same IEEE multiplications and additions in the same order (no fused multiply-add) — so
//! their results are bit-identical to the baseline build's; their property tests compare them
//! with a naive reference.

/// The widest instruction set a kernel's build may use on this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// The target's baseline (SSE2 on x86-64).
    Baseline,
    /// AVX2 (256-bit vectors).
    Avx2,
    /// AVX-512 foundation (512-bit vectors).
    Avx512,
}

impl Isa {
    /// The widest of [`Isa`] this CPU runs.
    #[cfg(target_arch = "x86_64")]
    pub fn detect() -> Self {
        if std::arch::is_x86_feature_detected!("avx512f") {
            Isa::Avx512
        } else if std::arch::is_x86_feature_detected!("avx2") {
            Isa::Avx2
        } else {
            Isa::Baseline
        }
    }

    /// The baseline (no wider build off x86-64).
    #[cfg(not(target_arch = "x86_64"))]
    pub fn detect() -> Self {
        Isa::Baseline
    }
}

impl Isa {
    /// [`Isa::detect`], detected once per process.
    pub fn current() -> Self {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(Isa::detect)
    }

    /// Every build this CPU runs, narrowest first (for tests comparing the builds).
    pub fn builds() -> impl Iterator<Item = Isa> {
        [Isa::Baseline, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|&isa| isa <= Isa::current())
    }
}

impl Isa {
    /// Runs `kernel` in the build of the narrower of `self` and [`Isa::current`], and tells it
    /// which build it runs in (for kernels whose block sizes follow the registers).
    ///
    /// The wider builds are `kernel` inlined into a function that enables the wider vectors, so
    /// `kernel` must be an `#[inline(always)]` closure calling `#[inline(always)]` code: what is
    /// not inlined runs in the baseline build (the same result, only slower). Every kernel run
    /// this way does the same IEEE operations in the same order in every build (no fused
    /// multiply-add), so its result is bit-identical to the baseline build's.
    ///
    /// In a profile every kernel's wider build is a `simd::run_avx512` (or `run_avx2`) symbol:
    /// `perf report --sort symbol,srcline`, or a DWARF call graph (`perf record --call-graph
    /// dwarf`), names the kernel inlined in it.
    #[inline(always)]
    pub fn run<R>(self, kernel: impl FnOnce(Isa) -> R) -> R {
        #[cfg(target_arch = "x86_64")]
        match self.min(Isa::current()) {
            // SAFETY: `Isa::current` is what the CPU reports, and the build never exceeds it.
            Isa::Avx512 => return unsafe { run_avx512(kernel) },
            Isa::Avx2 => return unsafe { run_avx2(kernel) },
            Isa::Baseline => {}
        }
        kernel(Isa::Baseline)
    }
}

/// `kernel` compiled with AVX-512 foundation enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn run_avx512<R>(kernel: impl FnOnce(Isa) -> R) -> R {
    kernel(Isa::Avx512)
}

/// `kernel` compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_avx2<R>(kernel: impl FnOnce(Isa) -> R) -> R {
    kernel(Isa::Avx2)
}

/// `acc[i] += w · src[i]` over the shorter of the two slices: one multiplication and one
/// addition per element (never fused), hence the same bits in every build; the widest build
/// [`Isa::current`] allows.
#[inline]
pub fn add_scaled(acc: &mut [f32], w: f32, src: &[f32]) {
    Isa::current().run(
        #[inline(always)]
        |_| {
            for (a, &v) in acc.iter_mut().zip(src) {
                *a += w * v;
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math;

    #[test]
    fn add_scaled_equals_the_plain_loop_bit_for_bit() {
        for n in [0usize, 1, 7, 16, 33, 1000] {
            let src: Vec<f32> = (0..n).map(|i| math::sinf(i as f32 * 0.37) * 1e3).collect();
            let start: Vec<f32> = (0..n).map(|i| math::cosf(i as f32 * 0.11) * 7.0).collect();
            let (mut fast, mut plain) = (start.clone(), start.clone());
            add_scaled(&mut fast, 0.3137, &src);
            for (p, &v) in plain.iter_mut().zip(&src) {
                *p += 0.3137 * v;
            }
            assert!(fast
                .iter()
                .zip(&plain)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            // Only the overlap is touched.
            let mut short = start.clone();
            add_scaled(&mut short, 2.0, &src[..n / 2]);
            assert!(short[n / 2..]
                .iter()
                .zip(&start[n / 2..])
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
}
