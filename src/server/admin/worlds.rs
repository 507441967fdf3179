//! `/admin/worlds`: create a world from a stored base and dictionary (served at once, loaded
//! again at every start), make one from a sketch (a job: `/admin/worlds/sketch`), and delete
//! one.

use std::sync::Arc;

use axum::extract::{Path, Request, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use terrasynth_core::synth::sketch::SizeLimits;
use terrasynth_store::service::{Assemble, Publish, Served};
use terrasynth_store::{Job, ServiceError, SketchRequest, WorldDefinition, WorldRequest};

use super::extract::json_body;
use crate::server::error::{Problem, ServerError};
use crate::server::state::{blocking, AppState};
use crate::server::worlds::{prepare_landscapes, share_shortfall, world_from};

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

/// Create a world.
#[utoipa::path(post, path = "/admin/worlds", tag = "admin", security(("bearer" = [])),
    request_body = WorldRequest,
    responses(
        (status = 201, description = "Created; tiles are served at once", body = WorldCreated),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Name taken", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Unknown base or dictionary, invalid zoom, weights, materials or species, or a base too large for a world's share of `cache_mb`", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn post_world(
    State(state): State<AppState>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = state.admin()?;
    let request: WorldRequest = json_body(req).await?;
    let catalogue = admin.catalogue.clone();
    let def = WorldDefinition::from_request(request, catalogue.defaults())?;
    let live = state.live.clone();
    let cache_bytes = admin.cache_bytes;
    let store = state.store();
    let (world, id, def) = blocking(move || {
        let (world, id) = catalogue.create_world(
            &def,
            |name| live.get(name).is_some(),
            |resolved| {
                let world = world_from(resolved, cache_bytes)
                    .map_err(|e| ServiceError::Invalid(format!("cannot create the world: {e}")))?;
                // A world that would overrun its memory share is refused, nothing stored.
                match share_shortfall(&world) {
                    Some(why) => Err(ServiceError::Invalid(format!(
                        "cannot create the world: {why}"
                    ))),
                    None => Ok(world),
                }
            },
        )?;
        let world = Arc::new(world);
        live.publish(world.clone(), store.as_ref());
        Ok((world, id, def))
    })
    .await?;
    prepare_landscapes(vec![world.clone()], state.store());
    tracing::info!(world = %def.name, id = %id, "world created");
    let body = WorldCreated {
        id,
        tiles: format!("/tiles/{}/elevation/{{z}}/{{x}}/{{y}}.png", def.name),
        native_zoom: world.z_base(),
        world: def,
    };
    Ok((StatusCode::CREATED, Json(body)).into_response())
}

/// Make a world from a sketch: ridge and valley lines become terrain made of patches of the
/// given exemplars (feature-guided synthesis), stored as the world's base, amplified by the
/// given dictionary. Answers at once with the job; poll `/admin/jobs/{id}` for its progress.
/// When it succeeds the world is served (and its `result` is the world's name).
#[utoipa::path(post, path = "/admin/worlds/sketch", tag = "admin", security(("bearer" = [])),
    request_body = SketchRequest,
    responses(
        (status = 202, description = "Queued; poll the job", body = Job),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Name taken (or being made)", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Bad sketch (no lines, outside the bounds, crossing itself, over 10 000 vertices), bounds or cell size over the size limits, unknown exemplar or dictionary; nothing is stored", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Job queue full", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn post_sketch_world(
    State(state): State<AppState>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = state.admin()?;
    let request: SketchRequest = json_body(req).await?;
    let catalogue = admin.catalogue.clone();
    let defaults = SizeLimits::default();
    let limits = SizeLimits {
        max_pixels: defaults.max_pixels.min(admin.limits.read.max_pixels),
        max_dimension: defaults.max_dimension.min(admin.limits.max_dimension),
    };
    let live = state.live.clone();
    let served: Served = {
        let live = live.clone();
        Arc::new(move |name: &str| live.get(name).is_some())
    };
    let cache_bytes = admin.cache_bytes;
    let store = state.store();
    let assemble: Assemble = Box::new(move |resolved| {
        let world = world_from(resolved, cache_bytes)
            .map_err(|e| ServiceError::Invalid(format!("cannot create the world: {e}")))?;
        let world = Arc::new(world);
        let publish: Publish = Box::new(move || {
            live.publish(world.clone(), store.as_ref());
            prepare_landscapes(vec![world], store);
        });
        Ok(publish)
    });
    // Checking the sketch and the store and writing the job record: off the runtime.
    let job =
        blocking(move || Ok(catalogue.submit_sketch(request, &limits, served, assemble)?)).await?;
    let location = format!("/admin/jobs/{}", job.id);
    let mut resp = (StatusCode::ACCEPTED, Json(job)).into_response();
    if let Ok(v) = axum::http::HeaderValue::from_str(&location) {
        resp.headers_mut().insert(axum::http::header::LOCATION, v);
    }
    Ok(resp)
}

/// Delete a world.
#[utoipa::path(delete, path = "/admin/worlds/{name}", tag = "admin", security(("bearer" = [])),
    params(("name" = String, Path, description = "World name")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "A configured (read-only) world", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn delete_world(
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<StatusCode, ServerError> {
    let catalogue = state.admin()?.catalogue.clone();
    let live = state.live.clone();
    blocking(move || {
        catalogue.delete_world(&name)?;
        live.remove(&name);
        Ok(())
    })
    .await?;
    Ok(StatusCode::NO_CONTENT)
}
