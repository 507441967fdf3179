//! Compact terrains (the sparse construction tree of Guérin et al.): a terrain written as blended
//! primitives on a regular lattice, `f(p) = Σ α_i(p) f_i(p) / Σ α_i(p)`, each primitive
//! `f_i(p) = z_i + Σ_j x_ij d_j(p − c_i)` a sparse combination (sparsity `s`, found by OMP) of
//! zero-mean dictionary atoms. Storing the lattice heights, the sparse coefficients and the atoms
//! they use is a compact representation of the terrain; decoding is a fixed blend.
//!
//! The lattice is the amplifier's: primitives every `step = patch/2` pixels, `c_i = step·(i, j)`,
//! each covering `[c − step, c + step)²` with `α = (1 − r²)³`, `r = |p − c| / step`, so every
//! pixel is covered by exactly four primitives and `Σ α` is a fixed pattern of the pixel's offset
//! in its lattice cell. The lattice runs one step beyond the grid on each side, so the border is
//! covered like the interior.
//!
//! Encoding fits each primitive to the `patch × patch` window around its centre by weighted least
//! squares with weights `α` (what the blend will use): `z_i` is the `α`-weighted mean and OMP
//! codes `√α ⊙ (y − z_i)` over the atoms weighted the same way. Heights, coefficients and atoms
//! are quantised before the final fit is measured, and encoding uses the quantised atoms, so
//! decoding a stored terrain gives back exactly what the encoder measured.

use ndarray::Array2;
use rayon::prelude::*;

use crate::dictionary::omp::{Omp, OmpScratch};
use crate::math;

/// A primitive while encoding: its quantised height and its code of `(atom index into the
/// offered atoms, quantised coefficient)` pairs.
pub type Primitive = (i32, Vec<(usize, i32)>);

/// Quantum of lattice heights, metres.
pub const HEIGHT_QUANTUM_M: f32 = 0.1;

/// A terrain as a sparse construction tree, quantised.
#[derive(Clone, Debug, PartialEq)]
pub struct CompactTerrain {
    /// Rows of the decoded grid.
    pub rows: usize,
    /// Columns of the decoded grid.
    pub cols: usize,
    /// Atom (patch) side, pixels; a multiple of 2.
    pub patch: usize,
    /// Largest number of atoms per primitive.
    pub sparsity: usize,
    /// Quantum of the coefficients (metres per unit of a unit-norm atom).
    pub coef_quantum: f32,
    /// `nj × ni` lattice heights in [`HEIGHT_QUANTUM_M`] units, row-major.
    pub heights: Vec<i32>,
    /// Per primitive (lattice order): `(atom, quantised coefficient)` pairs.
    pub codes: Vec<Vec<(u16, i32)>>,
    /// `k × patch²` quantised atoms (the atoms the codes use), atom-major.
    pub atoms: Vec<i16>,
    /// Per atom: the value of one quantisation step.
    pub atom_scales: Vec<f32>,
}

/// Blending weights `α` over a patch (`patch × patch`) and `1/Σα` per offset in a lattice cell
/// (`step × step`), exactly as the amplifier computes them.
pub fn blend_weights(patch: usize) -> (Vec<f32>, Vec<f32>) {
    let step = patch / 2;
    let alpha = super::level::blend_alpha(patch);
    let mut inv_norm = vec![0.0f32; step * step];
    for oy in 0..step {
        for ox in 0..step {
            let mut sum = 0.0f32;
            for py in [oy + step, oy] {
                for px in [ox + step, ox] {
                    sum += alpha[py * patch + px];
                }
            }
            inv_norm[oy * step + ox] = 1.0 / sum;
        }
    }
    (alpha, inv_norm)
}

/// The high-resolution atoms of `dict`, each centred and scaled to unit norm, atom-major
/// (`patch²` values each); flat atoms (zero norm) are left out.
pub fn unit_hi_atoms(dict: &crate::dictionary::Dictionary) -> Vec<f32> {
    let p2 = dict.patch() * dict.patch();
    let mut out = Vec::with_capacity(dict.n_atoms * p2);
    for i in 0..dict.n_atoms {
        let h = dict.hi_atom(i);
        let mean = h.iter().map(|&v| f64::from(v)).sum::<f64>() / p2.max(1) as f64;
        let norm = h
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            .sqrt();
        if norm > 0.0 {
            out.extend(h.iter().map(|&v| ((f64::from(v) - mean) / norm) as f32));
        }
    }
    out
}

/// Lattice size `(ni, nj)` of a `rows × cols` grid: centres `0, step, …` up to one step beyond
/// the last pixel.
pub fn lattice_size(rows: usize, cols: usize, step: usize) -> (usize, usize) {
    (cols.div_ceil(step) + 1, rows.div_ceil(step) + 1)
}

/// Quantises unit-norm atoms to `i16` with a scale per atom.
fn quantise_atoms(atoms: &[f32], p2: usize) -> (Vec<i16>, Vec<f32>) {
    let mut q = Vec::with_capacity(atoms.len());
    let mut scales = Vec::with_capacity(atoms.len() / p2.max(1));
    for a in atoms.chunks(p2) {
        let mx = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let scale = if mx > 0.0 { mx / 32767.0 } else { 1.0 };
        scales.push(scale);
        q.extend(
            a.iter()
                .map(|v| (v / scale).round().clamp(-32767.0, 32767.0) as i16),
        );
    }
    (q, scales)
}

/// The window of `grid` around lattice point `(i, j)` (edge pixels repeated beyond the grid).
fn window(grid: &Array2<f32>, i: usize, j: usize, patch: usize, out: &mut [f32]) {
    let step = (patch / 2) as i64;
    let (rows, cols) = grid.dim();
    let (r0, c0) = (j as i64 * step - step, i as i64 * step - step);
    for r in 0..patch {
        let rr = (r0 + r as i64).clamp(0, rows as i64 - 1) as usize;
        for c in 0..patch {
            let cc = (c0 + c as i64).clamp(0, cols as i64 - 1) as usize;
            out[r * patch + c] = grid[[rr, cc]];
        }
    }
}

/// Encodes `grid` (finite values) over `atoms` (`k × patch²`, zero-mean, unit norm) with at most
/// `sparsity` atoms per primitive and coefficients quantised to `coef_quantum`, then refines the
/// primitives jointly for `passes` passes ([`refine`]). Deterministic whatever the thread count
/// (primitives are independent within a step and collected in lattice order).
pub fn compress(
    grid: &Array2<f32>,
    atoms: &[f32],
    patch: usize,
    sparsity: usize,
    coef_quantum: f32,
    passes: usize,
) -> CompactTerrain {
    let (rows, cols) = grid.dim();
    let p2 = patch * patch;
    let step = patch / 2;
    let (alpha, _) = blend_weights(patch);
    let (qatoms, scales) = quantise_atoms(atoms, p2);
    let k = scales.len();
    // The dequantised atoms, weighted by √α and normalised for the pursuit; `norms` maps a
    // pursuit coefficient back to the dequantised atom's.
    let sqrt_alpha: Vec<f32> = alpha.iter().map(|a| a.sqrt()).collect();
    let mut weighted = vec![0.0f32; k * p2];
    let mut norms = vec![0.0f64; k];
    for a in 0..k {
        let src = &qatoms[a * p2..(a + 1) * p2];
        let dst = &mut weighted[a * p2..(a + 1) * p2];
        for ((d, &q), &w) in dst.iter_mut().zip(src).zip(&sqrt_alpha) {
            *d = f32::from(q) * scales[a] * w;
        }
        let norm = dst
            .iter()
            .map(|&v| f64::from(v).powi(2))
            .sum::<f64>()
            .sqrt();
        norms[a] = norm;
        if norm > 0.0 {
            dst.iter_mut()
                .for_each(|v| *v = (f64::from(*v) / norm) as f32);
        }
    }
    let omp = Omp::new(&weighted, p2);
    let alpha_sum: f64 = alpha.iter().map(|&a| f64::from(a)).sum();
    let (ni, nj) = lattice_size(rows, cols, step);
    let mut prims: Vec<Primitive> = (0..ni * nj)
        .into_par_iter()
        .map_init(
            || (vec![0.0f32; p2], vec![0.0f32; p2], OmpScratch::default()),
            |(y, r, scratch), n| {
                let (i, j) = (n % ni, n / ni);
                window(grid, i, j, patch, y);
                let z: f64 = y
                    .iter()
                    .zip(&alpha)
                    .map(|(&v, &a)| f64::from(v) * f64::from(a))
                    .sum::<f64>()
                    / alpha_sum;
                let zq = (z / f64::from(HEIGHT_QUANTUM_M)).round() as i32;
                let z_hat = zq as f32 * HEIGHT_QUANTUM_M;
                for ((rv, &yv), &w) in r.iter_mut().zip(y.iter()).zip(&sqrt_alpha) {
                    *rv = (yv - z_hat) * w;
                }
                let code = omp
                    .code(r, sparsity, scratch)
                    .into_iter()
                    .filter(|&(a, _)| norms[a] > 0.0)
                    .map(|(a, x)| {
                        let c = x / norms[a];
                        (a, (c / f64::from(coef_quantum)).round() as i32)
                    })
                    .filter(|&(_, q)| q != 0)
                    .collect();
                (zq, code)
            },
        )
        .collect();
    let dequantised: Vec<f32> = qatoms
        .chunks(p2)
        .zip(&scales)
        .flat_map(|(a, &sc)| a.iter().map(move |&q| f32::from(q) * sc))
        .collect();
    for _ in 0..passes {
        refine(
            grid,
            &dequantised,
            patch,
            sparsity,
            coef_quantum,
            &mut prims,
        );
    }
    // Keep only the atoms used, in index order.
    let mut used = vec![false; k];
    for (_, code) in &prims {
        for &(a, _) in code {
            used[a] = true;
        }
    }
    let mut remap = vec![0u16; k];
    let mut kept_atoms = Vec::new();
    let mut kept_scales = Vec::new();
    for a in 0..k {
        if used[a] {
            remap[a] = kept_scales.len() as u16;
            kept_atoms.extend_from_slice(&qatoms[a * p2..(a + 1) * p2]);
            kept_scales.push(scales[a]);
        }
    }
    CompactTerrain {
        rows,
        cols,
        patch,
        sparsity,
        coef_quantum,
        heights: prims.iter().map(|(z, _)| *z).collect(),
        codes: prims
            .into_iter()
            .map(|(_, c)| c.into_iter().map(|(a, q)| (remap[a], q)).collect())
            .collect(),
        atoms: kept_atoms,
        atom_scales: kept_scales,
    }
}

/// The blend `Σ α_i f_i / Σ α_i` over a `rows × cols` grid of primitives `(height, code)` in
/// lattice order, with `atom(a, offset)` the value of atom `a` at a patch offset. Rows are
/// computed in parallel, each independently.
fn blend<A: Fn(usize, usize) -> f32 + Sync>(
    rows: usize,
    cols: usize,
    patch: usize,
    coef_quantum: f32,
    prims: &[(i32, &[(usize, i32)])],
    atom: A,
) -> Array2<f32> {
    let step = patch / 2;
    let (alpha, inv_norm) = blend_weights(patch);
    let (ni, _) = lattice_size(rows, cols, step);
    let mut out = vec![0.0f32; rows * cols];
    out.par_chunks_mut(cols.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            // The two lattice rows covering y: c_j ∈ (y − step, y + step].
            let j_hi = (y + step) / step;
            for j in [j_hi - 1, j_hi] {
                let oy = y + step - j * step;
                for (x, v) in row.iter_mut().enumerate() {
                    let i_hi = (x + step) / step;
                    for i in [i_hi - 1, i_hi] {
                        let ox = x + step - i * step;
                        if oy >= patch || ox >= patch || i >= ni {
                            continue;
                        }
                        let (z, code) = prims[j * ni + i];
                        let off = oy * patch + ox;
                        let mut f = z as f32 * HEIGHT_QUANTUM_M;
                        for &(a, q) in code {
                            f += q as f32 * coef_quantum * atom(a, off);
                        }
                        *v += alpha[off] * f;
                    }
                }
            }
            for (x, v) in row.iter_mut().enumerate() {
                *v *= inv_norm[(y % step) * step + x % step];
            }
        });
    Array2::from_shape_vec((rows, cols), out).unwrap_or_default()
}

/// One pass of joint refinement (backfitting): the primitives are refitted to what the others
/// leave of the terrain, so that the *blend* fits it rather than each primitive its window.
///
/// Each pixel's value is `Σ w_i f_i` with `w_i = α_i / Σ α` (a fixed pattern `W` of the pixel's
/// place in the patch). For a primitive, with `B` the current blend, the target is
/// `r = T − B + W f_i` and the new `(z_i, code)` minimises `‖W ⊙ f_i − r‖²`: `z` and the OMP
/// support over the `W`-weighted atoms, then least squares of `z` and the support's coefficients
/// together, quantised; it replaces the old one only if it fits `r` better. Primitives of one
/// colour `(i mod 2, j mod 2)` do not overlap, so a colour is refitted in parallel and the
/// blend's error never grows. Primitives whose support leaves the grid keep their fit.
pub fn refine(
    grid: &Array2<f32>,
    atoms: &[f32],
    patch: usize,
    sparsity: usize,
    coef_quantum: f32,
    prims: &mut [Primitive],
) {
    let (rows, cols) = grid.dim();
    let p2 = patch * patch;
    let step = patch / 2;
    let (ni, nj) = lattice_size(rows, cols, step);
    let (alpha, inv_norm) = blend_weights(patch);
    let w: Vec<f64> = (0..p2)
        .map(|o| {
            let (oy, ox) = (o / patch, o % patch);
            f64::from(alpha[o]) * f64::from(inv_norm[(oy % step) * step + ox % step])
        })
        .collect();
    let k = atoms.len() / p2.max(1);
    let mut weighted = vec![0.0f32; k * p2];
    let mut norms = vec![0.0f64; k];
    for a in 0..k {
        let dst = &mut weighted[a * p2..(a + 1) * p2];
        let mut n2 = 0.0f64;
        for (o, d) in dst.iter_mut().enumerate() {
            let v = w[o] * f64::from(atoms[a * p2 + o]);
            n2 += v * v;
            *d = v as f32;
        }
        norms[a] = n2.sqrt();
        if norms[a] > 0.0 {
            dst.iter_mut()
                .for_each(|v| *v = (f64::from(*v) / norms[a]) as f32);
        }
    }
    let omp = Omp::new(&weighted, p2);
    let w_norm2: f64 = w.iter().map(|v| v * v).sum();
    let interior =
        |i: usize, j: usize| i >= 1 && j >= 1 && (i + 1) * step <= cols && (j + 1) * step <= rows;
    for colour in 0..4 {
        let views: Vec<(i32, &[(usize, i32)])> =
            prims.iter().map(|(z, c)| (*z, c.as_slice())).collect();
        let current = blend(rows, cols, patch, coef_quantum, &views, |a, o| {
            atoms[a * p2 + o]
        });
        let updates: Vec<Option<Primitive>> = (0..ni * nj)
            .into_par_iter()
            .map_init(
                || (vec![0.0f64; p2], vec![0.0f32; p2], OmpScratch::default()),
                |(r, y, scratch), n| {
                    let (i, j) = (n % ni, n / ni);
                    if (i % 2) + 2 * (j % 2) != colour || !interior(i, j) {
                        return None;
                    }
                    let (z_old, code_old) = &prims[n];
                    let value = |z: i32, code: &[(usize, i32)], o: usize| {
                        let mut f = f64::from(z as f32 * HEIGHT_QUANTUM_M);
                        for &(a, q) in code {
                            f += f64::from(q as f32 * coef_quantum) * f64::from(atoms[a * p2 + o]);
                        }
                        f
                    };
                    let (r0, c0) = (j * step - step, i * step - step);
                    for o in 0..p2 {
                        let (py, px) = (r0 + o / patch, c0 + o % patch);
                        r[o] = f64::from(grid[[py, px]]) - f64::from(current[[py, px]])
                            + w[o] * value(*z_old, code_old, o);
                    }
                    let err = |z: i32, code: &[(usize, i32)]| -> f64 {
                        (0..p2)
                            .map(|o| (w[o] * value(z, code, o) - r[o]).powi(2))
                            .sum()
                    };
                    let old = err(*z_old, code_old);
                    // z alone, then the support on what it leaves.
                    let z0 = (0..p2).map(|o| w[o] * r[o]).sum::<f64>() / w_norm2;
                    for o in 0..p2 {
                        y[o] = (r[o] - z0 * w[o]) as f32;
                    }
                    let support: Vec<usize> = omp
                        .code(y, sparsity, scratch)
                        .into_iter()
                        .map(|(a, _)| a)
                        .filter(|&a| norms[a] > 0.0)
                        .collect();
                    // Least squares of [W·1, W·d_a…] together.
                    let m = support.len() + 1;
                    let col = |c: usize, o: usize| {
                        if c == 0 {
                            w[o]
                        } else {
                            w[o] * f64::from(atoms[support[c - 1] * p2 + o])
                        }
                    };
                    let mut a_mat = vec![0.0f64; m * m];
                    let mut b = vec![0.0f64; m];
                    for p in 0..m {
                        for q in 0..m {
                            a_mat[p * m + q] = (0..p2).map(|o| col(p, o) * col(q, o)).sum();
                        }
                        b[p] = (0..p2).map(|o| col(p, o) * r[o]).sum();
                    }
                    let x = crate::dictionary::omp::solve(&mut a_mat, &mut b, m)?;
                    let zq = (x[0] / f64::from(HEIGHT_QUANTUM_M)).round() as i32;
                    let code: Vec<(usize, i32)> = support
                        .iter()
                        .zip(&x[1..])
                        .map(|(&a, &c)| (a, (c / f64::from(coef_quantum)).round() as i32))
                        .filter(|&(_, q)| q != 0)
                        .collect();
                    (err(zq, &code) < old).then_some((zq, code))
                },
            )
            .collect();
        for (p, u) in prims.iter_mut().zip(updates) {
            if let Some(u) = u {
                *p = u;
            }
        }
    }
}

impl CompactTerrain {
    /// The lattice size `(ni, nj)`.
    pub fn lattice(&self) -> (usize, usize) {
        lattice_size(self.rows, self.cols, self.patch / 2)
    }

    /// The decoded grid: the blend of every primitive, summed in lattice order. Rows are
    /// computed in parallel, each independently, so the result does not depend on the thread
    /// count.
    pub fn decode(&self) -> Array2<f32> {
        let p2 = self.patch * self.patch;
        let codes: Vec<Vec<(usize, i32)>> = self
            .codes
            .iter()
            .map(|c| c.iter().map(|&(a, q)| (usize::from(a), q)).collect())
            .collect();
        let views: Vec<(i32, &[(usize, i32)])> = self
            .heights
            .iter()
            .zip(&codes)
            .map(|(&z, c)| (z, c.as_slice()))
            .collect();
        blend(
            self.rows,
            self.cols,
            self.patch,
            self.coef_quantum,
            &views,
            |a, o| f32::from(self.atoms[a * p2 + o]) * self.atom_scales[a],
        )
    }

    /// Number of primitives.
    pub fn primitives(&self) -> usize {
        self.heights.len()
    }
}

/// Peak signal-to-noise ratio of `decoded` against `truth`, dB, with the truth's relief
/// (max − min) as the peak; infinite for an exact copy.
pub fn psnr_db(truth: &Array2<f32>, decoded: &Array2<f32>) -> f64 {
    let relief = crate::analysis::relief(truth);
    let rmse = crate::analysis::rmse(truth, decoded);
    if rmse == 0.0 {
        return f64::INFINITY;
    }
    20.0 * math::log10(relief / rmse)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A naive decoder: for every pixel, the weighted mean over every primitive whose support
    /// holds it, written from the definition (no offset tables).
    fn decode_naive(t: &CompactTerrain) -> Array2<f32> {
        let step = (t.patch / 2) as f64;
        let (ni, nj) = t.lattice();
        let p2 = t.patch * t.patch;
        Array2::from_shape_fn((t.rows, t.cols), |(y, x)| {
            let (py, px) = (y as f64 + 0.5, x as f64 + 0.5);
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for j in 0..nj {
                for i in 0..ni {
                    let (cy, cx) = (j as f64 * step, i as f64 * step);
                    let (dy, dx) = ((py - cy) / step, (px - cx) / step);
                    let r2 = dx * dx + dy * dy;
                    if r2 >= 1.0 || dy < -1.0 || dx < -1.0 {
                        continue;
                    }
                    let a = (1.0 - r2).powi(3);
                    let (oy, ox) = (
                        (py - cy + step - 0.5) as usize,
                        (px - cx + step - 0.5) as usize,
                    );
                    let n = j * ni + i;
                    let mut f = f64::from(t.heights[n]) * f64::from(HEIGHT_QUANTUM_M);
                    for &(atom, q) in &t.codes[n] {
                        let k = usize::from(atom);
                        let d = f64::from(t.atoms[k * p2 + oy * t.patch + ox])
                            * f64::from(t.atom_scales[k]);
                        f += f64::from(q) * f64::from(t.coef_quantum) * d;
                    }
                    num += a * f;
                    den += a;
                }
            }
            (num / den) as f32
        })
    }

    fn hills(rows: usize, cols: usize) -> Array2<f32> {
        Array2::from_shape_fn((rows, cols), |(r, c)| {
            let (x, y) = (c as f32, r as f32);
            500.0
                + 80.0 * math::sinf(x * 0.21) * math::cosf(y * 0.13)
                + 30.0 * math::sinf(x * 0.07 + y * 0.05)
        })
    }

    fn atoms(patch: usize) -> Vec<f32> {
        crate::dictionary::analytic::analytic_atoms(
            crate::dictionary::analytic::AnalyticKind::Perlin,
            patch,
            48,
            3,
        )
    }

    #[test]
    fn the_fast_decoder_equals_the_naive_one() {
        let grid = hills(37, 45);
        let t = compress(&grid, &atoms(8), 8, 3, 0.05, 2);
        let (a, b) = (t.decode(), decode_naive(&t));
        let diff = a
            .iter()
            .zip(b.iter())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max);
        assert!(diff < 1e-3, "{diff}");
    }

    #[test]
    fn a_flat_terrain_is_its_height_and_more_atoms_fit_better() {
        let flat = Array2::from_elem((20, 24), 321.4f32);
        let t = compress(&flat, &atoms(8), 8, 2, 0.05, 1);
        assert!(t.codes.iter().all(|c| c.is_empty()));
        assert!(t.decode().iter().all(|&v| (v - 321.4).abs() < 1e-3));
        let grid = hills(48, 48);
        let psnr: Vec<f64> = [1, 2, 4]
            .iter()
            .map(|&s| psnr_db(&grid, &compress(&grid, &atoms(8), 8, s, 0.01, 0).decode()))
            .collect();
        assert!(psnr[0] < psnr[1] && psnr[1] < psnr[2], "{psnr:?}");
    }

    #[test]
    fn joint_refinement_never_worsens_the_blend_and_improves_it() {
        let grid = hills(64, 72);
        let rmse: Vec<f64> = (0..4)
            .map(|passes| {
                let t = compress(&grid, &atoms(8), 8, 2, 0.01, passes);
                crate::analysis::rmse(&grid, &t.decode())
            })
            .collect();
        for w in rmse.windows(2) {
            assert!(w[1] <= w[0] + 1e-6, "{rmse:?}");
        }
        assert!(rmse[3] < 0.9 * rmse[0], "{rmse:?}");
    }

    #[test]
    fn encoding_is_deterministic_across_thread_counts() {
        let grid = hills(40, 40);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| compress(&grid, &atoms(8), 8, 2, 0.05, 2))
        };
        assert_eq!(run(1), run(3));
    }
}
