//! Realism metrics comparing grids and distributions: RMSE, relief, the exact 1-Wasserstein
//! distance between empirical distributions, and box down-sampling. All sums run in a fixed
//! (row-major) order in `f64`.

use ndarray::Array2;

use super::AnalysisError;

/// Root-mean-square difference of two grids of the same shape, over all cells in row-major
/// order (NaN propagates). Returns NaN when the shapes differ and 0 for empty grids.
pub fn rmse(a: &Array2<f32>, b: &Array2<f32>) -> f64 {
    if a.dim() != b.dim() {
        return f64::NAN;
    }
    if a.is_empty() {
        return 0.0;
    }
    let mut sum = 0.0f64;
    for (x, y) in a.iter().zip(b.iter()) {
        let d = *x as f64 - *y as f64;
        sum += d * d;
    }
    (sum / a.len() as f64).sqrt()
}

/// Relief `max − min` over the non-NaN cells; 0 when there are none.
pub fn relief(a: &Array2<f32>) -> f64 {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for &v in a.iter().filter(|v| !v.is_nan()) {
        lo = lo.min(v as f64);
        hi = hi.max(v as f64);
    }
    if lo > hi {
        0.0
    } else {
        hi - lo
    }
}

/// Exact 1-Wasserstein (earth mover's) distance between the empirical distributions of `a`
/// and `b`, which may have different sizes: `∫₀¹ |F_a⁻¹(t) − F_b⁻¹(t)| dt`, evaluated by merging
/// the two sorted samples' quantile steps. Step boundaries are kept as exact integers on the
/// common denominator `|a|·|b|`. NaN values are ignored; returns 0 when both are empty and NaN
/// when exactly one is.
pub fn wasserstein1(a: &[f64], b: &[f64]) -> f64 {
    let mut xs: Vec<f64> = a.iter().copied().filter(|v| !v.is_nan()).collect();
    let mut ys: Vec<f64> = b.iter().copied().filter(|v| !v.is_nan()).collect();
    match (xs.is_empty(), ys.is_empty()) {
        (true, true) => return 0.0,
        (true, false) | (false, true) => return f64::NAN,
        _ => {}
    }
    xs.sort_by(f64::total_cmp);
    ys.sort_by(f64::total_cmp);
    let (na, nb) = (xs.len() as u128, ys.len() as u128);
    // Quantile positions are measured in units of 1/(na·nb): sample i of `a` covers
    // [i·nb, (i+1)·nb), sample j of `b` covers [j·na, (j+1)·na).
    let (mut i, mut j) = (0usize, 0usize);
    let mut t: u128 = 0;
    let mut sum = 0.0f64;
    while i < xs.len() && j < ys.len() {
        let ea = (i as u128 + 1) * nb;
        let eb = (j as u128 + 1) * na;
        let e = ea.min(eb);
        sum += (xs[i] - ys[j]).abs() * (e - t) as f64;
        t = e;
        if ea == e {
            i += 1;
        }
        if eb == e {
            j += 1;
        }
    }
    sum / (na * nb) as f64
}

/// Box down-sampling by `factor`: each output cell is the mean (in `f64`, row-major order) of a
/// `factor × factor` block. Both dimensions must be divisible by `factor` (no truncation) and
/// `factor` must be ≥ 1; NaN propagates into its block.
pub fn box_down(a: &Array2<f32>, factor: usize) -> Result<Array2<f32>, AnalysisError> {
    let (rows, cols) = a.dim();
    if factor == 0 || rows % factor != 0 || cols % factor != 0 {
        return Err(AnalysisError::NotDivisible { rows, cols, factor });
    }
    let (orows, ocols) = (rows / factor, cols / factor);
    let norm = (factor * factor) as f64;
    Ok(Array2::from_shape_fn((orows, ocols), |(r, c)| {
        let mut s = 0.0f64;
        for i in 0..factor {
            for j in 0..factor {
                s += a[[r * factor + i, c * factor + j]] as f64;
            }
        }
        (s / norm) as f32
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wasserstein_unequal_sizes_exact() {
        // {0} vs {0, 1}: half the mass moves by 1.
        assert_eq!(wasserstein1(&[0.0], &[0.0, 1.0]), 0.5);
        assert_eq!(wasserstein1(&[2.0, f64::NAN], &[2.0]), 0.0);
    }

    #[test]
    fn box_down_errors() {
        let z = Array2::<f32>::zeros((3, 4));
        assert_eq!(
            box_down(&z, 2),
            Err(AnalysisError::NotDivisible {
                rows: 3,
                cols: 4,
                factor: 2
            })
        );
        assert_eq!(
            box_down(&Array2::<f32>::zeros((0, 0)), 3).map(|a| a.len()),
            Ok(0)
        );
    }
}
