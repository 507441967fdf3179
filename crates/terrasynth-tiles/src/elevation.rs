//! The elevation pyramid: the base raster resampled to Web Mercator at the native zoom `z_b`,
//! averaged overviews below it, and one amplification level per zoom above it, with the amplifier (dictionary or gradient tiles) of the zoom's band.
//!
//! Tile `(z, x, y)` is the window `[256x, 256x+256) × [256y, 256y+256)` of zoom `z`'s global pixel
//! plane. Zoom `z_b` is sampled bilinearly from the base (pixels outside the base get the world's
//! fill elevation). A tile of zoom `z > z_b` is amplified from the window of zoom `z − 1` that
//! [`Level::parent_window_for`] names, assembled from cached parent tiles; since the amplifier
//! is window-invariant, a tile computed alone equals the same window of any larger region. A tile
//! of zoom `z < z_b` is the 2×2 box average of its four children, so zooming is consistent.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use ndarray::Array2;

use terrasynth_core::raster::{box2, Grid};
use terrasynth_core::synth::{AnyAmplifier, Field, Level, Window};

use crate::chain::Chain;
use crate::error::TileError;
use crate::extent::Extent;
use crate::pyramid::{assemble, overview, tile_window, LevelCache};
use crate::resample::mercator_window_from_grid;

/// The elevation levels of a world.
pub struct ElevationLevels {
    base: Grid,
    fill_m: f32,
    extent: Extent,
    amplifiers: Chain<AnyAmplifier>,
    cache: LevelCache<Array2<f32>>,
    /// Level tiles synthesized by amplification (zooms above `z_b`).
    pub tiles_synthesized: AtomicU64,
    /// Time spent computing level tiles, microseconds.
    pub synthesis_micros: AtomicU64,
}

impl std::fmt::Debug for ElevationLevels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ElevationLevels")
            .field("extent", &self.extent)
            .finish_non_exhaustive()
    }
}

impl ElevationLevels {
    /// Levels over `base` (outside it: `fill_m`), each zoom amplified with its band's amplifier
    /// of `amplifiers`, cached in at most `cache_bytes` bytes.
    pub fn new(
        base: Grid,
        fill_m: f32,
        extent: Extent,
        amplifiers: Chain<AnyAmplifier>,
        cache_bytes: u64,
    ) -> Self {
        ElevationLevels {
            base,
            fill_m,
            extent,
            amplifiers,
            cache: LevelCache::new(cache_bytes),
            tiles_synthesized: AtomicU64::new(0),
            synthesis_micros: AtomicU64::new(0),
        }
    }

    /// The world's extent.
    pub fn extent(&self) -> &Extent {
        &self.extent
    }

    /// The base raster.
    pub fn base(&self) -> &Grid {
        &self.base
    }

    /// Elevation outside the base, metres.
    pub fn fill_m(&self) -> f32 {
        self.fill_m
    }

    /// The cache of level tiles.
    pub fn cache(&self) -> &LevelCache<Array2<f32>> {
        &self.cache
    }

    /// The level tile `(z, tx, ty)`, computed once. Tile indices may lie outside `[0, 2^z)`.
    pub fn tile(&self, z: u8, tx: i64, ty: i64) -> Result<Arc<Array2<f32>>, TileError> {
        self.cache.get_or_compute((z, tx, ty), || {
            let start = Instant::now();
            let tile = self.compute(z, tx, ty);
            self.synthesis_micros
                .fetch_add(start.elapsed().as_micros() as u64, Ordering::Relaxed);
            tile
        })
    }

    /// Window `w` of zoom `z`'s plane, assembled from level tiles. `z` may exceed `max_zoom` by
    /// one (for 512-px tiles at the deepest zoom).
    pub fn window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        let max = self.extent.max_zoom;
        if z > max.saturating_add(1) {
            return Err(TileError::ZoomTooDeep { z, max });
        }
        assemble(w, 1, |tx, ty| self.tile(z, tx, ty))
    }

    fn compute(&self, z: u8, tx: i64, ty: i64) -> Result<Array2<f32>, TileError> {
        let w = tile_window(tx, ty);
        let zb = self.extent.z_base;
        if z == zb {
            let (values, _) = mercator_window_from_grid(
                &self.base,
                z,
                w.col0,
                w.row0,
                w.cols,
                w.rows,
                self.fill_m,
            );
            return Ok(values);
        }
        if z < zb {
            return overview(tx, ty, 1, self.fill_m, box2, |cx, cy| {
                if self.extent.tile_outside(z + 1, cx, cy) {
                    return Ok(None);
                }
                self.tile(z + 1, cx, cy).map(Some)
            });
        }
        let amplifier = self.amplifiers.at(z);
        let need = amplifier.parent_window_for(w);
        let parent = Field::elevation_only(need, self.window(z - 1, need)?);
        let field = amplifier.amplify(&parent, w, self.extent.level_cell_m(z - 1) as f32)?;
        self.tiles_synthesized.fetch_add(1, Ordering::Relaxed);
        Ok(field.elevation)
    }
}
