//! The one FFT of the crate: an iterative radix-2 complex FFT in `f64` ([`Radix2`], forward or
//! inverse by conjugated twiddles), Bluestein's chirp-z algorithm for other lengths (exact to
//! rounding, O(n log n)), the 1D [`fft`] of any length, a 2D wrapper [`fft2`] (rows, then
//! columns) and the naive DFT [`dft_naive`] they are tested against. Twiddles are computed
//! directly with `sin`/`cos` (no recurrences), so results are deterministic and accurate to
//! about 1e-15 relative. [`band_energy`](super::spectrum::band_energy) and the SSD search of
//! `synth::sketch::ssd` use it.
//!
//! Convention: forward `X_k = Σ_n x_n·e^{−2πikn/N}` (unnormalised); inverse
//! `x_n = (1/N)·Σ_k X_k·e^{+2πikn/N}` ([`Radix2::run`] leaves the inverse unnormalised).

use std::f64::consts::PI;

use ndarray::Array2;

use crate::math;

/// A complex number in `f64`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Complex {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

impl Complex {
    /// `re + i·im`.
    pub const fn new(re: f64, im: f64) -> Self {
        Complex { re, im }
    }

    /// `e^{iθ}`.
    pub fn cis(theta: f64) -> Self {
        Complex::new(math::cos(theta), math::sin(theta))
    }

    /// Complex conjugate.
    pub fn conj(self) -> Self {
        Complex::new(self.re, -self.im)
    }

    /// `|z|²`.
    pub fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    /// Product.
    #[allow(clippy::should_implement_trait)]
    pub fn mul(self, o: Complex) -> Complex {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }

    /// Sum.
    #[allow(clippy::should_implement_trait)]
    pub fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }

    /// Difference.
    #[allow(clippy::should_implement_trait)]
    pub fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }

    /// Scaled by a real factor.
    pub fn scale(self, s: f64) -> Complex {
        Complex::new(self.re * s, self.im * s)
    }
}

/// A radix-2 FFT of one power-of-two length: its twiddle table `tw[k] = e^{−2πik/n}`, `k < n/2`.
/// Lengths that are not powers of two go through [`fft`] / [`fft2`] (Bluestein).
#[derive(Clone, Debug)]
pub struct Radix2 {
    n: usize,
    tw: Vec<Complex>,
}

impl Radix2 {
    /// The plan of length `n` (meant to be a power of two; [`run`](Self::run) leaves data of
    /// any other length untouched).
    pub fn new(n: usize) -> Self {
        let tw = (0..n / 2)
            .map(|k| Complex::cis(-2.0 * PI * k as f64 / n as f64))
            .collect();
        Radix2 { n, tw }
    }

    /// The length this plan transforms.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the length is 0.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// In-place, unnormalised transform of `data` (iterative decimation in time after a
    /// bit-reversal permutation); `inverse` conjugates the twiddles, giving
    /// `Σ_k X_k·e^{+2πikn/N}` without the `1/N`. Does nothing unless `data.len()` equals the
    /// plan's length, a power of two above 1.
    pub fn run(&self, data: &mut [Complex], inverse: bool) {
        let n = self.n;
        if n <= 1 || !n.is_power_of_two() || data.len() != n {
            return;
        }
        let bits = n.trailing_zeros();
        for i in 0..n {
            let j = i.reverse_bits() >> (usize::BITS - bits);
            if j > i {
                data.swap(i, j);
            }
        }
        let mut len = 2;
        while len <= n {
            let half = len / 2;
            let step = n / len;
            for start in (0..n).step_by(len) {
                for k in 0..half {
                    let w = self.tw[k * step];
                    let w = if inverse { w.conj() } else { w };
                    let u = data[start + k];
                    let v = data[start + k + half].mul(w);
                    data[start + k] = u.add(v);
                    data[start + k + half] = u.sub(v);
                }
            }
            len *= 2;
        }
    }
}

/// A precomputed FFT of one length: radix-2 for powers of two, Bluestein's chirp-z otherwise.
enum Plan {
    /// Length 0 or 1: the identity.
    Trivial,
    /// Power of two.
    Radix2(Radix2),
    /// Any other length `n`, as a circular convolution of power-of-two length `m ≥ 2n − 1`.
    Bluestein {
        n: usize,
        inner: Radix2,
        /// `e^{−iπk²/n}`, `k < n`.
        chirp: Vec<Complex>,
        /// FFT of the conjugate chirp laid out circularly.
        bfft: Vec<Complex>,
    },
}

impl Plan {
    fn new(n: usize) -> Self {
        if n <= 1 {
            return Plan::Trivial;
        }
        if n.is_power_of_two() {
            return Plan::Radix2(Radix2::new(n));
        }
        let m = (2 * n - 1).next_power_of_two();
        let inner = Radix2::new(m);
        // k² is reduced mod 2n in integers to keep the angle small and exact.
        let two_n = 2 * n as u128;
        let chirp: Vec<Complex> = (0..n)
            .map(|k| {
                let k2 = ((k as u128 * k as u128) % two_n) as f64;
                Complex::cis(-PI * k2 / n as f64)
            })
            .collect();
        let mut bfft = vec![Complex::default(); m];
        bfft[0] = chirp[0].conj();
        for k in 1..n {
            bfft[k] = chirp[k].conj();
            bfft[m - k] = chirp[k].conj();
        }
        inner.run(&mut bfft, false);
        Plan::Bluestein {
            n,
            inner,
            chirp,
            bfft,
        }
    }

    /// Forward unnormalised transform in place; `scratch` is reused between calls.
    fn forward(&self, data: &mut [Complex], scratch: &mut Vec<Complex>) {
        match self {
            Plan::Trivial => {}
            Plan::Radix2(r) => r.run(data, false),
            Plan::Bluestein {
                n,
                inner,
                chirp,
                bfft,
            } => {
                let m = inner.n;
                scratch.clear();
                scratch.resize(m, Complex::default());
                for k in 0..(*n).min(data.len()) {
                    scratch[k] = data[k].mul(chirp[k]);
                }
                inner.run(scratch, false);
                for (x, y) in scratch.iter_mut().zip(bfft) {
                    // Multiply and conjugate, preparing the inverse FFT by conjugation.
                    *x = x.mul(*y).conj();
                }
                inner.run(scratch, false);
                let inv_m = 1.0 / m as f64;
                for k in 0..(*n).min(data.len()) {
                    data[k] = scratch[k].conj().scale(inv_m).mul(chirp[k]);
                }
            }
        }
    }

    /// Forward or inverse (scaled by `1/N`) transform in place.
    fn run(&self, data: &mut [Complex], inverse: bool, scratch: &mut Vec<Complex>) {
        if !inverse {
            self.forward(data, scratch);
            return;
        }
        for x in data.iter_mut() {
            *x = x.conj();
        }
        self.forward(data, scratch);
        let s = 1.0 / data.len().max(1) as f64;
        for x in data.iter_mut() {
            *x = x.conj().scale(s);
        }
    }
}

/// In-place FFT of any length (radix-2 for powers of two, Bluestein otherwise). With
/// `inverse` the result is scaled by `1/N`.
pub fn fft(data: &mut [Complex], inverse: bool) {
    if data.len() <= 1 {
        return;
    }
    Plan::new(data.len()).run(data, inverse, &mut Vec::new());
}

/// In-place 2D FFT of a `(rows, cols)` array: every row, then every column (one plan per
/// axis, reused for all lines).
pub fn fft2(data: &mut Array2<Complex>, inverse: bool) {
    let (rows, cols) = data.dim();
    let mut buf = vec![Complex::default(); rows.max(cols)];
    let mut scratch = Vec::new();
    let row_plan = Plan::new(cols);
    for mut row in data.rows_mut() {
        let b = &mut buf[..cols];
        for (x, v) in b.iter_mut().zip(row.iter()) {
            *x = *v;
        }
        row_plan.run(b, inverse, &mut scratch);
        for (v, x) in row.iter_mut().zip(b.iter()) {
            *v = *x;
        }
    }
    let col_plan = Plan::new(rows);
    for mut col in data.columns_mut() {
        let b = &mut buf[..rows];
        for (x, v) in b.iter_mut().zip(col.iter()) {
            *x = *v;
        }
        col_plan.run(b, inverse, &mut scratch);
        for (v, x) in col.iter_mut().zip(b.iter()) {
            *v = *x;
        }
    }
}

/// Reference O(N²) DFT with the same convention as [`fft`] (the phase index `j·k` is reduced
/// mod N in integers).
pub fn dft_naive(x: &[Complex], inverse: bool) -> Vec<Complex> {
    let n = x.len();
    let sign = if inverse { 1.0 } else { -1.0 };
    (0..n)
        .map(|k| {
            let mut s = Complex::default();
            for (j, v) in x.iter().enumerate() {
                let p = ((j as u128 * k as u128) % n as u128) as f64;
                s = s.add(v.mul(Complex::cis(sign * 2.0 * PI * p / n as f64)));
            }
            if inverse {
                s.scale(1.0 / n as f64)
            } else {
                s
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(n: usize) -> Vec<Complex> {
        (0..n)
            .map(|i| Complex::new(math::sin(i as f64 * 0.7), math::cos(i as f64 * 1.3)))
            .collect()
    }

    fn close(a: &[Complex], b: &[Complex], tol: f64) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| x.sub(*y).norm_sqr().sqrt() < tol)
    }

    #[test]
    fn radix2_and_bluestein_match_naive_dft() {
        for n in [1usize, 2, 3, 5, 8, 12, 17, 64, 100] {
            let x = signal(n);
            let mut f = x.clone();
            fft(&mut f, false);
            assert!(close(&f, &dft_naive(&x, false), 1e-10), "forward, n = {n}");
            let mut g = x.clone();
            fft(&mut g, true);
            assert!(close(&g, &dft_naive(&x, true), 1e-12), "inverse, n = {n}");
            fft(&mut f, true);
            assert!(close(&f, &x, 1e-12), "round trip, n = {n}");
        }
    }

    #[test]
    fn radix2_plan_matches_naive_dft_both_ways() {
        for n in [1usize, 2, 4, 8, 32, 128] {
            let x = signal(n);
            let plan = Radix2::new(n);
            assert_eq!(plan.len(), n);
            let mut f = x.clone();
            plan.run(&mut f, false);
            assert!(close(&f, &dft_naive(&x, false), 1e-10), "forward, n = {n}");
            // The plan's inverse is unnormalised: N times the naive inverse.
            let mut g = x.clone();
            plan.run(&mut g, true);
            let want: Vec<Complex> = dft_naive(&x, true)
                .into_iter()
                .map(|v| v.scale(n as f64))
                .collect();
            assert!(close(&g, &want, 1e-10), "inverse, n = {n}");
        }
        // A length that is not the plan's, or not a power of two, is left alone.
        let x = signal(6);
        let mut y = x.clone();
        Radix2::new(6).run(&mut y, false);
        Radix2::new(8).run(&mut y, true);
        assert_eq!(x, y);
    }

    #[test]
    fn radix2_inverse_is_the_conjugated_forward_bit_for_bit() {
        // `fft(.., true)` conjugates around the forward plan, the SSD search conjugates the
        // twiddles: the same products and sums up to signs, so the same values.
        let n = 64;
        let x = signal(n);
        let plan = Radix2::new(n);
        let mut a = x.clone();
        plan.run(&mut a, true);
        let mut b: Vec<Complex> = x.iter().map(|v| v.conj()).collect();
        plan.run(&mut b, false);
        for (p, q) in a.iter().zip(&b) {
            assert_eq!((p.re, p.im), (q.re, -q.im));
        }
    }
}
