//! Metadata handlers: `/worlds`, `/worlds/{world}`, TileJSON per layer, the MapLibre style of a
//! world (`/styles/{world}.json`), its WMTS capabilities (`/worlds/{world}/WMTSCapabilities.xml`),
//! `/healthz`, `/metrics`. The documents themselves come from the
//! tiles crate ([`terrasynth_tiles::style`]); this module only adds the base URL of their
//! absolute URLs: the configured `public_url`, or else the `Host` (and `X-Forwarded-Proto`) the
//! request came with — then the answer says `Vary: Host, X-Forwarded-Proto`, so that caches keep
//! one copy per host — with the listening address standing in for a missing or invalid `Host`.
//! The documents carry a weak ETag of their bytes and `Cache-Control: no-cache`, and answer a
//! matching `If-None-Match` with 304 ([`super::conditional::revalidated`]).

use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use terrasynth_tiles::style::{style_json, tilejson_in, LAYERS};
use terrasynth_tiles::wmts::capabilities_xml;
use terrasynth_tiles::{TileJson, World};

use super::conditional::{bytes_etag, revalidated, revalidated_json};
use super::error::{Problem, ServerError};
use super::state::AppState;
use crate::config::ServerConfig;

/// JSON description of a world.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct WorldInfo {
    /// URL name.
    pub name: String,
    /// Human title.
    pub title: String,
    /// Attribution.
    pub attribution: String,
    /// `[west, south, east, north]`, degrees.
    pub bounds: [f64; 4],
    /// `[lon, lat, zoom]`.
    pub center: [f64; 3],
    /// Shallowest zoom.
    pub minzoom: u8,
    /// Deepest zoom.
    pub maxzoom: u8,
    /// Native zoom of the base.
    pub native_zoom: u8,
    /// Elevation outside the base coverage, metres.
    pub fill_m: f32,
    /// Layer names.
    pub layers: Vec<String>,
    /// Content ids of the synthesis chain's dictionaries.
    pub dictionaries: Vec<String>,
    /// The synthesis chain's zoom bands: each dictionary with the zooms it was given (a world
    /// with one dictionary: every amplified zoom).
    pub dictionary_bands: Vec<DictionaryBandInfo>,
    /// A biome world's painted biomes (#15), each with its dictionary, in the order given
    /// (absent: not a biome world).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub biomes: Vec<BiomeInfo>,
    /// TileJSON URL of each layer.
    pub tilejson: Vec<String>,
}

/// A dictionary of a world's chain and its zooms.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct DictionaryBandInfo {
    /// Content id of the dictionary.
    pub id: String,
    /// Its zooms, `"FIRST-LAST"` or `"ZOOM"`.
    pub zooms: String,
}

/// A painted biome of a world.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct BiomeInfo {
    /// The biome's name (its `biome.<name>` terms).
    pub name: String,
    /// Content id of its dictionary.
    pub dictionary: String,
}

fn bands(w: &World) -> Vec<DictionaryBandInfo> {
    let every = terrasynth_core::synth::ZoomBand {
        first: w.z_base().saturating_add(1).min(w.max_zoom()),
        last: w.max_zoom(),
    };
    w.dictionary_bands()
        .iter()
        .map(|(zooms, id)| DictionaryBandInfo {
            id: id.clone(),
            zooms: zooms.unwrap_or(every).to_string(),
        })
        .collect()
}

fn info(w: &World, base: &str) -> WorldInfo {
    WorldInfo {
        name: w.name().into(),
        title: w.title().into(),
        attribution: w.attribution().into(),
        bounds: w.bounds(),
        center: w.center(),
        minzoom: w.min_zoom(),
        maxzoom: w.max_zoom(),
        native_zoom: w.z_base(),
        fill_m: w.fill_m(),
        layers: LAYERS.iter().map(|s| s.to_string()).collect(),
        dictionaries: w.dictionary_ids(),
        dictionary_bands: bands(w),
        biomes: w
            .biome_names()
            .iter()
            .zip(w.dictionary_ids())
            .map(|(name, dictionary)| BiomeInfo {
                name: name.clone(),
                dictionary,
            })
            .collect(),
        tilejson: LAYERS
            .iter()
            .map(|l| format!("{base}/tiles/{}/{l}.json", w.name()))
            .collect(),
    }
}

/// The base of absolute URLs: `public_url` when configured; else the scheme and host the client
/// reached us at (`Some` of the `Vary` header the answer then needs).
fn base_url(config: &ServerConfig, headers: &HeaderMap) -> (String, Option<HeaderValue>) {
    if !config.public_url.is_empty() {
        return (config.public_url.clone(), None);
    }
    let fallback = fallback_host(&config.listen);
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .filter(|h| {
            !h.is_empty()
                && h.len() <= 255
                && h.chars()
                    .all(|c| c.is_ascii_alphanumeric() || ".-:[]".contains(c))
        })
        .unwrap_or(&fallback);
    let proto = headers
        .get("x-forwarded-proto")
        .and_then(|h| h.to_str().ok())
        .filter(|p| *p == "https" || *p == "http")
        .unwrap_or("http");
    (
        format!("{proto}://{host}"),
        Some(HeaderValue::from_static("Host, X-Forwarded-Proto")),
    )
}

/// The host of the listening address, with a wildcard address replaced by loopback (a client
/// cannot connect to `0.0.0.0`).
fn fallback_host(listen: &str) -> String {
    match listen.parse::<std::net::SocketAddr>() {
        Ok(a) if a.ip().is_unspecified() && a.is_ipv4() => format!("127.0.0.1:{}", a.port()),
        Ok(a) if a.ip().is_unspecified() => format!("[::1]:{}", a.port()),
        Ok(a) => a.to_string(),
        Err(_) => listen.to_string(),
    }
}

/// Every world.
#[utoipa::path(get, path = "/worlds", tag = "meta",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "Worlds; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = Vec<WorldInfo>),
        (status = 304, description = "Not modified (`If-None-Match` names the weak ETag of the document's bytes)"),
    ))]
pub async fn worlds(State(state): State<AppState>, headers: HeaderMap) -> Response {
    let (base, vary) = base_url(&state.config, &headers);
    let list: Vec<WorldInfo> = state.worlds.values().map(|w| info(w, &base)).collect();
    revalidated_json(&headers, &list, vary)
}

/// One world.
#[utoipa::path(get, path = "/worlds/{world}", tag = "meta",
    params(
        ("world" = String, Path, description = "World name"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "The world; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = WorldInfo),
        (status = 304, description = "Not modified (`If-None-Match` names the weak ETag of the document's bytes)"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn world(
    State(state): State<AppState>,
    Path(name): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let w = state.find_world(&name).await?;
    let (base, vary) = base_url(&state.config, &headers);
    Ok(revalidated_json(&headers, &info(&w, &base), vary))
}

/// TileJSON 3.0.0 of a layer.
#[utoipa::path(
    get,
    path = "/tiles/{world}/{file}",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name"),
        ("file" = String, Path, description = "`{layer}.json`"),
        ("tile_format" = Option<String>, Query, description = "`png` (default) or `webp` (lossless; `elevation` and `color`): the format of the tile URLs"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "TileJSON; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = TileJson),
        (status = 304, description = "Not modified (`If-None-Match` names the weak ETag of the document's bytes)"),
        (status = 404, description = "Unknown world or layer, or a layer without that tile format", body = Problem, content_type = "application/problem+json")
    )
)]
pub async fn tilejson(
    State(state): State<AppState>,
    Path((name, file)): Path<(String, String)>,
    Query(query): Query<std::collections::HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let w = state.find_world(&name).await?;
    let (base, vary) = base_url(&state.config, &headers);
    let format = query.get("tile_format").map_or("png", String::as_str);
    file.strip_suffix(".json")
        .and_then(|layer| tilejson_in(&w, &base, layer, format))
        .map(|t: TileJson| revalidated_json(&headers, &t, vary))
        .ok_or_else(|| ServerError::NotFound(format!("no TileJSON `{file}`")))
}

/// The OGC WMTS 1.0.0 capabilities of a world: its raster layers as PNG tile templates on the
/// `WebMercatorQuad` tile matrix set ([`terrasynth_tiles::wmts`]).
#[utoipa::path(
    get,
    path = "/worlds/{world}/WMTSCapabilities.xml",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "WMTS 1.0.0 capabilities (RESTful): every raster layer as a PNG `ResourceURL` template on `WebMercatorQuad` with the world's tile limits per zoom; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = String, content_type = "application/xml"),
        (status = 304, description = "Not modified (`If-None-Match` names the weak ETag of the document's bytes)"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    )
)]
pub async fn wmts_capabilities(
    State(state): State<AppState>,
    Path(name): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let w = state.find_world(&name).await?;
    let (base, vary) = base_url(&state.config, &headers);
    let xml = capabilities_xml(&w, &base);
    Ok(revalidated(
        &headers,
        &bytes_etag(xml.as_bytes()),
        xml.into(),
        HeaderValue::from_static("application/xml"),
        vary,
    ))
}

/// MapLibre style (version 8) of a world: its raster-dem as terrain and hillshade, the colour
/// map, vegetation overlay and drainage overlay as raster layers switchable with
/// `layout.visibility`.
#[utoipa::path(
    get,
    path = "/styles/{file}",
    tag = "tiles",
    params(
        ("file" = String, Path, description = "`{world}.json`"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "MapLibre style; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = Object),
        (status = 304, description = "Not modified (`If-None-Match` names the weak ETag of the document's bytes)"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    )
)]
pub async fn style(
    State(state): State<AppState>,
    Path(file): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let name = file
        .strip_suffix(".json")
        .ok_or_else(|| ServerError::NotFound(format!("no style `{file}`")))?;
    let w = state.find_world(name).await?;
    let (base, vary) = base_url(&state.config, &headers);
    Ok(revalidated_json(&headers, &style_json(&w, &base), vary))
}

/// Liveness.
#[utoipa::path(get, path = "/healthz", tag = "meta",
    responses((status = 200, description = "`ok`", body = String, content_type = "text/plain")))]
pub async fn healthz() -> Response {
    let mut resp = "ok".into_response();
    resp.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    resp
}

/// Prometheus metrics.
#[utoipa::path(get, path = "/metrics", tag = "meta",
    responses((status = 200, description = "Prometheus text exposition", body = String, content_type = "text/plain")))]
pub async fn metrics(State(state): State<AppState>) -> Response {
    let state2 = state.clone();
    let text = tokio::task::spawn_blocking(move || {
        state2
            .metrics
            .render(state2.worlds.values().map(|w| w.as_ref()))
    })
    .await
    .unwrap_or_default();
    let mut resp = text.into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; version=0.0.4"),
    );
    resp
}
