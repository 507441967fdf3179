//! `/admin/dictionaries` (queue a build, delete) and the public catalogue `/dictionaries`.

use axum::extract::{Path, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use terrasynth_store::{DictionaryInfo, DictionaryRequest, Job};

use super::extract::json_body;
use crate::server::error::{Problem, ServerError};
use crate::server::state::{blocking, AppState};

/// `{"id": ...}` of a queued job (and the job).
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct JobAccepted {
    /// Job id.
    pub id: String,
    /// The job as queued.
    pub job: Job,
}

/// Queue a dictionary build.
#[utoipa::path(post, path = "/admin/dictionaries", tag = "admin", security(("bearer" = [])),
    request_body = DictionaryRequest,
    responses(
        (status = 202, description = "Queued; `Location: /admin/jobs/{id}`", body = JobAccepted,
            headers(("Location" = String, description = "The job"))),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid parameters or unknown exemplar", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Build queue full", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn post_dictionary(
    State(state): State<AppState>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = state.admin()?;
    let request: DictionaryRequest = json_body(req).await?;
    let catalogue = admin.catalogue.clone();
    let job = blocking(move || Ok(catalogue.submit_build(request)?)).await?;
    let location = format!("/admin/jobs/{}", job.id);
    let mut resp = (
        StatusCode::ACCEPTED,
        Json(JobAccepted {
            id: job.id.clone(),
            job,
        }),
    )
        .into_response();
    if let Ok(v) = HeaderValue::from_str(&location) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

/// Delete a dictionary.
#[utoipa::path(delete, path = "/admin/dictionaries/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Dictionary id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown dictionary", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Used by a world", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn delete_dictionary(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ServerError> {
    let catalogue = state.admin()?.catalogue.clone();
    let live = state.live.clone();
    blocking(move || {
        let served_by = |dict: &str| {
            live.snapshot()
                .values()
                .find(|w| w.dictionary_ids().iter().any(|d| d == dict))
                .map(|w| w.name().to_string())
        };
        Ok(catalogue.delete_dictionary(&id, served_by)?)
    })
    .await?;
    Ok(StatusCode::NO_CONTENT)
}

/// Every dictionary of the store.
#[utoipa::path(get, path = "/dictionaries", tag = "meta", operation_id = "dictionaries",
    responses((status = 200, description = "Dictionaries", body = Vec<DictionaryInfo>)))]
pub async fn list_dictionaries(State(state): State<AppState>) -> Json<Vec<DictionaryInfo>> {
    Json(
        state
            .admin
            .as_ref()
            .map(|a| a.catalogue.dictionaries())
            .unwrap_or_default(),
    )
}

/// One dictionary.
#[utoipa::path(get, path = "/dictionaries/{id}", tag = "meta", operation_id = "dictionary",
    params(("id" = String, Path, description = "Dictionary id")),
    responses(
        (status = 200, description = "The dictionary", body = DictionaryInfo),
        (status = 404, description = "Unknown dictionary", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn get_dictionary(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<DictionaryInfo>, ServerError> {
    let admin = state
        .admin
        .as_ref()
        .ok_or_else(|| ServerError::NotFound(format!("no dictionary `{id}`")))?;
    Ok(Json(admin.catalogue.dictionary(&id)?))
}
