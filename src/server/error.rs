//! The server's request error: every crate's error rolled up into one type that implements
//! `IntoResponse` as an RFC 9457 `application/problem+json` body, never leaking internals (5xx
//! details are logged, not sent). Overload answers (503 with `Retry-After`) are not failures: they
//! are never logged as errors, and carry their [`Overload`] reason to the metrics. Error responses
//! produced outside the handlers (405, rejections of extractors, 413 of body limits) are given the
//! same problem shape by [`into_problem`]. Start-up failures are a separate type,
//! [`StartupError`].

use axum::body::Body;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use thiserror::Error;

use terrasynth_store::{ServiceError, StoreError};
use terrasynth_tiles::{RequestError, TileError};

use super::metrics::Overload;
use crate::config::ConfigError;

/// An error answering a request.
#[derive(Debug, Error)]
pub enum ServerError {
    /// A path segment, query parameter or body is malformed (400).
    #[error("{0}")]
    BadRequest(String),
    /// No such resource (404).
    #[error("{0}")]
    NotFound(String),
    /// Missing or wrong bearer token (401).
    #[error("{0}")]
    Unauthorized(String),
    /// The body is larger than allowed (413).
    #[error("{0}")]
    TooLarge(String),
    /// Wrong content type (415).
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// Well-formed but unusable (422).
    #[error("{0}")]
    Invalid(String),
    /// The synthesis queue is full (503 with `Retry-After`).
    #[error("the synthesis queue is full; retry shortly")]
    Busy,
    /// The request outlived its deadline (503 with `Retry-After`).
    #[error("the request took longer than {0} s; retry shortly")]
    Timeout(u64),
    /// Every upload slot is taken (503 with `Retry-After`).
    #[error("{0}")]
    UploadsBusy(String),
    /// The client failed authentication too often (429 with `Retry-After`).
    #[error("too many failed authentications from this address; retry in {0} s")]
    TooManyRequests(u64),
    /// The request target is longer than allowed (414).
    #[error("{0}")]
    UriTooLong(String),
    /// The tile URL names no tile.
    #[error(transparent)]
    Request(#[from] RequestError),
    /// A tile could not be produced.
    #[error(transparent)]
    Tile(#[from] TileError),
    /// A catalogue rule was broken or the store failed.
    #[error(transparent)]
    Service(#[from] ServiceError),
    /// Something else failed inside the server (500).
    #[error("internal error: {0}")]
    Internal(String),
}

impl From<StoreError> for ServerError {
    fn from(e: StoreError) -> Self {
        ServerError::Service(ServiceError::Store(e))
    }
}

/// An error starting the server.
#[derive(Debug, Error)]
pub enum StartupError {
    /// The configuration could not be loaded.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The store could not be opened.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The catalogue service could not start.
    #[error(transparent)]
    Service(#[from] ServiceError),
    /// A configured world could not be loaded.
    #[error("world `{world}`: {message}")]
    World {
        /// The world's name.
        world: String,
        /// What went wrong.
        message: String,
    },
    /// Another process listens on the address.
    #[error("{addr} is in use (is another terrasynth running?): set TERRASYNTH_LISTEN or pass --listen, e.g. --listen 127.0.0.1:8081")]
    AddressInUse {
        /// The address.
        addr: String,
    },
    /// The listening address is not available.
    #[error(
        "cannot listen on {addr}: {source} (set TERRASYNTH_LISTEN or pass --listen HOST:PORT)"
    )]
    Bind {
        /// The address.
        addr: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A setting is unusable.
    #[error("invalid setting: {0}")]
    Setting(String),
    /// The runtime or the server loop failed.
    #[error("server failed: {0}")]
    Runtime(String),
}

/// An RFC 9457 problem document.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct Problem {
    /// A URI reference identifying the problem type.
    #[serde(rename = "type")]
    pub kind: String,
    /// Short summary of the problem type.
    pub title: String,
    /// The HTTP status code.
    pub status: u16,
    /// Explanation specific to this occurrence.
    pub detail: String,
}

impl ServerError {
    /// The HTTP status of this error.
    pub fn status(&self) -> StatusCode {
        match self {
            ServerError::BadRequest(_) | ServerError::Request(RequestError::BadRequest(_)) => {
                StatusCode::BAD_REQUEST
            }
            ServerError::NotFound(_) | ServerError::Request(RequestError::NotFound(_)) => {
                StatusCode::NOT_FOUND
            }
            ServerError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ServerError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ServerError::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ServerError::Invalid(_) => StatusCode::UNPROCESSABLE_ENTITY,
            ServerError::Busy | ServerError::Timeout(_) | ServerError::UploadsBusy(_) => {
                StatusCode::SERVICE_UNAVAILABLE
            }
            ServerError::TooManyRequests(_) => StatusCode::TOO_MANY_REQUESTS,
            ServerError::UriTooLong(_) => StatusCode::URI_TOO_LONG,
            ServerError::Tile(TileError::Cancelled) => StatusCode::SERVICE_UNAVAILABLE,
            ServerError::Tile(
                TileError::OutOfRange { .. }
                | TileError::ZoomTooDeep { .. }
                | TileError::OutsideWorld { .. },
            ) => StatusCode::NOT_FOUND,
            ServerError::Tile(TileError::Decode(_)) => StatusCode::BAD_REQUEST,
            ServerError::Tile(_) | ServerError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
            ServerError::Service(e) => match e {
                ServiceError::NotFound(_) => StatusCode::NOT_FOUND,
                ServiceError::Conflict(_) => StatusCode::CONFLICT,
                ServiceError::Undecodable(_) => StatusCode::BAD_REQUEST,
                ServiceError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
                ServiceError::Invalid(_) => StatusCode::UNPROCESSABLE_ENTITY,
                ServiceError::QueueFull | ServiceError::Busy(_) => StatusCode::SERVICE_UNAVAILABLE,
                // An id or name that cannot even be a file name names nothing.
                ServiceError::Store(StoreError::BadName(_)) => StatusCode::NOT_FOUND,
                ServiceError::Store(_) | ServiceError::Internal(_) => {
                    StatusCode::INTERNAL_SERVER_ERROR
                }
            },
        }
    }

    /// Why this is an overload answer (503 with `Retry-After`, not a failure), if it is one.
    pub fn overload(&self) -> Option<Overload> {
        match self {
            ServerError::Busy => Some(Overload::SynthQueue),
            ServerError::Timeout(_) => Some(Overload::Timeout),
            ServerError::UploadsBusy(_) | ServerError::Service(ServiceError::Busy(_)) => {
                Some(Overload::Uploads)
            }
            ServerError::Service(ServiceError::QueueFull) => Some(Overload::BuildQueue),
            ServerError::Tile(TileError::Cancelled) => Some(Overload::Abandoned),
            _ => None,
        }
    }
}

/// A problem+json response with the given status and detail.
pub fn problem(status: StatusCode, detail: &str) -> Response {
    let body = Problem {
        kind: "about:blank".into(),
        title: status.canonical_reason().unwrap_or("Error").into(),
        status: status.as_u16(),
        detail: detail.to_string(),
    };
    let json = serde_json::to_vec(&body).unwrap_or_default();
    let mut resp = (status, json).into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/problem+json"),
    );
    resp
}

impl IntoResponse for ServerError {
    fn into_response(self) -> Response {
        let status = self.status();
        let overload = self.overload();
        let detail = if status.is_server_error() && overload.is_none() {
            // Internals are logged, not sent.
            tracing::error!(error = %self, "request failed");
            "the server could not produce this resource".to_string()
        } else {
            self.to_string()
        };
        let mut resp = problem(status, &detail);
        if let Some(why) = overload {
            resp.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            resp.extensions_mut().insert(why);
        }
        if let ServerError::TooManyRequests(secs) = self {
            resp.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(secs.max(1)));
        }
        if matches!(self, ServerError::Unauthorized(_)) {
            resp.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"terrasynth admin\""),
            );
        }
        resp
    }
}

/// Largest body of an error response that [`into_problem`] reads to reuse as the detail.
const MAX_DETAIL_BYTES: usize = 4096;

/// Gives an error response the problem+json shape: a response with a 4xx or 5xx status that is
/// not a problem document already (405 of the router, rejections of axum's extractors such as an
/// invalid UTF-8 path, 413 of body limits) is rewritten as one, keeping its status, headers
/// (`Allow`, `Retry-After`) and extensions and using a short plain-text body as the detail; any
/// other response is returned as it is. The server's edge middleware runs it on every response.
pub async fn into_problem(resp: Response) -> Response {
    let status = resp.status();
    let is_problem = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/problem+json"));
    if !(status.is_client_error() || status.is_server_error()) || is_problem {
        return resp;
    }
    let is_text = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"text/plain"));
    let (mut parts, body) = resp.into_parts();
    // A 5xx body could carry internals: only client errors keep their text.
    let text = if is_text && status.is_client_error() {
        axum::body::to_bytes(body, MAX_DETAIL_BYTES)
            .await
            .ok()
            .and_then(|b| String::from_utf8(b.to_vec()).ok())
            .filter(|t| !t.trim().is_empty())
    } else {
        None
    };
    let detail = text.unwrap_or_else(|| match status {
        StatusCode::METHOD_NOT_ALLOWED => "this method is not allowed on this resource".into(),
        _ => status
            .canonical_reason()
            .unwrap_or("error")
            .to_ascii_lowercase(),
    });
    let fresh = problem(status, detail.trim());
    parts.headers.remove(header::CONTENT_LENGTH);
    parts.headers.remove(header::TRANSFER_ENCODING);
    parts.headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/problem+json"),
    );
    let (_, body) = fresh.into_parts();
    Response::from_parts(parts, Body::new(body))
}
