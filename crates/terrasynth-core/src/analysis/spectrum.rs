//! Radial band energy of a Hann-windowed grid, from the 2D FFT of [`fft`](mod@super::fft).

use std::f64::consts::PI;

use ndarray::Array2;

use super::fft::{fft2, Complex};
use crate::math;

/// Periodic Hann window of length `n`: `0.5 − 0.5·cos(2πi/n)`.
fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 - 0.5 * math::cos(2.0 * PI * i as f64 / n as f64))
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
    let Some(f) = windowed_spectrum(z) else {
        return energies;
    };
    for ((r, c), v) in f.indexed_iter() {
        let fr = radial_freq(r, c, f.dim());
        for (e, &[f_lo, f_hi]) in energies.iter_mut().zip(bands) {
            if fr >= f_lo && fr < f_hi {
                *e += v.norm_sqr();
            }
        }
    }
    energies
}

/// The correlation of `a` and `b` (same shape) in each radial band of `bands`, from their
/// spectra as [`band_energy`] takes them (mean removed, Hann window): `Σ Re(A·B̄) / √(Σ|A|²·Σ|B|²)`
/// over the band's bins, in `[−1, 1]`; 0 where either has no energy in the band, and for every
/// band when the shapes differ or the grids are empty.
pub fn band_correlations(a: &Array2<f32>, b: &Array2<f32>, bands: &[[f64; 2]]) -> Vec<f64> {
    let mut sums = vec![[0.0f64; 3]; bands.len()];
    if a.dim() == b.dim() {
        if let (Some(fa), Some(fb)) = (windowed_spectrum(a), windowed_spectrum(b)) {
            for (((r, c), x), y) in fa.indexed_iter().zip(fb.iter()) {
                let fr = radial_freq(r, c, fa.dim());
                for (s, &[f_lo, f_hi]) in sums.iter_mut().zip(bands) {
                    if fr >= f_lo && fr < f_hi {
                        s[0] += x.re * y.re + x.im * y.im;
                        s[1] += x.norm_sqr();
                        s[2] += y.norm_sqr();
                    }
                }
            }
        }
    }
    sums.iter()
        .map(|&[ab, aa, bb]| {
            if aa > 0.0 && bb > 0.0 {
                ab / (aa * bb).sqrt()
            } else {
                0.0
            }
        })
        .collect()
}

/// The unnormalised 2D DFT of `z` with its mean removed and a separable periodic Hann window
/// applied; `None` for an empty grid.
fn windowed_spectrum(z: &Array2<f32>) -> Option<Array2<Complex>> {
    let (rows, cols) = z.dim();
    if rows == 0 || cols == 0 {
        return None;
    }
    let mean = z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64;
    let (wr, wc) = (hann(rows), hann(cols));
    let mut f = Array2::from_shape_fn((rows, cols), |(r, c)| {
        Complex::new((z[[r, c]] as f64 - mean) * wr[r] * wc[c], 0.0)
    });
    fft2(&mut f, false);
    Some(f)
}

/// `|f|` in cycles per sample of DFT bin `(r, c)` of a `(rows, cols)` spectrum.
fn radial_freq(r: usize, c: usize, (rows, cols): (usize, usize)) -> f64 {
    let (fy, fx) = (bin_freq(r, rows), bin_freq(c, cols));
    (fx * fx + fy * fy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The windowed spectrum of `z` by the 2D DFT written out as a double sum per bin: `(|f|,
    /// re, im)` per bin.
    fn direct_spectrum(z: &Array2<f32>) -> Vec<(f64, f64, f64)> {
        let (rows, cols) = z.dim();
        let mean = z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64;
        let (wr, wc) = (hann(rows), hann(cols));
        let mut out = Vec::new();
        for (kr, kc) in (0..rows).flat_map(|kr| (0..cols).map(move |kc| (kr, kc))) {
            let (mut re, mut im) = (0.0, 0.0);
            for ((r, c), &v) in z.indexed_iter() {
                let x = (v as f64 - mean) * wr[r] * wc[c];
                let phase =
                    -2.0 * PI * ((kr * r) as f64 / rows as f64 + (kc * c) as f64 / cols as f64);
                re += x * math::cos(phase);
                im += x * math::sin(phase);
            }
            let (fy, fx) = (bin_freq(kr, rows), bin_freq(kc, cols));
            out.push(((fx * fx + fy * fy).sqrt(), re, im));
        }
        out
    }

    fn test_grid(seed: usize) -> Array2<f32> {
        Array2::from_shape_fn((6, 8), |(r, c)| {
            ((r * 13 + c * 7 + seed) % 11) as f32 - 0.3 * (r * c) as f32
        })
    }

    const BANDS: [[f64; 2]; 5] = [[0.0, 1.0], [0.1, 0.3], [0.2, 0.5], [0.5, 1.0], [0.3, 0.3]];

    /// `band_energies` against the 2D DFT written out as a double sum per frequency bin.
    #[test]
    fn band_energies_match_a_direct_dft() {
        let z = test_grid(0);
        let mut expected = [0.0f64; 5];
        for (fr, re, im) in direct_spectrum(&z) {
            for (e, &[lo, hi]) in expected.iter_mut().zip(&BANDS) {
                if fr >= lo && fr < hi {
                    *e += re * re + im * im;
                }
            }
        }
        let got = band_energies(&z, &BANDS);
        assert_eq!(got.len(), BANDS.len());
        for (g, e) in got.iter().zip(&expected) {
            assert!((g - e).abs() <= 1e-9 * expected[0], "{g} vs {e}");
        }
        assert!(got[1] > 0.0 && got[3] > 0.0);
        assert_eq!(got[4], 0.0);
        assert!(band_energies(&Array2::<f32>::zeros((0, 4)), &BANDS)
            .iter()
            .all(|&e| e == 0.0));
        assert!(band_energies(&z, &[]).is_empty());
    }

    /// `band_correlations` against the direct DFT; ±1 against itself and its negative; 0 where a
    /// band is empty or the shapes differ.
    #[test]
    fn band_correlations_match_a_direct_dft() {
        let (a, b) = (test_grid(0), test_grid(5));
        let mut sums = [[0.0f64; 3]; 5];
        for ((fr, ar, ai), (_, br, bi)) in direct_spectrum(&a).into_iter().zip(direct_spectrum(&b))
        {
            for (s, &[lo, hi]) in sums.iter_mut().zip(&BANDS) {
                if fr >= lo && fr < hi {
                    s[0] += ar * br + ai * bi;
                    s[1] += ar * ar + ai * ai;
                    s[2] += br * br + bi * bi;
                }
            }
        }
        let got = band_correlations(&a, &b, &BANDS);
        for (g, s) in got.iter().zip(&sums).take(4) {
            let e = s[0] / (s[1] * s[2]).sqrt();
            assert!((g - e).abs() < 1e-9, "{g} vs {e}");
            assert!(g.abs() < 1.0 - 1e-6);
        }
        assert_eq!(got[4], 0.0);
        for (own, neg) in band_correlations(&a, &a, &BANDS)
            .iter()
            .zip(band_correlations(&a, &a.mapv(|v| -v), &BANDS))
            .take(4)
        {
            assert!((own - 1.0).abs() < 1e-12 && (neg + 1.0).abs() < 1e-12);
        }
        let other = Array2::<f32>::zeros((6, 7));
        assert!(band_correlations(&a, &other, &BANDS)
            .iter()
            .all(|&c| c == 0.0));
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
