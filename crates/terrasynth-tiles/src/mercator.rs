//! Web Mercator (EPSG:3857) XYZ tile math with 256-pixel tiles.
//!
//! The *global pixel plane of zoom `z`* has `256·2^z` pixels per side. Pixel `(px, py)` (integers,
//! `py` counted from the north) covers Mercator metres
//! `x ∈ [−πR + px·m, −πR + (px+1)·m]` and `y ∈ [πR − (py+1)·m, πR − py·m]` with
//! `m = 2πR / (256·2^z)` ([`pixel_size_m`]) and `R` = [`MERCATOR_RADIUS_M`]. Tile `(z, x, y)` is the
//! block of pixels `[256x, 256x + 256) × [256y, 256y + 256)`.
//!
//! Latitudes are clamped to ±[`MAX_LATITUDE`] (the latitude where the square world ends) before
//! they are projected, so every function returns finite values for any finite input.

use std::f64::consts::PI;

use terrasynth_core::math;
use terrasynth_core::raster::georef::MERCATOR_RADIUS_M;
use terrasynth_core::raster::CellSizes;

use super::error::TileError;

/// Tile size in pixels (both width and height).
pub const TILE_SIZE: u32 = 256;

/// The deepest zoom the tile math supports: `256·2^30` pixels per side still fits comfortably in
/// `i64` pixel indices and is represented exactly in `f64`.
pub const MAX_SUPPORTED_ZOOM: u8 = 30;

/// The latitude (degrees) of the north edge of the Web Mercator square world,
/// `atan(sinh(π))` ≈ 85.0511°.
pub const MAX_LATITUDE: f64 = 85.051_128_779_806_59;

/// Half the side of the Mercator square world in metres, `πR`.
fn half_world_m() -> f64 {
    PI * MERCATOR_RADIUS_M
}

/// Number of tiles per side at zoom `z` as `f64` (`2^z`).
fn tiles_per_side(z: u8) -> f64 {
    // powi is exact for powers of two.
    2f64.powi(i32::from(z))
}

/// Web Mercator metres `(x, y)` of a longitude/latitude in degrees. The latitude is clamped to
/// ±[`MAX_LATITUDE`]; the longitude is not wrapped.
pub fn lonlat_to_mercator(lon_deg: f64, lat_deg: f64) -> (f64, f64) {
    let lat = lat_deg.clamp(-MAX_LATITUDE, MAX_LATITUDE).to_radians();
    let x = MERCATOR_RADIUS_M * lon_deg.to_radians();
    let y = MERCATOR_RADIUS_M * math::log(math::tan(PI / 4.0 + lat / 2.0));
    (x, y)
}

/// Longitude/latitude in degrees of Web Mercator metres `(x, y)` (the inverse of
/// [`lonlat_to_mercator`] inside ±[`MAX_LATITUDE`]).
pub fn mercator_to_lonlat(x: f64, y: f64) -> (f64, f64) {
    let lon = (x / MERCATOR_RADIUS_M).to_degrees();
    let lat = (2.0 * math::atan(math::exp(y / MERCATOR_RADIUS_M)) - PI / 2.0).to_degrees();
    (lon, lat)
}

/// Side of a pixel of zoom `z` in Mercator metres, `2πR / (256·2^z)` (true metres only at the
/// equator).
pub fn pixel_size_m(z: u8) -> f64 {
    2.0 * half_world_m() / (f64::from(TILE_SIZE) * tiles_per_side(z))
}

/// Per-row metric cell sizes of the rows `[row0, row0 + rows)` of zoom `z`'s pixel plane: the
/// true Mercator scale at each row's latitude, for slopes, hillshades and cell areas.
pub fn plane_cell_sizes(z: u8, row0: i64, rows: usize) -> CellSizes {
    let world = f64::from(TILE_SIZE) * f64::from(1u32 << z.min(30));
    let m = pixel_size_m(z);
    let (dx, dy): (Vec<f64>, Vec<f64>) = (0..rows)
        .map(|r| {
            let py = (row0 + r as i64) as f64 + 0.5;
            let yn = PI * (1.0 - 2.0 * py / world);
            let c = m * math::cos(math::atan(math::sinh(yn)));
            (c, c)
        })
        .unzip();
    CellSizes { dx, dy }
}

/// True ground size in metres of a pixel of zoom `z` at latitude `lat_deg`,
/// `pixel_size_m(z) · cos(lat)`.
pub fn ground_cell_m(z: u8, lat_deg: f64) -> f64 {
    pixel_size_m(z) * math::cos(lat_deg.to_radians())
}

/// Latitude in degrees of the north edge of tile row `y` (may be fractional) at zoom `z`.
fn tile_row_latitude(z: u8, y: f64) -> f64 {
    let n = tiles_per_side(z);
    let merc_y = half_world_m() * (1.0 - 2.0 * y / n);
    mercator_to_lonlat(0.0, merc_y).1
}

/// Bounds `(west, south, east, north)` in degrees of tile `(z, x, y)`. The tile is not validated;
/// call [`validate_tile`] first for request input.
pub fn tile_bounds_lonlat(z: u8, x: u32, y: u32) -> (f64, f64, f64, f64) {
    let n = tiles_per_side(z);
    let (x, y) = (f64::from(x), f64::from(y));
    let west = x / n * 360.0 - 180.0;
    let east = (x + 1.0) / n * 360.0 - 180.0;
    let north = tile_row_latitude(z, y);
    let south = tile_row_latitude(z, y + 1.0);
    (west, south, east, north)
}

/// Continuous position of a longitude/latitude on the global pixel plane of zoom `z`: pixel edges
/// lie on integers, so pixel `(px, py)` contains the points `[px, px+1) × [py, py+1)` and its centre
/// is `(px + 0.5, py + 0.5)`. The latitude is clamped to ±[`MAX_LATITUDE`].
pub fn lonlat_to_global_pixel(z: u8, lon_deg: f64, lat_deg: f64) -> (f64, f64) {
    let (x, y) = lonlat_to_mercator(lon_deg, lat_deg);
    let m = pixel_size_m(z);
    let hw = half_world_m();
    ((x + hw) / m, (hw - y) / m)
}

/// Inclusive tile ranges `(x0, y0, x1, y1)` at zoom `z` of the tiles that overlap the bounds
/// `(west, south, east, north)` in degrees, clamped to the valid `[0, 2^z)`. A tile that only
/// touches the bounds along an edge is not included (unless the bounds are degenerate, in which
/// case the tile containing them is returned). Bounds given in the wrong order are sorted;
/// bounds crossing the antimeridian are not supported (pass `west ≤ east` within ±180°, or the
/// range is clamped to the world). Non-finite bounds give tile 0 on that side.
pub fn tile_range_for_bounds(z: u8, bounds: (f64, f64, f64, f64)) -> (u32, u32, u32, u32) {
    let (w, s, e, n) = bounds;
    let (w, e) = (w.min(e), w.max(e));
    let (s, n) = (s.min(n), s.max(n));
    let tiles = tiles_per_side(z);
    let max_index = tiles - 1.0;
    let tile = f64::from(TILE_SIZE);
    // Continuous tile coordinates: x grows east, y grows south.
    let (fx0, fy0) = lonlat_to_global_pixel(z, w, n);
    let (fx1, fy1) = lonlat_to_global_pixel(z, e, s);
    let (fx0, fy0, fx1, fy1) = (fx0 / tile, fy0 / tile, fx1 / tile, fy1 / tile);
    let first = |v: f64| v.floor().clamp(0.0, max_index);
    // The last tile overlapped is the one containing the far edge, unless the edge lies exactly on
    // a tile boundary, in which case it is the previous one.
    let last = |lo: f64, hi: f64| {
        let l = first(lo);
        let h = (hi.ceil() - 1.0).clamp(0.0, max_index);
        if h.is_nan() || h < l {
            l
        } else {
            h
        }
    };
    let to_u32 = |v: f64| if v.is_finite() { v as u32 } else { 0 };
    let x0 = first(fx0);
    let y0 = first(fy0);
    let x1 = last(fx0, fx1);
    let y1 = last(fy0, fy1);
    (to_u32(x0), to_u32(y0), to_u32(x1), to_u32(y1))
}

/// The zoom (0..=[`MAX_SUPPORTED_ZOOM`]) whose pixel ground size at latitude `lat_deg` is closest
/// in log scale to `cell_m_ground` metres, i.e. `round(log2(pixel_size_m(0)·cos(lat) / cell))`.
/// Returns 0 for a non-positive or non-finite cell size.
pub fn native_zoom(cell_m_ground: f64, lat_deg: f64) -> u8 {
    let ground0 = ground_cell_m(0, lat_deg.clamp(-MAX_LATITUDE, MAX_LATITUDE));
    if !(cell_m_ground.is_finite() && cell_m_ground > 0.0 && ground0 > 0.0) {
        return 0;
    }
    let z = math::log2(ground0 / cell_m_ground).round();
    if z.is_nan() {
        return 0;
    }
    z.clamp(0.0, f64::from(MAX_SUPPORTED_ZOOM)) as u8
}

/// Checks that tile `(z, x, y)` exists and is served: [`TileError::ZoomTooDeep`] when `z` exceeds
/// `max_zoom` (or [`MAX_SUPPORTED_ZOOM`]), [`TileError::OutOfRange`] when `x` or `y` is not in
/// `[0, 2^z)`. Both are "not found" answers for clients.
pub fn validate_tile(z: u8, x: u32, y: u32, max_zoom: u8) -> Result<(), TileError> {
    let max = max_zoom.min(MAX_SUPPORTED_ZOOM);
    if z > max {
        return Err(TileError::ZoomTooDeep { z, max });
    }
    let n = 1u64 << z;
    if u64::from(x) >= n || u64::from(y) >= n {
        return Err(TileError::OutOfRange { z, x, y });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The standard slippy-map formula (OpenStreetMap wiki), written independently of the module.
    fn slippy_tile(z: u8, lon: f64, lat: f64) -> (u32, u32) {
        let n = (1u64 << z) as f64;
        let lat_r = lat.to_radians();
        let x = ((lon + 180.0) / 360.0 * n).floor();
        let y =
            ((1.0 - math::log(math::tan(lat_r) + 1.0 / math::cos(lat_r)) / PI) / 2.0 * n).floor();
        (x as u32, y as u32)
    }

    #[test]
    fn mercator_round_trips() {
        for &(lon, lat) in &[
            (0.0, 0.0),
            (74.6, 42.87),
            (-122.4, 37.8),
            (179.9, -85.0),
            (-179.9, 85.0),
            (12.3456789, -33.3333),
        ] {
            let (x, y) = lonlat_to_mercator(lon, lat);
            let (lon2, lat2) = mercator_to_lonlat(x, y);
            assert!((lon - lon2).abs() < 1e-9, "{lon} vs {lon2}");
            assert!((lat - lat2).abs() < 1e-9, "{lat} vs {lat2}");
        }
        // Known values: the world edge is ±πR = ±20037508.342789244 m.
        let (x, y) = lonlat_to_mercator(180.0, MAX_LATITUDE);
        assert!((x - 20_037_508.342_789_244).abs() < 1e-6, "{x}");
        assert!((y - 20_037_508.342_789_244).abs() < 1e-4, "{y}");
        // Latitude is clamped, so the poles stay finite.
        let (_, y) = lonlat_to_mercator(0.0, 90.0);
        assert!(y.is_finite());
    }

    #[test]
    fn zoom_zero_tile_covers_the_world() {
        let (w, s, e, n) = tile_bounds_lonlat(0, 0, 0);
        assert_eq!(w, -180.0);
        assert_eq!(e, 180.0);
        assert!((n - 85.0511).abs() < 1e-4, "{n}");
        assert!((s + 85.0511).abs() < 1e-4, "{s}");
        assert!((n - MAX_LATITUDE).abs() < 1e-9);
    }

    #[test]
    fn bishkek_tile_at_zoom_12_matches_slippy_formula() {
        let (lon, lat) = (74.6, 42.87);
        let expected = slippy_tile(12, lon, lat);
        // Computed by hand (python) from the same published formula: 2896.78, 1507.09.
        assert_eq!(expected, (2896, 1507));
        let (px, py) = lonlat_to_global_pixel(12, lon, lat);
        assert_eq!(((px / 256.0) as u32, (py / 256.0) as u32), expected);
        let (x0, y0, x1, y1) = tile_range_for_bounds(12, (lon, lat, lon, lat));
        assert_eq!((x0, y0), expected);
        assert_eq!((x1, y1), expected);
        // The tile's bounds contain the point.
        let (w, s, e, n) = tile_bounds_lonlat(12, expected.0, expected.1);
        assert!(
            w <= lon && lon < e && s < lat && lat <= n,
            "{w} {s} {e} {n}"
        );
        // Width of a z12 tile is 360/4096 degrees.
        assert!((e - w - 360.0 / 4096.0).abs() < 1e-12);
        // North edge by the slippy inverse formula: atan(sinh(π(1 − 2y/n))).
        let n_ref = math::atan(math::sinh(PI * (1.0 - 2.0 * 1507.0 / 4096.0))).to_degrees();
        assert!((n - n_ref).abs() < 1e-9, "{n} vs {n_ref}");
    }

    #[test]
    fn tile_ranges_are_clamped_and_exclusive_of_touching_tiles() {
        assert_eq!(
            tile_range_for_bounds(3, (-180.0, -90.0, 180.0, 90.0)),
            (0, 0, 7, 7)
        );
        assert_eq!(
            tile_range_for_bounds(3, (-500.0, -90.0, 500.0, 90.0)),
            (0, 0, 7, 7)
        );
        // Exactly one z1 quadrant: the north-east one, touching its neighbours along edges.
        assert_eq!(
            tile_range_for_bounds(1, (0.0, 0.0, 180.0, 85.0)),
            (1, 0, 1, 0)
        );
        // Swapped bounds are sorted.
        assert_eq!(
            tile_range_for_bounds(1, (180.0, 85.0, 0.0, 0.0)),
            (1, 0, 1, 0)
        );
        // NaN never panics.
        let _ = tile_range_for_bounds(5, (f64::NAN, f64::NAN, f64::NAN, f64::NAN));
        // Tien Shan window 66–81°E, 39–44°N at zoom 8, from the slippy formula.
        let (ax, ay) = slippy_tile(8, 66.0, 44.0);
        let (bx, by) = slippy_tile(8, 81.0, 39.0);
        assert_eq!(
            tile_range_for_bounds(8, (66.0, 39.0, 81.0, 44.0)),
            (ax, ay, bx, by)
        );
    }

    #[test]
    fn pixel_sizes_follow_the_published_values() {
        // 156543.03392804097 m per pixel at zoom 0 (2π·6378137/256).
        assert!((pixel_size_m(0) - 156_543.033_928_040_97).abs() < 1e-6);
        assert!((pixel_size_m(8) - 611.496_226_281_380_4).abs() < 1e-9);
        assert!((ground_cell_m(8, 60.0) - 611.496_226_281_380_4 * 0.5).abs() < 1e-6);
    }

    #[test]
    fn tien_shan_15_arcsecond_grid_is_native_at_zoom_8() {
        // 15″ cells at 41°N: 463 m north-south, 463·cos(41°) ≈ 350 m east-west; geometric mean
        // ≈ 403 m. Zoom 8 pixels are 156543.03·cos(41°)/256 ≈ 461.5 m, zoom 9 ≈ 230.8 m, zoom 7
        // ≈ 923 m; log2(118144.5 / 403) ≈ 8.197, so the nearest zoom in log scale is 8.
        let cell = (463.0f64 * 350.0).sqrt();
        assert!((cell - 402.6).abs() < 0.5);
        assert!((ground_cell_m(8, 41.0) - 461.5).abs() < 0.1);
        assert_eq!(native_zoom(cell, 41.0), 8);
        assert_eq!(native_zoom(463.0, 41.0), 8);
        assert_eq!(native_zoom(30.0, 0.0), 12); // 156543/2^12 = 38.2 m, 2^13 → 19.1 m
        assert_eq!(native_zoom(0.0, 41.0), 0);
        assert_eq!(native_zoom(f64::NAN, 41.0), 0);
        assert_eq!(native_zoom(1e-9, 41.0), MAX_SUPPORTED_ZOOM);
    }

    #[test]
    fn validate_tile_rejects_missing_tiles() {
        assert_eq!(validate_tile(0, 0, 0, 14), Ok(()));
        assert_eq!(validate_tile(3, 7, 7, 14), Ok(()));
        assert_eq!(
            validate_tile(3, 8, 0, 14),
            Err(TileError::OutOfRange { z: 3, x: 8, y: 0 })
        );
        assert_eq!(
            validate_tile(3, 0, 8, 14),
            Err(TileError::OutOfRange { z: 3, x: 0, y: 8 })
        );
        assert_eq!(
            validate_tile(15, 0, 0, 14),
            Err(TileError::ZoomTooDeep { z: 15, max: 14 })
        );
        assert_eq!(
            validate_tile(31, 0, 0, 255),
            Err(TileError::ZoomTooDeep {
                z: 31,
                max: MAX_SUPPORTED_ZOOM
            })
        );
        // 2^30 = 1073741824 < u32::MAX: the largest x is out of range without overflow.
        assert_eq!(
            validate_tile(30, u32::MAX, 0, 30),
            Err(TileError::OutOfRange {
                z: 30,
                x: u32::MAX,
                y: 0
            })
        );
        assert_eq!(validate_tile(30, (1 << 30) - 1, 0, 30), Ok(()));
    }
}
