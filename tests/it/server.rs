//! The HTTP API through `tower::ServiceExt::oneshot` on the real router and a real (small) world:
//! every endpoint and error, ETag/304, HEAD, CORS on success and error, TileJSON validity,
//! Prometheus metrics, 503 when the synthesis queue is full. Also the tile invariants of the world
//! pyramid at the native zoom and at amplified zooms: seamlessness and zoom consistency.

use axum::body::Body;
use axum::http::{header, Method, Request, StatusCode};
use ndarray::{s, Array2};

use terrasynth::config::ServerConfig;
use terrasynth_core::dictionary::MatchWeights;
use terrasynth_core::landscape::LandscapeConfig;

use crate::support::{decode_rgba, mini_router, send, small_world};
use terrasynth_core::math;
use terrasynth_core::synth::{Amplifier, Field, Window};
use terrasynth_tiles::{decode_mapbox_png, decode_terrarium_png, World};

use terrasynth_test_support::coherence::{drainage_fit, mosaic_of, vegetation_fit};
use terrasynth_test_support::small_dictionary_with_vegetation;

fn router(config: &ServerConfig) -> axum::Router {
    mini_router(config)
}

fn get(uri: &str) -> Request<Body> {
    Request::builder()
        .uri(uri)
        .header(header::ORIGIN, "https://map.example")
        .body(Body::empty())
        .unwrap()
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
    let ch = terrasynth_tiles::decode_float_exr(&exr).unwrap();
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

/// The ETag is the first 16 bytes, in hex, of SHA-256 over the world's fingerprint (and, for
/// instance tiles, its scatter fingerprint) and `|{kind:?}|z|x|y`: computed here the plain way, it
/// must equal what the server's precomputed hash states give, so ETags clients hold stay valid
/// for as long as the world and the tiles' revision (`TILE_BYTES_REVISION`, in the fingerprint)
/// do.
#[test]
fn etags_equal_the_plain_hash_of_world_and_request() {
    use sha2::{Digest, Sha256};
    use std::collections::HashMap;
    let world = small_world();
    let no_query = HashMap::new();
    let cases = [
        ("elevation", "8", "179", "96.png"),
        ("elevation", "9", "358", "193@2x.png"),
        ("elevation", "10", "716", "386.exr"),
        ("hillshade", "8", "179", "96.png"),
        ("color", "11", "1432", "772.png"),
        ("instances", "11", "1432", "772.mvt"),
    ];
    let mut seen = std::collections::HashSet::new();
    for (layer, z, x, y) in cases {
        let req = terrasynth_tiles::parse_request("mini", layer, z, x, y, &no_query).unwrap();
        let mut h = Sha256::new();
        h.update(world.fingerprint().as_bytes());
        if layer == "instances" {
            h.update(world.scatter_fingerprint().as_bytes());
        }
        h.update(format!("|{:?}|{}|{}|{}", req.kind, req.z, req.x, req.y).as_bytes());
        let hex: String = h.finalize()[..16]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        let tag = terrasynth_tiles::etag(&world, &req);
        assert_eq!(tag, format!("\"{hex}\""), "{layer} {z}/{x}/{y}");
        assert!(seen.insert(tag), "ETags differ between tiles");
    }
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
    assert_eq!(
        w["layers"],
        serde_json::json!([
            "elevation",
            "hillshade",
            "vegetation",
            "drainage",
            "splat",
            "color",
            "water"
        ])
    );
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

/// `W/"` and the first 16 bytes of the SHA-256 of `body` in hex, computed here.
fn weak_tag_of(body: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    let hex: String = Sha256::digest(body)[..16]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    format!("W/\"{hex}\"")
}

#[tokio::test]
async fn documents_carry_a_weak_etag_of_their_bytes_and_revalidate_with_304() {
    let app = router(&ServerConfig::default());
    let asking = |uri: &str, fields: &[(header::HeaderName, &str)]| {
        let mut r = get(uri);
        for (k, v) in fields {
            r.headers_mut().append(k, v.parse().unwrap());
        }
        r
    };
    for uri in [
        "/worlds",
        "/worlds/mini",
        "/tiles/mini/elevation.json",
        "/tiles/mini/color.json?tile_format=webp",
        "/styles/mini.json",
        "/worlds/mini/WMTSCapabilities.xml",
        "/openapi.json",
        "/",
        "/minimal.html",
        "/app.js",
        "/app.css",
    ] {
        let (st, h, body) = send(&app, get(uri)).await;
        assert_eq!(st, StatusCode::OK, "{uri}");
        assert!(!body.is_empty(), "{uri}");
        let tag = h[header::ETAG].to_str().unwrap().to_string();
        assert_eq!(tag, weak_tag_of(&body), "{uri}");
        assert_eq!(h[header::CACHE_CONTROL], "no-cache", "{uri}");
        // Its own tag, alone or in a list, weak or not: 304, no body, the same validators.
        for field in [
            tag.clone(),
            format!("\"x\", {}", tag.trim_start_matches("W/")),
        ] {
            let (st, h2, b2) = send(&app, asking(uri, &[(header::IF_NONE_MATCH, &field)])).await;
            assert_eq!(st, StatusCode::NOT_MODIFIED, "{uri} {field}");
            assert!(b2.is_empty(), "{uri}");
            assert_eq!(h2[header::ETAG], tag.as_str(), "{uri}");
            assert_eq!(h2[header::CACHE_CONTROL], "no-cache", "{uri}");
        }
        let other = asking(uri, &[(header::IF_NONE_MATCH, "W/\"0123\"")]);
        assert_eq!(send(&app, other).await.0, StatusCode::OK, "{uri}");
        // Gzip-coded by the compression layer under the same weak tag, which revalidates too.
        let gz = [(header::ACCEPT_ENCODING, "gzip")];
        let (st, gh, gz_body) = send(&app, asking(uri, &gz)).await;
        assert_eq!(st, StatusCode::OK, "{uri}");
        assert_eq!(gh[header::ETAG], tag.as_str(), "{uri}");
        assert_eq!(
            crate::support::gzip_coded_body(&gh, &gz_body),
            body,
            "{uri}"
        );
        let again = asking(uri, &[gz[0].clone(), (header::IF_NONE_MATCH, &tag)]);
        assert_eq!(send(&app, again).await.0, StatusCode::NOT_MODIFIED, "{uri}");
    }
    // A document built on the request's host is another document on another host: its tag
    // changes with the bytes, and the first host's tag no longer matches.
    let (_, h, body) = send(&app, get("/tiles/mini/elevation.json")).await;
    let (st, h2, body2) = send(
        &app,
        asking(
            "/tiles/mini/elevation.json",
            &[
                (header::HOST, "tiles.example:8443"),
                (header::IF_NONE_MATCH, h[header::ETAG].to_str().unwrap()),
            ],
        ),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    assert_ne!(body, body2);
    assert_ne!(h[header::ETAG], h2[header::ETAG]);
    assert_eq!(h2[header::ETAG].to_str().unwrap(), weak_tag_of(&body2));
    assert!(h2[header::VARY].to_str().unwrap().contains("Host"));
}

/// The text of every `<tag>` element in `xml`, in order (the capabilities are written by us with
/// one element per line; no XML reader is needed to read them back).
fn element_texts<'a>(xml: &'a str, tag: &str) -> Vec<&'a str> {
    let (open, close) = (format!("<{tag}>"), format!("</{tag}>"));
    xml.split(open.as_str())
        .skip(1)
        .filter_map(|rest| rest.split_once(close.as_str()).map(|(text, _)| text))
        .collect()
}

#[tokio::test]
async fn wmts_capabilities_declare_exactly_the_tiles_served() {
    let app = router(&ServerConfig::default());
    let (st, h, body) = send(&app, get("/worlds/mini/WMTSCapabilities.xml")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "application/xml");
    let xml = String::from_utf8(body).unwrap();
    assert!(xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Capabilities "));
    // Every layer the world lists, each with a PNG template on the XYZ route.
    let (_, world) = crate::support::send_json(&app, get("/worlds/mini")).await;
    let layers: Vec<&str> = world["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap())
        .collect();
    let ids: Vec<&str> = element_texts(&xml, "ows:Identifier")
        .into_iter()
        .filter(|id| layers.contains(id))
        .collect();
    assert_eq!(ids, layers);
    for layer in &layers {
        let template =
            format!("/tiles/mini/{layer}/{{TileMatrix}}/{{TileCol}}/{{TileRow}}.png\"/>");
        let line = xml
            .lines()
            .find(|l| l.contains(&template))
            .unwrap_or_else(|| panic!("no {template}"));
        assert!(
            line.trim_start().starts_with(
                "<ResourceURL format=\"image/png\" resourceType=\"tile\" template=\"http://"
            ),
            "{line}"
        );
    }
    // The first layer's limits: the corners are served, one tile beyond each side is not.
    let world_struct = small_world();
    let first_layer = xml.split("</Layer>").next().unwrap();
    let zooms = element_texts(first_layer, "TileMatrix");
    assert_eq!(zooms.len(), 12, "zooms 0..=11 of the mini world");
    let num = |tag: &str| -> Vec<u32> {
        element_texts(first_layer, tag)
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let (r0, r1, c0, c1) = (
        num("MinTileRow"),
        num("MaxTileRow"),
        num("MinTileCol"),
        num("MaxTileCol"),
    );
    for (k, z) in zooms.iter().enumerate() {
        let z: u8 = z.parse().unwrap();
        let n = 1u32 << z;
        for (x, y) in [
            (c0[k], r0[k]),
            (c1[k], r0[k]),
            (c0[k], r1[k]),
            (c1[k], r1[k]),
        ] {
            assert!(world_struct.check_tile(z, x, y).is_ok(), "{z}/{x}/{y}");
        }
        let beyond = [
            (c0[k].checked_sub(1), Some(r0[k])),
            (Some(c1[k] + 1), Some(r0[k])),
            (Some(c0[k]), r0[k].checked_sub(1)),
            (Some(c0[k]), Some(r1[k] + 1)),
        ];
        for (x, y) in beyond {
            if let (Some(x), Some(y)) = (x, y) {
                if x < n && y < n {
                    assert!(world_struct.check_tile(z, x, y).is_err(), "{z}/{x}/{y}");
                }
            }
        }
    }
    // The tile matrices: 2^z tiles a side at a scale halving with each zoom, computed here.
    let widths: Vec<u64> = element_texts(&xml, "MatrixWidth")
        .iter()
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(widths, (0..=11).map(|z| 1u64 << z).collect::<Vec<_>>());
    let scales: Vec<f64> = element_texts(&xml, "ScaleDenominator")
        .iter()
        .map(|v| v.parse().unwrap())
        .collect();
    let z0 = 2.0 * std::f64::consts::PI * 6_378_137.0 / 256.0 / 0.000_28;
    for (z, s) in scales.iter().enumerate() {
        let want = z0 / f64::from(1u32 << z);
        assert!(
            (s - want).abs() <= 1e-9 * want,
            "zoom {z}: {s} against {want}"
        );
    }
    // Unknown worlds are 404.
    let (st, _, _) = send(&app, get("/worlds/nowhere/WMTSCapabilities.xml")).await;
    assert_eq!(st, StatusCode::NOT_FOUND);
}

// --- invariants of the pyramid: seamless and zoom-consistent ---

fn mosaic(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> Array2<f32> {
    mosaic_of(n, |dx, dy| {
        world
            .elevation_tile(z, x0 + dx, y0 + dy)
            .unwrap()
            .as_ref()
            .clone()
    })
}

/// Mean |step| across the tile borders of a 3×3 mosaic, and between interior neighbours.
pub(crate) fn border_and_interior_steps(m: &Array2<f32>) -> (f64, f64) {
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
    let dict = small_dictionary_with_vegetation(2);
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

// --- landscape layers: endpoints, invariants, coherence with the served elevation ---

#[tokio::test]
async fn landscape_layers_over_http() {
    let app = router(&ServerConfig::default());
    // An amplified zoom (the native zoom is 8).
    let (z, x, y) = (9u8, 358u32, 192u32);
    let ok = |uri: String| {
        let app = app.clone();
        async move {
            let (st, h, body) = send(&app, get(&uri)).await;
            assert_eq!(
                st,
                StatusCode::OK,
                "{uri}: {}",
                String::from_utf8_lossy(&body)
            );
            (h, body)
        }
    };
    let (h, veg) = ok(format!("/tiles/mini/vegetation/{z}/{x}/{y}.png")).await;
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
    let (_, _, px) = decode_rgba(&veg);
    let (_, exr) = ok(format!("/tiles/mini/vegetation/{z}/{x}/{y}.exr")).await;
    let ch = terrasynth_tiles::decode_float_exr(&exr).unwrap();
    let mut names: Vec<&str> = ch.iter().map(|(n, _)| n.as_str()).collect();
    names.sort_unstable();
    assert_eq!(names, ["juniper", "meadow", "spruce", "steppe"]);
    for (name, d) in &ch {
        // Channel k of the PNG is species k of the world file.
        let k = ["spruce", "juniper", "meadow", "steppe"]
            .iter()
            .position(|n| n == name)
            .unwrap();
        assert!(d.iter().all(|v| (0.0..=1.0).contains(v)));
        // The PNG channel is the density × 255.
        for (i, v) in d.iter().enumerate().step_by(97) {
            assert_eq!(px[4 * i + k], (v * 255.0).round() as u8);
        }
    }
    let (_, overlay) = ok(format!(
        "/tiles/mini/vegetation/{z}/{x}/{y}.png?style=overlay"
    ))
    .await;
    assert_eq!(decode_rgba(&overlay).0, 256);

    let (h, dexr) = ok(format!("/tiles/mini/drainage/{z}/{x}/{y}.exr")).await;
    assert_eq!(h[header::CONTENT_TYPE], "image/x-exr");
    let area = terrasynth_tiles::decode_float_exr(&dexr).unwrap();
    // The channel is named `upstream_area` (the reader renames a lone channel `elevation`).
    assert!(dexr.windows(13).any(|w| w == b"upstream_area"));
    // At least the pixel's own area (zoom 9: about 230 m × 230 m at 40°N), somewhere rivers.
    let a = &area[0].1;
    assert!(
        a.iter().all(|v| *v > 1e4),
        "min area {}",
        a.iter().cloned().fold(f32::MAX, f32::min)
    );
    assert!(a.iter().any(|v| *v > 1e8));
    let (_, dpng) = ok(format!("/tiles/mini/drainage/{z}/{x}/{y}.png")).await;
    let (_, _, dp) = decode_rgba(&dpng);
    assert!(dp.chunks(4).any(|p| p[3] > 100) && dp.chunks(4).any(|p| p[3] == 0));
    // The PNG draws exactly the channels of the EXR's upstream area of 10⁶ m² or more (the
    // world's `png_min_m2`, the default world's landscape), each at least at its floor opacity
    // 0.4 (alpha 102), and areas of 10¹⁰ m² (`png_max_m2`) or more opaque.
    for (p, &area) in dp.chunks(4).zip(a.iter()) {
        match area {
            v if v < 1e6 => assert_eq!(p[3], 0, "area {v}"),
            v if v >= 1e10 => assert_eq!(p[3], 255, "area {v}"),
            v => assert!(p[3] >= 102, "area {v}: alpha {}", p[3]),
        }
        assert_eq!(&p[..3], &[30, 100, 230]);
    }

    // Splat: the 8 materials in two sets; every pixel's bytes sum to 255 over both.
    let (_, s0) = ok(format!("/tiles/mini/splat/{z}/{x}/{y}.png")).await;
    let (_, s1) = ok(format!("/tiles/mini/splat/{z}/{x}/{y}.png?set=1")).await;
    let (_, _, a0) = decode_rgba(&s0);
    let (_, _, a1) = decode_rgba(&s1);
    for (p, q) in a0.chunks(4).zip(a1.chunks(4)) {
        let sum: u32 = p.iter().chain(q).map(|&v| u32::from(v)).sum();
        assert!((253..=257).contains(&sum), "{p:?} {q:?}");
    }
    let (_, col) = ok(format!("/tiles/mini/color/{z}/{x}/{y}.png")).await;
    let (_, _, c) = decode_rgba(&col);
    assert!(c.chunks(4).all(|p| p[3] == 255));

    // Errors: bad set (400), parameters of another layer (400), unknown format/layer (404).
    for (uri, want) in [
        // Eight materials and `water`: three sets.
        (format!("/tiles/mini/splat/{z}/{x}/{y}.png?set=3"), 400),
        (format!("/tiles/mini/splat/{z}/{x}/{y}.png?set=-1"), 400),
        (format!("/tiles/mini/splat/{z}/{x}/{y}.png?set=x"), 400),
        (format!("/tiles/mini/vegetation/{z}/{x}/{y}.png?set=1"), 400),
        (
            format!("/tiles/mini/vegetation/{z}/{x}/{y}.png?style=x"),
            400,
        ),
        (format!("/tiles/mini/color/{z}/{x}/{y}.png?set=0"), 400),
        (format!("/tiles/mini/drainage/{z}/{x}/{y}.tif"), 404),
        (format!("/tiles/mini/splat/{z}/{x}/{y}.exr"), 404),
        (format!("/tiles/mini/soil/{z}/{x}/{y}.png"), 404),
    ] {
        let (st, h, _) = send(&app, get(&uri)).await;
        assert_eq!(st.as_u16(), want, "{uri}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json", "{uri}");
    }

    // TileJSON of every layer, the world's layer list and the MapLibre style.
    for layer in ["vegetation", "drainage", "splat", "color"] {
        let (_, body) = ok(format!("/tiles/mini/{layer}.json")).await;
        let tj: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(tj["tilejson"], "3.0.0");
        let url = tj["tiles"][0].as_str().unwrap();
        assert!(
            url.ends_with(&format!("/mini/{layer}/{{z}}/{{x}}/{{y}}.png")),
            "{url}"
        );
    }
    let (_, body) = ok("/worlds/mini".into()).await;
    let info: serde_json::Value = serde_json::from_slice(&body).unwrap();
    for layer in ["vegetation", "drainage", "splat", "color"] {
        assert!(info["layers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| l == layer));
    }
    let (_, body) = ok("/styles/mini.json".into()).await;
    let style: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(style["version"], 8);
    assert_eq!(style["terrain"]["source"], "terrain");
    assert_eq!(style["sources"]["terrain"]["type"], "raster-dem");
    assert_eq!(style["sources"]["terrain"]["encoding"], "terrarium");
    let layers = style["layers"].as_array().unwrap();
    for id in ["color", "water", "vegetation", "drainage", "hillshade"] {
        let l = layers.iter().find(|l| l["id"] == id).unwrap();
        assert!(l["layout"]["visibility"] == "visible" || l["layout"]["visibility"] == "none");
    }
    assert_eq!(
        send(&app, get("/styles/nowhere.json")).await.0,
        StatusCode::NOT_FOUND
    );
}

/// The landscape fields of a tile as named grids: each vegetation species, log10 drainage and
/// each material weight.
fn landscape_channels(world: &World, z: u8, x: u32, y: u32) -> Vec<Array2<f32>> {
    let mut out: Vec<Array2<f32>> = world.vegetation_tile(z, x, y).unwrap().to_vec();
    out.push(world.drainage_tile(z, x, y).unwrap().mapv(math::log10f));
    out.extend(world.material_tile(z, x, y).unwrap().weights.clone());
    out
}

/// Mean |step| across the tile borders of a mosaic, and mean |step| between the pixel pairs just
/// beside each border (one pixel either side, same rows or columns).
fn border_and_adjacent_steps(m: &Array2<f32>) -> (f64, f64) {
    let (mut border, mut adjacent, mut n) = (0.0, 0.0, 0);
    let d = |a: f32, b: f32| f64::from((a - b).abs());
    for c in (255..m.ncols() - 2).step_by(256) {
        for r in 0..m.nrows() {
            border += d(m[[r, c + 1]], m[[r, c]]);
            adjacent += 0.5 * (d(m[[r, c]], m[[r, c - 1]]) + d(m[[r, c + 2]], m[[r, c + 1]]));
            n += 1;
        }
    }
    for r in (255..m.nrows() - 2).step_by(256) {
        for c in 0..m.ncols() {
            border += d(m[[r + 1, c]], m[[r, c]]);
            adjacent += 0.5 * (d(m[[r, c]], m[[r - 1, c]]) + d(m[[r + 2, c]], m[[r + 1, c]]));
            n += 1;
        }
    }
    (border / n as f64, adjacent / n as f64)
}

#[test]
fn landscape_layers_are_deterministic_and_seamless() {
    let world = small_world();
    let channels_of = |z: u8, x0: u32, y0: u32| -> Vec<Array2<f32>> {
        let tiles: Vec<Vec<Array2<f32>>> = (0..9)
            .map(|i| landscape_channels(&world, z, x0 + i % 3, y0 + i / 3))
            .collect();
        (0..tiles[0].len())
            .map(|ch| mosaic_of(3, |dx, dy| tiles[(dy * 3 + dx) as usize][ch].clone()))
            .collect()
    };
    // The elevation's test, unchanged, on every channel of every layer over the same amplified
    // zoom-10 block: mean border step ≤ 1.25 × mean interior step.
    let mut bad = Vec::new();
    for (ch, m) in channels_of(10, 716, 384).iter().enumerate() {
        let (border, inner) = border_and_interior_steps(m);
        eprintln!("z10 channel {ch}: border step {border:.5} vs interior {inner:.5}");
        if border > 1.25 * inner {
            bad.push((10, ch, "interior"));
        }
    }
    // At the native zoom every layer is cut from one whole-world raster (checked bit for bit
    // below), so a border cannot differ from any other line; there the test above measures how
    // patchy channels differ from one part of the mosaic to another (spruce: 1.32×, and lines
    // 16 px beside the borders reach 1.38×). The paired form compares each border step with the
    // steps one pixel either side on the same row (column), at both zooms; a step of 0.002 (0.2 %
    // of the 0–1 range) is allowed for channels present on a few dozen pixels.
    for (z, x0, y0) in [(8u8, 178u32, 95u32), (10, 716, 384)] {
        for (ch, m) in channels_of(z, x0, y0).iter().enumerate() {
            let (border, inner) = border_and_adjacent_steps(m);
            eprintln!("z{z} channel {ch}: border step {border:.5} vs adjacent {inner:.5}");
            if border > 1.25 * inner + 0.002 {
                bad.push((z, ch, "adjacent"));
            }
        }
    }
    assert!(bad.is_empty(), "(zoom, channel, test) {bad:?} show seams");
    // Deterministic and window-invariant: in a fresh world, assembling the whole 3×3 block first
    // (other request order, other cache state) gives the centre tile the same bits.
    // At the native zoom 8 and the amplified zoom 10.
    let fresh = small_world();
    let third = small_world();
    for (z, x0, y0) in [(8u8, 178i64, 95i64), (10, 716, 384)] {
        let block = Window::new(x0 * 256, y0 * 256, 768, 768);
        let veg = fresh.vegetation_window(z, block).unwrap();
        let drain = fresh.drainage_window(z, block).unwrap();
        let (x, y) = (x0 as u32 + 1, y0 as u32 + 1);
        let alone = world.vegetation_tile(z, x, y).unwrap();
        assert_eq!(alone.len(), veg.len());
        for (a, b) in alone.iter().zip(&veg) {
            assert_eq!(a, &b.slice(s![256..512, 256..512]).to_owned());
        }
        let d = world.drainage_tile(z, x, y).unwrap();
        assert_eq!(*d, drain.slice(s![256..512, 256..512]).to_owned());
        assert_eq!(
            third.material_tile(z, x, y).unwrap().weights,
            world.material_tile(z, x, y).unwrap().weights
        );
    }
}

#[test]
fn vegetation_densities_average_across_zooms() {
    // Densities average: a parent pixel's density is close to the mean of its 2×2 children
    // (amplified zooms: corrected blend, then the viability gate; overviews: exact averages).
    // Drainage is skipped (a coarse pixel's upstream area is that of its main channel, the
    // maximum, not the mean, of its children), and so are splat weights and colours: they are
    // nonlinear functions of slope and curvature, which grow with resolution.
    let world = small_world();
    for (z, x, y) in [(7u8, 89u32, 48u32), (8, 179, 96), (9, 358, 192)] {
        let parent = world.vegetation_tile(z, x, y).unwrap();
        let kids: Vec<Vec<Array2<f32>>> = (0..4)
            .map(|i| {
                world
                    .vegetation_tile(z + 1, 2 * x + i % 2, 2 * y + i / 2)
                    .unwrap()
                    .to_vec()
            })
            .collect();
        for k in 0..parent.len() {
            let m = mosaic_of(2, |dx, dy| kids[(dy * 2 + dx) as usize][k].clone());
            let mut err = 0.0f64;
            for r in 0..256 {
                for c in 0..256 {
                    let avg = (m[[2 * r, 2 * c]]
                        + m[[2 * r, 2 * c + 1]]
                        + m[[2 * r + 1, 2 * c]]
                        + m[[2 * r + 1, 2 * c + 1]])
                        / 4.0;
                    err += f64::from((avg - parent[k][[r, c]]).abs());
                }
            }
            let mae = err / 65536.0;
            let tol = if z < 8 { 1e-6 } else { 0.03 };
            eprintln!("z{z} species {k}: mean |avg − parent| {mae:.4}");
            assert!(mae <= tol, "z{z} species {k}: {mae}");
        }
    }
}

#[test]
fn vegetation_follows_the_niche_model_on_the_served_elevation() {
    // Acceptance 3 on a 4×4 mosaic of amplified zoom-9 tiles: the niche model evaluated on the
    // decoded elevation tiles correlates with each species' density (Pearson ≥ 0.6) and no
    // species reaches 0.05 where its niche is 0 (see `terrasynth_test_support::coherence`).
    let world = small_world();
    let fits = vegetation_fit(&world, 9, 356, 190, 4);
    let mut tested = 0;
    for f in &fits {
        eprintln!(
            "{}: present on {:.1} %, Pearson {:.3}, max density where excluded {:.4}",
            f.name,
            100.0 * f.present,
            f.pearson,
            f.worst_excluded
        );
        assert!(f.worst_excluded < 0.05, "{f:?}");
        if f.present > 0.02 {
            assert!(f.pearson >= 0.6, "{f:?}");
            tested += 1;
        }
    }
    assert!(tested >= 2, "at least two species grow on the mosaic");
}

#[test]
fn drainage_agrees_with_the_served_elevation_and_channels_cross_borders() {
    // Acceptance 4 on a 4×4 mosaic of amplified zoom-10 tiles: Spearman ≥ 0.7 against D8 on the
    // decoded elevation mosaic (16-px frame ignored), and main channels walked across tile
    // borders without a break (see `terrasynth_test_support::coherence`).
    let world = small_world();
    let fit = drainage_fit(&world, 10, 716, 384, 4);
    eprintln!(
        "Spearman(served log area, D8 on the decoded mosaic) = {:.3}; {} main-channel border crossings walked",
        fit.spearman, fit.crossings
    );
    assert!(fit.spearman >= 0.7, "{fit:?}");
    assert!(fit.crossings >= 3, "{fit:?}");
    assert!(fit.breaks.is_empty(), "{:?}", fit.breaks);
}

#[test]
fn splat_weights_sum_to_255_and_vanish_outside_their_ranges() {
    use terrasynth_core::landscape::{material_weights, quantise_weights, LayerInputs};
    // Synthetic inputs sweeping every parameter over and beyond the default materials' ranges.
    let cfg = LandscapeConfig::tienshan();
    let (rows, cols) = (64, 64);
    let grid =
        |f: &dyn Fn(usize, usize) -> f32| Array2::from_shape_fn((rows, cols), |(r, c)| f(r, c));
    let elevation = grid(&|r, c| -200.0 + 90.0 * r as f32 + 3.0 * c as f32);
    let slope = grid(&|r, c| ((r * 7 + c * 3) % 80) as f32);
    let northness = grid(&|r, c| ((r * 5 + c * 11) % 41) as f32 / 20.0 - 1.0);
    let curvature = grid(&|r, c| ((r * 3 + c * 13) % 21) as f32 * 5e-4 - 5e-3);
    let wetness = grid(&|r, c| ((r + c * 7) % 12) as f32);
    let vegetation: Vec<Array2<f32>> = (0..cfg.species.len())
        .map(|k| grid(&|r, c| ((r * (k + 2) + c * 5) % 11) as f32 / 10.0))
        .collect();
    let inputs = LayerInputs {
        elevation: &elevation,
        slope: &slope,
        northness: &northness,
        curvature: &curvature,
        wetness: &wetness,
        vegetation: &vegetation,
        classes: &[],
        origin: (1000, -3000),
        pixel_m: 150.0,
    };
    let w = material_weights(&cfg, &inputs);
    let fallback = cfg.fallback_index();
    let mut q = vec![0u8; w.len()];
    let mut fallbacks = 0;
    for r in 0..rows {
        for c in 0..cols {
            let px: Vec<f32> = w.iter().map(|m| m[[r, c]]).collect();
            quantise_weights(&px, &mut q);
            // All sets of a pixel together: 255 ± 2.
            let sum: u32 = q.iter().map(|&v| u32::from(v)).sum();
            assert!((253..=257).contains(&sum));
            // A pixel no material admits goes to the fallback alone.
            let only_fallback = px
                .iter()
                .enumerate()
                .all(|(k, &v)| (k == fallback) == (v == 1.0));
            if only_fallback && q[fallback] == 255 {
                fallbacks += 1;
            }
            for (k, m) in cfg.materials.iter().enumerate() {
                let outside = |t: Option<terrasynth_core::landscape::Trapezoid>, x: f32| {
                    t.is_some_and(|t| x <= t.min || x >= t.max)
                };
                let mut out = outside(m.elevation, elevation[[r, c]])
                    || outside(m.slope, slope[[r, c]])
                    || outside(m.northness, northness[[r, c]])
                    || outside(m.curvature, curvature[[r, c]])
                    || outside(m.wetness, wetness[[r, c]]);
                for (name, t) in &m.vegetation {
                    let i = cfg.species.iter().position(|s| &s.name == name).unwrap();
                    out |= outside(Some(*t), vegetation[i][[r, c]]);
                }
                if out && !(k == fallback && only_fallback) {
                    assert_eq!(q[k], 0, "material {} at ({r},{c})", m.name);
                    assert_eq!(px[k], 0.0);
                }
            }
        }
    }
    eprintln!(
        "{fallbacks} of {} pixels fell back to {}",
        rows * cols,
        cfg.materials[fallback].name
    );
}

/// A world whose base is in a projected CRS (the committed UTM 11N lidar) is reprojected onto
/// the globe: it lies over the Carrizo Plain and its native tiles carry the lidar's heights.
#[test]
fn a_world_on_a_utm_base_lies_where_the_data_lies() {
    let base = terrasynth_core::raster::embedded::carrizo().unwrap();
    let world = World::new(terrasynth_tiles::WorldParts {
        name: "carrizo".into(),
        title: "Carrizo".into(),
        attribution: "lidar".into(),
        base,
        z_base: None,
        max_zoom: 18,
        fill_m: 0.0,
        dictionaries: vec![terrasynth_tiles::DictionaryBand::every_zoom(
            small_dictionary_with_vegetation(4),
            "d",
        )],
        weights: MatchWeights::default(),
        cache_bytes: 16 << 20,
        landscape: LandscapeConfig::tienshan(),
        center: None,
        sparsity: None,
        water: Default::default(),
        classes: None,
        biomes: Vec::new(),
        controls: Vec::new(),
    })
    .unwrap();
    let [w, s, e, n] = world.bounds();
    assert!(
        (-119.9..-119.8).contains(&w) && (-119.9..-119.8).contains(&e),
        "{w} {e}"
    );
    assert!(
        (35.2..35.4).contains(&s) && (35.2..35.4).contains(&n),
        "{s} {n}"
    );
    // 2 m cells at 35.3°N: zoom 16 has 1.9 m pixels there.
    assert!(world.z_base() >= 15, "native zoom {}", world.z_base());
    let z = world.z_base();
    let (x, y) = terrasynth_test_support::tile_of((w + e) / 2.0, (s + n) / 2.0, z);
    let t = world.elevation_tile(z, x, y).unwrap();
    let inside: Vec<f32> = t.iter().copied().filter(|&v| v != 0.0).collect();
    assert!(inside.len() > 1000);
    assert!(
        inside.iter().all(|v| (628.0..704.0).contains(v)),
        "heights of the lidar"
    );
}

/// Waits until the world's background thread has computed the parent tiles of its cold chains.
fn wait_for_prefill(world: &World) {
    let start = std::time::Instant::now();
    while world.stats().prefilling {
        assert!(
            start.elapsed() < std::time::Duration::from_secs(300),
            "the background prefill never ended"
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

#[test]
fn the_background_prefill_moves_while_every_global_pool_worker_waits() {
    // The export renders tiles on rayon's global pool, and its workers may all wait for parent
    // tiles the background prefill is computing: the prefill must not need them (it hung an
    // export in CI when its parallel loops ran on the global pool).
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::time::{Duration, Instant};
    let world = small_world();
    let workers = rayon::current_num_threads();
    let (started, released) = (AtomicUsize::new(0), AtomicBool::new(false));
    std::thread::scope(|s| {
        // Every worker of the global pool waits until released (or gives up after 300 s).
        let blocked = s.spawn(|| {
            rayon::broadcast(|_| {
                started.fetch_add(1, Ordering::AcqRel);
                let t0 = Instant::now();
                while !released.load(Ordering::Acquire) {
                    if t0.elapsed() > Duration::from_secs(300) {
                        return false;
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                true
            })
        });
        while started.load(Ordering::Acquire) < workers {
            std::thread::sleep(Duration::from_millis(1));
        }
        // A cold zoom-11 tile, computed on a pool of its own, queues its parents.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| world.elevation_tile(11, 1434, 770).unwrap());
        assert!(world.stats().windows_synthesized > 0, "a cold chain");
        let t0 = Instant::now();
        let mut ended = true;
        while world.stats().prefilling {
            if t0.elapsed() > Duration::from_secs(240) {
                ended = false;
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        released.store(true, Ordering::Release);
        assert!(blocked.join().unwrap().iter().all(|&ok| ok));
        assert!(ended, "the prefill waited for the global pool's workers");
    });
}

#[test]
fn every_world_s_background_prefill_shares_one_pool() {
    // Two worlds with cold chains: their background jobs run on one process-wide pool, so the
    // process holds at most rayon's default thread count of prefill threads (a pool per world
    // held that many per world).
    use terrasynth_tiles::elevation::PREFILL_THREAD_PREFIX;
    let prefill_threads = || {
        std::fs::read_dir("/proc/self/task")
            .unwrap()
            .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
            .filter(|name| name.starts_with(PREFILL_THREAD_PREFIX))
            .count()
    };
    let (a, b) = (small_world(), small_world());
    a.elevation_tile(11, 1434, 770).unwrap();
    b.elevation_tile(11, 1434, 770).unwrap();
    assert!(a.stats().windows_synthesized > 0 && b.stats().windows_synthesized > 0);
    let n = prefill_threads();
    wait_for_prefill(&a);
    wait_for_prefill(&b);
    assert!(
        (1..=rayon::current_num_threads()).contains(&n),
        "{n} prefill threads for two worlds"
    );
}

#[test]
fn a_cold_chain_of_windows_equals_the_chain_of_cached_tiles() {
    // World A: a zoom-11 tile in an area nobody visited goes down its chain by windows (zooms 10
    // and 9 amplified directly); world B: the same tile after 3×3 blocks of its ancestors were
    // computed bottom-up, so every level assembles cached tiles.
    let (z, x, y) = (11u8, 1434u32, 770u32);
    let cold = small_world();
    let tile_cold = cold.elevation_tile(z, x, y).unwrap();
    assert_eq!(
        cold.stats().windows_synthesized,
        2,
        "zooms 10 and 9 by windows"
    );
    wait_for_prefill(&cold);

    let warm = small_world();
    for zz in 9..z {
        let (ax, ay) = (x >> (z - zz), y >> (z - zz));
        for dy in 0..3 {
            for dx in 0..3 {
                warm.elevation_tile(zz, ax + dx - 1, ay + dy - 1).unwrap();
            }
        }
    }
    let tile_warm = warm.elevation_tile(z, x, y).unwrap();
    assert_eq!(
        warm.stats().windows_synthesized,
        0,
        "every parent was cached"
    );
    assert!(
        tile_cold
            .iter()
            .zip(tile_warm.iter())
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "the window chain and the tile chain give different values"
    );

    // The background thread left the parents cached: the neighbour goes by tiles and amplifies
    // no window.
    let before = cold.stats();
    let next = cold.elevation_tile(z, x + 1, y).unwrap();
    let after = cold.stats();
    assert_eq!(after.windows_synthesized, before.windows_synthesized);
    assert!(after.tiles_synthesized > before.tiles_synthesized);
    let next_warm = warm.elevation_tile(z, x + 1, y).unwrap();
    assert!(next
        .iter()
        .zip(next_warm.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// The deeper routing halo (210 pixels at zoom 14, 254 from zoom 15; `drainage::drain_halo`)
/// keeps drainage a pure function of the tile: on the default world, a tile computed alone equals
/// the same window of a 2×2 block assembled in a second world loaded from the same store with
/// cold caches (another request order), bit for bit, at zooms 14 and 15.
#[test]
fn deep_drainage_tiles_are_window_invariant_with_their_deeper_halo() {
    let dir = tempfile::tempdir().unwrap();
    let config = terrasynth::config::load(None, Vec::new()).unwrap();
    let store = terrasynth_store::Store::open(&dir.path().join("store")).unwrap();
    let load = || terrasynth::server::load_worlds(&config, &store).unwrap()["tienshan"].clone();
    let (alone, block) = (load(), load());
    // Over the Kyrgyz Ala-Too (the tile-hash list's zoom-14 tile is 11584/6048).
    for (z, x, y) in [(14u8, 11590u32, 6050u32), (15, 23181, 12101)] {
        let tile = alone.drainage_tile(z, x, y).unwrap();
        assert!(
            tile.iter().any(|&a| a >= 1e6),
            "zoom {z}: no channel to compare"
        );
        let w = Window::new(i64::from(x - 1) * 256, i64::from(y - 1) * 256, 512, 512);
        let from_block = block.drainage_window(z, w).unwrap();
        assert_eq!(
            *tile,
            from_block.slice(s![256..512, 256..512]).to_owned(),
            "zoom {z}"
        );
    }
}
