//! The admin API and the dictionary catalogue through `oneshot` on the real router with a store
//! in a temporary directory: authentication (admin disabled, no token, wrong token, token on a
//! public route), uploads in every format (GeoTIFF, PNG with a georeference, EXR, multipart with
//! layers), every rejection (415, 400, 413, 422) with nothing written to the store, a fuzz-style
//! test of random and mutated files, and the whole build → world → tiles flow with its 409s,
//! cancellation and the full queue.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::http::{header, Method, Request, StatusCode};

use terrasynth::config::{parse_world, Config, Secret, ServerConfig};
use terrasynth::server::startup::state_with;
use terrasynth::server::{app, Worlds};
use terrasynth_core::math;
use terrasynth_core::raster::{Georef, Grid};
use terrasynth_store::Store;

use crate::support::{decode_rgba, send, send_json};
use terrasynth_tiles::World;

use terrasynth_test_support::{
    exr_bytes, geotiff_bytes, png16_bytes, small_dictionary, store_files, synthetic_terrain,
    tile_of,
};

const TOKEN: &str = "test-token-0123";

/// A small configured world `mini` (read-only for the admin API).
fn mini_world() -> World {
    terrasynth_test_support::mini_world(
        synthetic_terrain(240, 240, 3),
        small_dictionary(2),
        "mini-dictionary",
        10,
        16 << 20,
    )
}

fn config(store: &Path, token: &str, edit: impl FnOnce(&mut ServerConfig)) -> Config {
    let mut server = ServerConfig {
        store_dir: store.to_path_buf(),
        admin_token: Secret(token.into()),
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
    Config {
        server,
        worlds: vec![mini],
    }
}

fn router_with(store: &Path, token: &str, edit: impl FnOnce(&mut ServerConfig)) -> axum::Router {
    let mut worlds = Worlds::new();
    worlds.insert("mini".into(), Arc::new(mini_world()));
    let config = config(store, token, edit);
    let store = Store::open(&config.server.store_dir).unwrap();
    app(state_with(&config, store, worlds).unwrap())
}

fn router(store: &Path) -> axum::Router {
    router_with(store, TOKEN, |_| {})
}

fn req(method: Method, uri: &str, content_type: Option<&str>, body: Vec<u8>) -> Request<Body> {
    let mut b = Request::builder()
        .method(method)
        .uri(uri)
        .header(header::AUTHORIZATION, format!("Bearer {TOKEN}"));
    if let Some(ct) = content_type {
        b = b.header(header::CONTENT_TYPE, ct);
    }
    b.body(Body::from(body)).unwrap()
}

fn get(uri: &str) -> Request<Body> {
    req(Method::GET, uri, None, Vec::new())
}

fn json(method: Method, uri: &str, v: serde_json::Value) -> Request<Body> {
    req(
        method,
        uri,
        Some("application/json"),
        v.to_string().into_bytes(),
    )
}

fn problem_detail(st: StatusCode, h: &axum::http::HeaderMap, body: &[u8]) -> String {
    assert_eq!(h[header::CONTENT_TYPE], "application/problem+json", "{st}");
    let v: serde_json::Value = serde_json::from_slice(body).unwrap();
    assert_eq!(v["status"], st.as_u16());
    v["detail"].as_str().unwrap().to_string()
}

async fn upload_tiff(
    app: &axum::Router,
    name: &str,
    rows: usize,
    cols: usize,
    seed: u64,
) -> String {
    let (st, v) = send_json(
        app,
        req(
            Method::POST,
            &format!("/admin/exemplars?name={name}"),
            Some("image/tiff"),
            geotiff_bytes(rows, cols, seed),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    v["id"].as_str().unwrap().to_string()
}

async fn wait_job(app: &axum::Router, id: &str) -> serde_json::Value {
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        let (st, v) = send_json(app, get(&format!("/admin/jobs/{id}"))).await;
        assert_eq!(st, StatusCode::OK);
        let state = v["state"].as_str().unwrap().to_string();
        if state != "queued" && state != "running" {
            return v;
        }
        assert!(Instant::now() < deadline, "job {id} never ended");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

// --- authentication ---

#[tokio::test]
async fn admin_is_absent_without_a_token() {
    let dir = tempfile::tempdir().unwrap();
    let app = router_with(dir.path(), "", |_| {});
    for uri in ["/admin/exemplars", "/admin/jobs", "/admin/jobs/x"] {
        let (st, h, body) = send(&app, get(uri)).await;
        assert_eq!(st, StatusCode::NOT_FOUND, "{uri}");
        problem_detail(st, &h, &body);
    }
    // The public catalogue still answers.
    let (st, v) = send_json(&app, get("/dictionaries")).await;
    assert_eq!(st, StatusCode::OK);
    assert!(v.as_array().unwrap().is_empty());
}

#[tokio::test]
async fn missing_or_wrong_tokens_are_401_and_public_routes_ignore_tokens() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let anonymous = Request::builder()
        .uri("/admin/exemplars")
        .body(Body::empty())
        .unwrap();
    let (st, h, body) = send(&app, anonymous).await;
    assert_eq!(st, StatusCode::UNAUTHORIZED);
    assert!(h[header::WWW_AUTHENTICATE]
        .to_str()
        .unwrap()
        .starts_with("Bearer"));
    assert!(problem_detail(st, &h, &body).contains("Authorization"));
    for value in [
        "Bearer wrong-token",
        "Bearer test-token-012",
        "Bearer test-token-01234",
        "Basic dGVzdA==",
        TOKEN,
    ] {
        let r = Request::builder()
            .uri("/admin/exemplars")
            .header(header::AUTHORIZATION, value)
            .body(Body::empty())
            .unwrap();
        let (st, h, body) = send(&app, r).await;
        assert_eq!(st, StatusCode::UNAUTHORIZED, "{value}");
        problem_detail(st, &h, &body);
    }
    // A wrong token cannot upload either, and nothing is written.
    let before = store_files(dir.path());
    let r = Request::builder()
        .method(Method::POST)
        .uri("/admin/exemplars?name=x")
        .header(header::AUTHORIZATION, "Bearer nope")
        .header(header::CONTENT_TYPE, "image/tiff")
        .body(Body::from(geotiff_bytes(32, 32, 1)))
        .unwrap();
    assert_eq!(send(&app, r).await.0, StatusCode::UNAUTHORIZED);
    assert_eq!(store_files(dir.path()), before);
    // The right token works; a token on a public route changes nothing.
    assert_eq!(send(&app, get("/admin/exemplars")).await.0, StatusCode::OK);
    let (st, v) = send_json(&app, get("/worlds")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(v[0]["name"], "mini");
    assert_eq!(send(&app, get("/healthz")).await.0, StatusCode::OK);
    assert_eq!(
        send(&app, get("/tiles/mini/elevation/8/178/95.png"))
            .await
            .0,
        StatusCode::OK
    );
}

// --- uploads ---

#[tokio::test]
async fn uploads_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let (st, h, body) = send(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=crop",
            Some("image/tiff"),
            geotiff_bytes(48, 64, 1),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v["name"], "crop");
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(64), Some(48))
    );
    assert_eq!(v["layers"], serde_json::json!(["elevation"]));
    assert_eq!(v["crs"], "EPSG:4326");
    assert_eq!(v["statistics"]["valid_cells"], 48 * 64);
    let id = v["id"].as_str().unwrap();
    assert_eq!(id.len(), 64);
    assert_eq!(
        h[header::LOCATION],
        format!("/admin/exemplars/{id}").as_str()
    );
    // Same bytes, same name: same id.
    let (_, again) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=crop",
            Some("image/tiff"),
            geotiff_bytes(48, 64, 1),
        ),
    )
    .await;
    assert_eq!(again["id"], v["id"]);

    // PNG with its georeference in the query (EPSG:3857 metres).
    let (st, p) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=png&cell_size=30&west=8000000&north=5000000&crs=EPSG:3857",
            Some("image/png"),
            png16_bytes(40, 40, 2),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{p}");
    assert_eq!(p["crs"], "EPSG:3857");
    assert_eq!(p["cell_size"], serde_json::json!([30.0, 30.0]));

    // EXR: every channel a layer, elevation first.
    let (st, e) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=exr&cell_size=0.004166666666666667&west=74&north=42.5",
            Some("image/x-exr"),
            exr_bytes(32, 32, 3),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{e}");
    assert_eq!(e["layers"], serde_json::json!(["elevation", "forest"]));

    // Multipart: an elevation part and a named layer on the same grid.
    let (st, m) = send_json(
        &app,
        multipart(
            "mp",
            &[
                ("elevation", geotiff_bytes(32, 32, 4)),
                ("snow", geotiff_bytes(32, 32, 5)),
            ],
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{m}");
    assert_eq!(m["layers"], serde_json::json!(["elevation", "snow"]));

    let (st, list) = send_json(&app, get("/admin/exemplars")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(list.as_array().unwrap().len(), 4);
    let (st, one) = send_json(&app, get(&format!("/admin/exemplars/{id}"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(one["name"], "crop");
    assert_eq!(
        send(&app, get("/admin/exemplars/ffff")).await.0,
        StatusCode::NOT_FOUND
    );
    let del = req(
        Method::DELETE,
        &format!("/admin/exemplars/{id}"),
        None,
        Vec::new(),
    );
    assert_eq!(send(&app, del).await.0, StatusCode::NO_CONTENT);
    assert_eq!(
        send(&app, get(&format!("/admin/exemplars/{id}"))).await.0,
        StatusCode::NOT_FOUND
    );
}

fn multipart(name: &str, parts: &[(&str, Vec<u8>)]) -> Request<Body> {
    let boundary = "terrasynth-test-boundary";
    let mut body = Vec::new();
    for (part, bytes) in parts {
        body.extend_from_slice(
            format!(
                "--{boundary}\r\nContent-Disposition: form-data; name=\"{part}\"; filename=\"{part}.tif\"\r\nContent-Type: image/tiff\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    req(
        Method::POST,
        &format!("/admin/exemplars?name={name}"),
        Some(&format!("multipart/form-data; boundary={boundary}")),
        body,
    )
}

// --- rejections: each answers problem+json naming the problem, and writes nothing ---

#[tokio::test]
async fn every_rejection_names_the_problem_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let app = router_with(dir.path(), TOKEN, |c| {
        c.max_body_mb = 1;
        c.max_pixels = 100_000;
        c.max_dimension = 1000;
    });
    let before = store_files(dir.path());
    let tiff = geotiff_bytes(40, 40, 1);
    let nan_tiff = {
        let g = Grid::new(
            ndarray::Array2::from_elem((16, 16), f32::NAN),
            terrasynth_test_support::georef_15s(),
        );
        let mut out = std::io::Cursor::new(Vec::new());
        terrasynth_core::raster::write_geotiff(&g, &mut out).unwrap();
        out.into_inner()
    };
    let post = |uri: &str, ct: Option<&str>, body: Vec<u8>| req(Method::POST, uri, ct, body);
    let cases: Vec<(&str, Request<Body>, StatusCode, &str)> = vec![
        (
            "wrong content type",
            post("/admin/exemplars?name=a", Some("text/plain"), tiff.clone()),
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "Content-Type",
        ),
        (
            "no content type",
            post("/admin/exemplars?name=a", None, tiff.clone()),
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "Content-Type",
        ),
        (
            "undecodable",
            post(
                "/admin/exemplars?name=a",
                Some("application/octet-stream"),
                b"GIF89a not a raster".to_vec(),
            ),
            StatusCode::BAD_REQUEST,
            "undecodable",
        ),
        (
            "declared tiff, sent png",
            post(
                "/admin/exemplars?name=a",
                Some("image/tiff"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::BAD_REQUEST,
            "Content-Type",
        ),
        (
            "truncated",
            post(
                "/admin/exemplars?name=a",
                Some("image/tiff"),
                tiff[..tiff.len() / 2].to_vec(),
            ),
            StatusCode::BAD_REQUEST,
            "undecodable",
        ),
        (
            "NaN only",
            post("/admin/exemplars?name=a", Some("image/tiff"), nan_tiff),
            StatusCode::UNPROCESSABLE_ENTITY,
            "no valid",
        ),
        (
            "PNG without georeference",
            post(
                "/admin/exemplars?name=a",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "georeference",
        ),
        (
            "absurd georeference",
            post(
                "/admin/exemplars?name=a&cell_size=1&west=170&north=95",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "georeference",
        ),
        (
            "negative cell size",
            post(
                "/admin/exemplars?name=a&cell_size=-1&west=0&north=0",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "cell_size",
        ),
        (
            "partial georeference",
            post(
                "/admin/exemplars?name=a&cell_size=1",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "west",
        ),
        (
            "not a number",
            post(
                "/admin/exemplars?name=a&cell_size=abc&west=0&north=0",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::BAD_REQUEST,
            "cell_size",
        ),
        (
            "unknown crs",
            post(
                "/admin/exemplars?name=a&cell_size=1&west=0&north=0&crs=EPSG:32633",
                Some("image/png"),
                png16_bytes(8, 8, 1),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "crs",
        ),
        (
            "missing name",
            post("/admin/exemplars", Some("image/tiff"), tiff.clone()),
            StatusCode::BAD_REQUEST,
            "name",
        ),
        (
            "bad name",
            post(
                "/admin/exemplars?name=../x",
                Some("image/tiff"),
                tiff.clone(),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "name",
        ),
        (
            "body over the limit",
            post(
                "/admin/exemplars?name=a",
                Some("image/tiff"),
                vec![0u8; (1 << 20) + 1],
            ),
            StatusCode::PAYLOAD_TOO_LARGE,
            "limit",
        ),
        (
            "too many pixels",
            post(
                "/admin/exemplars?name=a",
                Some("image/tiff"),
                geotiff_bytes(400, 400, 1),
            ),
            StatusCode::PAYLOAD_TOO_LARGE,
            "too large",
        ),
        (
            "too wide",
            post(
                "/admin/exemplars?name=a",
                Some("image/tiff"),
                geotiff_bytes(2, 1200, 1),
            ),
            StatusCode::PAYLOAD_TOO_LARGE,
            "side",
        ),
        (
            "multipart without elevation",
            multipart("a", &[("forest", tiff.clone())]),
            StatusCode::UNPROCESSABLE_ENTITY,
            "elevation",
        ),
        (
            "mismatched layer grids",
            multipart(
                "a",
                &[
                    ("elevation", tiff.clone()),
                    ("forest", geotiff_bytes(30, 40, 2)),
                ],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "layer",
        ),
        (
            "bad layer name",
            multipart(
                "a",
                &[
                    ("elevation", tiff.clone()),
                    ("no way", geotiff_bytes(40, 40, 2)),
                ],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "layer name",
        ),
        (
            "duplicate layer",
            multipart(
                "a",
                &[
                    ("elevation", tiff.clone()),
                    ("f", tiff.clone()),
                    ("f", tiff.clone()),
                ],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "twice",
        ),
        (
            "dictionary: not JSON",
            req(
                Method::POST,
                "/admin/dictionaries",
                Some("text/plain"),
                b"{}".to_vec(),
            ),
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "application/json",
        ),
        (
            "dictionary: malformed JSON",
            req(
                Method::POST,
                "/admin/dictionaries",
                Some("application/json"),
                b"{".to_vec(),
            ),
            StatusCode::BAD_REQUEST,
            "JSON",
        ),
        (
            "dictionary: missing fields",
            json(
                Method::POST,
                "/admin/dictionaries",
                serde_json::json!({"name": "d"}),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "exemplars",
        ),
        (
            "dictionary: unknown exemplar",
            json(
                Method::POST,
                "/admin/dictionaries",
                serde_json::json!({"name": "d", "exemplars": ["abc"]}),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "unknown exemplar",
        ),
        (
            "world: unknown base",
            json(
                Method::POST,
                "/admin/worlds",
                serde_json::json!({"name": "w", "base": "abc", "dictionaries": ["x"]}),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "base",
        ),
        (
            "world: configured name",
            json(
                Method::POST,
                "/admin/worlds",
                serde_json::json!({"name": "mini", "base": "abc", "dictionaries": ["x"]}),
            ),
            StatusCode::CONFLICT,
            "exists",
        ),
    ];
    for (what, r, want, needle) in cases {
        let (st, h, body) = send(&app, r).await;
        assert_eq!(st, want, "{what}: {}", String::from_utf8_lossy(&body));
        let detail = problem_detail(st, &h, &body);
        assert!(
            detail.to_lowercase().contains(&needle.to_lowercase()),
            "{what}: `{detail}` should mention `{needle}`"
        );
        assert_eq!(store_files(dir.path()), before, "{what} wrote to the store");
    }
}

/// A xorshift generator for the fuzz test (deterministic).
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[tokio::test]
async fn fuzzed_uploads_never_fail_the_server_nor_touch_the_store() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let seeds: Vec<(&str, Vec<u8>)> = vec![
        ("image/tiff", geotiff_bytes(24, 24, 1)),
        ("image/png", png16_bytes(24, 24, 2)),
        ("image/x-exr", exr_bytes(16, 16, 3)),
    ];
    let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
    let mut created = 0usize;
    for i in 0..240 {
        let (ct, seed) = &seeds[i % seeds.len()];
        let mut bytes = seed.clone();
        match i % 4 {
            // Random bytes, sometimes behind the right magic.
            0 => {
                let n = rng.below(2048);
                bytes = (0..n).map(|_| rng.next() as u8).collect();
                if rng.below(2) == 0 {
                    bytes.splice(0..0, seed[..8].iter().copied());
                }
            }
            // Flip a few bytes.
            1 => {
                for _ in 0..1 + rng.below(8) {
                    let at = rng.below(bytes.len());
                    bytes[at] ^= 1 << rng.below(8);
                }
            }
            // Truncate.
            2 => bytes.truncate(rng.below(bytes.len())),
            // Overwrite a header field with extreme values.
            _ => {
                let at = rng.below(bytes.len().min(256).saturating_sub(4));
                let v = [0xff, 0xff, 0xff, 0x7f];
                bytes[at..at + 4].copy_from_slice(&v);
            }
        }
        let before = store_files(dir.path()).len();
        let uri = "/admin/exemplars?name=fuzz&cell_size=0.01&west=74&north=42";
        let (st, _, body) = send(&app, req(Method::POST, uri, Some(ct), bytes)).await;
        assert!(
            !st.is_server_error(),
            "case {i}: {st} {}",
            String::from_utf8_lossy(&body)
        );
        let after = store_files(dir.path()).len();
        if st == StatusCode::CREATED {
            // A mutation that still decodes is a valid upload: one object and its alias.
            created += 1;
            assert!(after <= before + 2, "case {i}");
        } else {
            assert!(
                [400u16, 413, 415, 422].contains(&st.as_u16()),
                "case {i}: unexpected {st}"
            );
            assert_eq!(
                after, before,
                "case {i}: a rejected upload changed the store"
            );
        }
    }
    // Most mutations must be rejected (a sanity check that the fuzzing bites).
    assert!(created < 120, "{created} mutated files accepted");
}

// --- builds, worlds, conflicts ---

#[tokio::test]
async fn build_a_dictionary_create_a_world_and_serve_its_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let ex = upload_tiff(&app, "crop", 96, 96, 7).await;
    let (st, h, body) = send(
        &app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": "small", "exemplars": [ex], "atoms": 16, "patch": 16,
                "stride": 8, "learning": "medoids:2", "seed": 3,
                "weights": {"elevation": 0.8, "altitude": 0.1, "slope": 0.1}}),
        ),
    )
    .await;
    assert_eq!(
        st,
        StatusCode::ACCEPTED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let job = v["id"].as_str().unwrap().to_string();
    assert_eq!(h[header::LOCATION], format!("/admin/jobs/{job}").as_str());
    let done = wait_job(&app, &job).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["progress"], 1.0);
    assert!(done["started"].is_string() && done["finished"].is_string());
    let dict = done["result"].as_str().unwrap().to_string();
    let (st, jobs) = send_json(&app, get("/admin/jobs")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(jobs[0]["id"], job.as_str());
    // Public catalogue, no token needed.
    let anon = |uri: &str| Request::builder().uri(uri).body(Body::empty()).unwrap();
    let (st, d) = send_json(&app, anon(&format!("/dictionaries/{dict}"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(d["name"], "small");
    assert_eq!(d["atoms"], 16);
    // The atoms carry the derived layers and the vegetation of the default world's species
    // (the niche model on the exemplar), so worlds on this dictionary synthesize vegetation
    // from its atoms.
    assert_eq!(
        d["layers"],
        serde_json::json!([
            "log_area",
            "northness",
            "spruce",
            "juniper",
            "meadow",
            "steppe"
        ])
    );
    assert_eq!(
        send(&app, anon("/dictionaries/nope")).await.0,
        StatusCode::NOT_FOUND
    );

    // A world from a coarse base (the crop at 1′).
    let base = {
        let g = Grid::new(
            synthetic_terrain(24, 24, 7),
            Georef {
                pixel_width: 1.0 / 60.0,
                pixel_height: 1.0 / 60.0,
                ..terrasynth_test_support::georef_15s()
            },
        );
        let mut out = std::io::Cursor::new(Vec::new());
        terrasynth_core::raster::write_geotiff(&g, &mut out).unwrap();
        out.into_inner()
    };
    let (st, b) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=base",
            Some("image/tiff"),
            base,
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED);
    let base_id = b["id"].as_str().unwrap().to_string();
    let (st, w) = send_json(
        &app,
        json(Method::POST, "/admin/worlds", serde_json::json!({"name": "mine", "base": base_id, "dictionaries": [dict], "max_zoom": 9})),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{w}");
    assert_eq!(w["world"]["max_zoom"], 9);
    assert_eq!(w["world"]["weights"]["elevation"], 0.8);
    let z = w["native_zoom"].as_u64().unwrap() as u8;
    assert!(z < 9);
    let (st, info) = send_json(&app, get("/worlds/mine")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(info["dictionaries"], serde_json::json!([dict]));
    // Tiles at the native zoom and one amplified zoom, over the base's centre.
    let (lon, lat) = (74.2, 42.3);
    for zz in [z, z + 1] {
        let (x, y) = tile_of(lon, lat, zz);
        let (st, _, png) = send(
            &app,
            get(&format!("/tiles/mine/elevation/{zz}/{x}/{y}.png")),
        )
        .await;
        assert_eq!(st, StatusCode::OK, "z{zz}");
        let hts = terrasynth_tiles::decode_terrarium_png(&png).unwrap();
        assert!(hts.iter().any(|v| *v > 300.0), "z{zz} has terrain");
        let (st, _, _) = send(
            &app,
            get(&format!("/tiles/mine/hillshade/{zz}/{x}/{y}.png")),
        )
        .await;
        assert_eq!(st, StatusCode::OK);
    }
    // Conflicts.
    let (st, _) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/worlds",
            serde_json::json!({"name": "mine", "base": base_id, "dictionaries": [dict]}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CONFLICT);
    let (st, _) = send_json(&app, json(Method::POST, "/admin/worlds", serde_json::json!({"name": "deep", "base": base_id, "dictionaries": [dict], "max_zoom": 2}))).await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    let (st, _) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/worlds",
            serde_json::json!({"name": "two", "base": base_id, "dictionaries": [dict, dict]}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    let del = |uri: String| req(Method::DELETE, &uri, None, Vec::new());
    assert_eq!(
        send(&app, del(format!("/admin/dictionaries/{dict}")))
            .await
            .0,
        StatusCode::CONFLICT
    );
    assert_eq!(
        send(&app, del(format!("/admin/exemplars/{base_id}")))
            .await
            .0,
        StatusCode::CONFLICT
    );
    assert_eq!(
        send(&app, del("/admin/worlds/mini".into())).await.0,
        StatusCode::CONFLICT
    );
    assert_eq!(
        send(&app, del("/admin/worlds/nope".into())).await.0,
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        send(&app, del(format!("/admin/jobs/{job}"))).await.0,
        StatusCode::CONFLICT
    );
    assert_eq!(
        send(&app, del("/admin/jobs/nope".into())).await.0,
        StatusCode::NOT_FOUND
    );
    // Its whole-world layers, prepared in the background, are stored under its name...
    let layers = dir.path().join("landscape/mine.layers");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while !layers.exists() {
        assert!(std::time::Instant::now() < deadline, "layers never stored");
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    // Deleting the world frees the dictionary and the base (and drops its stored layers).
    assert_eq!(
        send(&app, del("/admin/worlds/mine".into())).await.0,
        StatusCode::NO_CONTENT
    );
    assert!(!layers.exists());
    assert_eq!(
        send(&app, get("/tiles/mine/elevation/8/0/0.png")).await.0,
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        send(&app, del(format!("/admin/dictionaries/{dict}")))
            .await
            .0,
        StatusCode::NO_CONTENT
    );
    assert_eq!(
        send(&app, anon(&format!("/dictionaries/{dict}"))).await.0,
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        send(&app, del(format!("/admin/exemplars/{base_id}")))
            .await
            .0,
        StatusCode::NO_CONTENT
    );
}

#[tokio::test]
async fn cancelled_and_queued_builds_leave_nothing_and_a_full_queue_is_503() {
    let dir = tempfile::tempdir().unwrap();
    let app = router_with(dir.path(), TOKEN, |c| c.build_queue = 1);
    let ex = upload_tiff(&app, "big", 256, 256, 9).await;
    let heavy = serde_json::json!({"name": "heavy", "exemplars": [ex], "atoms": 1024, "patch": 16,
        "stride": 2, "learning": "medoids:50"});
    let dicts_before = store_files(dir.path())
        .keys()
        .filter(|k| k.starts_with("dictionaries/"))
        .count();
    let mut accepted = Vec::new();
    let mut refused = 0;
    for _ in 0..3 {
        let (st, h, body) = send(
            &app,
            json(Method::POST, "/admin/dictionaries", heavy.clone()),
        )
        .await;
        if st == StatusCode::SERVICE_UNAVAILABLE {
            refused += 1;
            assert_eq!(h[header::RETRY_AFTER], "1");
            problem_detail(st, &h, &body);
        } else {
            assert_eq!(st, StatusCode::ACCEPTED);
            let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
            accepted.push(v["id"].as_str().unwrap().to_string());
        }
    }
    assert!(
        refused >= 1,
        "a queue of 1 with one worker holds at most 2 heavy jobs"
    );
    // While a build uses the exemplar, it cannot be deleted.
    let del = req(
        Method::DELETE,
        &format!("/admin/exemplars/{ex}"),
        None,
        Vec::new(),
    );
    assert_eq!(send(&app, del).await.0, StatusCode::CONFLICT);
    for id in &accepted {
        let (st, v) = send_json(
            &app,
            req(
                Method::DELETE,
                &format!("/admin/jobs/{id}"),
                None,
                Vec::new(),
            ),
        )
        .await;
        assert_eq!(st, StatusCode::ACCEPTED, "{v}");
    }
    for id in &accepted {
        let v = wait_job(&app, id).await;
        assert_eq!(v["state"], "cancelled", "{v}");
        assert!(v["result"].is_null());
    }
    let dicts_after = store_files(dir.path())
        .keys()
        .filter(|k| k.starts_with("dictionaries/"))
        .count();
    assert_eq!(
        dicts_after, dicts_before,
        "a cancelled build left a dictionary"
    );
    assert!(std::fs::read_dir(dir.path().join("dictionaries"))
        .unwrap()
        .flatten()
        .all(|e| !e.file_name().to_string_lossy().starts_with(".tmp")));
}

/// A GeoTIFF upload whose body arrives in two halves `stall` apart.
fn slow_upload(stall: Duration) -> Request<Body> {
    let bytes = geotiff_bytes(32, 32, 1);
    let (head, tail) = bytes.split_at(bytes.len() / 2);
    let parts = vec![head.to_vec(), tail.to_vec()];
    let stream = futures_util::stream::unfold((0usize, parts), move |(i, parts)| async move {
        if i == 1 {
            tokio::time::sleep(stall).await;
        }
        let part = parts.get(i)?.clone();
        Some((Ok::<_, std::io::Error>(part), (i + 1, parts)))
    });
    Request::builder()
        .method(Method::POST)
        .uri("/admin/exemplars?name=slow")
        .header(header::AUTHORIZATION, format!("Bearer {TOKEN}"))
        .header(header::CONTENT_TYPE, "image/tiff")
        .body(Body::from_stream(stream))
        .unwrap()
}

#[tokio::test]
async fn uploads_have_their_own_timeout() {
    // `request_timeout_s` = 1 bounds tile and metadata requests; an upload whose body takes 2 s
    // to arrive is accepted under the default `upload_timeout_s` (an hour) ...
    let store = tempfile::tempdir().unwrap();
    let app = router_with(store.path(), TOKEN, |s| s.request_timeout_s = 1);
    let (st, v) = send_json(&app, slow_upload(Duration::from_secs(2))).await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    // ... and answered 503, storing nothing, when `upload_timeout_s` is 1 s too.
    let store = tempfile::tempdir().unwrap();
    let app = router_with(store.path(), TOKEN, |s| {
        s.request_timeout_s = 1;
        s.upload_timeout_s = 1;
    });
    let before = store_files(store.path());
    let (st, _) = send_json(&app, slow_upload(Duration::from_secs(2))).await;
    assert_eq!(st, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(store_files(store.path()), before);
}

/// Issue #11's bugs, fixed: a dictionary built through the API carries the species layers of the
/// request (or of the default world), and a world created through the API uses its own materials
/// and species for splat, colour and vegetation.
#[tokio::test]
async fn api_dictionaries_and_worlds_use_their_own_species_and_materials() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let exemplar = upload_tiff(&app, "hills", 96, 96, 5).await;
    // A dictionary for one species of its own, without niche limits.
    let (st, v) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": "mossy", "exemplars": [exemplar], "atoms": 16,
                "patch": 16, "stride": 8, "species": [{"name": "moss", "colour": [0, 200, 0]}]}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{v}");
    let done = wait_job(&app, v["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let dict = done["result"].as_str().unwrap().to_string();
    let (_, d) = send_json(&app, get(&format!("/dictionaries/{dict}"))).await;
    assert_eq!(
        d["layers"],
        serde_json::json!(["log_area", "northness", "moss"])
    );
    // Bad species are refused at submission, naming the problem; nothing is queued or stored.
    let before = store_files(dir.path());
    let (st, v) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": "bad", "exemplars": [exemplar],
                "species": [{"name": "a b"}]}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(v["detail"].as_str().unwrap().contains("species"), "{v}");
    assert_eq!(store_files(dir.path()), before);

    // Two worlds on the same base and dictionary: the default landscape, and one material
    // (lava, no ranges: weight 1 everywhere) with two species of its own.
    let base = upload_tiff(&app, "base", 64, 64, 6).await;
    for (name, extra) in [
        ("plain", serde_json::json!({})),
        (
            "lava",
            serde_json::json!({"materials": [{"name": "lava", "colour": [200, 0, 0]}],
                "species": [{"name": "moss", "colour": [0, 200, 0]},
                    {"name": "lichen", "colour": [90, 90, 0]}]}),
        ),
    ] {
        let mut body = serde_json::json!({"name": name, "base": base, "dictionaries": [dict],
            "max_zoom": 12});
        for (k, v) in extra.as_object().unwrap() {
            body[k] = v.clone();
        }
        let (st, w) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
        assert_eq!(st, StatusCode::CREATED, "{w}");
    }
    let (_, w) = send_json(&app, get("/worlds/lava")).await;
    let z = w["native_zoom"].as_u64().unwrap() as u8 + 1;
    let (lon, lat) = (74.0 + 32.0 / 240.0, 42.5 - 32.0 / 240.0);
    let (x, y) = tile_of(lon, lat, z);
    let tile = |world: &str, layer: &str, ext: &str| {
        let app = app.clone();
        let uri = format!("/tiles/{world}/{layer}/{z}/{x}/{y}.{ext}");
        async move {
            let (st, _, body) = send(&app, get(&uri)).await;
            assert_eq!(st, StatusCode::OK, "{uri}");
            body
        }
    };
    // Splat: every pixel of the lava world is wholly lava (channel R = 255, the others 0), or
    // nothing outside the base's coverage.
    let (_, _, splat) = decode_rgba(&tile("lava", "splat", "png").await);
    assert!(splat
        .chunks(4)
        .all(|p| p == [255, 0, 0, 0] || p == [0, 0, 0, 0]));
    assert!(splat.chunks(4).any(|p| p == [255, 0, 0, 0]));
    let (_, _, plain_splat) = decode_rgba(&tile("plain", "splat", "png").await);
    assert!(plain_splat.chunks(4).any(|p| p != [255, 0, 0, 0]));
    // Colour: lava's colour (200, 0, 0) shaded; green and blue stay 0. The default materials
    // (snow, rock, meadow...) give other colours. Transparent outside the base's coverage.
    let (_, _, colour) = decode_rgba(&tile("lava", "color", "png").await);
    assert!(colour
        .chunks(4)
        .all(|p| p[1] == 0 && p[2] == 0 && (p[3] == 255 || p == [0, 0, 0, 0])));
    assert!(colour.chunks(4).any(|p| p[0] > 100));
    let (_, _, plain_colour) = decode_rgba(&tile("plain", "color", "png").await);
    assert!(plain_colour.chunks(4).any(|p| p[1] > 0));
    // Vegetation: a channel per species of the world, named after it (the decoder sorts them).
    let channels =
        terrasynth_tiles::decode_float_exr(&tile("lava", "vegetation", "exr").await).unwrap();
    let names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["lichen", "moss"]);
    let plain =
        terrasynth_tiles::decode_float_exr(&tile("plain", "vegetation", "exr").await).unwrap();
    assert_eq!(plain.len(), 4);
    // The definition is echoed and kept.
    let (st, v) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/worlds",
            serde_json::json!({"name": "bad", "base": base, "dictionaries": [dict],
                "materials": [{"name": "x", "colour": [1, 2, 3], "slope": {"min": 9, "max": 1}}]}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(v["detail"].as_str().unwrap().contains("slope"), "{v}");
    // Bad scattering rules (#17) are refused by name: a negative radius, an unknown species,
    // a zero spacing.
    let rule = serde_json::json!({"kind": "trees", "method": "collision", "species": ["spruce"],
        "spacing_m": 10, "min_distance_m": 2, "height_m": {"min": 2, "max": 9},
        "radius_m": {"min": 1, "max": 3}});
    for (key, value, named) in [
        (
            "radius_m",
            serde_json::json!({"min": -1, "max": 3}),
            "radius_m",
        ),
        (
            "species",
            serde_json::json!(["oak"]),
            "unknown species `oak`",
        ),
        ("spacing_m", serde_json::json!(0), "spacing_m"),
    ] {
        let mut r = rule.clone();
        r[key] = value;
        let (st, v) = send_json(
            &app,
            json(
                Method::POST,
                "/admin/worlds",
                serde_json::json!({"name": "bad", "base": base, "dictionaries": [dict],
                    "scatter": [r]}),
            ),
        )
        .await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
        let detail = v["detail"].as_str().unwrap();
        assert!(
            detail.contains(named) && detail.contains("scatter `trees`"),
            "{v}"
        );
    }
}

/// A GeoTIFF (15″ cells, north-west corner 74° E 42.5° N) of a 500 m plain with one 2,500 m
/// mountain centred at `(row, col)`.
fn one_mountain_tiff(rows: usize, cols: usize, row: f64, col: f64) -> Vec<u8> {
    let data = ndarray::Array2::from_shape_fn((rows, cols), |(r, c)| {
        let d2 = (r as f64 - row).powi(2) + (c as f64 - col).powi(2);
        (500.0 + 2000.0 * math::exp(-d2 / 18.0)) as f32
    });
    let grid = terrasynth_core::raster::Grid::new(data, terrasynth_test_support::georef_15s());
    let mut out = std::io::Cursor::new(Vec::new());
    terrasynth_core::raster::write_geotiff(&grid, &mut out).unwrap();
    out.into_inner()
}

#[tokio::test]
async fn api_worlds_carry_title_attribution_fill_and_open_over_their_mountains() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let exemplar = upload_tiff(&app, "hills", 96, 96, 5).await;
    let (st, v) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": "d", "exemplars": [exemplar], "atoms": 16, "patch": 16,
                "stride": 8}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{v}");
    let done = wait_job(&app, v["id"].as_str().unwrap()).await;
    let dict = done["result"].as_str().unwrap().to_string();
    // The mountain stands in the north-east quarter, far from the base's middle (32, 32).
    let (st, v) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=peak",
            Some("image/tiff"),
            one_mountain_tiff(64, 64, 12.0, 50.0),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    let base = v["id"].as_str().unwrap().to_string();
    let body = serde_json::json!({"name": "peak", "base": base, "dictionaries": [dict],
        "max_zoom": 11, "title": "One Peak", "attribution": "Survey of Nowhere, 2026",
        "fill_m": -50.0});
    let (st, w) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
    assert_eq!(st, StatusCode::CREATED, "{w}");
    let (_, w) = send_json(&app, get("/worlds/peak")).await;
    assert_eq!(w["title"], "One Peak");
    assert_eq!(w["attribution"], "Survey of Nowhere, 2026");
    assert_eq!(w["fill_m"], -50.0);
    // The mountain's top is at 74° + 50.5/240, 42.5° − 12.5/240; the middle of the base at
    // 74° + 32/240, 42.5° − 32/240. The map opens within 6 cells of the top.
    let c: Vec<f64> = serde_json::from_value(w["center"].clone()).unwrap();
    let (peak_lon, peak_lat) = (74.0 + 50.5 / 240.0, 42.5 - 12.5 / 240.0);
    assert!(
        (c[0] - peak_lon).abs() < 6.0 / 240.0 && (c[1] - peak_lat).abs() < 6.0 / 240.0,
        "centre {c:?}, peak ({peak_lon}, {peak_lat})"
    );
    let (_, all) = send_json(&app, get("/worlds")).await;
    let listed = all
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["name"] == "peak")
        .unwrap();
    assert_eq!(listed["title"], "One Peak");
    for layer in ["elevation", "color"] {
        let (_, tj) = send_json(&app, get(&format!("/tiles/peak/{layer}.json"))).await;
        assert_eq!(tj["attribution"], "Survey of Nowhere, 2026", "{tj}");
        assert_eq!(tj["name"], format!("One Peak {layer}"));
        assert_eq!(tj["center"][0], c[0]);
    }
    let (_, style) = send_json(&app, get("/styles/peak.json")).await;
    assert_eq!(style["name"], "One Peak");
    assert_eq!(style["center"], serde_json::json!([c[0], c[1]]));
    // The fill is served outside the base: a zoom-6 overview tile is mostly outside it.
    let (x, y) = tile_of(74.0, 42.5, 6);
    let (st, _, exr) = send(&app, get(&format!("/tiles/peak/elevation/6/{x}/{y}.exr"))).await;
    assert_eq!(st, StatusCode::OK);
    let ch = terrasynth_tiles::decode_float_exr(&exr).unwrap();
    assert!(ch[0].1.iter().any(|&v| v == -50.0), "no fill pixel");
    // A centre given is the centre served; bad values are refused by name.
    let body = serde_json::json!({"name": "peak2", "base": base, "dictionaries": [dict],
        "center": [74.05, 42.45]});
    let (st, w) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
    assert_eq!(st, StatusCode::CREATED, "{w}");
    let (_, w) = send_json(&app, get("/worlds/peak2")).await;
    assert_eq!(w["center"][0], 74.05);
    assert_eq!(w["center"][1], 42.45);
    assert_eq!(w["title"], "peak2");
    let before = store_files(dir.path());
    for (field, value, named) in [
        ("center", serde_json::json!([200.0, 0.0]), "center"),
        ("fill_m", serde_json::json!(1e9), "fill_m"),
        ("sea_level_m", serde_json::json!(-2e4), "sea_level_m"),
        ("title", serde_json::json!("  "), "title"),
        (
            "water",
            serde_json::json!({"lakes": true, "lake_min_area_m2": -1.0}),
            "water.lake_min_area_m2",
        ),
        (
            "water",
            serde_json::json!({"lakes": true, "lake_min_depth_m": 0.0}),
            "water.lake_min_depth_m",
        ),
        ("water", serde_json::json!({"deep_m": -5.0}), "water.deep_m"),
        (
            "water",
            serde_json::json!({"surface_lake_min_area_m2": 0.0}),
            "water.surface_lake_min_area_m2",
        ),
        (
            "water",
            serde_json::json!({"surface_lake_bed_slope": 2.0}),
            "water.surface_lake_bed_slope",
        ),
        ("water", serde_json::json!({"lake": true}), "lake"),
        (
            "water",
            serde_json::json!({"shallow_colour": [300, 0, 0]}),
            "300",
        ),
    ] {
        let mut body = serde_json::json!({"name": "bad", "base": base, "dictionaries": [dict]});
        body[field] = value;
        let (st, v) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{field}: {v}");
        assert!(v["detail"].as_str().unwrap().contains(named), "{v}");
    }
    // Nothing of the refused worlds is stored.
    assert_eq!(store_files(dir.path()), before);
    assert_eq!(
        send_json(&app, get("/worlds/bad")).await.0,
        StatusCode::NOT_FOUND
    );
    // Valid lake settings are taken.
    let body = serde_json::json!({"name": "lakes", "base": base, "dictionaries": [dict],
        "water": {"lakes": true, "lake_min_area_m2": 5e5, "lake_min_depth_m": 2.0}});
    let (st, w) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
    assert_eq!(st, StatusCode::CREATED, "{w}");
    // A world named like an admin route could never be deleted (DELETE /admin/worlds/sketch
    // is not the world's route): refused by name, nothing stored.
    let before = store_files(dir.path());
    let body = serde_json::json!({"name": "sketch", "base": base, "dictionaries": [dict]});
    let (st, v) = send_json(&app, json(Method::POST, "/admin/worlds", body)).await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(v["detail"].as_str().unwrap().contains("reserved"), "{v}");
    assert_eq!(store_files(dir.path()), before);
}

// --- sketch worlds and features (issue #18) ---

/// GeoTIFF bytes of the Talas and Kyrgyz ranges: 256 × 256 cells of the committed Tien Shan grid
/// (columns 1600–1855, rows 600–855).
fn tienshan_crop_tiff() -> Vec<u8> {
    let g = terrasynth_core::raster::embedded::tienshan().unwrap();
    let crop = Grid::new(
        g.data.slice(ndarray::s![600..856, 1600..1856]).to_owned(),
        g.georef.window(1600, 600),
    );
    let mut out = std::io::Cursor::new(Vec::new());
    terrasynth_core::raster::write_geotiff(&crop, &mut out).unwrap();
    out.into_inner()
}

/// A sketch request for a 96 × 96 world at 15″ (bounds 70,42,70.4,42.4).
fn sketch_request(
    name: &str,
    ex: &str,
    dict: &str,
    sketch: serde_json::Value,
) -> serde_json::Value {
    serde_json::json!({"name": name, "sketch": sketch, "bounds": [70.0, 42.0, 70.4, 42.4],
        "cell_size": 1.0 / 240.0, "exemplars": [ex], "dictionaries": [dict], "seed": 5})
}

fn line(kind: &str, pts: &[[f64; 2]]) -> serde_json::Value {
    serde_json::json!({"type": "Feature", "properties": {"kind": kind},
        "geometry": {"type": "LineString", "coordinates": pts}})
}

fn good_sketch() -> serde_json::Value {
    serde_json::json!({"type": "FeatureCollection", "features": [
        line("ridge", &[[70.04, 42.2], [70.2, 42.22], [70.36, 42.19]]),
        line("valley", &[[70.04, 42.07], [70.2, 42.09], [70.36, 42.06]]),
        line("valley", &[[70.05, 42.34], [70.15, 42.3]]),
    ]})
}

#[tokio::test]
async fn a_sketch_becomes_a_served_world_and_bad_sketches_store_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let (st, v) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=talas",
            Some("image/tiff"),
            tienshan_crop_tiff(),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    let ex = v["id"].as_str().unwrap().to_string();
    let (st, v) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": "talas", "exemplars": [ex], "atoms": 16, "patch": 16,
                "stride": 16, "learning": "medoids:1"}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{v}");
    let built = wait_job(&app, v["id"].as_str().unwrap()).await;
    assert_eq!(built["state"], "succeeded", "{built}");
    let dict = built["result"].as_str().unwrap().to_string();

    // Refused with 422 (409 for a taken name) and nothing written.
    let before = store_files(dir.path());
    let many: Vec<[f64; 2]> = (0..10_001)
        .map(|i| [70.05 + 0.3 * f64::from(i) / 10_001.0, 42.2])
        .collect();
    let crossing = line(
        "ridge",
        &[[70.1, 42.1], [70.3, 42.3], [70.3, 42.1], [70.1, 42.3]],
    );
    let mut over_limits = sketch_request("big", &ex, &dict, good_sketch());
    over_limits["bounds"] = serde_json::json!([70.0, 42.0, 90.0, 62.0]);
    let cases: Vec<(serde_json::Value, StatusCode, &str)> = vec![
        (
            sketch_request(
                "a",
                &ex,
                &dict,
                serde_json::json!({"type": "FeatureCollection", "features": []}),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "no ridge",
        ),
        (
            sketch_request(
                "a",
                &ex,
                &dict,
                line("ridge", &[[70.1, 42.1], [71.0, 42.2]]),
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "outside",
        ),
        (
            sketch_request("a", &ex, &dict, line("ridge", &many)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "vertices",
        ),
        (
            sketch_request("a", &ex, &dict, crossing),
            StatusCode::UNPROCESSABLE_ENTITY,
            "itself",
        ),
        (over_limits, StatusCode::UNPROCESSABLE_ENTITY, "exceed"),
        (
            sketch_request("a", &"0".repeat(64), &dict, good_sketch()),
            StatusCode::UNPROCESSABLE_ENTITY,
            "unknown exemplar",
        ),
        (
            sketch_request("a", &ex, &"0".repeat(64), good_sketch()),
            StatusCode::UNPROCESSABLE_ENTITY,
            "unknown dictionary",
        ),
        (
            sketch_request("no/slash", &ex, &dict, good_sketch()),
            StatusCode::UNPROCESSABLE_ENTITY,
            "world name",
        ),
        (
            sketch_request("mini", &ex, &dict, good_sketch()),
            StatusCode::CONFLICT,
            "already exists",
        ),
    ];
    for (body, want, needle) in cases {
        let (st, h, b) = send(&app, json(Method::POST, "/admin/worlds/sketch", body)).await;
        assert_eq!(st, want, "{needle}: {}", String::from_utf8_lossy(&b));
        let detail = problem_detail(st, &h, &b);
        assert!(detail.contains(needle), "{needle}: {detail}");
    }
    assert_eq!(store_files(dir.path()), before);
    let (_, jobs) = send_json(&app, get("/admin/jobs")).await;
    assert_eq!(jobs.as_array().unwrap().len(), 1, "only the build: {jobs}");

    // A good sketch: 202 with the job, which ends with the world served.
    let (st, h, b) = send(
        &app,
        json(
            Method::POST,
            "/admin/worlds/sketch",
            sketch_request("drawn", &ex, &dict, good_sketch()),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&b));
    let job: serde_json::Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(job["kind"], "sketch");
    let id = job["id"].as_str().unwrap();
    assert_eq!(h[header::LOCATION], format!("/admin/jobs/{id}").as_str());
    let done = wait_job(&app, id).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"], "drawn");
    assert_eq!(done["progress"], 1.0);
    assert_eq!(
        done["request"]["bounds"],
        serde_json::json!([70.0, 42.0, 70.4, 42.4])
    );

    let (st, w) = send_json(&app, get("/worlds/drawn")).await;
    assert_eq!(st, StatusCode::OK, "{w}");
    let b = w["bounds"].as_array().unwrap();
    assert!(
        (b[0].as_f64().unwrap() - 70.0).abs() < 1e-6
            && (b[3].as_f64().unwrap() - 42.4).abs() < 1e-6,
        "{w}"
    );
    // Its base is stored as an exemplar, and a tile at the native zoom holds the exemplar's
    // kind of heights (the crop spans about 700–4800 m).
    let (_, exemplars) = send_json(&app, get("/admin/exemplars")).await;
    assert!(
        exemplars
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["name"] == "sketch-drawn"),
        "{exemplars}"
    );
    let z = w["native_zoom"].as_u64().unwrap() as u8;
    let (x, y) = tile_of(70.2, 42.2, z);
    let (st, _, png) = send(
        &app,
        get(&format!("/tiles/drawn/elevation/{z}/{x}/{y}.png")),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let h = terrasynth_tiles::encode::decode_terrarium_png(&png).unwrap();
    // The pixels inside the world (70.05–70.35°E, 42.05–42.35°N): fractional tile coordinates.
    let n = f64::from(1u32 << z);
    let px = |lon: f64| ((((lon + 180.0) / 360.0 * n - f64::from(x)) * 256.0) as usize).min(256);
    let py = |lat: f64| {
        let t = (1.0
            - math::log(math::tan(lat.to_radians()) + 1.0 / math::cos(lat.to_radians()))
                / std::f64::consts::PI)
            / 2.0;
        (((t * n - f64::from(y)) * 256.0) as usize).min(256)
    };
    let inside = h.slice(ndarray::s![py(42.35)..py(42.05), px(70.05)..px(70.35)]);
    assert!(inside.len() > 50, "{}", inside.len());
    let (lo, hi) = inside
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(lo > 300.0 && hi < 5500.0 && hi - lo > 100.0, "{lo}..{hi}");
    // Its ridges and valleys are served too.
    let (st, f) = send_json(&app, get("/worlds/drawn/features.geojson?kind=valley")).await;
    assert_eq!(st, StatusCode::OK);
    let fs = f["features"].as_array().unwrap();
    assert!(!fs.is_empty() && fs.iter().all(|f| f["properties"]["kind"] == "valley"));
    // The name is now taken.
    let (st, _, _) = send(
        &app,
        json(
            Method::POST,
            "/admin/worlds/sketch",
            sketch_request("drawn", &ex, &dict, good_sketch()),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CONFLICT);
}

#[tokio::test]
async fn features_of_a_world_as_geojson() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let (st, h, b) = send(&app, get("/worlds/mini/features.geojson")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "application/geo+json");
    let all: serde_json::Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(all["type"], "FeatureCollection");
    let features = all["features"].as_array().unwrap();
    let count = |k: &str| {
        features
            .iter()
            .filter(|f| f["properties"]["kind"] == k)
            .count()
    };
    assert!(count("ridge") > 0 && count("valley") > 0);
    assert_eq!(count("ridge") + count("valley"), features.len());
    for f in features {
        assert_eq!(f["geometry"]["type"], "LineString");
        assert!(f["properties"]["mean_elevation_m"].is_number());
    }
    let (_, ridges) = send_json(&app, get("/worlds/mini/features.geojson?kind=ridge")).await;
    assert_eq!(ridges["features"].as_array().unwrap().len(), count("ridge"));
    // A strong ETag; If-None-Match → 304.
    let tag = h[header::ETAG].to_str().unwrap().to_string();
    let mut r = get("/worlds/mini/features.geojson");
    r.headers_mut()
        .insert(header::IF_NONE_MATCH, tag.parse().unwrap());
    assert_eq!(send(&app, r).await.0, StatusCode::NOT_MODIFIED);
    // Gzip-coded once (the compression layer in front of the JSON routes leaves it alone) for a
    // client that accepts it, under an ETag of its own.
    let gz_get = |tag: Option<&str>| {
        let mut r = get("/worlds/mini/features.geojson");
        r.headers_mut()
            .insert(header::ACCEPT_ENCODING, "gzip".parse().unwrap());
        if let Some(t) = tag {
            r.headers_mut()
                .insert(header::IF_NONE_MATCH, t.parse().unwrap());
        }
        r
    };
    let (st, gh, gz) = send(&app, gz_get(None)).await;
    assert_eq!(st, StatusCode::OK);
    assert!(
        crate::support::gzip_coded_body(&gh, &gz) == b,
        "gzip-coded features decode to the identity bytes"
    );
    let gz_tag = gh[header::ETAG].to_str().unwrap().to_string();
    assert_eq!(gz_tag, format!("{}-gzip\"", tag.trim_end_matches('"')));
    assert_eq!(
        send(&app, gz_get(Some(&gz_tag))).await.0,
        StatusCode::NOT_MODIFIED
    );
    assert_eq!(send(&app, gz_get(Some(&tag))).await.0, StatusCode::OK);
    assert_eq!(
        send(&app, get("/worlds/mini/features.geojson?kind=hill"))
            .await
            .0,
        StatusCode::BAD_REQUEST
    );
    assert_eq!(
        send(&app, get("/worlds/nope/features.geojson")).await.0,
        StatusCode::NOT_FOUND
    );
}

/// Builds a dictionary from a fresh exemplar of seed `seed` and returns its id.
async fn build_small_dictionary(app: &axum::Router, name: &str, seed: u64) -> String {
    let exemplar = upload_tiff(app, name, 96, 96, seed).await;
    let (st, v) = send_json(
        app,
        json(
            Method::POST,
            "/admin/dictionaries",
            serde_json::json!({"name": name, "exemplars": [exemplar], "atoms": 16, "patch": 16,
                "stride": 8, "learning": "medoids:2", "seed": 3}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::ACCEPTED, "{v}");
    let done = wait_job(app, v["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    done["result"].as_str().unwrap().to_string()
}

#[tokio::test]
async fn api_worlds_take_a_dictionary_per_zoom_band() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let shallow = build_small_dictionary(&app, "shallow", 7).await;
    let deep = build_small_dictionary(&app, "deep", 11).await;
    assert_ne!(shallow, deep);
    let (st, b) = send_json(
        &app,
        req(
            Method::POST,
            "/admin/exemplars?name=base",
            Some("image/tiff"),
            one_mountain_tiff(48, 48, 24.0, 24.0),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{b}");
    let base = b["id"].as_str().unwrap().to_string();
    // One world with the shallow dictionary everywhere, one with the deep dictionary from
    // z_b + 2 on.
    let (st, one) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/worlds",
            serde_json::json!({"name": "one", "base": base, "dictionaries": [shallow], "max_zoom": 12}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{one}");
    let z = one["native_zoom"].as_u64().unwrap() as u8;
    assert!(z + 2 <= 12, "native zoom {z}");
    let bands = serde_json::json!([
        {"id": shallow, "zooms": format!("{}", z + 1)},
        {"id": deep, "zooms": format!("{}-12", z + 2)}
    ]);
    let (st, two) = send_json(
        &app,
        json(
            Method::POST,
            "/admin/worlds",
            serde_json::json!({"name": "two", "base": base, "dictionaries": bands, "max_zoom": 12}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{two}");
    assert_eq!(two["world"]["dictionaries"], bands);
    let (st, info) = send_json(&app, get("/worlds/two")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(info["dictionaries"], serde_json::json!([shallow, deep]));
    assert_eq!(info["dictionary_bands"], bands);
    let (_, info) = send_json(&app, get("/worlds/one")).await;
    assert_eq!(
        info["dictionary_bands"],
        serde_json::json!([{"id": shallow, "zooms": format!("{}-12", z + 1)}])
    );
    // Zooms up to the first band's: the same bytes as the one-dictionary world; deeper: other
    // bytes (and other ETags everywhere: the chain differs).
    let (lon, lat) = (74.1, 42.4);
    for zz in [z, z + 1, z + 2, z + 3] {
        let (x, y) = tile_of(lon, lat, zz);
        let uri = |w: &str| format!("/tiles/{w}/elevation/{zz}/{x}/{y}.png");
        let (st1, h1, a) = send(&app, get(&uri("one"))).await;
        let (st2, h2, b) = send(&app, get(&uri("two"))).await;
        assert_eq!((st1, st2), (StatusCode::OK, StatusCode::OK), "z{zz}");
        assert_ne!(h1[header::ETAG], h2[header::ETAG], "z{zz}");
        if zz <= z + 1 {
            assert_eq!(a, b, "zoom {zz} is amplified by the same dictionary");
        } else {
            assert_ne!(a, b, "zoom {zz} is amplified by the deep band");
        }
    }
    // The deep band's dictionary is in use.
    let del = req(
        Method::DELETE,
        &format!("/admin/dictionaries/{deep}"),
        None,
        Vec::new(),
    );
    assert_eq!(send(&app, del).await.0, StatusCode::CONFLICT);
    // Bad bands: 422 naming the field, nothing stored.
    let before = store_files(dir.path());
    let cases = [
        (
            serde_json::json!([{"id": shallow, "zooms": "9-12"}, {"id": deep, "zooms": "13-x"}]),
            "dictionaries[1].zooms",
        ),
        (
            serde_json::json!([{"id": shallow, "zooms": "12-9"}]),
            "dictionaries[0].zooms",
        ),
        (
            serde_json::json!([{"id": shallow, "zooms": format!("{}-11", z + 1)}, {"id": deep, "zooms": "11-12"}]),
            "overlap",
        ),
        (
            serde_json::json!([{"id": shallow, "zooms": format!("{}-12", z)}]),
            "outside the amplified zooms",
        ),
        (
            serde_json::json!([{"id": shallow, "zooms": "10-13"}]),
            "outside the amplified zooms",
        ),
        (
            serde_json::json!([shallow, {"id": deep, "zooms": "12"}]),
            "every one must give its zooms",
        ),
        (
            serde_json::json!([{"id": "nope", "zooms": "12"}]),
            "dictionaries[0]: unknown dictionary",
        ),
        (
            serde_json::json!([{"id": shallow, "zoom": "12"}]),
            "dictionaries",
        ),
    ];
    for (dictionaries, needle) in cases {
        let body = serde_json::json!({"name": "bad", "base": base, "dictionaries": dictionaries,
            "max_zoom": 12});
        let (st, h, body) = send(&app, json(Method::POST, "/admin/worlds", body)).await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{dictionaries}");
        let detail = problem_detail(st, &h, &body);
        assert!(detail.contains(needle), "{dictionaries}: `{detail}`");
        assert_eq!(
            store_files(dir.path()),
            before,
            "{dictionaries} wrote to the store"
        );
    }
}

/// A GeoTIFF of `f(row, col)` on [`terrasynth_test_support::georef_15s`].
fn tiff_of(rows: usize, cols: usize, f: impl Fn(usize, usize) -> f32) -> Vec<u8> {
    let grid = Grid::new(
        ndarray::Array2::from_shape_fn((rows, cols), |(r, c)| f(r, c)),
        terrasynth_test_support::georef_15s(),
    );
    let mut out = std::io::Cursor::new(Vec::new());
    terrasynth_core::raster::write_geotiff(&grid, &mut out).unwrap();
    out.into_inner()
}

#[tokio::test]
async fn api_worlds_take_painted_biomes_and_bad_biomes_store_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let app = router(dir.path());
    let ridges = build_small_dictionary(&app, "ridges", 7).await;
    let steppe = build_small_dictionary(&app, "steppe", 11).await;
    // The base with its weight layers as named parts (#15): west/east halves, 1 and 0
    // everywhere, a negative and a NaN cell.
    let (n, half) = (64usize, 32usize);
    let elevation = tiff_of(n, n, |r, c| {
        (900.0 + 400.0 * (math::sin(r as f64 * 0.2) * math::cos(c as f64 * 0.17))) as f32
    });
    let parts = [
        ("elevation", elevation),
        ("west", tiff_of(n, n, |_, c| f32::from(u8::from(c < half)))),
        ("east", tiff_of(n, n, |_, c| f32::from(u8::from(c >= half)))),
        ("ones", tiff_of(n, n, |_, _| 1.0)),
        ("zeros", tiff_of(n, n, |_, _| 0.0)),
        (
            "neg",
            tiff_of(n, n, |r, c| if (r, c) == (5, 7) { -2.0 } else { 1.0 }),
        ),
        (
            "nan",
            tiff_of(n, n, |r, c| if (r, c) == (6, 8) { f32::NAN } else { 1.0 }),
        ),
    ];
    let (st, b) = send_json(&app, multipart("painted-base", &parts)).await;
    assert_eq!(st, StatusCode::CREATED, "{b}");
    let base = b["id"].as_str().unwrap().to_string();
    let other = upload_tiff(&app, "other-grid", n + 1, n, 4).await;
    let create = |body: serde_json::Value| json(Method::POST, "/admin/worlds", body);
    let (st, alone) = send_json(
        &app,
        create(serde_json::json!({"name": "alone", "base": base, "dictionaries": [ridges], "max_zoom": 12})),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{alone}");
    let z = alone["native_zoom"].as_u64().unwrap() as u8;
    // Ridges painted everywhere (steppe listed first, weight 0): the tiles of `alone`.
    let everywhere = serde_json::json!([
        {"dictionary": steppe, "weight": "zeros"},
        {"dictionary": ridges, "weight": "ones", "name": "alps"}
    ]);
    let (st, a) = send_json(
        &app,
        create(serde_json::json!({"name": "everywhere", "base": base, "biomes": everywhere, "max_zoom": 12})),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{a}");
    assert_eq!(a["world"]["biomes"], everywhere);
    // Ridges west, steppe east.
    let halves = serde_json::json!([
        {"dictionary": ridges, "weight": "west"},
        {"dictionary": steppe, "weight": "east"}
    ]);
    let (st, h) = send_json(
        &app,
        create(
            serde_json::json!({"name": "halves", "base": base, "biomes": halves, "max_zoom": 12}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{h}");
    let (_, info) = send_json(&app, get("/worlds/halves")).await;
    assert_eq!(info["dictionaries"], serde_json::json!([ridges, steppe]));
    assert_eq!(
        info["biomes"],
        serde_json::json!([{"name": "west", "dictionary": ridges}, {"name": "east", "dictionary": steppe}])
    );
    let (_, info) = send_json(&app, get("/worlds/alone")).await;
    assert!(info.get("biomes").is_none(), "{info}");
    // The middle of the base: 74° + 32 cells of 15″ east, 42.5° − 32 cells south.
    let (lon, lat) = (74.0 + 32.0 / 240.0, 42.5 - 32.0 / 240.0);
    let mut differs = false;
    for zz in [z + 1, z + 2, z + 3] {
        let (x, y) = tile_of(lon, lat, zz);
        let uri = |w: &str| format!("/tiles/{w}/elevation/{zz}/{x}/{y}.png");
        let (s1, _, t_alone) = send(&app, get(&uri("alone"))).await;
        let (s2, _, t_every) = send(&app, get(&uri("everywhere"))).await;
        let (s3, _, t_halves) = send(&app, get(&uri("halves"))).await;
        assert_eq!(
            (s1, s2, s3),
            (StatusCode::OK, StatusCode::OK, StatusCode::OK),
            "z{zz}"
        );
        assert_eq!(
            t_alone, t_every,
            "z{zz}: a biome painted everywhere is its world alone"
        );
        differs |= t_halves != t_alone;
    }
    assert!(differs, "the steppe half amplifies differently");
    // Weights from another exemplar on the base's grid: that exemplar is then in use.
    let weights_parts = [
        ("elevation", tiff_of(n, n, |_, _| 1.0)),
        ("north", tiff_of(n, n, |r, _| f32::from(u8::from(r < half)))),
        (
            "south",
            tiff_of(n, n, |r, _| f32::from(u8::from(r >= half))),
        ),
    ];
    let (st, wv) = send_json(&app, multipart("painted-weights", &weights_parts)).await;
    assert_eq!(st, StatusCode::CREATED, "{wv}");
    let weights_id = wv["id"].as_str().unwrap().to_string();
    let borrowed = serde_json::json!([
        {"dictionary": ridges, "weight": "north", "exemplar": weights_id},
        {"dictionary": steppe, "weight": "south", "exemplar": weights_id}
    ]);
    let (st, v) = send_json(
        &app,
        create(serde_json::json!({"name": "borrowed", "base": base, "biomes": borrowed, "max_zoom": 12})),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    let del = req(
        Method::DELETE,
        &format!("/admin/exemplars/{weights_id}"),
        None,
        Vec::new(),
    );
    let (st, h, body) = send(&app, del).await;
    assert_eq!(st, StatusCode::CONFLICT);
    assert!(problem_detail(st, &h, &body)
        .contains("holds biome weights or controls of world `borrowed`"));
    // Both dictionaries and the weight exemplar are in use.
    for d in [&ridges, &steppe] {
        let del = req(
            Method::DELETE,
            &format!("/admin/dictionaries/{d}"),
            None,
            Vec::new(),
        );
        assert_eq!(send(&app, del).await.0, StatusCode::CONFLICT);
    }
    // Bad biomes: 422 problem+json naming the problem, nothing stored.
    let before = store_files(dir.path());
    let unknown_id = "0".repeat(64);
    let cases = [
        (
            serde_json::json!([{"dictionary": ridges, "weight": "zeros"}, {"dictionary": steppe, "weight": "zeros", "name": "dry"}]),
            "0 everywhere",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "alps"}]),
            "biomes[0].weight: exemplar",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "west"}, {"dictionary": unknown_id, "weight": "east"}]),
            "biomes[1]: unknown dictionary",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "neg"}]),
            "weight -2 at row 5, column 7",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "nan"}]),
            "weight NaN at row 6, column 8",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "west", "exemplar": other}]),
            "must lie on the base's grid",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "west"}, {"dictionary": steppe, "weight": "west"}]),
            "biomes[1].name `west` is used twice",
        ),
        (
            serde_json::json!([{"dictionary": ridges, "weight": "west", "layer": "x"}]),
            "unknown field `layer`",
        ),
    ];
    for (biomes, needle) in cases {
        let (st, h, body) = send(
            &app,
            create(serde_json::json!({"name": "bad", "base": base, "biomes": biomes})),
        )
        .await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{needle}");
        let detail = problem_detail(st, &h, &body);
        assert!(detail.contains(needle), "{needle}: {detail}");
    }
    let (st, h, body) = send(
        &app,
        create(serde_json::json!({"name": "bad", "base": base, "biomes": halves, "dictionaries": [ridges]})),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(problem_detail(st, &h, &body).contains("either `biomes` or `dictionaries`"));
    // Painted species controls: bad ones are 422 naming the problem (a good one is created
    // below).
    for (controls, needle) in [
        (
            serde_json::json!([{"species": "spruce", "layer": "west", "mode": "double"}]),
            "controls[0].mode `double` must be `replace` or `scale`",
        ),
        (
            serde_json::json!([{"species": "spruce", "layer": "alps", "mode": "scale"}]),
            "controls[0].layer: exemplar",
        ),
        (
            serde_json::json!([{"species": "oak", "layer": "west", "mode": "scale"}]),
            "controls[0]: unknown species `oak`",
        ),
        (
            serde_json::json!([{"species": "spruce", "layer": "neg", "mode": "scale"}]),
            "controls[0] (`spruce`): value -2 at row 5, column 7",
        ),
        (
            serde_json::json!([{"species": "spruce", "layer": "west", "mode": "scale", "exemplar": other}]),
            "must lie on the base's grid",
        ),
    ] {
        let (st, h, body) = send(
            &app,
            create(serde_json::json!({"name": "bad", "base": base, "dictionaries": [ridges], "controls": controls})),
        )
        .await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{needle}");
        let detail = problem_detail(st, &h, &body);
        assert!(detail.contains(needle), "{needle}: {detail}");
    }
    // A material's `biome.<name>` term must name one of the world's biomes.
    let sand = serde_json::json!([{"name": "sand", "colour": [200, 180, 120],
        "biome": {"desert": {"min": 0.5, "max": 1.0}}}]);
    let (st, h, body) = send(
        &app,
        create(
            serde_json::json!({"name": "bad", "base": base, "biomes": halves, "materials": sand}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    let detail = problem_detail(st, &h, &body);
    assert!(
        detail.contains("material sand names unknown biome `desert` (its biomes are west, east)"),
        "{detail}"
    );
    assert_eq!(store_files(dir.path()), before);
    assert_eq!(
        send(&app, get("/worlds/bad")).await.0,
        StatusCode::NOT_FOUND
    );
    // A good control is stored with the world and echoed back.
    let controls = serde_json::json!([{"species": "spruce", "layer": "east", "mode": "replace"}]);
    let (st, v) = send_json(
        &app,
        create(
            serde_json::json!({"name": "drawn", "base": base, "dictionaries": [ridges],
            "controls": controls, "max_zoom": 12}),
        ),
    )
    .await;
    assert_eq!(st, StatusCode::CREATED, "{v}");
    assert_eq!(v["world"]["controls"], controls);
}
