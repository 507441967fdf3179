//! K-SVD dictionary learning (Aharon, Elad & Bruckstein), as the sparse-representation paper
//! (Guérin et al.) uses it for unconstrained atoms: alternate sparse coding of every training
//! vector by OMP with sparsity `s` and, atom by atom, the best rank-1 update of the atom and of
//! its users' coefficients from the residual the atom explains.
//!
//! The atom update is sign-agnostic: an atom and its negation represent the same thing (their
//! coefficients change sign), so the rank-1 factor is oriented deterministically — the entry of
//! largest magnitude of the atom is made positive — and learning does not depend on which sign
//! the power iteration happened to reach.
//!
//! The training error `Σ ‖y − D x‖²` never increases from one iteration to the next: a new OMP
//! code replaces a vector's old code only when it fits better, and an atom update is kept only
//! when it lowers its users' error (in exact arithmetic the rank-1 update from the current atom
//! never raises it; the guard makes it hold in floating point too). Everything is deterministic:
//! per-vector work in parallel collected in order, fixed summation orders, a fixed number of
//! power iterations started from the current atom.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::error::DictionaryError;
use super::omp::{residual_energy, Omp, OmpScratch, SparseCode};

/// Power iterations of each rank-1 update.
const POWER_ITERATIONS: usize = 12;

/// What [`ksvd`] learned.
#[derive(Clone, Debug)]
pub struct Learned {
    /// `k × n` unit-norm atoms, atom-major.
    pub atoms: Vec<f32>,
    /// The training error `Σ ‖y − D x‖²` after each iteration (`errors[0]` is the error of the
    /// initial dictionary's codes).
    pub errors: Vec<f64>,
}

/// Learns `init.len() / n` atoms from `samples` (`m × n`, vector-major) with codes of sparsity
/// `sparsity`, starting from `init` (unit-norm rows), for `iterations` rounds. `progress` gets
/// the fraction done; `cancel` stops between atoms.
pub fn ksvd(
    samples: &[f32],
    n: usize,
    init: &[f32],
    sparsity: usize,
    iterations: u32,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(f64),
) -> Result<Learned, DictionaryError> {
    if n == 0 || init.is_empty() || init.len() % n != 0 || samples.len() % n != 0 {
        return Err(DictionaryError::InvalidParams(
            "K-SVD needs non-empty atoms and samples of one length".into(),
        ));
    }
    let k = init.len() / n;
    let sample = |i: usize| &samples[i * n..(i + 1) * n];
    let mut atoms = init.to_vec();
    let mut codes: Vec<SparseCode> = code_all(&atoms, n, samples, sparsity);
    let mut errors = vec![total_error(&atoms, n, samples, &codes)];
    for it in 0..iterations {
        // Atom updates, in index order.
        for j in 0..k {
            if j % 16 == 0 {
                if cancel.load(Ordering::Relaxed) {
                    return Err(DictionaryError::Cancelled);
                }
                progress((f64::from(it) + j as f64 / k as f64) / f64::from(iterations.max(1)));
            }
            update_atom(&mut atoms, n, j, samples, &mut codes);
        }
        // Sparse coding with the new atoms; a vector keeps its code unless OMP fits it better.
        let fresh = code_all(&atoms, n, samples, sparsity);
        codes = codes
            .into_par_iter()
            .zip(fresh)
            .enumerate()
            .map(|(i, (old, new))| {
                let y = sample(i);
                if residual_energy(&atoms, n, y, &new) < residual_energy(&atoms, n, y, &old) {
                    new
                } else {
                    old
                }
            })
            .collect();
        errors.push(total_error(&atoms, n, samples, &codes));
    }
    progress(1.0);
    Ok(Learned { atoms, errors })
}

fn code_all(atoms: &[f32], n: usize, samples: &[f32], sparsity: usize) -> Vec<SparseCode> {
    let omp = Omp::new(atoms, n);
    samples
        .par_chunks(n)
        .map_init(OmpScratch::default, |scratch, y| {
            omp.code(y, sparsity, scratch)
        })
        .collect()
}

/// `Σ ‖y − D x‖²` over every sample, summed in sample order.
pub fn total_error(atoms: &[f32], n: usize, samples: &[f32], codes: &[SparseCode]) -> f64 {
    let per: Vec<f64> = samples
        .par_chunks(n)
        .zip(codes.par_iter())
        .map(|(y, c)| residual_energy(atoms, n, y, c))
        .collect();
    per.iter().sum()
}

/// The rank-1 update of atom `j`: with `E` the residual of its users plus their `d_j x_j` term,
/// the top singular pair `(u, σv)` of `E` (power iteration from `d_j`) replaces `d_j` and the
/// users' coefficients, if that lowers their error.
fn update_atom(atoms: &mut [f32], n: usize, j: usize, samples: &[f32], codes: &mut [SparseCode]) {
    let users: Vec<(usize, usize)> = codes
        .iter()
        .enumerate()
        .filter_map(|(i, c)| c.iter().position(|&(a, _)| a == j).map(|p| (i, p)))
        .collect();
    if users.is_empty() {
        return;
    }
    // E: one column per user, the residual without atom j's contribution (f64, user-major).
    let mut e = vec![0.0f64; users.len() * n];
    for (u, &(i, _)) in users.iter().enumerate() {
        let y = &samples[i * n..(i + 1) * n];
        let col = &mut e[u * n..(u + 1) * n];
        for (d, v) in col.iter_mut().enumerate() {
            let mut fit = 0.0f64;
            for &(a, x) in &codes[i] {
                if a != j {
                    fit += f64::from(atoms[a * n + d]) * x;
                }
            }
            *v = f64::from(y[d]) - fit;
        }
    }
    let old_atom: Vec<f64> = atoms[j * n..(j + 1) * n]
        .iter()
        .map(|&v| f64::from(v))
        .collect();
    let old_x: Vec<f64> = users.iter().map(|&(i, p)| codes[i][p].1).collect();
    let error_of = |atom: &[f64], x: &[f64]| -> f64 {
        let mut s = 0.0f64;
        for (u, &xu) in x.iter().enumerate() {
            for (d, &a) in atom.iter().enumerate() {
                let r = e[u * n + d] - a * xu;
                s += r * r;
            }
        }
        s
    };
    let before = error_of(&old_atom, &old_x);
    // Power iteration on E Eᵀ from the current atom.
    let mut u_vec = old_atom.clone();
    let mut v = vec![0.0f64; users.len()];
    for _ in 0..POWER_ITERATIONS {
        for (uu, vv) in v.iter_mut().enumerate() {
            *vv = e[uu * n..(uu + 1) * n]
                .iter()
                .zip(&u_vec)
                .map(|(a, b)| a * b)
                .sum();
        }
        let mut next = vec![0.0f64; n];
        for (uu, &vv) in v.iter().enumerate() {
            for (d, nx) in next.iter_mut().enumerate() {
                *nx += e[uu * n + d] * vv;
            }
        }
        let norm = next.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm <= 0.0 {
            return;
        }
        u_vec = next.iter().map(|x| x / norm).collect();
    }
    // Orient: the entry of largest magnitude is positive.
    let mut arg = 0usize;
    for (d, &x) in u_vec.iter().enumerate() {
        if x.abs() > u_vec[arg].abs() {
            arg = d;
        }
    }
    if u_vec[arg] < 0.0 {
        u_vec.iter_mut().for_each(|x| *x = -*x);
    }
    let new_x: Vec<f64> = (0..users.len())
        .map(|uu| {
            e[uu * n..(uu + 1) * n]
                .iter()
                .zip(&u_vec)
                .map(|(a, b)| a * b)
                .sum()
        })
        .collect();
    if error_of(&u_vec, &new_x) >= before {
        return;
    }
    for (d, &x) in u_vec.iter().enumerate() {
        atoms[j * n + d] = x as f32;
    }
    for (&(i, p), &x) in users.iter().zip(&new_x) {
        codes[i][p].1 = x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::rng::Rng;

    #[test]
    fn the_training_error_never_increases_and_falls_on_structured_data() {
        // Samples are sparse combinations of a hidden dictionary plus a little noise; learning
        // from random atoms must lower the error monotonically, and by a large factor.
        let (n, k, m, s) = (16, 8, 400, 2);
        let mut rng = Rng::new(7);
        let hidden = rng.unit_rows(k, n);
        let mut samples = Vec::with_capacity(m * n);
        for _ in 0..m {
            let a = rng.below(k as u64) as usize;
            let b = rng.below(k as u64) as usize;
            let (xa, xb) = (1.0 + rng.next_f64(), rng.normal());
            for d in 0..n {
                let v = f64::from(hidden[a * n + d]) * xa
                    + f64::from(hidden[b * n + d]) * xb
                    + 0.01 * rng.normal();
                samples.push(v as f32);
            }
        }
        let init = rng.unit_rows(k, n);
        let learned = ksvd(
            &samples,
            n,
            &init,
            s,
            15,
            &AtomicBool::new(false),
            &mut |_| {},
        )
        .unwrap();
        for w in learned.errors.windows(2) {
            assert!(w[1] <= w[0], "error rose: {:?}", learned.errors);
        }
        let (first, last) = (learned.errors[0], *learned.errors.last().unwrap());
        assert!(last < 0.2 * first, "{first} → {last}");
        // Atoms stay unit norm and oriented (largest entry positive).
        for a in learned.atoms.chunks(n) {
            let norm: f32 = a.iter().map(|x| x * x).sum::<f32>().sqrt();
            assert!((norm - 1.0).abs() < 1e-4);
            let big = a
                .iter()
                .cloned()
                .fold(0.0f32, |m, x| if x.abs() > m.abs() { x } else { m });
            assert!(big > 0.0);
        }
    }

    #[test]
    fn learning_is_deterministic_across_thread_counts() {
        let (n, k, m) = (9, 5, 120);
        let mut rng = Rng::new(3);
        let samples: Vec<f32> = (0..m * n).map(|_| rng.normal() as f32).collect();
        let init = rng.unit_rows(k, n);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    ksvd(
                        &samples,
                        n,
                        &init,
                        2,
                        4,
                        &AtomicBool::new(false),
                        &mut |_| {},
                    )
                    .unwrap()
                })
        };
        let (a, b) = (run(1), run(3));
        assert_eq!(a.atoms, b.atoms);
        assert_eq!(a.errors, b.errors);
    }

    #[test]
    fn bad_shapes_are_errors_and_cancellation_stops() {
        let flag = AtomicBool::new(false);
        assert!(ksvd(&[1.0; 10], 4, &[1.0; 4], 1, 1, &flag, &mut |_| {}).is_err());
        assert!(ksvd(&[1.0; 8], 4, &[], 1, 1, &flag, &mut |_| {}).is_err());
        let cancelled = AtomicBool::new(true);
        let r = ksvd(&[1.0; 8], 4, &[0.5; 4], 1, 1, &cancelled, &mut |_| {});
        assert!(matches!(r, Err(DictionaryError::Cancelled)));
    }
}
