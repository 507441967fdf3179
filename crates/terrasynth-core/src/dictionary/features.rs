//! Patch features shared by dictionary building and amplification: THE ×2 down-sampling filter,
//! centring/normalisation of patches, and the mean slope of a low-resolution patch.
//!
//! Every function here sums in a fixed order (row-major, left to right) so results are
//! bit-identical on every machine and thread count.

use crate::raster::boxfilter::box_down2_rows;

/// Relief (norm `s` of the centred low-resolution patch, metres) below which a patch is considered
/// flat: it carries no shape to match or reconstruct and is skipped when building dictionaries.
pub const MIN_RELIEF_M: f32 = 0.5;

/// Down-samples a `side × side` row-major patch by 2×2 box averaging into `out`
/// (`side/2 × side/2`), summing in exactly this order:
///
/// ```text
/// out[r][c] = (hi[2r][2c] + hi[2r][2c+1] + hi[2r+1][2c] + hi[2r+1][2c+1]) * 0.25
/// ```
///
/// The filter itself is [`crate::raster::boxfilter`], the single down-sampling filter of
/// terrasynth: low-resolution atoms are built with it and the amplifier applies it to its inputs.
///
/// # Panics
/// If `side` is odd, `hi.len() != side²` or `out.len() != (side/2)²`.
#[inline(always)]
pub fn box_down2(hi: &[f32], side: usize, out: &mut [f32]) {
    assert!(side % 2 == 0, "box_down2: side {side} must be even");
    assert_eq!(hi.len(), side * side, "box_down2: input length");
    let lo = side / 2;
    assert_eq!(out.len(), lo * lo, "box_down2: output length");
    for r in 0..lo {
        let top = &hi[2 * r * side..(2 * r + 1) * side];
        let bottom = &hi[(2 * r + 1) * side..(2 * r + 2) * side];
        box_down2_rows(top, bottom, &mut out[r * lo..(r + 1) * lo]);
    }
}

/// Centres and normalises `x` into `out`: `out = (x − a) / s` with `a = mean(x)` and
/// `s = ‖x − a‖₂`; returns `(a, s)`. When `s` is 0 (constant input) `out` is all zeros.
/// Sums are accumulated in `f64` in index order.
///
/// # Panics
/// If `x.len() != out.len()`.
pub fn centre_normalise(x: &[f32], out: &mut [f32]) -> (f32, f32) {
    let [stats] = centre_normalise_n([x], [out]);
    stats
}

/// [`centre_normalise`] of `N` inputs of one length at once, each bit for bit as alone: every
/// input's sums run in index order, and the `N` chains of additions interleave, so that their
/// latencies overlap (the amplifier prepares its queries in groups).
///
/// # Panics
/// If the inputs and outputs do not all have the same length.
#[inline(always)]
pub fn centre_normalise_n<const N: usize>(
    xs: [&[f32]; N],
    outs: [&mut [f32]; N],
) -> [(f32, f32); N] {
    let len = xs.first().map_or(0, |x| x.len());
    assert!(
        xs.iter().all(|x| x.len() == len) && outs.iter().all(|o| o.len() == len),
        "centre_normalise: length mismatch"
    );
    if len == 0 {
        return [(0.0, 0.0); N];
    }
    let mut sum = [0.0f64; N];
    for i in 0..len {
        for (s, x) in sum.iter_mut().zip(&xs) {
            *s += f64::from(x[i]);
        }
    }
    let mean = sum.map(|s| s / len as f64);
    let mut sq = [0.0f64; N];
    for i in 0..len {
        for ((s, x), &m) in sq.iter_mut().zip(&xs).zip(&mean) {
            let d = f64::from(x[i]) - m;
            *s += d * d;
        }
    }
    let mut stats = [(0.0f32, 0.0f32); N];
    for (((out, x), st), (&mean, &sq)) in outs
        .into_iter()
        .zip(&xs)
        .zip(&mut stats)
        .zip(mean.iter().zip(&sq))
    {
        let norm = sq.sqrt();
        if norm > 0.0 && norm.is_finite() {
            let inv = 1.0 / norm;
            for (o, &v) in out.iter_mut().zip(*x) {
                *o = ((f64::from(v) - mean) * inv) as f32;
            }
        } else {
            out.fill(0.0);
        }
        *st = (mean as f32, norm as f32);
    }
    stats
}

/// Mean gradient magnitude (m/m) of a `side × side` row-major low-resolution patch whose cells are
/// `cell_m` metres apart. Derivatives are central differences inside the patch and one-sided
/// differences on its edges; the mean is accumulated in `f64` in row-major order. Returns 0 for a
/// patch of side < 2 or a non-positive cell size.
///
/// # Panics
/// If `lo.len() != side²`.
pub fn patch_mean_slope(lo: &[f32], side: usize, cell_m: f32) -> f32 {
    patch_mean_slope_n([lo], side, cell_m)[0]
}

/// [`patch_mean_slope`] of `N` patches at once, each bit for bit as alone (their sums
/// interleave, as in [`centre_normalise_n`]).
///
/// # Panics
/// If a patch's length is not `side²`.
#[inline(always)]
pub fn patch_mean_slope_n<const N: usize>(los: [&[f32]; N], side: usize, cell_m: f32) -> [f32; N] {
    for lo in &los {
        assert_eq!(lo.len(), side * side, "patch_mean_slope: length");
    }
    if side < 2 || cell_m <= 0.0 || !cell_m.is_finite() {
        return [0.0; N];
    }
    if side > MAX_ROW_SIDE {
        return los.map(|lo| mean_slope_plain(lo, side, cell_m));
    }
    let cell = f64::from(cell_m);
    let two_cell = 2.0 * cell;
    // Row by row: the derivatives and magnitudes of a whole row first (independent, so they
    // vectorise), then their sum in row-major order, which keeps the bits of the plain loop.
    let mut mags = [[0.0f64; MAX_ROW_SIDE]; N];
    let mut gy = [0.0f64; MAX_ROW_SIDE];
    let mut total = [0.0f64; N];
    for r in 0..side {
        for (lo, gx) in los.iter().zip(&mut mags) {
            let at = |r: usize| &lo[r * side..(r + 1) * side];
            let here = at(r);
            let (up, down, div) = if r == 0 {
                (here, at(1), cell)
            } else if r == side - 1 {
                (at(r - 1), here, cell)
            } else {
                (at(r - 1), at(r + 1), two_cell)
            };
            for ((g, &u), &d) in gy[..side].iter_mut().zip(up).zip(down) {
                *g = (f64::from(d) - f64::from(u)) / div;
            }
            gx[0] = (f64::from(here[1]) - f64::from(here[0])) / cell;
            for c in 1..side - 1 {
                gx[c] = (f64::from(here[c + 1]) - f64::from(here[c - 1])) / two_cell;
            }
            gx[side - 1] = (f64::from(here[side - 1]) - f64::from(here[side - 2])) / cell;
            for (x, &y) in gx[..side].iter_mut().zip(&gy[..side]) {
                *x = (*x * *x + y * y).sqrt();
            }
        }
        for c in 0..side {
            for (t, m) in total.iter_mut().zip(&mags) {
                *t += m[c];
            }
        }
    }
    total.map(|t| (t / (side * side) as f64) as f32)
}

/// Widest patch [`patch_mean_slope`] handles a row at a time (wider ones take the plain loop).
const MAX_ROW_SIDE: usize = 32;

/// [`patch_mean_slope`] one cell at a time (patches wider than [`MAX_ROW_SIDE`]).
fn mean_slope_plain(lo: &[f32], side: usize, cell_m: f32) -> f32 {
    let cell = f64::from(cell_m);
    let at = |r: usize, c: usize| f64::from(lo[r * side + c]);
    // One-sided differences on the edges, central ones inside (the same expressions for both
    // axes, so the result is symmetric under transposition).
    let diff = |before: f64, here: f64, after: f64, i: usize| -> f64 {
        if i == 0 {
            (after - here) / cell
        } else if i == side - 1 {
            (here - before) / cell
        } else {
            (after - before) / (2.0 * cell)
        }
    };
    let mut total = 0.0f64;
    for r in 0..side {
        for c in 0..side {
            let here = at(r, c);
            let left = if c > 0 { at(r, c - 1) } else { here };
            let right = if c + 1 < side { at(r, c + 1) } else { here };
            let up = if r > 0 { at(r - 1, c) } else { here };
            let down = if r + 1 < side { at(r + 1, c) } else { here };
            let gx = diff(left, here, right, c);
            let gy = diff(up, here, down, r);
            total += (gx * gx + gy * gy).sqrt();
        }
    }
    (total / (side * side) as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn box_down_known_values() {
        #[rustfmt::skip]
        let hi = [
            1.0, 2.0, 3.0, 4.0,
            5.0, 6.0, 7.0, 8.0,
            0.0, 0.0, 4.0, 4.0,
            0.0, 4.0, 4.0, 4.0,
        ];
        let mut out = [0.0; 4];
        box_down2(&hi, 4, &mut out);
        assert_eq!(out, [3.5, 5.5, 1.0, 4.0]);
    }

    #[test]
    fn centre_normalise_known_and_flat() {
        let mut out = [0.0f32; 4];
        // mean 2.5, deviations ±1.5, ±0.5: norm sqrt(2·2.25 + 2·0.25) = sqrt(5).
        let (a, s) = centre_normalise(&[1.0, 2.0, 3.0, 4.0], &mut out);
        assert_eq!(a, 2.5);
        assert!((s - 5f32.sqrt()).abs() < 1e-6);
        assert!((out[0] + 1.5 / 5f32.sqrt()).abs() < 1e-6);
        let (a, s) = centre_normalise(&[7.0; 4], &mut out);
        assert_eq!((a, s), (7.0, 0.0));
        assert_eq!(out, [0.0; 4]);
    }

    #[test]
    fn slope_of_planes() {
        // Plane z = 3·x_m + 4·y_m on 10 m cells: gradient magnitude 5 everywhere, edges included.
        let side = 6;
        let mut p = vec![0.0f32; side * side];
        for r in 0..side {
            for c in 0..side {
                p[r * side + c] = (3.0 * 10.0 * c as f64 + 4.0 * 10.0 * r as f64) as f32;
            }
        }
        assert!((patch_mean_slope(&p, side, 10.0) - 5.0).abs() < 1e-5);
        assert_eq!(patch_mean_slope(&[2.0; 16], 4, 10.0), 0.0);
        // A 1-cell step between columns 1 and 2 of a 4-wide patch: per-row gradients are
        // [0, h/2c, h/2c, 0] with h=2, c=1 → mean 0.5.
        #[rustfmt::skip]
        let step = [
            0.0, 0.0, 2.0, 2.0,
            0.0, 0.0, 2.0, 2.0,
            0.0, 0.0, 2.0, 2.0,
            0.0, 0.0, 2.0, 2.0,
        ];
        assert!((patch_mean_slope(&step, 4, 1.0) - 0.5).abs() < 1e-6);
    }

    /// Mean slope by the textbook formula, one derivative function per axis (the reference the
    /// loop in [`patch_mean_slope`] must equal bit for bit).
    fn patch_mean_slope_reference(lo: &[f32], side: usize, cell_m: f32) -> f32 {
        let cell = f64::from(cell_m);
        let at = |r: usize, c: usize| f64::from(lo[r * side + c]);
        let deriv = |i: usize, get: &dyn Fn(usize) -> f64| -> f64 {
            if i == 0 {
                (get(1) - get(0)) / cell
            } else if i == side - 1 {
                (get(side - 1) - get(side - 2)) / cell
            } else {
                (get(i + 1) - get(i - 1)) / (2.0 * cell)
            }
        };
        let mut total = 0.0f64;
        for r in 0..side {
            for c in 0..side {
                let gx = deriv(c, &|j| at(r, j));
                let gy = deriv(r, &|i| at(i, c));
                total += (gx * gx + gy * gy).sqrt();
            }
        }
        (total / (side * side) as f64) as f32
    }

    proptest! {
        #[test]
        fn mean_slope_equals_the_reference(
            side in 2usize..10,
            cell in 0.5f32..500.0,
            values in proptest::collection::vec(-3000.0f32..3000.0, 100),
        ) {
            prop_assert_eq!(
                mean_slope_plain(&values[..side * side], side, cell).to_bits(),
                patch_mean_slope_reference(&values[..side * side], side, cell).to_bits()
            );
            let lo = &values[..side * side];
            prop_assert_eq!(
                patch_mean_slope(lo, side, cell).to_bits(),
                patch_mean_slope_reference(lo, side, cell).to_bits()
            );
        }

        /// The batched features equal each input's own, bit for bit.
        #[test]
        fn batched_features_equal_each_alone(
            side in 2usize..12,
            cell in 0.5f32..500.0,
            values in proptest::collection::vec(-3000.0f32..3000.0, 4 * 144),
            flat in 0usize..5,
        ) {
            let n = side * side;
            let mut patches: Vec<Vec<f32>> = values.chunks(144).map(|c| c[..n].to_vec()).collect();
            if let Some(p) = patches.get_mut(flat) {
                p.fill(17.0);
            }
            let los = [0, 1, 2, 3].map(|m| patches[m].as_slice());
            let batch = patch_mean_slope_n(los, side, cell);
            let mut outs = vec![vec![0.0f32; n]; 4];
            let [o0, o1, o2, o3] = outs.as_mut_slice() else { unreachable!() };
            let stats = centre_normalise_n(los, [o0, o1, o2, o3].map(|o| o.as_mut_slice()));
            for m in 0..4 {
                prop_assert_eq!(batch[m].to_bits(), patch_mean_slope(los[m], side, cell).to_bits());
                let mut alone = vec![0.0f32; n];
                let (a, s) = centre_normalise(los[m], &mut alone);
                prop_assert_eq!((stats[m].0.to_bits(), stats[m].1.to_bits()), (a.to_bits(), s.to_bits()));
                prop_assert_eq!(
                    outs[m].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    alone.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
            }
        }

        // box_down2 against a naive formula written independently (2-D indexing, f64 average).
        #[test]
        fn box_down_matches_naive(half in 1usize..9, seed in any::<u64>()) {
            let side = 2 * half;
            let mut r = crate::dictionary::rng::Rng::new(seed);
            let hi: Vec<f32> = (0..side * side).map(|_| (r.next_f64() * 2000.0 - 500.0) as f32).collect();
            let mut out = vec![0.0; half * half];
            box_down2(&hi, side, &mut out);
            for i in 0..half {
                for j in 0..half {
                    let mut acc = 0.0f64;
                    for di in 0..2 {
                        for dj in 0..2 {
                            acc += f64::from(hi[(2 * i + di) * side + 2 * j + dj]);
                        }
                    }
                    let want = acc / 4.0;
                    prop_assert!((f64::from(out[i * half + j]) - want).abs() <= 1e-4 * (1.0 + want.abs()));
                }
            }
        }

        // centre_normalise against the textbook definition.
        #[test]
        fn centre_normalise_matches_naive(v in proptest::collection::vec(-3000.0f32..3000.0, 1..80)) {
            let mut out = vec![0.0; v.len()];
            let (a, s) = centre_normalise(&v, &mut out);
            let n = v.len() as f64;
            let mean: f64 = v.iter().map(|&x| x as f64).sum::<f64>() / n;
            let norm = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>().sqrt();
            prop_assert!((a as f64 - mean).abs() <= 1e-3);
            prop_assert!((s as f64 - norm).abs() <= 1e-3 * (1.0 + norm));
            if norm > 1e-3 {
                let mut sq = 0.0;
                for (o, &x) in out.iter().zip(&v) {
                    let want = (x as f64 - mean) / norm;
                    prop_assert!((*o as f64 - want).abs() <= 1e-5);
                    sq += (*o as f64).powi(2);
                }
                prop_assert!((sq - 1.0).abs() <= 1e-5);
            }
        }
    }
}
