//! A world's tile pyramid: the base raster resampled to Web Mercator at its native zoom `z_b`,
//! averaged overviews below it, and one amplification level per zoom above it.
//!
//! Tile `(z, x, y)` is the window `[256x, 256x+256) × [256y, 256y+256)` of zoom `z`'s global pixel
//! plane. Zoom `z_b` is sampled bilinearly from the base (pixels outside the base coverage get the
//! world's fill elevation). A tile of zoom `z > z_b` is amplified from the window of zoom `z − 1`
//! that [`Amplifier::parent_window_for`] names, assembled from cached parent tiles; since the
//! amplifier is window-invariant, a tile computed alone equals the same window of any larger
//! region. A tile of zoom `z < z_b` is the 2×2 box average of its four children, so zooming is
//! consistent. Level tiles are cached per `(zoom, x, y)` in a moka cache weighed in bytes, and
//! concurrent requests for one tile compute it once.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use moka::sync::Cache;
use ndarray::{s, Array2};

use super::error::TileError;
use super::layers::BaseLayers;
use super::mercator::{ground_cell_m, lonlat_to_global_pixel, validate_tile, TILE_SIZE};
use super::resample::mercator_window_from_grid;
use crate::dictionary::{Dictionary, MatchWeights};
use crate::landscape::LandscapeConfig;
use crate::raster::{CellSizes, Grid};
use crate::synth::{Amplifier, Field, Window};

const T: i64 = TILE_SIZE as i64;
/// A level tile's key: `(zoom, column, row)`.
type TileKey = (u8, i64, i64);
/// Bytes held by one cached 256×256 `f32` tile (plus bookkeeping).
const TILE_BYTES: u32 = TILE_SIZE * TILE_SIZE * 4 + 64;

/// Everything a world is made of, resolved: its base, dictionary and settings.
#[derive(Clone, Debug)]
pub struct WorldParts {
    /// URL name of the world.
    pub name: String,
    /// Human title.
    pub title: String,
    /// Attribution shown by map clients.
    pub attribution: String,
    /// The georeferenced base raster (EPSG:4326 or EPSG:3857).
    pub base: Grid,
    /// Native zoom of the base; `None` derives it from the base's cell size.
    pub z_base: Option<u8>,
    /// Deepest zoom served.
    pub max_zoom: u8,
    /// Elevation (m) of pixels outside the base coverage.
    pub fill_m: f32,
    /// The amplification dictionary (used at every level).
    pub dictionary: Arc<Dictionary>,
    /// Content id of the dictionary.
    pub dictionary_id: String,
    /// Matching weights.
    pub weights: MatchWeights,
    /// The world's memory budget, bytes: its whole-world landscape layers first, the rest (at
    /// least a quarter) for its level-tile caches: half for elevation, a quarter each for
    /// vegetation and drainage.
    pub cache_bytes: u64,
    /// Landscape layers: species niches, materials, drainage style.
    pub landscape: LandscapeConfig,
}

/// Counters a world keeps for `/metrics`.
#[derive(Debug, Default)]
pub struct WorldStats {
    /// Level tiles served from the cache.
    pub cache_hits: AtomicU64,
    /// Level tiles that had to be computed.
    pub cache_misses: AtomicU64,
    /// Level tiles synthesized by amplification (zooms above `z_b`).
    pub tiles_synthesized: AtomicU64,
    /// Total seconds spent computing level tiles, in microseconds.
    pub synthesis_micros: AtomicU64,
}

/// A world ready to serve tiles.
pub struct World {
    name: String,
    title: String,
    attribution: String,
    base: Grid,
    z_base: u8,
    max_zoom: u8,
    fill_m: f32,
    dictionary_id: String,
    amplifier: Amplifier,
    /// `(w, s, e, n)` in degrees.
    bounds: [f64; 4],
    /// Latitude at which per-level metric cell sizes are taken (the base's centre).
    ref_lat: f64,
    cache: Cache<(u8, i64, i64), Arc<Array2<f32>>>,
    stats: WorldStats,
    fingerprint: String,
    /// Landscape configuration.
    pub(super) landscape: Arc<LandscapeConfig>,
    /// The amplifier reconstructing the species layers from the same matches as elevation.
    pub(super) layer_amplifier: Amplifier,
    /// Whole-world layers at the native zoom (global drainage, base vegetation), computed on
    /// first use.
    pub(super) base_layers: OnceLock<Result<Arc<BaseLayers>, TileError>>,
    /// Vegetation level tiles (one grid per species), weighed in bytes.
    pub(super) vegetation_cache: Cache<TileKey, Arc<Vec<Array2<f32>>>>,
    /// Drainage level tiles (upstream area, m²), weighed in bytes.
    pub(super) drainage_cache: Cache<(u8, i64, i64), Arc<Array2<f32>>>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("name", &self.name)
            .field("z_base", &self.z_base)
            .field("max_zoom", &self.max_zoom)
            .finish_non_exhaustive()
    }
}

/// Bounds `(w, s, e, n)` in degrees of a georeferenced grid.
fn lonlat_bounds(g: &Grid) -> [f64; 4] {
    let (w, s, e, n) = g.georef.bounds(g.cols(), g.rows());
    match g.georef.crs {
        crate::raster::Crs::Epsg4326 => [w, s, e, n],
        crate::raster::Crs::Epsg3857 => {
            let (w, s) = super::mercator::mercator_to_lonlat(w, s);
            let (e, n) = super::mercator::mercator_to_lonlat(e, n);
            [w, s, e, n]
        }
    }
}

/// Hex SHA-256 of everything that determines a world's tiles.
fn fingerprint(parts: &WorldParts, z_base: u8) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(format!(
        "|{:?}|{}|{}|{}|{}|{:?}|",
        parts.base.georef,
        parts.dictionary_id,
        z_base,
        parts.max_zoom,
        parts.fill_m.to_bits(),
        parts.weights
    ));
    h.update(format!("{:?}|", parts.landscape));
    for v in parts.base.data.iter() {
        h.update(v.to_bits().to_le_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

impl World {
    /// Builds a world from its parts (resolving `z_base` from the base's cell size when absent).
    pub fn new(parts: WorldParts) -> Result<World, TileError> {
        let bounds = lonlat_bounds(&parts.base);
        let ref_lat = 0.5 * (bounds[1] + bounds[3]);
        let z_base = match parts.z_base {
            Some(z) => z,
            None => {
                let cells = parts.base.georef.cell_sizes(parts.base.rows());
                super::mercator::native_zoom(cells.mean_cell(), ref_lat)
            }
        };
        if parts.max_zoom < z_base || parts.max_zoom > 24 {
            return Err(TileError::Synthesis(format!(
                "max_zoom {} must lie between the native zoom {z_base} and 24",
                parts.max_zoom
            )));
        }
        let amplifier = Amplifier::new(parts.dictionary.clone(), &parts.weights)
            .map_err(|e| TileError::Synthesis(e.to_string()))?
            .without_layers();
        parts
            .landscape
            .validate()
            .map_err(|e| TileError::Synthesis(e.to_string()))?;
        let layer_amplifier = Amplifier::new(parts.dictionary.clone(), &parts.weights)
            .map_err(|e| TileError::Synthesis(e.to_string()))?
            .with_only_layers(&parts.landscape.species_names());
        let fingerprint = fingerprint(&parts, z_base);
        // The whole-world landscape layers come out of the same budget; the level caches keep
        // at least a quarter of it.
        let base_bytes = super::layers::base_layer_bytes(
            super::layers::base_layer_window(z_base, bounds),
            parts.landscape.species.len(),
        );
        let budget = parts
            .cache_bytes
            .saturating_sub(base_bytes)
            .max(parts.cache_bytes / 4);
        let cache = Cache::builder()
            .weigher(|_, _| TILE_BYTES)
            .max_capacity(budget / 2)
            .build();
        let vegetation_cache = Cache::builder()
            .weigher(|_, v: &Arc<Vec<Array2<f32>>>| {
                u32::try_from(v.len().max(1)).map_or(u32::MAX, |n| n.saturating_mul(TILE_BYTES))
            })
            .max_capacity(budget / 4)
            .build();
        let drainage_cache = Cache::builder()
            .weigher(|_, _| TILE_BYTES)
            .max_capacity(budget / 4)
            .build();
        Ok(World {
            name: parts.name,
            title: parts.title,
            attribution: parts.attribution,
            base: parts.base,
            z_base,
            max_zoom: parts.max_zoom,
            fill_m: parts.fill_m,
            dictionary_id: parts.dictionary_id,
            amplifier,
            bounds,
            ref_lat,
            cache,
            stats: WorldStats::default(),
            fingerprint,
            landscape: Arc::new(parts.landscape),
            layer_amplifier,
            base_layers: OnceLock::new(),
            vegetation_cache,
            drainage_cache,
        })
    }

    /// A hash of everything that determines this world's tiles (base values and georeference,
    /// dictionary id, weights, zooms, fill, crate version): tile ETags derive from it.
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }

    /// URL name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Human title.
    pub fn title(&self) -> &str {
        &self.title
    }

    /// Attribution for map clients.
    pub fn attribution(&self) -> &str {
        &self.attribution
    }

    /// Native zoom of the base.
    pub fn z_base(&self) -> u8 {
        self.z_base
    }

    /// Deepest zoom served.
    pub fn max_zoom(&self) -> u8 {
        self.max_zoom
    }

    /// Shallowest zoom served (always 0: overviews reach the whole globe).
    pub fn min_zoom(&self) -> u8 {
        0
    }

    /// Fill elevation outside the base coverage, metres.
    pub fn fill_m(&self) -> f32 {
        self.fill_m
    }

    /// Bounds `[w, s, e, n]` in degrees.
    pub fn bounds(&self) -> [f64; 4] {
        self.bounds
    }

    /// Centre `[lon, lat, zoom]` for map clients (zoom: one above the native zoom).
    pub fn center(&self) -> [f64; 3] {
        [
            0.5 * (self.bounds[0] + self.bounds[2]),
            self.ref_lat,
            f64::from((self.z_base + 2).min(self.max_zoom)),
        ]
    }

    /// Content ids of the dictionaries of the synthesis chain.
    pub fn dictionary_ids(&self) -> Vec<String> {
        vec![self.dictionary_id.clone()]
    }

    /// The counters of this world.
    pub fn stats(&self) -> &WorldStats {
        &self.stats
    }

    /// Bytes currently held by the level-tile caches (elevation, vegetation, drainage).
    pub fn cache_bytes(&self) -> u64 {
        self.cache.run_pending_tasks();
        self.vegetation_cache.run_pending_tasks();
        self.drainage_cache.run_pending_tasks();
        self.cache.weighted_size()
            + self.vegetation_cache.weighted_size()
            + self.drainage_cache.weighted_size()
    }

    /// Checks that tile `(z, x, y)` exists and intersects the world: `OutOfRange`, `ZoomTooDeep`
    /// or `OutsideWorld` otherwise.
    pub fn check_tile(&self, z: u8, x: u32, y: u32) -> Result<(), TileError> {
        validate_tile(z, x, y, self.max_zoom)?;
        let (px0, py0) = lonlat_to_global_pixel(z, self.bounds[0], self.bounds[3]);
        let (px1, py1) = lonlat_to_global_pixel(z, self.bounds[2], self.bounds[1]);
        let (x0, x1) = (f64::from(x) * T as f64, f64::from(x + 1) * T as f64);
        let (y0, y1) = (f64::from(y) * T as f64, f64::from(y + 1) * T as f64);
        if x1 <= px0 || x0 >= px1 || y1 <= py0 || y0 >= py1 {
            return Err(TileError::OutsideWorld { z, x, y });
        }
        Ok(())
    }

    /// Metric ground cell size of zoom `z`'s pixels at the world's reference latitude (the value
    /// the amplifier's slope term uses for every tile of that zoom).
    pub fn level_cell_m(&self, z: u8) -> f64 {
        ground_cell_m(z, self.ref_lat)
    }

    /// Per-row metric cell sizes of the rows `[row0, row0 + rows)` of zoom `z`'s pixel plane
    /// (true Mercator scale at each row's latitude), for slopes and hillshades.
    pub fn cell_sizes(&self, z: u8, row0: i64, rows: usize) -> CellSizes {
        super::mercator::plane_cell_sizes(z, row0, rows)
    }

    /// The elevation tile `(z, x, y)`, 256×256 metres, after [`World::check_tile`]. CPU-bound:
    /// call it off the async runtime.
    pub fn elevation_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<Array2<f32>>, TileError> {
        self.check_tile(z, x, y)?;
        self.level_tile(z, i64::from(x), i64::from(y))
    }

    /// An arbitrary window of zoom `z`'s pixel plane (columns `col0..col0+cols`, rows
    /// `row0..row0+rows`), assembled from level tiles. `z` may exceed `max_zoom` by one (for
    /// 512-px tiles at the deepest zoom).
    pub fn elevation_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        if z > self.max_zoom.saturating_add(1) {
            return Err(TileError::ZoomTooDeep {
                z,
                max: self.max_zoom,
            });
        }
        let mut out = Array2::<f32>::zeros((w.rows, w.cols));
        for_each_tile_part(w, |tx, ty, src, dst| {
            let tile = self.level_tile(z, tx, ty)?;
            out.slice_mut(s![dst.0, dst.1])
                .assign(&tile.slice(s![src.0, src.1]));
            Ok(())
        })?;
        Ok(out)
    }

    /// The level tile `(z, tx, ty)` from the cache, computing it (once, even under concurrent
    /// requests) when absent. Tile indices may lie outside `[0, 2^z)`: the plane is defined
    /// everywhere (fill outside the base).
    pub(super) fn level_tile(
        &self,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Array2<f32>>, TileError> {
        let key = (z, tx, ty);
        if let Some(t) = self.cache.get(&key) {
            self.stats.cache_hits.fetch_add(1, Ordering::Relaxed);
            return Ok(t);
        }
        self.cache
            .try_get_with(key, || {
                self.stats.cache_misses.fetch_add(1, Ordering::Relaxed);
                let start = Instant::now();
                let tile = self.compute_tile(z, tx, ty)?;
                self.stats
                    .synthesis_micros
                    .fetch_add(start.elapsed().as_micros() as u64, Ordering::Relaxed);
                Ok::<_, TileError>(Arc::new(tile))
            })
            .map_err(|e: Arc<TileError>| (*e).clone())
    }

    /// Computes a level tile (not cached).
    fn compute_tile(&self, z: u8, tx: i64, ty: i64) -> Result<Array2<f32>, TileError> {
        let w = Window::new(tx * T, ty * T, T as usize, T as usize);
        if z == self.z_base {
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
        if z < self.z_base {
            return self.overview_tile(z, tx, ty);
        }
        let need = self.amplifier.parent_window_for(w);
        let parent = Field::elevation_only(need, self.elevation_window(z - 1, need)?);
        let field = self
            .amplifier
            .amplify(&parent, w, self.level_cell_m(z - 1) as f32)
            .map_err(|e| TileError::Synthesis(e.to_string()))?;
        self.stats.tiles_synthesized.fetch_add(1, Ordering::Relaxed);
        Ok(field.elevation)
    }

    /// Whether tile `(z, tx, ty)` lies wholly outside the base coverage (all fill).
    pub(super) fn tile_outside(&self, z: u8, tx: i64, ty: i64) -> bool {
        if tx < 0 || ty < 0 || tx >= (1i64 << z) || ty >= (1i64 << z) {
            return true;
        }
        self.check_tile(z, tx as u32, ty as u32).is_err()
    }

    /// A tile below the native zoom: the 2×2 box average of its children.
    fn overview_tile(&self, z: u8, tx: i64, ty: i64) -> Result<Array2<f32>, TileError> {
        let half = (T / 2) as usize;
        let mut out = Array2::<f32>::from_elem((T as usize, T as usize), self.fill_m);
        for (dy, dx) in [(0i64, 0i64), (0, 1), (1, 0), (1, 1)] {
            let (cx, cy) = (2 * tx + dx, 2 * ty + dy);
            if self.tile_outside(z + 1, cx, cy) {
                continue;
            }
            let child = self.level_tile(z + 1, cx, cy)?;
            let (r0, c0) = (dy as usize * half, dx as usize * half);
            for r in 0..half {
                for c in 0..half {
                    let (a, b) = (child[[2 * r, 2 * c]], child[[2 * r, 2 * c + 1]]);
                    let (d, e) = (child[[2 * r + 1, 2 * c]], child[[2 * r + 1, 2 * c + 1]]);
                    out[[r0 + r, c0 + c]] = (a + b + d + e) * 0.25;
                }
            }
        }
        Ok(out)
    }
}

/// Row and column ranges of a tile part: `(rows, cols)`.
pub(super) type Part = (Range<usize>, Range<usize>);

/// Calls `f(tx, ty, src, dst)` for every tile `(tx, ty)` meeting window `w` of a zoom's pixel
/// plane, with the ranges of the intersection inside the tile (`src`) and inside `w` (`dst`), in
/// row-major tile order.
pub(super) fn for_each_tile_part(
    w: Window,
    mut f: impl FnMut(i64, i64, Part, Part) -> Result<(), TileError>,
) -> Result<(), TileError> {
    if w.is_empty() {
        return Ok(());
    }
    let tx0 = w.col0.div_euclid(T);
    let tx1 = (w.col1() - 1).div_euclid(T);
    let ty0 = w.row0.div_euclid(T);
    let ty1 = (w.row1() - 1).div_euclid(T);
    for ty in ty0..=ty1 {
        for tx in tx0..=tx1 {
            // Intersection of the tile with the window, in global pixels.
            let c0 = (tx * T).max(w.col0);
            let c1 = (tx * T + T).min(w.col1());
            let r0 = (ty * T).max(w.row0);
            let r1 = (ty * T + T).min(w.row1());
            let src = (
                (r0 - ty * T) as usize..(r1 - ty * T) as usize,
                (c0 - tx * T) as usize..(c1 - tx * T) as usize,
            );
            let dst = (
                (r0 - w.row0) as usize..(r1 - w.row0) as usize,
                (c0 - w.col0) as usize..(c1 - w.col0) as usize,
            );
            f(tx, ty, src, dst)?;
        }
    }
    Ok(())
}
