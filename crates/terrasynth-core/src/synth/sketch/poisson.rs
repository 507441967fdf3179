//! Poisson seam removal (Pérez et al. 2003, in its screened form, Bhat et al. 2008): given a
//! composite `h₀` and a guidance gradient on every edge between 4-adjacent cells (the patches'
//! own differences, averaged across seams), find `h` minimising
//! `Σ_edges (h_q − h_p − g_pq)² + λ Σ_cells (h − h₀)²`. Only seam edges disagree with `h₀`, so the
//! correction `δ = h − h₀` solves `(L + λ) δ = b` with `L` the grid graph's Laplacian (Neumann
//! borders) and `b` the divergence of the guidance residual; `λ = 1/R²` keeps corrections within
//! about `R` cells of the seams. [`conjugate_gradient`] solves it (fixed summation orders, so
//! results are bit-identical run to run); [`naive_gauss_seidel`] sweeps cell by cell until nothing
//! moves, and property tests compare the two.

/// `(L + λ) x` on a `rows × cols` grid (4-neighbour graph Laplacian, Neumann borders).
pub fn apply(x: &[f64], rows: usize, cols: usize, lambda: f64, out: &mut [f64]) {
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            let xi = x[i];
            let mut s = lambda * xi;
            if c > 0 {
                s += xi - x[i - 1];
            }
            if c + 1 < cols {
                s += xi - x[i + 1];
            }
            if r > 0 {
                s += xi - x[i - cols];
            }
            if r + 1 < rows {
                s += xi - x[i + cols];
            }
            out[i] = s;
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    // Blocks of 4 partial sums in a fixed order (vectorisable without reassociating anything
    // at run time: the order is the same on every machine).
    let mut acc = [0f64; 4];
    let chunks = a.len() / 4;
    for k in 0..chunks {
        for j in 0..4 {
            acc[j] += a[4 * k + j] * b[4 * k + j];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for i in 4 * chunks..a.len() {
        s += a[i] * b[i];
    }
    s
}

/// Solves `(L + λ) x = b` by conjugate gradients from `x = 0`, until the residual's norm falls
/// below `tol` times `b`'s, or `max_iter` iterations. `λ > 0` makes the system positive
/// definite.
pub fn conjugate_gradient(
    b: &[f64],
    rows: usize,
    cols: usize,
    lambda: f64,
    tol: f64,
    max_iter: usize,
) -> Vec<f64> {
    let n = rows * cols;
    let mut x = vec![0f64; n];
    if b.len() != n || n == 0 {
        return x;
    }
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut ap = vec![0f64; n];
    let bb = dot(b, b);
    if bb == 0.0 || !bb.is_finite() {
        return x;
    }
    let mut rr = bb;
    let stop = tol * tol * bb;
    for _ in 0..max_iter {
        if rr <= stop {
            break;
        }
        apply(&p, rows, cols, lambda, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let alpha = rr / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        let rr_next = dot(&r, &r);
        let beta = rr_next / rr;
        for i in 0..n {
            p[i] = r[i] + beta * p[i];
        }
        rr = rr_next;
    }
    x
}

/// Reference: Gauss–Seidel sweeps in row-major order until no cell moves by more than `tol`
/// (or `max_sweeps`).
pub fn naive_gauss_seidel(
    b: &[f64],
    rows: usize,
    cols: usize,
    lambda: f64,
    tol: f64,
    max_sweeps: usize,
) -> Vec<f64> {
    let n = rows * cols;
    let mut x = vec![0f64; n];
    if b.len() != n {
        return x;
    }
    for _ in 0..max_sweeps {
        let mut moved = 0f64;
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                let mut diag = lambda;
                let mut s = b[i];
                let mut nb = |j: usize| {
                    diag += 1.0;
                    s += x[j];
                };
                if c > 0 {
                    nb(i - 1);
                }
                if c + 1 < cols {
                    nb(i + 1);
                }
                if r > 0 {
                    nb(i - cols);
                }
                if r + 1 < rows {
                    nb(i + cols);
                }
                let v = s / diag;
                moved = moved.max((v - x[i]).abs());
                x[i] = v;
            }
        }
        if moved <= tol {
            break;
        }
    }
    x
}

/// The right-hand side `b` of the correction: for horizontal edges `gx[r·(cols−1) + c]` (from
/// `(r, c)` to `(r, c+1)`) and vertical edges `gy[r·cols + c]` (from `(r, c)` to `(r+1, c)`), the
/// residual `g − (h₀_q − h₀_p)` leaves `p` and enters `q`.
pub fn divergence(h0: &[f64], gx: &[f64], gy: &[f64], rows: usize, cols: usize) -> Vec<f64> {
    let mut b = vec![0f64; rows * cols];
    if h0.len() != rows * cols
        || gx.len() != rows * cols.saturating_sub(1)
        || gy.len() != rows.saturating_sub(1) * cols
    {
        return b;
    }
    for r in 0..rows {
        for c in 0..cols.saturating_sub(1) {
            let i = r * cols + c;
            let res = gx[r * (cols - 1) + c] - (h0[i + 1] - h0[i]);
            b[i] -= res;
            b[i + 1] += res;
        }
    }
    for r in 0..rows.saturating_sub(1) {
        for c in 0..cols {
            let i = r * cols + c;
            let res = gy[i] - (h0[i + cols] - h0[i]);
            b[i] -= res;
            b[i + cols] += res;
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_is_smoothed_away() {
        // Two halves 10 m apart; the guidance says the seam edge should be flat. The correction
        // decays over about 1/√λ = 8 cells, so 40 cells away it is gone.
        let (rows, cols) = (4, 80);
        let h0: Vec<f64> = (0..rows * cols)
            .map(|i| if i % cols < 40 { 0.0 } else { 10.0 })
            .collect();
        let gx = vec![0.0; rows * (cols - 1)];
        let gy = vec![0.0; (rows - 1) * cols];
        let b = divergence(&h0, &gx, &gy, rows, cols);
        let d = conjugate_gradient(&b, rows, cols, 1.0 / 64.0, 1e-12, 1000);
        let h: Vec<f64> = h0.iter().zip(&d).map(|(a, b)| a + b).collect();
        let step = h[40] - h[39];
        assert!(step.abs() < 1.0, "seam step {step}");
        // Far from the seam the heights are kept.
        assert!(
            h[0].abs() < 0.5 && (h[79] - 10.0).abs() < 0.5,
            "{} {}",
            h[0],
            h[79]
        );
        let slow = naive_gauss_seidel(&b, rows, cols, 1.0 / 64.0, 1e-12, 100_000);
        for (a, b) in d.iter().zip(&slow) {
            assert!((a - b).abs() < 1e-6);
        }
    }
}
