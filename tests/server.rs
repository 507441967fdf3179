//! The HTTP API through `tower::ServiceExt::oneshot` on the real router and a real (small) world:
//! every endpoint and error, ETag/304, HEAD, CORS on success and error, TileJSON validity,
//! Prometheus metrics, 503 when the synthesis queue is full. Also the tile invariants of the world
//! pyramid at the native zoom and at amplified zooms: seamlessness and zoom consistency.

mod common;

use std::sync::Arc;

use axum::body::{to_bytes, Body};
use axum::http::{header, Method, Request, StatusCode};
use ndarray::{s, Array2};
use tower::ServiceExt;

use terrasynth::config::ServerConfig;
use terrasynth::dictionary::MatchWeights;
use terrasynth::raster::{Crs, Georef, Grid};
use terrasynth::server::{app, AppState, Worlds};
use terrasynth::synth::{Amplifier, Field, Window};
use terrasynth::tiles::{decode_mapbox_png, decode_terrarium_png, World, WorldParts};

use common::{small_dictionary, synthetic_terrain};

/// A 6°×5° world (70–76°E, 38–43°N) of synthetic terrain at 15″, native zoom 8, max zoom 11.
fn small_world() -> World {
    let base = Grid::new(
        synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0),
        Georef {
            crs: Crs::Epsg4326,
            west: 70.0,
            north: 43.0,
            pixel_width: 1.0 / 240.0,
            pixel_height: 1.0 / 240.0,
        },
    );
    World::new(WorldParts {
        name: "mini".into(),
        title: "Mini".into(),
        attribution: "synthetic".into(),
        base,
        z_base: Some(8),
        max_zoom: 11,
        fill_m: 0.0,
        dictionary: small_dictionary(2),
        dictionary_id: "test-dictionary".into(),
        weights: MatchWeights::default(),
        cache_bytes: 64 << 20,
    })
    .unwrap()
}

fn router(config: &ServerConfig) -> axum::Router {
    let mut worlds = Worlds::new();
    worlds.insert("mini".into(), Arc::new(small_world()));
    app(AppState::new(worlds, config).unwrap())
}

fn get(uri: &str) -> Request<Body> {
    Request::builder()
        .uri(uri)
        .header(header::ORIGIN, "https://map.example")
        .body(Body::empty())
        .unwrap()
}

async fn send(
    app: &axum::Router,
    req: Request<Body>,
) -> (StatusCode, axum::http::HeaderMap, Vec<u8>) {
    let resp = app.clone().oneshot(req).await.unwrap();
    let status = resp.status();
    let headers = resp.headers().clone();
    let body = to_bytes(resp.into_body(), 64 << 20).await.unwrap().to_vec();
    (status, headers, body)
}

// A tile well inside the mini world (73°E, 40.5°N at zoom 8).
const Z8: (u8, u32, u32) = (8, 179, 96);

// --- tiles: formats, headers, caching semantics ---

#[tokio::test]
async fn elevation_tiles_in_every_format() {
    let app = router(&ServerConfig::default());
    let (z, x, y) = Z8;
    let (st, h, body) = send(&app, get(&format!("/tiles/mini/elevation/{z}/{x}/{y}.png"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
    assert_eq!(h[header::CACHE_CONTROL], "public, max-age=86400");
    assert_eq!(h[header::ACCESS_CONTROL_ALLOW_ORIGIN], "*");
    let etag = h[header::ETAG].to_str().unwrap().to_string();
    assert!(
        etag.starts_with('"') && etag.ends_with('"'),
        "strong etag {etag}"
    );
    let heights = decode_terrarium_png(&body).unwrap();
    assert_eq!(heights.dim(), (256, 256));
    // Plausible metres: the synthetic terrain lies between about 0 and 3000 m; fill is 0.
    assert!(heights.iter().all(|v| (-50.0..4000.0).contains(v)));
    assert!(heights.iter().any(|v| *v > 500.0));

    let (st, _, mb) = send(
        &app,
        get(&format!(
            "/tiles/mini/elevation/{z}/{x}/{y}.png?encoding=mapbox"
        )),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let m = decode_mapbox_png(&mb).unwrap();
    let max_diff = m
        .iter()
        .zip(heights.iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(max_diff < 0.2, "mapbox and terrarium agree ({max_diff})");

    let (st, _, big) = send(
        &app,
        get(&format!("/tiles/mini/elevation/{z}/{x}/{y}@2x.png")),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(decode_terrarium_png(&big).unwrap().dim(), (512, 512));

    let (st, h, exr) = send(&app, get(&format!("/tiles/mini/elevation/{z}/{x}/{y}.exr"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/x-exr");
    let ch = terrasynth::tiles::decode_float_exr(&exr).unwrap();
    assert_eq!(ch[0].0, "elevation");
    let diff = ch[0]
        .1
        .iter()
        .zip(heights.iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    // Terrarium rounds to the nearest 1/16 m (`TERRARIUM_STEPS_PER_M`); the EXR is exact.
    assert!(diff <= 1.0 / 32.0 + 1e-3, "exr vs terrarium {diff}");

    let (st, h, hs) = send(
        &app,
        get(&format!(
            "/tiles/mini/hillshade/{z}/{x}/{y}.png?azimuth=200&altitude=30"
        )),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
    assert!(hs.starts_with(b"\x89PNG"));
}

#[tokio::test]
async fn etag_304_and_head() {
    let app = router(&ServerConfig::default());
    let uri = "/tiles/mini/elevation/9/358/192.png";
    let (st, h, body) = send(&app, get(uri)).await;
    assert_eq!(st, StatusCode::OK);
    let etag = h[header::ETAG].clone();
    let req = Request::builder()
        .uri(uri)
        .header(header::IF_NONE_MATCH, etag.clone())
        .body(Body::empty())
        .unwrap();
    let (st, h2, b2) = send(&app, req).await;
    assert_eq!(st, StatusCode::NOT_MODIFIED);
    assert!(b2.is_empty());
    assert_eq!(h2[header::ETAG], etag);
    let other = Request::builder()
        .uri(uri)
        .header(header::IF_NONE_MATCH, "\"something-else\"")
        .body(Body::empty())
        .unwrap();
    assert_eq!(send(&app, other).await.0, StatusCode::OK);
    let head = Request::builder()
        .method(Method::HEAD)
        .uri(uri)
        .body(Body::empty())
        .unwrap();
    let (st, h3, b3) = send(&app, head).await;
    assert_eq!(st, StatusCode::OK);
    assert!(b3.is_empty());
    assert_eq!(h3[header::ETAG], etag);
    assert!(!body.is_empty());
}

// --- errors: status, problem+json, CORS ---

#[tokio::test]
async fn errors_are_problem_json_with_cors() {
    let app = router(&ServerConfig::default());
    let cases = [
        ("/tiles/nope/elevation/8/179/94.png", StatusCode::NOT_FOUND),
        ("/tiles/mini/vegetables/8/179/94.png", StatusCode::NOT_FOUND),
        ("/tiles/mini/elevation/8/179/94.jpg", StatusCode::NOT_FOUND),
        ("/tiles/mini/hillshade/8/179/94.exr", StatusCode::NOT_FOUND),
        (
            "/tiles/mini/elevation/12/2000/1000.png",
            StatusCode::NOT_FOUND,
        ),
        ("/tiles/mini/elevation/8/256/94.png", StatusCode::NOT_FOUND),
        ("/tiles/mini/elevation/8/0/0.png", StatusCode::NOT_FOUND),
        (
            "/tiles/mini/elevation/eight/179/94.png",
            StatusCode::BAD_REQUEST,
        ),
        ("/tiles/mini/elevation/8/-1/94.png", StatusCode::BAD_REQUEST),
        (
            "/tiles/mini/elevation/8/179/94.png?encoding=jpeg",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/tiles/mini/elevation/8/179/94.png?bogus=1",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/tiles/mini/hillshade/8/179/94.png?azimuth=north",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/tiles/mini/hillshade/8/179/94.png?altitude=95",
            StatusCode::BAD_REQUEST,
        ),
        ("/tiles/mini/nothing.json", StatusCode::NOT_FOUND),
        ("/worlds/nope", StatusCode::NOT_FOUND),
        ("/no/such/route", StatusCode::NOT_FOUND),
    ];
    for (uri, want) in cases {
        let (st, h, body) = send(&app, get(uri)).await;
        assert_eq!(st, want, "{uri}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json", "{uri}");
        assert_eq!(h[header::ACCESS_CONTROL_ALLOW_ORIGIN], "*", "{uri}");
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(
            v["status"].as_u64(),
            Some(u64::from(want.as_u16())),
            "{uri}"
        );
        assert!(v["title"].is_string() && v["detail"].is_string(), "{uri}");
    }
}

#[tokio::test]
async fn full_queue_answers_503_with_retry_after() {
    let config = ServerConfig {
        synth_queue: 0,
        ..ServerConfig::default()
    };
    let app = router(&config);
    let (st, h, body) = send(&app, get("/tiles/mini/elevation/10/717/385.png")).await;
    assert_eq!(st, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(h[header::RETRY_AFTER], "1");
    assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
    assert!(!body.is_empty());
}

#[tokio::test]
async fn configured_cors_origins_and_cache_control() {
    let config = ServerConfig {
        cors_origins: vec!["https://map.example".into()],
        cache_control: "public, max-age=60".into(),
        ..ServerConfig::default()
    };
    let app = router(&config);
    let (_, h, _) = send(&app, get("/tiles/mini/elevation/8/179/96.png")).await;
    assert_eq!(
        h[header::ACCESS_CONTROL_ALLOW_ORIGIN],
        "https://map.example"
    );
    assert_eq!(h[header::CACHE_CONTROL], "public, max-age=60");
    let other = Request::builder()
        .uri("/healthz")
        .header(header::ORIGIN, "https://evil.example")
        .body(Body::empty())
        .unwrap();
    let (_, h, _) = send(&app, other).await;
    assert!(h.get(header::ACCESS_CONTROL_ALLOW_ORIGIN).is_none());
}

// --- metadata: TileJSON, worlds, health, metrics ---

#[tokio::test]
async fn tilejson_worlds_health_metrics() {
    let app = router(&ServerConfig::default());
    for layer in ["elevation", "hillshade"] {
        let (st, h, body) = send(&app, get(&format!("/tiles/mini/{layer}.json"))).await;
        assert_eq!(st, StatusCode::OK);
        assert!(h[header::CONTENT_TYPE]
            .to_str()
            .unwrap()
            .starts_with("application/json"));
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(v["tilejson"], "3.0.0");
        let url = v["tiles"][0].as_str().unwrap();
        assert!(
            url.ends_with(&format!("/tiles/mini/{layer}/{{z}}/{{x}}/{{y}}.png")),
            "{url}"
        );
        assert_eq!(v["minzoom"], 0);
        assert_eq!(v["maxzoom"], 11);
        let b: Vec<f64> = serde_json::from_value(v["bounds"].clone()).unwrap();
        assert!((b[0] - 70.0).abs() < 1e-9 && (b[2] - 76.0).abs() < 1e-9);
        assert!((b[1] - 38.0).abs() < 1e-9 && (b[3] - 43.0).abs() < 1e-9);
        let c: Vec<f64> = serde_json::from_value(v["center"].clone()).unwrap();
        assert!(c[0] > b[0] && c[0] < b[2] && c[1] > b[1] && c[1] < b[3]);
        assert!(v["name"].is_string() && v["attribution"].is_string());
        if layer == "elevation" {
            assert_eq!(v["encoding"], "terrarium");
            assert_eq!(v["tileSize"], 256);
        }
    }
    let (st, _, body) = send(&app, get("/worlds")).await;
    assert_eq!(st, StatusCode::OK);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v[0]["name"], "mini");
    assert_eq!(v[0]["native_zoom"], 8);
    assert_eq!(v[0]["dictionaries"][0], "test-dictionary");
    let (st, _, body) = send(&app, get("/worlds/mini")).await;
    assert_eq!(st, StatusCode::OK);
    let w: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(w["layers"], serde_json::json!(["elevation", "hillshade"]));
    let (st, h, body) = send(&app, get("/healthz")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CACHE_CONTROL], "no-cache");
    assert_eq!(body, b"ok");
    // A synthesized tile, then the metrics.
    assert_eq!(
        send(&app, get("/tiles/mini/elevation/9/358/192.png"))
            .await
            .0,
        StatusCode::OK
    );
    assert_eq!(
        send(&app, get("/tiles/mini/elevation/99/1/1.png")).await.0,
        StatusCode::NOT_FOUND
    );
    let (st, _, body) = send(&app, get("/metrics")).await;
    assert_eq!(st, StatusCode::OK);
    let text = String::from_utf8(body).unwrap();
    assert!(text.contains("terrasynth_requests_total{route=\"/tiles/{world}/{layer}/{z}/{x}/{y}\",method=\"GET\",status=\"200\"}"), "{text}");
    assert!(text.contains("status=\"404\""));
    assert!(text.contains("terrasynth_request_duration_seconds_bucket"));
    let synthesized = text
        .lines()
        .find(|l| l.starts_with("terrasynth_tiles_synthesized_total{world=\"mini\"}"))
        .and_then(|l| l.split_whitespace().last())
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap();
    assert!(synthesized >= 1.0);
    assert!(text.contains("terrasynth_cache_misses_total{world=\"mini\"}"));
    assert!(text.contains("terrasynth_synthesis_seconds_total{world=\"mini\"}"));
}

// --- invariants of the pyramid: seamless and zoom-consistent ---

fn mosaic(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> Array2<f32> {
    let mut out = Array2::zeros((256 * n as usize, 256 * n as usize));
    for dy in 0..n {
        for dx in 0..n {
            let t = world.elevation_tile(z, x0 + dx, y0 + dy).unwrap();
            out.slice_mut(s![
                dy as usize * 256..(dy as usize + 1) * 256,
                dx as usize * 256..(dx as usize + 1) * 256
            ])
            .assign(&t);
        }
    }
    out
}

/// Mean |step| across the tile borders of a 3×3 mosaic, and between interior neighbours.
fn border_and_interior_steps(m: &Array2<f32>) -> (f64, f64) {
    let (mut border, mut nb, mut inner, mut ni) = (0.0, 0, 0.0, 0);
    for r in 0..m.nrows() {
        for c in 0..m.ncols() - 1 {
            let d = f64::from((m[[r, c + 1]] - m[[r, c]]).abs());
            if (c + 1) % 256 == 0 {
                border += d;
                nb += 1;
            } else {
                inner += d;
                ni += 1;
            }
        }
    }
    for r in 0..m.nrows() - 1 {
        for c in 0..m.ncols() {
            let d = f64::from((m[[r + 1, c]] - m[[r, c]]).abs());
            if (r + 1) % 256 == 0 {
                border += d;
                nb += 1;
            } else {
                inner += d;
                ni += 1;
            }
        }
    }
    (border / nb as f64, inner / ni as f64)
}

#[test]
fn tiles_are_seamless_at_native_and_amplified_zooms() {
    let world = small_world();
    // Native zoom 8 and amplified zoom 10, 3×3 blocks inside the world.
    for (z, x0, y0) in [(8u8, 178u32, 95u32), (10, 716, 384)] {
        let m = mosaic(&world, z, x0, y0, 3);
        let (border, inner) = border_and_interior_steps(&m);
        assert!(
            border <= 1.25 * inner,
            "z{z}: border step {border} vs interior {inner}"
        );
    }
    // The tile computed alone equals the same window of the level field computed over the whole
    // 3×3 block in one call.
    let z = 10u8;
    let (x0, y0) = (716i64, 384i64);
    let dict = small_dictionary(2);
    let amp = Amplifier::new(dict, &MatchWeights::default())
        .unwrap()
        .without_layers();
    let block = Window::new(x0 * 256, y0 * 256, 768, 768);
    let need = amp.parent_window_for(block);
    let parent = Field::elevation_only(need, world.elevation_window(z - 1, need).unwrap());
    let field = amp
        .amplify(&parent, block, world.level_cell_m(z - 1) as f32)
        .unwrap();
    let alone = world.elevation_tile(z, 717, 385).unwrap();
    let window = field.elevation.slice(s![256..512, 256..512]);
    assert!(alone
        .iter()
        .zip(window.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn children_average_to_their_parent() {
    let world = small_world();
    // Native zoom (8 → 9) and amplified zooms (10 → 11); also an overview (7 → 8).
    for (z, x, y) in [(8u8, 179u32, 96u32), (10, 717, 385), (7, 89, 48)] {
        let parent = world.elevation_tile(z, x, y).unwrap();
        let kids = mosaic(&world, z + 1, 2 * x, 2 * y, 2);
        let avg = Array2::from_shape_fn((256, 256), |(r, c)| {
            (kids[[2 * r, 2 * c]]
                + kids[[2 * r, 2 * c + 1]]
                + kids[[2 * r + 1, 2 * c]]
                + kids[[2 * r + 1, 2 * c + 1]])
                / 4.0
        });
        let rmse = (avg
            .iter()
            .zip(parent.iter())
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum::<f64>()
            / 65536.0)
            .sqrt();
        let relief = f64::from(
            parent.iter().cloned().fold(f32::MIN, f32::max)
                - parent.iter().cloned().fold(f32::MAX, f32::min),
        );
        assert!(relief > 10.0, "z{z}: the tile has relief");
        assert!(rmse < 0.01 * relief, "z{z}: rmse {rmse} vs relief {relief}");
    }
}
