//! The web map at `/`: an HTML page, its script and style sheet (embedded in the binary, so the
//! page works wherever the binary runs), and MapLibre GL JS served from the npm install
//! (`web_vendor_dir`, by default `node_modules/maplibre-gl/dist` as `scripts/install_web.sh`
//! leaves it). No request leaves for a CDN; without the install the page loads and says how to
//! install MapLibre. MapLibre's files go out gzip-coded to clients that accept it, compressed
//! once ([`super::encoding`]).

use std::path::Path as FsPath;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use terrasynth_tiles::gzip;

use super::encoding::Coding;
use super::error::{Problem, ServerError};
use super::state::AppState;

/// The page.
const INDEX_HTML: &str = include_str!("web/index.html");
/// The page's script (an ES module).
const APP_JS: &str = include_str!("web/app.js");
/// The README's minimal MapLibre GL JS page (the browser test loads it, so it cannot rot).
const MINIMAL_HTML: &str = include_str!("web/minimal.html");
/// The page's style sheet.
const APP_CSS: &str = include_str!("web/app.css");

fn text(body: &'static str, content_type: &'static str) -> Response {
    let mut resp = body.into_response();
    let h = resp.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    resp
}

/// The web map page.
#[utoipa::path(get, path = "/", tag = "web", operation_id = "web_index",
    responses((status = 200, description = "HTML page", body = String, content_type = "text/html")))]
pub async fn index() -> Response {
    text(INDEX_HTML, "text/html; charset=utf-8")
}

/// The README's minimal MapLibre GL JS page: 3D terrain and hillshade of the default world.
#[utoipa::path(get, path = "/minimal.html", tag = "web", operation_id = "web_minimal",
    responses((status = 200, description = "HTML page", body = String, content_type = "text/html")))]
pub async fn minimal() -> Response {
    text(MINIMAL_HTML, "text/html; charset=utf-8")
}

/// The web map's script.
#[utoipa::path(get, path = "/app.js", tag = "web", operation_id = "web_js",
    responses((status = 200, description = "JavaScript", body = String, content_type = "text/javascript")))]
pub async fn app_js() -> Response {
    text(APP_JS, "text/javascript; charset=utf-8")
}

/// The web map's style sheet.
#[utoipa::path(get, path = "/app.css", tag = "web", operation_id = "web_css",
    responses((status = 200, description = "CSS", body = String, content_type = "text/css")))]
pub async fn app_css() -> Response {
    text(APP_CSS, "text/css; charset=utf-8")
}

/// The content type of a vendor file name, or `None` for names that are not served: only plain
/// file names (no directories, nothing hidden) of scripts, style sheets and source maps.
pub fn vendor_content_type(name: &str) -> Option<&'static str> {
    let plain = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    if !plain {
        return None;
    }
    let (_, ext) = name.rsplit_once('.')?;
    match ext {
        "mjs" | "js" => Some("text/javascript; charset=utf-8"),
        "css" => Some("text/css; charset=utf-8"),
        "map" => Some("application/json"),
        _ => None,
    }
}

/// Where the vendor files are read from: `configured`; or, when that is a relative path with
/// nothing at it (a binary run from another directory, e.g. after `cargo install --path .`), the
/// same path under the source tree the binary was built from, if it is still there.
pub async fn vendor_dir(configured: &FsPath) -> std::path::PathBuf {
    let is_dir = |p: std::path::PathBuf| async move {
        tokio::fs::metadata(&p).await.is_ok_and(|m| m.is_dir())
    };
    if configured.is_relative() && !is_dir(configured.to_path_buf()).await {
        let built_from = FsPath::new(env!("CARGO_MANIFEST_DIR")).join(configured);
        if is_dir(built_from.clone()).await {
            return built_from;
        }
    }
    configured.to_path_buf()
}

/// A file of the MapLibre GL JS distribution (from `web_vendor_dir`).
#[utoipa::path(get, path = "/vendor/maplibre-gl/{file}", tag = "web", operation_id = "web_vendor",
    params(("file" = String, Path, description = "A plain `.js`, `.mjs`, `.css` or `.map` file name")),
    responses(
        (status = 200, description = "The file; gzip-coded (`Content-Encoding: gzip`, `Vary: Accept-Encoding`) when the request's `Accept-Encoding` takes gzip", content(("text/javascript"), ("text/css"), ("application/json"))),
        (status = 404, description = "Not a served name, or not installed", body = Problem, content_type = "application/problem+json")
    ))]
pub async fn vendor(
    State(state): State<AppState>,
    Path(file): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let content_type = vendor_content_type(&file)
        .ok_or_else(|| ServerError::NotFound(format!("no vendor file `{file}`")))?;
    let dir = vendor_dir(&state.config.web_vendor_dir).await;
    let path = dir.join(&file);
    let not_installed = move || {
        ServerError::NotFound(format!(
            "`{file}` is not in {}: run scripts/install_web.sh to install MapLibre GL JS",
            dir.display()
        ))
    };
    let coding = Coding::negotiate(&headers);
    let bytes: Bytes = match coding {
        Coding::Identity => tokio::fs::read(&path)
            .await
            .map_err(|_| not_installed())?
            .into(),
        // Compressed once on the blocking pool and cached with the tiles, by the file's length
        // and modification time (a new install is read again); the compression layer would
        // compress the megabyte of MapLibre GL JS at every request on a runtime thread. Not
        // through `AppState::cached_bytes`: the page's script must not wait for, or be refused
        // by, the synthesis queue.
        Coding::Gzip => {
            let meta = tokio::fs::metadata(&path)
                .await
                .map_err(|_| not_installed())?;
            let key = format!(
                "vendor|{}|{}|{:?}",
                path.display(),
                meta.len(),
                meta.modified().ok()
            );
            match state.tile_bytes.get(&key) {
                Some(b) => b,
                None => {
                    let coded = tokio::task::spawn_blocking(move || {
                        let raw = std::fs::read(&path).map_err(|_| not_installed())?;
                        Ok::<_, ServerError>(Bytes::from(gzip(&raw)?))
                    })
                    .await
                    .map_err(|e| ServerError::Internal(e.to_string()))??;
                    state.tile_bytes.insert(key, coded.clone());
                    coded
                }
            }
        }
    };
    let mut resp = bytes.into_response();
    let h = resp.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CACHE_CONTROL, state.cache_control.clone());
    coding.mark(h);
    Ok(resp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_script_style_and_map_names_are_served() {
        assert_eq!(
            vendor_content_type("maplibre-gl.mjs"),
            Some("text/javascript; charset=utf-8")
        );
        assert_eq!(
            vendor_content_type("maplibre-gl.css"),
            Some("text/css; charset=utf-8")
        );
        assert_eq!(
            vendor_content_type("maplibre-gl.mjs.map"),
            Some("application/json")
        );
        for bad in [
            "",
            "..",
            "../Cargo.toml",
            "a/b.js",
            ".hidden.js",
            "x.json",
            "maplibre-gl.d.ts",
            "a%2Fb.js",
            "noext",
        ] {
            assert_eq!(vendor_content_type(bad), None, "{bad}");
        }
    }
}
