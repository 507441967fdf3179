//! Thin-plate splines in the plane (Bookstein 1989): the smoothest map `f(x) = a₀ + a₁x + a₂y +
//! Σ wᵢ U(|x − cᵢ|)`, `U(r) = r² log r`, taking control points `cᵢ` to given values, or, with a
//! regularisation `λ > 0`, approximating them. Feature-guided synthesis uses one to warp a
//! candidate patch so that its exemplar ridge or valley lands on the sketched line. The
//! `(n + 3)²` system is solved by Gaussian elimination with partial pivoting in `f64`
//! ([`solve`]), deterministic and exact to rounding.

use crate::math;
/// `U(r) = r² log r` from `r²` (`0` at `r = 0`).
fn radial(r2: f64) -> f64 {
    if r2 <= 0.0 {
        0.0
    } else {
        0.5 * r2 * math::log(r2)
    }
}

/// Solves `a · x = b` for a dense `n × n` matrix (row-major) and `m` right-hand sides (`b` is
/// `n × m`, row-major); `None` when the matrix is singular (a pivot below `1e-12` of the
/// largest entry).
pub fn solve(mut a: Vec<f64>, mut b: Vec<f64>, n: usize, m: usize) -> Option<Vec<f64>> {
    if a.len() != n * n || b.len() != n * m {
        return None;
    }
    let scale = a.iter().fold(0f64, |s, v| s.max(v.abs())).max(1e-300);
    for col in 0..n {
        // Partial pivoting: the largest entry of the column at or below the diagonal (first on
        // ties).
        let mut p = col;
        for r in col + 1..n {
            if a[r * n + col].abs() > a[p * n + col].abs() {
                p = r;
            }
        }
        if a[p * n + col].abs() < 1e-12 * scale {
            return None;
        }
        if p != col {
            for k in 0..n {
                a.swap(col * n + k, p * n + k);
            }
            for k in 0..m {
                b.swap(col * m + k, p * m + k);
            }
        }
        let d = a[col * n + col];
        for r in col + 1..n {
            let f = a[r * n + col] / d;
            if f == 0.0 {
                continue;
            }
            for k in col..n {
                a[r * n + k] -= f * a[col * n + k];
            }
            for k in 0..m {
                b[r * m + k] -= f * b[col * m + k];
            }
        }
    }
    let mut x = vec![0f64; n * m];
    for col in (0..n).rev() {
        for k in 0..m {
            let mut s = b[col * m + k];
            for j in col + 1..n {
                s -= a[col * n + j] * x[j * m + k];
            }
            x[col * m + k] = s / a[col * n + col];
        }
    }
    Some(x)
}

/// A fitted thin-plate spline from the plane to the plane.
#[derive(Clone, Debug, PartialEq)]
pub struct Tps {
    centres: Vec<[f64; 2]>,
    /// Radial weights, one pair per centre.
    weights: Vec<[f64; 2]>,
    /// Affine part `[a₀, a₁, a₂]` of each output coordinate.
    affine: [[f64; 3]; 2],
}

impl Tps {
    /// The spline taking `from[i]` to `to[i]` (exactly for `lambda = 0`, in the least-bending
    /// sense for `lambda > 0`). `None` with fewer than 3 points, mismatched lengths, or
    /// collinear/duplicate points that make the system singular.
    pub fn fit(from: &[[f64; 2]], to: &[[f64; 2]], lambda: f64) -> Option<Tps> {
        let n = from.len();
        if n < 3 || to.len() != n || !lambda.is_finite() || lambda < 0.0 {
            return None;
        }
        let dim = n + 3;
        let mut a = vec![0f64; dim * dim];
        let mut b = vec![0f64; dim * 2];
        for i in 0..n {
            for j in 0..n {
                let dx = from[i][0] - from[j][0];
                let dy = from[i][1] - from[j][1];
                a[i * dim + j] = radial(dx * dx + dy * dy);
            }
            a[i * dim + i] += lambda;
            let p = [1.0, from[i][0], from[i][1]];
            for k in 0..3 {
                a[i * dim + n + k] = p[k];
                a[(n + k) * dim + i] = p[k];
            }
            b[i * 2] = to[i][0];
            b[i * 2 + 1] = to[i][1];
        }
        let x = solve(a, b, dim, 2)?;
        let weights = (0..n).map(|i| [x[i * 2], x[i * 2 + 1]]).collect();
        let affine = [
            [x[n * 2], x[(n + 1) * 2], x[(n + 2) * 2]],
            [x[n * 2 + 1], x[(n + 1) * 2 + 1], x[(n + 2) * 2 + 1]],
        ];
        Some(Tps {
            centres: from.to_vec(),
            weights,
            affine,
        })
    }

    /// The spline's value at `p`.
    pub fn eval(&self, p: [f64; 2]) -> [f64; 2] {
        let mut out = [
            self.affine[0][0] + self.affine[0][1] * p[0] + self.affine[0][2] * p[1],
            self.affine[1][0] + self.affine[1][1] * p[0] + self.affine[1][2] * p[1],
        ];
        for (c, w) in self.centres.iter().zip(&self.weights) {
            let dx = p[0] - c[0];
            let dy = p[1] - c[1];
            let u = radial(dx * dx + dy * dy);
            out[0] += w[0] * u;
            out[1] += w[1] * u;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_its_points_and_keeps_affine_maps() {
        let from = [
            [0.0, 0.0],
            [10.0, 0.0],
            [0.0, 10.0],
            [10.0, 10.0],
            [4.0, 6.0],
        ];
        let to = [
            [1.0, 0.0],
            [10.0, 2.0],
            [0.0, 9.0],
            [12.0, 11.0],
            [5.0, 5.0],
        ];
        let t = Tps::fit(&from, &to, 0.0).unwrap();
        for (f, g) in from.iter().zip(&to) {
            let v = t.eval(*f);
            assert!((v[0] - g[0]).abs() < 1e-9 && (v[1] - g[1]).abs() < 1e-9);
        }
        // An affine map is reproduced everywhere.
        let aff = |p: [f64; 2]| {
            [
                2.0 + 0.5 * p[0] - 0.2 * p[1],
                -1.0 + 0.1 * p[0] + 1.3 * p[1],
            ]
        };
        let to2: Vec<[f64; 2]> = from.iter().map(|&p| aff(p)).collect();
        let t2 = Tps::fit(&from, &to2, 0.0).unwrap();
        let q = t2.eval([3.3, -7.1]);
        let w = aff([3.3, -7.1]);
        assert!((q[0] - w[0]).abs() < 1e-9 && (q[1] - w[1]).abs() < 1e-9);
        assert!(Tps::fit(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], &to[..3], 0.0).is_none());
    }

    #[test]
    fn solve_matches_a_known_system() {
        let x = solve(vec![2.0, 1.0, 1.0, 3.0], vec![3.0, 5.0], 2, 1).unwrap();
        assert!((x[0] - 0.8).abs() < 1e-12 && (x[1] - 1.4).abs() < 1e-12);
        assert!(solve(vec![1.0, 2.0, 2.0, 4.0], vec![1.0, 2.0], 2, 1).is_none());
    }
}
