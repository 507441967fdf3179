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
    }
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

    /// Centre `[lon, lat, zoom]` for map clients (zoom: two above the native zoom).
    pub fn center(&self) -> [f64; 3] {
        [
            0.5 * (self.bounds[0] + self.bounds[2]),
            self.ref_lat,
            f64::from((self.z_base + 2).min(self.max_zoom)),
        ]
    }
}
