//! The HTTP server: an axum router over the worlds ([`app`]), its handlers ([`tiles`], [`meta`],
//! the admin API and dictionary catalogue in [`admin`]), errors as problem+json ([`error`]),
//! Prometheus metrics ([`metrics`]), world loading ([`worlds`]) and the OpenAPI description
//! ([`openapi`]). The set of worlds is dynamic (worlds are created and deleted through the admin
//! API): [`LiveWorlds`] holds it and every request works on a snapshot. CPU work (tile synthesis and encoding) runs on tokio's blocking pool
//! behind a semaphore and a bounded queue; the async runtime only moves bytes.

pub mod admin;
pub mod error;
pub mod meta;
pub mod metrics;
pub mod openapi;
pub mod tiles;
pub mod web;
pub mod worlds;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

use axum::body::Bytes;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::Response;
use axum::routing::{get, post};
use axum::serve::ListenerExt;
use axum::Router;
use moka::sync::Cache;
use tokio::sync::Semaphore;
use tower_http::compression::CompressionLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::trace::TraceLayer;

pub use error::ServerError;
pub use worlds::{load_worlds, Worlds};

use crate::config::ServerConfig;
use crate::tiles::World;

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

/// Shared state of the handlers.
///
/// Cloning it (which axum does for every request's `State` extractor) takes a fresh snapshot of
/// the live worlds into [`AppState::worlds`], so handlers read `state.worlds` as a plain map and
/// see worlds created or deleted through the admin API at their next request.
pub struct AppState {
    /// The worlds served (a snapshot of [`AppState::live`] taken when the state was cloned).
    pub worlds: Arc<Worlds>,
    /// The live set of worlds.
    pub live: LiveWorlds,
    /// The admin API and catalogue (`None`: no store, catalogue empty, admin routes absent).
    pub admin: Option<Arc<admin::Admin>>,
    /// Encoded tiles by ETag, weighed in bytes.
    pub tile_bytes: Cache<String, Bytes>,
    /// Concurrent tile computations.
    pub synth: Arc<Semaphore>,
    /// Requests waiting for a computation slot.
    pub queue: Arc<Queue>,
    /// `Cache-Control` of tiles.
    pub cache_control: HeaderValue,
    /// Request metrics.
    pub metrics: Arc<metrics::Metrics>,
    /// Server settings.
    pub config: Arc<ServerConfig>,
}

impl Clone for AppState {
    fn clone(&self) -> Self {
        AppState {
            worlds: self.live.snapshot(),
            live: self.live.clone(),
            admin: self.admin.clone(),
            tile_bytes: self.tile_bytes.clone(),
            synth: self.synth.clone(),
            queue: self.queue.clone(),
            cache_control: self.cache_control.clone(),
            metrics: self.metrics.clone(),
            config: self.config.clone(),
        }
    }
}

impl AppState {
    /// State for `worlds` under `config`, without a store: the admin API is absent.
    pub fn new(worlds: Worlds, config: &ServerConfig) -> Result<Self, ServerError> {
        Self::with_live(LiveWorlds::new(worlds), None, config)
    }

    /// State with the admin API: opens the store at `config.server.store_dir`, starts the build
    /// workers and adds the worlds stored by earlier runs to the configured `worlds`. The admin
    /// routes are mounted only when a token is configured.
    pub fn with_admin(worlds: Worlds, config: &crate::config::Config) -> Result<Self, ServerError> {
        let live = LiveWorlds::new(worlds);
        let admin = admin::Admin::open(config, live.clone())?;
        Self::with_live(live, Some(Arc::new(admin)), &config.server)
    }

    fn with_live(
        live: LiveWorlds,
        admin: Option<Arc<admin::Admin>>,
        config: &ServerConfig,
    ) -> Result<Self, ServerError> {
        let cache_control = HeaderValue::from_str(&config.cache_control).map_err(|_| {
            ServerError::Internal(format!("invalid cache_control `{}`", config.cache_control))
        })?;
        let bytes_capacity = config.encoded_cache_bytes();
        Ok(AppState {
            worlds: live.snapshot(),
            live,
            admin,
            tile_bytes: Cache::builder()
                .weigher(|k: &String, v: &Bytes| {
                    u32::try_from(k.len() + v.len() + 64).unwrap_or(u32::MAX)
                })
                .max_capacity(bytes_capacity)
                .build(),
            synth: Arc::new(Semaphore::new(config.synth_concurrency.max(1))),
            queue: Arc::new(Queue::new(config.synth_queue)),
            cache_control,
            metrics: Arc::new(metrics::Metrics::default()),
            config: Arc::new(config.clone()),
        })
    }
}

async fn record_metrics(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = req.method().to_string();
    let resp = next.run(req).await;
    state
        .metrics
        .record(&route, &method, resp.status().as_u16(), start.elapsed());
    resp
}

async fn not_found() -> ServerError {
    ServerError::NotFound("no such resource".into())
}

fn cors(config: &ServerConfig) -> CorsLayer {
    let layer = CorsLayer::new()
        .allow_methods([Method::GET, Method::HEAD, Method::OPTIONS])
        .expose_headers([axum::http::header::ETAG]);
    if config.cors_origins.iter().any(|o| o == "*") || config.cors_origins.is_empty() {
        layer.allow_origin(AllowOrigin::any())
    } else {
        let origins: Vec<HeaderValue> = config
            .cors_origins
            .iter()
            .filter_map(|o| HeaderValue::from_str(o).ok())
            .collect();
        layer.allow_origin(origins)
    }
}

/// The router of the whole HTTP API.
pub fn app(state: AppState) -> Router {
    let timeout = Duration::from_secs(state.config.request_timeout_s.max(1));
    let upload_timeout = Duration::from_secs(state.config.upload_timeout_s.max(1));
    let json = Router::new()
        .route("/worlds", get(meta::worlds))
        .route("/dictionaries", get(admin::list_dictionaries))
        .route("/dictionaries/{id}", get(admin::get_dictionary))
        .route("/openapi.json", get(openapi::serve_spec))
        .route("/worlds/{world}", get(meta::world))
        .route("/tiles/{world}/{file}", get(meta::tilejson))
        .route("/styles/{file}", get(meta::style))
        .layer(CompressionLayer::new());
    let web = Router::new()
        .route("/", get(web::index))
        .route("/app.js", get(web::app_js))
        .route("/app.css", get(web::app_css))
        .route("/vendor/maplibre-gl/{file}", get(web::vendor))
        .layer(CompressionLayer::new());
    let admin_enabled = state.admin.as_ref().is_some_and(|a| a.enabled());
    let admin_routes = if admin_enabled {
        let max_body = state.admin.as_ref().map_or(2 << 20, |a| a.limits.max_body);
        Router::new()
            .route(
                "/admin/exemplars",
                post(admin::post_exemplar).get(admin::list_exemplars),
            )
            .route(
                "/admin/exemplars/{id}",
                get(admin::get_exemplar).delete(admin::delete_exemplar),
            )
            .route("/admin/dictionaries", post(admin::post_dictionary))
            .route(
                "/admin/dictionaries/{id}",
                axum::routing::delete(admin::delete_dictionary),
            )
            .route("/admin/jobs", get(admin::list_jobs))
            .route(
                "/admin/jobs/{id}",
                get(admin::get_job).delete(admin::cancel_job),
            )
            .route("/admin/worlds", post(admin::post_world))
            .route(
                "/admin/worlds/{name}",
                axum::routing::delete(admin::delete_world),
            )
            .route_layer(middleware::from_fn_with_state(
                state.clone(),
                admin::authorize,
            ))
            .layer(axum::extract::DefaultBodyLimit::max(max_body))
            .layer(tower_http::timeout::TimeoutLayer::with_status_code(
                StatusCode::SERVICE_UNAVAILABLE,
                upload_timeout,
            ))
    } else {
        Router::new()
    };
    Router::new()
        .route("/tiles/{world}/{layer}/{z}/{x}/{y}", get(tiles::tile))
        .route("/healthz", get(meta::healthz))
        .route("/metrics", get(meta::metrics))
        .merge(json)
        .merge(web)
        .layer(tower_http::timeout::TimeoutLayer::with_status_code(
            StatusCode::SERVICE_UNAVAILABLE,
            timeout,
        ))
        .merge(admin_routes)
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(
            state.clone(),
            record_metrics,
        ))
        .layer(tower::limit::GlobalConcurrencyLimitLayer::new(4096))
        .layer(cors(&state.config))
        .layer(TraceLayer::new_for_http())
        .with_state(state)
}

/// Waits for SIGTERM or SIGINT.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {},
        _ = term => {},
    }
    tracing::info!("shutting down");
}

/// Allocations at or above this size are mapped from the OS and given back when freed.
pub const MMAP_THRESHOLD_BYTES: usize = 512 * 1024;

/// Makes the allocator give large buffers back to the OS when they are freed. glibc otherwise
/// raises its mmap threshold after the first large free, so the transient grids of the
/// whole-world layers and of halo routing stay in the heap: measured on the load test, peak RSS
/// 777 MiB without this, 583 MiB with it, warm throughput unchanged. A no-op off glibc. Call it
/// before the server starts allocating.
pub fn return_large_buffers_to_os() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let bytes = libc::c_int::try_from(MMAP_THRESHOLD_BYTES).unwrap_or(libc::c_int::MAX);
        // SAFETY: mallopt(3) only changes allocator tuning; M_MMAP_THRESHOLD takes a size.
        let ok = unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, bytes) };
        if ok != 1 {
            tracing::debug!("mallopt(M_MMAP_THRESHOLD) refused");
        }
    }
}

/// Loads the worlds (building dictionaries into the store if needed), binds `config.listen` and
/// serves until SIGTERM/SIGINT, then drains in-flight requests.
pub async fn serve(config: crate::config::Config) -> Result<(), ServerError> {
    let cfg = config.clone();
    let state = tokio::task::spawn_blocking(move || {
        let worlds = load_worlds(&cfg)?;
        AppState::with_admin(worlds, &cfg)
    })
    .await
    .map_err(|e| ServerError::Internal(e.to_string()))??;
    worlds::prepare_landscapes(state.live.snapshot().values().cloned().collect());
    if state.admin.as_ref().is_some_and(|a| a.enabled()) {
        tracing::info!("admin API enabled under /admin");
    } else {
        tracing::info!("admin disabled: no admin token configured (set TERRASYNTH_ADMIN_TOKEN)");
    }
    let listener = tokio::net::TcpListener::bind(&config.server.listen)
        .await
        .map_err(|e| {
            ServerError::Internal(format!("cannot listen on {}: {e}", config.server.listen))
        })?;
    let addr = listener
        .local_addr()
        .map_err(|e| ServerError::Internal(e.to_string()))?;
    tracing::info!(%addr, "listening");
    // Tiles are written whole: without TCP_NODELAY a tile's last segment can wait on the
    // client's delayed ACK.
    let listener = listener.tap_io(|tcp| {
        if let Err(e) = tcp.set_nodelay(true) {
            tracing::debug!("cannot set TCP_NODELAY: {e}");
        }
    });
    axum::serve(listener, app(state))
        .with_graceful_shutdown(shutdown_signal())
        .await
        .map_err(|e| ServerError::Internal(e.to_string()))
}
