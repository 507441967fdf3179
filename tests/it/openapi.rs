//! The committed OpenAPI description (`openapi/openapi.json`) must equal the one generated from
//! the code, which the server also serves at `/openapi.json`. To regenerate the committed copy
//! after changing the API: `cargo run -- openapi > openapi/openapi.json`, or run this test with
//! `TERRASYNTH_UPDATE_OPENAPI=1`.

use axum::body::{to_bytes, Body};
use axum::http::Request;
use tower::ServiceExt;

use terrasynth::config::ServerConfig;
use terrasynth::server::openapi::spec_json;
use terrasynth::server::{app, AppState, LiveWorlds, Worlds};

#[test]
fn committed_openapi_matches_the_code() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("openapi/openapi.json");
    let generated = spec_json();
    if std::env::var_os("TERRASYNTH_UPDATE_OPENAPI").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "openapi/openapi.json is stale: regenerate it with `cargo run -- openapi > openapi/openapi.json` \
         (or TERRASYNTH_UPDATE_OPENAPI=1 cargo test --test it openapi)"
    );
    let v: serde_json::Value = serde_json::from_str(&generated).unwrap();
    assert!(v["openapi"].as_str().unwrap().starts_with("3.1"));
    for path in [
        "/tiles/{world}/{layer}/{z}/{x}/{y}",
        "/worlds",
        "/admin/exemplars",
        "/admin/dictionaries",
        "/admin/jobs/{id}",
        "/admin/worlds",
        "/admin/worlds/{name}",
        "/dictionaries/{id}",
    ] {
        assert!(v["paths"][path].is_object(), "{path} is described");
    }
}

#[tokio::test]
async fn the_server_serves_the_same_description() {
    let app = app(AppState::new(
        LiveWorlds::new(Worlds::new()),
        None,
        &ServerConfig::default(),
    )
    .unwrap());
    let resp = app
        .oneshot(
            Request::builder()
                .uri("/openapi.json")
                .body(Body::empty())
                .unwrap(),
        )
        .await
        .unwrap();
    assert_eq!(resp.status(), 200);
    assert_eq!(resp.headers()["content-type"], "application/json");
    let body = to_bytes(resp.into_body(), 1 << 24).await.unwrap();
    assert_eq!(String::from_utf8_lossy(&body), spec_json());
}
