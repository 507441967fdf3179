//! The web map at `/`: an HTML page, its script and style sheet (embedded in the binary, so the
//! page works wherever the binary runs), and MapLibre GL JS served from the npm install
//! (`web_vendor_dir`, by default `node_modules/maplibre-gl/dist` as `scripts/install_web.sh`
//! leaves it). No request leaves for a CDN; without the install the page loads and says how to
//! install MapLibre. MapLibre's files go out gzip-coded to clients that accept it, compressed
//! once ([`super::encoding`]). The embedded files carry a weak ETag of their bytes and
//! `Cache-Control: no-cache` ([`super::conditional`]): a reload revalidates them with a 304.

use std::path::Path as FsPath;
use std::sync::OnceLock;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use terrasynth_store::object::hex;
use terrasynth_tiles::gzip;

use super::conditional::{bytes_etag, none_match, revalidated};
use super::encoding::Coding;
use super::error::{Problem, ServerError};
use super::state::AppState;

/// A file embedded in the binary, with its weak ETag computed at its first request.
struct Embedded {
    body: &'static str,
    content_type: &'static str,
    tag: OnceLock<String>,
}

impl Embedded {
    const fn new(body: &'static str, content_type: &'static str) -> Embedded {
        Embedded {
            body,
            content_type,
            tag: OnceLock::new(),
        }
    }

    /// The file, or a 304 when `If-None-Match` names its ETag; `Cache-Control: no-cache`.
    fn answer(&self, headers: &HeaderMap) -> Response {
        let tag = self.tag.get_or_init(|| bytes_etag(self.body.as_bytes()));
        revalidated(
            headers,
            tag,
            Bytes::from_static(self.body.as_bytes()),
            HeaderValue::from_static(self.content_type),
            None,
        )
    }
}

/// The page.
static INDEX_HTML: Embedded =
    Embedded::new(include_str!("web/index.html"), "text/html; charset=utf-8");
/// The page's script (an ES module).
static APP_JS: Embedded =
    Embedded::new(include_str!("web/app.js"), "text/javascript; charset=utf-8");
/// The README's minimal MapLibre GL JS page (the browser test loads it, so it cannot rot).
static MINIMAL_HTML: Embedded =
    Embedded::new(include_str!("web/minimal.html"), "text/html; charset=utf-8");
/// The page's style sheet.
static APP_CSS: Embedded = Embedded::new(include_str!("web/app.css"), "text/css; charset=utf-8");

/// The web map page.
#[utoipa::path(get, path = "/", tag = "web", operation_id = "web_index",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "HTML page; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = String, content_type = "text/html"),
        (status = 304, description = "Not modified (`If-None-Match`)")
    ))]
pub async fn index(headers: HeaderMap) -> Response {
    INDEX_HTML.answer(&headers)
}

/// The README's minimal MapLibre GL JS page: 3D terrain and hillshade of the default world.
#[utoipa::path(get, path = "/minimal.html", tag = "web", operation_id = "web_minimal",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "HTML page; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = String, content_type = "text/html"),
        (status = 304, description = "Not modified (`If-None-Match`)")
    ))]
pub async fn minimal(headers: HeaderMap) -> Response {
    MINIMAL_HTML.answer(&headers)
}

/// The web map's script.
#[utoipa::path(get, path = "/app.js", tag = "web", operation_id = "web_js",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "JavaScript; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = String, content_type = "text/javascript"),
        (status = 304, description = "Not modified (`If-None-Match`)")
    ))]
pub async fn app_js(headers: HeaderMap) -> Response {
    APP_JS.answer(&headers)
}

/// The web map's style sheet.
#[utoipa::path(get, path = "/app.css", tag = "web", operation_id = "web_css",
    params(("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")),
    responses(
        (status = 200, description = "CSS; a weak `ETag` of the bytes, `Cache-Control: no-cache`", body = String, content_type = "text/css"),
        (status = 304, description = "Not modified (`If-None-Match`)")
    ))]
pub async fn app_css(headers: HeaderMap) -> Response {
    APP_CSS.answer(&headers)
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
    params(
        ("file" = String, Path, description = "A plain `.js`, `.mjs`, `.css` or `.map` file name"),
        ("If-None-Match" = Option<String>, Header, description = "ETag of a cached copy")
    ),
    responses(
        (status = 200, description = "The file; a strong `ETag` of the install (path, length, modification time), `Cache-Control` from the configuration; gzip-coded (`Content-Encoding: gzip`, an ETag of its own ending `-gzip\"`, `Vary: Accept-Encoding`) when the request's `Accept-Encoding` takes gzip", content(("text/javascript"), ("text/css"), ("application/json"))),
        (status = 304, description = "Not modified (`If-None-Match`)"),
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
    let meta = tokio::fs::metadata(&path)
        .await
        .map_err(|_| not_installed())?;
    // The install's identity (path, length, modification time) names the file's bytes: a new
    // install has another ETag, and another cache key for its gzip coding.
    let install = format!(
        "{}|{}|{:?}",
        path.display(),
        meta.len(),
        meta.modified().ok()
    );
    let digest = Sha256::digest(install.as_bytes());
    let identity_tag = format!("\"vendor-{}\"", hex(&digest[..16]));
    let coding = Coding::negotiate(&headers);
    let tag = coding.etag(&identity_tag);
    let tag_value =
        HeaderValue::from_str(&tag).map_err(|e| ServerError::Internal(e.to_string()))?;
    let mut resp = if none_match(&headers, &tag) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        let bytes: Bytes = match coding {
            Coding::Identity => tokio::fs::read(&path)
                .await
                .map_err(|_| not_installed())?
                .into(),
            // Compressed once on the blocking pool and cached with the tiles under its ETag;
            // the compression layer would compress the megabyte of MapLibre GL JS at every
            // request on a runtime thread. Not through `AppState::cached_bytes`: the page's
            // script must not wait for, or be refused by, the synthesis queue.
            Coding::Gzip => match state.tile_bytes.get(&tag) {
                Some(b) => b,
                None => {
                    let coded = tokio::task::spawn_blocking(move || {
                        let raw = std::fs::read(&path).map_err(|_| not_installed())?;
                        Ok::<_, ServerError>(Bytes::from(gzip(&raw)?))
                    })
                    .await
                    .map_err(|e| ServerError::Internal(e.to_string()))??;
                    state.tile_bytes.insert(tag.clone(), coded.clone());
                    coded
                }
            },
        };
        let mut resp = bytes.into_response();
        resp.headers_mut()
            .insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
        resp
    };
    let h = resp.headers_mut();
    h.insert(header::ETAG, tag_value);
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
