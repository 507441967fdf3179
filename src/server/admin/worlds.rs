//! `/admin/worlds`: create a world from a stored base and dictionary (served at once, loaded
//! again at every start) and delete it.

use std::sync::Arc;

use axum::extract::{Path, Request, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use terrasynth_store::{ServiceError, WorldDefinition, WorldRequest};

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
        live.insert(world.clone());
        Ok((world, id, def))
    })
    .await?;
    prepare_landscapes(vec![world.clone()]);
    tracing::info!(world = %def.name, id = %id, "world created");
    let body = WorldCreated {
        id,
        tiles: format!("/tiles/{}/elevation/{{z}}/{{x}}/{{y}}.png", def.name),
        native_zoom: world.z_base(),
        world: def,
    };
    Ok((StatusCode::CREATED, Json(body)).into_response())
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
