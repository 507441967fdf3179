//! Worlds with the gradient amplifier (issue #20) on the real binary and real sockets: one from a
//! world file (`amplifier = "gradient"` on the embedded Tien Shan base) and one created through
//! the admin API (the same base uploaded, a gradient tile set built with `"kind": "gradient"`,
//! the world's `dictionaries` entry with `"amplifier": "gradient"`). Both serve every layer;
//! a second process on the same store serves the same bytes; served tiles are seamless across
//! a 3×3 block and a 512-px tile equals the four tiles it covers. Bad build parameters and a
//! file of the wrong kind are 422 naming the problem, and store nothing. The hillshade mosaics
//! of the 3×3 blocks at zooms 11 and 12 are written to `CARGO_TARGET_TMPDIR` (the pictures
//! `tests/pictures/gradient-hillshade-z11.png` and `-z12.png` are the world file's world's).

use std::path::Path;

use ndarray::Array2;

use terrasynth_test_support::coherence::mosaic_of;
use terrasynth_test_support::process::{get, json, post};
use terrasynth_test_support::{store_files, tile_of};
use terrasynth_tiles::{decode_float_exr, decode_terrarium_png};

use crate::admin_e2e::{tienshan_crop, tiff, upload, wait_until, TOKEN};
use crate::server::border_and_interior_steps;
use crate::support::{start, Server};

/// The world file: the default base, one gradient band over every amplified zoom.
const WORLD_TOML: &str = "name = \"gts\"\nbase = \"embedded:tienshan\"\nz_base = 8\n\
    max_zoom = 16\ncenter = [74.55, 42.55]\n[dictionary]\namplifier = \"gradient\"\n\
    exemplars = [\"embedded:tienshan\"]\n";

fn serve(dir: &Path) -> Server {
    std::fs::write(dir.join("gts.toml"), WORLD_TOML).unwrap();
    let cfg = dir.join("server.toml");
    std::fs::write(&cfg, "worlds = [\"gts.toml\"]\nbuild_queue = 4\n").unwrap();
    start(
        &["--config", &cfg.display().to_string()],
        &[
            ("TERRASYNTH_ADMIN_TOKEN", TOKEN),
            ("TERRASYNTH_CACHE_MB", "512"),
            ("TERRASYNTH_REQUEST_TIMEOUT_S", "900"),
        ],
        &dir.join("store"),
    )
}

fn post_json(server: &Server, path: &str, body: serde_json::Value) -> (u16, serde_json::Value) {
    let (st, b) = post(
        server,
        path,
        TOKEN,
        "application/json",
        body.to_string().as_bytes(),
    );
    (st, serde_json::from_slice(&b).unwrap_or_default())
}

/// Builds through `POST /admin/dictionaries` and waits for the job; the id.
fn build(server: &Server, body: serde_json::Value) -> String {
    let (st, accepted) = post_json(server, "/admin/dictionaries", body);
    assert_eq!(st, 202, "{accepted}");
    let id = accepted["id"].as_str().unwrap().to_string();
    let done = wait_until(server, &id, |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(done["state"], "succeeded", "{done}");
    done["result"].as_str().unwrap().to_string()
}

/// Every layer of world `w`: a native, two amplified and an instance zoom, plus its features.
fn paths(w: &str) -> Vec<String> {
    let mut out = Vec::new();
    for z in [8u8, 10, 12] {
        let (x, y) = tile_of(74.6, 42.55, z);
        let t = format!("{z}/{x}/{y}");
        for p in [
            format!("elevation/{t}.png"),
            format!("elevation/{t}.png?encoding=mapbox"),
            format!("elevation/{t}@2x.png"),
            format!("elevation/{t}.exr"),
            format!("hillshade/{t}.png"),
            format!("color/{t}.png"),
            format!("splat/{t}.png?set=0"),
            format!("splat/{t}.png?set=1"),
            format!("vegetation/{t}.png"),
            format!("vegetation/{t}.exr"),
            format!("drainage/{t}.png"),
            format!("drainage/{t}.exr"),
            format!("contours/{t}.mvt"),
        ] {
            out.push(format!("/tiles/{w}/{p}"));
        }
    }
    let (x, y) = tile_of(74.6, 42.55, 14);
    out.push(format!("/tiles/{w}/instances/14/{x}/{y}.mvt"));
    out.push(format!("/tiles/{w}/instances/14/{x}/{y}.json"));
    out.push(format!("/tiles/{w}/elevation/16/{}/{}.exr", x * 4, y * 4));
    out
}

fn fetch_all(server: &Server, paths: &[String]) -> Vec<Vec<u8>> {
    paths
        .iter()
        .map(|p| {
            let (st, body) = get(server, p, None);
            assert_eq!(st, 200, "{p}: {}", String::from_utf8_lossy(&body));
            body
        })
        .collect()
}

/// The first channel of a PNG (grey or RGB[A]) as bytes.
fn grey(bytes: &[u8]) -> Array2<u8> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let n = info.color_type.samples();
    let (h, w) = (info.height as usize, info.width as usize);
    Array2::from_shape_fn((h, w), |(r, c)| buf[(r * w + c) * n])
}

fn write_grey_png(path: &Path, img: &Array2<u8>) {
    let f = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(f, img.ncols() as u32, img.nrows() as u32);
    enc.set_color(png::ColorType::Grayscale);
    let mut w = enc.write_header().unwrap();
    w.write_image_data(img.as_slice().unwrap()).unwrap();
}

/// A 3×3 block of zoom `z` around (74.6°E, 42.55°N) of world `w`: the elevation mosaic from the
/// served EXR tiles, and the hillshade mosaic written to `CARGO_TARGET_TMPDIR`.
fn block(server: &Server, w: &str, z: u8) -> Array2<f32> {
    let (cx, cy) = tile_of(74.6, 42.55, z);
    let tile = |kind: &str, dx: u32, dy: u32| {
        let p = format!("/tiles/{w}/{kind}/{z}/{}/{}", cx + dx - 1, cy + dy - 1);
        let p = format!("{p}.{}", if kind == "elevation" { "exr" } else { "png" });
        let (st, body) = get(server, &p, None);
        assert_eq!(st, 200, "{p}");
        body
    };
    let shade: Vec<Array2<u8>> = (0..9)
        .map(|i| grey(&tile("hillshade", i % 3, i / 3)))
        .collect();
    let picture = Array2::from_shape_fn((768, 768), |(r, c)| {
        shade[(r / 256) * 3 + c / 256][[r % 256, c % 256]]
    });
    let out =
        Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("gradient-hillshade-{w}-z{z}.png"));
    write_grey_png(&out, &picture);
    mosaic_of(3, |dx, dy| {
        decode_float_exr(&tile("elevation", dx, dy))
            .unwrap()
            .remove(0)
            .1
    })
}

/// Mean |step| across the lines `≡ 0 (mod period)` of a mosaic that are not tile borders, and
/// across every other line.
fn lattice_steps(m: &Array2<f32>, period: usize) -> (f64, f64) {
    let (mut on, mut n_on, mut off, mut n_off) = (0.0, 0usize, 0.0, 0usize);
    let mut add = |line: usize, d: f32| {
        if line % 256 == 0 {
            return;
        }
        if line % period == 0 {
            on += f64::from(d.abs());
            n_on += 1;
        } else {
            off += f64::from(d.abs());
            n_off += 1;
        }
    };
    for r in 0..m.nrows() {
        for c in 0..m.ncols() - 1 {
            add(c + 1, m[[r, c + 1]] - m[[r, c]]);
        }
    }
    for r in 0..m.nrows() - 1 {
        for c in 0..m.ncols() {
            add(r + 1, m[[r + 1, c]] - m[[r, c]]);
        }
    }
    (on / n_on as f64, off / n_off as f64)
}

#[test]
fn gradient_worlds_serve_every_layer_the_same_from_two_processes_and_seamlessly() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let a = serve(dir.path());
    let (st, info) = get(&a, "/worlds/gts", None);
    assert_eq!(st, 200);
    let gts_dict = json(&info)["dictionaries"][0]
        .as_str()
        .unwrap_or("")
        .to_string();

    // The default base through the admin API, and a gradient tile set built from it.
    let base_tif = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/data/tienshan_west_gebco15s.tif"),
    )
    .unwrap();
    let base = upload(&a, "tienshan", &base_tif);
    let small = upload(&a, "alatoo", &tiff(&tienshan_crop(1600, 600, 128, 1)));

    // Bad parameters: 422 naming the field; nothing is stored and no job is queued.
    let files = store_files(&store);
    let jobs = json(&get(&a, "/admin/jobs", Some(TOKEN)).1);
    for (extra, needle) in [
        (
            serde_json::json!({"tile": 6}),
            "tile 6 must be a multiple of 4",
        ),
        (
            serde_json::json!({"tile": 20}),
            "tile 20 must be a multiple of 4",
        ),
        (
            serde_json::json!({"colours": 1}),
            "colours 1 must be between 2",
        ),
        (
            serde_json::json!({"alternatives": 0}),
            "alternatives 0 must be between 1",
        ),
        (
            serde_json::json!({"mixing": 1.5}),
            "mixing 1.5 must lie in [0, 1]",
        ),
        (
            serde_json::json!({"atoms": 64}),
            "atoms is a dictionary parameter",
        ),
        (
            serde_json::json!({"kind": "poisson"}),
            "kind `poisson` must be",
        ),
    ] {
        let mut body = serde_json::json!({"name": "bad", "exemplars": [base], "kind": "gradient"});
        for (k, v) in extra.as_object().unwrap() {
            body[k] = v.clone();
        }
        let (st, problem) = post_json(&a, "/admin/dictionaries", body);
        assert_eq!(st, 422, "{extra}: {problem}");
        let detail = problem["detail"].as_str().unwrap_or_default();
        assert!(detail.contains(needle), "{extra}: {problem}");
    }
    let (st, problem) = post_json(
        &a,
        "/admin/dictionaries",
        serde_json::json!({"name": "bad", "exemplars": [base], "tile": 8}),
    );
    assert_eq!(st, 422, "{problem}");
    assert!(problem["detail"]
        .as_str()
        .unwrap()
        .contains("give \"kind\": \"gradient\""));
    assert_eq!(store_files(&store), files);
    assert_eq!(json(&get(&a, "/admin/jobs", Some(TOKEN)).1), jobs);

    let grad = build(
        &a,
        serde_json::json!({"name": "tienshan-gradient", "exemplars": [base], "kind": "gradient",
            "tile": 8, "colours": 4, "alternatives": 4, "mixing": 0.25}),
    );
    let (st, d) = get(&a, &format!("/dictionaries/{grad}"), None);
    assert_eq!(st, 200);
    let d = json(&d);
    assert_eq!(d["kind"], "gradient", "{d}");
    assert_eq!(
        (
            d["gradient"]["tile"].as_u64(),
            d["gradient"]["colours"].as_u64()
        ),
        (Some(8), Some(4))
    );
    // The same exemplar and parameters as the world file's band (whose seed is the world file's
    // default, 1, where the API's default is the tile sets' own): a different file.
    assert!(!gts_dict.is_empty() && gts_dict != grad);
    let dict = build(
        &a,
        serde_json::json!({"name": "tiny", "exemplars": [small], "atoms": 8, "patch": 8,
            "stride": 16, "learning": "medoids:1"}),
    );

    // A file of the other kind than the entry's amplifier: 422, nothing stored.
    let files = store_files(&store);
    for (entry, needle) in [
        (
            serde_json::json!(grad),
            "is a gradient tile set, but the amplifier is \"dictionary\"",
        ),
        (
            serde_json::json!({"id": dict, "amplifier": "gradient"}),
            "is a dictionary, but the amplifier is \"gradient\"",
        ),
        (
            serde_json::json!({"id": grad, "amplifier": "fourier"}),
            "unknown variant `fourier`",
        ),
    ] {
        let (st, problem) = post_json(
            &a,
            "/admin/worlds",
            serde_json::json!({"name": "wrong", "base": base, "dictionaries": [entry]}),
        );
        assert_eq!(st, 422, "{entry}: {problem}");
        assert!(
            problem["detail"]
                .as_str()
                .unwrap_or_default()
                .contains(needle),
            "{entry}: {problem}"
        );
    }
    assert_eq!(store_files(&store), files);

    let (st, created) = post_json(
        &a,
        "/admin/worlds",
        serde_json::json!({"name": "gapi", "base": base,
            "dictionaries": [{"id": grad, "amplifier": "gradient"}]}),
    );
    assert_eq!(st, 201, "{created}");

    // Every layer of both worlds, then the features of the world file's world.
    let all: Vec<String> = paths("gts").into_iter().chain(paths("gapi")).collect();
    let first = fetch_all(&a, &all);
    let features = fetch_all(&a, &["/worlds/gts/features.geojson".to_string()]);
    assert!(json(&features[0])["features"]
        .as_array()
        .is_some_and(|f| !f.is_empty()));
    // Plausible terrain: the zoom-12 tile over the Kyrgyz Ala-Too.
    let h = decode_terrarium_png(&first[26]).unwrap();
    let (lo, hi) = h
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, u), &v| (l.min(v), u.max(v)));
    assert!(
        lo > 500.0 && hi < 5500.0 && hi - lo > 300.0,
        "{} {lo}..{hi}",
        all[26]
    );

    // Seamless blocks of served tiles at an amplified zoom, and the hillshade pictures.
    for w in ["gts", "gapi"] {
        for z in [11u8, 12] {
            let m = block(&a, w, z);
            let (border, inner) = border_and_interior_steps(&m);
            // Tile borders lie on every lattice of the amplifier's levels (blocks and tiles of
            // 8 px at each level, 64 px after three levels), where steps are larger than on
            // average: compare them with the steps on the same lattice lines inside the tiles.
            let (on_lattice, _) = lattice_steps(&m, 64);
            assert!(
                border <= 1.1 * on_lattice,
                "{w} z{z}: border step {border} vs {on_lattice} on the lattice lines inside"
            );
            assert!(
                border <= 1.5 * inner,
                "{w} z{z}: border step {border} vs interior {inner}"
            );
        }
    }
    a.kill();

    // A second process on the same store: the zoom-12 tile first, computed alone (nothing
    // around it cached), then everything in reverse order: the same bytes.
    let b = serve(dir.path());
    let alone = fetch_all(&b, &all[26..27]);
    assert!(alone[0] == first[26], "{}: a tile alone differs", all[26]);
    let mut again: Vec<Vec<u8>> = fetch_all(&b, &all.iter().rev().cloned().collect::<Vec<_>>());
    again.reverse();
    for ((p, x), y) in all.iter().zip(&first).zip(&again) {
        assert!(x == y, "{p} differs between processes");
    }
    // A 512-px tile of zoom 11 is the window of zoom 12 its four tiles cover.
    let (x, y) = tile_of(74.6, 42.55, 11);
    for w in ["gts", "gapi"] {
        let big = decode_terrarium_png(
            &fetch_all(&b, &[format!("/tiles/{w}/elevation/11/{x}/{y}@2x.png")])[0],
        )
        .unwrap();
        let quad = mosaic_of(2, |dx, dy| {
            let p = format!("/tiles/{w}/elevation/12/{}/{}.png", 2 * x + dx, 2 * y + dy);
            decode_terrarium_png(&fetch_all(&b, &[p])[0]).unwrap()
        });
        assert!(
            big == quad,
            "{w}: the 512-px tile is not the window of its four tiles"
        );
    }
    let features = fetch_all(&b, &["/worlds/gapi/features.geojson".to_string()]);
    assert!(json(&features[0])["features"]
        .as_array()
        .is_some_and(|f| !f.is_empty()));
}
