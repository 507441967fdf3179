//! Bearer-token authorisation of the admin routes. The token is compared through SHA-256
//! digests in constant time, so the comparison's duration says nothing about the token. Failed
//! attempts are counted, logged and rate-limited per client address ([`super::throttle`]); the
//! address is the peer of the connection (behind a proxy, the proxy's).

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::atomic::Ordering;

use axum::extract::{ConnectInfo, Request, State};
use axum::http::{header, HeaderMap};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use subtle::ConstantTimeEq;

use super::throttle::Verdict;
use super::Admin;
use crate::server::error::ServerError;
use crate::server::state::AppState;

/// The address a request's failures are counted under: the peer's IPv4 address, or the /64 of
/// its IPv6 address (one host usually owns a whole /64); unknown peers share one entry.
fn client_key(req: &Request) -> IpAddr {
    let Some(ConnectInfo(peer)) = req.extensions().get::<ConnectInfo<SocketAddr>>() else {
        return IpAddr::V4(Ipv4Addr::UNSPECIFIED);
    };
    match peer.ip() {
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => IpAddr::V4(v4),
            None => {
                let s = v6.segments();
                IpAddr::V6(Ipv6Addr::new(s[0], s[1], s[2], s[3], 0, 0, 0, 0))
            }
        },
        v4 => v4,
    }
}

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

/// Middleware of the admin routes: 429 for an address that failed too often, else the bearer
/// token, compared in constant time (a failure is counted, and logged at most once a minute per
/// address).
pub async fn authorize(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let admin = match state.admin() {
        Ok(a) => a,
        Err(e) => return e.into_response(),
    };
    let client = client_key(&req);
    if let Verdict::Throttled(secs) = admin.throttle.verdict(client) {
        state
            .metrics
            .counters
            .auth_throttled
            .fetch_add(1, Ordering::Relaxed);
        return ServerError::TooManyRequests(secs).into_response();
    }
    match admin.check_token(req.headers()) {
        Ok(()) => next.run(req).await,
        Err(e) => {
            if let ServerError::Unauthorized(why) = &e {
                state
                    .metrics
                    .counters
                    .auth_failures
                    .fetch_add(1, Ordering::Relaxed);
                admin.throttle.failed(client, why);
            }
            e.into_response()
        }
    }
}
