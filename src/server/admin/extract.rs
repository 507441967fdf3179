//! Reading admin requests: JSON bodies (`application/json` only, at most [`MAX_JSON`] bytes),
//! upload bodies spooled to the store's `uploads/` as they arrive and cut at a limit (so that a
//! body, chunked or not, never accumulates in memory), query strings (a repeated key is a 400),
//! the upload format a `Content-Type` declares, and the georeference query parameters of PNG and
//! EXR uploads.

use std::collections::HashMap;
use std::path::PathBuf;

use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, Request};
use axum::http::header;
use tokio::io::AsyncWriteExt;

use terrasynth_core::raster::{Crs, Georef};
use terrasynth_store::ingest::{Spooled, UploadFormat};
use terrasynth_store::Store;
use terrasynth_tiles::query_map;

use crate::server::error::ServerError;

/// Largest JSON request body, bytes.
pub const MAX_JSON: usize = 1 << 20;

/// The query pairs, or 400 for a malformed query string or a key given more than once.
pub fn query(
    q: Result<Query<Vec<(String, String)>>, QueryRejection>,
) -> Result<HashMap<String, String>, ServerError> {
    let Query(pairs) = q.map_err(|e| ServerError::BadRequest(format!("malformed query: {e}")))?;
    Ok(query_map(&pairs)?)
}

/// An upload part being written to a spool file as it arrives.
pub struct Spooler {
    file: tokio::fs::File,
    spooled: Spooled,
}

impl Spooler {
    /// A new spool file in `store` for part `name` claiming `format`.
    pub async fn new(store: &Store, name: &str, format: UploadFormat) -> Result<Self, ServerError> {
        let store = store.clone();
        let (file, path): (std::fs::File, PathBuf) =
            tokio::task::spawn_blocking(move || store.spool_file())
                .await
                .map_err(|e| ServerError::Internal(e.to_string()))??;
        Ok(Spooler {
            file: tokio::fs::File::from_std(file),
            spooled: Spooled {
                name: name.to_string(),
                format,
                path,
                len: 0,
            },
        })
    }

    /// Appends `chunk`, counting it in `total`: 413 once `total` passes `limit`.
    pub async fn push(
        &mut self,
        chunk: &[u8],
        total: &mut u64,
        limit: u64,
    ) -> Result<(), ServerError> {
        *total = total.saturating_add(chunk.len() as u64);
        if *total > limit {
            return Err(too_large(limit));
        }
        self.file
            .write_all(chunk)
            .await
            .map_err(|e| ServerError::Internal(format!("spooling an upload: {e}")))?;
        self.spooled.len += chunk.len() as u64;
        Ok(())
    }

    /// The spooled part, its file complete.
    pub async fn finish(mut self) -> Result<Spooled, ServerError> {
        let flushed = self.file.flush().await;
        let Spooler { file, spooled } = self;
        drop(file);
        match flushed {
            Ok(()) => Ok(spooled),
            Err(e) => {
                discard(vec![spooled]).await;
                Err(ServerError::Internal(format!("spooling an upload: {e}")))
            }
        }
    }

    /// Removes the spool file (off the runtime).
    pub async fn discard(self) {
        let Spooler { file, spooled } = self;
        drop(file);
        discard(vec![spooled]).await;
    }
}

/// Removes spooled parts' files on the blocking pool.
pub async fn discard(parts: Vec<Spooled>) {
    let _ = tokio::task::spawn_blocking(move || drop(parts)).await;
}

fn too_large(limit: u64) -> ServerError {
    ServerError::TooLarge(format!("the body exceeds the limit of {limit} bytes"))
}

/// The declared `Content-Length` of `req`, 413 when it already exceeds `limit`.
pub fn check_declared_length(req: &Request, limit: u64) -> Result<(), ServerError> {
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit) {
        return Err(too_large(limit));
    }
    Ok(())
}

/// The body of `req` spooled to a file of `store` as part `elevation` claiming `format`, cut
/// with 413 as soon as it passes `limit` bytes (or declares more).
pub async fn spool_body(
    req: Request,
    store: &Store,
    format: UploadFormat,
    limit: u64,
) -> Result<Spooled, ServerError> {
    use http_body_util::BodyExt;
    check_declared_length(&req, limit)?;
    let mut body = req.into_body();
    let mut spooler = Spooler::new(store, terrasynth_core::raster::ELEVATION, format).await?;
    let mut total = 0u64;
    loop {
        let frame = match body.frame().await {
            None => break,
            Some(Ok(f)) => f,
            Some(Err(e)) => {
                spooler.discard().await;
                return Err(ServerError::BadRequest(format!(
                    "cannot read the body: {e}"
                )));
            }
        };
        let Ok(chunk) = frame.into_data() else {
            continue; // trailers
        };
        if let Err(e) = spooler.push(&chunk, &mut total, limit).await {
            spooler.discard().await;
            return Err(e);
        }
    }
    spooler.finish().await
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
