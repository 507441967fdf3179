//! Local terrain derivatives on a 3×3 window: Horn's gradient, slope, aspect, northness and
//! curvature (−Laplacian). Edge cells use replicated borders (the missing neighbour takes the
//! value of the nearest cell inside the grid). NaN inputs propagate to every cell whose window
//! contains them.

use ndarray::Array2;
use rayon::prelude::*;

use super::common::{row_sizes, values};
use super::hillshade::Light;
use crate::math;
use crate::raster::CellSizes;

/// Horn (1981) gradient `(dz/dx eastwards, dz/dy northwards)` in m/m.
///
/// With the window `a b c / d e f / g h i` (row 0 north), the east derivative is the 1-2-1
/// weighted mean of the three central differences `(c − a)/(2·dx[r−1])`, `(f − d)/(2·dx[r])`,
/// `(i − g)/(2·dx[r+1])` (each row uses its own metric width, which reduces to Horn's
/// `((c+2f+i) − (a+2d+g)) / 8dx` for uniform cells), and the north derivative is
/// `((a+2b+c) − (g+2h+i)) / (2·(dy[r−1] + 2dy[r] + dy[r+1]))`, the difference divided by the
/// weighted centre-to-centre distance (again Horn's `/8dy` for uniform cells). Row indices are
/// clamped at the edges, like the values.
pub fn gradient(z: &Array2<f32>, cs: &CellSizes) -> (Array2<f32>, Array2<f32>) {
    let (rows, cols) = z.dim();
    let mut gx = Array2::<f32>::zeros((rows, cols));
    let mut gy = Array2::<f32>::zeros((rows, cols));
    if rows == 0 || cols == 0 {
        return (gx, gy);
    }
    let v = values(z);
    let (dx, dy) = row_sizes(cs, rows);
    let (Some(gxs), Some(gys)) = (gx.as_slice_mut(), gy.as_slice_mut()) else {
        return (gx, gy);
    };
    // Rows in parallel: each output row reads three input rows and writes only itself.
    let rows_out = gxs.par_chunks_mut(cols).zip(gys.par_chunks_mut(cols));
    rows_out.enumerate().for_each(|(r, (gx_row, gy_row))| {
        let rn = r.saturating_sub(1);
        let rs = (r + 1).min(rows - 1);
        let (north, mid, south) = (
            &v[rn * cols..(rn + 1) * cols],
            &v[r * cols..(r + 1) * cols],
            &v[rs * cols..(rs + 1) * cols],
        );
        let ydist = 2.0 * (dy[rn] + 2.0 * dy[r] + dy[rs]);
        for c in 0..cols {
            let cw = c.saturating_sub(1);
            let ce = (c + 1).min(cols - 1);
            let (a, b, cc) = (north[cw] as f64, north[c] as f64, north[ce] as f64);
            let (d, f) = (mid[cw] as f64, mid[ce] as f64);
            let (g, h, i) = (south[cw] as f64, south[c] as f64, south[ce] as f64);
            let ex = ((cc - a) / (2.0 * dx[rn])
                + 2.0 * ((f - d) / (2.0 * dx[r]))
                + (i - g) / (2.0 * dx[rs]))
                / 4.0;
            let ny = ((a + 2.0 * b + cc) - (g + 2.0 * h + i)) / ydist;
            gx_row[c] = ex as f32;
            gy_row[c] = ny as f32;
        }
    });
    (gx, gy)
}

/// The steepness `√(gx² + gy²)` of a cell of gradient `(x, y)`, in f64.
#[inline]
fn steepness(x: f32, y: f32) -> f64 {
    math::hypot(x as f64, y as f64)
}

/// Degrees of a slope whose tangent, rounded to `f32` as [`slope`] stores it, is `tangent`.
#[inline]
fn degrees_of_tangent(tangent: f32) -> f32 {
    math::atan(tangent as f64).to_degrees() as f32
}

/// Northness of a cell of north gradient `y` and steepness `s` ([`steepness`]).
#[inline]
fn northness_of(y: f32, s: f64) -> f32 {
    if s == 0.0 {
        0.0
    } else {
        (-(y as f64) / s).clamp(-1.0, 1.0) as f32
    }
}

/// Slope as the tangent of the steepest angle (m/m): `sqrt(gx² + gy²)` of [`gradient`].
pub fn slope(z: &Array2<f32>, cs: &CellSizes) -> Array2<f32> {
    let (gx, gy) = gradient(z, cs);
    ndarray::Zip::from(&gx)
        .and(&gy)
        .par_map_collect(|&x, &y| steepness(x, y) as f32)
}

/// Slope in degrees, `atan(`[`slope`]`)`, in [0, 90).
pub fn slope_degrees(z: &Array2<f32>, cs: &CellSizes) -> Array2<f32> {
    let mut s = slope(z, cs);
    s.par_mapv_inplace(degrees_of_tangent);
    s
}

/// Slope in degrees, northness and hillshade (for a light at `azimuth_deg`, `altitude_deg`) from
/// one [`gradient`], each bit for bit what [`slope_degrees`], [`northness`] and
/// [`hillshade`](super::hillshade::hillshade) give: the terrain of a landscape tile needs all
/// three, and this computes the gradient and each cell's steepness once instead of three and
/// two times.
pub fn slope_northness_shade(
    z: &Array2<f32>,
    cs: &CellSizes,
    azimuth_deg: f32,
    altitude_deg: f32,
) -> [Array2<f32>; 3] {
    let (gx, gy) = gradient(z, cs);
    let light = Light::new(azimuth_deg, altitude_deg);
    let mut slope = Array2::<f32>::zeros(z.dim());
    let mut north = Array2::<f32>::zeros(z.dim());
    let mut shade = Array2::<f32>::zeros(z.dim());
    ndarray::Zip::from(&mut slope)
        .and(&mut north)
        .and(&mut shade)
        .and(&gx)
        .and(&gy)
        .par_for_each(|sl, no, sh, &x, &y| {
            let s = steepness(x, y);
            *sl = degrees_of_tangent(s as f32);
            *no = northness_of(y, s);
            *sh = light.shade(x, y);
        });
    [slope, north, shade]
}

/// Aspect: the compass direction (degrees clockwise from north) of the downslope direction the
/// cell faces, in [0, 360). Exactly flat cells (zero gradient) get 0; NaN propagates.
pub fn aspect(z: &Array2<f32>, cs: &CellSizes) -> Array2<f32> {
    let (gx, gy) = gradient(z, cs);
    ndarray::Zip::from(&gx).and(&gy).map_collect(|&x, &y| {
        if x == 0.0 && y == 0.0 {
            return 0.0;
        }
        // Downslope vector is (-gx east, -gy north); compass bearing = atan2(east, north).
        let mut a = math::atan2(-(x as f64), -(y as f64)).to_degrees();
        if a < 0.0 {
            a += 360.0;
        }
        let a = a as f32 + 0.0; // + 0.0 turns -0.0 into 0.0
        if a >= 360.0 {
            0.0
        } else {
            a
        }
    })
}

/// Northness `cos(aspect)` in [−1, 1]: 1 on slopes facing (descending towards) north, −1 facing
/// south, 0 on flat cells.
pub fn northness(z: &Array2<f32>, cs: &CellSizes) -> Array2<f32> {
    let (gx, gy) = gradient(z, cs);
    ndarray::Zip::from(&gx)
        .and(&gy)
        .par_map_collect(|&x, &y| northness_of(y, steepness(x, y)))
}

/// Curvature as the negative Laplacian in 1/m: positive on convex ridges and peaks, negative in
/// valleys. Second differences `(z_w − 2z + z_e)/dx[r]²` and `(z_n − 2z + z_s)/dy[r]²` with
/// replicated borders (so an edge cell sees a zero one-sided half of the stencil).
pub fn curvature(z: &Array2<f32>, cs: &CellSizes) -> Array2<f32> {
    let (rows, cols) = z.dim();
    let mut out = Array2::<f32>::zeros((rows, cols));
    if rows == 0 || cols == 0 {
        return out;
    }
    let v = values(z);
    let (dx, dy) = row_sizes(cs, rows);
    let Some(os) = out.as_slice_mut() else {
        return out;
    };
    for r in 0..rows {
        let rn = r.saturating_sub(1);
        let rs = (r + 1).min(rows - 1);
        for c in 0..cols {
            let cw = c.saturating_sub(1);
            let ce = (c + 1).min(cols - 1);
            let e = v[r * cols + c] as f64;
            let zxx =
                (v[r * cols + cw] as f64 - 2.0 * e + v[r * cols + ce] as f64) / (dx[r] * dx[r]);
            let zyy =
                (v[rn * cols + c] as f64 - 2.0 * e + v[rs * cols + c] as f64) / (dy[r] * dy[r]);
            os[r * cols + c] = (-(zxx + zyy)) as f32;
        }
    }
    out
}
