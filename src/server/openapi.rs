//! The OpenAPI 3.1 description of the whole HTTP API, generated from the code: every route is
//! declared once, in the router ([`super::api_routes`]), with `#[utoipa::path]` on the handler
//! itself, so the description cannot drift from the routes. This module adds the document's
//! info, tags and bearer security scheme, serves it at `/openapi.json`, and writes the copy
//! committed at `openapi/openapi.json` (`terrasynth openapi > openapi/openapi.json`); a test
//! fails when the two differ.
//!
//! Tile layers are described generically (`/tiles/{world}/{layer}/{z}/{x}/{y}`, with the layer
//! and extension as parameters), so that new layers fit without changing the description.

use std::sync::OnceLock;

use axum::body::Bytes;
use axum::http::{HeaderMap, HeaderValue};
use axum::response::Response;
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

use super::conditional::{bytes_etag, revalidated};
use super::error::Problem;

struct BearerAuth;

impl Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The document's frame: info, tags, the problem schema and the security scheme (paths come
/// from the router).
#[derive(OpenApi)]
#[openapi(
    info(
        title = "terrasynth",
        description = "HTTP tile server for synthesized terrain: tiles, metadata, and the admin API that uploads exemplars, builds dictionaries and creates worlds. Errors are RFC 9457 problem+json.",
        license(name = "MIT OR Apache-2.0")
    ),
    components(schemas(Problem)),
    modifiers(&BearerAuth),
    tags(
        (name = "tiles", description = "Tiles and TileJSON"),
        (name = "meta", description = "Worlds, dictionaries, health, metrics"),
        (name = "web", description = "The web map"),
        (name = "admin", description = "Admin API (bearer token; 404 when disabled)")
    )
)]
pub struct ApiDoc;

/// The whole description: the frame merged with every route's.
pub fn spec() -> utoipa::openapi::OpenApi {
    let mut doc = ApiDoc::openapi();
    doc.merge(super::api_routes(true).into_openapi());
    doc
}

/// The description as pretty JSON (what is committed at `openapi/openapi.json`, with a final
/// newline).
pub fn spec_json() -> String {
    let mut s = spec().to_pretty_json().unwrap_or_else(|_| "{}".to_string());
    s.push('\n');
    s
}

/// This description.
#[utoipa::path(get, path = "/openapi.json", tag = "meta", operation_id = "openapi_json",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "OpenAPI 3.1; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = Object),
        (status = 304, description = "Not modified (`If-None-Match`)")
    ))]
pub async fn serve_spec(headers: HeaderMap) -> Response {
    /// The description's bytes and their ETag, made at the first request.
    static SPEC: OnceLock<(Bytes, String)> = OnceLock::new();
    let (body, tag) = SPEC.get_or_init(|| {
        let body = spec_json();
        let tag = bytes_etag(body.as_bytes());
        (Bytes::from(body), tag)
    });
    revalidated(
        &headers,
        tag,
        body.clone(),
        HeaderValue::from_static("application/json"),
        None,
    )
}
