//! TEMPORARY stand-in (replaced by the dictionary branch): patch features shared by build and synthesis.

/// Patches whose centred norm is below this are flat.
pub const MIN_RELIEF_M: f32 = 1e-3;

/// 2×2 box average of a `side × side` patch into `side/2 × side/2`.
pub fn box_down2(hi: &[f32], side: usize, out: &mut [f32]) {
    let lo = side / 2;
    for r in 0..lo {
        for c in 0..lo {
            let a = hi[2 * r * side + 2 * c];
            let b = hi[2 * r * side + 2 * c + 1];
            let d = hi[(2 * r + 1) * side + 2 * c];
            let e = hi[(2 * r + 1) * side + 2 * c + 1];
            out[r * lo + c] = (a + b + d + e) * 0.25;
        }
    }
}

/// Centres `x` and scales it to unit norm into `out`; returns `(mean, norm)`.
pub fn centre_normalise(x: &[f32], out: &mut [f32]) -> (f32, f32) {
    let n = x.len() as f32;
    let mean = x.iter().sum::<f32>() / n;
    let mut ss = 0.0f32;
    for (o, &v) in out.iter_mut().zip(x) {
        *o = v - mean;
        ss += *o * *o;
    }
    let norm = ss.sqrt();
    if norm > 0.0 {
        for o in out.iter_mut() {
            *o /= norm;
        }
    } else {
        out.iter_mut().for_each(|o| *o = 0.0);
    }
    (mean, norm)
}

/// Mean gradient magnitude of a low-res patch.
pub fn patch_mean_slope(lo: &[f32], side: usize, cell_m: f32) -> f32 {
    let _ = (lo, side, cell_m);
    0.0
}
