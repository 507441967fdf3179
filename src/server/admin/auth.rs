//! Bearer-token authorisation of the admin routes. The token is compared through SHA-256
//! digests in constant time, so the comparison's duration says nothing about the token.

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use subtle::ConstantTimeEq;

use super::Admin;
use crate::server::error::ServerError;
use crate::server::state::AppState;

impl Admin {
    /// Checks the `Authorization: Bearer <token>` header: 404 when the admin API is disabled,
    /// 401 when the header is missing or wrong.
    pub fn check_token(&self, headers: &HeaderMap) -> Result<(), ServerError> {
        use sha2::{Digest, Sha256};
        let Some(token) = &self.token else {
            return Err(ServerError::NotFound("no such resource".into()));
        };
        let given = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| {
                let (scheme, rest) = v.trim().split_once(' ')?;
                scheme.eq_ignore_ascii_case("bearer").then(|| rest.trim())
            })
            .ok_or_else(|| {
                ServerError::Unauthorized("missing `Authorization: Bearer <token>`".into())
            })?;
        // Hashes have equal lengths, so the comparison time does not depend on the token.
        let a = Sha256::digest(given.as_bytes());
        let b = Sha256::digest(token.as_bytes());
        if bool::from(a.as_slice().ct_eq(b.as_slice())) {
            Ok(())
        } else {
            Err(ServerError::Unauthorized("invalid admin token".into()))
        }
    }
}

/// Middleware of the admin routes: the bearer token, compared in constant time.
pub async fn authorize(State(state): State<AppState>, req: Request, next: Next) -> Response {
    match state.admin().and_then(|a| a.check_token(req.headers())) {
        Ok(()) => next.run(req).await,
        Err(e) => e.into_response(),
    }
}
