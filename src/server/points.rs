//! Point queries of the served elevation: `GET /worlds/{world}/elevation?lon=&lat=&z=` and
//! `POST /worlds/{world}/elevation` with up to [`MAX_POINTS`] points (a profile along a line).
//! Values are the float32 metres of the elevation tiles the map shows (the `.exr` tile's pixel
//! that contains the point), computed on the blocking pool behind the synthesis semaphore by
//! [`terrasynth_tiles::point`]; this module only translates HTTP.

use std::collections::HashMap;

use axum::extract::{Path, Query, Request, State};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use terrasynth_tiles::point::{elevations, PointError};
use terrasynth_tiles::World;

use super::admin::extract::json_body;
use super::error::{Problem, ServerError};
use super::state::AppState;

/// Most points of one `POST /worlds/{world}/elevation`.
pub const MAX_POINTS: usize = 10_000;

/// The elevation at one point.
#[derive(Debug, Serialize, ToSchema)]
pub struct PointElevation {
    /// Longitude, degrees.
    pub lon: f64,
    /// Latitude, degrees.
    pub lat: f64,
    /// Served elevation, metres (`null` outside the world).
    pub elevation_m: Option<f32>,
    /// The zoom whose tile answered.
    pub z: u8,
}

/// Points of a profile.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ElevationRequest {
    /// `[lon, lat]` pairs in degrees, at most 10,000.
    pub points: Vec<[f64; 2]>,
    /// Zoom to read (default: the world's opening zoom; deeper than the world: its deepest).
    #[serde(default)]
    pub z: Option<u8>,
}

/// The elevations of a profile, in the order of the points.
#[derive(Debug, Serialize, ToSchema)]
pub struct ElevationProfile {
    /// The zoom whose tiles answered.
    pub z: u8,
    /// Metres at each point (`null` outside the world).
    pub elevations_m: Vec<Option<f32>>,
}

/// The zoom a query reads: the asked one capped at the world's deepest, by default the world's
/// opening zoom.
fn zoom_used(world: &World, z: Option<u8>) -> u8 {
    let opening = world.center()[2].clamp(0.0, f64::from(world.max_zoom())) as u8;
    z.map_or(opening, |z| z.min(world.max_zoom()))
}

/// Elevations at `points`, computed through [`AppState::compute`] (queue, permit, cancellation).
async fn compute(
    state: &AppState,
    world: std::sync::Arc<World>,
    z: u8,
    points: Vec<(f64, f64)>,
) -> Result<Vec<Option<f32>>, ServerError> {
    state
        .compute(move || {
            elevations(&world, z, &points).map_err(|e| match e {
                PointError::OutOfRange { index, why } => {
                    ServerError::Invalid(format!("point {index}: {why}"))
                }
                PointError::Tile(e) => ServerError::Tile(e),
            })
        })
        .await
}

fn number(query: &HashMap<String, String>, key: &str) -> Result<Option<f64>, ServerError> {
    query
        .get(key)
        .map(|v| {
            v.parse::<f64>()
                .map_err(|_| ServerError::BadRequest(format!("`{key}` = `{v}` is not a number")))
        })
        .transpose()
}

/// The served elevation at one point.
#[utoipa::path(get, path = "/worlds/{world}/elevation", tag = "meta",
    params(
        ("world" = String, Path, description = "World name", example = "tienshan"),
        ("lon" = f64, Query, description = "Longitude, degrees (−180..180)", example = 72.5,
            minimum = -180.0, maximum = 180.0),
        ("lat" = f64, Query, description = "Latitude, degrees (±85.0511)", example = 42.4,
            minimum = -85.051_128_779_806_59, maximum = 85.051_128_779_806_59),
        ("z" = Option<u8>, Query, description = "Zoom to read (default the world's opening zoom; capped at its deepest)",
            maximum = 255)
    ),
    responses(
        (status = 200, description = "Metres at the point, and the zoom used", body = PointElevation),
        (status = 400, description = "Missing, malformed or unknown parameters", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world, or a point outside it", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Coordinates out of range", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Synthesis queue full", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn elevation_at(
    State(state): State<AppState>,
    Path(name): Path<String>,
    Query(query): Query<HashMap<String, String>>,
) -> Result<Response, ServerError> {
    let world = state.find_world(&name).await?;
    if let Some(k) = query
        .keys()
        .find(|k| !["lon", "lat", "z"].contains(&k.as_str()))
    {
        return Err(ServerError::BadRequest(format!(
            "unknown query parameter `{k}`"
        )));
    }
    let missing = |k: &str| ServerError::BadRequest(format!("query parameter `{k}` is required"));
    let lon = number(&query, "lon")?.ok_or_else(|| missing("lon"))?;
    let lat = number(&query, "lat")?.ok_or_else(|| missing("lat"))?;
    let z = query
        .get("z")
        .map(|v| {
            v.parse::<u8>()
                .map_err(|_| ServerError::BadRequest(format!("`z` = `{v}` is not a zoom")))
        })
        .transpose()?;
    let z = zoom_used(&world, z);
    let values = compute(&state, world, z, vec![(lon, lat)]).await?;
    let elevation_m = values.first().copied().flatten();
    if elevation_m.is_none() {
        return Err(ServerError::NotFound(format!(
            "({lon}, {lat}) lies outside world `{name}`"
        )));
    }
    Ok(Json(PointElevation {
        lon,
        lat,
        elevation_m,
        z,
    })
    .into_response())
}

/// The served elevation at up to 10,000 points (a profile along a line).
#[utoipa::path(post, path = "/worlds/{world}/elevation", tag = "meta",
    params(("world" = String, Path, description = "World name", example = "tienshan")),
    request_body = ElevationRequest,
    responses(
        (status = 200, description = "Metres at each point (`null` outside the world), and the zoom used", body = ElevationProfile),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body larger than 1 MiB", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not `application/json`", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "More than 10,000 points, or coordinates out of range", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Synthesis queue full", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn elevation_profile(
    State(state): State<AppState>,
    Path(name): Path<String>,
    req: Request,
) -> Result<Response, ServerError> {
    let world = state.find_world(&name).await?;
    let body: ElevationRequest = json_body(req).await?;
    if body.points.len() > MAX_POINTS {
        return Err(ServerError::Invalid(format!(
            "{} points: at most {MAX_POINTS} are accepted",
            body.points.len()
        )));
    }
    let z = zoom_used(&world, body.z);
    let points = body.points.iter().map(|p| (p[0], p[1])).collect();
    let elevations_m = compute(&state, world, z, points).await?;
    Ok(Json(ElevationProfile { z, elevations_m }).into_response())
}
