//! Land-cover classes (#15, acceptance 3 and 5): a world with a class raster gives splat weights
//! that follow the classes, pixel by pixel (expected values worked by hand from the smoothstep
//! of the class weight's box average); and through the real binary, bad control rasters (a class
//! raster off the base's grid, a legend missing a raster value, a material naming an unknown
//! class, HSV ranges out of range, an exemplar without the layer) are 422 problem+json naming
//! the problem and store nothing, while good ones (a class raster with a legend, an RGB image
//! with HSV ranges, both uploaded through the exemplar endpoint) make worlds whose splat tiles
//! are served.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use ndarray::Array2;

use terrasynth_core::landscape::{ClassesConfig, LandscapeConfig};
use terrasynth_core::raster::{Crs, Georef, Grid};
use terrasynth_tiles::{pixel_size_m, World, WorldClasses};

use terrasynth_test_support::process::{get, json, post};
use terrasynth_test_support::{small_dictionary_with_vegetation, store_files, synthetic_terrain};

use crate::admin_e2e::{tienshan_crop, tiff, upload, wait_until, TOKEN};
use crate::support::start;

const Z: u8 = 8;
const TX: u32 = 180;
const TY: u32 = 100;

/// Two materials that follow the classes: `meadow` the smoothstep of the `grass` weight,
/// `scree` that of the `rock` weight (range (0, 2) with falloff 1: `t²(3 − 2t)` on (0, 1]).
fn class_landscape() -> LandscapeConfig {
    let toml = r#"
        [[materials]]
        name = "meadow"
        colour = [60, 160, 60]
        class.grass = { min = 0.0, max = 2.0, falloff = 1.0 }
        [[materials]]
        name = "scree"
        colour = [140, 140, 140]
        class.rock = { min = 0.0, max = 2.0, falloff = 1.0 }
        [[species]]
        name = "sward"
        class.grass = { min = 0.5, max = 1.0 }
    "#;
    toml::from_str(toml).unwrap()
}

/// A world whose 256 × 256 EPSG:3857 base is exactly tile `(TX, TY)` of zoom `Z` (so a native
/// tile pixel is a base cell), with a class raster: value 10 (`grass`) west of column 128, 20
/// (`rock`) from it on.
fn class_world(smoothing_m: f32) -> Result<World, terrasynth_tiles::TileError> {
    class_world_with(
        smoothing_m,
        small_dictionary_with_vegetation(2),
        Default::default(),
    )
}

/// [`class_world`] with its dictionary and matching weights.
fn class_world_with(
    smoothing_m: f32,
    dictionary: std::sync::Arc<terrasynth_core::dictionary::Dictionary>,
    weights: terrasynth_core::dictionary::MatchWeights,
) -> Result<World, terrasynth_tiles::TileError> {
    let m = pixel_size_m(Z);
    let half = PI * 6_378_137.0;
    let georef = Georef {
        crs: Crs::Epsg3857,
        west: -half + f64::from(TX * 256) * m,
        north: half - f64::from(TY * 256) * m,
        pixel_width: m,
        pixel_height: m,
    };
    let base = Grid::new(synthetic_terrain(256, 256, 3) + 1000.0, georef);
    let raster = Grid::new(
        Array2::from_shape_fn((256, 256), |(_, c)| if c < 128 { 10.0 } else { 20.0 }),
        georef,
    );
    let legend: BTreeMap<String, String> = [("10", "grass"), ("20", "rock")]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    World::new(terrasynth_tiles::WorldParts {
        name: "classes".into(),
        title: "Classes".into(),
        attribution: "synthetic".into(),
        base,
        z_base: Some(Z),
        max_zoom: 10,
        fill_m: 0.0,
        dictionaries: vec![terrasynth_tiles::DictionaryBand::every_zoom(
            dictionary, "d",
        )],
        weights,
        cache_bytes: 128 << 20,
        landscape: class_landscape(),
        center: None,
        sparsity: None,
        water: Default::default(),
        biomes: Vec::new(),
        controls: Vec::new(),
        classes: Some(WorldClasses {
            config: ClassesConfig {
                legend,
                smoothing_m,
                ..Default::default()
            },
            raster,
        }),
    })
}

#[test]
fn splat_weights_follow_the_class_raster_pixel_by_pixel() {
    // Sharp classes: meadow 1 west of column 128, scree 1 from it on, `water` 0.
    let world = class_world(0.0).unwrap();
    let w = &world.material_tile(Z, TX, TY).unwrap().weights;
    assert_eq!(w.len(), 3, "meadow, scree, water");
    for ((r, c), &v) in w[0].indexed_iter() {
        let want = if c < 128 { 1.0 } else { 0.0 };
        assert!((v - want).abs() < 1e-4, "meadow ({r}, {c}): {v}");
        assert!(
            (w[1][[r, c]] - (1.0 - want)).abs() < 1e-4,
            "scree ({r}, {c})"
        );
        assert_eq!(w[2][[r, c]], 0.0);
    }
    // Smoothed over 2,000 m: the base's cells are 611.5 m · cos(36.6°) ≈ 491 m at this tile's
    // latitude (Mercator y of row 25,600 of zoom 8), so r = round(2000 / 982) = 2 cells: the
    // grass weight is the share of grass cells in a 5-cell box: 1, 0.8, 0.6, 0.4, 0.2, 0 at
    // columns 125–130. Meadow = s(g) with s(t) = t²(3 − 2t), scree = s(1 − g) = 1 − s(g), so
    // the normalised weights are s(g): 1, 0.896, 0.648, 0.352, 0.104, 0.
    let world = class_world(2000.0).unwrap();
    let w = &world.material_tile(Z, TX, TY).unwrap().weights;
    let want = [
        (120, 1.0f32),
        (125, 1.0),
        (126, 0.896),
        (127, 0.648),
        (128, 0.352),
        (129, 0.104),
        (130, 0.0),
        (200, 0.0),
    ];
    for r in [3usize, 100, 250] {
        for (c, m) in want {
            let (got, scree) = (w[0][[r, c]], w[1][[r, c]]);
            assert!((got - m).abs() < 1e-3, "meadow ({r}, {c}): {got}, want {m}");
            assert!(
                (scree - (1.0 - m)).abs() < 1e-3,
                "scree ({r}, {c}): {scree}"
            );
        }
    }
    // The served splat PNG carries them: byte 0 (meadow) 255 in the west, byte 1 (scree) 255
    // in the east.
    let req = terrasynth_tiles::parse_request(
        world.name(),
        "splat",
        &Z.to_string(),
        &TX.to_string(),
        &format!("{TY}.png"),
        &std::collections::HashMap::new(),
    )
    .unwrap();
    let bytes = terrasynth_tiles::render(&world, &req).unwrap();
    let (_, cols, px) = crate::support::decode_rgba(&bytes);
    assert_eq!(px[(10 * cols + 10) * 4..][..2], [255, 0]);
    assert_eq!(px[(10 * cols + 200) * 4..][..2], [0, 255]);
}

#[test]
fn species_densities_follow_the_classes() {
    // `sward` admits grass weights in [0.5, 1] and nothing else constrains it: its suitability
    // is 1 west of column 128 and 0 from it on, so its density is 0 on the east half at the
    // native zoom and on every amplified tile there, and at least the clustering floor (the
    // share of suitability kept whatever the seeding) on the west half at the native zoom.
    let world = class_world(0.0).unwrap();
    let floor = world.landscape().clustering.floor;
    let v = world.vegetation_tile(Z, TX, TY).unwrap();
    for ((r, c), &d) in v[0].indexed_iter() {
        if c < 128 {
            assert!(d >= floor - 1e-6, "west ({r}, {c}): {d}");
        } else {
            assert_eq!(d, 0.0, "east ({r}, {c})");
        }
    }
    // Zoom 9: the east child tiles of the base tile, away from the border.
    for (x, y) in [(2 * TX + 1, 2 * TY), (2 * TX + 1, 2 * TY + 1)] {
        let v = world.vegetation_tile(Z + 1, x, y).unwrap();
        for ((r, c), &d) in v[0].indexed_iter() {
            if c >= 8 {
                assert_eq!(d, 0.0, "zoom 9 ({x}, {y}) pixel ({r}, {c})");
            }
        }
    }
}

/// A dictionary built from synthetic terrain whose west half is class 10 and east half class
/// 20, with those class layers (`classes_10`, `classes_20`, group `classes`).
fn class_dictionary() -> std::sync::Arc<terrasynth_core::dictionary::Dictionary> {
    use terrasynth_core::dictionary::{build, BuildOptions, Exemplar, Learning};
    use terrasynth_core::landscape::classes::class_layers;
    let n = 96;
    let raster = Array2::from_shape_fn((n, n), |(_, c)| if c < n / 2 { 10.0f32 } else { 20.0 });
    let ex = Exemplar {
        elevation: synthetic_terrain(n, n, 7),
        valid: None,
        cell_m: 30.0,
        layers: class_layers("classes", &raster, &[10, 20]),
    };
    let opts = BuildOptions {
        patch: 8,
        stride: 4,
        atoms: 32,
        learning: Learning::Medoids { iterations: 2 },
        seed: 3,
        sparsity: 1,
    };
    std::sync::Arc::new(build(&[ex], &opts, &mut |_, _| {}).unwrap())
}

#[test]
fn a_world_weighing_classes_feeds_them_to_the_matching_seamlessly() {
    let dict = class_dictionary();
    let elevation_only = terrasynth_core::dictionary::MatchWeights {
        elevation: 1.0,
        altitude: 0.0,
        slope: 0.0,
        layers: Vec::new(),
    };
    let with_classes = terrasynth_core::dictionary::MatchWeights {
        layers: vec![("classes".into(), 1.0)],
        ..elevation_only.clone()
    };
    let w0 = class_world_with(0.0, dict.clone(), elevation_only).unwrap();
    let w1 = class_world_with(0.0, dict.clone(), with_classes.clone()).unwrap();
    let z = Z + 1;
    // The class term changes the matches, hence the amplified elevation.
    let (x, y) = (2 * TX, 2 * TY + 1);
    let a = w0.elevation_tile(z, x, y).unwrap();
    let b = w1.elevation_tile(z, x, y).unwrap();
    let differ = a.iter().zip(b.iter()).filter(|(p, q)| p != q).count();
    assert!(differ > 1000, "{differ} pixels differ");
    // Still a window of one plane: a fresh world's 2 × 2 block holds the tile alone, bit for
    // bit, and the vegetation (the same matches) too.
    let fresh = class_world_with(0.0, dict, with_classes).unwrap();
    let block = terrasynth_core::synth::Window {
        col0: i64::from(x) * 256 - 256,
        row0: i64::from(y) * 256,
        cols: 512,
        rows: 512,
    };
    let big = fresh.elevation_window(z, block).unwrap();
    let part = big.slice(ndarray::s![0..256, 256..512]);
    assert!(part == *b, "the tile alone differs from the block's window");
    let veg_alone = w1.vegetation_tile(z, x, y).unwrap();
    let veg_big = fresh.vegetation_window(z, block).unwrap();
    assert!(veg_big[0].slice(ndarray::s![0..256, 256..512]) == veg_alone[0]);
}

#[test]
fn a_smoothing_distance_beyond_64_cells_is_refused_by_name() {
    // 100 km over ≈ 491 m cells is ≈ 102 cells each way.
    let e = class_world(1e5).unwrap_err().to_string();
    assert!(e.contains("smoothing_m"), "{e}");
}

/// A multipart upload: `(part, content type, bytes)`.
fn upload_parts(
    server: &crate::support::Server,
    name: &str,
    parts: &[(&str, &str, Vec<u8>)],
) -> String {
    let boundary = "terrasynth-classes-boundary";
    let mut body = Vec::new();
    for (part, ct, bytes) in parts {
        body.extend_from_slice(
            format!(
                "--{boundary}\r\nContent-Disposition: form-data; name=\"{part}\"; filename=\"{part}\"\r\nContent-Type: {ct}\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    let (st, out) = post(
        server,
        &format!("/admin/exemplars?name={name}"),
        TOKEN,
        &format!("multipart/form-data; boundary={boundary}"),
        &body,
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&out));
    json(&out)["id"].as_str().unwrap().to_string()
}

/// A multipart upload that must be refused: its status and problem detail.
fn refused_upload(
    server: &crate::support::Server,
    parts: &[(&str, &str, Vec<u8>)],
) -> (u16, String) {
    let boundary = "terrasynth-classes-boundary";
    let mut body = Vec::new();
    for (part, ct, bytes) in parts {
        body.extend_from_slice(
            format!(
                "--{boundary}\r\nContent-Disposition: form-data; name=\"{part}\"; filename=\"{part}\"\r\nContent-Type: {ct}\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    let (st, out) = post(
        server,
        "/admin/exemplars?name=bad",
        TOKEN,
        &format!("multipart/form-data; boundary={boundary}"),
        &body,
    );
    let problem = json(&out);
    assert_eq!(problem["status"], st, "{problem}");
    (
        st,
        problem["detail"].as_str().unwrap_or_default().to_string(),
    )
}

/// An 8-bit RGB PNG of `rows × cols` pixels.
fn rgb_png(rows: usize, cols: usize, px: impl Fn(usize, usize) -> [u8; 3]) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, cols as u32, rows as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        let mut data = Vec::with_capacity(rows * cols * 3);
        for r in 0..rows {
            for c in 0..cols {
                data.extend_from_slice(&px(r, c));
            }
        }
        w.write_image_data(&data).unwrap();
    }
    out
}

#[test]
fn bad_control_rasters_are_422_naming_the_problem_and_store_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let cfg = dir.path().join("server.toml");
    std::fs::write(&cfg, "worlds = []\nbuild_queue = 4\n").unwrap();
    let server = start(
        &["--config", &cfg.display().to_string()],
        &[("TERRASYNTH_ADMIN_TOKEN", TOKEN)],
        &store,
    );
    // A small dictionary to make worlds with.
    let ex = upload(&server, "alatoo", &tiff(&tienshan_crop(1600, 600, 128, 1)));
    let (st, body) = post(
        &server,
        "/admin/dictionaries",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "alatoo", "exemplars": [ex], "atoms": 16, "patch": 16,
            "stride": 8, "learning": "medoids:1", "seed": 5})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 202, "{}", String::from_utf8_lossy(&body));
    let job = json(&body)["id"].as_str().unwrap().to_string();
    let done = wait_until(&server, &job, |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(done["state"], "succeeded", "{done}");
    let dict = done["result"].as_str().unwrap().to_string();

    // A 64 × 64 base with a class raster (1 west, 2 east) and an RGB image (green west, grey
    // east) on its grid, uploaded as `classes` and `rgb` parts.
    let base = tienshan_crop(1700, 700, 256, 4);
    let classes = Grid::new(
        Array2::from_shape_fn((64, 64), |(_, c)| if c < 32 { 1.0 } else { 2.0 }),
        base.georef,
    );
    let rgb = rgb_png(64, 64, |_, c| {
        if c < 32 {
            [30, 100, 40]
        } else {
            [150, 150, 150]
        }
    });
    let with_layers = upload_parts(
        &server,
        "coarse",
        &[
            ("elevation", "image/tiff", tiff(&base)),
            ("classes", "image/tiff", tiff(&classes)),
            ("rgb", "image/png", rgb),
        ],
    );
    // The same place without layers, and a class raster on another grid (32 × 32).
    let plain = upload(&server, "plain", &tiff(&base));
    let small = tienshan_crop(1700, 700, 128, 4);
    let small_classes = Grid::new(Array2::from_elem((32, 32), 1.0), small.georef);
    let off_grid = upload_parts(
        &server,
        "small",
        &[
            ("elevation", "image/tiff", tiff(&small)),
            ("classes", "image/tiff", tiff(&small_classes)),
        ],
    );

    // Control rasters that do not fit are refused at upload, naming the part, storing nothing:
    // an RGB image or a class raster of another size, an RGB image that is no 8-bit RGB PNG.
    let before = store_files(&store);
    let elevation = ("elevation", "image/tiff", tiff(&base));
    for (parts, status, needle) in [
        (
            vec![
                elevation.clone(),
                ("rgb", "image/png", rgb_png(32, 32, |_, _| [1, 2, 3])),
            ],
            422,
            "layer `rgb` is 32×32",
        ),
        (
            vec![
                elevation.clone(),
                ("classes", "image/tiff", tiff(&small_classes)),
            ],
            422,
            "layer `classes` is 32×32",
        ),
        (
            vec![elevation.clone(), ("rgb", "image/tiff", tiff(&classes))],
            400,
            "8-bit RGB or RGBA PNG",
        ),
    ] {
        let (st, detail) = refused_upload(&server, &parts);
        assert_eq!(st, status, "{needle}: {detail}");
        assert!(detail.contains(needle), "{needle}: {detail}");
        assert_eq!(store_files(&store), before, "{needle} wrote to the store");
    }

    let legend = serde_json::json!({"1": "forest", "2": "rock"});
    let materials = serde_json::json!([
        {"name": "woods", "colour": [30, 110, 40], "class": {"forest": {"min": 0.5, "max": 1.0}}},
        {"name": "stone", "colour": [150, 150, 150], "class": {"rock": {"min": 0.5, "max": 1.0}}}
    ]);
    let world =
        |name: &str, base: &str, classes: serde_json::Value, materials: &serde_json::Value| {
            serde_json::json!({"name": name, "base": base, "dictionaries": [dict], "max_zoom": 10,
            "classes": classes, "materials": materials})
        };
    let cases = [
        (
            "a class raster off the base's grid",
            world(
                "w1",
                &with_layers,
                serde_json::json!({"exemplar": off_grid, "legend": legend}),
                &materials,
            ),
            "base's grid",
        ),
        (
            "a legend missing a raster value",
            world(
                "w2",
                &with_layers,
                serde_json::json!({"legend": {"1": "forest"}}),
                &serde_json::json!([materials[0]]),
            ),
            "no entry for raster value 2",
        ),
        (
            "a material naming an unknown class",
            world(
                "w3",
                &with_layers,
                serde_json::json!({"legend": legend}),
                &serde_json::json!([{"name": "bog", "colour": [0, 0, 0],
                    "class": {"wetland": {"min": 0.5, "max": 1.0}}}]),
            ),
            "unknown class `wetland`",
        ),
        (
            "HSV ranges out of range",
            world(
                "w4",
                &with_layers,
                serde_json::json!({"hsv": [{"name": "forest",
                    "hsv": {"h": [70, 170], "s": [0.2, 1.5], "v": [0, 1]}}]}),
                &serde_json::json!([materials[0]]),
            ),
            "hsv.s",
        ),
        (
            "a hue out of range",
            world(
                "w5",
                &with_layers,
                serde_json::json!({"hsv": [{"name": "forest",
                    "hsv": {"h": [70, 400], "s": [0, 1], "v": [0, 1]}}]}),
                &serde_json::json!([materials[0]]),
            ),
            "hsv.h",
        ),
        (
            "an exemplar without the layer",
            world(
                "w6",
                &plain,
                serde_json::json!({"legend": legend}),
                &materials,
            ),
            "no `classes` layer",
        ),
        (
            "a legend key that is no raster value",
            world(
                "w7",
                &with_layers,
                serde_json::json!({"legend": {"one": "forest"}}),
                &serde_json::json!([materials[0]]),
            ),
            "`one`",
        ),
    ];
    let before = store_files(&store);
    for (what, request, needle) in &cases {
        let (st, body) = post(
            &server,
            "/admin/worlds",
            TOKEN,
            "application/json",
            request.to_string().as_bytes(),
        );
        assert_eq!(st, 422, "{what}: {}", String::from_utf8_lossy(&body));
        let problem = json(&body);
        assert_eq!(problem["status"], 422, "{what}");
        let detail = problem["detail"].as_str().unwrap();
        assert!(detail.contains(needle), "{what}: {detail}");
        assert_eq!(store_files(&store), before, "{what} wrote to the store");
    }
    let (_, h) = get(&server, "/worlds/w1", None);
    assert!(!String::from_utf8_lossy(&h).contains("\"w1\""));

    // Good control rasters make worlds whose splat tiles follow the classes.
    let (st, body) = post(
        &server,
        "/admin/worlds",
        TOKEN,
        "application/json",
        world(
            "legend",
            &with_layers,
            serde_json::json!({"legend": legend}),
            &materials,
        )
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let hsv = serde_json::json!({"hsv": [
        {"name": "forest", "hsv": {"h": [70, 170], "s": [0.2, 1], "v": [0, 0.6]}},
        {"name": "rock", "hsv": {"h": [0, 360], "s": [0, 0.1], "v": [0.3, 1]}}
    ], "smoothing_m": 2000});
    let (st, body) = post(
        &server,
        "/admin/worlds",
        TOKEN,
        "application/json",
        world("satellite", &with_layers, hsv, &materials)
            .to_string()
            .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    // A dictionary built from the exemplar with the class raster carries it as class layers
    // (one per raster value, matched as the group `classes`); the `rgb` layer is left out.
    let (st, body) = post(
        &server,
        "/admin/dictionaries",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "classy", "exemplars": [with_layers], "atoms": 8, "patch": 16,
            "stride": 8, "learning": "medoids:1", "seed": 5})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 202, "{}", String::from_utf8_lossy(&body));
    let job = json(&body)["id"].as_str().unwrap().to_string();
    let done = wait_until(&server, &job, |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(done["state"], "succeeded", "{done}");
    let id = done["result"].as_str().unwrap();
    let (st, d) = get(&server, &format!("/dictionaries/{id}"), None);
    assert_eq!(st, 200);
    let layers: Vec<String> = json(&d)["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap().to_string())
        .collect();
    assert!(
        layers.contains(&"classes_1".to_string()) && layers.contains(&"classes_2".to_string()),
        "{layers:?}"
    );
    assert!(
        !layers.iter().any(|l| l == "classes" || l == "rgb"),
        "{layers:?}"
    );
    // A world weighing the class term with that dictionary: made and served.
    let (st, body) = post(
        &server,
        "/admin/worlds",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "matched", "base": with_layers, "dictionaries": [id],
            "max_zoom": 10, "classes": {"legend": legend}, "materials": materials,
            "weights": {"elevation": 1.0, "classes": 1.0}})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let (st, info) = get(&server, "/worlds/matched", None);
    assert_eq!(st, 200);
    let info = json(&info);
    let z = info["native_zoom"].as_u64().unwrap() as u8 + 1;
    let [w, s, e, n] = [0, 1, 2, 3].map(|i| info["bounds"][i].as_f64().unwrap());
    let (x, y) = terrasynth_test_support::tile_of(0.5 * (w + e), 0.5 * (s + n), z);
    let (st, _) = get(
        &server,
        &format!("/tiles/matched/elevation/{z}/{x}/{y}.png"),
        None,
    );
    assert_eq!(st, 200);
    // An exemplar holding a world's classes cannot be deleted while the world exists.
    let holder = upload_parts(
        &server,
        "holder",
        &[
            ("elevation", "image/tiff", tiff(&base)),
            ("classes", "image/tiff", tiff(&classes)),
        ],
    );
    let (st, body) = post(
        &server,
        "/admin/worlds",
        TOKEN,
        "application/json",
        world(
            "apart",
            &plain,
            serde_json::json!({"exemplar": holder, "legend": legend}),
            &materials,
        )
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let (st, body) = terrasynth_test_support::process::delete(
        &server,
        &format!("/admin/exemplars/{holder}"),
        TOKEN,
    );
    assert_eq!(st, 409, "{}", String::from_utf8_lossy(&body));
    assert!(String::from_utf8_lossy(&body).contains("classes of world"));
    for name in ["legend", "satellite"] {
        let (st, info) = get(&server, &format!("/worlds/{name}"), None);
        assert_eq!(st, 200);
        let info = json(&info);
        let native = info["native_zoom"].as_u64().unwrap() as u8;
        let [w, s, e, n] = [0, 1, 2, 3].map(|i| info["bounds"][i].as_f64().unwrap());
        // A point well inside the west (forest) half and one inside the east (rock) half.
        for (lon, want_woods) in [(w + 0.15 * (e - w), 255u8), (w + 0.85 * (e - w), 0)] {
            let lat = 0.5 * (s + n);
            let (x, y) = terrasynth_test_support::tile_of(lon, lat, native);
            let (st, png) = get(
                &server,
                &format!("/tiles/{name}/splat/{native}/{x}/{y}.png"),
                None,
            );
            assert_eq!(st, 200, "{name}");
            let (_, cols, px) = crate::support::decode_rgba(&png);
            let (fx, fy) = terrasynth_tiles::lonlat_to_global_pixel(native, lon, lat);
            let (c, r) = (
                fx as usize - x as usize * 256,
                fy as usize - y as usize * 256,
            );
            assert_eq!(
                px[(r * cols + c) * 4],
                want_woods,
                "{name} woods at {lon}, {lat}"
            );
            assert_eq!(
                px[(r * cols + c) * 4 + 1],
                255 - want_woods,
                "{name} stone at {lon}, {lat}"
            );
        }
    }
}
