//! The server's request error: every crate's error rolled up into one type that implements
//! `IntoResponse` as an RFC 9457 `application/problem+json` body, never leaking internals (5xx
//! details are logged, not sent). Start-up failures are a separate type, [`StartupError`].

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use thiserror::Error;

use terrasynth_store::{ServiceError, StoreError};
use terrasynth_tiles::{RequestError, TileError};

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
            ServerError::Busy => StatusCode::SERVICE_UNAVAILABLE,
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
                ServiceError::QueueFull => StatusCode::SERVICE_UNAVAILABLE,
                // An id or name that cannot even be a file name names nothing.
                ServiceError::Store(StoreError::BadName(_)) => StatusCode::NOT_FOUND,
                ServiceError::Store(_) | ServiceError::Internal(_) => {
                    StatusCode::INTERNAL_SERVER_ERROR
                }
            },
        }
    }

    /// Whether this is an overload answer (503 with `Retry-After`), not a failure.
    fn is_overload(&self) -> bool {
        matches!(
            self,
            ServerError::Busy | ServerError::Service(ServiceError::QueueFull)
        )
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
        let overload = self.is_overload();
        let detail = if status.is_server_error() && !overload {
            // Internals are logged, not sent.
            tracing::error!(error = %self, "request failed");
            "the server could not produce this resource".to_string()
        } else {
            self.to_string()
        };
        let mut resp = problem(status, &detail);
        if overload {
            resp.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
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
