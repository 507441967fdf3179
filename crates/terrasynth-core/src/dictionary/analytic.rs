//! Analytic (procedural) atoms: patches of Perlin gradient noise and of ridged noise
//! (`1 − 2|perlin|`, sharp crests) at several wavelengths, orientations and elongations, centred
//! and scaled to unit norm like exemplar atoms. A dictionary may mix them with exemplar atoms;
//! compressing a real terrain with analytic atoms only is the paper's *inverse procedural
//! modelling* (how much of the terrain procedural noise can explain).
//!
//! The noise is ours and deterministic: lattice gradients are drawn from [`hash2`] of the lattice
//! point and the atom's seed, and evaluated with the quintic fade `6t⁵ − 15t⁴ + 10t³`.

use super::rng::hash2;
use crate::math;

/// Which procedural atoms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnalyticKind {
    /// Perlin gradient noise.
    Perlin,
    /// Ridged noise, `1 − 2|perlin|`.
    Ridged,
}

impl std::str::FromStr for AnalyticKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "perlin" => Ok(AnalyticKind::Perlin),
            "ridged" => Ok(AnalyticKind::Ridged),
            _ => Err(format!("`{s}`: expected `perlin` or `ridged`")),
        }
    }
}

/// Wavelengths of the noise, in patch sides (a lattice cell spans `patch × w` pixels).
const WAVELENGTHS: [f64; 3] = [1.0, 0.5, 0.25];
/// Orientations, degrees.
const ORIENTATIONS: [f64; 4] = [0.0, 45.0, 90.0, 135.0];
/// Elongations: isotropic, and stretched 3× along the orientation (ridges and valleys).
const ELONGATIONS: [f64; 2] = [1.0, 3.0];

/// 2-D Perlin gradient noise at `(x, y)` with lattice gradients seeded by `seed` (about −1..1).
pub fn perlin(x: f64, y: f64, seed: u64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let grad = |gx: i64, gy: i64, dx: f64, dy: f64| -> f64 {
        // An angle from the hash: the gradient is a unit vector.
        let h = hash2(seed, gx, gy);
        let angle = (h >> 11) as f64 * (std::f64::consts::TAU / (1u64 << 53) as f64);
        math::cos(angle) * dx + math::sin(angle) * dy
    };
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let n00 = grad(ix, iy, fx, fy);
    let n10 = grad(ix + 1, iy, fx - 1.0, fy);
    let n01 = grad(ix, iy + 1, fx, fy - 1.0);
    let n11 = grad(ix + 1, iy + 1, fx - 1.0, fy - 1.0);
    let a = n00 + u * (n10 - n00);
    let b = n01 + u * (n11 - n01);
    (a + v * (b - a)) * std::f64::consts::SQRT_2
}

/// `count` analytic atoms of side `patch` (`count × patch²`, atom-major, centred, unit norm):
/// every combination of wavelength, orientation and elongation, repeated with new seeds until
/// `count` atoms are made. Flat patches (which cannot be normalised) are skipped.
pub fn analytic_atoms(kind: AnalyticKind, patch: usize, count: usize, seed: u64) -> Vec<f32> {
    let p2 = patch * patch;
    let mut out = Vec::with_capacity(count * p2);
    let mut buf = vec![0.0f64; p2];
    let mut made = 0usize;
    let mut round = 0u64;
    while made < count && round < 1024 {
        for &w in &WAVELENGTHS {
            for &theta in &ORIENTATIONS {
                for &elong in &ELONGATIONS {
                    if made == count {
                        continue;
                    }
                    let s = seed ^ round.wrapping_mul(0x9e37_79b9_7f4a_7c15);
                    let (sin, cos) = math::sincos(theta.to_radians());
                    let scale = 1.0 / (w * patch as f64);
                    // Offsets move the lattice so different rounds differ.
                    let (ox, oy) = ((s % 97) as f64 * 0.37, (s % 89) as f64 * 0.41);
                    for r in 0..patch {
                        for c in 0..patch {
                            let (x, y) = ((c as f64 + 0.5) * scale, (r as f64 + 0.5) * scale);
                            let (u, v) = (cos * x + sin * y, (-sin * x + cos * y) * elong);
                            let n = perlin(u + ox, v + oy, s);
                            buf[r * patch + c] = match kind {
                                AnalyticKind::Perlin => n,
                                AnalyticKind::Ridged => 1.0 - 2.0 * n.abs(),
                            };
                        }
                    }
                    let mean = buf.iter().sum::<f64>() / p2 as f64;
                    let norm = buf
                        .iter()
                        .map(|v| (v - mean) * (v - mean))
                        .sum::<f64>()
                        .sqrt();
                    if norm < 1e-9 {
                        continue;
                    }
                    out.extend(buf.iter().map(|v| ((v - mean) / norm) as f32));
                    made += 1;
                }
            }
        }
        round += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_zero_on_the_lattice_and_continuous() {
        // Gradient noise vanishes at lattice points.
        for (x, y) in [(0.0, 0.0), (3.0, -2.0), (17.0, 5.0)] {
            assert!(perlin(x, y, 9).abs() < 1e-12);
        }
        // Small steps make small changes (C¹ fade).
        let a = perlin(1.3, 2.7, 4);
        let b = perlin(1.3 + 1e-6, 2.7, 4);
        assert!((a - b).abs() < 1e-4);
        assert!(perlin(0.5, 0.5, 1) != perlin(0.5, 0.5, 2));
    }

    #[test]
    fn atoms_are_centred_unit_norm_and_deterministic() {
        for kind in [AnalyticKind::Perlin, AnalyticKind::Ridged] {
            let atoms = analytic_atoms(kind, 16, 30, 5);
            assert_eq!(atoms.len(), 30 * 256);
            for a in atoms.chunks(256) {
                let mean: f64 = a.iter().map(|&v| f64::from(v)).sum::<f64>() / 256.0;
                let norm: f64 = a.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>().sqrt();
                assert!(mean.abs() < 1e-6 && (norm - 1.0).abs() < 1e-5);
            }
            assert_eq!(atoms, analytic_atoms(kind, 16, 30, 5));
        }
        // The two kinds differ.
        assert_ne!(
            analytic_atoms(AnalyticKind::Ridged, 16, 4, 1),
            analytic_atoms(AnalyticKind::Perlin, 16, 4, 1)
        );
    }
}
