//! CPU feature detection shared by the numeric kernels that have AVX2 and AVX-512 builds
//! (matching's dot products and scan, the pursuit's next-atom scan, the amplifier's patch
//! measures and blend strips, the gradient reconstruction). Those kernels compile the same Rust
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

impl Isa {
    /// [`Isa::detect`], detected once per process.
    pub fn current() -> Self {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(Isa::detect)
    }
}

/// `acc[i] += w · src[i]` over the shorter of the two slices: one multiplication and one
/// addition per element (never fused), hence the same bits in every build; the widest build
/// [`Isa::current`] allows.
#[inline]
pub fn add_scaled(acc: &mut [f32], w: f32, src: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    match Isa::current() {
        // SAFETY: `Isa::detect` returns these only when the CPU reports the feature.
        Isa::Avx512 => return unsafe { add_scaled_avx512(acc, w, src) },
        Isa::Avx2 => return unsafe { add_scaled_avx2(acc, w, src) },
        Isa::Baseline => {}
    }
    add_scaled_plain(acc, w, src);
}

#[inline(always)]
fn add_scaled_plain(acc: &mut [f32], w: f32, src: &[f32]) {
    for (a, &v) in acc.iter_mut().zip(src) {
        *a += w * v;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn add_scaled_avx2(acc: &mut [f32], w: f32, src: &[f32]) {
    add_scaled_plain(acc, w, src);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn add_scaled_avx512(acc: &mut [f32], w: f32, src: &[f32]) {
    add_scaled_plain(acc, w, src);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn add_scaled_equals_the_plain_loop_bit_for_bit() {
        for n in [0usize, 1, 7, 16, 33, 1000] {
            let src: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin() * 1e3).collect();
            let start: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos() * 7.0).collect();
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
