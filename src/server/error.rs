//! The server's error: every module error rolled up into one type that implements
//! `IntoResponse` as an RFC 9457 `application/problem+json` body, never leaking internals.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use thiserror::Error;

use super::admin::AdminError;
use crate::config::ConfigError;
use crate::store::StoreError;
use crate::tiles::TileError;

/// An error answering a request or starting the server.
#[derive(Debug, Error)]
pub enum ServerError {
    /// A path segment or query parameter is malformed (400).
    #[error("{0}")]
    BadRequest(String),
    /// No such world, layer, format or tile (404).
    #[error("{0}")]
    NotFound(String),
    /// The synthesis queue is full (503 with `Retry-After`).
    #[error("the synthesis queue is full; retry shortly")]
    Busy,
    /// A tile could not be produced.
    #[error(transparent)]
    Tile(#[from] TileError),
    /// Configuration could not be loaded.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// An admin or catalogue request failed.
    #[error(transparent)]
    Admin(#[from] AdminError),
    /// Something else failed inside the server (500).
    #[error("internal error: {0}")]
    Internal(String),
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
            ServerError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ServerError::NotFound(_) => StatusCode::NOT_FOUND,
            ServerError::Busy => StatusCode::SERVICE_UNAVAILABLE,
            ServerError::Tile(
                TileError::OutOfRange { .. }
                | TileError::ZoomTooDeep { .. }
                | TileError::OutsideWorld { .. },
            ) => StatusCode::NOT_FOUND,
            ServerError::Tile(TileError::Decode(_)) => StatusCode::BAD_REQUEST,
            ServerError::Admin(e) => e.status(),
            // An id or name that cannot even be a file name names nothing.
            ServerError::Store(StoreError::BadName(_)) => StatusCode::NOT_FOUND,
            _ => StatusCode::INTERNAL_SERVER_ERROR,
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
        let quiet = matches!(
            self,
            ServerError::Busy | ServerError::Admin(AdminError::QueueFull)
        );
        let detail = if status.is_server_error() && !quiet {
            // Internals are logged, not sent.
            tracing::error!(error = %self, "request failed");
            "the server could not produce this resource".to_string()
        } else {
            self.to_string()
        };
        let mut resp = problem(status, &detail);
        if quiet {
            resp.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
        }
        if matches!(self, ServerError::Admin(AdminError::Unauthorized(_))) {
            resp.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"terrasynth admin\""),
            );
        }
        resp
    }
}
