//! Lossless WebP tiles (`{y}.webp`, issue #19): the elevation WebP decodes to the same heights as
//! the PNG of the same request (terrarium, mapbox, `@2x`), the colour WebP to the same pixels,
//! with `image/webp`; TileJSON's `tile_format` and `?tile_format=webp`; the formats and
//! parameters WebP does not have are refused.

use axum::body::Body;
use axum::http::{header, Request, StatusCode};

use terrasynth::config::ServerConfig;
use terrasynth_tiles::{decode_mapbox_png, decode_terrarium_png};

use crate::support::{decode_rgba, mini_router, send, send_json};

fn router() -> axum::Router {
    mini_router(&ServerConfig::default())
}

fn get(uri: &str) -> Request<Body> {
    Request::builder().uri(uri).body(Body::empty()).unwrap()
}

/// RGBA samples of a WebP, decoded by `image-webp` (RGB expanded with alpha 255).
fn webp_rgba(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    let mut d = image_webp::WebPDecoder::new(std::io::Cursor::new(bytes)).unwrap();
    let (w, h) = d.dimensions();
    let mut buf = vec![0u8; d.output_buffer_size().unwrap()];
    d.read_image(&mut buf).unwrap();
    let rgba = if d.has_alpha() {
        buf
    } else {
        buf.chunks(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect()
    };
    (h as usize, w as usize, rgba)
}

/// RGBA samples of an RGB or RGBA PNG (RGB expanded with alpha 255).
fn png_rgba(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    let rgba = match info.color_type {
        png::ColorType::Rgba => buf,
        png::ColorType::Rgb => buf
            .chunks(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        other => panic!("unexpected PNG colour type {other:?}"),
    };
    (info.height as usize, info.width as usize, rgba)
}

// A tile inside the mini world at an amplified zoom and one at the native zoom.
const TILES: [(u8, u32, u32); 2] = [(8, 179, 96), (10, 718, 386)];

#[tokio::test]
async fn webp_elevation_decodes_to_the_png_heights() {
    let app = router();
    for (z, x, y) in TILES {
        for (suffix, query) in [
            ("", ""),
            ("", "?encoding=mapbox"),
            ("@2x", ""),
            ("@2x", "?encoding=terrarium"),
        ] {
            let url = |ext: &str| format!("/tiles/mini/elevation/{z}/{x}/{y}{suffix}.{ext}{query}");
            let (st, _, png) = send(&app, get(&url("png"))).await;
            assert_eq!(st, StatusCode::OK);
            let (st, h, webp) = send(&app, get(&url("webp"))).await;
            assert_eq!(st, StatusCode::OK, "{}", url("webp"));
            assert_eq!(h[header::CONTENT_TYPE], "image/webp");
            assert_eq!(&webp[..4], b"RIFF");
            assert_eq!(&webp[8..12], b"WEBP");
            let decode = if query.contains("mapbox") {
                decode_mapbox_png
            } else {
                decode_terrarium_png
            };
            let (a, b) = (decode(&png).unwrap(), decode(&webp).unwrap());
            assert_eq!(
                a.dim(),
                if suffix.is_empty() {
                    (256, 256)
                } else {
                    (512, 512)
                }
            );
            assert_eq!(a, b, "{}: WebP heights differ from PNG", url("webp"));
            // The pixels themselves, decoded without the height formulas.
            assert_eq!(png_rgba(&png), webp_rgba(&webp));
            // A distinct resource with its own ETag.
            let (_, hp, _) = send(&app, get(&url("png"))).await;
            assert_ne!(h[header::ETAG], hp[header::ETAG]);
        }
    }
}

#[tokio::test]
async fn webp_colour_has_the_png_pixels() {
    let app = router();
    for (z, x, y) in TILES {
        let (st, _, png) = send(&app, get(&format!("/tiles/mini/color/{z}/{x}/{y}.png"))).await;
        assert_eq!(st, StatusCode::OK);
        let (st, h, webp) = send(&app, get(&format!("/tiles/mini/color/{z}/{x}/{y}.webp"))).await;
        assert_eq!(st, StatusCode::OK);
        assert_eq!(h[header::CONTENT_TYPE], "image/webp");
        assert_eq!(decode_rgba(&png), webp_rgba(&webp));
    }
}

#[tokio::test]
async fn webp_formats_and_parameters_that_do_not_exist_are_refused() {
    let app = router();
    let (z, x, y) = TILES[0];
    for (path, status) in [
        (
            format!("/tiles/mini/hillshade/{z}/{x}/{y}.webp"),
            StatusCode::NOT_FOUND,
        ),
        (
            format!("/tiles/mini/color/{z}/{x}/{y}@2x.webp"),
            StatusCode::NOT_FOUND,
        ),
        (
            format!("/tiles/mini/splat/{z}/{x}/{y}.webp"),
            StatusCode::NOT_FOUND,
        ),
        (
            format!("/tiles/mini/color/{z}/{x}/{y}.webp?encoding=mapbox"),
            StatusCode::BAD_REQUEST,
        ),
        (
            format!("/tiles/mini/elevation/{z}/{x}/{y}.webp?encoding=lerc"),
            StatusCode::BAD_REQUEST,
        ),
        (
            format!("/tiles/mini/elevation/{z}/{x}/{y}.webp?azimuth=3"),
            StatusCode::BAD_REQUEST,
        ),
    ] {
        let (st, h, _) = send(&app, get(&path)).await;
        assert_eq!(st, status, "{path}");
        assert_eq!(
            h[header::CONTENT_TYPE],
            "application/problem+json",
            "{path}"
        );
    }
}

#[tokio::test]
async fn tilejson_names_the_tile_format() {
    let app = router();
    let (st, png) = send_json(&app, get("/tiles/mini/elevation.json")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(png["tile_format"], "png");
    assert!(png["tiles"][0].as_str().unwrap().ends_with("{y}.png"));
    for layer in ["elevation", "color"] {
        let (st, webp) = send_json(
            &app,
            get(&format!("/tiles/mini/{layer}.json?tile_format=webp")),
        )
        .await;
        assert_eq!(st, StatusCode::OK);
        assert_eq!(webp["tile_format"], "webp");
        assert!(webp["tiles"][0].as_str().unwrap().ends_with("{y}.webp"));
    }
    let (st, elevation) = send_json(&app, get("/tiles/mini/elevation.json?tile_format=webp")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(elevation["encoding"], "terrarium");
    for bad in [
        "/tiles/mini/hillshade.json?tile_format=webp",
        "/tiles/mini/elevation.json?tile_format=gif",
    ] {
        let (st, _) = send_json(&app, get(bad)).await;
        assert_eq!(st, StatusCode::NOT_FOUND, "{bad}");
    }
}
