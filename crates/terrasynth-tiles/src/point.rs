//! Point queries: the served elevation at longitudes/latitudes, read from the same elevation
//! tiles the map shows (the float32 values of the `.exr` tile, before any PNG quantisation). A
//! point falls in the pixel of zoom `z`'s global plane that contains it (pixel `(px, py)` holds
//! `[px, px+1) × [py, py+1)`); points are grouped by tile so that each tile is fetched once.

use std::collections::BTreeMap;

use crate::error::TileError;
use crate::mercator::{lonlat_to_global_pixel, MAX_LATITUDE, TILE_SIZE};
use crate::world::World;

/// Why a point query failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PointError {
    /// Point `index`'s longitude or latitude is not finite or out of range (±180°,
    /// ±[`MAX_LATITUDE`]).
    OutOfRange {
        /// Which point.
        index: usize,
        /// What is wrong with it.
        why: String,
    },
    /// A tile could not be computed.
    Tile(TileError),
}

/// Points by the tile that holds them: `(index, row, col)`.
type PixelsByTile = BTreeMap<(u32, u32), Vec<(usize, usize, usize)>>;

/// The tile and the pixel inside it that contain `(lon, lat)` at zoom `z`:
/// `(x, y, row, col)`, or an error for coordinates out of range.
pub fn pixel_of(z: u8, lon: f64, lat: f64) -> Result<(u32, u32, usize, usize), String> {
    if !lon.is_finite() || !(-180.0..=180.0).contains(&lon) {
        return Err(format!("longitude {lon} must lie in [-180, 180]"));
    }
    if !lat.is_finite() || !(-MAX_LATITUDE..=MAX_LATITUDE).contains(&lat) {
        return Err(format!(
            "latitude {lat} must lie in [-{MAX_LATITUDE}, {MAX_LATITUDE}]"
        ));
    }
    let side = f64::from(TILE_SIZE) * f64::from(1u32 << z.min(31));
    let (px, py) = lonlat_to_global_pixel(z, lon, lat);
    // The east and south edges belong to the last pixel.
    let clamp = |v: f64| v.floor().clamp(0.0, side - 1.0) as u64;
    let (px, py) = (clamp(px), clamp(py));
    let t = u64::from(TILE_SIZE);
    Ok((
        (px / t) as u32,
        (py / t) as u32,
        (py % t) as usize,
        (px % t) as usize,
    ))
}

/// The served elevation (metres) at each point `(lon, lat)` at zoom `z`; `None` for a point
/// outside the world. Coordinates out of range are an error naming the point's index. Each
/// tile is fetched once (CPU-bound: call it off the async runtime).
pub fn elevations(
    world: &World,
    z: u8,
    points: &[(f64, f64)],
) -> Result<Vec<Option<f32>>, PointError> {
    let mut by_tile = PixelsByTile::new();
    for (index, &(lon, lat)) in points.iter().enumerate() {
        let (x, y, r, c) =
            pixel_of(z, lon, lat).map_err(|why| PointError::OutOfRange { index, why })?;
        by_tile.entry((x, y)).or_default().push((index, r, c));
    }
    let mut out = vec![None; points.len()];
    for ((x, y), pixels) in by_tile {
        if world.check_tile(z, x, y).is_err() {
            continue;
        }
        let tile = world.elevation_tile(z, x, y).map_err(PointError::Tile)?;
        for (i, r, c) in pixels {
            out[i] = tile.get([r, c]).copied();
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mercator::tile_bounds_lonlat;

    #[test]
    fn a_point_falls_in_the_pixel_that_contains_it() {
        // The north-west corner of a tile is its pixel (0, 0); just inside its south-east corner
        // is pixel (255, 255).
        let (w, s, e, n) = tile_bounds_lonlat(12, 2896, 1512);
        assert_eq!(
            pixel_of(12, w + 1e-9, n - 1e-9).unwrap(),
            (2896, 1512, 0, 0)
        );
        assert_eq!(
            pixel_of(12, e - 1e-9, s + 1e-9).unwrap(),
            (2896, 1512, 255, 255)
        );
        // The centre of the tile lies at the corner of pixels 127 and 128.
        let (_, _, r, c) = pixel_of(12, (w + e) / 2.0 + 1e-9, n - (n - s) * 0.75).unwrap();
        assert_eq!(c, 128);
        assert!((191..=192).contains(&r), "{r}");
        // The east edge of the world and the south edge of the plane stay on the plane.
        assert_eq!(pixel_of(0, 180.0, -MAX_LATITUDE).unwrap(), (0, 0, 255, 255));
    }

    #[test]
    fn coordinates_out_of_range_are_errors() {
        for (lon, lat) in [
            (f64::NAN, 0.0),
            (0.0, f64::INFINITY),
            (180.5, 0.0),
            (0.0, 86.0),
        ] {
            assert!(pixel_of(5, lon, lat).is_err(), "{lon} {lat}");
        }
    }
}
