//! The water pyramid: at every zoom, three planes per tile — water depth (m, 0 where dry), water
//! surface level (m, NaN where dry) and a sea flag (1 sea, 0 lake or dry).
//!
//! - **Native zoom `z_b`**: cut from the whole-world sea and lakes
//!   ([`terrasynth_core::landscape::water`](fn@terrasynth_core::landscape::water), computed once by
//!   [`ElevationLevels::base_water`]); depth = level − bed.
//! - **Amplified zooms**: each pixel takes the level and sea flag of its parent pixel (water
//!   surfaces are flat: the level never gets detail), or where its parent is dry the highest
//!   level of the wet parents beside its quarter of the parent (at most three: the side and
//!   corner neighbours it touches), and its depth is that level minus the amplified bed, where
//!   positive; a pixel whose bed rises above the level is dry. So the shoreline follows the
//!   amplified bed, which may carry it up to one pixel beyond its parents' at each zoom
//!   instead of drawing the native zoom's pixel staircase.
//!
//! The native zoom's lakes include those the base records as flat surfaces
//! ([`take_surface_lakes`], when the world asks for them): their beds are sunk below the
//! surface before anything reads the base.
//! - **Overviews** (`z < z_b`): depth is the 2×2 box average of the children (depth averages:
//!   zoom-consistent), level and sea flag the children's maximum.
//!
//! Depth is 0 outside the base's coverage ([`crate::coverage`]). Every value is a function of
//! the pixel's global coordinates: tiles are seamless and window-invariant.

use std::sync::Arc;

use ndarray::Array2;

use terrasynth_core::landscape::surface_lakes::{sink_surface_lake_beds, surface_lakes};
use terrasynth_core::landscape::WaterConfig;
use terrasynth_core::raster::{box2, Grid};
use terrasynth_core::synth::Window;

use crate::base_layers::cut;
use crate::elevation::ElevationLevels;
use crate::error::TileError;
use crate::pyramid::{assemble, overview, tile_window, LevelCache};

/// Plane indices of a water tile.
pub const DEPTH: usize = 0;
/// The surface level plane (NaN where dry).
pub const LEVEL: usize = 1;
/// The sea flag plane (1 sea, 0 otherwise).
pub const SEA: usize = 2;
const PLANES: usize = 3;

/// The water levels of a world.
#[derive(Debug)]
pub struct WaterLevels {
    cache: LevelCache<Vec<Array2<f32>>>,
    /// The one tile of a world without water (every tile is dry): never cached per key.
    dry: Arc<Vec<Array2<f32>>>,
}

fn max4(v: [f32; 4]) -> f32 {
    v[0].max(v[1]).max(v[2]).max(v[3])
}

fn reduce(v: [f32; 4]) -> f32 {
    // Depths average, flags and levels take the maximum; the planes share one reducer, told
    // apart by their values: depths are ≥ 0 and finite, so the box average applies to all but
    // NaN-bearing level planes, whose maximum `f32::max` takes without NaN.
    if v.iter().any(|x| x.is_nan()) {
        max4(v)
    } else {
        box2(v)
    }
}

impl WaterLevels {
    /// Water levels cached in at most `cache_bytes` bytes.
    pub fn new(cache_bytes: u64) -> Self {
        WaterLevels {
            cache: LevelCache::new("water", cache_bytes),
            dry: Arc::new(dry(tile_window(0, 0))),
        }
    }

    /// The cache of level tiles.
    pub fn cache(&self) -> &LevelCache<Vec<Array2<f32>>> {
        &self.cache
    }

    /// The water tile `(z, tx, ty)`: depth, level and sea planes.
    pub fn tile(
        &self,
        elevation: &ElevationLevels,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Vec<Array2<f32>>>, TileError> {
        let extent = elevation.extent();
        let dry = extent.tile_outside(z, tx, ty)
            || elevation.base_water_near(z, tile_window(tx, ty))?.is_none();
        if dry {
            // Dry everywhere (or outside the world, or far from any water): the shared dry
            // tile, no cache entry.
            return Ok(self.dry.clone());
        }
        self.cache
            .get_or_compute((z, tx, ty), || self.compute(elevation, z, tx, ty))
    }

    /// Water over window `w` of zoom `z` (depth, level, sea).
    pub fn window(
        &self,
        elevation: &ElevationLevels,
        z: u8,
        w: Window,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        assemble(w, PLANES, |tx, ty| self.tile(elevation, z, tx, ty))
    }

    /// Water depth over window `w` of zoom `z` (0 where dry).
    pub fn depth_window(
        &self,
        elevation: &ElevationLevels,
        z: u8,
        w: Window,
    ) -> Result<Array2<f32>, TileError> {
        Ok(self.window(elevation, z, w)?.swap_remove(DEPTH))
    }

    fn compute(
        &self,
        elevation: &ElevationLevels,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        let w = tile_window(tx, ty);
        let extent = elevation.extent();
        let zb = extent.z_base;
        let Some(base) = elevation.base_water()? else {
            return Ok(dry(w));
        };
        if extent.tile_outside(z, tx, ty) {
            return Ok(dry(w));
        }
        if z < zb {
            let mut t: Vec<Array2<f32>> = overview(tx, ty, PLANES, 0.0, reduce, |cx, cy| {
                if extent.tile_outside(z + 1, cx, cy) {
                    return Ok(None);
                }
                self.tile(elevation, z + 1, cx, cy).map(Some)
            })?;
            // Level: NaN where no child is wet.
            let (depth, rest) = t.split_at_mut(LEVEL);
            ndarray::Zip::from(&mut rest[0])
                .and(&depth[DEPTH])
                .for_each(|l, &d| {
                    if d <= 0.0 {
                        *l = f32::NAN;
                    }
                });
            return Ok(t);
        }
        let (level, sea) = if z == zb {
            (
                cut(&base.level, base.window, w, f32::NAN),
                cut(&base.sea, base.window, w, 0.0),
            )
        } else {
            // Each pixel takes its parent's level and sea flag, or where its parent is dry, the
            // highest level of the (at most three) wet parents beside its quarter of it.
            let pw = Window::new(
                w.col0 / 2 - 1,
                w.row0 / 2 - 1,
                w.cols / 2 + 2,
                w.rows / 2 + 2,
            );
            let parent = self.window(elevation, z - 1, pw)?;
            let mut level = Array2::from_elem((w.rows, w.cols), f32::NAN);
            let mut sea = Array2::zeros((w.rows, w.cols));
            for ((r, c), l) in level.indexed_iter_mut() {
                let (pr, pc) = (r / 2 + 1, c / 2 + 1);
                let (sr, sc) = ((r % 2) * 2, (c % 2) * 2);
                let mut best = (parent[LEVEL][[pr, pc]], parent[SEA][[pr, pc]]);
                if best.0.is_nan() {
                    for (nr, nc) in [
                        (pr + sr - 1, pc),
                        (pr, pc + sc - 1),
                        (pr + sr - 1, pc + sc - 1),
                    ] {
                        let nl = parent[LEVEL][[nr, nc]];
                        if nl > best.0 || (best.0.is_nan() && !nl.is_nan()) {
                            best = (nl, parent[SEA][[nr, nc]]);
                        }
                    }
                }
                *l = best.0;
                sea[[r, c]] = best.1;
            }
            (level, sea)
        };
        let bed = elevation.tile(z, tx, ty)?;
        let coverage = elevation.coverage_tile(z, tx, ty)?;
        let mut depth = Array2::zeros((w.rows, w.cols));
        let mut level = level;
        let mut sea = sea;
        for ((r, c), d) in depth.indexed_iter_mut() {
            let l = level[[r, c]];
            let v = l - bed[[r, c]];
            if crate::coverage::uncovered(coverage[[r, c]]) || v.is_nan() || v <= 0.0 {
                level[[r, c]] = f32::NAN;
                sea[[r, c]] = 0.0;
            } else {
                *d = v;
            }
        }
        Ok(vec![depth, level, sea])
    }
}

/// The lakes `base` records as flat surfaces, when `cfg` asks for them
/// (`surface_lake_min_area_m2`): sinks their beds in `base` and returns their surfaces on the
/// base's grid (valid on the lakes' cells only), or `None` when there are none. Found on the
/// base's own cells, where a lake is exactly flat, before any resampling.
pub fn take_surface_lakes(base: &mut Grid, cfg: &WaterConfig) -> Option<Grid> {
    let min_area = cfg.surface_lake_min_area_m2?;
    let cells = base.georef.cell_sizes(base.rows());
    let surface = surface_lakes(
        &base.data,
        base.valid.as_ref(),
        &cells,
        min_area,
        cfg.sea_level_m,
    );
    let on_lake = surface.mapv(|v| !v.is_nan());
    if !on_lake.iter().any(|&l| l) {
        return None;
    }
    sink_surface_lake_beds(&mut base.data, &surface, &cells, cfg.surface_lake_bed_slope);
    Some(Grid {
        data: surface,
        georef: base.georef,
        valid: Some(on_lake),
    })
}

/// Zeroes `values` under water (`depth > 0`, same shape): no channel, plant or land material
/// there.
pub fn zero_under_water(values: &mut Array2<f32>, depth: &Array2<f32>) {
    ndarray::Zip::from(values).and(depth).for_each(|v, &d| {
        if d > 0.0 {
            *v = 0.0;
        }
    });
}

fn dry(w: Window) -> Vec<Array2<f32>> {
    vec![
        Array2::zeros((w.rows, w.cols)),
        Array2::from_elem((w.rows, w.cols), f32::NAN),
        Array2::zeros((w.rows, w.cols)),
    ]
}
