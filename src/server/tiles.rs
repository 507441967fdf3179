//! The tile handler: `GET/HEAD /tiles/{world}/{layer}/{z}/{x}/{y}.{ext}`. It parses the request
//! (the tiles crate's [`parse_request`]), answers `If-None-Match` with 304 from the strong ETag
//! without computing anything, serves encoded tiles from the byte cache, and computes a miss on
//! the blocking pool behind a bounded queue (full → 503), never on an async runtime thread.

use std::collections::HashMap;
use std::sync::Arc;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use terrasynth_tiles::{check_against_world, etag, parse_request, render, TileError};

use super::error::{Problem, ServerError};
use super::state::AppState;

fn etag_matches(headers: &HeaderMap, tag: &str) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .any(|t| t == "*" || t == tag || t.strip_prefix("W/") == Some(tag))
}

/// A tile.
#[utoipa::path(
    get,
    path = "/tiles/{world}/{layer}/{z}/{x}/{y}",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name", example = "tienshan"),
        ("layer" = String, Path, description = "Layer: `elevation`, `hillshade`, or any other layer the world lists in `/worlds/{world}`"),
        ("z" = String, Path, description = "Zoom"),
        ("x" = String, Path, description = "Column"),
        ("y" = String, Path, description = "Row with the format extension: `{y}.png`, `{y}@2x.png` (512 px) or `{y}.exr` (float32)"),
        ("encoding" = Option<String>, Query, description = "Elevation PNG packing: `terrarium` (default) or `mapbox`"),
        ("azimuth" = Option<String>, Query, description = "Hillshade sun azimuth, degrees (0–360, default 315)"),
        ("altitude" = Option<String>, Query, description = "Hillshade sun altitude, degrees (0–90, default 45)"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "The tile; strong `ETag`, `Cache-Control` from the configuration",
            content(("image/png"), ("image/x-exr"))),
        (status = 304, description = "Not modified (the `If-None-Match` ETag matches)"),
        (status = 400, description = "Malformed coordinates or parameters", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world, layer or format, zoom too deep, tile outside the world", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Synthesis queue full (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    )
)]
pub async fn tile(
    State(state): State<AppState>,
    Path((world_name, layer, z, x, y_ext)): Path<(String, String, String, String, String)>,
    Query(query): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let world = state.world(&world_name)?;
    let req = parse_request(&world_name, &layer, &z, &x, &y_ext, &query)?;
    check_against_world(&world, &req)?;
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
                    .map_err(|e: Arc<TileError>| ServerError::Tile((*e).clone()))
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
