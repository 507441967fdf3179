//! The tile handler: `GET/HEAD /tiles/{world}/{layer}/{z}/{x}/{y}.{ext}`. It parses the request
//! strictly from the raw path (the tiles crate's [`parse_request`]: one spelling per tile),
//! answers `If-None-Match` with 304 from the strong ETag without computing anything, serves
//! encoded tiles from the byte cache, and computes a miss on the blocking pool behind a bounded
//! queue (full → 503), never on an async runtime thread. The computation runs under a
//! cancellation token the handler's future holds: when the client leaves or the deadline passes,
//! the synthesis stops unless another request still waits for it. Vector and GeoJSON tiles go
//! out gzip-coded to clients that accept it ([`super::encoding`]), compressed with the tile's
//! computation and cached compressed.

use axum::body::Body;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode, Uri};
use axum::response::{IntoResponse, Response};

use terrasynth_tiles::{
    check_against_world, etag, gzip, parse_request, query_map, render, RequestError,
};

use super::conditional::none_match;
use super::encoding::Coding;
use super::error::{Problem, ServerError};
use super::state::AppState;

/// The raw (still percent-encoded) segments `world, layer, z, x, y.ext` of a tile path.
fn tile_segments(uri: &Uri) -> Result<[&str; 5], ServerError> {
    let mut parts = uri.path().split('/').skip(1);
    let (Some("tiles"), Some(w), Some(l), Some(z), Some(x), Some(y), None) = (
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
    ) else {
        return Err(ServerError::NotFound("no such resource".into()));
    };
    Ok([w, l, z, x, y])
}

/// A tile.
#[utoipa::path(
    get,
    path = "/tiles/{world}/{layer}/{z}/{x}/{y}",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name", example = "tienshan"),
        ("layer" = String, Path, description = "Layer: `elevation`, `hillshade`, or any other layer the world lists in `/worlds/{world}`"),
        ("z" = String, Path, description = "Zoom (a canonical decimal integer: no sign, no leading zero)",
            pattern = "^(0|[1-9][0-9]*)$"),
        ("x" = String, Path, description = "Column (a canonical decimal integer)",
            pattern = "^(0|[1-9][0-9]*)$"),
        ("y" = String, Path, description = "Row with the format extension: `{y}.png`, `{y}@2x.png` (512 px) or `{y}.exr` (float32); elevation and colour also `{y}.webp` (lossless; elevation `{y}@2x.webp` too); instances: `{y}.mvt` (Mapbox Vector Tile 2.1) or `{y}.json` (GeoJSON); contours: `{y}.mvt`",
            pattern = "^(0|[1-9][0-9]*)(@2x)?\\.(png|webp|exr|mvt|json)$"),
        ("encoding" = Option<String>, Query, description = "Elevation PNG packing: `terrarium` (default) or `mapbox`",
            pattern = "^(terrarium|mapbox)$"),
        ("azimuth" = Option<String>, Query, description = "Hillshade sun azimuth, degrees (0–360, default 315)"),
        ("altitude" = Option<String>, Query, description = "Hillshade sun altitude, degrees (0–90, default 45)"),
        ("set" = Option<String>, Query, description = "Vegetation and splat tiles: which group of four species (materials) the RGBA channels carry, 0 (default) to ⌈count/4⌉ − 1",
            pattern = "^(0|[1-9][0-9]*)$"),
        ("style" = Option<String>, Query, description = "Vegetation tiles: `channels` (default: one species per RGBA channel) or `overlay` (the species colours blended by density, alpha the total density)",
            pattern = "^(channels|overlay)$"),
        ("interval" = Option<String>, Query, description = "Contour interval, metres (positive, at least a quarter of the zoom's pixel; default: the largest of 1, 2, 5 × 10^n m not above four pixels)"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "The tile; strong `ETag`, `Cache-Control` from the configuration. Vector (`.mvt`) and GeoJSON tiles are gzip-coded (`Content-Encoding: gzip`, an ETag of their own ending `-gzip\"`) when the request's `Accept-Encoding` takes gzip, and carry `Vary: Accept-Encoding`",
            content(("image/png"), ("image/x-exr"), ("application/vnd.mapbox-vector-tile"), ("application/geo+json"))),
        (status = 304, description = "Not modified (the `If-None-Match` ETag matches)"),
        (status = 400, description = "Malformed or non-canonical coordinates (sign, leading zeros, percent-encoding), unknown or repeated parameters, parameters that do not apply to the format, a contour interval that is not positive or too dense", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world, layer or format, zoom too deep, tile outside the world", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Synthesis queue full or request timed out (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    )
)]
pub async fn tile(
    State(state): State<AppState>,
    uri: Uri,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let [world_name, layer, z, x, y_ext] = tile_segments(&uri)?;
    let Query(pairs) =
        query.map_err(|e| RequestError::BadRequest(format!("malformed query: {e}")))?;
    let query = query_map(&pairs)?;
    let world = state.find_world(world_name).await?;
    let req = parse_request(world_name, layer, z, x, y_ext, &query)?;
    check_against_world(&world, &req)?;
    world.check_tile(req.z, req.x, req.y)?;
    // The representation served: its coding, and the strong ETag (also the cache key) of the
    // bytes in that coding.
    let coding = if req.kind.compressible() {
        Some(Coding::negotiate(&headers))
    } else {
        None
    };
    let (tag, other_tag) = match coding {
        Some(c) => {
            let identity = etag(&world, &req);
            (c.etag(&identity), Some(c.other().etag(&identity)))
        }
        None => (etag(&world, &req), None),
    };
    let cache_control = state.cache_control.clone();
    let respond = |status: StatusCode, body: Body| -> Response {
        let mut resp = (status, body).into_response();
        let h = resp.headers_mut();
        if let Ok(v) = HeaderValue::from_str(&tag) {
            h.insert(header::ETAG, v);
        }
        h.insert(header::CACHE_CONTROL, cache_control.clone());
        if let Some(c) = coding {
            c.mark(h);
        }
        resp
    };
    if none_match(&headers, &tag) {
        return Ok(respond(StatusCode::NOT_MODIFIED, Body::empty()));
    }
    let content_type = HeaderValue::from_static(req.kind.content_type());
    let other_coding = other_tag.map(|t| (state.tile_bytes.clone(), t));
    let bytes = state
        .cached_bytes(&tag, move || {
            // The other coding of the tile, when cached, is recoded instead of computing it.
            let other = other_coding.and_then(|(cache, t)| cache.get(&t));
            match (coding, other) {
                (Some(c), Some(other)) => c.from_other(&other),
                (Some(Coding::Gzip), None) => gzip(&render(&world, &req)?),
                _ => render(&world, &req),
            }
        })
        .await?;
    let mut resp = respond(StatusCode::OK, Body::from(bytes));
    resp.headers_mut()
        .insert(header::CONTENT_TYPE, content_type);
    Ok(resp)
}
