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
    // Gzip-coded for a client that accepts it (compressed once, not again by the compression
    // layer), twice the same bytes.
    let gz_get = || {
        Request::builder()
            .uri("/vendor/maplibre-gl/maplibre-gl.mjs")
            .header(header::ACCEPT_ENCODING, "gzip, br")
            .body(Body::empty())
            .unwrap()
    };
    let (st, gh, gz) = send(&app, gz_get()).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(
        crate::support::gzip_coded_body(&gh, &gz),
        b"export const v = 1;\n"
    );
    assert_eq!(send(&app, gz_get()).await.2, gz);
    // Strong ETags, one per coding, that revalidate with 304 and no body.
    let tag = h[header::ETAG].to_str().unwrap().to_string();
    let gz_tag = gh[header::ETAG].to_str().unwrap().to_string();
    assert!(tag.starts_with("\"vendor-") && tag.ends_with('"'), "{tag}");
    assert_eq!(gz_tag, format!("{}-gzip\"", tag.trim_end_matches('"')));
    let revalidate = |tag: &str, gzip: bool| {
        let mut r = Request::builder()
            .uri("/vendor/maplibre-gl/maplibre-gl.mjs")
            .header(header::IF_NONE_MATCH, tag);
        if gzip {
            r = r.header(header::ACCEPT_ENCODING, "gzip");
        }
        r.body(Body::empty()).unwrap()
    };
    for (t, gzip) in [(&tag, false), (&gz_tag, true)] {
        let (st, rh, body) = send(&app, revalidate(t, gzip)).await;
        assert_eq!(st, StatusCode::NOT_MODIFIED, "{t}");
        assert!(body.is_empty());
        assert_eq!(rh[header::ETAG], t.as_str());
    }
    assert_eq!(send(&app, revalidate(&tag, true)).await.0, StatusCode::OK);
    // A new install is served, not the cached old one, under another ETag.
    std::fs::write(dir.join("maplibre-gl.mjs"), "export const v = 22;\n").unwrap();
    let (_, gh, gz2) = send(&app, gz_get()).await;
    assert_eq!(
        crate::support::gzip_coded_body(&gh, &gz2),
        b"export const v = 22;\n"
    );
    assert_ne!(gh[header::ETAG], gz_tag.as_str());
    let (st, _, body) = send(&app, revalidate(&tag, false)).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(body, b"export const v = 22;\n");

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

#[tokio::test]
async fn the_readme_minimal_page_is_the_served_file() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let (st, h, body) = get(&app, "/minimal.html").await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "text/html; charset=utf-8");
    let file = include_str!("../../src/server/web/minimal.html");
    assert_eq!(body, file);
    // The README shows the page whole, so that what a reader copies is what the browser test
    // loads; and the page imports the module the server vendors.
    let readme = include_str!("../../README.md");
    assert!(
        readme.contains(&format!("```html\n{file}```")),
        "README's minimal page differs from src/server/web/minimal.html"
    );
    assert!(file.contains("/vendor/maplibre-gl/maplibre-gl.mjs"));
}

#[test]
fn the_readme_world_file_recipe_parses_with_its_title_and_centre() {
    let readme = include_str!("../../README.md");
    let start = readme
        .find("```toml\n# config/worlds/mine.toml")
        .expect("the README's world-file recipe");
    let body = &readme[start + "```toml\n".len()..];
    let body = &body[..body.find("```").unwrap()];
    let w =
        terrasynth::config::parse_world(body, "mine.toml", std::path::Path::new("config/worlds"))
            .unwrap();
    assert_eq!(w.name, "mine");
    assert_eq!(w.title, "My range");
    assert_eq!(w.center, Some([74.5, 42.6]));
    assert_eq!(w.max_zoom, 14);
    assert_eq!(w.dictionary.atoms, 256);
}

#[test]
fn a_world_file_centre_off_the_map_is_refused_by_name() {
    let dir = std::path::Path::new("config/worlds");
    for center in ["[200.0, 0.0]", "[0.0, 89.0]", "[nan, 0.0]"] {
        let text = format!("name = \"w\"\nbase = \"b.tif\"\ncenter = {center}\n");
        let err = terrasynth::config::parse_world(&text, "w.toml", dir).unwrap_err();
        assert!(err.to_string().contains("center"), "{center}: {err}");
    }
    let ok =
        terrasynth::config::parse_world("name = \"w\"\nbase = \"b.tif\"\n", "w.toml", dir).unwrap();
    assert_eq!(ok.center, None);
}
