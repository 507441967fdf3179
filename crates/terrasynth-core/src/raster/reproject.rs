//! Reprojection of a grid in a projected CRS (metres, e.g. UTM) onto WGS84 longitude/latitude:
//! the EPSG:4326 grid covering the projected extent, with square-metre cells about the size of
//! the source's at the extent's middle latitude, each sampled bilinearly from the source at the
//! point its centre projects to. Only valid source cells contribute (their weights
//! renormalised); an output cell with less than half of its bilinear weight on valid cells, or
//! outside the source, is invalid.

use ndarray::Array2;

use super::error::RasterError;
use super::georef::{Crs, Georef, EARTH_RADIUS_M};
use super::grid::Grid;
use super::projection::Projection;
use crate::math;

/// Points sampled along each edge of the source to find the geographic bounding box.
const EDGE_SAMPLES: usize = 64;

/// `grid` reprojected onto EPSG:4326 (a copy when it is not in a projected CRS).
pub fn to_geographic(grid: &Grid) -> Result<Grid, RasterError> {
    let Crs::Projected(code) = grid.georef.crs else {
        return Ok(grid.clone());
    };
    let p = Projection::new(code)?;
    let g = grid.georef;
    let (rows, cols) = grid.data.dim();
    let (w, s, e, n) = g.bounds(cols, rows);
    // The geographic bounding box of the projected rectangle, from points along its edges.
    let (mut lon0, mut lat0, mut lon1, mut lat1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for i in 0..=EDGE_SAMPLES {
        let t = i as f64 / EDGE_SAMPLES as f64;
        let (x, y) = (w + t * (e - w), s + t * (n - s));
        for (px, py) in [(x, s), (x, n), (w, y), (e, y)] {
            let (lon, lat) = p.to_lonlat(px, py).ok_or_else(|| {
                RasterError::BadGeoreference(format!(
                    "EPSG:{code} point ({px}, {py}) has no longitude/latitude"
                ))
            })?;
            lon0 = lon0.min(lon);
            lon1 = lon1.max(lon);
            lat0 = lat0.min(lat);
            lat1 = lat1.max(lat);
        }
    }
    // Cells of about the source's size at the middle latitude.
    let deg = EARTH_RADIUS_M * std::f64::consts::PI / 180.0;
    let mid = (0.5 * (lat0 + lat1)).to_radians();
    let ph = g.pixel_height / deg;
    let pw = g.pixel_width / (deg * math::cos(mid).max(1e-6));
    let out_rows = ((lat1 - lat0) / ph).ceil().max(1.0);
    let out_cols = ((lon1 - lon0) / pw).ceil().max(1.0);
    let limit = (rows.max(cols) as f64) * 4.0;
    if out_rows > limit || out_cols > limit {
        return Err(RasterError::BadGeoreference(format!(
            "EPSG:{code} grid reprojects to {out_cols}×{out_rows} cells"
        )));
    }
    let (out_rows, out_cols) = (out_rows as usize, out_cols as usize);
    let georef = Georef {
        crs: Crs::Epsg4326,
        west: lon0,
        north: lat1,
        pixel_width: pw,
        pixel_height: ph,
    };
    let mut data = Array2::from_elem((out_rows, out_cols), f32::NAN);
    let mut valid = Array2::from_elem((out_rows, out_cols), false);
    for r in 0..out_rows {
        for c in 0..out_cols {
            let (lon, lat) = georef.pixel_centre(c as f64, r as f64);
            let Some((x, y)) = p.from_lonlat(lon, lat) else {
                continue;
            };
            // Fractional source pixel of the point (cell centres at integer + 0.5).
            let fc = (x - g.west) / g.pixel_width - 0.5;
            let fr = (g.north - y) / g.pixel_height - 0.5;
            if let Some(v) = bilinear_valid(grid, fr, fc) {
                data[(r, c)] = v;
                valid[(r, c)] = true;
            }
        }
    }
    let mut out = Grid::new(data, georef);
    out.valid = Some(valid);
    Ok(out)
}

/// Bilinear sample of `grid` at fractional cell-centre coordinates `(fr, fc)` from its valid
/// cells (weights renormalised); `None` outside the grid or when less than half of the weight
/// falls on valid cells.
pub fn bilinear_valid(grid: &Grid, fr: f64, fc: f64) -> Option<f32> {
    let (rows, cols) = grid.data.dim();
    if !(fr >= -0.5 && fc >= -0.5 && fr <= rows as f64 - 0.5 && fc <= cols as f64 - 0.5) {
        return None;
    }
    let (r0, c0) = (fr.floor(), fc.floor());
    let (tr, tc) = (fr - r0, fc - c0);
    let (mut sum, mut weight) = (0.0f64, 0.0f64);
    for (dr, wr) in [(0i64, 1.0 - tr), (1, tr)] {
        for (dc, wc) in [(0i64, 1.0 - tc), (1, tc)] {
            let w = wr * wc;
            // Taps beyond the edge (within half a cell of it) fall back on the edge cell.
            let r = (r0 as i64 + dr).clamp(0, rows as i64 - 1) as usize;
            let c = (c0 as i64 + dc).clamp(0, cols as i64 - 1) as usize;
            let v = grid.data[(r, c)];
            if w > 0.0 && grid.is_valid(r, c) && v.is_finite() {
                sum += w * f64::from(v);
                weight += w;
            }
        }
    }
    (weight >= 0.5).then(|| (sum / weight) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UTM 11N (NAD83) grid of `rows × cols` 2 m cells near the Carrizo Plain whose values are
    /// `f(x, y)` of the cell centre's metres.
    fn utm_grid(rows: usize, cols: usize, f: impl Fn(f64, f64) -> f32) -> Grid {
        let georef = Georef {
            crs: Crs::Projected(26911),
            west: 240_000.0,
            north: 3_907_000.0,
            pixel_width: 2.0,
            pixel_height: 2.0,
        };
        let data = Array2::from_shape_fn((rows, cols), |(r, c)| {
            let (x, y) = georef.pixel_centre(c as f64, r as f64);
            f(x, y)
        });
        Grid::new(data, georef)
    }

    #[test]
    fn a_plane_in_utm_stays_the_same_plane_on_the_globe() {
        // A plane in projected metres is bilinear-exact: every reprojected cell holds the
        // plane's value at the point its centre projects to, computed here independently.
        let plane = |x: f64, y: f64| (0.01 * (x - 240_000.0) - 0.02 * (y - 3_906_000.0)) as f32;
        let g = utm_grid(60, 40, plane);
        let out = to_geographic(&g).unwrap();
        assert_eq!(out.georef.crs, Crs::Epsg4326);
        let p = Projection::new(26911).unwrap();
        let (mut inside, mut checked) = (0, 0);
        for r in 0..out.rows() {
            for c in 0..out.cols() {
                let (lon, lat) = out.georef.pixel_centre(c as f64, r as f64);
                let (x, y) = p.from_lonlat(lon, lat).unwrap();
                let within = x > 240_000.0 + 1.0
                    && x < 240_080.0 - 1.0
                    && y < 3_907_000.0 - 1.0
                    && y > 3_906_880.0 + 1.0;
                if within {
                    inside += 1;
                    assert!(out.is_valid(r, c), "({r}, {c}) lies inside the source");
                    let want = plane(x, y);
                    assert!(
                        (out.data[(r, c)] - want).abs() < 1e-3,
                        "{} vs {want}",
                        out.data[(r, c)]
                    );
                    checked += 1;
                }
            }
        }
        // The rotated rectangle fills most of its bounding box; cells are about 2 m.
        assert!(inside > 60 * 40 * 3 / 4, "{inside}");
        assert!(checked > 0);
        let (dx, dy) = out.georef.cell_size_m(out.rows() as f64 / 2.0);
        assert!(
            (dy - 2.0).abs() < 0.05 && (dx - 2.0).abs() < 0.05,
            "{dx} {dy}"
        );
        // Outside the rotated rectangle: invalid.
        assert!(out.valid_count() < out.rows() * out.cols());
    }

    #[test]
    fn invalid_source_cells_do_not_leak() {
        let mut g = utm_grid(40, 40, |_, _| 100.0);
        let mut valid = Array2::from_elem((40, 40), true);
        for r in 0..40 {
            for c in 20..40 {
                valid[(r, c)] = false;
                g.data[(r, c)] = f32::NAN;
            }
        }
        g.valid = Some(valid);
        let out = to_geographic(&g).unwrap();
        assert!(out.valid_count() > 0);
        for (v, ok) in out.data.iter().zip(out.valid.as_ref().unwrap()) {
            if *ok {
                assert_eq!(*v, 100.0);
            }
        }
    }

    #[test]
    fn geographic_grids_are_returned_unchanged() {
        let g = Grid::new(Array2::from_elem((3, 3), 1.0), Georef::local_metric(10.0));
        assert_eq!(to_geographic(&g).unwrap().data, g.data);
    }
}
