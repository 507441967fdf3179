//! Metadata handlers: `/worlds`, `/worlds/{world}`, TileJSON per layer, `/healthz`, `/metrics`.

use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;

use super::error::ServerError;
use super::AppState;
use crate::tiles::{TerrainEncoding, TileJson, World};

/// The layers every world serves.
pub const LAYERS: [&str; 2] = ["elevation", "hillshade"];

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
    /// TileJSON URL of each layer.
    pub tilejson: Vec<String>,
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
        tilejson: LAYERS
            .iter()
            .map(|l| format!("{base}/tiles/{}/{l}.json", w.name()))
            .collect(),
    }
}

/// The scheme and host clients reached us at, for absolute URLs in TileJSON.
fn base_url(headers: &HeaderMap) -> String {
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .filter(|h| {
            h.chars()
                .all(|c| c.is_ascii_alphanumeric() || ".-:[]".contains(c))
        })
        .unwrap_or("127.0.0.1:8080");
    let proto = headers
        .get("x-forwarded-proto")
        .and_then(|h| h.to_str().ok())
        .filter(|p| *p == "https" || *p == "http")
        .unwrap_or("http");
    format!("{proto}://{host}")
}

/// `GET /worlds`.
pub async fn worlds(State(state): State<AppState>, headers: HeaderMap) -> Json<Vec<WorldInfo>> {
    let base = base_url(&headers);
    Json(state.worlds.values().map(|w| info(w, &base)).collect())
}

/// `GET /worlds/{world}`.
pub async fn world(
    State(state): State<AppState>,
    Path(name): Path<String>,
    headers: HeaderMap,
) -> Result<Json<WorldInfo>, ServerError> {
    let w = state
        .worlds
        .get(&name)
        .ok_or_else(|| ServerError::NotFound(format!("unknown world `{name}`")))?;
    Ok(Json(info(w, &base_url(&headers))))
}

/// `GET /tiles/{world}/{layer}.json`: TileJSON 3.0.0.
pub async fn tilejson(
    State(state): State<AppState>,
    Path((name, file)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Json<TileJson>, ServerError> {
    let w = state
        .worlds
        .get(&name)
        .ok_or_else(|| ServerError::NotFound(format!("unknown world `{name}`")))?;
    let layer = file
        .strip_suffix(".json")
        .filter(|l| LAYERS.contains(l))
        .ok_or_else(|| ServerError::NotFound(format!("no TileJSON `{file}`")))?;
    let base = format!("{}/tiles", base_url(&headers));
    let mut tj = TileJson::new(
        &base,
        w.name(),
        layer,
        "png",
        w.min_zoom(),
        w.max_zoom(),
        w.bounds(),
    )
    .with_attribution(w.attribution());
    tj.center = w.center();
    tj.name = format!("{} {layer}", w.title());
    if layer == "elevation" {
        tj = tj
            .with_encoding(TerrainEncoding::Terrarium)
            .with_tile_size(256);
    }
    Ok(Json(tj))
}

/// `GET /healthz`.
pub async fn healthz() -> Response {
    let mut resp = "ok".into_response();
    resp.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    resp
}

/// `GET /metrics`: Prometheus text.
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
