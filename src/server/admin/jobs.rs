//! `/admin/jobs`: list, describe and cancel dictionary build jobs.

use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::Json;

use terrasynth_store::Job;

use crate::server::error::{Problem, ServerError};
use crate::server::state::{blocking, AppState};

/// Every job.
#[utoipa::path(get, path = "/admin/jobs", tag = "admin", security(("bearer" = [])),
    responses(
        (status = 200, description = "Jobs, oldest first", body = Vec<Job>),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn list_jobs(State(state): State<AppState>) -> Result<Json<Vec<Job>>, ServerError> {
    Ok(Json(state.admin()?.catalogue.jobs()))
}

/// One job.
#[utoipa::path(get, path = "/admin/jobs/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = Job),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown job", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Job>, ServerError> {
    Ok(Json(state.admin()?.catalogue.job(&id)?))
}

/// Cancel a queued or running job.
#[utoipa::path(delete, path = "/admin/jobs/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 202, description = "Cancelled (queued) or cancelling (running)", body = Job),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Already ended", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn cancel_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<(StatusCode, Json<Job>), ServerError> {
    let catalogue = state.admin()?.catalogue.clone();
    // Cancelling rewrites the job record (an fsync'd write): off the runtime.
    let job = blocking(move || Ok(catalogue.cancel_job(&id)?)).await?;
    Ok((StatusCode::ACCEPTED, Json(job)))
}
