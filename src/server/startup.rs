//! Start-up: open the store once, load the configured worlds (building missing dictionaries),
//! start the catalogue service and add the worlds stored by earlier runs, then bind and serve
//! until SIGTERM/SIGINT. Failures are [`StartupError`]s, worded for the operator.

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Duration;

use terrasynth_core::landscape::LandscapeConfig;
use terrasynth_core::raster::ReadLimits;
use terrasynth_store::ingest::UploadLimits;
use terrasynth_store::worlds::weights_map;
use terrasynth_store::{Catalogue, JobSettings, Store, WorldDefaults};

use super::admin::Admin;
use super::connections;
use super::error::StartupError;
use super::state::{AppState, LiveWorlds};
use super::worlds::{load_worlds, prepare_landscapes, share_shortfall, world_from, Worlds};
use crate::config::Config;

/// What worlds created through the admin API inherit: the first configured world's settings
/// (the default world's when none is configured).
fn world_defaults(config: &Config) -> WorldDefaults {
    let first = config.worlds.first();
    WorldDefaults {
        max_zoom: first.map_or(16, |w| w.max_zoom),
        weights: weights_map(&first.map(|w| w.weights.clone()).unwrap_or_default()),
        landscape: first.map_or_else(LandscapeConfig::tienshan, |w| w.landscape.clone()),
    }
}

/// The server's state for `config` (blocking: opens and verifies the store, loads or builds the
/// configured worlds' dictionaries, loads the stored worlds). The store is opened once here and
/// shared by the world loader and the catalogue service.
pub fn build_state(config: &Config) -> Result<AppState, StartupError> {
    let store = Store::open(&config.server.store_dir)?;
    let worlds = load_worlds(config, &store)?;
    state_with(config, store, worlds)
}

/// The server's state for `config` serving `worlds` (already loaded for the configured worlds)
/// over the opened `store`: starts the catalogue service and adds the stored worlds.
pub fn state_with(config: &Config, store: Store, worlds: Worlds) -> Result<AppState, StartupError> {
    let s = &config.server;
    let live = LiveWorlds::new(worlds);
    let catalogue = Arc::new(Catalogue::open(
        store,
        JobSettings {
            workers: s.build_workers,
            threads: s.build_threads,
            queue: s.build_queue,
        },
        world_defaults(config),
        config
            .worlds
            .iter()
            .map(|w| w.name.clone())
            .collect::<BTreeSet<_>>(),
    )?);
    let cache_bytes = s.level_cache_bytes(config.worlds.len());
    for (id, def) in catalogue.worlds_to_load()? {
        let name = def.name.clone();
        match catalogue
            .resolve(&def)
            .map_err(|e| e.to_string())
            .and_then(|r| world_from(r, cache_bytes).map_err(|e| e.to_string()))
        {
            Ok(w) => {
                if let Some(why) = share_shortfall(&w) {
                    tracing::warn!(world = %name, "{why}");
                }
                tracing::info!(world = %name, id = %id, "world: loaded from the store");
                live.insert(Arc::new(w));
            }
            Err(e) => tracing::warn!(world = %name, error = %e, "stored world unusable; skipped"),
        }
    }
    let limits = UploadLimits {
        max_body: usize::try_from(s.max_body_mb.saturating_mul(1 << 20)).unwrap_or(usize::MAX),
        read: ReadLimits {
            max_pixels: s.max_pixels,
            max_layers: s.max_layers,
        },
        max_dimension: s.max_dimension,
    };
    let admin = Admin::new(catalogue, s, limits, cache_bytes);
    AppState::new(live, Some(Arc::new(admin)), s)
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

/// Binds `addr`, with an error that says what to do when it is taken.
async fn bind(addr: &str) -> Result<tokio::net::TcpListener, StartupError> {
    tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|source| match source.kind() {
            std::io::ErrorKind::AddrInUse => StartupError::AddressInUse {
                addr: addr.to_string(),
            },
            _ => StartupError::Bind {
                addr: addr.to_string(),
                source,
            },
        })
}

/// Loads the worlds (building dictionaries into the store if needed), binds `config.listen` and
/// serves until SIGTERM/SIGINT, then drains in-flight requests.
pub async fn serve(config: Config) -> Result<(), StartupError> {
    // Fail before the worlds load (which may build dictionaries) when the address is taken;
    // the real listener is bound once they are ready.
    drop(bind(&config.server.listen).await?);
    let cfg = config.clone();
    let state = tokio::task::spawn_blocking(move || build_state(&cfg))
        .await
        .map_err(|e| StartupError::Runtime(e.to_string()))??;
    prepare_landscapes(
        state.live.snapshot().values().cloned().collect(),
        state.store(),
    );
    super::pickup::spawn_store_sync(&state);
    if state.admin.as_ref().is_some_and(|a| a.enabled()) {
        tracing::info!("admin API enabled under /admin");
    } else {
        tracing::info!("admin disabled: no admin token configured (set TERRASYNTH_ADMIN_TOKEN)");
    }
    let listener = bind(&config.server.listen).await?;
    let local = listener
        .local_addr()
        .map_err(|e| StartupError::Runtime(e.to_string()))?;
    let mut state = state;
    if local.to_string() != state.config.listen {
        // The address clients can reach (port 0 resolved), for URLs without a valid `Host`.
        let mut c = (*state.config).clone();
        c.listen = local.to_string();
        state = state.with_config(c);
    }
    if config.server.public_url.is_empty() && local.ip().is_unspecified() {
        tracing::info!("public_url is not set: TileJSON and style URLs reflect each request's Host (set public_url behind a proxy or CDN)");
    }
    let s = &config.server;
    let limits = connections::Limits {
        header_read_timeout: Duration::from_secs(s.header_read_timeout_s),
        idle_timeout: Duration::from_secs(s.idle_timeout_s),
        max_connections: connections::fit_open_files(s.max_connections),
    };
    tracing::info!(addr = %local, max_connections = limits.max_connections, "listening");
    let metrics = state.metrics.clone();
    connections::serve(
        listener,
        super::app(state),
        limits,
        metrics,
        shutdown_signal(),
    )
    .await;
    Ok(())
}
