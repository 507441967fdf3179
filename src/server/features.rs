//! `GET /worlds/{world}/features.geojson`: the ridges and valleys of a world's base (PPA,
//! computed once per world by [`terrasynth_tiles::World::features`]) as a GeoJSON
//! `FeatureCollection` of `LineString`s in longitude/latitude with `kind` and
//! `mean_elevation_m`. The computation runs on the blocking pool behind the synthesis
//! semaphore; the answer carries a strong ETag derived from the world's fingerprint. Clients that
//! accept gzip get it gzip-coded ([`super::encoding`]), compressed once and cached compressed.

use std::collections::HashMap;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use terrasynth_core::analysis::ppa::FeatureTree;
use terrasynth_core::synth::sketch::geojson::write_features_geojson;
use terrasynth_tiles::{gzip, TileError, World};

use super::conditional::none_match;
use super::encoding::Coding;
use super::error::{Problem, ServerError};
use super::state::AppState;

/// Which trees a request asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kinds {
    Ridge,
    Valley,
    All,
}

impl Kinds {
    fn parse(q: Option<&String>) -> Result<Kinds, ServerError> {
        match q.map(String::as_str) {
            None | Some("all") => Ok(Kinds::All),
            Some("ridge") => Ok(Kinds::Ridge),
            Some("valley") => Ok(Kinds::Valley),
            Some(other) => Err(ServerError::BadRequest(format!(
                "kind `{other}` must be ridge, valley or all"
            ))),
        }
    }

    fn as_str(self) -> &'static str {
        match self {
            Kinds::Ridge => "ridge",
            Kinds::Valley => "valley",
            Kinds::All => "all",
        }
    }
}

/// Ridges and valleys of a world's base.
#[utoipa::path(get, path = "/worlds/{world}/features.geojson", tag = "meta",
    params(
        ("world" = String, Path, description = "World name"),
        ("kind" = Option<String>, Query, description = "`ridge`, `valley` or `all` (default)",
            pattern = "^(ridge|valley|all)$")
    ),
    responses(
        (status = 200, description = "GeoJSON FeatureCollection of LineStrings (lon/lat) with properties `kind`, `mean_elevation_m`, `cells`, `start`, `end`. Gzip-coded (`Content-Encoding: gzip`, an ETag of its own ending `-gzip\"`) when the request's `Accept-Encoding` takes gzip; `Vary: Accept-Encoding`", body = Object, content_type = "application/geo+json"),
        (status = 304, description = "Not modified (`If-None-Match`)"),
        (status = 400, description = "Bad `kind`", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn features(
    State(state): State<AppState>,
    Path(name): Path<String>,
    Query(query): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let world = state.find_world(&name).await?;
    let kinds = Kinds::parse(query.get("kind"))?;
    let coding = Coding::negotiate(&headers);
    let fp = world.fingerprint();
    let identity_tag = format!(
        "\"features-{}-{}\"",
        &fp[..fp.len().min(32)],
        kinds.as_str()
    );
    let tag = coding.etag(&identity_tag);
    let tag_value =
        HeaderValue::from_str(&tag).map_err(|e| ServerError::Internal(e.to_string()))?;
    if none_match(&headers, &tag) {
        let mut resp = StatusCode::NOT_MODIFIED.into_response();
        resp.headers_mut().insert(header::ETAG, tag_value);
        coding.mark(resp.headers_mut());
        return Ok(resp);
    }
    let bytes: Bytes = match coding {
        // Gzip-coded (a few MB for the default world), cached with the tiles.
        Coding::Gzip => {
            state
                .cached_bytes(&tag, move || gzip(&features_json(&world, kinds)?))
                .await?
        }
        // Identity (ten times larger) is not cached: decompressed from the cached gzip bytes,
        // else computed again.
        Coding::Identity => {
            let cache = state.tile_bytes.clone();
            let gz_tag = Coding::Gzip.etag(&identity_tag);
            state
                .compute(move || {
                    Ok(match cache.get(&gz_tag) {
                        Some(gz) => Coding::Identity.from_other(&gz)?,
                        None => features_json(&world, kinds)?,
                    })
                })
                .await?
                .into()
        }
    };
    let mut resp = (StatusCode::OK, Body::from(bytes)).into_response();
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/geo+json"),
    );
    h.insert(header::ETAG, tag_value);
    h.insert(header::CACHE_CONTROL, state.cache_control.clone());
    coding.mark(h);
    Ok(resp)
}

/// The GeoJSON of `world`'s trees of `kinds`.
fn features_json(world: &World, kinds: Kinds) -> Result<Vec<u8>, TileError> {
    let f = world.features()?;
    let mut trees: Vec<&FeatureTree> = Vec::new();
    if kinds != Kinds::Valley {
        trees.push(&f.ridges);
    }
    if kinds != Kinds::Ridge {
        trees.push(&f.valleys);
    }
    let mut json = Vec::new();
    write_features_geojson(&trees, &world.base_georef(), &mut json)
        .map_err(|e| TileError::Encode(format!("features GeoJSON: {e}")))?;
    Ok(json)
}
