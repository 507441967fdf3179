//! Radial band energy of a Hann-windowed grid, from the 2D FFT of [`fft`](mod@super::fft).

use std::f64::consts::PI;

use ndarray::Array2;

use super::fft::{fft2, Complex};

/// Periodic Hann window of length `n`: `0.5 − 0.5·cos(2πi/n)`.
fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos())
        .collect()
}

/// Signed frequency in cycles per sample of DFT bin `k` of `n`: `k/n` for `k ≤ n/2`, else
/// `(k − n)/n`.
fn bin_freq(k: usize, n: usize) -> f64 {
    if 2 * k <= n {
        k as f64 / n as f64
    } else {
        (k as f64 - n as f64) / n as f64
    }
}

/// Spectral energy of `z` in the radial band `f_lo ≤ |f| < f_hi`, `|f| = √(fx² + fy²)` in cycles
/// per pixel (Nyquist 0.5 along each axis; diagonal corners beyond 0.5 lie outside any band
/// ending at 0.5). The grid's mean is removed, a separable periodic Hann window applied, and the
/// energy is the plain sum of `|F|²` of the unnormalised 2D DFT over the band's bins (by
/// Parseval, the full-band sum is `rows·cols·Σ x_w²`). NaN propagates; empty grids give 0.
pub fn band_energy(z: &Array2<f32>, f_lo: f64, f_hi: f64) -> f64 {
    let (rows, cols) = z.dim();
    if rows == 0 || cols == 0 {
        return 0.0;
    }
    let mean = z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64;
    let (wr, wc) = (hann(rows), hann(cols));
    let mut f = Array2::from_shape_fn((rows, cols), |(r, c)| {
        Complex::new((z[[r, c]] as f64 - mean) * wr[r] * wc[c], 0.0)
    });
    fft2(&mut f, false);
    let mut e = 0.0;
    for ((r, c), v) in f.indexed_iter() {
        let (fy, fx) = (bin_freq(r, rows), bin_freq(c, cols));
        let fr = (fx * fx + fy * fy).sqrt();
        if fr >= f_lo && fr < f_hi {
            e += v.norm_sqr();
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_energy_parseval() {
        // The full band holds rows·cols·Σ x_w² (Parseval), corners beyond 0.5 included.
        let z = Array2::from_shape_fn((6, 10), |(r, c)| ((r * 7 + c * 3) % 5) as f32);
        let mean = z.iter().map(|&v| v as f64).sum::<f64>() / 60.0;
        let (wr, wc) = (hann(6), hann(10));
        let mut s = 0.0;
        for ((r, c), &v) in z.indexed_iter() {
            let x = (v as f64 - mean) * wr[r] * wc[c];
            s += x * x;
        }
        let e = band_energy(&z, 0.0, 1.0);
        assert!((e - 60.0 * s).abs() < 1e-9 * e.max(1.0));
        assert_eq!(bin_freq(3, 6), 0.5);
        assert_eq!(bin_freq(4, 6), -2.0 / 6.0);
    }
}
