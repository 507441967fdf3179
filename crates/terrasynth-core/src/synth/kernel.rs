//! Cell-centred ×2 up-sampling kernels of the amplifier: the Catmull-Rom cubic of the original
//! residual correction, and Kaiser-windowed sincs whose responses fall much faster past the
//! parent's Nyquist frequency. A separable kernel images the parent's spectrum around the child's
//! pixel axes (the response at `(½ − f, 0)` is the kernel's response at `½ − f` times its response
//! at 0); Catmull-Rom passes 27 % of a frequency 0.3 cycles per child pixel, Kaiser-6 under 4 %,
//! which is what made the corrected levels ribbed along rows and columns (issue #12).
//!
//! Weights are constants (computed once in `f64` from the kernel formulas and rounded to `f32`),
//! so every machine uses the same bits.

use crate::dictionary::features::box_down2;

/// Integer division rounding towards −∞.
pub(crate) fn floor_div(a: i64, b: i64) -> i64 {
    a.div_euclid(b)
}

/// The up-sampling kernels a level can use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelKind {
    /// Catmull-Rom cubic (4 taps per phase), C¹.
    CatmullRom,
    /// Kaiser-windowed sinc, 4 lobes, β = 4 (8 taps per phase).
    Kaiser4,
    /// Kaiser-windowed sinc, 6 lobes, β = 5 (12 taps per phase).
    Kaiser6,
}

/// Catmull-Rom weights: child `2k` (at parent coordinate `k − 1/4`) reads parents
/// `k−2 .. k+1`; child `2k+1` (at `k + 1/4`) reads `k−1 .. k+2` with the mirrored weights.
const CR_EVEN: [f32; 4] = [-0.0234375, 0.2265625, 0.8671875, -0.0703125];

/// Kaiser-4 weights of child `2k`, parents `k−4 .. k+3`: sinc · I₀(4√(1 − (x/4)²))/I₀(4),
/// normalised to sum 1, then adjusted by the least change `a + b·d` (d: tap minus child position)
/// that makes their first moment zero, so that linear ramps are reproduced exactly (a windowed
/// sinc alone is off by 1 % of a cell's slope, alternately on even and odd children: ribbing).
const K4_EVEN: [f32; 8] = [
    -0.009_083_099,
    0.032_256_823,
    -0.091_820_48,
    0.283_253_22,
    0.897_776_07,
    -0.151_797_22,
    0.056_396_53,
    -0.016_981_835,
];

/// Kaiser-6 weights of child `2k`, parents `k−6 .. k+5`: sinc · I₀(5√(1 − (x/6)²))/I₀(5),
/// normalised and moment-adjusted like [`K4_EVEN`].
const K6_EVEN: [f32; 12] = [
    -0.002_432_664_2,
    0.008_753_669,
    -0.023_035_586,
    0.049_975_87,
    -0.106_128_32,
    0.290_069,
    0.897_790_13,
    -0.163_403_05,
    0.072_475_37,
    -0.034_198_06,
    0.014_851_691,
    -0.004_718_055_5,
];

/// Largest number of taps per phase.
const MAX_TAPS: usize = 12;

/// A cell-centred ×2 up-sampling kernel with `n` taps per phase: child `2k` reads parents
/// `k − n/2 .. k + n/2 − 1` with weights `even`; child `2k + 1` reads `k − n/2 + 1 .. k + n/2`
/// with `odd`, the mirror image of `even`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpKernel {
    kind: KernelKind,
    n: usize,
    even: [f32; MAX_TAPS],
    odd: [f32; MAX_TAPS],
}

impl UpKernel {
    /// The kernel of `kind`.
    pub const fn new(kind: KernelKind) -> Self {
        let (n, src): (usize, &[f32]) = match kind {
            KernelKind::CatmullRom => (4, &CR_EVEN),
            KernelKind::Kaiser4 => (8, &K4_EVEN),
            KernelKind::Kaiser6 => (12, &K6_EVEN),
        };
        let mut even = [0.0f32; MAX_TAPS];
        let mut odd = [0.0f32; MAX_TAPS];
        let mut t = 0;
        while t < n {
            even[t] = src[t];
            odd[t] = src[n - 1 - t];
            t += 1;
        }
        UpKernel { kind, n, even, odd }
    }

    /// Which kernel this is.
    pub fn kind(&self) -> KernelKind {
        self.kind
    }

    /// Taps per phase.
    pub fn taps_per_phase(&self) -> usize {
        self.n
    }

    /// Parent pixels one up-sampling reaches on each side of a child's own parent.
    pub fn reach(&self) -> i64 {
        (self.n / 2) as i64
    }

    /// First parent tap and the weights of child `x`.
    pub fn taps(&self, x: i64) -> (i64, &[f32]) {
        let k = floor_div(x, 2);
        let h = (self.n / 2) as i64;
        if x.rem_euclid(2) == 0 {
            (k - h, &self.even[..self.n])
        } else {
            (k - h + 1, &self.odd[..self.n])
        }
    }
}

/// The Catmull-Rom kernel.
pub const CATMULL_ROM: UpKernel = UpKernel::new(KernelKind::CatmullRom);

/// Up-sampling of a `lo × lo` patch to `2lo × 2lo` with `kernel`, clamped at the patch edges.
/// Bit-identical to [`upsample_patch_naive`]: every output sums its taps in tap order from 0.
pub fn upsample_patch(kernel: &UpKernel, lo_patch: &[f32], lo: usize, out: &mut [f32]) {
    let mut rows = Vec::new();
    upsample_patch_with(kernel, lo_patch, lo, out, &mut rows);
}

/// Largest high-resolution side whose tap table [`upsample_patch_with`] keeps on the stack.
const MAX_TABLE_SIDE: usize = 64;

/// [`upsample_patch`] with a reusable buffer for the horizontal pass.
#[inline(always)]
fn upsample_patch_with(
    kernel: &UpKernel,
    lo_patch: &[f32],
    lo: usize,
    out: &mut [f32],
    rows: &mut Vec<f32>,
) {
    // Small patches (the matcher's octave measure: 4² → 8²) take a table on a small stack.
    let small = 2 * lo <= SMALL_TABLE_SIDE;
    match (kernel.n, small) {
        (4, true) => upsample_patch_n::<4, SMALL_TABLE_SIDE>(kernel, lo_patch, lo, out, rows),
        (4, false) => upsample_patch_n::<4, MAX_TABLE_SIDE>(kernel, lo_patch, lo, out, rows),
        (8, _) => upsample_patch_n::<8, MAX_TABLE_SIDE>(kernel, lo_patch, lo, out, rows),
        _ => upsample_patch_n::<12, MAX_TABLE_SIDE>(kernel, lo_patch, lo, out, rows),
    }
}

/// The table side of [`upsample_patch_with`] for small patches.
const SMALL_TABLE_SIDE: usize = 16;

/// [`upsample_patch_with`] for a kernel of `N` taps per phase: the clamped tap indices and
/// weights of every high-resolution position are tabulated once, the vertical pass runs along
/// rows (each output still adds its taps in tap order, so the bits are those of the naive loop).
#[inline(always)]
fn upsample_patch_n<const N: usize, const SIDE: usize>(
    kernel: &UpKernel,
    lo_patch: &[f32],
    lo: usize,
    out: &mut [f32],
    rows: &mut Vec<f32>,
) {
    let hi = 2 * lo;
    if hi > SIDE || N != kernel.n || lo == 0 {
        upsample_patch_naive(kernel, lo_patch, lo, out);
        return;
    }
    let mut idx = [[0usize; N]; SIDE];
    let mut wts = [[0.0f32; N]; SIDE];
    for x in 0..hi {
        let (k, w) = kernel.taps(x as i64);
        for t in 0..N {
            idx[x][t] = (k + t as i64).clamp(0, lo as i64 - 1) as usize;
            wts[x][t] = w[t];
        }
    }
    rows.clear();
    rows.resize(lo * hi, 0.0);
    // Horizontal pass: lo rows × hi columns.
    for (src, dst) in lo_patch.chunks_exact(lo).zip(rows.chunks_exact_mut(hi)) {
        for ((d, ix), w) in dst.iter_mut().zip(&idx[..hi]).zip(&wts[..hi]) {
            let mut v = 0.0f32;
            for t in 0..N {
                v += w[t] * src[ix[t]];
            }
            *d = v;
        }
    }
    // Vertical pass, a whole row at a time.
    for (r, dst) in out.chunks_exact_mut(hi).take(hi).enumerate() {
        dst.fill(0.0);
        for t in 0..N {
            let w = wts[r][t];
            let src = &rows[idx[r][t] * hi..idx[r][t] * hi + hi];
            if hi <= SMALL_TABLE_SIDE {
                // Rows this short cost more to dispatch than to add.
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += w * s;
                }
            } else {
                crate::simd::add_scaled(dst, w, src);
            }
        }
    }
}

/// Reference implementation of [`upsample_patch`]: the plain loops over the kernel's taps.
pub fn upsample_patch_naive(kernel: &UpKernel, lo_patch: &[f32], lo: usize, out: &mut [f32]) {
    let hi = 2 * lo;
    let clamp = |k: i64| k.clamp(0, lo as i64 - 1) as usize;
    let mut rows = vec![0.0f32; lo * hi];
    // Horizontal pass: lo rows × hi columns.
    for r in 0..lo {
        for c in 0..hi {
            let (k, w) = kernel.taps(c as i64);
            let mut v = 0.0f32;
            for (t, wt) in w.iter().enumerate() {
                v += wt * lo_patch[r * lo + clamp(k + t as i64)];
            }
            rows[r * hi + c] = v;
        }
    }
    for r in 0..hi {
        let (k, w) = kernel.taps(r as i64);
        for c in 0..hi {
            let mut v = 0.0f32;
            for (t, wt) in w.iter().enumerate() {
                v += wt * rows[clamp(k + t as i64) * hi + c];
            }
            out[r * hi + c] = v;
        }
    }
}

/// Iterations of [`consistent_upsample_patch`] (each shrinks the box-average error of the result
/// several times).
pub const SPLIT_ITERATIONS: usize = 8;

/// Consistent up-sampling of a `lo × lo` patch: Catmull-Rom, then [`SPLIT_ITERATIONS`] passes of
/// `U += CR(lo − box(U))`, so that the 2×2 box averages of `out` reproduce `lo_patch` (to
/// rounding, away from the clamped edges).
pub fn consistent_upsample_patch(lo_patch: &[f32], lo: usize, out: &mut [f32]) {
    let hi = 2 * lo;
    upsample_patch(&CATMULL_ROM, lo_patch, lo, out);
    let mut down = vec![0.0f32; lo * lo];
    let mut up = vec![0.0f32; hi * hi];
    for _ in 0..SPLIT_ITERATIONS {
        box_down2(out, hi, &mut down);
        for (d, &l) in down.iter_mut().zip(lo_patch) {
            *d = l - *d;
        }
        upsample_patch(&CATMULL_ROM, &down, lo, &mut up);
        for (o, u) in out.iter_mut().zip(&up) {
            *o += u;
        }
    }
}

/// Buffers of [`finest_octave_rms`].
#[derive(Debug, Default)]
pub struct OctaveScratch {
    down: Vec<f32>,
    up: Vec<f32>,
    rows: Vec<f32>,
}

/// RMS of `x − CR(box(x))` over a `side × side` patch (`side` even): the energy of the patch's
/// finest octave, which [`Levers::roughness`](super::Levers::roughness) scales into the detail
/// amplitude of the next level.
pub fn finest_octave_rms(x: &[f32], side: usize, s: &mut OctaveScratch) -> f32 {
    finest_octave_rms_n([x], side, s)[0]
}

/// [`finest_octave_rms`] of `N` patches at once, each bit for bit as alone: every patch's sum of
/// squares runs in index order and the `N` sums interleave, so that their latencies overlap.
#[inline(always)]
pub fn finest_octave_rms_n<const N: usize>(
    xs: [&[f32]; N],
    side: usize,
    s: &mut OctaveScratch,
) -> [f32; N] {
    let n = side * side;
    if side < 2 {
        return [0.0; N];
    }
    s.down.resize((side / 2) * (side / 2), 0.0);
    s.up.resize(N * n, 0.0);
    let mut ok = [false; N];
    for ((x, up), ok) in xs.iter().zip(s.up.chunks_exact_mut(n)).zip(&mut ok) {
        if x.len() == n {
            box_down2(x, side, &mut s.down);
            upsample_patch_with(&CATMULL_ROM, &s.down, side / 2, up, &mut s.rows);
            *ok = true;
        }
    }
    let ups: [&[f32]; N] = std::array::from_fn(|m| &s.up[m * n..(m + 1) * n]);
    // A patch of the wrong length is measured against its own (stale) up-sampling: 0, unused.
    let xs: [&[f32]; N] = std::array::from_fn(|m| if ok[m] { xs[m] } else { ups[m] });
    let mut ss = [0.0f64; N];
    for i in 0..n {
        for ((acc, x), up) in ss.iter_mut().zip(&xs).zip(&ups) {
            let d = f64::from(x[i]) - f64::from(up[i]);
            *acc += d * d;
        }
    }
    let mut rms = [0.0f32; N];
    for ((r, &ss), &ok) in rms.iter_mut().zip(&ss).zip(&ok) {
        if ok {
            *r = (ss / n as f64).sqrt() as f32;
        }
    }
    rms
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math;

    /// The formulas the constants were computed from, in `f64`.
    fn reference(kind: KernelKind) -> Vec<f64> {
        fn sinc(x: f64) -> f64 {
            if x == 0.0 {
                1.0
            } else {
                math::sin(std::f64::consts::PI * x) / (std::f64::consts::PI * x)
            }
        }
        fn i0(x: f64) -> f64 {
            let (mut s, mut t) = (1.0, 1.0);
            for k in 1..40 {
                t *= (x / 2.0 / k as f64).powi(2);
                s += t;
            }
            s
        }
        let (n, h): (usize, Box<dyn Fn(f64) -> f64>) = match kind {
            KernelKind::CatmullRom => (
                4,
                Box::new(|x: f64| {
                    let x = x.abs();
                    if x <= 1.0 {
                        (1.5 * x - 2.5) * x * x + 1.0
                    } else if x < 2.0 {
                        ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0
                    } else {
                        0.0
                    }
                }),
            ),
            KernelKind::Kaiser4 => (
                8,
                Box::new(|x: f64| sinc(x) * i0(4.0 * (1.0 - (x / 4.0).powi(2)).sqrt()) / i0(4.0)),
            ),
            KernelKind::Kaiser6 => (
                12,
                Box::new(|x: f64| sinc(x) * i0(5.0 * (1.0 - (x / 6.0).powi(2)).sqrt()) / i0(5.0)),
            ),
        };
        let half = (n / 2) as f64;
        let w: Vec<f64> = (0..n).map(|t| h(half - t as f64 - 0.25)).collect();
        let s: f64 = w.iter().sum();
        let w: Vec<f64> = w.iter().map(|v| v / s).collect();
        if kind == KernelKind::CatmullRom {
            return w;
        }
        // Least change a + b·d zeroing the first moment (d: tap minus child position).
        let d: Vec<f64> = (0..n).map(|t| t as f64 - half + 0.25).collect();
        let e: f64 = w.iter().zip(&d).map(|(a, b)| a * b).sum();
        let (s1, s2) = (d.iter().sum::<f64>(), d.iter().map(|x| x * x).sum::<f64>());
        let det = n as f64 * s2 - s1 * s1;
        let (a, b) = (s1 * e / det, -(n as f64) * e / det);
        w.iter().zip(&d).map(|(wi, di)| wi + a + b * di).collect()
    }

    #[test]
    fn constants_match_their_formulas_and_reproduce_ramps() {
        for kind in [
            KernelKind::CatmullRom,
            KernelKind::Kaiser4,
            KernelKind::Kaiser6,
        ] {
            let k = UpKernel::new(kind);
            for (a, b) in k.taps(0).1.iter().zip(reference(kind)) {
                assert!((f64::from(*a) - b).abs() < 1e-7, "{kind:?}: {a} vs {b}");
            }
            // A linear ramp p(k) = k is reproduced: child x lies at (x + 0.5)/2 − 0.5.
            for x in [-7i64, -2, 0, 1, 6, 11] {
                let (k0, w) = k.taps(x);
                let v: f64 = w
                    .iter()
                    .enumerate()
                    .map(|(t, &wt)| f64::from(wt) * (k0 + t as i64) as f64)
                    .sum();
                let want = (x as f64 + 0.5) / 2.0 - 0.5;
                assert!(
                    (v - want).abs() < 2e-6 * (1.0 + want.abs()),
                    "{kind:?} x={x}: {v} vs {want}"
                );
            }
        }
    }

    proptest::proptest! {
        /// The tabulated up-sampling gives the naive loops' bits for every kernel and size.
        #[test]
        fn upsample_patch_equals_the_naive_loops(
            lo in 1usize..12,
            kind in 0usize..3,
            values in proptest::collection::vec(-3000.0f32..3000.0, 144),
        ) {
            let kernel = UpKernel::new(
                [KernelKind::CatmullRom, KernelKind::Kaiser4, KernelKind::Kaiser6][kind],
            );
            let x = &values[..lo * lo];
            let (mut fast, mut naive) = (vec![0.0f32; 4 * lo * lo], vec![1.0f32; 4 * lo * lo]);
            upsample_patch(&kernel, x, lo, &mut fast);
            upsample_patch_naive(&kernel, x, lo, &mut naive);
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            proptest::prop_assert_eq!(bits(&fast), bits(&naive));
        }
    }

    #[test]
    fn consistent_upsampling_reproduces_box_averages() {
        let lo: Vec<f32> = (0..64).map(|i| ((i * 37) % 11) as f32 - 5.0).collect();
        let mut hi = vec![0.0f32; 256];
        consistent_upsample_patch(&lo, 8, &mut hi);
        let mut down = vec![0.0f32; 64];
        box_down2(&hi, 16, &mut down);
        // Interior cells (the clamped edges converge more slowly).
        for r in 2..6 {
            for c in 2..6 {
                let (a, b) = (down[r * 8 + c], lo[r * 8 + c]);
                assert!((a - b).abs() < 0.05, "({r},{c}): {a} vs {b}");
            }
        }
    }
}
