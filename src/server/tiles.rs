//! Tile handlers: elevation (terrarium or mapbox PNG, 256 or 512 px, float32 EXR) and hillshade
//! PNG. Encoded tiles are cached by everything that determines their bytes; a miss is computed on
//! the blocking pool behind a bounded queue (full → 503), never on an async runtime thread.

use std::collections::HashMap;
use std::sync::Arc;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use ndarray::s;
use sha2::{Digest, Sha256};

use super::error::ServerError;
use super::AppState;
use crate::analysis::{hillshade_u8, DEFAULT_ALTITUDE_DEG, DEFAULT_AZIMUTH_DEG};
use crate::synth::Window;
use crate::tiles::{
    encode_float_exr, encode_gray_png, encode_mapbox_png, encode_terrarium_png, World,
};

/// What a tile request asks for, parsed and validated.
#[derive(Clone, Debug, PartialEq)]
pub struct TileRequest {
    /// World name.
    pub world: String,
    /// Layer and format.
    pub kind: TileKind,
    /// Zoom.
    pub z: u8,
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
}

/// A layer in one encoding.
#[derive(Clone, Debug, PartialEq)]
pub enum TileKind {
    /// Terrarium (or mapbox Terrain-RGB) PNG; `retina` for 512 px.
    ElevationPng {
        /// Mapbox Terrain-RGB instead of terrarium.
        mapbox: bool,
        /// 512 px (`@2x`).
        retina: bool,
    },
    /// Float32 metres, one channel.
    ElevationExr,
    /// Grey hillshade with sun azimuth and altitude in degrees.
    Hillshade {
        /// Sun azimuth, degrees clockwise from north.
        azimuth: f32,
        /// Sun altitude above the horizon, degrees.
        altitude: f32,
    },
}

impl TileKind {
    fn content_type(&self) -> &'static str {
        match self {
            TileKind::ElevationExr => "image/x-exr",
            _ => "image/png",
        }
    }
}

fn parse_num<T: std::str::FromStr>(what: &str, v: &str) -> Result<T, ServerError> {
    v.parse()
        .map_err(|_| ServerError::BadRequest(format!("{what} `{v}` is not a valid number")))
}

/// Parses `{layer}/{z}/{x}/{y}.{ext}` and the query into a request.
pub fn parse_request(
    world: &str,
    layer: &str,
    z: &str,
    x: &str,
    y_ext: &str,
    query: &HashMap<String, String>,
) -> Result<TileRequest, ServerError> {
    let z: u8 = parse_num("zoom", z)?;
    let x: u32 = parse_num("x", x)?;
    let (stem, ext) = y_ext
        .rsplit_once('.')
        .ok_or_else(|| ServerError::NotFound(format!("`{y_ext}` has no format extension")))?;
    let (y_str, retina) = match stem.strip_suffix("@2x") {
        Some(y) => (y, true),
        None => (stem, false),
    };
    let y: u32 = parse_num("y", y_str)?;
    for key in query.keys() {
        if !matches!(key.as_str(), "encoding" | "azimuth" | "altitude") {
            return Err(ServerError::BadRequest(format!(
                "unknown query parameter `{key}`"
            )));
        }
    }
    let kind = match (layer, ext) {
        ("elevation", "png") => {
            let mapbox = match query.get("encoding").map(String::as_str) {
                None | Some("terrarium") => false,
                Some("mapbox") => true,
                Some(other) => {
                    return Err(ServerError::BadRequest(format!(
                        "encoding `{other}`: expected `terrarium` or `mapbox`"
                    )))
                }
            };
            TileKind::ElevationPng { mapbox, retina }
        }
        ("elevation", "exr") if !retina => TileKind::ElevationExr,
        ("hillshade", "png") if !retina => {
            let azimuth = match query.get("azimuth") {
                Some(v) => parse_num::<f32>("azimuth", v)?,
                None => DEFAULT_AZIMUTH_DEG,
            };
            let altitude = match query.get("altitude") {
                Some(v) => parse_num::<f32>("altitude", v)?,
                None => DEFAULT_ALTITUDE_DEG,
            };
            if !azimuth.is_finite() || !(0.0..=360.0).contains(&azimuth) {
                return Err(ServerError::BadRequest(format!(
                    "azimuth {azimuth} must lie in [0, 360]"
                )));
            }
            if !altitude.is_finite() || !(0.0..=90.0).contains(&altitude) {
                return Err(ServerError::BadRequest(format!(
                    "altitude {altitude} must lie in [0, 90]"
                )));
            }
            TileKind::Hillshade { azimuth, altitude }
        }
        ("elevation" | "hillshade", _) => {
            return Err(ServerError::NotFound(format!(
                "layer `{layer}` has no format `{}{ext}`",
                if retina { "@2x." } else { "" }
            )))
        }
        _ => return Err(ServerError::NotFound(format!("unknown layer `{layer}`"))),
    };
    Ok(TileRequest {
        world: world.to_string(),
        kind,
        z,
        x,
        y,
    })
}

/// The strong ETag of a request: a hash of everything that determines the tile's bytes (the
/// world's fingerprint, layer, encoding, parameters and coordinates), so that a matching
/// `If-None-Match` is answered without computing anything.
pub fn etag(world: &World, req: &TileRequest) -> String {
    let mut h = Sha256::new();
    h.update(world.fingerprint().as_bytes());
    h.update(format!("|{:?}|{}|{}|{}", req.kind, req.z, req.x, req.y).as_bytes());
    let d = h.finalize();
    let hex: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
    format!("\"{hex}\"")
}

/// Computes and encodes a tile (CPU-bound: runs on the blocking pool).
pub fn render(world: &World, req: &TileRequest) -> Result<Vec<u8>, ServerError> {
    let (z, x, y) = (req.z, req.x, req.y);
    world.check_tile(z, x, y)?;
    let bytes = match &req.kind {
        TileKind::ElevationPng { mapbox, retina } => {
            let heights = if *retina {
                let w = Window::new(i64::from(x) * 512, i64::from(y) * 512, 512, 512);
                Arc::new(world.elevation_window(z + 1, w)?)
            } else {
                world.elevation_tile(z, x, y)?
            };
            if *mapbox {
                encode_mapbox_png(&heights)?
            } else {
                encode_terrarium_png(&heights)?
            }
        }
        TileKind::ElevationExr => {
            let heights = world.elevation_tile(z, x, y)?;
            encode_float_exr(&[("elevation", &heights)])?
        }
        TileKind::Hillshade { azimuth, altitude } => {
            // One pixel of border from the neighbouring tiles makes the shade seamless.
            let w = Window::new(i64::from(x) * 256 - 1, i64::from(y) * 256 - 1, 258, 258);
            let heights = world.elevation_window(z, w)?;
            let cells = world.cell_sizes(z, w.row0, w.rows);
            let shade = hillshade_u8(&heights, &cells, *azimuth, *altitude);
            encode_gray_png(&shade.slice(s![1..257, 1..257]).to_owned())?
        }
    };
    Ok(bytes)
}

fn etag_matches(headers: &HeaderMap, tag: &str) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .any(|t| t == "*" || t == tag || t.strip_prefix("W/") == Some(tag))
}

/// `GET/HEAD /tiles/{world}/{layer}/{z}/{x}/{y}.{ext}`.
pub async fn tile(
    State(state): State<AppState>,
    Path((world_name, layer, z, x, y_ext)): Path<(String, String, String, String, String)>,
    Query(query): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let world = state
        .worlds
        .get(&world_name)
        .cloned()
        .ok_or_else(|| ServerError::NotFound(format!("unknown world `{world_name}`")))?;
    let req = parse_request(&world_name, &layer, &z, &x, &y_ext, &query)?;
    world.check_tile(req.z, req.x, req.y)?;
    let tag = etag(&world, &req);
    let cache_control = state.cache_control.clone();
    let respond = |status: StatusCode, body: Body| -> Response {
        let mut resp = (status, body).into_response();
        let h = resp.headers_mut();
        if let Ok(v) = HeaderValue::from_str(&tag) {
            h.insert(header::ETAG, v);
        }
        h.insert(header::CACHE_CONTROL, cache_control.clone());
        resp
    };
    if etag_matches(&headers, &tag) {
        return Ok(respond(StatusCode::NOT_MODIFIED, Body::empty()));
    }
    let content_type = HeaderValue::from_static(req.kind.content_type());
    let bytes = match state.tile_bytes.get(&tag) {
        Some(b) => b,
        None => {
            let _slot = state.queue.enter()?;
            let permit = state
                .synth
                .clone()
                .acquire_owned()
                .await
                .map_err(|e| ServerError::Internal(e.to_string()))?;
            let cache = state.tile_bytes.clone();
            let key = tag.clone();
            tokio::task::spawn_blocking(move || {
                let _permit = permit;
                cache
                    .try_get_with(key, || render(&world, &req).map(Bytes::from))
                    .map_err(|e: Arc<ServerError>| match &*e {
                        ServerError::Tile(t) => ServerError::Tile(t.clone()),
                        other => ServerError::Internal(other.to_string()),
                    })
            })
            .await
            .map_err(|e| ServerError::Internal(e.to_string()))??
        }
    };
    let mut resp = respond(StatusCode::OK, Body::from(bytes));
    resp.headers_mut()
        .insert(header::CONTENT_TYPE, content_type);
    Ok(resp)
}
