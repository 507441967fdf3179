//! The admin API (`/admin/...`, bearer token) and the public dictionary catalogue
//! (`/dictionaries`). Handlers only translate HTTP into calls of the store crate's catalogue
//! service ([`terrasynth_store::Catalogue`]), which holds the rules; its blocking work (decoding
//! uploads, fsync'd writes and deletions, assembling worlds) runs on the blocking pool and builds
//! on their own workers, never on an async runtime thread.
//!
//! - [`auth`]: the bearer token, compared in constant time;
//! - [`extract`]: bodies, queries and upload formats;
//! - [`exemplars`], [`dictionaries`], [`jobs`], [`worlds`]: the handlers.

pub mod auth;
pub mod dictionaries;
pub mod exemplars;
pub mod extract;
pub mod jobs;
pub mod worlds;

use std::sync::Arc;

use terrasynth_store::ingest::UploadLimits;
use terrasynth_store::Catalogue;

/// The admin API's state.
pub struct Admin {
    /// The catalogue service (store, catalogue, build jobs, rules).
    pub catalogue: Arc<Catalogue>,
    /// The bearer token; `None` disables the admin routes.
    token: Option<String>,
    /// Upload limits.
    pub limits: UploadLimits,
    /// The cache share of each world created through the API.
    pub cache_bytes: u64,
}

impl Admin {
    /// The admin API over `catalogue`, enabled when `token` is not empty.
    pub fn new(
        catalogue: Arc<Catalogue>,
        token: &str,
        limits: UploadLimits,
        cache_bytes: u64,
    ) -> Admin {
        Admin {
            catalogue,
            token: Some(token.to_string()).filter(|t| !t.is_empty()),
            limits,
            cache_bytes,
        }
    }

    /// Whether the admin routes are enabled (a token is configured).
    pub fn enabled(&self) -> bool {
        self.token.is_some()
    }
}
