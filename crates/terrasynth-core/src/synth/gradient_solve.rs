//! The gradient amplifier's reconstruction (issue #20): heights of a `T × T` block of child
//! pixels from its gradient field and its parent's control points, by a Poisson solve whose
//! inverse is precomputed per tile size.
//!
//! The block's heights `h` minimise `Σ (h[x+1] − h[x] − gx)² + Σ (h[y+1] − h[y] − gy)²` over its
//! `T(T−1)` inner x-edges and `(T−1)T` inner y-edges subject to `box2(h) = p` on each of its
//! `(T/2)²` 2×2 blocks. The KKT system `[L Cᵀ; C 0] [h; λ] = [Aᵀg; p]` (`L = AᵀA`, the Neumann
//! Laplacian, `C` the box averages) is inverted once ([`Reconstruction::new`]), so every output
//! value is a fixed linear combination of the `2T(T−1) + T²/4` inputs
//! ([`Reconstruction::apply`], summed in input order). [`solve_naive`] solves the same system
//! densely for each call: the naive twin the property tests compare against.

use super::error::SynthError;
use crate::simd::Isa;

/// The precomputed reconstruction operator of one tile size.
#[derive(Clone, Debug)]
pub struct Reconstruction {
    t: usize,
    /// `inputs × T²`: for each input, its weight in every output (input-major, so
    /// [`Reconstruction::apply`] is a sequence of contiguous multiply-adds).
    weights: Vec<f32>,
    /// The widest build of [`Reconstruction::apply`] this CPU runs.
    isa: Isa,
}

/// Number of inputs of a block of side `t`: `gx` (`t·(t−1)`, row-major), `gy` (`(t−1)·t`), `p`
/// (`(t/2)²`).
pub fn input_count(t: usize) -> usize {
    2 * t * (t - 1) + (t / 2) * (t / 2)
}

/// The KKT matrix (`(n + m)²`, row-major, `n = t²`, `m = (t/2)²`) of a block of side `t`.
fn kkt(t: usize) -> Vec<f64> {
    let n = t * t;
    let m = (t / 2) * (t / 2);
    let k = n + m;
    let mut a = vec![0.0f64; k * k];
    let mut edge = |i: usize, j: usize| {
        a[i * k + i] += 1.0;
        a[j * k + j] += 1.0;
        a[i * k + j] -= 1.0;
        a[j * k + i] -= 1.0;
    };
    for r in 0..t {
        for c in 0..t {
            if c + 1 < t {
                edge(r * t + c, r * t + c + 1);
            }
            if r + 1 < t {
                edge(r * t + c, (r + 1) * t + c);
            }
        }
    }
    let h = t / 2;
    for br in 0..h {
        for bc in 0..h {
            let row = n + br * h + bc;
            for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let i = (2 * br + dr) * t + 2 * bc + dc;
                a[row * k + i] = 0.25;
                a[i * k + row] = 0.25;
            }
        }
    }
    a
}

/// The right-hand side `[Aᵀg; p]` of the KKT system for `inputs` (laid out as
/// [`input_count`] says).
fn rhs(t: usize, inputs: &[f64]) -> Vec<f64> {
    let n = t * t;
    let mut b = vec![0.0f64; n + (t / 2) * (t / 2)];
    let nx = t * (t - 1);
    for r in 0..t {
        for c in 0..t - 1 {
            let g = inputs[r * (t - 1) + c];
            b[r * t + c] -= g;
            b[r * t + c + 1] += g;
        }
    }
    for r in 0..t - 1 {
        for c in 0..t {
            let g = inputs[nx + r * t + c];
            b[r * t + c] -= g;
            b[(r + 1) * t + c] += g;
        }
    }
    b[n..].copy_from_slice(&inputs[2 * nx..]);
    b
}

/// Solves `a x = b` (`a`: `k × k` row-major, consumed) by Gaussian elimination with partial
/// pivoting; `None` when singular.
fn gauss_solve(mut a: Vec<f64>, mut b: Vec<f64>, k: usize, cols: usize) -> Option<Vec<f64>> {
    for col in 0..k {
        let piv =
            (col..k).max_by(|&i, &j| a[i * k + col].abs().total_cmp(&a[j * k + col].abs()))?;
        if a[piv * k + col].abs() < 1e-12 {
            return None;
        }
        if piv != col {
            for c in 0..k {
                a.swap(piv * k + c, col * k + c);
            }
            for c in 0..cols {
                b.swap(piv * cols + c, col * cols + c);
            }
        }
        let d = a[col * k + col];
        for r in 0..k {
            if r == col {
                continue;
            }
            let f = a[r * k + col] / d;
            if f == 0.0 {
                continue;
            }
            for c in col..k {
                a[r * k + c] -= f * a[col * k + c];
            }
            for c in 0..cols {
                b[r * cols + c] -= f * b[col * cols + c];
            }
        }
    }
    for r in 0..k {
        let d = a[r * k + r];
        for c in 0..cols {
            b[r * cols + c] /= d;
        }
    }
    Some(b)
}

/// The heights of a block of side `t` from `inputs` by a dense solve of the KKT system (`f64`):
/// the naive twin of [`Reconstruction::apply`].
pub fn solve_naive(t: usize, inputs: &[f32]) -> Option<Vec<f64>> {
    let k = t * t + (t / 2) * (t / 2);
    let inputs: Vec<f64> = inputs.iter().map(|&v| f64::from(v)).collect();
    let x = gauss_solve(kkt(t), rhs(t, &inputs), k, 1)?;
    Some(x[..t * t].to_vec())
}

impl Reconstruction {
    /// The operator of blocks of side `t` (a multiple of 4, 4–16).
    pub fn new(t: usize) -> Result<Self, SynthError> {
        if !(4..=16).contains(&t) || t % 4 != 0 {
            return Err(SynthError::BadWindow(format!(
                "gradient tile size {t} must be a multiple of 4 in 4–16"
            )));
        }
        let n = t * t;
        let k = n + (t / 2) * (t / 2);
        // The inverse of the KKT matrix: solve for the identity.
        let mut eye = vec![0.0f64; k * k];
        for i in 0..k {
            eye[i * k + i] = 1.0;
        }
        let inv = gauss_solve(kkt(t), eye, k, k)
            .ok_or_else(|| SynthError::BadWindow("singular reconstruction system".into()))?;
        let ni = input_count(t);
        let mut weights = vec![0.0f32; ni * n];
        // Column j of [Aᵀ | 0; 0 | I] applied through the inverse: each input's weights.
        let mut unit = vec![0.0f64; ni];
        for j in 0..ni {
            unit[j] = 1.0;
            let b = rhs(t, &unit);
            unit[j] = 0.0;
            for o in 0..n {
                let row = &inv[o * k..(o + 1) * k];
                let v: f64 = row.iter().zip(&b).map(|(a, b)| a * b).sum();
                weights[j * n + o] = v as f32;
            }
        }
        Ok(Reconstruction {
            t,
            weights,
            isa: Isa::detect(),
        })
    }

    /// The block side.
    pub fn tile(&self) -> usize {
        self.t
    }

    /// The heights of a block (`out`, `t²`, row-major) from `inputs` ([`input_count`]); each
    /// output sums its terms in input order. Dispatches to a kernel of the block's size that
    /// keeps the outputs in registers, compiled for AVX2 where the CPU has it (the same IEEE
    /// multiplications and additions in the same order, hence the same bits); [`apply_naive`]
    /// is its reference.
    #[inline]
    pub fn apply(&self, inputs: &[f32], out: &mut [f32]) {
        let isa = self.isa;
        match self.t {
            4 => apply_sized::<16>(&self.weights, inputs, out, isa),
            8 => apply_sized::<64>(&self.weights, inputs, out, isa),
            12 => apply_sized::<144>(&self.weights, inputs, out, isa),
            16 => apply_sized::<256>(&self.weights, inputs, out, isa),
            _ => apply_naive(&self.weights, self.t * self.t, inputs, out),
        }
    }

    /// The operator's weights, input-major (`inputs × t²`).
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }
}

/// `out = Σ_j inputs[j] · weights[j·n ..][..n]`, each output summed in input order: the
/// reference of the sized kernels.
pub fn apply_naive(weights: &[f32], n: usize, inputs: &[f32], out: &mut [f32]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    for (col, &x) in weights.chunks_exact(n).zip(inputs) {
        for (o, &w) in out.iter_mut().zip(col) {
            *o += w * x;
        }
    }
}

/// [`apply_naive`] for `N` outputs with the accumulators in a fixed-size array (registers).
#[inline(always)]
fn apply_fixed<const N: usize>(weights: &[f32], inputs: &[f32], out: &mut [f32]) {
    let mut acc = [0.0f32; N];
    for (col, &x) in weights.chunks_exact(N).zip(inputs) {
        let col: &[f32; N] = match col.try_into() {
            Ok(c) => c,
            Err(_) => return,
        };
        for k in 0..N {
            acc[k] += col[k] * x;
        }
    }
    for (o, a) in out.iter_mut().zip(acc) {
        *o = a;
    }
}

/// [`apply_fixed`] in the widest build `isa` allows (no fused multiply-add: the same bits).
fn apply_sized<const N: usize>(weights: &[f32], inputs: &[f32], out: &mut [f32], isa: Isa) {
    isa.run(
        #[inline(always)]
        |_| apply_fixed::<N>(weights, inputs, out),
    );
}
