//! CPU feature detection shared by the numeric kernels that have AVX2 and AVX-512 builds
//! (matching's dot products, the gradient reconstruction). Those kernels compile the same Rust
//! loops with the wider vectors enabled — the same IEEE multiplications and additions in the same
//! order (no fused multiply-add) — so their results are bit-identical to the baseline build's;
//! their property tests compare them with a naive reference.

/// The widest instruction set a kernel's build may use on this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
