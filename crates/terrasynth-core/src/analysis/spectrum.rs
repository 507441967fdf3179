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
    band_energies(z, &[[f_lo, f_hi]])[0]
}

/// [`band_energy`] of every `[f_lo, f_hi]` in `bands`, from one transform of `z`: each value is
/// bit-identical to the single-band call (the same bins summed in the same order). Bands may
/// overlap.
pub fn band_energies(z: &Array2<f32>, bands: &[[f64; 2]]) -> Vec<f64> {
    let mut energies = vec![0.0; bands.len()];
    let (rows, cols) = z.dim();
    if rows == 0 || cols == 0 {
        return energies;
    }
    let mean = z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64;
    let (wr, wc) = (hann(rows), hann(cols));
    let mut f = Array2::from_shape_fn((rows, cols), |(r, c)| {
        Complex::new((z[[r, c]] as f64 - mean) * wr[r] * wc[c], 0.0)
    });
    fft2(&mut f, false);
    for ((r, c), v) in f.indexed_iter() {
        let (fy, fx) = (bin_freq(r, rows), bin_freq(c, cols));
        let fr = (fx * fx + fy * fy).sqrt();
        for (e, &[f_lo, f_hi]) in energies.iter_mut().zip(bands) {
            if fr >= f_lo && fr < f_hi {
                *e += v.norm_sqr();
            }
        }
    }
    energies
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `band_energies` against the 2D DFT written out as a double sum per frequency bin.
    #[test]
    fn band_energies_match_a_direct_dft() {
        let (rows, cols) = (6, 8);
        let z = Array2::from_shape_fn((rows, cols), |(r, c)| {
            ((r * 13 + c * 7) % 11) as f32 - 0.3 * (r * c) as f32
        });
        let mean = z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64;
        let (wr, wc) = (hann(rows), hann(cols));
        let bands = [[0.0, 1.0], [0.1, 0.3], [0.2, 0.5], [0.5, 1.0], [0.3, 0.3]];
        let mut expected = [0.0f64; 5];
        for (kr, kc) in (0..rows).flat_map(|kr| (0..cols).map(move |kc| (kr, kc))) {
            let (mut re, mut im) = (0.0, 0.0);
            for ((r, c), &v) in z.indexed_iter() {
                let x = (v as f64 - mean) * wr[r] * wc[c];
                let phase =
                    -2.0 * PI * ((kr * r) as f64 / rows as f64 + (kc * c) as f64 / cols as f64);
                re += x * phase.cos();
                im += x * phase.sin();
            }
            let (fy, fx) = (bin_freq(kr, rows), bin_freq(kc, cols));
            let fr = (fx * fx + fy * fy).sqrt();
            for (e, &[lo, hi]) in expected.iter_mut().zip(&bands) {
                if fr >= lo && fr < hi {
                    *e += re * re + im * im;
                }
            }
        }
        let got = band_energies(&z, &bands);
        assert_eq!(got.len(), bands.len());
        for (g, e) in got.iter().zip(&expected) {
            assert!((g - e).abs() <= 1e-9 * expected[0], "{g} vs {e}");
        }
        assert!(got[1] > 0.0 && got[3] > 0.0);
        assert_eq!(got[4], 0.0);
        assert!(band_energies(&Array2::<f32>::zeros((0, 4)), &bands)
            .iter()
            .all(|&e| e == 0.0));
        assert!(band_energies(&z, &[]).is_empty());
    }

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
