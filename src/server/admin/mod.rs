//! The admin API (`/admin/...`, bearer token) and the public dictionary catalogue
//! (`/dictionaries`). Handlers only translate HTTP into calls of the store crate's catalogue
//! service ([`terrasynth_store::Catalogue`]), which holds the rules; its blocking work (decoding
//! uploads, fsync'd writes and deletions, assembling worlds) runs on the blocking pool and builds
//! on their own workers, never on an async runtime thread.
//!
//! - [`auth`]: the bearer token, compared in constant time, and [`throttle`]: failed attempts
//!   logged and rate-limited per client address;
//! - [`extract`]: bodies (spooled to the store's `uploads/` as they arrive), queries and upload
//!   formats;
//! - [`exemplars`], [`dictionaries`], [`jobs`], [`worlds`]: the handlers.
//!
//! Uploads are bounded in number (`max_concurrent_uploads`, beyond: 503) and in memory (each
//! reserves its body and its decoded size from a budget of `upload_memory_mb` before anything is
//! decoded).

pub mod auth;
pub mod dictionaries;
pub mod exemplars;
pub mod extract;
pub mod jobs;
pub mod throttle;
pub mod worlds;

use std::sync::Arc;

use tokio::sync::Semaphore;

use terrasynth_store::ingest::UploadLimits;
use terrasynth_store::{Catalogue, MemoryBudget};

use crate::config::ServerConfig;
use throttle::AuthThrottle;

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
    /// Failed authentications per client address.
    pub throttle: AuthThrottle,
    /// Uploads processed at once.
    pub upload_slots: Arc<Semaphore>,
    /// The memory all uploads in progress may use together.
    pub upload_memory: Arc<MemoryBudget>,
}

impl Admin {
    /// The admin API over `catalogue` with the token and upload and authentication settings of
    /// `config` (enabled when the token is not empty).
    pub fn new(
        catalogue: Arc<Catalogue>,
        config: &ServerConfig,
        limits: UploadLimits,
        cache_bytes: u64,
    ) -> Admin {
        Admin {
            catalogue,
            token: Some(config.admin_token.0.clone()).filter(|t| !t.is_empty()),
            limits,
            cache_bytes,
            throttle: AuthThrottle::new(config.auth_failures_per_minute),
            upload_slots: Arc::new(Semaphore::new(config.max_concurrent_uploads.max(1))),
            upload_memory: MemoryBudget::new(config.upload_memory_mb.saturating_mul(1 << 20)),
        }
    }

    /// Whether the admin routes are enabled (a token is configured).
    pub fn enabled(&self) -> bool {
        self.token.is_some()
    }
}
