//! The elevation pyramid: the base raster resampled to Web Mercator at the native zoom `z_b`,
//! averaged overviews below it, and one amplification level per zoom above it, with the amplifier (dictionary or gradient tiles) of the zoom's band.
//!
//! Tile `(z, x, y)` is the window `[256x, 256x+256) × [256y, 256y+256)` of zoom `z`'s global pixel
//! plane. Zoom `z_b` is sampled bilinearly from the base (pixels outside the base get the world's
//! fill elevation). A tile of zoom `z > z_b` is amplified from the window of zoom `z − 1` that
//! [`Level::parent_window_for`] names, assembled from cached parent tiles; since the amplifier
//! is window-invariant, a tile computed alone equals the same window of any larger region. A tile
//! of zoom `z < z_b` is the 2×2 box average of its four children, so zooming is consistent.
//! In a biome world every biome painted over a tile amplifies the same parent window and the
//! outputs are blended by the painted weights ([`crate::biomes`]).
//!
//! Amplified pixels outside the base's coverage are the fill, exactly. Cells under water keep
//! their bed elevation; where the bed is exactly flat under water (a
//! flat lake bed), amplified levels add no detail (`calm_flat_water`). The sea and lakes of the
//! native zoom are computed here once ([`ElevationLevels::base_water`]) since they depend only on
//! the native-zoom elevation and coverage, and on the lakes the base records as flat surfaces
//! (whose beds the world sank into the base: `crate::water::take_surface_lakes`). That takes the
//! whole world's native zoom; a tile far from every surface lake of a world whose only water
//! they are is known dry without it ([`ElevationLevels::base_water_near`]), so a fresh server's
//! first tiles do not wait for it.
//!
//! **Least work on a cold chain.** When none of the parent tiles a tile needs is cached or being
//! computed (an area nobody has visited), the tile does not wait for whole parent tiles down to
//! the native zoom: its parent *window* is amplified directly from the grandparent window it
//! needs, and so on down the chain, each window a little larger than half its child (the halo
//! of `parent_window_for`) instead of whole 256² tiles: about an eighth of the work
//! for a zoom-14 tile six levels above its native zoom. Window invariance makes the values
//! bit-identical to the tile path. Once the tile is done, the parent tiles themselves are
//! computed in the background on a pool shared by every world (`Prefill`), so that the
//! neighbours that follow find their parents cached; every level is a cancellation point, and
//! an abandoned tile queues nothing.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::Instant;

use ndarray::Array2;

use moka::sync::Cache;
use terrasynth_core::landscape::{water, WaterConfig};
use terrasynth_core::raster::{box2, Grid};

use terrasynth_core::synth::{AnyAmplifier, Field, LayerAtoms, Level, Window};

use crate::biomes::{blend, Biomes};
use crate::cancel::uncancellable;
use crate::chain::Chain;
use crate::classes::ClassWeights;
use crate::coverage::CoverageLevels;
use crate::error::TileError;
use crate::extent::Extent;
use crate::pyramid::{
    assemble, for_each_tile_part, overview, recent_cache, tile_window, LevelCache, TileKey,
};
use crate::resample::{mercator_footprints, mercator_window_from_valid_grid};

/// The elevation levels of a world.
pub struct ElevationLevels {
    base: Grid,
    fill_m: f32,
    extent: Extent,
    amplifiers: Chain<AnyAmplifier>,
    /// A biome world's biomes ([`crate::biomes`]; `None`: the chain amplifies alone).
    biomes: Option<Biomes<AnyAmplifier>>,
    cache: LevelCache<Array2<f32>>,
    /// The atoms each amplified tile matched for the primitives its extra layers read
    /// ([`ElevationLevels::layer_atoms`]), so that the vegetation tile at the same address
    /// reconstructs its species layers without matching again.
    layer_atoms: Cache<TileKey, Arc<LayerAtoms>>,
    coverage: CoverageLevels,
    water: WaterConfig,
    /// The lakes the base records as flat surfaces: their levels on the base's grid, valid on
    /// their cells only (`crate::water::take_surface_lakes`; the base holds their sunk beds).
    surface_lakes: Option<Grid>,
    /// The world's class probabilities for the matching's class term.
    classes: Arc<ClassWeights>,
    base_water: OnceLock<Result<Option<Arc<BaseWater>>, TileError>>,
    /// Where the native zoom may be wet, known without the base water.
    water_reach: WaterReach,
    prefill: Prefill,
    /// This levels' own handle, for the background thread of [`Prefill`].
    me: Weak<ElevationLevels>,
    /// Level tiles synthesized by amplification (zooms above `z_b`).
    pub tiles_synthesized: AtomicU64,
    /// Windows amplified directly on a cold chain (not cached; see the module documentation).
    pub windows_synthesized: AtomicU64,
    /// Time spent computing level tiles, microseconds.
    pub synthesis_micros: AtomicU64,
}

/// The share of an elevation cache's bytes its tiles' layer atoms take (`1/LAYER_ATOMS_SHARE`):
/// a tile's atoms are 5–25 KB against its 256 KB of elevation.
const LAYER_ATOMS_SHARE: u64 = 16;

/// Most parent tiles waiting for the background thread; beyond, new ones are dropped (a request
/// computes them when it needs them).
const PREFILL_QUEUE: usize = 256;

/// Parent tiles to compute in the background after a cold chain: one job at a time per world,
/// started when tiles are queued and ending when the queue is empty.
///
/// The jobs of every world run on one process-wide pool ([`prefill_pool`]), never on rayon's
/// global pool: other threads (the export renders its tiles on the global pool) may wait for the
/// tiles a job computes, and if its amplification's parallel loops needed the global pool's
/// workers while every one of them waited for it, nothing would move (it hung an export in CI
/// before).
#[derive(Debug, Default)]
struct Prefill {
    queue: Mutex<VecDeque<TileKey>>,
    running: AtomicBool,
}

impl Prefill {
    fn queue(&self) -> std::sync::MutexGuard<'_, VecDeque<TileKey>> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// Name prefix of the background prefill's threads.
pub const PREFILL_THREAD_PREFIX: &str = "ts-prefill-";

/// The background prefill's pool, shared by every world of the process (rayon's default thread
/// count), built at the first cold chain; `None` if its threads could not be started. One pool
/// for all worlds: a server with many worlds holds no idle threads per world, and the
/// background work of all of them together never takes more than the machine's cores.
fn prefill_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("{PREFILL_THREAD_PREFIX}{i}"))
            .build()
            .ok()
    })
    .as_ref()
}

/// Largest whole-world window of the native zoom, pixels.
pub const MAX_WORLD_PIXELS: usize = 1 << 26;

/// The sea and lakes of the native zoom's whole-world window
/// ([`terrasynth_core::landscape::water`](fn@terrasynth_core::landscape::water) on the native-zoom elevation and coverage).
#[derive(Debug)]
pub struct BaseWater {
    /// The window of the native zoom's plane they cover.
    pub window: Window,
    /// Water surface level, metres; NaN where dry.
    pub level: Array2<f32>,
    /// 1 on sea cells, 0 elsewhere.
    pub sea: Array2<f32>,
}

impl BaseWater {
    /// Whether any pixel of window `w` of zoom `z` may be wet, for a world whose native zoom is
    /// `z_base`: whether the native-zoom footprint of `w`, grown by one pixel, holds a wet cell.
    /// An amplified pixel is wet only where its parent or a parent beside it is (one pixel of
    /// its zoom per level, less than one native pixel over every level), and an overview pixel
    /// only where one of its children is, so `false` means the window is dry.
    pub fn may_wet(&self, z: u8, z_base: u8, w: Window) -> bool {
        let footprint = native_footprint(z, z_base, w);
        let b = self.window;
        let (r0, r1) = (footprint.row0.max(b.row0), footprint.row1().min(b.row1()));
        let (c0, c1) = (footprint.col0.max(b.col0), footprint.col1().min(b.col1()));
        (r0..r1).any(|r| {
            (c0..c1).any(|c| !self.level[[(r - b.row0) as usize, (c - b.col0) as usize]].is_nan())
        })
    }
}

/// The native-zoom footprint of window `w` of zoom `z` (`z_base`: the native zoom), grown by
/// one pixel: the native pixels whose water may reach `w` ([`BaseWater::may_wet`]).
fn native_footprint(z: u8, z_base: u8, w: Window) -> Window {
    if z >= z_base {
        let shift = u32::from(z - z_base);
        let (c0, r0) = (w.col0 >> shift, w.row0 >> shift);
        let (c1, r1) = ((w.col1() - 1) >> shift, (w.row1() - 1) >> shift);
        Window::new(c0, r0, (c1 - c0 + 1) as usize, (r1 - r0 + 1) as usize)
    } else {
        let shift = u32::from(z_base - z);
        Window::new(
            w.col0 << shift,
            w.row0 << shift,
            w.cols << shift,
            w.rows << shift,
        )
    }
    .grown(1)
}

/// Side of the blocks of base cells whose footprints bound the surface lakes in
/// [`WaterReach::Within`]: 145 windows for the default world's lakes.
const LAKE_BLOCK: usize = 32;

/// Where a world's native zoom may be wet, known when the world is made, before the base water.
#[derive(Debug)]
enum WaterReach {
    /// A sea level or depression lakes: anywhere, as far as anyone knows before the base water.
    Anywhere,
    /// Only within these windows of the native zoom's plane (none: dry everywhere): the
    /// footprints of blocks of the base's cells that hold a surface lake's cell, the only water
    /// of the world.
    Within(Vec<Window>),
}

impl WaterReach {
    fn of(water: &WaterConfig, surface_lakes: Option<&Grid>, extent: &Extent) -> WaterReach {
        if water.sea_level_m.is_some() || water.lakes {
            return WaterReach::Anywhere;
        }
        let Some(lakes) = surface_lakes else {
            return WaterReach::Within(Vec::new());
        };
        let (rows, cols) = lakes.data.dim();
        let mut blocks = Vec::new();
        for r0 in (0..rows).step_by(LAKE_BLOCK) {
            for c0 in (0..cols).step_by(LAKE_BLOCK) {
                let (r1, c1) = ((r0 + LAKE_BLOCK).min(rows), (c0 + LAKE_BLOCK).min(cols));
                let wet = (r0..r1).any(|r| (c0..c1).any(|c| lakes.is_valid(r, c)));
                if wet {
                    blocks.push((r0..r1, c0..c1));
                }
            }
        }
        let z = extent.z_base;
        let footprints = mercator_footprints(lakes, z, extent.world_window(z), &blocks);
        WaterReach::Within(footprints.into_iter().flatten().collect())
    }
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
    /// of `amplifiers`, cached in at most `cache_bytes` bytes (the coverage overviews in at most
    /// `coverage_bytes` more), with the sea and lakes of `water`; `classes`: the class
    /// probabilities its matching reads (none: elevation only); `biomes`: a biome world's
    /// biomes, which then amplify instead of `amplifiers`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        base: Grid,
        fill_m: f32,
        extent: Extent,
        amplifiers: Chain<AnyAmplifier>,
        biomes: Option<Biomes<AnyAmplifier>>,
        cache_bytes: u64,
        coverage_bytes: u64,
        water: WaterConfig,
        surface_lakes: Option<Grid>,
        classes: Arc<ClassWeights>,
    ) -> Arc<Self> {
        let coverage = CoverageLevels::new(&base, coverage_bytes);
        let water_reach = WaterReach::of(&water, surface_lakes.as_ref(), &extent);
        Arc::new_cyclic(|me| ElevationLevels {
            base,
            fill_m,
            extent,
            amplifiers,
            biomes,
            water,
            surface_lakes,
            classes,
            base_water: OnceLock::new(),
            water_reach,
            coverage,
            cache: LevelCache::new("elevation", cache_bytes - cache_bytes / LAYER_ATOMS_SHARE),
            layer_atoms: recent_cache(cache_bytes / LAYER_ATOMS_SHARE, |a: &Arc<LayerAtoms>| {
                a.bytes()
            }),
            prefill: Prefill::default(),
            me: me.clone(),
            tiles_synthesized: AtomicU64::new(0),
            windows_synthesized: AtomicU64::new(0),
            synthesis_micros: AtomicU64::new(0),
        })
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

    /// The atoms amplified tile `(z, tx, ty)` of a world without biomes matched for the
    /// primitives its extra layers read, when its amplifier is a dictionary's and they are still
    /// cached (they are kept when the tile is computed).
    pub fn layer_atoms(&self, z: u8, tx: i64, ty: i64) -> Option<Arc<LayerAtoms>> {
        self.layer_atoms.get(&(z, tx, ty))
    }

    /// The cache of coverage overview tiles.
    pub fn coverage_cache(&self) -> &LevelCache<Array2<f32>> {
        self.coverage.cache()
    }

    /// The coverage tile `(z, tx, ty)`: the fraction of each pixel the base's valid data covers
    /// ([`crate::coverage`]).
    pub fn coverage_tile(&self, z: u8, tx: i64, ty: i64) -> Result<Arc<Array2<f32>>, TileError> {
        self.coverage.tile(&self.base, &self.extent, z, tx, ty)
    }

    /// Coverage over window `w` of zoom `z`.
    pub fn coverage_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        self.coverage.window(&self.base, &self.extent, z, w)
    }

    /// The sea and lakes of the native zoom (`None`: nothing is wet), computed once on first use
    /// (never cancelled: the result is kept).
    pub fn base_water(&self) -> Result<Option<Arc<BaseWater>>, TileError> {
        self.base_water
            .get_or_init(|| uncancellable(|| self.compute_base_water()))
            .clone()
    }

    /// The base water when window `w` of zoom `z` may be wet ([`BaseWater::may_wet`]), else
    /// `None` (dry). A window far from every surface lake of a world whose only water they are
    /// is known dry without computing the base water, which takes the whole world's native
    /// zoom: a fresh server's first tiles do not wait for it.
    pub fn base_water_near(&self, z: u8, w: Window) -> Result<Option<Arc<BaseWater>>, TileError> {
        let z_base = self.extent.z_base;
        let reachable = match &self.water_reach {
            WaterReach::Anywhere => true,
            WaterReach::Within(windows) => {
                let footprint = native_footprint(z, z_base, w);
                windows.iter().any(|l| l.intersects(&footprint))
            }
        };
        if !reachable {
            return Ok(None);
        }
        Ok(self.base_water()?.filter(|bw| bw.may_wet(z, z_base, w)))
    }

    /// Whether the base water has been computed (or read back) yet.
    pub fn base_water_known(&self) -> bool {
        self.base_water.get().is_some()
    }

    /// Sets the base water to `water`, read back from a layers file written from
    /// [`ElevationLevels::base_water`]'s result for the same inputs
    /// ([`crate::layer_file`]); no effect once it is known.
    pub fn install_base_water(&self, water: Option<Arc<BaseWater>>) {
        let _ = self.base_water.set(Ok(water));
    }

    /// The sea and lake settings the base water follows.
    pub fn water_config(&self) -> &WaterConfig {
        &self.water
    }

    fn compute_base_water(&self) -> Result<Option<Arc<BaseWater>>, TileError> {
        if !self.water.may_have_water() {
            // No sea level and no lakes: dry everywhere, without looking at the whole world.
            return Ok(None);
        }
        let z = self.extent.z_base;
        let window = self.extent.world_window(z);
        if window.len() > MAX_WORLD_PIXELS {
            return Err(TileError::WorldTooLarge(window));
        }
        let heights = self.window(z, window)?;
        let covered = self
            .coverage_window(z, window)?
            .mapv(|c| !crate::coverage::uncovered(c));
        let cells = self.extent.cell_sizes(z, window.row0, window.rows);
        let mut wet = water(&heights, &covered, &cells, &self.water);
        if let Some(lakes) = &self.surface_lakes {
            // A surface lake's level where a cell takes any of its value from the lake's cells
            // and its (sunk) bed lies below that level.
            let (surface, on_lake) =
                mercator_window_from_valid_grid(lakes, lakes.valid.as_ref(), z, window, f32::NAN);
            for (((level, &sea), &bed), (&s, (&on, &cover))) in wet
                .level
                .iter_mut()
                .zip(&wet.sea)
                .zip(&heights)
                .zip(surface.iter().zip(on_lake.iter().zip(&covered)))
            {
                if on && cover && !sea && bed < s {
                    *level = level.max(s);
                }
            }
        }
        if wet.level.iter().all(|v| v.is_nan()) {
            return Ok(None);
        }
        Ok(Some(Arc::new(BaseWater {
            window,
            level: wet.level,
            sea: wet.sea.mapv(f32::from),
        })))
    }

    /// The level tile `(z, tx, ty)`, computed once. Tile indices may lie outside `[0, 2^z)`.
    pub fn tile(&self, z: u8, tx: i64, ty: i64) -> Result<Arc<Array2<f32>>, TileError> {
        self.tile_by(z, tx, ty, Route::LeastWork)
    }

    /// Whether the background thread has parent tiles left to compute (for tests and tools that
    /// wait for a quiet world).
    pub fn prefilling(&self) -> bool {
        self.prefill.running.load(Ordering::Acquire)
    }

    fn tile_by(
        &self,
        z: u8,
        tx: i64,
        ty: i64,
        route: Route,
    ) -> Result<Arc<Array2<f32>>, TileError> {
        self.cache.get_or_compute((z, tx, ty), || {
            let start = Instant::now();
            let tile = self.compute(z, tx, ty, route);
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
        self.window_by(z, w, Route::LeastWork)
    }

    fn window_by(&self, z: u8, w: Window, route: Route) -> Result<Array2<f32>, TileError> {
        assemble(w, 1, |tx, ty| self.tile_by(z, tx, ty, route))
    }

    fn compute(&self, z: u8, tx: i64, ty: i64, route: Route) -> Result<Array2<f32>, TileError> {
        let w = tile_window(tx, ty);
        let zb = self.extent.z_base;
        if z == zb {
            // The base's validity is read once (with the coverage levels), not per tile.
            let valid = self.coverage.base_validity();
            let (values, _) = mercator_window_from_valid_grid(&self.base, valid, z, w, self.fill_m);
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
        let mut parents = Vec::new();
        let elevation = self.amplify(z, w, route, &mut parents, Some((z, tx, ty)))?;
        self.tiles_synthesized.fetch_add(1, Ordering::Relaxed);
        // The parent tiles a cold chain skipped, computed once the tile is done (an abandoned
        // tile leaves nothing behind).
        if !parents.is_empty() {
            self.queue_prefill(parents);
        }
        Ok(elevation)
    }

    /// Window `w` of amplified zoom `z`, from the parent window it needs; the parent tiles a
    /// cold chain skipped are added to `skipped`. Each level is a cancellation point. `tile`:
    /// the key of the tile `w` is, whose layer atoms a dictionary amplifier keeps.
    fn amplify(
        &self,
        z: u8,
        w: Window,
        route: Route,
        skipped: &mut Vec<TileKey>,
        tile: Option<TileKey>,
    ) -> Result<Array2<f32>, TileError> {
        let (mut out, parent) = match &self.biomes {
            None => {
                let amplifier = self.amplifiers.at(z);
                let need = amplifier.parent_window_for(w);
                let parent = self.parent_window(z - 1, need, route, skipped)?;
                if crate::cancel::is_cancelled() {
                    return Err(TileError::Cancelled);
                }
                // The world's class probabilities, for a dictionary's class term (none:
                // elevation only).
                let layers = match amplifier {
                    AnyAmplifier::Dictionary(_) => self.classes.indicator_window(z - 1, need),
                    AnyAmplifier::Gradient(_) => Vec::new(),
                };
                let parent = Field {
                    window: need,
                    elevation: parent,
                    layers,
                };
                let cell = self.extent.level_cell_m(z - 1) as f32;
                let field = match (amplifier, tile) {
                    (AnyAmplifier::Dictionary(a), Some(key)) => {
                        let (field, atoms) = a.amplify_keeping_atoms(&parent, w, cell)?;
                        self.layer_atoms.insert(key, Arc::new(atoms));
                        field
                    }
                    _ => amplifier.amplify(&parent, w, cell)?,
                };
                (field.elevation, parent)
            }
            Some(biomes) => self.amplify_biomes(biomes, z, w, route, skipped)?,
        };
        let need = parent.window;
        // Outside the coverage the elevation is the fill, exactly (no detail over no data).
        let coverage = self.coverage_window(z, w)?;
        ndarray::Zip::from(&mut out)
            .and(&*coverage)
            .for_each(|v, &c| {
                if crate::coverage::uncovered(c) {
                    *v = self.fill_m;
                }
            });
        // Only where water may lie: a world with a few lakes leaves the rest of its tiles alone.
        if let Some(bw) = self.base_water_near(z, w)? {
            calm_flat_water(
                &mut out,
                w,
                &parent.elevation,
                need,
                &bw,
                z - self.extent.z_base,
            );
        }
        Ok(out)
    }

    /// Window `w` of amplified zoom `z` of a biome world: every biome painted over `w`
    /// amplifies the same parent window, and the outputs are blended by the normalised weights
    /// ([`crate::biomes`]). Returns the blend and the parent field.
    fn amplify_biomes(
        &self,
        biomes: &Biomes<AnyAmplifier>,
        z: u8,
        w: Window,
        route: Route,
        skipped: &mut Vec<TileKey>,
    ) -> Result<(Array2<f32>, Field), TileError> {
        let need = biomes.parent_window_for(w);
        let parent = self.parent_window(z - 1, need, route, skipped)?;
        if crate::cancel::is_cancelled() {
            return Err(TileError::Cancelled);
        }
        let painted = biomes.weights.window(z, w);
        // The class probabilities, for the dictionaries' class term (the gradient amplifiers
        // of elevation drop extra layers).
        let any_dictionary = painted
            .iter()
            .any(|(i, _)| matches!(biomes.amplifiers[*i], AnyAmplifier::Dictionary(_)));
        let layers = if any_dictionary {
            self.classes.indicator_window(z - 1, need)
        } else {
            Vec::new()
        };
        let parent = Field {
            window: need,
            elevation: parent,
            layers,
        };
        let cell = self.extent.level_cell_m(z - 1) as f32;
        let mut outs = Vec::with_capacity(painted.len());
        for (i, _) in &painted {
            if crate::cancel::is_cancelled() {
                return Err(TileError::Cancelled);
            }
            outs.push(biomes.amplifiers[*i].amplify(&parent, w, cell)?.elevation);
        }
        let pairs: Vec<_> = painted.iter().map(|(_, wt)| wt).zip(&outs).collect();
        Ok((blend(&pairs), parent))
    }

    /// Window `w` of zoom `z` as a child's parent: assembled from tiles, unless the least-work
    /// route finds none of its tiles cached or in progress above the native zoom; then it is
    /// amplified directly and its tiles are added to `skipped` (for the background thread).
    fn parent_window(
        &self,
        z: u8,
        w: Window,
        route: Route,
        skipped: &mut Vec<TileKey>,
    ) -> Result<Array2<f32>, TileError> {
        if route == Route::Tiles || z <= self.extent.z_base {
            return self.window_by(z, w, route);
        }
        let mut keys = Vec::new();
        for_each_tile_part(w, |tx, ty, _, _| {
            keys.push((z, tx, ty));
            Ok(())
        })?;
        if keys.iter().any(|k| self.cache.is_known(k)) {
            return self.window(z, w);
        }
        let values = self.amplify(z, w, Route::LeastWork, skipped, None)?;
        self.windows_synthesized.fetch_add(1, Ordering::Relaxed);
        skipped.extend(keys);
        Ok(values)
    }

    /// Queues tiles for the background thread, starting it if it is not running.
    fn queue_prefill(&self, keys: Vec<TileKey>) {
        {
            let mut q = self.prefill.queue();
            for k in keys {
                if q.len() < PREFILL_QUEUE && !q.contains(&k) {
                    q.push_back(k);
                }
            }
        }
        if self.prefill.running.swap(true, Ordering::AcqRel) {
            return;
        }
        let Some(me) = self.me.upgrade() else {
            self.prefill.running.store(false, Ordering::Release);
            return;
        };
        match prefill_pool() {
            Some(pool) => pool.spawn(move || me.run_prefill()),
            None => {
                // No threads: requests compute the tiles when they need them.
                self.prefill.running.store(false, Ordering::Release);
                self.prefill.queue().clear();
            }
        }
    }

    /// The background job (on the prefill pool, [`prefill_pool`]): computes queued tiles by the tile route
    /// (so that their parents are cached too) until the queue is empty. Nobody can abandon this
    /// work.
    fn run_prefill(&self) {
        loop {
            let next = self.prefill.queue().pop_front();
            let Some((z, tx, ty)) = next else {
                self.prefill.running.store(false, Ordering::Release);
                // A tile queued between the pop and the store would wait for the next cold
                // chain: look once more and take the thread back if so.
                if self.prefill.queue().is_empty()
                    || self.prefill.running.swap(true, Ordering::AcqRel)
                {
                    return;
                }
                continue;
            };
            // A failure is not kept: a request asking for the tile computes it again.
            let _ = uncancellable(|| self.tile_by(z, tx, ty, Route::Tiles));
        }
    }
}

/// How a tile reaches its parent level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route {
    /// Parent tiles when any of them is known, else directly amplified windows.
    LeastWork,
    /// Parent tiles always (the background thread, which fills the caches).
    Tiles,
}

/// No detail on flat beds under water: a pixel of an amplified level whose native-zoom ancestor
/// is wet and whose parent pixel and its eight neighbours are exactly equal takes the parent's
/// value (so a flat lake bed stays flat, bit for bit, at every zoom). A function of global
/// coordinates only: window-invariant.
fn calm_flat_water(
    out: &mut Array2<f32>,
    w: Window,
    parent: &Array2<f32>,
    pw: Window,
    bw: &BaseWater,
    levels_above_base: u8,
) {
    let shift = u32::from(levels_above_base);
    let at = |a: &Array2<f32>, win: Window, gr: i64, gc: i64| -> Option<f32> {
        let (r, c) = (gr - win.row0, gc - win.col0);
        if r < 0 || c < 0 {
            return None;
        }
        a.get((r as usize, c as usize)).copied()
    };
    for ((r, c), v) in out.indexed_iter_mut() {
        let (gr, gc) = (w.row0 + r as i64, w.col0 + c as i64);
        let wet = at(&bw.level, bw.window, gr >> shift, gc >> shift).is_some_and(|l| !l.is_nan());
        if !wet {
            continue;
        }
        let (pr, pc) = (gr >> 1, gc >> 1);
        let Some(centre) = at(parent, pw, pr, pc) else {
            continue;
        };
        let flat =
            (-1..=1).all(|dr| (-1..=1).all(|dc| at(parent, pw, pr + dr, pc + dc) == Some(centre)));
        if flat {
            *v = centre;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A native zoom (8) whose only wet cell is (row 1010, column 2010) of a window from
    /// (row 1000, column 2000).
    fn one_wet_cell() -> BaseWater {
        let mut level = Array2::from_elem((40, 40), f32::NAN);
        level[[10, 10]] = 500.0;
        BaseWater {
            window: Window::new(2000, 1000, 40, 40),
            level,
            sea: Array2::zeros((40, 40)),
        }
    }

    proptest::proptest! {
        /// Every native pixel the base water can take a surface lake's level at (one that reads
        /// a lake cell: `compute_base_water`'s `on_lake`) lies in a window of the reach, so
        /// tiles outside it are dry without the base water; with a sea level or depression
        /// lakes the reach is everywhere, and without any lake nowhere.
        #[test]
        fn the_reach_of_surface_lakes_holds_every_pixel_that_reads_a_lake(
            lakes in proptest::collection::vec((0usize..146, 0usize..116, 4usize..40, 4usize..40), 1..4),
            z_base in 7u8..10,
        ) {
            use terrasynth_core::raster::{Crs, Georef};
            let (rows, cols) = (150, 120);
            let on = Array2::from_shape_fn((rows, cols), |(r, c)| {
                lakes.iter().any(|&(r0, c0, h, w)| (r0..r0 + h).contains(&r) && (c0..c0 + w).contains(&c))
            });
            let georef = Georef {
                crs: Crs::Epsg4326,
                west: 71.0,
                north: 42.5,
                pixel_width: 1.0 / 240.0,
                pixel_height: 1.0 / 240.0,
            };
            let grid = Grid {
                data: on.mapv(|l| if l { 1500.0 } else { f32::NAN }),
                georef,
                valid: Some(on),
            };
            let extent = Extent::of_base(&grid, Some(z_base), 14).unwrap();
            let surface_only = WaterConfig {
                surface_lake_min_area_m2: Some(1e6),
                ..Default::default()
            };
            let WaterReach::Within(reach) = WaterReach::of(&surface_only, Some(&grid), &extent)
            else {
                panic!("surface lakes alone reach anywhere");
            };
            let world = extent.world_window(z_base);
            let (_, reads) =
                mercator_window_from_valid_grid(&grid, grid.valid.as_ref(), z_base, world, f32::NAN);
            let mut read = 0usize;
            for ((r, c), &l) in reads.indexed_iter() {
                if l {
                    read += 1;
                    let px = Window::new(world.col0 + c as i64, world.row0 + r as i64, 1, 1);
                    proptest::prop_assert!(reach.iter().any(|w| w.contains(&px)), "{px:?}");
                }
            }
            proptest::prop_assert!(read > 0);
            let sea = WaterConfig { sea_level_m: Some(0.0), ..surface_only.clone() };
            proptest::prop_assert!(matches!(WaterReach::of(&sea, Some(&grid), &extent), WaterReach::Anywhere));
            let dry = WaterReach::of(&surface_only, None, &extent);
            proptest::prop_assert!(matches!(dry, WaterReach::Within(w) if w.is_empty()));
        }
    }

    #[test]
    fn a_window_may_be_wet_only_within_one_native_pixel_of_water() {
        let bw = one_wet_cell();
        // Native zoom: the cell itself and its neighbours' windows, not two pixels away.
        assert!(bw.may_wet(8, 8, Window::new(2010, 1010, 1, 1)));
        assert!(bw.may_wet(8, 8, Window::new(2011, 1011, 5, 5)));
        assert!(!bw.may_wet(8, 8, Window::new(2012, 1010, 5, 5)));
        // Zoom 11 (8 pixels a native pixel): a window starting on the neighbour's last column.
        assert!(bw.may_wet(11, 8, Window::new(8 * 2011 + 7, 8 * 1010, 4, 4)));
        assert!(!bw.may_wet(11, 8, Window::new(8 * 2012, 8 * 1010, 8, 8)));
        // A window ending on the column before the neighbour's.
        assert!(!bw.may_wet(11, 8, Window::new(8 * 2000, 8 * 1010, 8 * 9, 8)));
        assert!(bw.may_wet(11, 8, Window::new(8 * 2000, 8 * 1010, 8 * 9 + 1, 8)));
        // Zoom 6 (a pixel covers 4 × 4 native pixels): the overview pixel over the cell.
        assert!(bw.may_wet(6, 8, Window::new(2010 / 4, 1010 / 4, 1, 1)));
        assert!(!bw.may_wet(6, 8, Window::new(2010 / 4 + 2, 1010 / 4, 1, 1)));
        // Outside the base water's window: dry.
        assert!(!bw.may_wet(8, 8, Window::new(0, 0, 256, 256)));
    }
}
