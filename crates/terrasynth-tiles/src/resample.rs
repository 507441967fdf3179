//! Resampling a georeferenced grid (EPSG:4326 or EPSG:3857) onto a window of the Web Mercator
//! global pixel plane of one zoom, by bilinear interpolation at pixel centres.
//!
//! Because the target is north-up in Mercator and the sources are north-up in degrees or Mercator
//! metres, a target pixel's source column depends only on its global column and its source row only
//! on its global row. Both are precomputed once per column and per row, so the per-pixel work is a
//! four-tap weighted sum.

use std::f64::consts::PI;
use std::ops::Range;

use ndarray::Array2;
use rayon::prelude::*;

use terrasynth_core::raster::georef::{Crs, MERCATOR_RADIUS_M};
use terrasynth_core::raster::grid::Grid;
use terrasynth_core::synth::Window;

use super::mercator::{mercator_to_lonlat, pixel_size_m};

/// Where one target column (or row) falls in the source: the two neighbouring source indices
/// (clamped at the source's edge) and the weight of the second, or `None` when the pixel centre
/// lies outside the source's coverage.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Tap {
    i0: usize,
    i1: usize,
    t: f64,
}

/// Maps a source coordinate `u` in cell units (0 at the source's first edge, `n` at its last) to
/// a tap, or `None` when `u` is outside `[0, n)` or not finite.
fn tap(u: f64, n: usize) -> Option<Tap> {
    if !(u.is_finite() && u >= 0.0 && u < n as f64) {
        return None;
    }
    // Cell-centred convention: cell c's centre is at u = c + 0.5.
    let f = u - 0.5;
    let c0 = f.floor();
    let t = f - c0;
    let last = n - 1;
    // c0 ∈ [-1, n-1] because u ∈ [0, n); the casts are of small exact integers.
    let i0 = if c0 < 0.0 { 0 } else { (c0 as usize).min(last) };
    let i1 = if c0 + 1.0 < 0.0 {
        0
    } else {
        ((c0 + 1.0) as usize).min(last)
    };
    Some(Tap { i0, i1, t })
}

/// Source coordinate in cell units along one axis, trying the coordinate shifted by ±`period`
/// (one full turn of longitude) when the plain one is outside `[0, n)`, so that sources given in
/// 0..360° (or beyond ±πR) are sampled too.
fn wrapped_tap(coord: f64, origin: f64, step: f64, n: usize, period: f64) -> Option<Tap> {
    [0.0, period, -period]
        .iter()
        .find_map(|shift| tap((coord + shift - origin) / step, n))
}

/// Samples the global pixel plane of zoom `z` (see [`super::mercator`]) over the window of `cols ×
/// rows` pixels whose top-left pixel is `(col0, row0)`, from `grid` (EPSG:4326 or EPSG:3857) by
/// bilinear interpolation at each pixel centre.
///
/// A pixel centre is mapped to the source's fractional `(col, row)` with the cell-centred
/// convention (source cell `(c, r)` has its centre at `west + (c+0.5)·pixel_width`,
/// `north − (r+0.5)·pixel_height`). Returns the values and a mask, both of shape `(rows, cols)`:
///
/// - a pixel whose centre lies outside the source bounds (`[west, east) × (south, north]`, also
///   tried one turn of longitude east and west) gets `fill` and mask `false`;
/// - near the source's edge, missing neighbours are replaced by the nearest edge cell (clamped);
/// - invalid source cells (masked or NaN) are left out and the remaining neighbours' bilinear
///   weights are renormalised; if the valid neighbours all have zero weight their plain mean is
///   used, and if no neighbour is valid the pixel gets `fill` and mask `false`.
///
/// So the mask is `true` exactly where the value comes from source data. The result is a pure
/// function of the inputs (computed in `f64`, no fused multiply-add).
///
/// Reads the whole grid once for its validity ([`source_validity`]); a caller that samples one
/// grid many times (a world's base, tile by tile) reads it once and calls
/// [`mercator_window_from_valid_grid`].
pub fn mercator_window_from_grid(
    grid: &Grid,
    z: u8,
    col0: i64,
    row0: i64,
    cols: usize,
    rows: usize,
    fill: f32,
) -> (Array2<f32>, Array2<bool>) {
    let valid = source_validity(grid);
    let w = Window::new(col0, row0, cols, rows);
    mercator_window_from_valid_grid(grid, valid.as_ref(), z, w, fill)
}

/// [`mercator_window_from_grid`] with the grid's validity given: `valid` must be
/// [`source_validity`]`(grid)`; `w` is the window of zoom `z`'s pixel plane.
pub fn mercator_window_from_valid_grid(
    grid: &Grid,
    valid: Option<&Array2<bool>>,
    z: u8,
    w: Window,
    fill: f32,
) -> (Array2<f32>, Array2<bool>) {
    let Window { cols, rows, .. } = w;
    let mut values = Array2::from_elem((rows, cols), fill);
    let mut mask = Array2::from_elem((rows, cols), false);
    let (src_rows, src_cols) = grid.data.dim();
    if src_rows == 0 || src_cols == 0 || rows == 0 || cols == 0 {
        return (values, mask);
    }
    let (row_taps, col_taps) = taps(grid, z, w);
    let data = &grid.data;

    let (Some(value_rows), Some(mask_rows)) = (values.as_slice_mut(), mask.as_slice_mut()) else {
        return (values, mask);
    };
    // Rows in parallel: each output row reads its own taps and writes only itself.
    let out_rows = value_rows
        .par_chunks_mut(cols)
        .zip(mask_rows.par_chunks_mut(cols));
    out_rows
        .zip(&row_taps)
        .for_each(|((value_row, mask_row), row_tap)| {
            let Some(ry) = row_tap else { return };
            for (i, col_tap) in col_taps.iter().enumerate() {
                let Some(cx) = col_tap else { continue };
                let taps = [
                    (ry.i0, cx.i0, (1.0 - ry.t) * (1.0 - cx.t)),
                    (ry.i0, cx.i1, (1.0 - ry.t) * cx.t),
                    (ry.i1, cx.i0, ry.t * (1.0 - cx.t)),
                    (ry.i1, cx.i1, ry.t * cx.t),
                ];
                let value = match valid {
                    None => Some(
                        taps.iter()
                            .map(|&(r, c, w)| w * f64::from(data[[r, c]]))
                            .sum::<f64>(),
                    ),
                    Some(valid) => {
                        let mut sum = 0.0f64;
                        let mut weight = 0.0f64;
                        let mut plain_sum = 0.0f64;
                        let mut count = 0u32;
                        for &(r, c, w) in &taps {
                            if valid[[r, c]] {
                                let v = f64::from(data[[r, c]]);
                                sum += w * v;
                                weight += w;
                                plain_sum += v;
                                count += 1;
                            }
                        }
                        if count == 0 {
                            None
                        } else if weight > 0.0 {
                            Some(sum / weight)
                        } else {
                            Some(plain_sum / f64::from(count))
                        }
                    }
                };
                if let Some(v) = value {
                    value_row[i] = v as f32;
                    mask_row[i] = true;
                }
            }
        });
    (values, mask)
}

/// The source taps of the rows and of the columns of a window (see
/// [`mercator_window_from_grid`]): `(row_taps, col_taps)`, `None` outside the source.
fn taps(grid: &Grid, z: u8, w: Window) -> (Vec<Option<Tap>>, Vec<Option<Tap>>) {
    let Window {
        col0,
        row0,
        cols,
        rows,
    } = w;
    let (src_rows, src_cols) = grid.data.dim();
    let g = &grid.georef;
    let m = pixel_size_m(z);
    let half_world = PI * MERCATOR_RADIUS_M;

    // Mercator metres of the centre of global column px / row py.
    let centre_x = |px: i64| -half_world + (px as f64 + 0.5) * m;
    let centre_y = |py: i64| half_world - (py as f64 + 0.5) * m;

    let col_taps: Vec<Option<Tap>> = (0..cols)
        .map(|i| {
            let x = centre_x(col0.saturating_add(i as i64));
            match g.crs {
                Crs::Epsg4326 => {
                    let lon = mercator_to_lonlat(x, 0.0).0;
                    wrapped_tap(lon, g.west, g.pixel_width, src_cols, 360.0)
                }
                Crs::Epsg3857 => wrapped_tap(x, g.west, g.pixel_width, src_cols, 2.0 * half_world),
                // Projected grids are reprojected onto EPSG:4326 before they are resampled
                // (`World::new`); never sampled here.
                Crs::Projected(_) => None,
            }
        })
        .collect();
    let row_taps: Vec<Option<Tap>> = (0..rows)
        .map(|j| {
            let y = centre_y(row0.saturating_add(j as i64));
            let src_y = match g.crs {
                Crs::Epsg4326 => mercator_to_lonlat(0.0, y).1,
                Crs::Epsg3857 => y,
                Crs::Projected(_) => f64::NAN,
            };
            // Rows run southwards; `(north − y) / ph ∈ [0, rows)` is the half-open (south, north].
            tap((g.north - src_y) / g.pixel_height, src_rows)
        })
        .collect();

    (row_taps, col_taps)
}

/// For each box of `grid`'s cells (a range of rows, a range of columns), the smallest
/// sub-window of window `w` of zoom `z`'s plane that holds every pixel whose value
/// [`mercator_window_from_valid_grid`] takes from a cell of the box (any of its four taps,
/// whatever its weight), or `None` when no pixel of `w` reads one. Reads the grid's georeference
/// only: the taps of `w`'s rows and columns, computed once for all the boxes.
pub fn mercator_footprints(
    grid: &Grid,
    z: u8,
    w: Window,
    boxes: &[(Range<usize>, Range<usize>)],
) -> Vec<Option<Window>> {
    let (row_taps, col_taps) = taps(grid, z, w);
    // First and last index of `taps` that reads a cell of `range`.
    let span = |taps: &[Option<Tap>], range: &Range<usize>| -> Option<(usize, usize)> {
        let mut reads = taps.iter().enumerate().filter_map(|(i, t)| {
            t.filter(|t| range.contains(&t.i0) || range.contains(&t.i1))
                .map(|_| i)
        });
        let first = reads.next()?;
        Some((first, reads.next_back().unwrap_or(first)))
    };
    boxes
        .iter()
        .map(|(rows, cols)| {
            let (r0, r1) = span(&row_taps, rows)?;
            let (c0, c1) = span(&col_taps, cols)?;
            Some(Window::new(
                w.col0 + c0 as i64,
                w.row0 + r0 as i64,
                c1 - c0 + 1,
                r1 - r0 + 1,
            ))
        })
        .collect()
}

/// Validity of every cell of `grid` (masked or NaN cells are invalid), or `None` when every
/// cell is valid. Worth computing once per grid: it reads the whole grid.
pub fn source_validity(grid: &Grid) -> Option<Array2<bool>> {
    let (src_rows, src_cols) = grid.data.dim();
    if grid.valid.is_some() || grid.data.iter().any(|v| !v.is_finite()) {
        Some(Array2::from_shape_fn((src_rows, src_cols), |(r, c)| {
            grid.is_valid(r, c)
        }))
    } else {
        None
    }
}

/// The mask alone of [`mercator_window_from_grid`] over the same window, given the grid's
/// [`source_validity`] (computed once by the caller): `true` where the pixel centre lies inside
/// the source and at least one of its four bilinear neighbours is valid.
pub fn mercator_mask_from_grid(
    grid: &Grid,
    valid: Option<&Array2<bool>>,
    z: u8,
    w: Window,
) -> Array2<bool> {
    let Window { cols, rows, .. } = w;
    let mut mask = Array2::from_elem((rows, cols), false);
    let (src_rows, src_cols) = grid.data.dim();
    if src_rows == 0 || src_cols == 0 || rows == 0 || cols == 0 {
        return mask;
    }
    let (row_taps, col_taps) = taps(grid, z, w);
    let Some(mask_rows) = mask.as_slice_mut() else {
        return mask;
    };
    // Rows in parallel, as in `mercator_window_from_grid`.
    mask_rows
        .par_chunks_mut(cols)
        .zip(&row_taps)
        .for_each(|(mask_row, row_tap)| {
            let Some(ry) = row_tap else { return };
            for (i, col_tap) in col_taps.iter().enumerate() {
                let Some(cx) = col_tap else { continue };
                mask_row[i] = match valid {
                    None => true,
                    Some(v) => {
                        v[[ry.i0, cx.i0]]
                            || v[[ry.i0, cx.i1]]
                            || v[[ry.i1, cx.i0]]
                            || v[[ry.i1, cx.i1]]
                    }
                };
            }
        });
    mask
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasynth_core::math;
    use terrasynth_core::raster::georef::Georef;

    /// Pixel-centre longitude/latitude of global pixel (px, py) at zoom z, from the slippy-map
    /// inverse formulas (independent of the module).
    fn centre_lonlat(z: u8, px: i64, py: i64) -> (f64, f64) {
        let n = 256.0 * (1u64 << z) as f64;
        let lon = (px as f64 + 0.5) / n * 360.0 - 180.0;
        let lat = math::atan(math::sinh(PI * (1.0 - 2.0 * (py as f64 + 0.5) / n))).to_degrees();
        (lon, lat)
    }

    /// A 15″-ish EPSG:4326 grid over 70–75°E, 40–44°N holding `a + b·lon + c·lat` at cell centres.
    fn linear_grid() -> (Grid, impl Fn(f64, f64) -> f64) {
        let (west, north, step) = (70.0, 44.0, 0.05);
        let (cols, rows) = (100, 80);
        let f = |lon: f64, lat: f64| 1000.0 + 30.0 * (lon - 70.0) - 50.0 * (lat - 40.0);
        let data = Array2::from_shape_fn((rows, cols), |(r, c)| {
            let lon = west + (c as f64 + 0.5) * step;
            let lat = north - (r as f64 + 0.5) * step;
            f(lon, lat) as f32
        });
        let georef = Georef {
            crs: Crs::Epsg4326,
            west,
            north,
            pixel_width: step,
            pixel_height: step,
        };
        (Grid::new(data, georef), f)
    }

    #[test]
    fn linear_function_is_reproduced_inside_and_filled_outside() {
        let (grid, f) = linear_grid();
        let z = 7u8;
        // A window straddling the grid's south-west corner (70°E, 40°N).
        let (px, py) = super::super::mercator::lonlat_to_global_pixel(z, 70.0, 40.0);
        let (col0, row0) = (px.floor() as i64 - 40, py.floor() as i64 - 60);
        let (cols, rows) = (120usize, 100usize);
        let fill = -9999.0f32;
        let (v, mask) = mercator_window_from_grid(&grid, z, col0, row0, cols, rows, fill);
        let (mut inside, mut outside) = (0, 0);
        for j in 0..rows {
            for i in 0..cols {
                let (lon, lat) = centre_lonlat(z, col0 + i as i64, row0 + j as i64);
                let covered = (70.0..75.0).contains(&lon) && lat > 40.0 && lat <= 44.0;
                assert_eq!(mask[[j, i]], covered, "mask at {lon} {lat}");
                if covered {
                    inside += 1;
                    // Bilinear reproduces a linear function exactly between cell centres; in the
                    // outer half cell the clamped neighbours flatten it, so test away from edges.
                    let margin = 0.05;
                    if lon > 70.0 + margin
                        && lon < 75.0 - margin
                        && lat > 40.0 + margin
                        && lat < 44.0 - margin
                    {
                        let expected = f(lon, lat);
                        let got = f64::from(v[[j, i]]);
                        assert!(
                            (got - expected).abs() <= 1e-3 * expected.abs(),
                            "at {lon} {lat}: {got} vs {expected}"
                        );
                    }
                } else {
                    outside += 1;
                    assert_eq!(v[[j, i]], fill);
                }
            }
        }
        assert!(inside > 1000 && outside > 1000, "{inside} {outside}");
    }

    #[test]
    fn mercator_source_at_the_same_zoom_is_copied_exactly() {
        // A 3857 grid aligned with the z=2 pixel plane: sampling it at z=2 hits cell centres.
        let z = 2u8;
        let m = pixel_size_m(z);
        let half = PI * MERCATOR_RADIUS_M;
        let data = Array2::from_shape_fn((16, 16), |(r, c)| (r * 100 + c) as f32);
        let georef = Georef {
            crs: Crs::Epsg3857,
            west: -half + 300.0 * m,
            north: half - 200.0 * m,
            pixel_width: m,
            pixel_height: m,
        };
        let grid = Grid::new(data.clone(), georef);
        let (v, mask) = mercator_window_from_grid(&grid, z, 300, 200, 16, 16, f32::NAN);
        assert!(mask.iter().all(|&b| b));
        for ((r, c), &x) in data.indexed_iter() {
            assert!(
                (v[[r, c]] - x).abs() < 1e-3,
                "{r} {c}: {} vs {x}",
                v[[r, c]]
            );
        }
        // Shifted by one pixel: the first column is outside.
        let (v, mask) = mercator_window_from_grid(&grid, z, 299, 200, 4, 1, -1.0);
        assert!(!mask[[0, 0]] && mask[[0, 1]]);
        assert_eq!(v[[0, 0]], -1.0);
        assert!((v[[0, 1]] - 0.0).abs() < 1e-3 && (v[[0, 2]] - 1.0).abs() < 1e-3);
    }

    #[test]
    fn invalid_cells_use_renormalised_weights_or_fill() {
        let z = 2u8;
        let m = pixel_size_m(z);
        let half = PI * MERCATOR_RADIUS_M;
        // Source cells are two target pixels wide, so target centres fall a quarter cell off the
        // source centres.
        let mut data = Array2::from_elem((4, 4), 10.0f32);
        data[[1, 1]] = 1000.0;
        data[[0, 0]] = f32::NAN;
        data[[0, 2]] = f32::NAN;
        let mut valid = Array2::from_elem((4, 4), true);
        valid[[1, 1]] = false;
        let georef = Georef {
            crs: Crs::Epsg3857,
            west: -half,
            north: half,
            pixel_width: 2.0 * m,
            pixel_height: 2.0 * m,
        };
        let grid = Grid {
            data,
            georef,
            valid: Some(valid),
        };
        let (v, mask) = mercator_window_from_grid(&grid, z, 0, 0, 8, 8, -5.0);
        // Pixel (0, 0) sits in the corner quarter of source cell (0, 0), where all four clamped
        // neighbours are that NaN cell: fill. Every other pixel has a valid neighbour, and the
        // masked 1000 and the NaNs never leak in.
        assert!(!mask[[0, 0]]);
        assert_eq!(v[[0, 0]], -5.0);
        for ((r, c), &x) in v.indexed_iter() {
            if (r, c) != (0, 0) {
                assert!(mask[[r, c]], "{r} {c}");
                assert!((x - 10.0).abs() < 1e-4, "{r} {c}: {x}");
            }
        }

        // A source with no valid cell at all gives fill everywhere.
        let empty = Grid {
            data: Array2::from_elem((4, 4), f32::NAN),
            georef,
            valid: None,
        };
        let (v, mask) = mercator_window_from_grid(&empty, z, 0, 0, 8, 8, -5.0);
        assert!(mask.iter().all(|&b| !b));
        assert!(v.iter().all(|&x| x == -5.0));
    }

    #[test]
    fn mask_alone_matches_the_resampler_mask_around_holes_and_edges() {
        // A grid with a NaN block and a masked cell, sampled at several zooms over windows that
        // reach outside it: the mask-only lookup gives the resampler's own mask pixel by pixel.
        let (mut grid, _) = linear_grid();
        for r in 30..40 {
            for c in 40..47 {
                grid.data[[r, c]] = f32::NAN;
            }
        }
        let mut valid = Array2::from_elem(grid.data.dim(), true);
        valid[[5, 5]] = false;
        grid.valid = Some(valid);
        let v = source_validity(&grid);
        assert!(v.is_some());
        for z in [7u8, 9, 11] {
            let (x0, y0) = crate::mercator::lonlat_to_global_pixel(z, 69.9, 44.1);
            let (x1, y1) = crate::mercator::lonlat_to_global_pixel(z, 75.1, 39.9);
            let (c0, r0) = (x0.floor() as i64, y0.floor() as i64);
            let (cols, rows) = ((x1 - x0) as usize + 2, (y1 - y0) as usize + 2);
            let (_, want) = mercator_window_from_grid(&grid, z, c0, r0, cols, rows, 0.0);
            let window = Window::new(c0, r0, cols, rows);
            let got = mercator_mask_from_grid(&grid, v.as_ref(), z, window);
            assert_eq!(got, want, "zoom {z}");
            assert!(
                want.iter().any(|&b| b) && want.iter().any(|&b| !b),
                "zoom {z}"
            );
        }
        // A grid with every cell valid needs no validity grid.
        assert!(source_validity(&linear_grid().0).is_none());
    }

    #[test]
    fn sources_in_0_to_360_degrees_are_found() {
        // A grid covering 180–200°E (i.e. 180°W–160°W).
        let georef = Georef {
            crs: Crs::Epsg4326,
            west: 180.0,
            north: 10.0,
            pixel_width: 1.0,
            pixel_height: 1.0,
        };
        let grid = Grid::new(Array2::from_elem((20, 20), 7.0f32), georef);
        // Global pixel column 10 at z=0 is at about −165.2°E; row 125 at about 3°N.
        let (v, mask) = mercator_window_from_grid(&grid, 0, 10, 125, 1, 1, 0.0);
        assert!(mask[[0, 0]]);
        assert_eq!(v[[0, 0]], 7.0);
    }

    #[test]
    fn resampling_is_deterministic_and_handles_empty_windows() {
        let (grid, _) = linear_grid();
        let a = mercator_window_from_grid(&grid, 9, 45_000, 24_000, 64, 48, 0.0);
        let b = mercator_window_from_grid(&grid, 9, 45_000, 24_000, 64, 48, 0.0);
        assert_eq!(a, b);
        let (v, mask) = mercator_window_from_grid(&grid, 9, 0, 0, 0, 5, 0.0);
        assert_eq!(v.dim(), (5, 0));
        assert_eq!(mask.dim(), (5, 0));
        // Extreme window origins neither panic nor cover anything.
        let (_, mask) = mercator_window_from_grid(&grid, 30, i64::MAX - 2, i64::MIN, 2, 2, 0.0);
        assert!(mask.iter().all(|&b| !b));
    }

    #[test]
    fn a_large_window_is_covered_where_the_grid_lies() {
        let (grid, _) = linear_grid();
        let z = 12u8;
        let (px, py) = super::super::mercator::lonlat_to_global_pixel(z, 71.0, 43.5);
        let (v, mask) = mercator_window_from_grid(&grid, z, px as i64, py as i64, 2048, 2048, 0.0);
        assert_eq!(v.dim(), (2048, 2048));
        assert!(mask.iter().filter(|&&b| b).count() > 2048 * 1024);
    }

    proptest::proptest! {
        /// A box's footprint is the bounding window of the pixels whose mask a grid valid on
        /// that box alone sets (every pixel that reads one of its cells), and `None` when there
        /// is none.
        #[test]
        fn a_footprint_bounds_every_pixel_that_reads_the_box(
            r0 in 0usize..80, c0 in 0usize..100, rows in 1usize..12, cols in 1usize..12,
            z in 5u8..9, dx in -40i64..40, dy in -40i64..40,
        ) {
            let (grid, _) = linear_grid();
            let (r1, c1) = ((r0 + rows).min(80), (c0 + cols).min(100));
            let (px, py) = super::super::mercator::lonlat_to_global_pixel(z, 70.0, 44.0);
            let w = Window::new(px as i64 + dx, py as i64 + dy, 200, 160);
            let valid = Array2::from_shape_fn((80, 100), |(r, c)| {
                (r0..r1).contains(&r) && (c0..c1).contains(&c)
            });
            let mask = mercator_mask_from_grid(&grid, Some(&valid), z, w);
            let mut bounds: Option<(usize, usize, usize, usize)> = None;
            for ((r, c), &m) in mask.indexed_iter() {
                if m {
                    let b = bounds.get_or_insert((r, r, c, c));
                    *b = (b.0.min(r), b.1.max(r), b.2.min(c), b.3.max(c));
                }
            }
            let expected = bounds.map(|(ra, rb, ca, cb)| {
                Window::new(w.col0 + ca as i64, w.row0 + ra as i64, cb - ca + 1, rb - ra + 1)
            });
            let got = mercator_footprints(&grid, z, w, &[(r0..r1, c0..c1)]);
            proptest::prop_assert_eq!(got, vec![expected]);
        }
    }
}
