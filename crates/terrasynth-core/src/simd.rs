//! CPU feature detection shared by the numeric kernels that have an AVX2 or AVX-512 build
//! (matching's dot products, the gradient reconstruction). Those kernels compile the same Rust
//! loops with the wider vectors enabled — wider vectors, the same IEEE multiplications and additions in the same order (no
//! fused multiply-add) — so their results are bit-identical to the baseline build's.

/// Whether this CPU runs AVX2 code.
#[cfg(target_arch = "x86_64")]
pub fn avx2_available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// Whether this CPU runs AVX2 code (never, off x86-64).
#[cfg(not(target_arch = "x86_64"))]
pub fn avx2_available() -> bool {
    false
}

/// Whether this CPU runs AVX-512 (foundation) code.
#[cfg(target_arch = "x86_64")]
pub fn avx512_available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
}

/// Whether this CPU runs AVX-512 code (never, off x86-64).
#[cfg(not(target_arch = "x86_64"))]
pub fn avx512_available() -> bool {
    false
}
