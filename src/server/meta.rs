//! Metadata handlers: `/worlds`, `/worlds/{world}`, TileJSON per layer, the MapLibre style of a
//! world (`/styles/{world}.json`), `/healthz`, `/metrics`.

use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;

use super::error::ServerError;
use super::AppState;
use crate::tiles::{TerrainEncoding, TileJson, World};

/// The layers every world serves.
pub const LAYERS: [&str; 6] = [
    "elevation",
    "hillshade",
    "vegetation",
    "drainage",
    "splat",
    "color",
];

/// What the TileJSON of a landscape layer says about its tiles.
fn layer_description(w: &World, layer: &str) -> Option<String> {
    let l = w.landscape();
    let names = |v: Vec<&str>| v.join(", ");
    match layer {
        "vegetation" => Some(format!(
            "Species densities × 255, one a channel (set n = species 4n..4n+3 with ?set=n; \
             ?style=overlay for a coloured overlay); .exr: float densities, one named channel \
             per species. Species: {}",
            names(l.species.iter().map(|s| s.name.as_str()).collect())
        )),
        "drainage" => Some(
            "Upstream area in m²: .exr float32 channel upstream_area; .png log-scaled rivers on \
             transparent"
                .into(),
        ),
        "splat" => Some(format!(
            "Material weights, RGBA = materials 4n..4n+3 of ?set=n (all sets of a pixel sum to \
             255). Materials: {}",
            names(l.materials.iter().map(|m| m.name.as_str()).collect())
        )),
        "color" => Some("Baked material colour shaded by the hillshade".into()),
        _ => None,
    }
}

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
    if let Some(d) = layer_description(w, layer) {
        tj = tj.with_description(d).with_tile_size(256);
    }
    Ok(Json(tj))
}

/// `GET /styles/{world}.json`: a MapLibre style (version 8) with the world's raster-dem as 3D
/// terrain and hillshade, and the colour map, vegetation overlay and drainage overlay as raster
/// layers switchable through `layout.visibility` (colour and drainage visible, vegetation not).
pub async fn style(
    State(state): State<AppState>,
    Path(file): Path<String>,
    headers: HeaderMap,
) -> Result<Json<serde_json::Value>, ServerError> {
    let name = file
        .strip_suffix(".json")
        .ok_or_else(|| ServerError::NotFound(format!("no style `{file}`")))?;
    let w = state
        .worlds
        .get(name)
        .ok_or_else(|| ServerError::NotFound(format!("unknown world `{name}`")))?;
    Ok(Json(style_json(w, &base_url(&headers))))
}

/// The MapLibre style of world `w` served at `base`.
pub fn style_json(w: &World, base: &str) -> serde_json::Value {
    let n = w.name();
    let tiles =
        |layer: &str, ext: &str| format!("{base}/tiles/{n}/{layer}/{{z}}/{{x}}/{{y}}.{ext}");
    let raster = |url: String| {
        serde_json::json!({
            "type": "raster",
            "tiles": [url],
            "tileSize": 256,
            "minzoom": w.min_zoom(),
            "maxzoom": w.max_zoom(),
            "bounds": w.bounds(),
            "attribution": w.attribution(),
        })
    };
    let dem = serde_json::json!({
        "type": "raster-dem",
        "url": format!("{base}/tiles/{n}/elevation.json"),
        "tileSize": 256,
        "encoding": "terrarium",
    });
    let c = w.center();
    serde_json::json!({
        "version": 8,
        "name": w.title(),
        "center": [c[0], c[1]],
        "zoom": c[2],
        "pitch": 45,
        "sources": {
            "terrain": dem.clone(),
            "hillshade": dem,
            "color": raster(tiles("color", "png")),
            "vegetation": raster(format!("{}?style=overlay", tiles("vegetation", "png"))),
            "drainage": raster(tiles("drainage", "png")),
        },
        "terrain": { "source": "terrain", "exaggeration": 1.0 },
        "layers": [
            { "id": "background", "type": "background",
              "paint": { "background-color": "#d8d4c8" } },
            { "id": "color", "type": "raster", "source": "color",
              "layout": { "visibility": "visible" } },
            { "id": "vegetation", "type": "raster", "source": "vegetation",
              "layout": { "visibility": "none" }, "paint": { "raster-opacity": 0.8 } },
            { "id": "hillshade", "type": "hillshade", "source": "hillshade",
              "layout": { "visibility": "visible" },
              "paint": { "hillshade-exaggeration": 0.35 } },
            { "id": "drainage", "type": "raster", "source": "drainage",
              "layout": { "visibility": "visible" } },
        ],
    })
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
