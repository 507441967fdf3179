//! `/admin/exemplars`: upload (a raster body or multipart parts), list, describe, delete.

use std::collections::HashMap;

use axum::extract::rejection::QueryRejection;
use axum::extract::{FromRequest, Multipart, Path, Query, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use terrasynth_core::raster::ELEVATION;
use terrasynth_store::ingest::{self, UploadFormat};
use terrasynth_store::ExemplarInfo;

use super::extract::{georef_from_query, query, read_body, upload_format};
use crate::server::error::{Problem, ServerError};
use crate::server::state::{blocking, AppState};

/// A raster file (GeoTIFF, 16-bit PNG or OpenEXR).
#[derive(utoipa::ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct RasterFile(pub Vec<u8>);

/// A multipart exemplar: an `elevation` part and any number of named layer parts (each a raster
/// file on the elevation's grid).
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
    request_body(description = "A GeoTIFF, a 16-bit grayscale PNG or an OpenEXR file; or multipart/form-data with an `elevation` part and named layer parts on the same grid",
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
        (status = 422, description = "NaN-only, mismatched layers, absurd or missing georeference", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn post_exemplar(
    State(state): State<AppState>,
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
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
    let raster = if is_multipart {
        let mut mp = Multipart::from_request(req, &())
            .await
            .map_err(|e| ServerError::BadRequest(format!("malformed multipart body: {e}")))?;
        let mut parts: Vec<(String, UploadFormat, axum::body::Bytes)> = Vec::new();
        let mut total = 0usize;
        loop {
            let field = mp.next_field().await.map_err(multipart_error)?;
            let Some(field) = field else { break };
            let part = field.name().unwrap_or("").to_string();
            let format = match field.content_type() {
                None => UploadFormat::Sniff,
                Some(c) => upload_format(Some(c))?,
            };
            let bytes = field.bytes().await.map_err(multipart_error)?;
            total += bytes.len();
            if total > limits.max_body {
                return Err(ServerError::TooLarge("the body exceeds the limit".into()));
            }
            if parts.len() > limits.read.max_layers {
                return Err(ServerError::TooLarge(format!(
                    "more than {} parts",
                    limits.read.max_layers
                )));
            }
            parts.push((part, format, bytes));
        }
        blocking(move || {
            let elevation_at = parts
                .iter()
                .position(|(n, _, _)| n == ELEVATION)
                .ok_or_else(|| {
                    ServerError::Invalid("the multipart body has no `elevation` part".into())
                })?;
            let (_, format, bytes) = &parts[elevation_at];
            let elevation =
                ingest::decode_raster("part `elevation`", bytes, *format, georef, &limits)?;
            let mut layers = Vec::new();
            for (i, (n, format, bytes)) in parts.iter().enumerate() {
                if i == elevation_at {
                    continue;
                }
                ingest::check_layer_name(n)?;
                let r = ingest::decode_raster(
                    &format!("part `{n}`"),
                    bytes,
                    *format,
                    Some(elevation.georef),
                    &limits,
                )?;
                layers.push((n.clone(), r));
            }
            Ok(ingest::assemble(elevation, layers, &limits)?)
        })
        .await?
    } else {
        let format = upload_format(ct.as_deref())?;
        let bytes = read_body(req, limits.max_body).await?;
        blocking(move || {
            let r = ingest::decode_raster("the body", &bytes, format, georef, &limits)?;
            Ok(ingest::assemble(r, Vec::new(), &limits)?)
        })
        .await?
    };
    let catalogue = admin.catalogue.clone();
    let info = blocking(move || Ok(catalogue.put_exemplar(&name, &raster)?)).await?;
    let mut resp = (StatusCode::CREATED, Json(&info)).into_response();
    if let Ok(v) = HeaderValue::from_str(&format!("/admin/exemplars/{}", info.id)) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

/// Every exemplar.
#[utoipa::path(get, path = "/admin/exemplars", tag = "admin", security(("bearer" = [])),
    responses(
        (status = 200, description = "Exemplars", body = Vec<ExemplarInfo>),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn list_exemplars(
    State(state): State<AppState>,
) -> Result<Json<Vec<ExemplarInfo>>, ServerError> {
    Ok(Json(state.admin()?.catalogue.exemplars()))
}

/// One exemplar.
#[utoipa::path(get, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 200, description = "The exemplar", body = ExemplarInfo),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown exemplar", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn get_exemplar(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<ExemplarInfo>, ServerError> {
    Ok(Json(state.admin()?.catalogue.exemplar(&id)?))
}

/// Delete an exemplar.
#[utoipa::path(delete, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
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
