//! The HTTP server: the router ([`app`], every route declared once with its OpenAPI description
//! in [`api_routes`]), handlers that translate HTTP into calls of the tiles and store crates
//! ([`tiles`], [`meta`], [`features`], point queries in [`points`], [`web`], the admin API in
//! [`admin`]), errors as problem+json
//! ([`error`]), Prometheus metrics ([`metrics`]), the shared state ([`state`]), world loading
//! ([`worlds`]), worlds other replicas created in a shared store ([`pickup`]), start-up ([`startup`]) and the accept loop with its connection limits
//! ([`connections`]), the gzip coding of vector and GeoJSON answers ([`encoding`]), ETags and
//! `If-None-Match` ([`conditional`]). CPU work (tile synthesis and encoding) and blocking IO run on tokio's
//! blocking pool, tiles behind a semaphore and a bounded queue; the async runtime only moves
//! bytes. A request that outlives its deadline, or whose client leaves, cancels the synthesis
//! nobody else waits for.

pub mod admin;
pub mod conditional;
pub mod connections;
pub mod encoding;
pub mod error;
pub mod features;
pub mod meta;
pub mod metrics;
pub mod openapi;
pub mod pickup;
pub mod points;
pub mod startup;
pub mod state;
pub mod tiles;
pub mod web;
pub mod worlds;

use std::time::{Duration, Instant};

use axum::extract::{MatchedPath, Request, State};
use axum::handler::Handler;
use axum::http::{HeaderValue, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::Router;
use tower::Layer;
use tower_http::classify::ServerErrorsFailureClass;
use tower_http::compression::CompressionLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::trace::TraceLayer;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

pub use error::{ServerError, StartupError};
pub use startup::serve;
pub use state::{AppState, LiveWorlds};
pub use worlds::{load_worlds, share_shortfall, Worlds};

use crate::config::ServerConfig;
use metrics::Overload;

/// What [`edge`] needs: the server's state and the deadline of the routes it wraps (`None`: no
/// deadline).
#[derive(Clone)]
struct Edge {
    state: AppState,
    deadline: Option<Duration>,
}

/// The edge of every route, one middleware (a middleware layer clones the route's service below
/// it for every request, so one layer instead of four saves those clones on the warm path). From
/// the outside in: the request's metrics (route template, method, status, latency, overload
/// reason), the problem+json shape of error responses ([`error::into_problem`]), 414 for a
/// request target longer than `max_uri_bytes`, and the deadline: 503 (problem+json,
/// `Retry-After`) when the inner service takes longer. Dropping the inner future drops its
/// cancellation guards, so that synthesis nobody else waits for stops too.
async fn edge(State(edge): State<Edge>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    let state = &edge.state;
    // A route template (bounded), never the path the client sent.
    let route = req.extensions().get::<MatchedPath>().cloned();
    let method = req.method().clone();
    let len = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    let max = state.config.max_uri_bytes;
    let resp = if len > max {
        ServerError::UriTooLong(format!(
            "the request target has {len} bytes; at most {max} are accepted"
        ))
        .into_response()
    } else {
        let resp = match edge.deadline {
            Some(limit) => match tokio::time::timeout(limit, next.run(req)).await {
                Ok(resp) => resp,
                Err(_) => ServerError::Timeout(limit.as_secs()).into_response(),
            },
            None => next.run(req).await,
        };
        error::into_problem(resp).await
    };
    if let Some(why) = resp.extensions().get::<Overload>() {
        state.metrics.counters.overload(*why);
    }
    state.metrics.record(
        route.as_ref().map_or("unmatched", MatchedPath::as_str),
        &method,
        resp.status().as_u16(),
        start.elapsed(),
    );
    resp
}

/// Logs server faults at ERROR, but overload answers (503) only at DEBUG: they are counted in
/// the metrics, and a flood of them must not flood the log.
fn on_failure(class: ServerErrorsFailureClass, latency: Duration, _span: &tracing::Span) {
    match class {
        ServerErrorsFailureClass::StatusCode(StatusCode::SERVICE_UNAVAILABLE) => {
            tracing::debug!(
                latency_ms = latency.as_millis() as u64,
                "overloaded: answered 503"
            )
        }
        other => {
            tracing::error!(classification = %other, latency_ms = latency.as_millis() as u64, "response failed")
        }
    }
}

async fn not_found() -> ServerError {
    ServerError::NotFound("no such resource".into())
}

fn cors(config: &ServerConfig) -> CorsLayer {
    let layer = CorsLayer::new()
        .allow_methods([Method::GET, Method::HEAD, Method::OPTIONS])
        .expose_headers([axum::http::header::ETAG]);
    if config.cors_origins.iter().any(|o| o == "*") || config.cors_origins.is_empty() {
        layer.allow_origin(AllowOrigin::any())
    } else {
        let origins: Vec<HeaderValue> = config
            .cors_origins
            .iter()
            .filter_map(|o| HeaderValue::from_str(o).ok())
            .collect();
        layer.allow_origin(origins)
    }
}

/// The public routes (tiles, metadata, the web map) and, with `admin`, the admin routes — each
/// declared once with its OpenAPI description. Layers that do not change the description
/// (timeouts, auth, compression) are added by [`app`].
pub fn api_routes(admin: bool) -> OpenApiRouter<AppState> {
    let public = OpenApiRouter::new()
        .routes(routes!(tiles::tile))
        .routes(routes!(meta::healthz))
        .routes(routes!(meta::metrics));
    let json = OpenApiRouter::new()
        .routes(routes!(meta::worlds))
        .routes(routes!(admin::dictionaries::list_dictionaries))
        .routes(routes!(admin::dictionaries::get_dictionary))
        .routes(routes!(openapi::serve_spec))
        .routes(routes!(meta::world))
        .routes(routes!(features::features))
        .routes(routes!(points::elevation_at, points::elevation_profile))
        .routes(routes!(meta::tilejson))
        .routes(routes!(meta::style))
        .routes(routes!(meta::wmts_capabilities))
        .layer(CompressionLayer::new());
    let web = OpenApiRouter::new()
        .routes(routes!(web::index))
        .routes(routes!(web::minimal))
        .routes(routes!(web::app_js))
        .routes(routes!(web::app_css))
        .routes(routes!(web::vendor))
        .layer(CompressionLayer::new());
    let mut router = public.merge(json).merge(web);
    if admin {
        router = router.merge(admin_routes());
    }
    router
}

/// The admin routes (without their layers).
fn admin_routes() -> OpenApiRouter<AppState> {
    use admin::{dictionaries, exemplars, jobs, worlds};
    OpenApiRouter::new()
        .routes(routes!(exemplars::post_exemplar, exemplars::list_exemplars))
        .routes(routes!(exemplars::get_exemplar, exemplars::delete_exemplar))
        .routes(routes!(dictionaries::post_dictionary))
        .routes(routes!(dictionaries::delete_dictionary))
        .routes(routes!(jobs::list_jobs))
        .routes(routes!(jobs::get_job, jobs::cancel_job))
        .routes(routes!(worlds::post_world))
        .routes(routes!(worlds::post_sketch_world))
        .routes(routes!(worlds::delete_world))
}

/// The router of the whole HTTP API.
pub fn app(state: AppState) -> Router {
    let timeout = Duration::from_secs(state.config.request_timeout_s.max(1));
    let upload_timeout = Duration::from_secs(state.config.upload_timeout_s.max(1));
    let edge_with = |deadline: Option<Duration>| {
        middleware::from_fn_with_state(
            Edge {
                state: state.clone(),
                deadline,
            },
            edge,
        )
    };
    let (public, _) = api_routes(false).split_for_parts();
    let admin_enabled = state.admin.as_ref().is_some_and(|a| a.enabled());
    let admin: Router<AppState> = if admin_enabled {
        let max_body = state.admin.as_ref().map_or(2 << 20, |a| a.limits.max_body);
        let (routes, _) = admin_routes().split_for_parts();
        routes
            .route_layer(middleware::from_fn_with_state(
                state.clone(),
                admin::auth::authorize,
            ))
            .layer(axum::extract::DefaultBodyLimit::max(max_body))
            .layer(edge_with(Some(upload_timeout)))
    } else {
        Router::new()
    };
    // Unknown paths: the edge without a deadline (metrics as "unmatched", 414 first).
    let fallback = Layer::layer(
        &edge_with(None),
        Handler::with_state(not_found, state.clone()),
    );
    public
        .layer(edge_with(Some(timeout)))
        .merge(admin)
        .fallback_service(fallback)
        .layer(tower::limit::GlobalConcurrencyLimitLayer::new(4096))
        .layer(cors(&state.config))
        .layer(TraceLayer::new_for_http().on_failure(on_failure))
        .with_state(state)
}
