//! Issue #14 (a server you can put on the internet): one test per defect it lists, on the real
//! router through `oneshot` or on the real binary, whichever reproduces the defect.
//!
//! 1. metric labels stay bounded whatever method or path a client sends;
//! 2. slow and idle connections are closed, and the connection cap keeps `/healthz` reachable when
//!    file descriptors are scarce (real binary);
//! 3. overload 503s are counted, never logged at ERROR;
//! 4. synthesis nobody waits for any more stops (while a request still waiting gets its tile), and
//!    a world whose share cannot hold its whole-world layers is flagged;
//! 5. uploads are bounded in memory (decoded size against a budget), in number, and spooled as
//!    they arrive;
//! 6. TileJSON URLs use `public_url`, or the listening address without a `Host`, and say `Vary`;
//! 7. every error status is problem+json (request timeout, 405, 414, invalid UTF-8 path);
//! 8. strict parameters (canonical coordinates, repeated keys, parameters per format) that the
//!    URLs of the TileJSON and styles still satisfy, and unknown build weights are 422;
//! 9. the store repairs aliases, orphans and bad job records, refuses foreign directories, and
//!    verifies exemplars lazily without ever describing a corrupted one;
//! 10. failed authentication is counted, logged and rate-limited per address.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use axum::extract::ConnectInfo;
use axum::http::{header, Method, Request, StatusCode};

use terrasynth::config::{parse_world, Config, Secret, ServerConfig};
use terrasynth::server::startup::state_with;
use terrasynth::server::{app, share_shortfall, AppState, LiveWorlds, Worlds};
use terrasynth_store::{Store, StoreError};
use terrasynth_tiles::World;

use crate::support::{proc, send, send_json, Server};
use terrasynth_test_support::{
    geotiff_bytes, mini_world, small_dictionary, small_dictionary_with_vegetation,
    synthetic_terrain,
};

const TOKEN: &str = "hardening-token-42";

/// Spins (asynchronously) until `cond` holds; fails the test after 120 s: a hang is a failure.
async fn eventually(what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while !cond() {
        assert!(Instant::now() < deadline, "never: {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// The 6°×5° synthetic world of the server tests (native zoom 8, max zoom 11).
fn tile_world() -> Arc<World> {
    Arc::new(mini_world(
        synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0),
        small_dictionary_with_vegetation(2),
        "test-dictionary",
        11,
        64 << 20,
    ))
}

fn public_router(world: Arc<World>, config: &ServerConfig) -> axum::Router {
    let mut worlds = Worlds::new();
    worlds.insert("mini".into(), world);
    app(AppState::new(LiveWorlds::new(worlds), None, config).unwrap())
}

fn get(uri: &str) -> Request<Body> {
    Request::builder()
        .uri(uri)
        .header(header::ORIGIN, "https://map.example")
        .body(Body::empty())
        .unwrap()
}

/// A router with the admin API enabled over a store in `store`, and a small configured world.
fn admin_router(store: &Path, edit: impl FnOnce(&mut ServerConfig)) -> axum::Router {
    let mut server = ServerConfig {
        store_dir: store.to_path_buf(),
        admin_token: Secret(TOKEN.into()),
        cache_mb: 32,
        ..ServerConfig::default()
    };
    edit(&mut server);
    let mini = parse_world(
        "name = \"mini\"\nbase = \"x.tif\"\nmax_zoom = 10\n",
        "mini.toml",
        store,
    )
    .unwrap();
    let config = Config {
        server,
        worlds: vec![mini],
    };
    let mut worlds = Worlds::new();
    worlds.insert(
        "mini".into(),
        Arc::new(mini_world(
            synthetic_terrain(240, 240, 3),
            small_dictionary(2),
            "mini-dictionary",
            10,
            16 << 20,
        )),
    );
    let store = Store::open(&config.server.store_dir).unwrap();
    app(state_with(&config, store, worlds).unwrap())
}

fn admin(method: Method, uri: &str, content_type: Option<&str>, body: Body) -> Request<Body> {
    let mut b = Request::builder()
        .method(method)
        .uri(uri)
        .header(header::AUTHORIZATION, format!("Bearer {TOKEN}"));
    if let Some(ct) = content_type {
        b = b.header(header::CONTENT_TYPE, ct);
    }
    b.body(body).unwrap()
}

/// A request body whose chunks the test sends through the returned channel (the body ends when
/// the sender is dropped).
fn streamed_body() -> (tokio::sync::mpsc::Sender<Bytes>, Body) {
    let (tx, rx) = tokio::sync::mpsc::channel::<Bytes>(4);
    let stream = futures_util::stream::unfold(rx, |mut rx| async move {
        rx.recv().await.map(|c| (Ok::<_, std::io::Error>(c), rx))
    });
    (tx, Body::from_stream(stream))
}

/// The value of the metric line starting with `series` (name and labels) in `/metrics`.
async fn metric(app: &axum::Router, series: &str) -> f64 {
    let (st, _, body) = send(app, get("/metrics")).await;
    assert_eq!(st, StatusCode::OK);
    let text = String::from_utf8(body).unwrap();
    text.lines()
        .find_map(|l| l.strip_prefix(series).and_then(|v| v.trim().parse().ok()))
        .unwrap_or_else(|| panic!("no metric `{series}` in:\n{text}"))
}

fn assert_problem(st: StatusCode, h: &axum::http::HeaderMap, body: &[u8], want: StatusCode) {
    assert_eq!(st, want, "{}", String::from_utf8_lossy(body));
    assert_eq!(
        h[header::CONTENT_TYPE],
        "application/problem+json",
        "{want}"
    );
    let v: serde_json::Value = serde_json::from_slice(body).unwrap();
    assert_eq!(v["status"], want.as_u16());
    assert!(
        v["title"].is_string() && !v["detail"].as_str().unwrap_or("").is_empty(),
        "{v}"
    );
}

/// Log lines captured from the tracing events of the current thread.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Captured {
    /// Captures every event (DEBUG and up) of this thread until the guard is dropped.
    fn install(&self) -> tracing::subscriber::DefaultGuard {
        let me = self.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_ansi(false)
            .with_max_level(tracing::Level::DEBUG)
            .with_writer(move || me.clone())
            .finish();
        tracing::subscriber::set_default(subscriber)
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(&self.0.lock().unwrap()).into_owned()
    }
}

// --- 1. metrics cardinality ---

#[tokio::test]
async fn metric_labels_stay_bounded_whatever_clients_send() {
    let app = public_router(tile_world(), &ServerConfig::default());
    for i in 0..200 {
        let method = Method::from_bytes(format!("M{i}X").as_bytes()).unwrap();
        let uri = if i % 2 == 0 {
            "/healthz".to_string()
        } else {
            format!("/no/such/{i}")
        };
        let r = Request::builder()
            .method(method)
            .uri(uri)
            .body(Body::empty())
            .unwrap();
        send(&app, r).await;
    }
    let (_, _, body) = send(&app, get("/metrics")).await;
    let text = String::from_utf8(body).unwrap();
    assert!(
        !text.contains("M1X") && !text.contains("/no/such/"),
        "{text}"
    );
    let series = text
        .lines()
        .filter(|l| l.starts_with("terrasynth_requests_total{"))
        .count();
    // Two routes (/healthz, unmatched) × one method label (`other`) × their statuses.
    assert!(series <= 4, "{series} series:\n{text}");
    assert!(text.contains("method=\"other\""), "{text}");
}

// --- 2. slow and idle connections, connection cap (real binary) ---

/// `terrasynth serve` without worlds, its open-file limit lowered to 256 (so that a few hundred
/// idle sockets would exhaust it), with `env`.
fn start_limited(dir: &Path, env: &[(&str, &str)]) -> Server {
    let cfg = dir.join("config.toml");
    std::fs::write(&cfg, "worlds = []\n").unwrap();
    let port = proc::free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut cmd = std::process::Command::new("sh");
    cmd.arg("-c")
        .arg("ulimit -n 256 && exec \"$0\" serve --config \"$1\" --listen \"$2\"")
        .arg(env!("CARGO_BIN_EXE_terrasynth"))
        .arg(&cfg)
        .arg(&addr)
        .env("TERRASYNTH_STORE_DIR", dir.join("store"))
        .env("TERRASYNTH_CACHE_MB", "64")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
    for (k, v) in env {
        cmd.env(k, v);
    }
    let server = Server {
        child: cmd.spawn().unwrap(),
        base: format!("http://{addr}"),
        addr,
    };
    let deadline = Instant::now() + Duration::from_secs(120);
    while !ureq::get(&format!("{}/healthz", server.base))
        .call()
        .is_ok_and(|r| r.status() == 200)
    {
        assert!(Instant::now() < deadline, "server did not become healthy");
        std::thread::sleep(Duration::from_millis(100));
    }
    server
}

/// Whether the server closes `s` (EOF or reset) before `patience` passes, reading and
/// discarding whatever it sends, and sending `trickle` one byte every 200 ms meanwhile.
fn closed_by_server(s: &mut TcpStream, trickle: &[u8], patience: Duration) -> bool {
    s.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let deadline = Instant::now() + patience;
    let mut buf = [0u8; 4096];
    let mut next = trickle.iter();
    while Instant::now() < deadline {
        if let Some(b) = next.next() {
            if s.write_all(&[*b]).is_err() {
                return true;
            }
        }
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return true,
        }
    }
    false
}

#[test]
fn slow_and_idle_connections_are_closed_and_the_cap_keeps_health_checks_reachable() {
    let dir = tempfile::tempdir().unwrap();
    let server = start_limited(
        dir.path(),
        &[
            ("TERRASYNTH_HEADER_READ_TIMEOUT_S", "1"),
            ("TERRASYNTH_IDLE_TIMEOUT_S", "2"),
            ("TERRASYNTH_MAX_CONNECTIONS", "100"),
        ],
    );
    let patience = Duration::from_secs(30);
    // Slowloris: a request head trickled a byte every 200 ms never completes; the server closes.
    let mut slow = TcpStream::connect(&server.addr).unwrap();
    let head = b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-a: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
    assert!(
        closed_by_server(&mut slow, head, patience),
        "a trickled request head is never cut"
    );
    // A connection that says nothing is closed.
    let mut mute = TcpStream::connect(&server.addr).unwrap();
    assert!(
        closed_by_server(&mut mute, b"", patience),
        "a mute connection stays open"
    );
    // A kept-alive connection idle after its request is closed.
    let mut idle = TcpStream::connect(&server.addr).unwrap();
    idle.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    assert!(
        closed_by_server(&mut idle, b"", patience),
        "an idle kept-alive connection stays open"
    );
    // More idle sockets than file descriptors: health checks still get through (the idlest
    // connections are closed to make room, and nothing fails to accept).
    let hoard: Vec<TcpStream> = (0..400)
        .filter_map(|_| TcpStream::connect(&server.addr).ok())
        .collect();
    assert!(hoard.len() >= 300, "{} sockets", hoard.len());
    for _ in 0..5 {
        let (st, _) = proc::get(&server, "/healthz", None);
        assert_eq!(st, 200);
    }
    let (_, m) = proc::get(&server, "/metrics", None);
    let m = String::from_utf8(m).unwrap();
    let value = |name: &str| -> f64 {
        m.lines()
            .find_map(|l| l.strip_prefix(name).and_then(|v| v.trim().parse().ok()))
            .unwrap_or_else(|| panic!("no {name}"))
    };
    assert!(value("terrasynth_connections_evicted_total ") >= 1.0, "{m}");
    assert!(
        value("terrasynth_connections_timed_out_total ") >= 2.0,
        "{m}"
    );
    assert!(value("terrasynth_connections_open ") <= 100.0, "{m}");
    drop(hoard);
}

// --- 3. log flooding ---

#[tokio::test]
async fn overload_is_counted_not_logged_as_an_error() {
    let logs = Captured::default();
    let _guard = logs.install();
    let config = ServerConfig {
        synth_queue: 0,
        ..ServerConfig::default()
    };
    let app = public_router(tile_world(), &config);
    for _ in 0..20 {
        let (st, h, body) = send(&app, get("/tiles/mini/elevation/10/717/385.png")).await;
        assert_problem(st, &h, &body, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(h[header::RETRY_AFTER], "1");
    }
    assert_eq!(
        metric(&app, "terrasynth_overload_total{reason=\"synth_queue\"}").await,
        20.0
    );
    let text = logs.text();
    assert!(!text.contains("ERROR"), "{text}");
    // The capture works: the 503s are there at DEBUG.
    assert!(text.contains("DEBUG"), "{text}");
}

// --- 4. abandoned work, a world's share ---

#[tokio::test]
async fn abandoned_synthesis_stops_and_requests_still_waiting_get_their_tile() {
    let world = tile_world();
    let app = public_router(world.clone(), &ServerConfig::default());
    // A cold zoom-11 tile: three amplified levels of many level tiles each.
    let uri = "/tiles/mini/elevation/11/1433/771.png";
    let lone = tokio::spawn({
        let app = app.clone();
        async move { send(&app, get(uri)).await }
    });
    eventually("synthesis starts", || world.stats().cache_misses > 0).await;
    lone.abort();
    let _ = lone.await;
    let mut cancelled = 0.0;
    let deadline = Instant::now() + Duration::from_secs(120);
    while cancelled < 1.0 {
        assert!(
            Instant::now() < deadline,
            "the abandoned synthesis never stopped"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
        cancelled = metric(
            &app,
            "terrasynth_synthesis_cancelled_total{world=\"mini\"} ",
        )
        .await;
    }
    // It stopped: once the threads that noticed have unwound, no level tile is computed any more.
    tokio::time::sleep(Duration::from_millis(200)).await;
    let misses = world.stats().cache_misses;
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(world.stats().cache_misses, misses);
    // Two clients want another cold tile; one leaves: the other still gets it, computed whole.
    let uri2 = "/tiles/mini/elevation/11/1434/772.png";
    let before = world.stats().cache_misses;
    let leaver = tokio::spawn({
        let app = app.clone();
        async move { send(&app, get(uri2)).await }
    });
    let stayer = tokio::spawn({
        let app = app.clone();
        async move { send(&app, get(uri2)).await }
    });
    eventually("synthesis starts", || world.stats().cache_misses > before).await;
    leaver.abort();
    let (st, h, body) = stayer.await.unwrap();
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
    // And nothing is poisoned: the first tile is served now, equal to the one a fresh world
    // computes.
    let (st, _, first) = send(&app, get(uri)).await;
    assert_eq!(st, StatusCode::OK);
    let fresh = public_router(tile_world(), &ServerConfig::default());
    assert_eq!(send(&fresh, get(uri)).await.2, first);
    assert_eq!(send(&fresh, get(uri2)).await.2, body);
}

#[test]
fn a_world_whose_share_cannot_hold_its_whole_world_layers_is_flagged() {
    let heights = || synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0);
    let roomy = mini_world(
        heights(),
        small_dictionary_with_vegetation(2),
        "d",
        11,
        256 << 20,
    );
    assert_eq!(share_shortfall(&roomy), None);
    let cramped = mini_world(
        heights(),
        small_dictionary_with_vegetation(2),
        "d",
        11,
        1 << 20,
    );
    let why = share_shortfall(&cramped).expect("a 1 MiB share is too small");
    assert!(why.contains("raise cache_mb"), "{why}");
}

// --- 5. upload memory ---

#[tokio::test]
async fn uploads_are_bounded_by_decoded_size_by_number_and_spooled_as_they_arrive() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let app = admin_router(&store, |c| {
        c.upload_memory_mb = 5;
        c.max_concurrent_uploads = 1;
        c.max_body_mb = 1;
    });
    let before = terrasynth_test_support::store_files(&store);
    // 600×600 f32: a 1.4 MB body is over max_body_mb; 500×500 (1 MB body) decodes to ≈ 2.25 MB
    // of samples, f32 and mask on top of the body and the decoder: more than 5 MiB in all.
    let tiff = geotiff_bytes(500, 500, 4);
    assert!(tiff.len() < 1 << 20);
    let (st, h, body) = send(
        &app,
        admin(
            Method::POST,
            "/admin/exemplars?name=big",
            Some("image/tiff"),
            Body::from(tiff),
        ),
    )
    .await;
    assert_problem(st, &h, &body, StatusCode::PAYLOAD_TOO_LARGE);
    assert!(String::from_utf8_lossy(&body).contains("memory"));
    // A small one fits.
    let (st, v) = send_json(
        &app,
        admin(
            Method::POST,
            "/admin/exemplars?name=small",
            Some("image/tiff"),
            Body::from(geotiff_bytes(64, 64, 4)),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    let small_id = v["id"].as_str().unwrap().to_string();
    // One upload in progress (its body still arriving) takes the only slot: the next is 503.
    let (tx, body) = streamed_body();
    let first = tokio::spawn({
        let app = app.clone();
        async move {
            send(
                &app,
                admin(
                    Method::POST,
                    "/admin/exemplars?name=slow",
                    Some("image/tiff"),
                    body,
                ),
            )
            .await
        }
    });
    let chunk = Bytes::from(vec![0x49u8; 64 << 10]);
    tx.send(chunk.clone()).await.unwrap();
    // The body is spooled to the store's uploads/ as it arrives, not held in memory.
    let uploads = store.join("uploads");
    let spooled = || -> u64 {
        std::fs::read_dir(&uploads)
            .map(|d| {
                d.filter_map(|e| e.ok()?.metadata().ok())
                    .map(|m| m.len())
                    .sum()
            })
            .unwrap_or(0)
    };
    eventually("the first chunk is spooled", || spooled() >= 64 << 10).await;
    let (st, h, body) = send(
        &app,
        admin(
            Method::POST,
            "/admin/exemplars?name=second",
            Some("image/tiff"),
            Body::from(geotiff_bytes(64, 64, 5)),
        ),
    )
    .await;
    assert_problem(st, &h, &body, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(h[header::RETRY_AFTER], "1");
    // A body that goes on and on (no Content-Length) is cut at max_body_mb as it arrives.
    let mut sent = 64 << 10;
    let cut = loop {
        if tx.send(chunk.clone()).await.is_err() {
            break true;
        }
        sent += chunk.len();
        if sent > 64 << 20 {
            break false;
        }
    };
    assert!(cut, "a 64 MiB body was read on past the 1 MiB limit");
    let (st, h, body) = first.await.unwrap();
    assert_problem(st, &h, &body, StatusCode::PAYLOAD_TOO_LARGE);
    // Nothing but the small exemplar was stored, and no spool file is left.
    eventually("the spool file is removed", || spooled() == 0).await;
    let after = terrasynth_test_support::store_files(&store);
    let added: Vec<&String> = after.keys().filter(|k| !before.contains_key(*k)).collect();
    assert!(
        added
            .iter()
            .all(|k| k.contains(&small_id) || k.ends_with("exemplar.small")),
        "{added:?}"
    );
}

// --- 6. TileJSON base URL ---

#[tokio::test]
async fn tilejson_urls_use_public_url_or_the_listening_address_and_vary_on_host() {
    let world = tile_world();
    let listening = ServerConfig {
        listen: "0.0.0.0:9123".into(),
        ..ServerConfig::default()
    };
    let app = public_router(world.clone(), &listening);
    let no_host = Request::builder()
        .uri("/tiles/mini/elevation.json")
        .body(Body::empty())
        .unwrap();
    let (st, h, body) = send(&app, no_host).await;
    assert_eq!(st, StatusCode::OK);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let url = v["tiles"][0].as_str().unwrap();
    assert!(
        url.starts_with("http://127.0.0.1:9123/tiles/mini/"),
        "{url}"
    );
    let with_host = Request::builder()
        .uri("/tiles/mini/elevation.json")
        .header(header::HOST, "maps.example:8443")
        .header("x-forwarded-proto", "https")
        .body(Body::empty())
        .unwrap();
    let (_, h2, body) = send(&app, with_host).await;
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(v["tiles"][0]
        .as_str()
        .unwrap()
        .starts_with("https://maps.example:8443/tiles/mini/"));
    for h in [&h, &h2] {
        let vary = h[header::VARY].to_str().unwrap().to_ascii_lowercase();
        assert!(vary.contains("host"), "{vary}");
    }
    let public = ServerConfig {
        public_url: "https://tiles.example.com/terrain".into(),
        ..ServerConfig::default()
    };
    let app = public_router(world, &public);
    for uri in [
        "/tiles/mini/elevation.json",
        "/styles/mini.json",
        "/worlds",
        "/worlds/mini",
    ] {
        let r = Request::builder()
            .uri(uri)
            .header(header::HOST, "evil.example")
            .body(Body::empty())
            .unwrap();
        let (st, h, body) = send(&app, r).await;
        assert_eq!(st, StatusCode::OK, "{uri}");
        let text = String::from_utf8(body).unwrap();
        assert!(
            text.contains("https://tiles.example.com/terrain/tiles/mini/"),
            "{uri}: {text}"
        );
        assert!(!text.contains("evil.example"), "{uri}: {text}");
        assert!(
            h.get(header::VARY).is_none_or(|v| !v
                .to_str()
                .unwrap()
                .to_ascii_lowercase()
                .contains("host")),
            "{uri}"
        );
    }
}

// --- 7. one error shape ---

#[tokio::test]
async fn every_error_status_is_problem_json() {
    let app = public_router(tile_world(), &ServerConfig::default());
    // 405, with its Allow header kept.
    let r = Request::builder()
        .method(Method::DELETE)
        .uri("/healthz")
        .header(header::ORIGIN, "https://map.example")
        .body(Body::empty())
        .unwrap();
    let (st, h, body) = send(&app, r).await;
    assert_problem(st, &h, &body, StatusCode::METHOD_NOT_ALLOWED);
    assert!(h.contains_key(header::ALLOW));
    // 414, with CORS.
    let long = format!("/tiles/mini/elevation/8/179/96.png?{}", "a".repeat(9000));
    let (st, h, body) = send(&app, get(&long)).await;
    assert_problem(st, &h, &body, StatusCode::URI_TOO_LONG);
    assert_eq!(h[header::ACCESS_CONTROL_ALLOW_ORIGIN], "*");
    // An invalid UTF-8 path segment.
    let (st, h, body) = send(&app, get("/worlds/%FF%FE")).await;
    assert!(st.is_client_error(), "{st}");
    assert_problem(st, &h, &body, st);
    // The request deadline (here an upload whose body stalls past upload_timeout_s).
    let dir = tempfile::tempdir().unwrap();
    let admin_app = admin_router(dir.path(), |c| c.upload_timeout_s = 1);
    let (tx, body) = streamed_body();
    tx.send(Bytes::from_static(b"II*\0")).await.unwrap();
    let (st, h, body) = send(
        &admin_app,
        admin(
            Method::POST,
            "/admin/exemplars?name=stalled",
            Some("image/tiff"),
            body,
        ),
    )
    .await;
    drop(tx);
    assert_problem(st, &h, &body, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(h[header::RETRY_AFTER], "1");
}

// --- 8. strict parsing ---

#[tokio::test]
async fn tile_urls_have_one_spelling_and_the_urls_clients_are_given_parse() {
    let app = public_router(tile_world(), &ServerConfig::default());
    let ok = "/tiles/mini/elevation/8/179/96.png";
    assert_eq!(send(&app, get(ok)).await.0, StatusCode::OK);
    for uri in [
        "/tiles/mini/elevation/+8/179/96.png",
        "/tiles/mini/elevation/08/179/96.png",
        "/tiles/mini/elevation/8/0179/096.png",
        "/tiles/mini/elevation/%38/179/96.png",
        "/tiles/mini/elevation/8/17%39/96.png",
        "/tiles/mini/elevation/8/179/96.png?encoding=mapbox&encoding=terrarium",
        "/tiles/mini/elevation/8/179/96.exr?encoding=mapbox",
        "/tiles/mini/vegetation/8/179/96.exr?style=overlay",
        "/tiles/mini/color/8/179/96.png?set=0",
    ] {
        let (st, h, body) = send(&app, get(uri)).await;
        assert_problem(st, &h, &body, StatusCode::BAD_REQUEST);
    }
    // Every tile URL template the styles and TileJSON documents hand to clients (MapLibre, the
    // web page) still parses.
    let (_, _, style) = send(&app, get("/styles/mini.json")).await;
    let style: serde_json::Value = serde_json::from_slice(&style).unwrap();
    // (template, the source's shallowest zoom): instance tiles start at zoom 14.
    let mut templates: Vec<(String, u64)> = Vec::new();
    for (_, source) in style["sources"].as_object().unwrap() {
        let minzoom = source["minzoom"].as_u64().unwrap_or(0);
        if let Some(tiles) = source["tiles"].as_array() {
            templates.extend(
                tiles
                    .iter()
                    .map(|t| (t.as_str().unwrap().to_string(), minzoom)),
            );
        }
        if let Some(url) = source["url"].as_str() {
            let path = url.split_once("/tiles/").map(|(_, p)| p).unwrap();
            let (_, _, tj) = send(&app, get(&format!("/tiles/{path}"))).await;
            let tj: serde_json::Value = serde_json::from_slice(&tj).unwrap();
            let minzoom = tj["minzoom"].as_u64().unwrap_or(minzoom);
            templates.extend(
                tj["tiles"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|t| (t.as_str().unwrap().to_string(), minzoom)),
            );
        }
    }
    assert!(!templates.is_empty());
    for (t, minzoom) in &templates {
        let path = t.split_once("/tiles/").map(|(_, p)| p).unwrap();
        // Tile 179/96 of zoom 8, or its first descendant at the source's shallowest zoom.
        let z = (*minzoom).max(8);
        let uri = format!("/tiles/{path}")
            .replace("{z}", &z.to_string())
            .replace("{x}", &(179u64 << (z - 8)).to_string())
            .replace("{y}", &(96u64 << (z - 8)).to_string());
        let (st, _, body) = send(&app, get(&uri)).await;
        assert_eq!(
            st,
            StatusCode::OK,
            "{uri}: {}",
            String::from_utf8_lossy(&body)
        );
    }
}

#[tokio::test]
async fn unknown_build_weights_are_refused_before_the_job_is_queued() {
    let dir = tempfile::tempdir().unwrap();
    let app = admin_router(dir.path(), |_| {});
    let (st, v) = send_json(
        &app,
        admin(
            Method::POST,
            "/admin/exemplars?name=crop",
            Some("image/tiff"),
            Body::from(geotiff_bytes(96, 96, 7)),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    let ex = v["id"].as_str().unwrap();
    let build = |weights: serde_json::Value| {
        admin(
            Method::POST,
            "/admin/dictionaries",
            Some("application/json"),
            Body::from(
                serde_json::json!({"name": "w", "exemplars": [ex], "atoms": 16, "patch": 16,
                    "stride": 8, "learning": "medoids:2", "seed": 3, "weights": weights})
                .to_string(),
            ),
        )
    };
    let (st, h, body) = send(&app, build(serde_json::json!({"nosuch": 1.0}))).await;
    assert_problem(st, &h, &body, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(String::from_utf8_lossy(&body).contains("nosuch"));
    let (_, jobs) = send_json(&app, admin(Method::GET, "/admin/jobs", None, Body::empty())).await;
    assert_eq!(jobs.as_array().map(Vec::len), Some(0), "{jobs}");
    // Known terms and layers the dictionary carries are accepted.
    let (st, v) = send_json(
        &app,
        build(
            serde_json::json!({"elevation": 0.7, "slope": 0.1, "northness": 0.1, "log_area": 0.1}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{v}");
}

// --- 9. store hygiene ---

#[tokio::test]
async fn start_up_repairs_the_store_and_never_describes_a_corrupted_exemplar() {
    let dir = tempfile::tempdir().unwrap();
    let store_dir = dir.path().join("store");
    let (good, bad) = {
        let app = admin_router(&store_dir, |_| {});
        let mut ids = Vec::new();
        for (name, seed) in [("good", 1), ("bad", 2)] {
            let (st, v) = send_json(
                &app,
                admin(
                    Method::POST,
                    &format!("/admin/exemplars?name={name}"),
                    Some("image/tiff"),
                    Body::from(geotiff_bytes(64, 64, seed)),
                ),
            )
            .await;
            assert_eq!(st, StatusCode::CREATED, "{v}");
            ids.push(v["id"].as_str().unwrap().to_string());
        }
        (ids[0].clone(), ids[1].clone())
    };
    // While stopped: one exemplar's pixels rot, a job record is garbage, a world definition has
    // no alias (its process died before writing it).
    let obj = store_dir.join("exemplars").join(format!("{bad}.obj"));
    let mut bytes = std::fs::read(&obj).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 0x55;
    std::fs::write(&obj, bytes).unwrap();
    std::fs::write(
        store_dir.join("jobs").join("job-garbage.json"),
        b"{not json",
    )
    .unwrap();
    let orphan = Store::open(&store_dir)
        .unwrap()
        .put_object(terrasynth_store::ObjectKind::World, b"{\"orphan\":true}")
        .unwrap();
    let app = admin_router(&store_dir, |_| {});
    // The corrupted exemplar is never described, and its alias goes with it.
    let (st, list) = send_json(
        &app,
        admin(Method::GET, "/admin/exemplars", None, Body::empty()),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let ids: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, vec![good.as_str()]);
    let (st, _) = send_json(
        &app,
        admin(
            Method::GET,
            &format!("/admin/exemplars/{bad}"),
            None,
            Body::empty(),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::NOT_FOUND);
    assert!(!store_dir.join("aliases").join("exemplar.bad").exists());
    assert!(store_dir.join("aliases").join("exemplar.good").exists());
    // The bad job record and the corrupted object are in corrupt/; the orphan is gone.
    let corrupt: Vec<String> = std::fs::read_dir(store_dir.join("corrupt"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        corrupt.iter().any(|f| f.contains("job-garbage")),
        "{corrupt:?}"
    );
    assert!(corrupt.iter().any(|f| f.contains(&bad)), "{corrupt:?}");
    assert!(!store_dir
        .join("worlds")
        .join(format!("{orphan}.obj"))
        .exists());
    assert!(!store_dir.join("jobs").join("job-garbage.json").exists());
    // A non-empty directory that is not a store is refused, untouched.
    let foreign = tempfile::tempdir().unwrap();
    std::fs::write(foreign.path().join("thesis.tex"), b"mine").unwrap();
    assert!(matches!(
        Store::open(foreign.path()),
        Err(StoreError::NotAStore(_))
    ));
    assert!(!foreign.path().join("VERSION").exists());
}

// --- 10. failed authentication ---

fn from(addr: [u8; 4], token: &str) -> Request<Body> {
    let mut r = Request::builder()
        .uri("/admin/exemplars")
        .header(header::AUTHORIZATION, format!("Bearer {token}"))
        .body(Body::empty())
        .unwrap();
    r.extensions_mut()
        .insert(ConnectInfo(SocketAddr::from((addr, 40000))));
    r
}

#[tokio::test]
async fn failed_authentication_is_logged_and_rate_limited_per_address() {
    let logs = Captured::default();
    let _guard = logs.install();
    let dir = tempfile::tempdir().unwrap();
    let app = admin_router(dir.path(), |c| c.auth_failures_per_minute = 3);
    let guesser = [198, 51, 100, 7];
    for _ in 0..3 {
        let (st, h, body) = send(&app, from(guesser, "guess")).await;
        assert_problem(st, &h, &body, StatusCode::UNAUTHORIZED);
    }
    for token in ["guess", TOKEN] {
        let (st, h, body) = send(&app, from(guesser, token)).await;
        assert_problem(st, &h, &body, StatusCode::TOO_MANY_REQUESTS);
        let secs: u64 = h[header::RETRY_AFTER].to_str().unwrap().parse().unwrap();
        assert!((1..=60).contains(&secs), "{secs}");
    }
    // Another address is not affected.
    assert_eq!(
        send(&app, from([192, 0, 2, 1], TOKEN)).await.0,
        StatusCode::OK
    );
    assert_eq!(metric(&app, "terrasynth_auth_failures_total ").await, 3.0);
    assert_eq!(metric(&app, "terrasynth_auth_throttled_total ").await, 2.0);
    let text = logs.text();
    assert!(
        text.contains("admin authentication failed") && text.contains("198.51.100.7"),
        "{text}"
    );
    // Logged once per address and window, not once per attempt.
    assert!(text.matches("198.51.100.7").count() <= 2, "{text}");
}
