//! Picking up worlds that another process created in a shared store: replicas behind one load
//! balancer read one `--store`, and a world created through the admin API on one of them must be
//! served by the others without a restart. A request naming a world this process does not serve
//! looks the name up in the store ([`terrasynth_store::Catalogue::stored_world`]: one alias
//! read) and, when it is there, builds the world and adds it to the live set, as if it had been
//! created here. Look-ups run one at a time on the blocking pool, and a name found absent is
//! not looked up again for [`RECHECK`], so that requests for unknown names cost at most one
//! file read per name per second (the remembered names are bounded).

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

/// The look-ups of unknown world names in the store.
#[derive(Debug, Default)]
pub struct Pickup {
    /// When each name was last found absent.
    absent: Mutex<HashMap<String, Instant>>,
    /// One look-up at a time (a second request for the same new world waits and finds it).
    running: tokio::sync::Mutex<()>,
}

impl Pickup {
    fn recently_absent(&self, name: &str) -> bool {
        let map = self.absent.lock().unwrap_or_else(|p| p.into_inner());
        map.get(name).is_some_and(|t| t.elapsed() < RECHECK)
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
        let (live, owned) = (self.live.clone(), name.to_string());
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
            live.insert(world.clone());
            tracing::info!(world = %owned, id = %id, "world: picked up from the store");
            Ok(Some(world))
        })
        .await?;
        match found {
            Some(w) => {
                prepare_landscapes(vec![w.clone()]);
                Ok(w)
            }
            None => {
                self.pickup.mark_absent(name);
                Err(unknown(name))
            }
        }
    }
}
