//! Sum-of-squared-differences search by FFT: the cost of placing a masked template at *every*
//! position of an exemplar, `Σ_m M(m) (E(u + m) + o − T(m))²` with the best height offset `o`
//! (optionally penalised), from three correlations computed in the frequency domain (Kwatra et
//! al. 2003 §2.2; Soler et al. 2002). The exemplar's transforms are computed once
//! ([`SsdIndex::new`]); a query costs one forward and two inverse 2-D FFTs (two real transforms
//! packed into one complex one each way). [`naive_costs`] computes the same sums directly;
//! property tests compare them.
//!
//! The FFT is the crate's own [`Radix2`] (`analysis::fft`, tested against the naive DFT both
//! ways): power-of-two lengths, rows then columns. Rows (and columns) are transformed in
//! parallel, each exactly as it would be alone, so results do not depend on the thread count.

use ndarray::Array2;
use rayon::prelude::*;

use crate::analysis::{Complex, Radix2};

/// A 2-D FFT of a power-of-two `rows × cols` array (row-major).
#[derive(Clone, Debug)]
pub struct Fft2 {
    rows: usize,
    cols: usize,
    row_plan: Radix2,
    col_plan: Radix2,
}

impl Fft2 {
    /// A plan for `rows × cols` (both powers of two).
    pub fn new(rows: usize, cols: usize) -> Self {
        Fft2 {
            rows,
            cols,
            row_plan: Radix2::new(cols),
            col_plan: Radix2::new(rows),
        }
    }

    /// Rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// In-place transform; the inverse is scaled by `1/(rows·cols)`.
    pub fn run(&self, data: &mut [Complex], inverse: bool) {
        let (rows, cols) = (self.rows, self.cols);
        if data.len() != rows * cols || rows == 0 || cols == 0 {
            return;
        }
        data.par_chunks_mut(cols)
            .for_each(|row| self.row_plan.run(row, inverse));
        // Columns: transpose, transform as rows, transpose back.
        let mut t = vec![Complex::default(); rows * cols];
        t.par_chunks_mut(rows).enumerate().for_each(|(c, col)| {
            for (r, v) in col.iter_mut().enumerate() {
                *v = data[r * cols + c];
            }
            self.col_plan.run(col, inverse);
        });
        let scale = if inverse {
            1.0 / (rows * cols) as f64
        } else {
            1.0
        };
        data.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
            for (c, v) in row.iter_mut().enumerate() {
                let x = t[c * rows + r];
                *v = if inverse { x.scale(scale) } else { x };
            }
        });
    }
}

/// How the height offset between the template and the exemplar is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Offset {
    /// No offset: absolute heights are compared.
    None,
    /// The offset minimising `SSD + penalty · n · o²` (`n` = the mask's weight).
    Penalised(f64),
}

/// The cost of every placement and the offset that goes with it.
#[derive(Clone, Debug, PartialEq)]
pub struct Costs {
    /// Placements down (`exemplar rows − template rows + 1`).
    pub rows: usize,
    /// Placements across.
    pub cols: usize,
    /// Cost of the template's top-left cell at exemplar cell `(u, v)`, index `u·cols + v`.
    pub cost: Vec<f64>,
    /// The height to add to the exemplar there.
    pub offset: Vec<f64>,
}

impl Costs {
    /// The placement of least cost (first in row-major order on ties) and its cost.
    pub fn best(&self) -> Option<(usize, usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for (i, &c) in self.cost.iter().enumerate() {
            if best.is_none_or(|(_, b)| c < b) {
                best = Some((i, c));
            }
        }
        best.map(|(i, c)| (i / self.cols, i % self.cols, c))
    }
}

fn finish(s0: f64, s1: f64, s2: f64, x: f64, t1: f64, t2: f64, offset: Offset) -> (f64, f64) {
    let a = s2 - 2.0 * x + t2;
    match offset {
        Offset::None => (a.max(0.0), 0.0),
        Offset::Penalised(p) => {
            let den = s0 * (1.0 + p.max(0.0));
            if den <= 0.0 {
                return (a.max(0.0), 0.0);
            }
            let b = s1 - t1;
            ((a - b * b / den).max(0.0), -b / den)
        }
    }
}

/// An exemplar prepared for SSD queries.
#[derive(Clone, Debug)]
pub struct SsdIndex {
    rows: usize,
    cols: usize,
    mean: f64,
    fft: Fft2,
    fe: Vec<Complex>,
    fe2: Vec<Complex>,
}

impl SsdIndex {
    /// Transforms of `e − mean` and `(e − mean)²`, zero-padded to powers of two.
    pub fn new(e: &Array2<f32>) -> Self {
        let (rows, cols) = e.dim();
        let n = (rows * cols).max(1) as f64;
        let mean = e.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let (pr, pc) = (
            rows.max(1).next_power_of_two(),
            cols.max(1).next_power_of_two(),
        );
        let fft = Fft2::new(pr, pc);
        let mut fe = vec![Complex::default(); pr * pc];
        let mut fe2 = vec![Complex::default(); pr * pc];
        for ((r, c), &v) in e.indexed_iter() {
            let d = f64::from(v) - mean;
            fe[r * pc + c] = Complex::new(d, 0.0);
            fe2[r * pc + c] = Complex::new(d * d, 0.0);
        }
        fft.run(&mut fe, false);
        fft.run(&mut fe2, false);
        SsdIndex {
            rows,
            cols,
            mean,
            fft,
            fe,
            fe2,
        }
    }

    /// The exemplar's size.
    pub fn dim(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }

    /// Costs of template `t` under mask `m` (weights ≥ 0, same shape, at most the exemplar's).
    pub fn costs(&self, t: &Array2<f64>, m: &Array2<f64>, offset: Offset) -> Option<Costs> {
        let (tr, tc) = t.dim();
        if m.dim() != (tr, tc) || tr == 0 || tc == 0 || tr > self.rows || tc > self.cols {
            return None;
        }
        let (pr, pc) = (self.fft.rows(), self.fft.cols());
        let (mut s0, mut t1, mut t2) = (0f64, 0f64, 0f64);
        let mut z = vec![Complex::default(); pr * pc];
        for ((r, c), &w) in m.indexed_iter() {
            let tv = t[[r, c]] - self.mean;
            s0 += w;
            t1 += w * tv;
            t2 += w * tv * tv;
            z[r * pc + c] = Complex::new(w, w * tv);
        }
        self.fft.run(&mut z, false);
        // Unpack the two real transforms, correlate, and pack the real results back in pairs.
        let mut p12 = vec![Complex::default(); pr * pc];
        let mut p3 = vec![Complex::default(); pr * pc];
        for kr in 0..pr {
            let nr = (pr - kr) % pr;
            for kc in 0..pc {
                let nc = (pc - kc) % pc;
                let a = z[kr * pc + kc];
                let b = z[nr * pc + nc].conj();
                let fm = a.add(b).scale(0.5);
                // (a − b) / (2i) = −i (a − b) / 2
                let d = a.sub(b);
                let fmt = Complex::new(d.im * 0.5, -d.re * 0.5);
                let k = kr * pc + kc;
                let c1 = self.fe[k].mul(fm.conj());
                let c2 = self.fe2[k].mul(fm.conj());
                // c1 + i·c2
                p12[k] = Complex::new(c1.re - c2.im, c1.im + c2.re);
                p3[k] = self.fe[k].mul(fmt.conj());
            }
        }
        self.fft.run(&mut p12, true);
        self.fft.run(&mut p3, true);
        let (orows, ocols) = (self.rows - tr + 1, self.cols - tc + 1);
        let mut cost = Vec::with_capacity(orows * ocols);
        let mut off = Vec::with_capacity(orows * ocols);
        for u in 0..orows {
            for v in 0..ocols {
                let k = u * pc + v;
                let (c, o) = finish(s0, p12[k].re, p12[k].im, p3[k].re, t1, t2, offset);
                cost.push(c);
                off.push(o);
            }
        }
        Some(Costs {
            rows: orows,
            cols: ocols,
            cost,
            offset: off,
        })
    }
}

/// The cost of the template's top-left cell at exemplar cell `(u, v)` by direct summation, and
/// its offset; `None` when the template does not fit there. Heights are taken relative to
/// `shift` (any value near the data keeps the sums small).
pub fn direct_cost(
    e: &Array2<f32>,
    u: usize,
    v: usize,
    t: &Array2<f64>,
    m: &Array2<f64>,
    offset: Offset,
    shift: f64,
) -> Option<(f64, f64)> {
    let (rows, cols) = e.dim();
    let (tr, tc) = t.dim();
    if m.dim() != (tr, tc) || u + tr > rows || v + tc > cols {
        return None;
    }
    let (mut s0, mut s1, mut s2, mut x, mut t1, mut t2) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for r in 0..tr {
        for c in 0..tc {
            let w = m[[r, c]];
            if w == 0.0 {
                continue;
            }
            let ev = f64::from(e[[u + r, v + c]]) - shift;
            let tv = t[[r, c]] - shift;
            s0 += w;
            s1 += w * ev;
            s2 += w * ev * ev;
            x += w * tv * ev;
            t1 += w * tv;
            t2 += w * tv * tv;
        }
    }
    Some(finish(s0, s1, s2, x, t1, t2, offset))
}

/// Reference: the same costs by direct summation (with the same mean removal).
pub fn naive_costs(
    e: &Array2<f32>,
    t: &Array2<f64>,
    m: &Array2<f64>,
    offset: Offset,
) -> Option<Costs> {
    let (rows, cols) = e.dim();
    let (tr, tc) = t.dim();
    if m.dim() != (tr, tc) || tr == 0 || tc == 0 || tr > rows || tc > cols {
        return None;
    }
    let n = (rows * cols) as f64;
    let mean = e.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let (orows, ocols) = (rows - tr + 1, cols - tc + 1);
    let mut cost = Vec::new();
    let mut off = Vec::new();
    for u in 0..orows {
        for v in 0..ocols {
            let (mut s0, mut s1, mut s2, mut x, mut t1, mut t2) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for r in 0..tr {
                for c in 0..tc {
                    let w = m[[r, c]];
                    let ev = f64::from(e[[u + r, v + c]]) - mean;
                    let tv = t[[r, c]] - mean;
                    s0 += w;
                    s1 += w * ev;
                    s2 += w * ev * ev;
                    x += w * tv * ev;
                    t1 += w * tv;
                    t2 += w * tv * tv;
                }
            }
            let (c, o) = finish(s0, s1, s2, x, t1, t2, offset);
            cost.push(c);
            off.push(o);
        }
    }
    Some(Costs {
        rows: orows,
        cols: ocols,
        cost,
        offset: off,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_an_exact_copy() {
        // Not periodic (a periodic pattern has exact copies elsewhere): a hash of the cell.
        let e = Array2::from_shape_fn((20, 24), |(r, c)| {
            (crate::dictionary::rng::hash2(7, r as i64, c as i64) % 1000) as f32
        });
        let t = Array2::from_shape_fn((5, 6), |(r, c)| f64::from(e[[9 + r, 4 + c]]) + 3.0);
        let m = Array2::from_shape_fn((5, 6), |(r, c)| if (r + c) % 3 == 0 { 0.0 } else { 1.0 });
        let idx = SsdIndex::new(&e);
        let costs = idx.costs(&t, &m, Offset::Penalised(0.0)).unwrap();
        let (u, v, c) = costs.best().unwrap();
        assert_eq!((u, v), (9, 4));
        assert!(c < 1e-6);
        assert!((costs.offset[u * costs.cols + v] - 3.0).abs() < 1e-9);
        let naive = naive_costs(&e, &t, &m, Offset::Penalised(0.0)).unwrap();
        for (a, b) in costs.cost.iter().zip(&naive.cost) {
            assert!((a - b).abs() < 1e-6 * b.abs().max(1.0));
        }
    }
}
