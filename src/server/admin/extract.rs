//! Reading admin requests: JSON bodies (`application/json` only, at most [`MAX_JSON`] bytes),
//! raw bodies cut at a limit as they arrive, query strings, the upload format a `Content-Type`
//! declares, and the georeference query parameters of PNG and EXR uploads.

use std::collections::HashMap;

use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, Request};
use axum::http::header;

use terrasynth_core::raster::{Crs, Georef};
use terrasynth_store::ingest::UploadFormat;

use crate::server::error::ServerError;

/// Largest JSON request body, bytes.
pub const MAX_JSON: usize = 1 << 20;

/// The query pairs, or 400 for a malformed query string.
pub fn query(
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
) -> Result<HashMap<String, String>, ServerError> {
    q.map(|Query(q)| q)
        .map_err(|e| ServerError::BadRequest(format!("malformed query: {e}")))
}

/// The body, at most `limit` bytes: 413 as soon as `Content-Length` or the bytes received pass
/// it.
pub async fn read_body(req: Request, limit: usize) -> Result<axum::body::Bytes, ServerError> {
    let too_large =
        || ServerError::TooLarge(format!("the body exceeds the limit of {limit} bytes"));
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    axum::body::to_bytes(req.into_body(), limit)
        .await
        .map_err(|e| {
            let mut source: Option<&(dyn std::error::Error + 'static)> = Some(&e);
            while let Some(s) = source {
                if s.is::<http_body_util::LengthLimitError>() {
                    return too_large();
                }
                source = s.source();
            }
            ServerError::BadRequest(format!("cannot read the body: {e}"))
        })
}

/// A JSON body: 415 unless `application/json` (or `+json`), 400 when malformed, 422 when it does
/// not fit `T`.
pub async fn json_body<T: serde::de::DeserializeOwned>(req: Request) -> Result<T, ServerError> {
    let ct = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_ascii_lowercase();
    let essence = ct.split(';').next().unwrap_or("").trim().to_string();
    if essence != "application/json" && !essence.ends_with("+json") {
        return Err(ServerError::UnsupportedMediaType(format!(
            "Content-Type `{essence}`: send application/json"
        )));
    }
    let bytes = read_body(req, MAX_JSON).await?;
    serde_json::from_slice(&bytes).map_err(|e| match e.classify() {
        serde_json::error::Category::Data => ServerError::Invalid(format!("invalid request: {e}")),
        _ => ServerError::BadRequest(format!("malformed JSON: {e}")),
    })
}

/// What a raster upload's `Content-Type` declares, or 415.
pub fn upload_format(content_type: Option<&str>) -> Result<UploadFormat, ServerError> {
    let ct = content_type
        .map(|c| {
            c.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
        .unwrap_or_default();
    match ct.as_str() {
        "image/tiff" | "image/geotiff" => Ok(UploadFormat::Tiff),
        "image/png" => Ok(UploadFormat::Png),
        "image/x-exr" | "image/aces" | "image/exr" => Ok(UploadFormat::Exr),
        "application/octet-stream" => Ok(UploadFormat::Sniff),
        "" => Err(ServerError::UnsupportedMediaType(
            "missing Content-Type: send image/tiff, image/png, image/x-exr, application/octet-stream or multipart/form-data".into(),
        )),
        other => Err(ServerError::UnsupportedMediaType(format!(
            "Content-Type `{other}` is not accepted: send image/tiff, image/png, image/x-exr, application/octet-stream or multipart/form-data"
        ))),
    }
}

/// The georeference given by the query parameters `cell_size`, `west`, `north` and `crs`
/// (`EPSG:4326` by default, or `EPSG:3857`); `None` when none of the first three is given.
pub fn georef_from_query(q: &HashMap<String, String>) -> Result<Option<Georef>, ServerError> {
    let num = |k: &str| -> Result<Option<f64>, ServerError> {
        q.get(k)
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        ServerError::BadRequest(format!(
                            "query parameter {k}=`{v}` is not a finite number"
                        ))
                    })
            })
            .transpose()
    };
    let (cell, west, north) = (num("cell_size")?, num("west")?, num("north")?);
    let crs = match q.get("crs").map(|c| c.trim().to_ascii_uppercase()) {
        None => Crs::Epsg4326,
        Some(c) if c == "EPSG:4326" || c == "4326" => Crs::Epsg4326,
        Some(c) if c == "EPSG:3857" || c == "3857" => Crs::Epsg3857,
        Some(c) => {
            return Err(ServerError::Invalid(format!(
                "crs `{c}` is not supported (EPSG:4326 or EPSG:3857)"
            )))
        }
    };
    match (cell, west, north) {
        (None, None, None) => Ok(None),
        (Some(cell), Some(west), Some(north)) => {
            if cell <= 0.0 {
                return Err(ServerError::Invalid(format!(
                    "absurd georeference: cell_size {cell} must be positive"
                )));
            }
            Ok(Some(Georef {
                crs,
                west,
                north,
                pixel_width: cell,
                pixel_height: cell,
            }))
        }
        _ => Err(ServerError::Invalid(
            "give all of cell_size, west and north (and optionally crs)".into(),
        )),
    }
}
