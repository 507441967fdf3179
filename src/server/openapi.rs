//! The OpenAPI 3.1 description of the whole HTTP API, generated from the code: every route is
//! declared once, in the router ([`super::api_routes`]), with `#[utoipa::path]` on the handler
//! itself, so the description cannot drift from the routes. This module adds the document's
//! info, tags and bearer security scheme, serves it at `/openapi.json`, and writes the copy
//! committed at `openapi/openapi.json` (`terrasynth openapi > openapi/openapi.json`); a test
//! fails when the two differ.
//!
//! Tile layers are described generically (`/tiles/{world}/{layer}/{z}/{x}/{y}`, with the layer
//! and extension as parameters), so that new layers fit without changing the description.

use axum::http::{header, HeaderValue};
use axum::response::{IntoResponse, Response};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

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
    responses((status = 200, description = "OpenAPI 3.1", body = Object)))]
pub async fn serve_spec() -> Response {
    static SPEC: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    let body = SPEC.get_or_init(spec_json).clone();
    let mut resp = body.into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    resp
}
