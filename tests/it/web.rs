//! The web map's routes through `oneshot` on the real router: the embedded page, its script and
//! style sheet, and MapLibre GL JS served from the configured install directory (real files in a
//! temporary directory), with a clear 404 when the install is missing and no path escapes. The
//! page itself is tested in a real browser by `scripts/browser_test.sh`.

use axum::body::Body;
use axum::http::{header, Request, StatusCode};

use terrasynth::config::ServerConfig;
use terrasynth::server::{app, AppState, LiveWorlds, Worlds};

use crate::support::send;

fn router(vendor_dir: &std::path::Path) -> axum::Router {
    let config = ServerConfig {
        web_vendor_dir: vendor_dir.to_path_buf(),
        ..ServerConfig::default()
    };
    app(AppState::new(LiveWorlds::new(Worlds::new()), None, &config).unwrap())
}

async fn get(app: &axum::Router, uri: &str) -> (StatusCode, axum::http::HeaderMap, String) {
    let req = Request::builder()
        .uri(uri)
        .header(header::ORIGIN, "https://map.example")
        .body(Body::empty())
        .unwrap();
    let (status, headers, body) = send(app, req).await;
    (status, headers, String::from_utf8_lossy(&body).into_owned())
}

#[tokio::test]
async fn the_page_its_script_and_style_are_served() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let (st, h, html) = get(&app, "/").await;
    assert_eq!(st, StatusCode::OK);
    assert!(h[header::CONTENT_TYPE]
        .to_str()
        .unwrap()
        .starts_with("text/html"));
    assert!(html.contains(r#"<script type="module" src="/app.js">"#));
    assert!(html.contains(r#"href="/openapi.json""#));

    let (st, h, js) = get(&app, "/app.js").await;
    assert_eq!(st, StatusCode::OK);
    assert!(h[header::CONTENT_TYPE]
        .to_str()
        .unwrap()
        .starts_with("text/javascript"));
    // The page loads MapLibre from this server and uses the world's style endpoint.
    assert!(js.contains("/vendor/maplibre-gl/maplibre-gl.mjs"));
    assert!(js.contains("/styles/${world.name}.json"));
    assert!(
        !js.contains("https://"),
        "no CDN or other remote URL in the page script"
    );

    let (st, h, _) = get(&app, "/app.css").await;
    assert_eq!(st, StatusCode::OK);
    assert!(h[header::CONTENT_TYPE]
        .to_str()
        .unwrap()
        .starts_with("text/css"));
}

#[tokio::test]
async fn maplibre_comes_from_the_install_directory() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("dist");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("maplibre-gl.mjs"), "export const v = 1;\n").unwrap();
    std::fs::write(dir.join("secret.txt"), "no").unwrap();
    std::fs::write(root.path().join("outside.js"), "no").unwrap();
    let app = router(&dir);

    let (st, h, body) = get(&app, "/vendor/maplibre-gl/maplibre-gl.mjs").await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(body, "export const v = 1;\n");
    assert!(h[header::CONTENT_TYPE]
        .to_str()
        .unwrap()
        .starts_with("text/javascript"));
    assert_eq!(h[header::ACCESS_CONTROL_ALLOW_ORIGIN], "*");

    for uri in [
        "/vendor/maplibre-gl/secret.txt",
        "/vendor/maplibre-gl/..%2Foutside.js",
        "/vendor/maplibre-gl/%2E%2E",
        "/vendor/maplibre-gl/.hidden.js",
    ] {
        let (st, h, _) = get(&app, uri).await;
        assert_eq!(st, StatusCode::NOT_FOUND, "{uri}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json", "{uri}");
    }
}

#[tokio::test]
async fn a_missing_install_is_a_clear_404() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(&dir.path().join("not-installed"));
    let (st, h, body) = get(&app, "/vendor/maplibre-gl/maplibre-gl.mjs").await;
    assert_eq!(st, StatusCode::NOT_FOUND);
    assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
    assert!(body.contains("scripts/install_web.sh"), "{body}");
    // The page itself still loads (it shows the same advice when the import fails).
    let (st, _, _) = get(&app, "/").await;
    assert_eq!(st, StatusCode::OK);
    let (_, _, js) = get(&app, "/app.js").await;
    assert!(js.contains("scripts/install_web.sh"));
}
