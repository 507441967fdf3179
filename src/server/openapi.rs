//! The OpenAPI 3.1 description of the whole HTTP API, generated from the code with `utoipa`:
//! response and request types derive `ToSchema`, and every route is declared here with
//! `#[utoipa::path]` on a documentation-only function (the handlers live in [`super::tiles`],
//! [`super::meta`] and [`super::admin`]). It is served at `/openapi.json` and committed at
//! `openapi/openapi.json`; `tests/openapi.rs` fails when the two differ. Regenerate the
//! committed copy with `terrasynth openapi > openapi/openapi.json` (or run the test with
//! `TERRASYNTH_UPDATE_OPENAPI=1`).
//!
//! Tile layers are described generically (`/tiles/{world}/{layer}/{z}/{x}/{y}`, with the layer
//! and extension as parameters), so that new layers fit without changing the description.
#![allow(dead_code)]

use axum::http::{header, HeaderValue};
use axum::response::{IntoResponse, Response};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

use super::admin::jobs::{DictionaryRequest, Job, JobState};
use super::admin::{
    DictionaryInfo, ExemplarInfo, JobAccepted, Statistics, WorldCreated, WorldDefinition,
    WorldRequest,
};
use super::error::Problem;
use super::meta::WorldInfo;
use crate::tiles::{TerrainEncoding, TileJson};

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

/// The API description.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "terrasynth",
        description = "HTTP tile server for synthesized terrain: tiles, metadata, and the admin API that uploads exemplars, builds dictionaries and creates worlds. Errors are RFC 9457 problem+json.",
        license(name = "MIT OR Apache-2.0")
    ),
    paths(
        tile, tilejson, style, worlds, world, healthz, metrics, openapi_json, dictionaries, dictionary,
        web_index, web_js, web_css, web_vendor,
        post_exemplar, list_exemplars, get_exemplar, delete_exemplar, post_dictionary,
        delete_dictionary, list_jobs, get_job, cancel_job, post_world, delete_world
    ),
    components(schemas(
        Problem, RasterFile, ExemplarForm, WorldInfo, TileJson, TerrainEncoding, DictionaryInfo, ExemplarInfo, Statistics,
        DictionaryRequest, Job, JobState, JobAccepted, WorldRequest, WorldCreated, WorldDefinition
    )),
    modifiers(&BearerAuth),
    tags(
        (name = "tiles", description = "Tiles and TileJSON"),
        (name = "meta", description = "Worlds, dictionaries, health, metrics"),
        (name = "web", description = "The web map"),
        (name = "admin", description = "Admin API (bearer token; 404 when disabled)")
    )
)]
pub struct ApiDoc;

/// The description as pretty JSON (what is committed at `openapi/openapi.json`, with a final
/// newline).
pub fn spec_json() -> String {
    let mut s = ApiDoc::openapi()
        .to_pretty_json()
        .unwrap_or_else(|_| "{}".to_string());
    s.push('\n');
    s
}

/// `GET /openapi.json`.
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

/// A raster file (GeoTIFF, 16-bit PNG or OpenEXR).
#[derive(utoipa::ToSchema)]
#[schema(value_type = String, format = Binary)]
struct RasterFile(Vec<u8>);

/// A multipart exemplar: an `elevation` part and any number of named layer parts (each a raster
/// file on the elevation's grid).
#[derive(utoipa::ToSchema)]
struct ExemplarForm {
    /// The elevation raster.
    #[schema(value_type = String, format = Binary)]
    elevation: Vec<u8>,
}

/// A tile.
#[utoipa::path(
    get,
    path = "/tiles/{world}/{layer}/{z}/{x}/{y}",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name", example = "tienshan"),
        ("layer" = String, Path, description = "Layer: `elevation`, `hillshade`, or any other layer the world lists in `/worlds/{world}`"),
        ("z" = String, Path, description = "Zoom"),
        ("x" = String, Path, description = "Column"),
        ("y" = String, Path, description = "Row with the format extension: `{y}.png`, `{y}@2x.png` (512 px) or `{y}.exr` (float32)"),
        ("encoding" = Option<String>, Query, description = "Elevation PNG packing: `terrarium` (default) or `mapbox`"),
        ("azimuth" = Option<String>, Query, description = "Hillshade sun azimuth, degrees (0–360, default 315)"),
        ("altitude" = Option<String>, Query, description = "Hillshade sun altitude, degrees (0–90, default 45)"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "The tile; strong `ETag`, `Cache-Control` from the configuration",
            content(("image/png"), ("image/x-exr"))),
        (status = 304, description = "Not modified (the `If-None-Match` ETag matches)"),
        (status = 400, description = "Malformed coordinates or parameters", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world, layer or format, zoom too deep, tile outside the world", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Synthesis queue full (`Retry-After`)", body = Problem, content_type = "application/problem+json")
    )
)]
fn tile() {}

/// TileJSON 3.0.0 of a layer.
#[utoipa::path(
    get,
    path = "/tiles/{world}/{file}",
    tag = "tiles",
    params(
        ("world" = String, Path, description = "World name"),
        ("file" = String, Path, description = "`{layer}.json`")
    ),
    responses(
        (status = 200, description = "TileJSON", body = TileJson),
        (status = 404, description = "Unknown world or layer", body = Problem, content_type = "application/problem+json")
    )
)]
fn tilejson() {}

/// MapLibre style (version 8) of a world: its raster-dem as terrain and hillshade, the colour
/// map, vegetation overlay and drainage overlay as raster layers switchable with
/// `layout.visibility`.
#[utoipa::path(
    get,
    path = "/styles/{file}",
    tag = "tiles",
    params(("file" = String, Path, description = "`{world}.json`")),
    responses(
        (status = 200, description = "MapLibre style", body = Object),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    )
)]
fn style() {}

/// Every world.
#[utoipa::path(get, path = "/worlds", tag = "meta",
    responses((status = 200, description = "Worlds", body = Vec<WorldInfo>)))]
fn worlds() {}

/// One world.
#[utoipa::path(get, path = "/worlds/{world}", tag = "meta",
    params(("world" = String, Path, description = "World name")),
    responses(
        (status = 200, description = "The world", body = WorldInfo),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json")
    ))]
fn world() {}

/// Liveness.
#[utoipa::path(get, path = "/healthz", tag = "meta",
    responses((status = 200, description = "`ok`", body = String, content_type = "text/plain")))]
fn healthz() {}

/// Prometheus metrics.
#[utoipa::path(get, path = "/metrics", tag = "meta",
    responses((status = 200, description = "Prometheus text exposition", body = String, content_type = "text/plain")))]
fn metrics() {}

/// This description.
#[utoipa::path(get, path = "/openapi.json", tag = "meta",
    responses((status = 200, description = "OpenAPI 3.1", body = Object)))]
fn openapi_json() {}

/// Every dictionary of the store.
#[utoipa::path(get, path = "/dictionaries", tag = "meta",
    responses((status = 200, description = "Dictionaries", body = Vec<DictionaryInfo>)))]
fn dictionaries() {}

/// One dictionary.
#[utoipa::path(get, path = "/dictionaries/{id}", tag = "meta",
    params(("id" = String, Path, description = "Dictionary id")),
    responses(
        (status = 200, description = "The dictionary", body = DictionaryInfo),
        (status = 404, description = "Unknown dictionary", body = Problem, content_type = "application/problem+json")
    ))]
fn dictionary() {}

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
fn post_exemplar() {}

/// Every exemplar.
#[utoipa::path(get, path = "/admin/exemplars", tag = "admin", security(("bearer" = [])),
    responses(
        (status = 200, description = "Exemplars", body = Vec<ExemplarInfo>),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json")
    ))]
fn list_exemplars() {}

/// One exemplar.
#[utoipa::path(get, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 200, description = "The exemplar", body = ExemplarInfo),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown exemplar", body = Problem, content_type = "application/problem+json")
    ))]
fn get_exemplar() {}

/// Delete an exemplar.
#[utoipa::path(delete, path = "/admin/exemplars/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Exemplar id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown exemplar", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Used by a build or a world", body = Problem, content_type = "application/problem+json")
    ))]
fn delete_exemplar() {}

/// Queue a dictionary build.
#[utoipa::path(post, path = "/admin/dictionaries", tag = "admin", security(("bearer" = [])),
    request_body = DictionaryRequest,
    responses(
        (status = 202, description = "Queued; `Location: /admin/jobs/{id}`", body = JobAccepted,
            headers(("Location" = String, description = "The job"))),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid parameters or unknown exemplar", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Build queue full", body = Problem, content_type = "application/problem+json")
    ))]
fn post_dictionary() {}

/// Delete a dictionary.
#[utoipa::path(delete, path = "/admin/dictionaries/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Dictionary id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown dictionary", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Used by a world", body = Problem, content_type = "application/problem+json")
    ))]
fn delete_dictionary() {}

/// Every job.
#[utoipa::path(get, path = "/admin/jobs", tag = "admin", security(("bearer" = [])),
    responses(
        (status = 200, description = "Jobs, oldest first", body = Vec<Job>),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json")
    ))]
fn list_jobs() {}

/// One job.
#[utoipa::path(get, path = "/admin/jobs/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = Job),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown job", body = Problem, content_type = "application/problem+json")
    ))]
fn get_job() {}

/// Cancel a queued or running job.
#[utoipa::path(delete, path = "/admin/jobs/{id}", tag = "admin", security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 202, description = "Cancelled (queued) or cancelling (running)", body = Job),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Already ended", body = Problem, content_type = "application/problem+json")
    ))]
fn cancel_job() {}

/// Create a world.
#[utoipa::path(post, path = "/admin/worlds", tag = "admin", security(("bearer" = [])),
    request_body = WorldRequest,
    responses(
        (status = 201, description = "Created; tiles are served at once", body = WorldCreated),
        (status = 400, description = "Malformed JSON", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Name taken", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not JSON", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Unknown base or dictionary, invalid zoom or weights", body = Problem, content_type = "application/problem+json")
    ))]
fn post_world() {}

/// Delete a world.
#[utoipa::path(delete, path = "/admin/worlds/{name}", tag = "admin", security(("bearer" = [])),
    params(("name" = String, Path, description = "World name")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong token", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown world", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "A configured (read-only) world", body = Problem, content_type = "application/problem+json")
    ))]
fn delete_world() {}

/// The web map page.
#[utoipa::path(get, path = "/", tag = "web",
    responses((status = 200, description = "HTML page", body = String, content_type = "text/html")))]
fn web_index() {}

/// The web map's script.
#[utoipa::path(get, path = "/app.js", tag = "web",
    responses((status = 200, description = "JavaScript", body = String, content_type = "text/javascript")))]
fn web_js() {}

/// The web map's style sheet.
#[utoipa::path(get, path = "/app.css", tag = "web",
    responses((status = 200, description = "CSS", body = String, content_type = "text/css")))]
fn web_css() {}

/// A file of the MapLibre GL JS distribution (from `web_vendor_dir`).
#[utoipa::path(get, path = "/vendor/maplibre-gl/{file}", tag = "web",
    params(("file" = String, Path, description = "A plain `.js`, `.mjs`, `.css` or `.map` file name")),
    responses(
        (status = 200, description = "The file", content(("text/javascript"), ("text/css"), ("application/json"))),
        (status = 404, description = "Not a served name, or not installed", body = Problem, content_type = "application/problem+json")
    ))]
fn web_vendor() {}
