//! The one level pyramid every layer uses: level tiles cached per `(zoom, column, row)` and
//! computed once even under concurrent requests ([`LevelCache`]; every lookup that misses is a
//! cancellation point, see [`crate::cancel`]), windows of a zoom's pixel plane
//! assembled from those tiles ([`assemble`]; [`assemble_concurrently`] computes the cold ones
//! side by side), and overview tiles reduced from their four children
//! ([`overview`]).
//!
//! A layer's tile is a stack of `f32` planes (one for elevation and drainage, one per species for
//! vegetation): [`LevelTile`] is implemented for `Array2<f32>` and `Vec<Array2<f32>>`, and every
//! cache entry is weighed in bytes so that the caches of all layers share one memory budget.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use moka::policy::EvictionPolicy;
use moka::sync::Cache;
use ndarray::{s, Array2};

use terrasynth_core::raster::reduce2x2;
use terrasynth_core::synth::Window;

use crate::cancel::{concurrently, Flights};
use crate::error::TileError;
use crate::mercator::TILE_SIZE;

/// Tile side in pixels, as a signed global coordinate.
pub const T: i64 = TILE_SIZE as i64;

/// A level tile's key: `(zoom, column, row)`. Columns and rows may lie outside `[0, 2^z)`: a
/// zoom's plane is defined everywhere (fill outside the world).
pub type TileKey = (u8, i64, i64);

/// Bytes of bookkeeping charged per cached plane on top of its values.
const PLANE_OVERHEAD: u64 = 64;

/// A cache of at most `capacity_bytes` bytes, each value weighed by `bytes`, that evicts the
/// least recently used entries and admits every new one. Level tiles are read again right after
/// they are computed, by the next step of the same request (a vegetation tile reads the drainage
/// tile and the elevation tile's atoms that were just computed; the neighbouring tiles of a
/// window are read again by the next window over them), so a new entry must get in: moka's
/// default admission (TinyLFU) turns a new entry away while the cache is full of entries read
/// more often, and the next read computes it again.
pub(crate) fn recent_cache<K, V>(
    capacity_bytes: u64,
    bytes: impl Fn(&V) -> u64 + Send + Sync + 'static,
) -> Cache<K, V>
where
    K: std::hash::Hash + Eq + Send + Sync + 'static,
    V: Clone + Send + Sync + 'static,
{
    Cache::builder()
        .weigher(move |_, v: &V| u32::try_from(bytes(v)).unwrap_or(u32::MAX))
        .max_capacity(capacity_bytes)
        .eviction_policy(EvictionPolicy::lru())
        .build()
}

/// The window of tile `(tx, ty)` on its zoom's plane.
pub fn tile_window(tx: i64, ty: i64) -> Window {
    Window::new(tx * T, ty * T, TILE_SIZE as usize, TILE_SIZE as usize)
}

/// The values a layer holds for one tile: one or more `f32` planes of the same shape.
pub trait LevelTile: Send + Sync + 'static {
    /// Number of planes.
    fn planes(&self) -> usize;
    /// Plane `k`.
    fn plane(&self, k: usize) -> &Array2<f32>;
    /// A tile from its planes (exactly [`LevelTile::planes`] of them for single-plane types).
    fn from_planes(planes: Vec<Array2<f32>>) -> Self;
    /// Bytes the tile holds in a cache.
    fn bytes(&self) -> u64 {
        (0..self.planes())
            .map(|k| self.plane(k).len() as u64 * 4 + PLANE_OVERHEAD)
            .sum::<u64>()
            .max(PLANE_OVERHEAD)
    }
}

impl LevelTile for Array2<f32> {
    fn planes(&self) -> usize {
        1
    }
    fn plane(&self, _: usize) -> &Array2<f32> {
        self
    }
    fn from_planes(planes: Vec<Array2<f32>>) -> Self {
        planes
            .into_iter()
            .next()
            .unwrap_or_else(|| Array2::zeros((0, 0)))
    }
}

impl LevelTile for Vec<Array2<f32>> {
    fn planes(&self) -> usize {
        self.len()
    }
    fn plane(&self, k: usize) -> &Array2<f32> {
        &self[k]
    }
    fn from_planes(planes: Vec<Array2<f32>>) -> Self {
        planes
    }
}

/// Hit and miss counters of a [`LevelCache`].
#[derive(Debug, Default)]
pub struct CacheStats {
    /// Tiles served from the cache.
    pub hits: AtomicU64,
    /// Tiles that had to be computed.
    pub misses: AtomicU64,
    /// Computations abandoned because nobody waited for them any more.
    pub cancelled: AtomicU64,
}

/// The `tracing` target of the level tiles' debug events: with
/// `RUST_LOG=terrasynth_tiles::levels=debug` the server logs every level tile it computes, with
/// its layer, key and wall time (including the level tiles it waited for), so that a slow
/// request can be traced to the chain it computed.
pub const LEVELS_LOG_TARGET: &str = "terrasynth_tiles::levels";

/// The level tiles of one layer of one world, weighed in bytes.
pub struct LevelCache<T: LevelTile> {
    /// The layer's name in the debug events ([`LEVELS_LOG_TARGET`]).
    layer: &'static str,
    cache: Cache<TileKey, Arc<T>>,
    flights: Flights<TileKey, Arc<T>>,
    stats: CacheStats,
}

impl<T: LevelTile> std::fmt::Debug for LevelCache<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelCache")
            .field("layer", &self.layer)
            .field("entries", &self.cache.entry_count())
            .finish_non_exhaustive()
    }
}

impl<T: LevelTile> LevelCache<T> {
    /// A cache of `layer`'s tiles holding at most `capacity_bytes` bytes of them.
    pub fn new(layer: &'static str, capacity_bytes: u64) -> Self {
        LevelCache {
            layer,
            cache: recent_cache(capacity_bytes, |v: &Arc<T>| v.bytes()),
            flights: Flights::new(),
            stats: CacheStats::default(),
        }
    }

    /// Tile `key` from the cache, or computed by `compute` (once, even when several threads ask
    /// for it at the same time; the others wait for that computation). A miss is a cancellation
    /// point: when everyone who wants this tile has left, it fails with
    /// [`TileError::Cancelled`] instead of computing it, and a computation abandoned half-way
    /// caches nothing.
    pub fn get_or_compute(
        &self,
        key: TileKey,
        compute: impl FnOnce() -> Result<T, TileError>,
    ) -> Result<Arc<T>, TileError> {
        if let Some(t) = self.cache.get(&key) {
            self.stats.hits.fetch_add(1, Ordering::Relaxed);
            return Ok(t);
        }
        let r = self.flights.run(
            key,
            || {
                // Another flight may have finished it between the lookup and now.
                if let Some(t) = self.cache.get(&key) {
                    return Ok(t);
                }
                self.stats.misses.fetch_add(1, Ordering::Relaxed);
                let started = Instant::now();
                let r = compute().map(Arc::new);
                log_computed(self.layer, key, started, &r);
                r
            },
            |t| self.cache.insert(key, t.clone()),
        );
        if matches!(r, Err(TileError::Cancelled)) {
            self.stats.cancelled.fetch_add(1, Ordering::Relaxed);
        }
        r
    }

    /// Whether tile `key` is cached or being computed right now (so that asking for it costs at
    /// most a wait, not a computation).
    pub fn is_known(&self, key: &TileKey) -> bool {
        self.cache.contains_key(key) || self.flights.is_running(key)
    }

    /// Bytes currently held.
    pub fn weighted_size(&self) -> u64 {
        self.cache.run_pending_tasks();
        self.cache.weighted_size()
    }

    /// The hit and miss counters.
    pub fn stats(&self) -> &CacheStats {
        &self.stats
    }
}

/// Row and column ranges of a tile part: `(rows, cols)`.
pub type Part = (Range<usize>, Range<usize>);

/// Calls `f(tx, ty, src, dst)` for every tile `(tx, ty)` meeting window `w` of a zoom's pixel
/// plane, with the ranges of the intersection inside the tile (`src`) and inside `w` (`dst`), in
/// row-major tile order.
pub fn for_each_tile_part(
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

/// Window `w` of a zoom's plane with `planes` planes, copied from the tiles `tile(tx, ty)`
/// returns. Because tiles are windows of one plane, the result does not depend on which tiles
/// were cached before.
pub fn assemble<T: LevelTile>(
    w: Window,
    planes: usize,
    mut tile: impl FnMut(i64, i64) -> Result<Arc<T>, TileError>,
) -> Result<T, TileError> {
    let mut out: Vec<Array2<f32>> = (0..planes)
        .map(|_| Array2::zeros((w.rows, w.cols)))
        .collect();
    for_each_tile_part(w, |tx, ty, src, dst| {
        let t = tile(tx, ty)?;
        for (k, o) in out.iter_mut().enumerate().take(t.planes()) {
            o.slice_mut(s![dst.0.clone(), dst.1.clone()])
                .assign(&t.plane(k).slice(s![src.0.clone(), src.1.clone()]));
        }
        Ok(())
    })?;
    Ok(T::from_planes(out))
}

/// [`assemble`], with the tiles that are neither cached nor being computed (`known` is false)
/// computed concurrently ([`concurrently`]): the parent tiles of a cold landscape tile are
/// independent chains, each mostly sequential (priority-flood, D8), so one thread each keeps
/// every core busy. Values are the same as [`assemble`]'s: a tile is a pure function of its key.
pub fn assemble_concurrently<T: LevelTile>(
    w: Window,
    planes: usize,
    known: impl Fn(i64, i64) -> bool,
    tile: impl Fn(i64, i64) -> Result<Arc<T>, TileError> + Sync,
) -> Result<T, TileError> {
    let mut cold = Vec::new();
    for_each_tile_part(w, |tx, ty, _, _| {
        if !known(tx, ty) {
            cold.push((tx, ty));
        }
        Ok(())
    })?;
    if cold.len() < 2 {
        return assemble(w, planes, tile);
    }
    let mut fetched = Vec::with_capacity(cold.len());
    for (key, r) in cold
        .iter()
        .zip(concurrently(&cold, |&(tx, ty)| tile(tx, ty)))
    {
        fetched.push((*key, r?));
    }
    assemble(w, planes, |tx, ty| {
        match fetched.iter().find(|(key, _)| *key == (tx, ty)) {
            Some((_, t)) => Ok(t.clone()),
            None => tile(tx, ty),
        }
    })
}

/// The debug event of one level tile's computation (`RUST_LOG=terrasynth_tiles::levels=debug`):
/// the layer, the key, the wall time in milliseconds from its start (the level tiles it waited
/// for included) and how it ended.
fn log_computed<T>(
    layer: &'static str,
    (z, x, y): TileKey,
    started: Instant,
    r: &Result<T, TileError>,
) {
    let ms = (started.elapsed().as_secs_f64() * 1e5).round() / 100.0;
    match r {
        Ok(_) => {
            tracing::debug!(target: LEVELS_LOG_TARGET, layer, z, x, y, ms, "level tile computed")
        }
        Err(TileError::Cancelled) => {
            tracing::debug!(target: LEVELS_LOG_TARGET, layer, z, x, y, ms, "level tile cancelled")
        }
        Err(e) => {
            tracing::debug!(target: LEVELS_LOG_TARGET, layer, z, x, y, ms, error = %e, "level tile failed")
        }
    }
}

/// An overview tile: each of its `planes` planes is made of its four children's 2×2 blocks
/// reduced by `reduce` (the box average for quantities that average, the maximum for drainage).
/// `child(cx, cy)` returns `None` for a child outside the world, whose quarter keeps `fill`.
pub fn overview<T: LevelTile>(
    tx: i64,
    ty: i64,
    planes: usize,
    fill: f32,
    reduce: fn([f32; 4]) -> f32,
    mut child: impl FnMut(i64, i64) -> Result<Option<Arc<T>>, TileError>,
) -> Result<T, TileError> {
    let n = TILE_SIZE as usize;
    let half = n / 2;
    let mut out: Vec<Array2<f32>> = (0..planes)
        .map(|_| Array2::from_elem((n, n), fill))
        .collect();
    for (dy, dx) in [(0i64, 0i64), (0, 1), (1, 0), (1, 1)] {
        let Some(c) = child(2 * tx + dx, 2 * ty + dy)? else {
            continue;
        };
        let (r0, c0) = (dy as usize * half, dx as usize * half);
        for (k, o) in out.iter_mut().enumerate().take(c.planes()) {
            reduce2x2(
                c.plane(k).view(),
                o.slice_mut(s![r0..r0 + half, c0..c0 + half]),
                reduce,
            );
        }
    }
    Ok(T::from_planes(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasynth_core::raster::box2;

    fn ramp(tx: i64, ty: i64) -> Array2<f32> {
        Array2::from_shape_fn((256, 256), |(r, c)| {
            ((ty * T + r as i64) * 1000 + tx * T + c as i64) as f32
        })
    }

    #[test]
    fn assembled_windows_equal_the_plane() {
        // A window straddling four tiles (with negative coordinates) equals the plane's values.
        let w = Window::new(-10, 250, 30, 20);
        let got: Array2<f32> = assemble(w, 1, |tx, ty| Ok(Arc::new(ramp(tx, ty)))).unwrap();
        for r in 0..w.rows {
            for c in 0..w.cols {
                let want = ((w.row0 + r as i64) * 1000 + w.col0 + c as i64) as f32;
                assert_eq!(got[[r, c]], want);
            }
        }
    }

    #[test]
    fn concurrently_assembled_windows_equal_the_plane() {
        // Twelve tiles (4 × 3), two of them known (fetched on the calling thread), the others each on a
        // thread of its own; every value where `assemble` puts it.
        let w = Window::new(-300, 200, 600, 400);
        let known = |tx: i64, ty: i64| (tx, ty) == (0, 1) || (tx, ty) == (-2, 0);
        let threads = std::sync::Mutex::new(Vec::new());
        let got: Array2<f32> = assemble_concurrently(w, 1, known, |tx, ty| {
            if !known(tx, ty) {
                threads
                    .lock()
                    .unwrap()
                    .push(format!("{:?}", std::thread::current().id()));
            }
            Ok(Arc::new(ramp(tx, ty)))
        })
        .unwrap();
        let want: Array2<f32> = assemble(w, 1, |tx, ty| Ok(Arc::new(ramp(tx, ty)))).unwrap();
        assert_eq!(got, want);
        let mut ids = threads.into_inner().unwrap();
        assert_eq!(ids.len(), 10, "each cold tile computed once");
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), 10, "one thread per cold tile");
        // A failing tile fails the window.
        let failed: Result<Array2<f32>, TileError> = assemble_concurrently(
            w,
            1,
            |_, _| false,
            |tx, ty| {
                if (tx, ty) == (1, 2) {
                    Err(TileError::Cancelled)
                } else {
                    Ok(Arc::new(ramp(tx, ty)))
                }
            },
        );
        assert_eq!(failed, Err(TileError::Cancelled));
    }

    #[test]
    fn overviews_reduce_children_and_fill_missing_ones() {
        let child = |cx: i64, cy: i64| -> Result<Option<Arc<Array2<f32>>>, TileError> {
            Ok((cx, cy) != (1, 1)).map(|keep| {
                keep.then(|| Arc::new(Array2::from_elem((256, 256), (cx + 2 * cy) as f32)))
            })
        };
        let o: Array2<f32> = overview(0, 0, 1, -5.0, box2, child).unwrap();
        assert_eq!(o[[0, 0]], 0.0);
        assert_eq!(o[[0, 200]], 1.0);
        assert_eq!(o[[200, 0]], 2.0);
        assert_eq!(o[[200, 200]], -5.0);
    }

    #[test]
    fn the_cache_computes_once_and_weighs_bytes() {
        let cache: LevelCache<Vec<Array2<f32>>> = LevelCache::new("test", 1 << 30);
        let mut calls = 0;
        for _ in 0..3 {
            let t = cache
                .get_or_compute((3, 1, 2), || {
                    calls += 1;
                    Ok(vec![Array2::zeros((256, 256)); 2])
                })
                .unwrap();
            assert_eq!(t.len(), 2);
        }
        assert_eq!(calls, 1);
        assert_eq!(cache.stats().hits.load(Ordering::Relaxed), 2);
        assert_eq!(cache.weighted_size(), 2 * (256 * 256 * 4 + 64));
        let err = cache.get_or_compute((3, 0, 0), || Err(TileError::Encode("x".into())));
        assert!(err.is_err());
    }

    #[test]
    fn a_full_cache_keeps_the_tile_it_just_computed() {
        // Room for four 16²-tiles. Four tiles read often fill it; a new tile read right after it
        // was computed must come from the cache (the least recently read tile goes instead), as a
        // request's next step reads the level tiles its previous step just computed.
        let tile_bytes = 16 * 16 * 4 + PLANE_OVERHEAD;
        let cache: LevelCache<Array2<f32>> = LevelCache::new("test", 4 * tile_bytes);
        let tile = |v: f32| Ok(Array2::from_elem((16, 16), v));
        for _ in 0..5 {
            for k in 0..4 {
                cache.get_or_compute((9, k, 0), || tile(k as f32)).unwrap();
                cache.cache.run_pending_tasks();
            }
        }
        assert_eq!(cache.stats().misses.load(Ordering::Relaxed), 4);
        let mut calls = 0;
        for _ in 0..2 {
            let t = cache
                .get_or_compute((9, 7, 7), || {
                    calls += 1;
                    tile(7.0)
                })
                .unwrap();
            assert_eq!(t[[3, 3]], 7.0);
            cache.cache.run_pending_tasks();
        }
        assert_eq!(calls, 1, "the new tile was turned away and computed again");
        assert!(cache.weighted_size() <= 4 * tile_bytes);
        // The least recently read of the four went.
        let mut recomputed = 0;
        cache
            .get_or_compute((9, 0, 0), || {
                recomputed += 1;
                tile(0.0)
            })
            .unwrap();
        assert_eq!(recomputed, 1);
    }
}
