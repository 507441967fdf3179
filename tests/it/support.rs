//! Helpers of this test binary, written once: requests through `tower::ServiceExt::oneshot` on
//! the real router, and `terrasynth serve` processes of this package's binary (the process
//! machinery itself is `terrasynth_test_support::process`).

use std::path::Path;
use std::sync::Arc;

use axum::body::{to_bytes, Body};
use axum::http::{HeaderMap, Request, StatusCode};
use tower::ServiceExt;

pub use terrasynth_test_support::process::{self as proc, Server};

use terrasynth::config::ServerConfig;
use terrasynth::server::{app, AppState, LiveWorlds, Worlds};
use terrasynth_test_support::{mini_world, small_dictionary_with_vegetation, synthetic_terrain};

/// The test binary's small world `mini`: 6°×5° (70–76°E, 38–43°N) of synthetic terrain at 15″,
/// native zoom 8, max zoom 11, a small dictionary with two vegetation layers.
pub fn small_world() -> terrasynth_tiles::World {
    mini_world(
        synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0),
        small_dictionary_with_vegetation(2),
        "test-dictionary",
        11,
        64 << 20,
    )
}

/// The real router serving [`small_world`] as `mini` under `config`, without admin.
pub fn mini_router(config: &ServerConfig) -> axum::Router {
    let mut worlds = Worlds::new();
    worlds.insert("mini".into(), Arc::new(small_world()));
    app(AppState::new(LiveWorlds::new(worlds), None, config).unwrap())
}

/// Sends `req` to `app`; the status, headers and body.
pub async fn send(app: &axum::Router, req: Request<Body>) -> (StatusCode, HeaderMap, Vec<u8>) {
    let resp = app.clone().oneshot(req).await.unwrap();
    let status = resp.status();
    let headers = resp.headers().clone();
    let body = to_bytes(resp.into_body(), 64 << 20).await.unwrap().to_vec();
    (status, headers, body)
}

/// Sends `req` to `app`; the status and the body as JSON (`Null` when it is not JSON).
pub async fn send_json(app: &axum::Router, req: Request<Body>) -> (StatusCode, serde_json::Value) {
    let (st, _, body) = send(app, req).await;
    (
        st,
        serde_json::from_slice(&body).unwrap_or(serde_json::Value::Null),
    )
}

/// Starts this package's `terrasynth serve` in the package directory with extra `args` and
/// environment `env`, its store in `store`, and waits for `/healthz`.
pub fn start(args: &[&str], env: &[(&str, &str)], store: &Path) -> Server {
    proc::start_binary(
        Path::new(env!("CARGO_BIN_EXE_terrasynth")),
        Path::new(env!("CARGO_MANIFEST_DIR")),
        args,
        env,
        store,
    )
}

/// [`start`] with the server's log (its standard output) written to the file `log`.
pub fn start_logging(args: &[&str], env: &[(&str, &str)], store: &Path, log: &Path) -> Server {
    proc::start_binary_logging(
        Path::new(env!("CARGO_BIN_EXE_terrasynth")),
        Path::new(env!("CARGO_MANIFEST_DIR")),
        args,
        env,
        store,
        log,
    )
}

/// Reads an RGBA PNG into rows × cols × 4 bytes.
pub fn decode_rgba(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    buf.truncate(info.buffer_size());
    (info.height as usize, info.width as usize, buf)
}

/// The gzip-coded representation of `path` on `server`, whose identity bytes are `identity`,
/// checked as a client and a shared cache see it: gzip-coded when `Accept-Encoding` takes gzip
/// (and only then), the same bytes once decoded (by flate2's decoder, not the server's code),
/// smaller, a strong ETag of its own that answers 304, and `Vary: Accept-Encoding` on both
/// representations. Returns the gzip bytes.
pub fn check_gzip_coding(server: &Server, path: &str, identity: &[u8]) -> Vec<u8> {
    let plain = proc::get_with(server, path, &[]);
    assert_eq!(plain.status, 200, "{path}");
    assert!(plain.body == identity, "{path}: identity bytes");
    assert_eq!(plain.header("content-encoding"), "", "{path}");
    assert!(plain.header("vary").contains("accept-encoding"), "{path}");
    let gz = proc::get_with(server, path, &[("Accept-Encoding", "gzip, deflate, br")]);
    assert_eq!(gz.status, 200, "{path}");
    assert_eq!(gz.header("content-encoding"), "gzip", "{path}");
    assert!(gz.header("vary").contains("accept-encoding"), "{path}");
    assert!(
        gunzip(&gz.body) == identity,
        "{path}: gzip decodes to other bytes"
    );
    assert!(
        gz.body.len() < identity.len(),
        "{path}: {} gzip bytes from {}",
        gz.body.len(),
        identity.len()
    );
    let (tag, gz_tag) = (plain.header("etag"), gz.header("etag"));
    assert_eq!(
        gz_tag,
        format!("{}-gzip\"", tag.trim_end_matches('"')),
        "{path}"
    );
    let again = proc::get_with(
        server,
        path,
        &[("Accept-Encoding", "gzip"), ("If-None-Match", gz_tag)],
    );
    assert_eq!(again.status, 304, "{path}");
    assert_eq!(again.header("etag"), gz_tag, "{path}");
    assert!(again.body.is_empty());
    // The identity tag names another representation: the gzip one is sent.
    let other = proc::get_with(
        server,
        path,
        &[("Accept-Encoding", "gzip"), ("If-None-Match", tag)],
    );
    assert_eq!(other.status, 200, "{path}");
    assert!(
        other.body == gz.body,
        "{path}: gzip bytes differ between requests"
    );
    // Refused with weight 0, gzip is not sent.
    let refused = proc::get_with(server, path, &[("Accept-Encoding", "gzip;q=0, identity")]);
    assert_eq!(refused.header("content-encoding"), "", "{path}");
    assert!(refused.body == identity, "{path}");
    gz.body
}

/// `gz` decoded by flate2's decoder (not the server's code).
pub fn gunzip(gz: &[u8]) -> Vec<u8> {
    let mut decoded = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(gz), &mut decoded)
        .expect("a gzip stream");
    decoded
}

/// The body of an in-process answer that must be gzip-coded (`Content-Encoding: gzip`, `Vary:
/// Accept-Encoding`), decoded by [`gunzip`].
pub fn gzip_coded_body(headers: &HeaderMap, body: &[u8]) -> Vec<u8> {
    assert_eq!(headers[axum::http::header::CONTENT_ENCODING], "gzip");
    assert!(headers
        .get_all(axum::http::header::VARY)
        .iter()
        .any(|v| v.to_str().unwrap().contains("accept-encoding")));
    gunzip(body)
}
