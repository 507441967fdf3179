//! Picking up worlds that another process created in a shared store: replicas behind one load
//! balancer read one `--store`, and a world created through the admin API on one of them must be
//! served by the others without a restart. A request naming a world this process does not serve
//! looks the name up in the store ([`terrasynth_store::Catalogue::stored_world`]: one alias
//! read) and, when it is there, builds the world and adds it to the live set, as if it had been
//! created here. Look-ups run one at a time on the blocking pool, and a name found absent is
//! not looked up again for [`RECHECK`], so that requests for unknown names cost at most one
//! file read per name per second (the remembered names are bounded).
//!
//! The other direction is a periodic sync ([`spawn_store_sync`], every [`SYNC_INTERVAL`] while
//! the admin API is on): a world deleted from the store by another replica stops being served
//! here, one re-created under the same name by another replica replaces the old one, and worlds
//! another replica created appear in `/worlds` without being asked for by name.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use terrasynth_tiles::World;

use super::error::ServerError;
use super::state::{blocking, AppState};
use super::worlds::{prepare_landscapes, world_from};

/// How long a name found absent from the store is answered 404 without looking again.
pub const RECHECK: Duration = Duration::from_secs(1);

/// Names remembered as absent at most (the memory is cleared when full).
const MAX_REMEMBERED: usize = 4096;

/// How often a replica compares the worlds it serves from the store with the store.
pub const SYNC_INTERVAL: Duration = Duration::from_secs(2);

/// The look-ups of unknown world names in the store.
#[derive(Debug, Default)]
pub struct Pickup {
    /// When each name was last found absent.
    absent: Mutex<HashMap<String, Instant>>,
    /// The store id of every world served from the store, by name (the sync's memory).
    from_store: Mutex<HashMap<String, String>>,
    /// One look-up at a time (a second request for the same new world waits and finds it).
    running: tokio::sync::Mutex<()>,
}

impl Pickup {
    fn recently_absent(&self, name: &str) -> bool {
        let map = self.absent.lock().unwrap_or_else(|p| p.into_inner());
        map.get(name).is_some_and(|t| t.elapsed() < RECHECK)
    }

    /// Records that world `name` is served from the store's definition `id`.
    pub fn served_from_store(&self, name: &str, id: &str) {
        let mut map = self.from_store.lock().unwrap_or_else(|p| p.into_inner());
        map.insert(name.to_string(), id.to_string());
    }

    fn served_ids(&self) -> HashMap<String, String> {
        self.from_store
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    fn forget(&self, name: &str) {
        let mut map = self.from_store.lock().unwrap_or_else(|p| p.into_inner());
        map.remove(name);
    }

    fn mark_absent(&self, name: &str) {
        let mut map = self.absent.lock().unwrap_or_else(|p| p.into_inner());
        if map.len() >= MAX_REMEMBERED {
            map.clear();
        }
        map.insert(name.to_string(), Instant::now());
    }
}

fn unknown(name: &str) -> ServerError {
    ServerError::NotFound(format!("unknown world `{name}`"))
}

impl AppState {
    /// World `name`: from this request's snapshot, the live set, or else the shared store (a
    /// world another replica created); 404 when none has it.
    pub async fn find_world(&self, name: &str) -> Result<Arc<World>, ServerError> {
        if let Ok(w) = self.world(name) {
            return Ok(w);
        }
        if let Some(w) = self.live.get(name) {
            return Ok(w);
        }
        let Some(admin) = self.admin.clone() else {
            return Err(unknown(name));
        };
        if !terrasynth_core::names::is_valid_name(name) || self.pickup.recently_absent(name) {
            return Err(unknown(name));
        }
        let _one = self.pickup.running.lock().await;
        // Another request may have picked it up, or found it absent, while this one waited.
        if let Some(w) = self.live.get(name) {
            return Ok(w);
        }
        if self.pickup.recently_absent(name) {
            return Err(unknown(name));
        }
        let (live, owned, pickup) = (self.live.clone(), name.to_string(), self.pickup.clone());
        let store = self.store();
        let found = blocking(move || {
            let catalogue = &admin.catalogue;
            let Some((id, def)) = catalogue.stored_world(&owned)? else {
                return Ok(None);
            };
            let world = catalogue
                .resolve(&def)
                .map_err(ServerError::from)
                .and_then(|r| world_from(r, admin.cache_bytes).map_err(ServerError::from))?;
            let world = Arc::new(world);
            live.publish(world.clone(), store.as_ref());
            pickup.served_from_store(&owned, &id);
            tracing::info!(world = %owned, id = %id, "world: picked up from the store");
            Ok(Some(world))
        })
        .await?;
        match found {
            Some(w) => {
                prepare_landscapes(vec![w.clone()], self.store());
                Ok(w)
            }
            None => {
                self.pickup.mark_absent(name);
                Err(unknown(name))
            }
        }
    }
}

/// Starts the periodic sync of the worlds served from the store with the store (see the module
/// documentation); nothing when the admin API is off (no store catalogue). Runs on the blocking
/// pool, one pass at a time, for the life of the process.
pub fn spawn_store_sync(state: &AppState) {
    if state.admin.is_none() {
        return;
    }
    let state = state.clone();
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(SYNC_INTERVAL);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            let s = state.clone();
            match blocking(move || sync_once(&s)).await {
                Ok(added) if !added.is_empty() => prepare_landscapes(added, state.store()),
                Ok(_) => {}
                Err(e) => tracing::warn!(error = %e, "store sync failed; retrying"),
            }
        }
    });
}

/// One pass of the sync: drops worlds whose stored definition is gone, reloads those whose
/// definition changed, loads stored worlds not served yet. Returns the worlds it loaded.
fn sync_once(state: &AppState) -> Result<Vec<Arc<World>>, ServerError> {
    let admin = state.admin()?;
    let catalogue = &admin.catalogue;
    let stored: HashMap<String, String> = catalogue
        .stored_worlds()?
        .into_iter()
        .map(|(id, def)| (def.name, id))
        .collect();
    let known = state.pickup.served_ids();
    for (name, id) in &known {
        if stored.get(name) != Some(id) {
            state.pickup.forget(name);
            if !stored.contains_key(name) && state.live.remove(name) {
                tracing::info!(world = %name, "world: deleted from the store; no longer served");
            }
        }
    }
    let mut added = Vec::new();
    for (name, id) in &stored {
        if known.get(name) == Some(id) {
            continue;
        }
        // `stored_world` leaves out names a configured world shadows.
        let Some((id_now, def)) = catalogue.stored_world(name)? else {
            continue;
        };
        if !known.contains_key(name) && state.live.get(name).is_some() {
            // Served already (created through this process's admin API, or loaded at start
            // before the sync knew it): adopt it.
            state.pickup.served_from_store(name, &id_now);
            continue;
        }
        let built = catalogue
            .resolve(&def)
            .map_err(ServerError::from)
            .and_then(|r| world_from(r, admin.cache_bytes).map_err(ServerError::from));
        match built {
            Ok(world) => {
                let world = Arc::new(world);
                state.live.publish(world.clone(), state.store().as_ref());
                state.pickup.served_from_store(name, &id_now);
                tracing::info!(world = %name, id = %id_now, "world: loaded from the store by the sync");
                added.push(world);
            }
            Err(e) => {
                // Remembered, so that a broken definition is not rebuilt every pass.
                state.pickup.served_from_store(name, &id_now);
                tracing::warn!(world = %name, error = %e, "stored world unusable; skipped");
            }
        }
    }
    Ok(added)
}
