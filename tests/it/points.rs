//! Point queries (issue #19): `GET` and `POST /worlds/{world}/elevation` answer the float32
//! value of the served EXR tile's pixel that contains each point (pixel found here with the Web
//! Mercator formulas written out, not the server's helpers); the zoom used; at most 10,000
//! points (10,001 is a 422 problem+json); bad coordinates and parameters.

use axum::body::Body;
use axum::http::{header, Method, Request, StatusCode};

use terrasynth::config::ServerConfig;
use terrasynth_core::math;
use terrasynth_tiles::decode_float_exr;

use crate::support::{mini_router, send, send_json};

fn router() -> axum::Router {
    mini_router(&ServerConfig::default())
}

fn get(uri: &str) -> Request<Body> {
    Request::builder().uri(uri).body(Body::empty()).unwrap()
}

fn post(uri: &str, body: &serde_json::Value) -> Request<Body> {
    Request::builder()
        .method(Method::POST)
        .uri(uri)
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from(body.to_string()))
        .unwrap()
}

/// Longitude and latitude of the centre of pixel `(row, col)` of tile `z/x/y` (spherical Web
/// Mercator written out).
fn pixel_centre(z: u8, x: u32, y: u32, row: usize, col: usize) -> (f64, f64) {
    let size = 256.0 * f64::from(1u32 << z);
    let px = f64::from(x) * 256.0 + col as f64 + 0.5;
    let py = f64::from(y) * 256.0 + row as f64 + 0.5;
    let lon = px / size * 360.0 - 180.0;
    let n = std::f64::consts::PI * (1.0 - 2.0 * py / size);
    let lat = math::atan(math::sinh(n)).to_degrees();
    (lon, lat)
}

async fn exr(app: &axum::Router, z: u8, x: u32, y: u32) -> ndarray::Array2<f32> {
    let (st, _, bytes) = send(app, get(&format!("/tiles/mini/elevation/{z}/{x}/{y}.exr"))).await;
    assert_eq!(st, StatusCode::OK);
    decode_float_exr(&bytes).unwrap().remove(0).1
}

// Pixels of two tiles (an amplified zoom and the native zoom): corners, edges and inside.
const PIXELS: [(usize, usize); 6] = [(0, 0), (0, 255), (255, 0), (255, 255), (17, 200), (128, 64)];

#[tokio::test]
async fn a_point_answers_the_exr_pixel_that_contains_it() {
    let app = router();
    for (z, x, y) in [(10, 718, 386), (8, 179, 96)] {
        let tile = exr(&app, z, x, y).await;
        for (r, c) in PIXELS {
            let (lon, lat) = pixel_centre(z, x, y, r, c);
            let (st, v) = send_json(
                &app,
                get(&format!("/worlds/mini/elevation?lon={lon}&lat={lat}&z={z}")),
            )
            .await;
            assert_eq!(st, StatusCode::OK, "{v}");
            assert_eq!(v["z"], z);
            let got = v["elevation_m"].as_f64().unwrap() as f32;
            assert_eq!(got, tile[[r, c]], "{z}/{x}/{y} pixel {r},{c}");
        }
    }
}

#[tokio::test]
async fn a_profile_answers_every_point_from_the_exr_tiles() {
    let app = router();
    let z = 10;
    // A 2×2 block of tiles; points in every one, in a scrambled order.
    let mut points = Vec::new();
    let mut want = Vec::new();
    for (x, y) in [(719, 387), (718, 386), (719, 386), (718, 387)] {
        let tile = exr(&app, z, x, y).await;
        for (r, c) in PIXELS {
            points.push(pixel_centre(z, x, y, r, c));
            want.push(tile[[r, c]]);
        }
    }
    // And one point outside the world (70–76°E, 38–43°N): null.
    points.push((10.0, 10.0));
    let body = serde_json::json!({
        "z": z,
        "points": points.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(),
    });
    let (st, v) = send_json(&app, post("/worlds/mini/elevation", &body)).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["z"], z);
    let got = v["elevations_m"].as_array().unwrap();
    assert_eq!(got.len(), want.len() + 1);
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.as_f64().unwrap() as f32, *w);
    }
    assert!(got[want.len()].is_null());
}

#[tokio::test]
async fn the_zoom_used_is_capped_and_defaults_to_the_opening_zoom() {
    let app = router();
    let (st, v) = send_json(&app, get("/worlds/mini/elevation?lon=73&lat=40.5&z=30")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(v["z"], 11, "capped at the world's deepest zoom");
    let (_, world) = send_json(&app, get("/worlds/mini")).await;
    let (st, v) = send_json(&app, get("/worlds/mini/elevation?lon=73&lat=40.5")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(
        v["z"].as_f64().unwrap(),
        world["center"][2].as_f64().unwrap()
    );
}

#[tokio::test]
async fn ten_thousand_points_pass_and_one_more_is_a_422() {
    let app = router();
    let line = |n: usize| -> serde_json::Value {
        let pts: Vec<[f64; 2]> = (0..n)
            .map(|i| [72.0 + 2.0 * i as f64 / n as f64, 40.5])
            .collect();
        serde_json::json!({"points": pts, "z": 8})
    };
    let (st, v) = send_json(&app, post("/worlds/mini/elevation", &line(10_000))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(v["elevations_m"].as_array().unwrap().len(), 10_000);
    let (st, h, body) = send(&app, post("/worlds/mini/elevation", &line(10_001))).await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
    let p: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(p["detail"].as_str().unwrap().contains("10000"), "{p}");
}

#[tokio::test]
async fn bad_points_and_parameters_are_problems() {
    let app = router();
    for (uri, status) in [
        (
            "/worlds/mini/elevation?lon=73&lat=89",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            "/worlds/mini/elevation?lon=181&lat=40",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            "/worlds/mini/elevation?lon=NaN&lat=40",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        ("/worlds/mini/elevation?lat=40", StatusCode::BAD_REQUEST),
        (
            "/worlds/mini/elevation?lon=x&lat=40",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/worlds/mini/elevation?lon=73&lat=40&z=-1",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/worlds/mini/elevation?lon=73&lat=40&zoom=3",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/worlds/mini/elevation?lon=10&lat=10",
            StatusCode::NOT_FOUND,
        ),
        (
            "/worlds/nope/elevation?lon=73&lat=40",
            StatusCode::NOT_FOUND,
        ),
    ] {
        let (st, h, _) = send(&app, get(uri)).await;
        assert_eq!(st, status, "{uri}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json", "{uri}");
    }
    for (body, status) in [
        (
            serde_json::json!({"points": [[73.0, 95.0]]}),
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            serde_json::json!({"points": [[73.0]]}),
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            serde_json::json!({"pts": []}),
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
    ] {
        let (st, h, _) = send(&app, post("/worlds/mini/elevation", &body)).await;
        assert_eq!(st, status, "{body}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
    }
    let raw = Request::builder()
        .method(Method::POST)
        .uri("/worlds/mini/elevation")
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from("{not json"))
        .unwrap();
    assert_eq!(send(&app, raw).await.0, StatusCode::BAD_REQUEST);
}
