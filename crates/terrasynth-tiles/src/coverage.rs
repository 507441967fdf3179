//! The coverage pyramid: at every zoom, the fraction (0–1) of each pixel that the base's data
//! covers. Every overlay layer (colour, splat, vegetation, drainage, water, instances) is
//! transparent, zero or empty where the coverage is 0, so nothing is drawn, routed or scattered
//! outside the base or in its nodata holes.
//!
//! - **Native and amplified zooms** (`z ≥ z_b`): 1 where the pixel's centre takes its value from
//!   valid base cells ([`crate::resample::mercator_window_from_grid`]'s mask, sampled at that zoom directly, so the
//!   border is as sharp as the zoom's pixels), else 0.
//! - **Overviews** (`z < z_b`): the 2×2 box average of the children (a fraction on the border).
//!
//! Each pixel is a function of its global coordinates only: the layer is seamless and
//! window-invariant like every other. Only the overview tiles are cached: a tile of `z ≥ z_b` is
//! a per-pixel lookup of the base's validity (read once), cheaper to recompute than to hold.

use std::sync::Arc;

use ndarray::Array2;

use terrasynth_core::raster::{box2, Grid};
use terrasynth_core::synth::Window;

use crate::error::TileError;
use crate::extent::Extent;
use crate::pyramid::{assemble, overview, tile_window, LevelCache};
use crate::resample::{mercator_mask_from_grid, source_validity};

/// The coverage levels of a world.
#[derive(Debug)]
pub struct CoverageLevels {
    /// Overview tiles (`z < z_b`) only: the tiles of the native and amplified zooms are cheap
    /// per-pixel lookups, computed on each use so that they take no cache memory.
    cache: LevelCache<Array2<f32>>,
    /// The base's per-cell validity, read once (`None`: every cell is valid).
    valid: Option<Array2<bool>>,
}

impl CoverageLevels {
    /// Coverage levels of `base`, the overview tiles cached in at most `cache_bytes` bytes.
    pub fn new(base: &Grid, cache_bytes: u64) -> Self {
        CoverageLevels {
            cache: LevelCache::new("coverage", cache_bytes),
            valid: source_validity(base),
        }
    }

    /// The base's per-cell validity, read once ([`source_validity`]; `None`: every cell is
    /// valid), for the resampling of the base's own values.
    pub(crate) fn base_validity(&self) -> Option<&Array2<bool>> {
        self.valid.as_ref()
    }

    /// The cache of overview tiles.
    pub fn cache(&self) -> &LevelCache<Array2<f32>> {
        &self.cache
    }

    /// The coverage tile `(z, tx, ty)` of `base` placed by `extent`.
    pub fn tile(
        &self,
        base: &Grid,
        extent: &Extent,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Array2<f32>>, TileError> {
        if z < extent.z_base && !extent.tile_outside(z, tx, ty) {
            self.cache
                .get_or_compute((z, tx, ty), || self.compute(base, extent, z, tx, ty))
        } else {
            self.compute(base, extent, z, tx, ty).map(Arc::new)
        }
    }

    /// Coverage over window `w` of zoom `z`, assembled from tiles.
    pub fn window(
        &self,
        base: &Grid,
        extent: &Extent,
        z: u8,
        w: Window,
    ) -> Result<Array2<f32>, TileError> {
        assemble(w, 1, |tx, ty| self.tile(base, extent, z, tx, ty))
    }

    fn compute(
        &self,
        base: &Grid,
        extent: &Extent,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Array2<f32>, TileError> {
        let w = tile_window(tx, ty);
        if extent.tile_outside(z, tx, ty) {
            return Ok(Array2::zeros((w.rows, w.cols)));
        }
        if z < extent.z_base {
            return overview(tx, ty, 1, 0.0, box2, |cx, cy| {
                if extent.tile_outside(z + 1, cx, cy) {
                    return Ok(None);
                }
                self.tile(base, extent, z + 1, cx, cy).map(Some)
            });
        }
        let mask = mercator_mask_from_grid(base, self.valid.as_ref(), z, w);
        Ok(mask.mapv(|m| if m { 1.0 } else { 0.0 }))
    }
}

/// Whether a coverage value means "no data here".
pub fn uncovered(coverage: f32) -> bool {
    coverage <= 0.0
}

/// Multiplies `values` by `coverage` (same shape) in place: zero outside the coverage, scaled
/// by the covered fraction on overview borders.
pub fn mask_in_place(values: &mut Array2<f32>, coverage: &Array2<f32>) {
    ndarray::Zip::from(values).and(coverage).for_each(|v, &c| {
        if c < 1.0 {
            *v *= c;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::resample::mercator_window_from_grid;
    use terrasynth_core::raster::Georef;

    /// A 1°×1° base at (10°E, 40°N) of 64×64 cells with a 16×16 nodata hole in its middle.
    fn base() -> Grid {
        let mut g = Grid::new(
            Array2::from_elem((64, 64), 100.0f32),
            Georef {
                crs: terrasynth_core::raster::Crs::Epsg4326,
                west: 10.0,
                north: 41.0,
                pixel_width: 1.0 / 64.0,
                pixel_height: 1.0 / 64.0,
            },
        );
        for r in 24..40 {
            for c in 24..40 {
                g.data[[r, c]] = f32::NAN;
            }
        }
        g
    }

    #[test]
    fn coverage_is_one_inside_zero_outside_and_in_holes() {
        let b = base();
        let extent = Extent::of_base(&b, None, 14).unwrap();
        let levels = CoverageLevels::new(&b, 1 << 26);
        let z = extent.z_base + 1;
        let w = extent.world_window(z);
        let big = Window::new(w.col0 - 40, w.row0 - 40, w.cols + 80, w.rows + 80);
        let cov = levels.window(&b, &extent, z, big).unwrap();
        let (_, mask) =
            mercator_window_from_grid(&b, z, big.col0, big.row0, big.cols, big.rows, -1.0);
        // Independent of the cache: the resampler's own mask, pixel by pixel.
        for ((r, c), &m) in mask.indexed_iter() {
            assert_eq!(cov[[r, c]], if m { 1.0 } else { 0.0 }, "pixel {r},{c}");
        }
        assert!(cov.iter().any(|&v| v == 0.0) && cov.iter().any(|&v| v == 1.0));
        // The hole's centre is uncovered.
        let (hx, hy) = crate::mercator::lonlat_to_global_pixel(z, 10.5, 40.5);
        let (hr, hc) = (
            (hy as i64 - big.row0) as usize,
            (hx as i64 - big.col0) as usize,
        );
        assert_eq!(cov[[hr, hc]], 0.0);
        // A tile alone (fresh cache) equals the same window of a block around it.
        let t = tile_window((hx as i64).div_euclid(256), (hy as i64).div_euclid(256));
        let block = Window::new(t.col0 - 40, t.row0 - 40, 336, 336);
        let big = levels.window(&b, &extent, z, block).unwrap();
        let alone = CoverageLevels::new(&b, 1 << 26)
            .window(&b, &extent, z, t)
            .unwrap();
        assert_eq!(alone.view(), big.slice(ndarray::s![40..296, 40..296]));
    }

    #[test]
    fn overviews_average_the_children() {
        let b = base();
        let extent = Extent::of_base(&b, None, 14).unwrap();
        let levels = CoverageLevels::new(&b, 1 << 26);
        let z = extent.z_base - 1;
        let w = extent.world_window(z);
        let cov = levels.window(&b, &extent, z, w).unwrap();
        let child = levels
            .window(
                &b,
                &extent,
                z + 1,
                Window::new(2 * w.col0, 2 * w.row0, 2 * w.cols, 2 * w.rows),
            )
            .unwrap();
        for ((r, c), &v) in cov.indexed_iter() {
            let s = child[[2 * r, 2 * c]]
                + child[[2 * r, 2 * c + 1]]
                + child[[2 * r + 1, 2 * c]]
                + child[[2 * r + 1, 2 * c + 1]];
            assert_eq!(v, s / 4.0);
        }
    }
}
