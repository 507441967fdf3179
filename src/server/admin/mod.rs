//! The admin API (`/admin/...`, bearer token) and the public dictionary catalogue
//! (`/dictionaries`): exemplar uploads ([`ingest`]), dictionary build jobs ([`jobs`]), worlds
//! created at run time, and their errors ([`AdminError`]). Objects live in the store
//! (`crate::store`); the [`Catalog`] keeps their metadata in memory so listings never read big
//! files. CPU work (decoding uploads, assembling worlds) runs on the blocking pool and builds on
//! their own workers, never on an async runtime thread.

pub mod ingest;
pub mod jobs;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::{Arc, Mutex, MutexGuard};

use axum::extract::rejection::QueryRejection;
use axum::extract::{FromRequest, Multipart, Path, Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::{Deserialize, Serialize};
use subtle::ConstantTimeEq;
use thiserror::Error;
use utoipa::ToSchema;

use self::ingest::{Declared, UploadLimits};
use self::jobs::{DictionaryRequest, Job, Jobs};
use super::error::ServerError;
use super::{AppState, LiveWorlds};
use crate::config::Config;
use crate::dictionary::{Dictionary, Learning, MatchWeights};
use crate::raster::ReadLimits;
use crate::store::exemplar::{self, ExemplarHeader};
use crate::store::{ObjectKind, Store, StoreError};
use crate::tiles::{World, WorldParts};

/// Largest JSON request body, bytes.
const MAX_JSON: usize = 1 << 20;

/// An error of the admin API or the catalogue.
#[derive(Debug, Error)]
pub enum AdminError {
    /// Missing or wrong bearer token (401).
    #[error("{0}")]
    Unauthorized(String),
    /// Malformed request or undecodable upload (400).
    #[error("{0}")]
    BadRequest(String),
    /// No such object (404).
    #[error("{0}")]
    NotFound(String),
    /// The object is in use, or the name is taken (409).
    #[error("{0}")]
    Conflict(String),
    /// The body or raster exceeds a limit (413).
    #[error("{0}")]
    TooLarge(String),
    /// Wrong content type (415).
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// Well-formed but unusable: NaN-only raster, mismatched layers, absurd georeference,
    /// invalid parameters (422).
    #[error("{0}")]
    Invalid(String),
    /// The build queue is full (503).
    #[error("the build queue is full; retry later")]
    QueueFull,
    /// The store failed (500).
    #[error(transparent)]
    Store(#[from] StoreError),
    /// Something else failed (500).
    #[error("internal error: {0}")]
    Internal(String),
}

impl AdminError {
    /// The HTTP status of this error.
    pub fn status(&self) -> StatusCode {
        match self {
            AdminError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            AdminError::BadRequest(_) => StatusCode::BAD_REQUEST,
            AdminError::NotFound(_) => StatusCode::NOT_FOUND,
            AdminError::Conflict(_) => StatusCode::CONFLICT,
            AdminError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            AdminError::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            AdminError::Invalid(_) => StatusCode::UNPROCESSABLE_ENTITY,
            AdminError::QueueFull => StatusCode::SERVICE_UNAVAILABLE,
            // An id or name that cannot even be a file name names nothing.
            AdminError::Store(StoreError::BadName(_)) => StatusCode::NOT_FOUND,
            AdminError::Store(_) | AdminError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The current time as RFC 3339 UTC with seconds (`2026-11-22T09:30:00Z`).
pub fn now_rfc3339() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// Elevation statistics of an exemplar.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Statistics {
    /// Lowest elevation, metres.
    pub min: f32,
    /// Highest elevation, metres.
    pub max: f32,
    /// Mean elevation, metres.
    pub mean: f32,
    /// Valid (non-nodata) cells.
    pub valid_cells: u64,
}

/// An exemplar's description.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ExemplarInfo {
    /// Content id.
    pub id: String,
    /// Human name.
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Layer names, `elevation` first.
    pub layers: Vec<String>,
    /// `EPSG:4326` or `EPSG:3857`.
    pub crs: String,
    /// `[west, south, east, north]` in CRS units.
    pub bounds: [f64; 4],
    /// Cell width and height in CRS units.
    pub cell_size: [f64; 2],
    /// Elevation statistics.
    pub statistics: Statistics,
}

fn exemplar_info(id: &str, h: &ExemplarHeader) -> ExemplarInfo {
    let (w, s, e, n) = h.georef.bounds(h.width, h.height);
    ExemplarInfo {
        id: id.to_string(),
        name: h.name.clone(),
        width: h.width,
        height: h.height,
        layers: h.layers.clone(),
        crs: format!("EPSG:{}", h.georef.crs.epsg()),
        bounds: [w, s, e, n],
        cell_size: [h.georef.pixel_width, h.georef.pixel_height],
        statistics: Statistics {
            min: h.stats.min,
            max: h.stats.max,
            mean: h.stats.mean,
            valid_cells: h.stats.valid_cells,
        },
    }
}

/// A dictionary's public metadata.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DictionaryInfo {
    /// Content id.
    pub id: String,
    /// Human name (an alias), if any.
    pub name: Option<String>,
    /// Number of atoms.
    pub atoms: usize,
    /// High-resolution patch side.
    pub patch: usize,
    /// Step between patches.
    pub stride: usize,
    /// `complete` or `medoids:N`.
    pub learning: String,
    /// Seed.
    pub seed: u64,
    /// Mean exemplar cell size, metres.
    pub cell_m: f64,
    /// Extra layers carried by the atoms.
    pub layers: Vec<String>,
}

fn dictionary_info(id: &str, name: Option<String>, d: &Dictionary) -> DictionaryInfo {
    DictionaryInfo {
        id: id.to_string(),
        name,
        atoms: d.n_atoms,
        patch: d.params.patch,
        stride: d.params.stride,
        learning: match d.params.learning {
            Learning::Complete => "complete".into(),
            Learning::Medoids { iterations } => format!("medoids:{iterations}"),
        },
        seed: d.params.seed,
        cell_m: d.params.cell_m,
        layers: d.layers.iter().map(|l| l.name.clone()).collect(),
    }
}

/// Metadata of the store's exemplars and dictionaries, kept in memory.
#[derive(Default)]
pub struct Catalog {
    exemplars: Mutex<BTreeMap<String, ExemplarHeader>>,
    dictionaries: Mutex<BTreeMap<String, DictionaryInfo>>,
}

impl Catalog {
    /// Reads the metadata of every exemplar and dictionary of `store`.
    pub fn load(store: &Store) -> Result<Catalog, StoreError> {
        let catalog = Catalog::default();
        for id in store.object_ids(ObjectKind::Exemplar)? {
            if let Some(p) = store.get_object(ObjectKind::Exemplar, &id)? {
                match exemplar::decode_header(&p) {
                    Ok(h) => {
                        lock(&catalog.exemplars).insert(id, h);
                    }
                    Err(e) => {
                        tracing::warn!(exemplar = %id, error = %e, "unusable exemplar skipped")
                    }
                }
            }
        }
        let mut names: BTreeMap<String, String> = BTreeMap::new();
        for (alias, id) in store.aliases("")? {
            let name = alias
                .strip_prefix("dictionary.")
                .unwrap_or(&alias)
                .to_string();
            if alias.starts_with("dictionary.") || alias.starts_with("world-") {
                names.entry(id).or_insert(name);
            }
        }
        for id in store.dictionary_ids()? {
            match store.get_dictionary(&id) {
                Ok(Some(d)) => {
                    let info = dictionary_info(&id, names.get(&id).cloned(), &d);
                    lock(&catalog.dictionaries).insert(id, info);
                }
                Ok(None) => {}
                Err(e) => {
                    tracing::warn!(dictionary = %id, error = %e, "unusable dictionary skipped")
                }
            }
        }
        Ok(catalog)
    }

    /// Stores dictionary `d` under alias `dictionary.{name}` and records it; its id.
    pub fn add_dictionary(
        &self,
        store: &Store,
        name: &str,
        d: Dictionary,
    ) -> Result<String, StoreError> {
        let id = store.put_dictionary(&d)?;
        store.set_alias(&format!("dictionary.{name}"), &id)?;
        lock(&self.dictionaries).insert(id.clone(), dictionary_info(&id, Some(name.into()), &d));
        Ok(id)
    }

    /// Every dictionary.
    pub fn dictionaries(&self) -> Vec<DictionaryInfo> {
        lock(&self.dictionaries).values().cloned().collect()
    }

    /// Dictionary `id`.
    pub fn dictionary(&self, id: &str) -> Option<DictionaryInfo> {
        lock(&self.dictionaries).get(id).cloned()
    }
}

/// A world created through the API, as stored (JSON in a world object).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct WorldDefinition {
    /// URL name.
    pub name: String,
    /// Exemplar id of the base (the coarse DEM or sketch).
    pub base: String,
    /// Dictionary ids of the synthesis chain.
    pub dictionaries: Vec<String>,
    /// Deepest zoom served.
    pub max_zoom: u8,
    /// Matching weights by term or layer name.
    pub weights: BTreeMap<String, f32>,
    /// Layer styles (materials), kept with the world.
    #[schema(value_type = Object)]
    pub materials: serde_json::Value,
}

/// `POST /admin/worlds`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorldRequest {
    /// URL name: 1–64 letters, digits, `-` or `_`.
    #[schema(pattern = "^[A-Za-z0-9_-]{1,64}$")]
    pub name: String,
    /// Exemplar id of the base.
    pub base: String,
    /// Dictionary ids of the synthesis chain (currently exactly one).
    pub dictionaries: Vec<String>,
    /// Deepest zoom served (default: the default world's).
    #[serde(default)]
    pub max_zoom: Option<u8>,
    /// Matching weights (default: the default world's).
    #[serde(default)]
    pub weights: Option<BTreeMap<String, f32>>,
    /// Layer styles (default: the default world's).
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub materials: Option<serde_json::Value>,
}

/// `POST /admin/worlds` answer.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct WorldCreated {
    /// Content id of the stored definition.
    pub id: String,
    /// The definition, defaults filled in.
    pub world: WorldDefinition,
    /// Native zoom derived from the base.
    pub native_zoom: u8,
    /// Tile URL template of the elevation layer.
    pub tiles: String,
}

/// `{"id": ...}` of a queued job (and the job).
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct JobAccepted {
    /// Job id.
    pub id: String,
    /// The job as queued.
    pub job: Job,
}

/// Defaults of created worlds: the default (first configured) world's settings.
#[derive(Clone, Debug)]
struct WorldDefaults {
    max_zoom: u8,
    weights: BTreeMap<String, f32>,
}

fn weights_map(w: &MatchWeights) -> BTreeMap<String, f32> {
    let mut m = BTreeMap::new();
    m.insert("elevation".to_string(), w.elevation);
    m.insert("altitude".to_string(), w.altitude);
    m.insert("slope".to_string(), w.slope);
    for (k, v) in &w.layers {
        m.insert(k.clone(), *v);
    }
    m
}

/// The admin API's state.
pub struct Admin {
    token: Option<String>,
    store: Store,
    /// Upload limits.
    pub limits: UploadLimits,
    catalog: Arc<Catalog>,
    jobs: Jobs,
    config_worlds: BTreeSet<String>,
    defaults: WorldDefaults,
    cache_bytes: u64,
    live: LiveWorlds,
    worlds_lock: tokio::sync::Mutex<()>,
}

impl Admin {
    /// Opens the store, its catalogue and job records, starts the build workers, and adds the
    /// worlds stored by earlier runs to `live`.
    pub fn open(config: &Config, live: LiveWorlds) -> Result<Admin, ServerError> {
        let s = &config.server;
        let store = Store::open(&s.store_dir)?;
        let catalog = Arc::new(Catalog::load(&store)?);
        let jobs = Jobs::start(
            store.clone(),
            catalog.clone(),
            s.build_workers,
            s.build_threads,
            s.build_queue,
        )?;
        let first = config.worlds.first();
        let defaults = WorldDefaults {
            max_zoom: first.map_or(16, |w| w.max_zoom),
            weights: weights_map(&first.map(|w| w.weights.clone()).unwrap_or_default()),
        };
        let token = Some(s.admin_token.0.clone()).filter(|t| !t.is_empty());
        let admin = Admin {
            token,
            store,
            limits: UploadLimits {
                max_body: usize::try_from(s.max_body_mb.saturating_mul(1 << 20))
                    .unwrap_or(usize::MAX),
                read: ReadLimits {
                    max_pixels: s.max_pixels,
                    max_layers: s.max_layers,
                },
                max_dimension: s.max_dimension,
            },
            catalog,
            jobs,
            config_worlds: config.worlds.iter().map(|w| w.name.clone()).collect(),
            defaults,
            cache_bytes: s.level_cache_bytes(config.worlds.len()),
            live,
            worlds_lock: tokio::sync::Mutex::new(()),
        };
        admin.load_stored_worlds()?;
        Ok(admin)
    }

    /// Whether the admin routes are enabled (a token is configured).
    pub fn enabled(&self) -> bool {
        self.token.is_some()
    }

    /// The store.
    pub fn store(&self) -> &Store {
        &self.store
    }

    fn load_stored_worlds(&self) -> Result<(), ServerError> {
        for (alias, id) in self.store.aliases("world.")? {
            let name = alias.trim_start_matches("world.");
            if self.config_worlds.contains(name) {
                tracing::warn!(world = %name, "stored world shadowed by a configured world; skipped");
                continue;
            }
            let def = match self.store.get_object(ObjectKind::World, &id) {
                Ok(Some(p)) => serde_json::from_slice::<WorldDefinition>(&p)
                    .map_err(|e| AdminError::Internal(e.to_string())),
                Ok(None) => Err(AdminError::Internal("definition missing".into())),
                Err(e) => Err(AdminError::from(e)),
            };
            match def.and_then(|d| self.assemble_world(&d)) {
                Ok(w) => {
                    tracing::info!(world = %name, id = %id, "world: loaded from the store");
                    self.live.insert(Arc::new(w));
                }
                Err(e) => {
                    tracing::warn!(world = %name, error = %e, "stored world unusable; skipped")
                }
            }
        }
        Ok(())
    }

    /// Assembles a world from a definition (CPU-bound: call it off the runtime).
    fn assemble_world(&self, def: &WorldDefinition) -> Result<World, AdminError> {
        let unknown = |what: &str, id: &str| AdminError::Invalid(format!("unknown {what} `{id}`"));
        if !is_id(&def.base) {
            return Err(unknown("base exemplar", &def.base));
        }
        if let Some(d) = def.dictionaries.iter().find(|d| !is_id(d)) {
            return Err(unknown("dictionary", d));
        }
        let payload = self
            .store
            .get_object(ObjectKind::Exemplar, &def.base)?
            .ok_or_else(|| AdminError::Invalid(format!("unknown base exemplar `{}`", def.base)))?;
        let (_, raster) = exemplar::decode(&payload)?;
        let base = raster
            .elevation()
            .ok_or_else(|| AdminError::Invalid("the base has no elevation".into()))?;
        let [dict_id] = def.dictionaries.as_slice() else {
            return Err(AdminError::Invalid(format!(
                "a world takes exactly one dictionary for now ({} given)",
                def.dictionaries.len()
            )));
        };
        let dictionary = self
            .store
            .get_dictionary(dict_id)?
            .ok_or_else(|| AdminError::Invalid(format!("unknown dictionary `{dict_id}`")))?;
        World::new(WorldParts {
            name: def.name.clone(),
            title: def.name.clone(),
            attribution: String::new(),
            base,
            z_base: None,
            max_zoom: def.max_zoom,
            fill_m: 0.0,
            dictionary: Arc::new(dictionary),
            dictionary_id: dict_id.clone(),
            weights: jobs::match_weights(&def.weights),
            cache_bytes: self.cache_bytes,
            // Runtime worlds get the default world's landscape (species, materials).
            landscape: crate::landscape::LandscapeConfig::tienshan(),
        })
        .map_err(|e| AdminError::Invalid(format!("cannot create the world: {e}")))
    }

    fn check_token(&self, headers: &HeaderMap) -> Result<(), AdminError> {
        use sha2::{Digest, Sha256};
        let Some(token) = &self.token else {
            return Err(AdminError::NotFound("no such resource".into()));
        };
        let given = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| {
                let (scheme, rest) = v.trim().split_once(' ')?;
                scheme.eq_ignore_ascii_case("bearer").then(|| rest.trim())
            })
            .ok_or_else(|| {
                AdminError::Unauthorized("missing `Authorization: Bearer <token>`".into())
            })?;
        // Hashes have equal lengths, so the comparison time does not depend on the token.
        let a = Sha256::digest(given.as_bytes());
        let b = Sha256::digest(token.as_bytes());
        if bool::from(a.as_slice().ct_eq(b.as_slice())) {
            Ok(())
        } else {
            Err(AdminError::Unauthorized("invalid admin token".into()))
        }
    }
}

/// Whether `s` can be a content id (64 lowercase hex digits).
fn is_id(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

fn admin(state: &AppState) -> Result<Arc<Admin>, AdminError> {
    state
        .admin
        .clone()
        .ok_or_else(|| AdminError::NotFound("no such resource".into()))
}

/// Middleware of the admin routes: the bearer token, compared in constant time.
pub async fn authorize(State(state): State<AppState>, req: Request, next: Next) -> Response {
    match admin(&state).and_then(|a| a.check_token(req.headers())) {
        Ok(()) => next.run(req).await,
        Err(e) => ServerError::from(e).into_response(),
    }
}

fn check_name(what: &str, name: &str) -> Result<(), AdminError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if ok {
        Ok(())
    } else {
        Err(AdminError::Invalid(format!(
            "{what} `{name}` must be 1–64 letters, digits, `-` or `_`"
        )))
    }
}

fn query(
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
) -> Result<HashMap<String, String>, AdminError> {
    q.map(|Query(q)| q)
        .map_err(|e| AdminError::BadRequest(format!("malformed query: {e}")))
}

async fn read_body(req: Request, limit: usize) -> Result<axum::body::Bytes, AdminError> {
    let too_large = || AdminError::TooLarge(format!("the body exceeds the limit of {limit} bytes"));
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    axum::body::to_bytes(req.into_body(), limit)
        .await
        .map_err(|e| {
            let mut source: Option<&(dyn std::error::Error + 'static)> = Some(&e);
            while let Some(s) = source {
                if s.is::<http_body_util::LengthLimitError>() {
                    return too_large();
                }
                source = s.source();
            }
            AdminError::BadRequest(format!("cannot read the body: {e}"))
        })
}

async fn json_body<T: serde::de::DeserializeOwned>(req: Request) -> Result<T, AdminError> {
    let ct = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_ascii_lowercase();
    let essence = ct.split(';').next().unwrap_or("").trim().to_string();
    if essence != "application/json" && !essence.ends_with("+json") {
        return Err(AdminError::UnsupportedMediaType(format!(
            "Content-Type `{essence}`: send application/json"
        )));
    }
    let bytes = read_body(req, MAX_JSON).await?;
    serde_json::from_slice(&bytes).map_err(|e| match e.classify() {
        serde_json::error::Category::Data => AdminError::Invalid(format!("invalid request: {e}")),
        _ => AdminError::BadRequest(format!("malformed JSON: {e}")),
    })
}

async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, AdminError> + Send + 'static,
) -> Result<T, AdminError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| AdminError::Internal(e.to_string()))?
}

/// `POST /admin/exemplars?name=`: upload an exemplar.
pub async fn post_exemplar(
    State(state): State<AppState>,
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = admin(&state)?;
    let q = query(q)?;
    let name = q
        .get("name")
        .cloned()
        .ok_or_else(|| AdminError::BadRequest("query parameter `name` is required".into()))?;
    check_name("exemplar name", &name)?;
    let georef = ingest::georef_from_query(&q)?;
    let limits = admin.limits;
    let ct = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    let is_multipart = ct.as_deref().is_some_and(|c| {
        c.trim()
            .to_ascii_lowercase()
            .starts_with("multipart/form-data")
    });
    let raster = if is_multipart {
        let mut mp = Multipart::from_request(req, &())
            .await
            .map_err(|e| AdminError::BadRequest(format!("malformed multipart body: {e}")))?;
        let mut parts: Vec<(String, Declared, axum::body::Bytes)> = Vec::new();
        let mut total = 0usize;
        loop {
            let field = mp.next_field().await.map_err(multipart_error)?;
            let Some(field) = field else { break };
            let part = field.name().unwrap_or("").to_string();
            let declared = match field.content_type() {
                None => Declared::Sniff,
                Some(c) => ingest::declared(Some(c))?,
            };
            let bytes = field.bytes().await.map_err(multipart_error)?;
            total += bytes.len();
            if total > limits.max_body {
                return Err(AdminError::TooLarge("the body exceeds the limit".into()).into());
            }
            if parts.len() > limits.read.max_layers {
                return Err(AdminError::TooLarge(format!(
                    "more than {} parts",
                    limits.read.max_layers
                ))
                .into());
            }
            parts.push((part, declared, bytes));
        }
        blocking(move || {
            let elevation_at = parts
                .iter()
                .position(|(n, _, _)| n == crate::raster::ELEVATION)
                .ok_or_else(|| {
                    AdminError::Invalid("the multipart body has no `elevation` part".into())
                })?;
            let (_, decl, bytes) = &parts[elevation_at];
            let elevation =
                ingest::decode_raster("part `elevation`", bytes, *decl, georef, &limits)?;
            let mut layers = Vec::new();
            for (i, (n, decl, bytes)) in parts.iter().enumerate() {
                if i == elevation_at {
                    continue;
                }
                ingest::check_layer_name(n)?;
                let r = ingest::decode_raster(
                    &format!("part `{n}`"),
                    bytes,
                    *decl,
                    Some(elevation.georef),
                    &limits,
                )?;
                layers.push((n.clone(), r));
            }
            ingest::assemble(elevation, layers, &limits)
        })
        .await?
    } else {
        let declared = ingest::declared(ct.as_deref())?;
        let bytes = read_body(req, limits.max_body).await?;
        blocking(move || {
            let r = ingest::decode_raster("the body", &bytes, declared, georef, &limits)?;
            ingest::assemble(r, Vec::new(), &limits)
        })
        .await?
    };
    let store = admin.store.clone();
    let (id, header) = blocking(move || {
        let (header, payload) = exemplar::encode(&name, &raster)?;
        let id = store.put_object(ObjectKind::Exemplar, &payload)?;
        store.set_alias(&format!("exemplar.{name}"), &id)?;
        Ok((id, header))
    })
    .await?;
    lock(&admin.catalog.exemplars).insert(id.clone(), header.clone());
    tracing::info!(exemplar = %id, name = %header.name, "exemplar stored");
    let mut resp = (StatusCode::CREATED, Json(exemplar_info(&id, &header))).into_response();
    if let Ok(v) = HeaderValue::from_str(&format!("/admin/exemplars/{id}")) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

fn multipart_error(e: axum::extract::multipart::MultipartError) -> AdminError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        AdminError::TooLarge(format!("multipart body: {e}"))
    } else {
        AdminError::BadRequest(format!("malformed multipart body: {e}"))
    }
}

/// `GET /admin/exemplars`.
pub async fn list_exemplars(
    State(state): State<AppState>,
) -> Result<Json<Vec<ExemplarInfo>>, ServerError> {
    let admin = admin(&state)?;
    let list = lock(&admin.catalog.exemplars)
        .iter()
        .map(|(id, h)| exemplar_info(id, h))
        .collect();
    Ok(Json(list))
}

/// `GET /admin/exemplars/{id}`.
pub async fn get_exemplar(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<ExemplarInfo>, ServerError> {
    let admin = admin(&state)?;
    let info = lock(&admin.catalog.exemplars)
        .get(&id)
        .map(|h| exemplar_info(&id, h))
        .ok_or_else(|| AdminError::NotFound(format!("no exemplar `{id}`")))?;
    Ok(Json(info))
}

/// `DELETE /admin/exemplars/{id}`: 409 while a build or a world uses it.
pub async fn delete_exemplar(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ServerError> {
    let admin = admin(&state)?;
    let _guard = admin.worlds_lock.lock().await;
    let header = lock(&admin.catalog.exemplars)
        .get(&id)
        .cloned()
        .ok_or_else(|| AdminError::NotFound(format!("no exemplar `{id}`")))?;
    if admin.jobs.uses_exemplar(&id) {
        return Err(
            AdminError::Conflict(format!("exemplar `{id}` is used by a dictionary build")).into(),
        );
    }
    for (_, def) in stored_worlds(&admin)? {
        if def.base == id {
            return Err(AdminError::Conflict(format!(
                "exemplar `{id}` is the base of world `{}`",
                def.name
            ))
            .into());
        }
    }
    lock(&admin.catalog.exemplars).remove(&id);
    let alias = format!("exemplar.{}", header.name);
    if admin.store.alias(&alias)?.as_deref() == Some(id.as_str()) {
        admin.store.remove_alias(&alias)?;
    }
    admin.store.delete_object(ObjectKind::Exemplar, &id)?;
    Ok(StatusCode::NO_CONTENT)
}

fn stored_worlds(admin: &Admin) -> Result<Vec<(String, WorldDefinition)>, AdminError> {
    let mut out = Vec::new();
    for (_, id) in admin.store.aliases("world.")? {
        if let Some(p) = admin.store.get_object(ObjectKind::World, &id)? {
            if let Ok(def) = serde_json::from_slice::<WorldDefinition>(&p) {
                out.push((id, def));
            }
        }
    }
    Ok(out)
}

/// `POST /admin/dictionaries`: queue a build; 202 with `Location: /admin/jobs/{id}`.
pub async fn post_dictionary(
    State(state): State<AppState>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = admin(&state)?;
    let request: DictionaryRequest = json_body(req).await?;
    check_name("dictionary name", &request.name)?;
    if request.exemplars.is_empty() || request.exemplars.len() > 64 {
        return Err(AdminError::Invalid("give 1–64 exemplar ids".into()).into());
    }
    for e in &request.exemplars {
        if !lock(&admin.catalog.exemplars).contains_key(e) {
            return Err(AdminError::Invalid(format!("unknown exemplar `{e}`")).into());
        }
    }
    jobs::build_options(&request)?;
    let job = admin.jobs.submit(request)?;
    tracing::info!(job = %job.id, "dictionary job queued");
    let location = format!("/admin/jobs/{}", job.id);
    let mut resp = (
        StatusCode::ACCEPTED,
        Json(JobAccepted {
            id: job.id.clone(),
            job,
        }),
    )
        .into_response();
    if let Ok(v) = HeaderValue::from_str(&location) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

/// `GET /admin/jobs`.
pub async fn list_jobs(State(state): State<AppState>) -> Result<Json<Vec<Job>>, ServerError> {
    Ok(Json(admin(&state)?.jobs.list()))
}

/// `GET /admin/jobs/{id}`.
pub async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Job>, ServerError> {
    let job = admin(&state)?
        .jobs
        .get(&id)
        .ok_or_else(|| AdminError::NotFound(format!("no job `{id}`")))?;
    Ok(Json(job))
}

/// `DELETE /admin/jobs/{id}`: cancel a queued or running job.
pub async fn cancel_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<(StatusCode, Json<Job>), ServerError> {
    let job = admin(&state)?.jobs.cancel(&id)?;
    Ok((StatusCode::ACCEPTED, Json(job)))
}

/// `GET /dictionaries` (public).
pub async fn list_dictionaries(State(state): State<AppState>) -> Json<Vec<DictionaryInfo>> {
    Json(
        state
            .admin
            .as_ref()
            .map(|a| a.catalog.dictionaries())
            .unwrap_or_default(),
    )
}

/// `GET /dictionaries/{id}` (public).
pub async fn get_dictionary(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<DictionaryInfo>, ServerError> {
    state
        .admin
        .as_ref()
        .and_then(|a| a.catalog.dictionary(&id))
        .map(Json)
        .ok_or_else(|| AdminError::NotFound(format!("no dictionary `{id}`")).into())
}

/// `DELETE /admin/dictionaries/{id}`: 409 while a world uses it.
pub async fn delete_dictionary(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ServerError> {
    let admin = admin(&state)?;
    let _guard = admin.worlds_lock.lock().await;
    if admin.catalog.dictionary(&id).is_none() {
        return Err(AdminError::NotFound(format!("no dictionary `{id}`")).into());
    }
    if let Some(w) = state
        .worlds
        .values()
        .find(|w| w.dictionary_ids().contains(&id))
    {
        return Err(AdminError::Conflict(format!(
            "dictionary `{id}` is used by world `{}`",
            w.name()
        ))
        .into());
    }
    for (_, def) in stored_worlds(&admin)? {
        if def.dictionaries.contains(&id) {
            return Err(AdminError::Conflict(format!(
                "dictionary `{id}` is used by world `{}`",
                def.name
            ))
            .into());
        }
    }
    lock(&admin.catalog.dictionaries).remove(&id);
    for (alias, target) in admin.store.aliases("")? {
        if target == id {
            admin.store.remove_alias(&alias)?;
        }
    }
    admin.store.delete_dictionary(&id)?;
    Ok(StatusCode::NO_CONTENT)
}

/// `POST /admin/worlds`: create a world; its tiles are served at once.
pub async fn post_world(
    State(state): State<AppState>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = admin(&state)?;
    let r: WorldRequest = json_body(req).await?;
    check_name("world name", &r.name)?;
    let def = WorldDefinition {
        name: r.name.clone(),
        base: r.base,
        dictionaries: r.dictionaries,
        max_zoom: r.max_zoom.unwrap_or(admin.defaults.max_zoom),
        weights: r.weights.unwrap_or_else(|| admin.defaults.weights.clone()),
        materials: r
            .materials
            .unwrap_or_else(|| serde_json::Value::Array(Vec::new())),
    };
    if def.weights.values().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(AdminError::Invalid("weights must be finite and non-negative".into()).into());
    }
    let _guard = admin.worlds_lock.lock().await;
    if admin.config_worlds.contains(&def.name) || admin.live.get(&def.name).is_some() {
        return Err(AdminError::Conflict(format!("world `{}` already exists", def.name)).into());
    }
    let a = admin.clone();
    let d = def.clone();
    let (world, id) = blocking(move || {
        let world = a.assemble_world(&d)?;
        let json = serde_json::to_vec(&d).map_err(|e| AdminError::Internal(e.to_string()))?;
        let id = a.store.put_object(ObjectKind::World, &json)?;
        a.store.set_alias(&format!("world.{}", d.name), &id)?;
        Ok((world, id))
    })
    .await?;
    let native_zoom = world.z_base();
    let world = Arc::new(world);
    admin.live.insert(world.clone());
    super::worlds::prepare_landscapes(vec![world]);
    tracing::info!(world = %def.name, id = %id, "world created");
    let body = WorldCreated {
        id,
        tiles: format!("/tiles/{}/elevation/{{z}}/{{x}}/{{y}}.png", def.name),
        world: def,
        native_zoom,
    };
    Ok((StatusCode::CREATED, Json(body)).into_response())
}

/// `DELETE /admin/worlds/{name}`: configured worlds are read-only (409).
pub async fn delete_world(
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<StatusCode, ServerError> {
    let admin = admin(&state)?;
    let _guard = admin.worlds_lock.lock().await;
    if admin.config_worlds.contains(&name) {
        return Err(AdminError::Conflict(format!(
            "world `{name}` comes from the configuration and is read-only"
        ))
        .into());
    }
    let alias = format!("world.{name}");
    let id = match admin.store.alias(&alias) {
        Ok(Some(id)) => id,
        Ok(None) | Err(StoreError::BadName(_)) => {
            return Err(AdminError::NotFound(format!("unknown world `{name}`")).into())
        }
        Err(e) => return Err(e.into()),
    };
    admin.live.remove(&name);
    admin.store.remove_alias(&alias)?;
    admin.store.delete_object(ObjectKind::World, &id)?;
    Ok(StatusCode::NO_CONTENT)
}
