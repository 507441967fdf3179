//! Orthogonal Matching Pursuit (OMP): the sparse code `x` of a signal `y` over a dictionary of
//! unit-norm atoms `D` with at most `s` non-zero coefficients, chosen greedily — at each step the
//! atom most correlated with the residual joins the support, and the coefficients of the support
//! are the least-squares fit of `y` (so the residual stays orthogonal to every chosen atom).
//!
//! Two implementations compute the same thing:
//!
//! - [`omp_naive`]: the textbook form — the residual `r = y − D_S x_S` is formed explicitly, its
//!   correlation with every atom computed, and the normal equations of the support solved from
//!   scratch by Gaussian elimination at every step;
//! - [`Omp`]: "batch OMP" — the Gram matrix `G = DᵀD` is computed once per dictionary, `Dᵀy` once
//!   per signal, correlations are updated as `Dᵀy − G_S x_S` and the normal equations are solved
//!   through a Cholesky factor extended by one row per step, so a code costs `O(K·s + s³)` after
//!   the `O(K·n)` product instead of `O(K·n·s)`.
//!
//! Both work in `f64`, sum in index order and break ties towards the lowest atom index, so they
//! are deterministic; they agree on the support and, to rounding, on the coefficients (property
//! tests). Atoms already in the support are never chosen again; a step whose best correlation is
//! zero (or whose atom is numerically dependent on the support) ends the pursuit early.

use crate::simd::Isa;

/// A sparse code: `(atom index, coefficient)` pairs in the order the atoms were chosen.
pub type SparseCode = Vec<(usize, f64)>;

/// Correlations smaller than this (relative to `‖y‖`) end the pursuit: the residual is spent.
const TINY: f64 = 1e-12;

/// The naive reference: `atoms` is `k × n` (atom-major, each unit norm), `y` has `n` values.
pub fn omp_naive(atoms: &[f32], n: usize, y: &[f32], sparsity: usize) -> SparseCode {
    omp_naive_from(atoms, n, y, None, sparsity)
}

/// [`omp_naive`] whose first atom is `first` when given (chosen by another rule, e.g. the
/// amplifier's matcher), the others chosen by the pursuit.
pub fn omp_naive_from(
    atoms: &[f32],
    n: usize,
    y: &[f32],
    first: Option<usize>,
    sparsity: usize,
) -> SparseCode {
    let k = atoms.len().checked_div(n).unwrap_or(0);
    let atom = |j: usize| &atoms[j * n..(j + 1) * n];
    let norm_y = y
        .iter()
        .map(|&v| f64::from(v) * f64::from(v))
        .sum::<f64>()
        .sqrt();
    let mut support: Vec<usize> = Vec::new();
    let mut coefs: Vec<f64> = Vec::new();
    let mut residual: Vec<f64> = y.iter().map(|&v| f64::from(v)).collect();
    for _ in 0..sparsity.min(k) {
        let mut best = None;
        let mut best_abs = 0.0f64;
        for j in 0..k {
            if support.contains(&j) {
                continue;
            }
            let c: f64 = atom(j)
                .iter()
                .zip(&residual)
                .map(|(&a, &r)| f64::from(a) * r)
                .sum();
            if c.abs() > best_abs {
                best_abs = c.abs();
                best = Some(j);
            }
        }
        let forced = first.filter(|&f| support.is_empty() && f < k);
        let Some(j) = forced.or(best) else { break };
        if forced.is_none() && best_abs <= TINY * norm_y.max(f64::MIN_POSITIVE) {
            break;
        }
        support.push(j);
        // Normal equations of the support, solved by Gaussian elimination with partial pivoting.
        let m = support.len();
        let mut a = vec![0.0f64; m * m];
        let mut b = vec![0.0f64; m];
        for (p, &jp) in support.iter().enumerate() {
            for (q, &jq) in support.iter().enumerate() {
                a[p * m + q] = atom(jp)
                    .iter()
                    .zip(atom(jq))
                    .map(|(&u, &v)| f64::from(u) * f64::from(v))
                    .sum();
            }
            b[p] = atom(jp)
                .iter()
                .zip(y)
                .map(|(&u, &v)| f64::from(u) * f64::from(v))
                .sum();
        }
        match solve(&mut a, &mut b, m) {
            Some(x) => coefs = x,
            None => {
                support.pop();
                break;
            }
        }
        for (i, r) in residual.iter_mut().enumerate() {
            let mut fit = 0.0f64;
            for (&jp, &x) in support.iter().zip(&coefs) {
                fit += f64::from(atom(jp)[i]) * x;
            }
            *r = f64::from(y[i]) - fit;
        }
    }
    support.into_iter().zip(coefs).collect()
}

/// Solves `a x = b` (`m × m`) by Gaussian elimination with partial pivoting; `None` when `a` is
/// numerically singular.
pub fn solve(a: &mut [f64], b: &mut [f64], m: usize) -> Option<Vec<f64>> {
    for col in 0..m {
        let mut piv = col;
        for r in col + 1..m {
            if a[r * m + col].abs() > a[piv * m + col].abs() {
                piv = r;
            }
        }
        if a[piv * m + col].abs() < 1e-10 {
            return None;
        }
        if piv != col {
            for c in 0..m {
                a.swap(piv * m + c, col * m + c);
            }
            b.swap(piv, col);
        }
        for r in col + 1..m {
            let f = a[r * m + col] / a[col * m + col];
            for c in col..m {
                a[r * m + c] -= f * a[col * m + c];
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = vec![0.0f64; m];
    for r in (0..m).rev() {
        let mut s = b[r];
        for c in r + 1..m {
            s -= a[r * m + c] * x[c];
        }
        x[r] = s / a[r * m + r];
    }
    Some(x)
}

/// Batch OMP over one dictionary: its atoms and their Gram matrix, computed once.
#[derive(Clone, Debug)]
pub struct Omp {
    n: usize,
    k: usize,
    /// `k × n`, atom-major, as given.
    atoms: Vec<f32>,
    /// `k × k` Gram matrix `G = DᵀD` in `f64`.
    gram: Vec<f64>,
}

/// Reusable buffers of [`Omp::code`].
#[derive(Clone, Debug, Default)]
pub struct OmpScratch {
    dty: Vec<f64>,
    chol: Vec<f64>,
    rhs: Vec<f64>,
    tmp: Vec<f64>,
    coefs: Vec<f64>,
    support: Vec<usize>,
    /// 0 for every atom, NaN for those of the support while a pursuit runs (see [`next_atom`]).
    excluded: Vec<f64>,
    code: SparseCode,
}

impl Omp {
    /// The pursuit over `atoms` (`k × n`, atom-major, unit-norm rows).
    pub fn new(atoms: &[f32], n: usize) -> Omp {
        let k = atoms.len().checked_div(n).unwrap_or(0);
        let mut gram = vec![0.0f64; k * k];
        for i in 0..k {
            for j in i..k {
                let g: f64 = atoms[i * n..(i + 1) * n]
                    .iter()
                    .zip(&atoms[j * n..(j + 1) * n])
                    .map(|(&u, &v)| f64::from(u) * f64::from(v))
                    .sum();
                gram[i * k + j] = g;
                gram[j * k + i] = g;
            }
        }
        Omp {
            n,
            k,
            atoms: atoms[..k * n].to_vec(),
            gram,
        }
    }

    /// Number of atoms.
    pub fn atoms(&self) -> usize {
        self.k
    }

    /// Signal length.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Atom `j`.
    pub fn atom(&self, j: usize) -> &[f32] {
        &self.atoms[j * self.n..(j + 1) * self.n]
    }

    /// The sparse code of `y` (length [`Omp::dim`]) with at most `sparsity` atoms.
    pub fn code(&self, y: &[f32], sparsity: usize, scratch: &mut OmpScratch) -> SparseCode {
        self.code_from(y, None, sparsity, scratch)
    }

    /// [`Omp::code`] whose first atom is `first` when given (chosen by another rule, e.g. the
    /// amplifier's matcher); the pursuit adds the others.
    pub fn code_from(
        &self,
        y: &[f32],
        first: Option<usize>,
        sparsity: usize,
        scratch: &mut OmpScratch,
    ) -> SparseCode {
        let mut dty = std::mem::take(&mut scratch.dty);
        dty.clear();
        dty.extend((0..self.k).map(|j| {
            self.atom(j)
                .iter()
                .zip(y)
                .map(|(&u, &v)| f64::from(u) * f64::from(v))
                .sum::<f64>()
        }));
        self.pursue(&dty, norm(y, self.n), first, sparsity, scratch);
        scratch.dty = dty;
        scratch.code.clone()
    }

    /// [`Omp::code_from`] on the correlations `dots` of `y` with every atom (`Dᵀy`, length
    /// [`Omp::atoms`]) computed elsewhere — the amplifier's matcher has them already, in `f32`,
    /// so the pursuit skips its `O(K·n)` product; `y` gives only `‖y‖`. The code is left in
    /// `scratch` (no allocation per code); `dots` of another length give an empty code.
    pub fn code_from_dots<'s>(
        &self,
        y: &[f32],
        dots: &[f32],
        first: Option<usize>,
        sparsity: usize,
        scratch: &'s mut OmpScratch,
    ) -> &'s [(usize, f64)] {
        if dots.len() == self.k {
            self.pursue(dots, norm(y, self.n), first, sparsity, scratch);
        } else {
            scratch.code.clear();
        }
        &scratch.code
    }

    /// The pursuit on `dty = Dᵀy` (length [`Omp::atoms`]), `‖y‖` being `norm_y`, into
    /// `scratch.code`. The correlations of the residual, `Dᵀy − G_S x_S`, are computed in the
    /// scan that picks the next atom, never stored, and not at all after the last step.
    fn pursue<T: Copy + Into<f64>>(
        &self,
        dty: &[T],
        norm_y: f64,
        first: Option<usize>,
        sparsity: usize,
        scratch: &mut OmpScratch,
    ) {
        let k = self.k;
        let s = sparsity.min(k);
        let OmpScratch {
            chol,
            rhs,
            tmp,
            coefs,
            support,
            excluded,
            code,
            ..
        } = scratch;
        if excluded.len() != k {
            excluded.clear();
            excluded.resize(k, 0.0);
        }
        // `chol` holds the lower-triangular factor L (row-major, s × s) of G_SS = L Lᵀ.
        chol.clear();
        chol.resize(s * s, 0.0);
        support.clear();
        coefs.clear();
        for step in 0..s {
            let forced = first.filter(|&f| step == 0 && f < k);
            let j = match forced {
                Some(f) => f,
                None => {
                    let (best, best_abs) =
                        next_atom(dty, &self.gram, k, (support, coefs), excluded);
                    match best {
                        Some(j) if best_abs > TINY * norm_y.max(f64::MIN_POSITIVE) => j,
                        _ => break,
                    }
                }
            };
            // Extend the Cholesky factor: solve L w = G_{S,j}, then the new diagonal
            // sqrt(G_jj − w·w).
            let m = step;
            tmp.clear();
            for p in 0..m {
                let mut v = self.gram[support[p] * k + j];
                for q in 0..p {
                    v -= chol[p * s + q] * tmp[q];
                }
                tmp.push(v / chol[p * s + p]);
            }
            let d2 = self.gram[j * k + j] - tmp.iter().map(|w| w * w).sum::<f64>();
            if d2 <= 1e-10 {
                break;
            }
            for (q, &w) in tmp.iter().enumerate() {
                chol[m * s + q] = w;
            }
            chol[m * s + m] = d2.sqrt();
            support.push(j);
            excluded[j] = f64::NAN;
            // Solve L Lᵀ x = (Dᵀy)_S by forward and back substitution.
            let len = support.len();
            rhs.clear();
            for p in 0..len {
                let mut v: f64 = dty[support[p]].into();
                for q in 0..p {
                    v -= chol[p * s + q] * rhs[q];
                }
                rhs.push(v / chol[p * s + p]);
            }
            coefs.clear();
            coefs.resize(len, 0.0);
            for p in (0..len).rev() {
                let mut v = rhs[p];
                for q in p + 1..len {
                    v -= chol[q * s + p] * coefs[q];
                }
                coefs[p] = v / chol[p * s + p];
            }
        }
        for &j in support.iter() {
            excluded[j] = 0.0;
        }
        code.clear();
        code.extend(support.iter().copied().zip(coefs.iter().copied()));
    }

    /// `Σ x_j d_j` of a code, into `out` (length [`Omp::dim`]).
    pub fn reconstruct(&self, code: &[(usize, f64)], out: &mut [f32]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        for &(j, x) in code {
            for (o, &a) in out.iter_mut().zip(self.atom(j)) {
                *o += (f64::from(a) * x) as f32;
            }
        }
    }
}

/// Lanes of [`next_atom_lanes`]: eight `f64`, one AVX-512 vector.
const SCAN_LANES: usize = 8;

/// The next atom of the pursuit and its correlation's magnitude: over every atom `j` in index
/// order, the correlation of the residual `c_j = dty_j − Σ_s G[s, j]·x_s` (the support's terms
/// subtracted in support order), the first `j` outside the support whose `|c_j|` is strictly the
/// largest (`None` when none is above 0). `excluded` holds 0 for every atom but NaN for those of
/// the support. The widest build [`Isa::current`] allows of [`next_atom_lanes`], the same result
/// as [`next_atom_scalar`].
fn next_atom<T: Copy + Into<f64>>(
    dty: &[T],
    gram: &[f64],
    k: usize,
    (support, coefs): (&[usize], &[f64]),
    excluded: &[f64],
) -> (Option<usize>, f64) {
    Isa::current().run(
        #[inline(always)]
        |_| next_atom_lanes(dty, gram, k, (support, coefs), excluded),
    )
}

/// [`next_atom`] in [`SCAN_LANES`] lanes: lane `t` keeps the largest `|c_j|` of the atoms
/// `j ≡ t (mod SCAN_LANES)` and the first `j` that reached it (a strict comparison, as the
/// scalar scan's); the lanes' largest value, at the lowest index among the lanes that hold it,
/// is then the scalar scan's choice, and the atoms past the last whole group of lanes continue
/// it one by one. Each `c_j` takes the same multiplications and subtractions as in
/// [`next_atom_scalar`] (never fused); an excluded atom's `|c_j| + NaN` is above nothing.
#[inline(always)]
fn next_atom_lanes<T: Copy + Into<f64>>(
    dty: &[T],
    gram: &[f64],
    k: usize,
    (support, coefs): (&[usize], &[f64]),
    excluded: &[f64],
) -> (Option<usize>, f64) {
    let n = dty.len().min(excluded.len()).min(k);
    let whole = n - n % SCAN_LANES;
    let mut lane_max = [0.0f64; SCAN_LANES];
    let mut lane_at = [u64::MAX; SCAN_LANES];
    for g in (0..whole).step_by(SCAN_LANES) {
        let mut c = [0.0f64; SCAN_LANES];
        for (ci, &d) in c.iter_mut().zip(&dty[g..g + SCAN_LANES]) {
            *ci = d.into();
        }
        for (&sp, &x) in support.iter().zip(coefs) {
            let row = &gram[sp * k + g..sp * k + g + SCAN_LANES];
            for (ci, &gv) in c.iter_mut().zip(row) {
                *ci -= gv * x;
            }
        }
        let ex = &excluded[g..g + SCAN_LANES];
        for t in 0..SCAN_LANES {
            let a = c[t].abs() + ex[t];
            let above = a > lane_max[t];
            lane_max[t] = if above { a } else { lane_max[t] };
            lane_at[t] = if above { (g + t) as u64 } else { lane_at[t] };
        }
    }
    let mut best = None;
    let mut best_abs = 0.0f64;
    for t in 0..SCAN_LANES {
        let at = lane_at[t] as usize;
        if lane_at[t] != u64::MAX
            && (lane_max[t] > best_abs || (lane_max[t] == best_abs && best.is_some_and(|b| at < b)))
        {
            best_abs = lane_max[t];
            best = Some(at);
        }
    }
    for j in whole..n {
        let mut c: f64 = dty[j].into();
        for (&sp, &x) in support.iter().zip(coefs) {
            c -= gram[sp * k + j] * x;
        }
        if c.abs() > best_abs && !support.contains(&j) {
            best_abs = c.abs();
            best = Some(j);
        }
    }
    (best, best_abs)
}

/// The reference of [`next_atom`]: one atom at a time.
#[cfg(test)]
fn next_atom_scalar<T: Copy + Into<f64>>(
    dty: &[T],
    gram: &[f64],
    k: usize,
    support: &[usize],
    coefs: &[f64],
) -> (Option<usize>, f64) {
    let mut best = None;
    let mut best_abs = 0.0f64;
    for (j, &d) in dty.iter().enumerate() {
        let mut c: f64 = d.into();
        for (&sp, &x) in support.iter().zip(coefs) {
            c -= gram[sp * k + j] * x;
        }
        if c.abs() > best_abs && !support.contains(&j) {
            best_abs = c.abs();
            best = Some(j);
        }
    }
    (best, best_abs)
}

/// `‖y‖` over its first `n` values, in `f64`.
fn norm(y: &[f32], n: usize) -> f64 {
    y[..n.min(y.len())]
        .iter()
        .map(|&v| f64::from(v) * f64::from(v))
        .sum::<f64>()
        .sqrt()
}

/// `‖y − Σ x_j d_j‖²` of a code, in `f64`.
pub fn residual_energy(atoms: &[f32], n: usize, y: &[f32], code: &[(usize, f64)]) -> f64 {
    (0..n)
        .map(|i| {
            let mut fit = 0.0f64;
            for &(j, x) in code {
                fit += f64::from(atoms[j * n + i]) * x;
            }
            let r = f64::from(y[i]) - fit;
            r * r
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::rng::Rng;
    use proptest::prelude::*;

    /// `k` random unit-norm atoms of length `n`.
    fn random_atoms(k: usize, n: usize, seed: u64) -> Vec<f32> {
        Rng::new(seed).unit_rows(k, n)
    }

    #[test]
    fn an_exact_combination_is_recovered() {
        // y = 2·d3 − 0.5·d7 over orthonormal atoms (the identity): found exactly, in order of
        // magnitude, with a zero residual.
        let n = 8;
        let mut atoms = vec![0.0f32; n * n];
        for i in 0..n {
            atoms[i * n + i] = 1.0;
        }
        let mut y = vec![0.0f32; n];
        y[3] = 2.0;
        y[7] = -0.5;
        for code in [
            omp_naive(&atoms, n, &y, 4),
            Omp::new(&atoms, n).code(&y, 4, &mut OmpScratch::default()),
        ] {
            assert_eq!(code.len(), 2, "{code:?}");
            assert_eq!(code[0].0, 3);
            assert_eq!(code[1].0, 7);
            assert!((code[0].1 - 2.0).abs() < 1e-12 && (code[1].1 + 0.5).abs() < 1e-12);
            assert!(residual_energy(&atoms, n, &y, &code) < 1e-20);
        }
    }

    #[test]
    fn least_squares_on_the_support_by_hand() {
        // Two non-orthogonal atoms a = (1, 0), b = (0.6, 0.8) and y = (1, 1): y·a = 1, y·b = 1.4,
        // so b is chosen first (coefficient 1.4), then a; the fit of y on {a, b} is exact:
        // y = 0.25·a + 1.25·b.
        let atoms = [0.0f32, 0.0, 1.0, 0.0, 0.6, 0.8];
        let y = [1.0f32, 1.0];
        let naive = omp_naive(&atoms, 2, &y, 1);
        assert_eq!(naive[0].0, 2);
        assert!((naive[0].1 - 1.4).abs() < 1e-6);
        let fast = Omp::new(&atoms, 2).code(&y, 2, &mut OmpScratch::default());
        assert_eq!((fast[0].0, fast[1].0), (2, 1));
        assert!((fast[0].1 - 1.25).abs() < 1e-6 && (fast[1].1 - 0.25).abs() < 1e-6);
    }

    #[test]
    fn zero_signals_and_sparsity_zero_give_empty_codes() {
        let atoms = random_atoms(5, 6, 1);
        assert!(omp_naive(&atoms, 6, &[0.0; 6], 3).is_empty());
        let omp = Omp::new(&atoms, 6);
        assert!(omp
            .code(&[0.0; 6], 3, &mut OmpScratch::default())
            .is_empty());
        assert!(omp
            .code(&[1.0; 6], 0, &mut OmpScratch::default())
            .is_empty());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn batch_omp_matches_the_naive_pursuit(
            k in 1usize..40, n in 1usize..24, s in 1usize..8, seed in any::<u64>()
        ) {
            let atoms = random_atoms(k, n, seed);
            let mut rng = Rng::new(seed ^ 0x5eed);
            let y: Vec<f32> = (0..n).map(|_| rng.normal() as f32).collect();
            let naive = omp_naive(&atoms, n, &y, s);
            let fast = Omp::new(&atoms, n).code(&y, s, &mut OmpScratch::default());
            prop_assert_eq!(naive.len(), fast.len());
            for (a, b) in naive.iter().zip(&fast) {
                prop_assert_eq!(a.0, b.0);
                prop_assert!((a.1 - b.1).abs() <= 1e-6 * (1.0 + a.1.abs()), "{:?} vs {:?}", a, b);
            }
            // Each added atom lowers (never raises) the residual.
            let mut last = f64::INFINITY;
            for m in 1..=fast.len() {
                let e = residual_energy(&atoms, n, &y, &omp_naive(&atoms, n, &y, m));
                prop_assert!(e <= last + 1e-9);
                last = e;
            }
        }

        #[test]
        fn the_lane_scan_picks_the_scalar_scans_atom(
            k in 1usize..70, s in 0usize..4, ties in 0usize..5, seed in any::<u64>()
        ) {
            // Correlations with repeated magnitudes (both signs), so that ties between lanes
            // and within a lane are common; a Gram matrix with exact zeros, and supports of up
            // to three atoms.
            let mut rng = Rng::new(seed);
            let levels: Vec<f32> = (0..=ties).map(|_| rng.normal() as f32).collect();
            let dots: Vec<f32> = (0..k)
                .map(|_| {
                    let v = levels[rng.below(levels.len() as u64) as usize];
                    if rng.next_f64() < 0.5 { -v } else { v }
                })
                .collect();
            let gram: Vec<f64> = (0..k * k)
                .map(|_| if rng.next_f64() < 0.3 { 0.0 } else { rng.normal() * 0.1 })
                .collect();
            let mut support: Vec<usize> = Vec::new();
            while support.len() < s.min(k) {
                let j = rng.below(k as u64) as usize;
                if !support.contains(&j) {
                    support.push(j);
                }
            }
            let coefs: Vec<f64> = support.iter().map(|_| rng.normal()).collect();
            let mut excluded = vec![0.0f64; k];
            for &j in &support {
                excluded[j] = f64::NAN;
            }
            let want = next_atom_scalar(&dots, &gram, k, &support, &coefs);
            let plain = next_atom_lanes(&dots, &gram, k, (&support, &coefs), &excluded);
            let widest = next_atom(&dots, &gram, k, (&support, &coefs), &excluded);
            for got in [plain, widest] {
                prop_assert_eq!(got.0, want.0);
                prop_assert_eq!(got.1.to_bits(), want.1.to_bits());
            }
        }

        #[test]
        fn a_forced_first_atom_is_kept_and_both_pursuits_agree(
            k in 2usize..40, n in 2usize..24, s in 1usize..8, seed in any::<u64>(), f in any::<usize>()
        ) {
            let atoms = random_atoms(k, n, seed);
            let mut rng = Rng::new(seed ^ 0xf1257);
            let y: Vec<f32> = (0..n).map(|_| rng.normal() as f32).collect();
            let first = f % k;
            let naive = omp_naive_from(&atoms, n, &y, Some(first), s);
            let fast = Omp::new(&atoms, n).code_from(&y, Some(first), s, &mut OmpScratch::default());
            prop_assert_eq!(naive[0].0, first);
            prop_assert_eq!(naive.len(), fast.len());
            for (a, b) in naive.iter().zip(&fast) {
                prop_assert_eq!(a.0, b.0);
                prop_assert!((a.1 - b.1).abs() <= 1e-6 * (1.0 + a.1.abs()), "{:?} vs {:?}", a, b);
            }
            // On the correlations given in f32 (as the amplifier's matcher has them), the
            // same support and, to the f32 rounding of `Dᵀy`, the same coefficients.
            let dots: Vec<f32> = (0..k)
                .map(|j| {
                    atoms[j * n..(j + 1) * n]
                        .iter()
                        .zip(&y)
                        .map(|(&a, &v)| f64::from(a) * f64::from(v))
                        .sum::<f64>() as f32
                })
                .collect();
            let mut scratch = OmpScratch::default();
            let given = Omp::new(&atoms, n).code_from_dots(&y, &dots, Some(first), s, &mut scratch);
            prop_assert_eq!(given.len(), naive.len());
            for (a, b) in naive.iter().zip(given) {
                prop_assert_eq!(a.0, b.0);
                prop_assert!((a.1 - b.1).abs() <= 1e-4 * (1.0 + a.1.abs()), "{:?} vs {:?}", a, b);
            }
            prop_assert!(Omp::new(&atoms, n)
                .code_from_dots(&y, &dots[1..], Some(first), s, &mut scratch)
                .is_empty());
            // With one atom the coefficient is the projection on the forced atom, `⟨a, y⟩ / ⟨a, a⟩`
            // (the f32 atoms are unit-norm only to rounding).
            let one = omp_naive_from(&atoms, n, &y, Some(first), 1);
            let a = &atoms[first * n..(first + 1) * n];
            let dot: f64 = a.iter().zip(&y).map(|(&a, &v)| f64::from(a) * f64::from(v)).sum();
            let aa: f64 = a.iter().map(|&a| f64::from(a) * f64::from(a)).sum();
            prop_assert!((one[0].1 - dot / aa).abs() <= 1e-9 * (1.0 + (dot / aa).abs()));
        }
    }
}
