//! Where a world lies on the Web Mercator planes: its bounds in degrees, its native zoom, its
//! deepest zoom, and which tiles it touches. Every layer asks the same [`Extent`] so that all of
//! them agree on which tiles exist.

use terrasynth_core::raster::{CellSizes, Crs, Grid};
use terrasynth_core::synth::Window;

use crate::error::TileError;
use crate::mercator::{
    ground_cell_m, lonlat_to_global_pixel, mercator_to_lonlat, native_zoom, plane_cell_sizes,
    validate_tile, TILE_SIZE,
};

const T: f64 = TILE_SIZE as f64;

/// A world's place on the tile planes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    /// `[west, south, east, north]` in degrees.
    pub bounds: [f64; 4],
    /// Latitude at which per-level metric cell sizes are taken (the base's centre).
    pub ref_lat: f64,
    /// Native zoom of the base.
    pub z_base: u8,
    /// Deepest zoom served.
    pub max_zoom: u8,
}

/// Bounds `[w, s, e, n]` in degrees of a georeferenced grid.
pub fn lonlat_bounds(g: &Grid) -> [f64; 4] {
    let (w, s, e, n) = g.georef.bounds(g.cols(), g.rows());
    match g.georef.crs {
        Crs::Epsg4326 => [w, s, e, n],
        Crs::Epsg3857 => {
            let (w, s) = mercator_to_lonlat(w, s);
            let (e, n) = mercator_to_lonlat(e, n);
            [w, s, e, n]
        }
        // World bases are reprojected onto EPSG:4326 first ([`crate::World::new`]); elsewhere,
        // the box of the corners.
        Crs::Projected(_) => {
            let corners: Vec<(f64, f64)> = [(w, s), (w, n), (e, s), (e, n)]
                .iter()
                .filter_map(|&(x, y)| g.georef.crs.to_lonlat(x, y))
                .collect();
            let f = |pick: fn(&(f64, f64)) -> f64, min: bool| {
                corners.iter().map(pick).fold(
                    if min { f64::MAX } else { f64::MIN },
                    if min { f64::min } else { f64::max },
                )
            };
            [
                f(|p| p.0, true),
                f(|p| p.1, true),
                f(|p| p.0, false),
                f(|p| p.1, false),
            ]
        }
    }
}

/// `[lon, lat]` of the centre of the base's highest-relief region: the square window (an eighth
/// of the base's shorter side, at least 2 cells, moved by half its side) whose valid cells span
/// the largest elevation range; the first such window in row-major order on ties. `None` when the
/// base has no valid cell. Map clients open there: a newcomer sees mountains, not the
/// geometric centre (which may be a plain).
pub fn relief_center(base: &Grid) -> Option<[f64; 2]> {
    let (rows, cols) = (base.rows(), base.cols());
    let side = (rows.min(cols) / 8).max(2).min(rows.min(cols)).max(1);
    let stride = (side / 2).max(1);
    let starts = |n: usize| {
        let last = n.saturating_sub(side);
        let mut v: Vec<usize> = (0..=last).step_by(stride).collect();
        if v.last() != Some(&last) {
            v.push(last);
        }
        v
    };
    let mut best: Option<(f32, usize, usize)> = None;
    for r0 in starts(rows) {
        for c0 in starts(cols) {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for r in r0..(r0 + side).min(rows) {
                for c in c0..(c0 + side).min(cols) {
                    if base.is_valid(r, c) {
                        let v = base.data[[r, c]];
                        lo = lo.min(v);
                        hi = hi.max(v);
                    }
                }
            }
            if hi >= lo && best.is_none_or(|(b, _, _)| hi - lo > b) {
                best = Some((hi - lo, r0, c0));
            }
        }
    }
    let (_, r0, c0) = best?;
    let half = side as f64 / 2.0 - 0.5;
    let (x, y) = base.georef.pixel_centre(c0 as f64 + half, r0 as f64 + half);
    Some(match base.georef.crs {
        Crs::Epsg4326 => [x, y],
        Crs::Epsg3857 => {
            let (lon, lat) = mercator_to_lonlat(x, y);
            [lon, lat]
        }
        Crs::Projected(_) => {
            let (lon, lat) = base.georef.crs.to_lonlat(x, y)?;
            [lon, lat]
        }
    })
}

impl Extent {
    /// The extent of `base` served up to `max_zoom`, with native zoom `z_base` (derived from the
    /// base's cell size when `None`). `max_zoom` must lie between the native zoom and 24.
    pub fn of_base(base: &Grid, z_base: Option<u8>, max_zoom: u8) -> Result<Extent, TileError> {
        let bounds = lonlat_bounds(base);
        let ref_lat = 0.5 * (bounds[1] + bounds[3]);
        let z_base = match z_base {
            Some(z) => z,
            None => {
                let cells = base.georef.cell_sizes(base.rows());
                native_zoom(cells.mean_cell(), ref_lat)
            }
        };
        if max_zoom < z_base || max_zoom > 24 {
            return Err(TileError::ZoomRange { max_zoom, z_base });
        }
        Ok(Extent {
            bounds,
            ref_lat,
            z_base,
            max_zoom,
        })
    }

    /// Checks that tile `(z, x, y)` exists and intersects the world: `OutOfRange`, `ZoomTooDeep`
    /// or `OutsideWorld` otherwise.
    pub fn check_tile(&self, z: u8, x: u32, y: u32) -> Result<(), TileError> {
        validate_tile(z, x, y, self.max_zoom)?;
        let (px0, py0) = lonlat_to_global_pixel(z, self.bounds[0], self.bounds[3]);
        let (px1, py1) = lonlat_to_global_pixel(z, self.bounds[2], self.bounds[1]);
        let (x0, x1) = (f64::from(x) * T, f64::from(x + 1) * T);
        let (y0, y1) = (f64::from(y) * T, f64::from(y + 1) * T);
        if x1 <= px0 || x0 >= px1 || y1 <= py0 || y0 >= py1 {
            return Err(TileError::OutsideWorld { z, x, y });
        }
        Ok(())
    }

    /// Whether tile `(z, tx, ty)` lies wholly outside the world (all fill), including tile
    /// indices outside `[0, 2^z)`.
    pub fn tile_outside(&self, z: u8, tx: i64, ty: i64) -> bool {
        if tx < 0 || ty < 0 || tx >= (1i64 << z) || ty >= (1i64 << z) {
            return true;
        }
        self.check_tile(z, tx as u32, ty as u32).is_err()
    }

    /// Metric ground cell size of zoom `z`'s pixels at the reference latitude (the value the
    /// amplifier's slope term uses for every tile of that zoom).
    pub fn level_cell_m(&self, z: u8) -> f64 {
        ground_cell_m(z, self.ref_lat)
    }

    /// Per-row metric cell sizes of the rows `[row0, row0 + rows)` of zoom `z`'s pixel plane.
    pub fn cell_sizes(&self, z: u8, row0: i64, rows: usize) -> CellSizes {
        plane_cell_sizes(z, row0, rows)
    }

    /// The window of zoom `z`'s plane that covers the world: its bounds plus two pixels.
    pub fn world_window(&self, z: u8) -> Window {
        let b = self.bounds;
        let (px0, py0) = lonlat_to_global_pixel(z, b[0], b[3]);
        let (px1, py1) = lonlat_to_global_pixel(z, b[2], b[1]);
        Window::from_bounds(
            px0.floor() as i64 - 2,
            py0.floor() as i64 - 2,
            px1.ceil() as i64 + 2,
            py1.ceil() as i64 + 2,
        )
    }

    /// The geometric centre `[lon, lat]` of the bounds.
    pub fn middle(&self) -> [f64; 2] {
        [0.5 * (self.bounds[0] + self.bounds[2]), self.ref_lat]
    }

    /// The zoom map clients open at: two above the native zoom.
    pub fn opening_zoom(&self) -> u8 {
        (self.z_base + 2).min(self.max_zoom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;
    use terrasynth_core::raster::Georef;

    fn grid(data: Array2<f32>, crs: Crs, west: f64, north: f64, cell: f64) -> Grid {
        Grid::new(
            data,
            Georef {
                crs,
                west,
                north,
                pixel_width: cell,
                pixel_height: cell,
            },
        )
    }

    #[test]
    fn the_relief_centre_finds_the_one_steep_region_in_either_crs() {
        // A plain with one cliff block at rows 40..48, cols 8..16 of 64 × 64.
        let data = Array2::from_shape_fn((64, 64), |(r, c)| {
            if (40..48).contains(&r) && (8..16).contains(&c) {
                3000.0
            } else {
                100.0
            }
        });
        let g = grid(data.clone(), Crs::Epsg4326, 10.0, 50.0, 0.01);
        let [lon, lat] = relief_center(&g).unwrap();
        // Windows of 8 cells at a stride of 4: the chosen one overlaps the block, so its centre
        // lies within 8 cells of the block's centre (12, 44).
        assert!((lon - (10.0 + 12.0 * 0.01)).abs() <= 0.08, "{lon}");
        assert!((lat - (50.0 - 44.0 * 0.01)).abs() <= 0.08, "{lat}");
        // The same block in Web Mercator metres comes back in degrees.
        let g = grid(data, Crs::Epsg3857, 1_000_000.0, 5_000_000.0, 1000.0);
        let [lon, lat] = relief_center(&g).unwrap();
        let (want_lon, want_lat) = mercator_to_lonlat(1_012_000.0, 4_956_000.0);
        assert!((lon - want_lon).abs() < 0.08 && (lat - want_lat).abs() < 0.08);
    }

    #[test]
    fn a_base_without_valid_cells_has_no_relief_centre() {
        let g = grid(
            Array2::from_elem((8, 8), f32::NAN),
            Crs::Epsg4326,
            0.0,
            1.0,
            0.1,
        );
        assert_eq!(relief_center(&g), None);
        // A flat base: every window ties at 0; the first (north-west) one wins.
        let g = grid(Array2::zeros((16, 16)), Crs::Epsg4326, 0.0, 1.0, 0.1);
        let [lon, lat] = relief_center(&g).unwrap();
        assert!(
            (lon - 0.1).abs() < 1e-9 && (lat - 0.9).abs() < 1e-9,
            "{lon} {lat}"
        );
    }
}
