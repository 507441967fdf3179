//! `/admin/exemplars`: upload (a raster body or multipart parts), list, describe, delete.
//!
//! An upload takes one of `max_concurrent_uploads` slots (beyond: 503), is spooled to the store's
//! `uploads/` as it arrives (cut at `max_body_mb`), then, on the blocking pool, reserves its body
//! and its decoded size (estimated from the file headers) from the upload memory budget before
//! anything is decoded, and is streamed to the store once decoded and checked.

use axum::extract::rejection::QueryRejection;
use axum::extract::{FromRequest, Multipart, Path, Query, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use terrasynth_store::ingest::{self, Spooled, UploadFormat, UploadLimits};
use terrasynth_store::{ExemplarInfo, Store};

use super::extract::{
    check_declared_length, discard, georef_from_query, query, spool_body, upload_format, Spooler,
};
use crate::server::error::{Problem, ServerError};
use crate::server::state::{blocking, AppState};

/// A raster file (GeoTIFF, 16-bit PNG or OpenEXR).
#[derive(utoipa::ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct RasterFile(pub Vec<u8>);

/// A multipart exemplar: an `elevation` part and any number of named layer parts (each a raster
/// file on the elevation's grid): e.g. a `classes` part (a land-cover class raster of integers,
/// for a world's `classes.legend`) or an `rgb` part (an 8-bit RGB or RGBA PNG of the same size,
/// a satellite image for a world's `classes.hsv`, stored as packed `0xRRGGBB` values).
#[derive(utoipa::ToSchema)]
pub struct ExemplarForm {
    /// The elevation raster.
    #[schema(value_type = String, format = Binary)]
    pub elevation: Vec<u8>,
}

fn multipart_error(e: axum::extract::multipart::MultipartError) -> ServerError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        ServerError::TooLarge(format!("multipart body: {e}"))
    } else {
        ServerError::BadRequest(format!("malformed multipart body: {e}"))
    }
}

/// Upload an exemplar.
#[utoipa::path(post, path = "/admin/exemplars", tag = "admin",
    security(("bearer" = [])),
    params(
        ("name" = String, Query, description = "Human name (1–64 letters, digits, `-`, `_`)", pattern = "^[A-Za-z0-9_-]{1,64}$"),
        ("cell_size" = Option<f64>, Query, description = "Cell size in CRS units (PNG and EXR)"),
        ("west" = Option<f64>, Query, description = "West edge in CRS units (PNG and EXR)"),
        ("north" = Option<f64>, Query, description = "North edge in CRS units (PNG and EXR)"),
        ("crs" = Option<String>, Query, description = "`EPSG:4326` (default) or `EPSG:3857`")
    ),
    request_body(description = "A GeoTIFF, a 16-bit grayscale PNG or an OpenEXR file; or multipart/form-data with an `elevation` part and named layer parts on the same grid (a `classes` part: a land-cover class raster; an `rgb` part: an 8-bit RGB(A) PNG satellite image)",
        content(
            (RasterFile = "image/tiff"), (RasterFile = "image/png"), (RasterFile = "image/x-exr"),
            (RasterFile = "application/octet-stream"), (ExemplarForm = "multipart/form-data")
        )),
    responses(
        (status = 201, description = "Stored", body = ExemplarInfo),
        (status = 400, description = "Malformed request or undecodable file", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Admin disabled", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body or raster too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Wrong content type", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "NaN-only, mismatched layers, absurd or missing georeference", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Every upload slot is taken or the upload memory budget is in use (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn post_exemplar(
    State(state): State<AppState>,
    q: Result<Query<Vec<(String, String)>>, QueryRejection>,
    req: Request,
) -> Result<Response, ServerError> {
    let admin = state.admin()?;
    let q = query(q)?;
    let name = q
        .get("name")
        .cloned()
        .ok_or_else(|| ServerError::BadRequest("query parameter `name` is required".into()))?;
    terrasynth_store::worlds::check_name("exemplar name", &name)?;
    let georef = georef_from_query(&q)?;
    let limits = admin.limits;
    let ct = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    let is_multipart = ct.as_deref().is_some_and(|c| {
        c.trim()
            .to_ascii_lowercase()
            .starts_with("multipart/form-data")
    });
    let max_body = limits.max_body as u64;
    check_declared_length(&req, max_body)?;
    let format = if is_multipart {
        None
    } else {
        Some(upload_format(ct.as_deref())?)
    };
    let _slot = admin
        .upload_slots
        .clone()
        .try_acquire_owned()
        .map_err(|_| {
            ServerError::UploadsBusy(
                "every upload slot is taken (max_concurrent_uploads); retry shortly".into(),
            )
        })?;
    let store = admin.catalogue.store().clone();
    let parts = match format {
        Some(format) => vec![spool_body(req, &store, format, max_body).await?],
        None => spool_multipart(req, &store, &limits).await?,
    };
    let catalogue = admin.catalogue.clone();
    let budget = admin.upload_memory.clone();
    let info = blocking(move || {
        let (raster, _reservation) = ingest::decode_spooled(&parts, georef, &limits, &budget)?;
        // The files are no longer needed: remove them before storing.
        drop(parts);
        Ok(catalogue.put_exemplar(&name, &raster)?)
    })
    .await?;
    let mut resp = (StatusCode::CREATED, Json(&info)).into_response();
    if let Ok(v) = HeaderValue::from_str(&format!("/admin/exemplars/{}", info.id)) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

/// The parts of a multipart upload, each spooled to a file of `store` as it arrives: at most
/// `max_layers` parts and `max_body` bytes together (413 beyond).
async fn spool_multipart(
    req: Request,
    store: &Store,
    limits: &UploadLimits,
) -> Result<Vec<Spooled>, ServerError> {
    let mut mp = Multipart::from_request(req, &())
        .await
        .map_err(|e| ServerError::BadRequest(format!("malformed multipart body: {e}")))?;
    let mut parts: Vec<Spooled> = Vec::new();
    let mut total = 0u64;
    let limit = limits.max_body as u64;
    let result: Result<(), ServerError> = async {
        while let Some(mut field) = mp.next_field().await.map_err(multipart_error)? {
            if parts.len() >= limits.read.max_layers {
                return Err(ServerError::TooLarge(format!(
                    "more than {} parts",
                    limits.read.max_layers
                )));
            }
            let name = field.name().unwrap_or("").to_string();
            let format = match field.content_type() {
                None => UploadFormat::Sniff,
                Some(c) => upload_format(Some(c))?,
            };
            let mut spooler = Spooler::new(store, &name, format).await?;
            loop {
                let chunk = match field.chunk().await {
                    Ok(Some(c)) => c,
                    Ok(None) => break,
                    Err(e) => {
                        spooler.discard().await;
                        return Err(multipart_error(e));
                    }
                };
                if let Err(e) = spooler.push(&chunk, &mut total, limit).await {
                    spooler.discard().await;
                    return Err(e);
                }
            }
            parts.push(spooler.finish().await?);
        }
        Ok(())
    }
    .await;
    match result {
        Ok(()) => Ok(parts),
        Err(e) => {
            discard(parts).await;
            Err(e)
        }
    }
}

/// Every exemplar.
#[utoipa::path(get, path = "/admin/exemplars", tag = "admin", security(("bearer" = [])),
    responses(
        (status = 200, description = "Exemplars", body = Vec<ExemplarInfo>),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn list_exemplars(
    State(state): State<AppState>,
) -> Result<Json<Vec<ExemplarInfo>>, ServerError> {
    // Exemplars not verified since start are verified first: blocking IO.
    let catalogue = state.admin()?.catalogue.clone();
    Ok(Json(blocking(move || Ok(catalogue.exemplars())).await?))
}

/// One exemplar.
#[utoipa::path(get, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 200, description = "The exemplar", body = ExemplarInfo),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown exemplar", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn get_exemplar(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<ExemplarInfo>, ServerError> {
    let catalogue = state.admin()?.catalogue.clone();
    Ok(Json(blocking(move || Ok(catalogue.exemplar(&id)?)).await?))
}

/// Delete an exemplar.
#[utoipa::path(delete, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Too many failed authentications from this address (`Retry-After`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown exemplar", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Used by a build or a world", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn delete_exemplar(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ServerError> {
    let catalogue = state.admin()?.catalogue.clone();
    blocking(move || Ok(catalogue.delete_exemplar(&id)?)).await?;
    Ok(StatusCode::NO_CONTENT)
}
