//! The handlers' shared state: the live set of worlds (swapped whole when a world is created or
//! deleted, so a request works on a consistent snapshot without locking), the encoded-tile
//! cache, the bounded synthesis queue, the admin service and the settings.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};

use axum::body::Bytes;
use axum::http::HeaderValue;
use moka::sync::Cache;
use tokio::sync::Semaphore;

use terrasynth_tiles::{run_cancellable, CancelToken, Flights, TileError, World};

use super::admin::Admin;
use super::error::{ServerError, StartupError};
use super::metrics::Metrics;
use super::pickup::Pickup;
use super::worlds::{keep_landscape, Worlds};
use crate::config::ServerConfig;

/// Requests waiting for a synthesis slot, bounded: entering a full queue is [`ServerError::Busy`].
#[derive(Debug)]
pub struct Queue {
    waiting: AtomicUsize,
    limit: usize,
}

/// A place in the [`Queue`], released on drop.
#[derive(Debug)]
pub struct QueueSlot<'a>(&'a Queue);

impl Drop for QueueSlot<'_> {
    fn drop(&mut self) {
        self.0.waiting.fetch_sub(1, Ordering::AcqRel);
    }
}

impl Queue {
    /// A queue admitting `limit` waiting requests.
    pub fn new(limit: usize) -> Self {
        Queue {
            waiting: AtomicUsize::new(0),
            limit,
        }
    }

    /// Takes a place, or fails with [`ServerError::Busy`] when the queue is full.
    pub fn enter(&self) -> Result<QueueSlot<'_>, ServerError> {
        let prev = self.waiting.fetch_add(1, Ordering::AcqRel);
        if prev >= self.limit {
            self.waiting.fetch_sub(1, Ordering::AcqRel);
            return Err(ServerError::Busy);
        }
        Ok(QueueSlot(self))
    }
}

/// The live set of worlds, swapped as a whole when a world is created or deleted, so that a
/// request holds a consistent snapshot without locking.
#[derive(Clone, Default)]
pub struct LiveWorlds(Arc<RwLock<Arc<Worlds>>>);

impl LiveWorlds {
    /// A live set starting with `worlds`.
    pub fn new(worlds: Worlds) -> Self {
        LiveWorlds(Arc::new(RwLock::new(Arc::new(worlds))))
    }

    /// The current worlds.
    pub fn snapshot(&self) -> Arc<Worlds> {
        self.0.read().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// World `name`, if served.
    pub fn get(&self, name: &str) -> Option<Arc<World>> {
        self.snapshot().get(name).cloned()
    }

    /// Serves `world` (adding or replacing it) with its whole-world landscape layers kept in
    /// `store` *before* any request can reach it, so that a request which starts them first
    /// stores them too ([`keep_landscape`]).
    pub fn publish(&self, world: Arc<World>, store: Option<&terrasynth_store::Store>) {
        keep_landscape(&world, store);
        self.insert(world);
    }

    /// Adds (or replaces) a world.
    pub fn insert(&self, world: Arc<World>) {
        let mut guard = self.0.write().unwrap_or_else(|p| p.into_inner());
        let mut next = Worlds::clone(&guard);
        next.insert(world.name().to_string(), world);
        *guard = Arc::new(next);
    }

    /// Removes a world; whether it was served.
    pub fn remove(&self, name: &str) -> bool {
        let mut guard = self.0.write().unwrap_or_else(|p| p.into_inner());
        let mut next = Worlds::clone(&guard);
        let had = next.remove(name).is_some();
        *guard = Arc::new(next);
        had
    }
}

/// Shared state of the handlers: a snapshot of the live worlds and one shared [`Shared`].
///
/// Cloning it (which axum does for every request's `State` extractor and for each middleware
/// given the state) takes a fresh snapshot of the live worlds into [`AppState::worlds`], so
/// handlers read `state.worlds` as a plain map and see worlds created or deleted through the
/// admin API at their next request; everything else is one reference count ([`Shared`] is
/// reached through `Deref`), so the clone costs two atomic increments and a read lock.
pub struct AppState {
    /// The worlds served (a snapshot of [`Shared::live`] taken when the state was cloned).
    pub worlds: Arc<Worlds>,
    shared: Arc<Shared>,
}

/// What every request of a server shares.
#[derive(Clone)]
pub struct Shared {
    /// The live set of worlds.
    pub live: LiveWorlds,
    /// The admin API and catalogue (`None`: no store, catalogue empty, admin routes absent).
    pub admin: Option<Arc<Admin>>,
    /// Encoded tiles (and gzip-coded features) by ETag, weighed in bytes.
    pub tile_bytes: Cache<String, Bytes>,
    /// Encoded tiles being computed, by ETag: concurrent requests for one tile wait for one
    /// computation, which stops when all of them have left.
    pub tile_flights: Arc<Flights<String, Bytes>>,
    /// Concurrent tile computations.
    pub synth: Arc<Semaphore>,
    /// Requests waiting for a computation slot.
    pub queue: Arc<Queue>,
    /// `Cache-Control` of tiles.
    pub cache_control: HeaderValue,
    /// Request metrics.
    pub metrics: Arc<Metrics>,
    /// Server settings.
    pub config: Arc<ServerConfig>,
    /// Look-ups of worlds other processes created in the shared store.
    pub pickup: Arc<Pickup>,
}

impl Clone for AppState {
    fn clone(&self) -> Self {
        AppState {
            worlds: self.live.snapshot(),
            shared: self.shared.clone(),
        }
    }
}

impl std::ops::Deref for AppState {
    type Target = Shared;

    fn deref(&self) -> &Shared {
        &self.shared
    }
}

impl AppState {
    /// State serving `live` under `config`, with the admin service when given (without it the
    /// catalogue is empty and the admin routes are absent).
    pub fn new(
        live: LiveWorlds,
        admin: Option<Arc<Admin>>,
        config: &ServerConfig,
    ) -> Result<Self, StartupError> {
        let cache_control = HeaderValue::from_str(&config.cache_control).map_err(|_| {
            StartupError::Setting(format!("invalid cache_control `{}`", config.cache_control))
        })?;
        let bytes_capacity = config.encoded_cache_bytes();
        Ok(AppState {
            worlds: live.snapshot(),
            shared: Arc::new(Shared {
                live,
                admin,
                tile_bytes: Cache::builder()
                    .weigher(|k: &String, v: &Bytes| {
                        u32::try_from(k.len() + v.len() + 64).unwrap_or(u32::MAX)
                    })
                    .max_capacity(bytes_capacity)
                    .build(),
                tile_flights: Arc::new(Flights::new()),
                synth: Arc::new(Semaphore::new(config.synth_concurrency.max(1))),
                queue: Arc::new(Queue::new(config.synth_queue)),
                cache_control,
                metrics: Arc::new(Metrics::default()),
                config: Arc::new(config.clone()),
                pickup: Arc::new(Pickup::default()),
            }),
        })
    }

    /// The same state under other settings (the caches, queue and worlds stay shared only when
    /// no other clone of the state exists yet: call it before serving).
    pub fn with_config(mut self, config: ServerConfig) -> Self {
        Arc::make_mut(&mut self.shared).config = Arc::new(config);
        self
    }

    /// Runs a request's CPU work `f` on the blocking pool, never on a runtime thread: takes a
    /// place in the bounded queue (full → [`ServerError::Busy`]), waits for a synthesis permit,
    /// and runs `f` under a cancellation token that this future holds, so that synthesis `f`
    /// starts or joins stops when the client leaves or the deadline passes, unless another
    /// request still waits for it.
    pub async fn compute<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> Result<T, ServerError> + Send + 'static,
    ) -> Result<T, ServerError> {
        let token = CancelToken::new();
        let _cancel_on_drop = token.cancel_on_drop();
        let _slot = self.queue.enter()?;
        let permit = self
            .synth
            .clone()
            .acquire_owned()
            .await
            .map_err(|e| ServerError::Internal(e.to_string()))?;
        tokio::task::spawn_blocking(move || {
            let _permit = permit;
            run_cancellable(&token, f)
        })
        .await
        .map_err(|e| ServerError::Internal(e.to_string()))?
    }

    /// The bytes cached under `key` (an answer's strong ETag), or computed by `encode` through
    /// [`Self::compute`] — once for all the requests that want them at the same time — and
    /// cached. The async runtime only looks the cache up.
    pub async fn cached_bytes(
        &self,
        key: &str,
        encode: impl FnOnce() -> Result<Vec<u8>, TileError> + Send + 'static,
    ) -> Result<Bytes, ServerError> {
        if let Some(b) = self.tile_bytes.get(key) {
            return Ok(b);
        }
        let key = key.to_string();
        let cache = self.tile_bytes.clone();
        let flights = self.tile_flights.clone();
        self.compute(move || {
            flights
                .run(
                    key.clone(),
                    // A flight that ended since the lookup above may have cached it.
                    || match cache.get(&key) {
                        Some(b) => Ok(b),
                        None => encode().map(Bytes::from),
                    },
                    |b| cache.insert(key.clone(), b.clone()),
                )
                .map_err(ServerError::Tile)
        })
        .await
    }

    /// World `name` of this request's snapshot, or 404.
    pub fn world(&self, name: &str) -> Result<Arc<World>, ServerError> {
        self.worlds
            .get(name)
            .cloned()
            .ok_or_else(|| ServerError::NotFound(format!("unknown world `{name}`")))
    }

    /// The admin service, or 404 (admin disabled).
    pub fn admin(&self) -> Result<Arc<Admin>, ServerError> {
        self.admin
            .clone()
            .ok_or_else(|| ServerError::NotFound("no such resource".into()))
    }

    /// The store, when the server has one (with the admin API's catalogue).
    pub fn store(&self) -> Option<terrasynth_store::Store> {
        self.admin.as_ref().map(|a| a.catalogue.store().clone())
    }
}

/// Runs CPU- or IO-bound work on the blocking pool, never on a runtime thread.
pub async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ServerError> + Send + 'static,
) -> Result<T, ServerError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ServerError::Internal(e.to_string()))?
}
