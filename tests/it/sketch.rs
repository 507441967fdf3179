//! Feature extraction and sketch synthesis (issue #18) from the outside: `terrasynth features`
//! and `terrasynth sketch` run as real processes on a crop of the committed Tien Shan grid (the
//! GeoJSON they write, the grid they make, the same bytes from two runs, bad sketches refused
//! with a message and no output); and a sketched base served as a world gives window-invariant
//! tiles.

use std::path::Path;
use std::process::Command;

use serde_json::{json, Value};
use terrasynth_core::raster::{read_geotiff_file, ReadLimits};

const TIENSHAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/config/data/tienshan_west_gebco15s.tif"
);

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_terrasynth"))
}

fn run(cmd: &mut Command) -> (bool, String, String) {
    let out = cmd.output().expect("run terrasynth");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn run_ok(cmd: &mut Command) -> String {
    let (ok, stdout, stderr) = run(cmd);
    assert!(ok, "terrasynth failed: {stdout}\n{stderr}");
    stdout
}

/// Crops `window` (`COL,ROW,W,H`) of the committed Tien Shan grid into `out`.
fn crop(window: &str, out: &Path) {
    run_ok(
        bin()
            .args(["crop", "--input", TIENSHAN, "--window", window, "--output"])
            .arg(out),
    );
}

/// A sketch on the 96 × 96 grid of bounds 70,42,70.4,42.4 at 1/240°: a ridge across the
/// middle with a spur, a valley on each side.
fn test_sketch() -> Value {
    let line = |kind: &str, pts: &[[f64; 2]]| {
        json!({"type": "Feature", "properties": {"kind": kind},
               "geometry": {"type": "LineString", "coordinates": pts}})
    };
    json!({"type": "FeatureCollection", "features": [
        line("ridge", &[[70.04, 42.2], [70.2, 42.22], [70.36, 42.19]]),
        line("ridge", &[[70.2, 42.22], [70.24, 42.34]]),
        line("valley", &[[70.04, 42.07], [70.2, 42.09], [70.36, 42.06]]),
        line("valley", &[[70.05, 42.34], [70.15, 42.3]]),
    ]})
}

const BOUNDS: &str = "70,42,70.4,42.4";
const CELL: &str = "0.004166666666666667";

#[test]
fn features_writes_ridge_and_valley_lines_in_lonlat() {
    let dir = tempfile::tempdir().unwrap();
    let dem = dir.path().join("dem.tif");
    // The Chatkal range: columns 900–1155, rows 1300–1555.
    crop("900,1300,256,256", &dem);
    let all = dir.path().join("all.geojson");
    let report = run_ok(
        bin()
            .args(["features", "--check", "--input"])
            .arg(&dem)
            .arg("--output")
            .arg(&all),
    );
    // --check prints the drainage agreement as JSON.
    let check: Value = serde_json::from_str(&report).unwrap();
    assert!(check["channel_cells"].as_u64().unwrap() > 1000, "{check}");
    assert!(
        check["channels_near_valleys"].as_f64().unwrap() >= 0.8,
        "{check}"
    );
    assert!(
        check["ridges_separating_basins"].as_f64().unwrap() >= 0.8,
        "{check}"
    );

    let grid = read_geotiff_file(&dem, &ReadLimits::default()).unwrap();
    let (west, north) = (grid.georef.west, grid.georef.north);
    let (east, south) = (west + 256.0 / 240.0, north - 256.0 / 240.0);
    let (lo, hi) = grid.min_max().unwrap();
    let fc: Value = serde_json::from_slice(&std::fs::read(&all).unwrap()).unwrap();
    assert_eq!(fc["type"], "FeatureCollection");
    let features = fc["features"].as_array().unwrap();
    let mut kinds = std::collections::BTreeMap::new();
    for f in features {
        assert_eq!(f["geometry"]["type"], "LineString");
        let kind = f["properties"]["kind"].as_str().unwrap().to_string();
        assert!(kind == "ridge" || kind == "valley", "{kind}");
        *kinds.entry(kind).or_insert(0usize) += 1;
        let h = f["properties"]["mean_elevation_m"].as_f64().unwrap();
        assert!(h >= f64::from(lo) - 0.1 && h <= f64::from(hi) + 0.1, "{h}");
        let coords = f["geometry"]["coordinates"].as_array().unwrap();
        assert!(coords.len() >= 2);
        for p in coords {
            let (lon, lat) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
            assert!(
                lon > west && lon < east && lat > south && lat < north,
                "{p}"
            );
        }
    }
    assert!(kinds["ridge"] > 50 && kinds["valley"] > 50, "{kinds:?}");

    // --kind ridge writes exactly the ridges of the full file.
    let ridges = dir.path().join("ridges.geojson");
    run_ok(
        bin()
            .args(["features", "--kind", "ridge", "--input"])
            .arg(&dem)
            .arg("--output")
            .arg(&ridges),
    );
    let only: Value = serde_json::from_slice(&std::fs::read(&ridges).unwrap()).unwrap();
    let want: Vec<&Value> = features
        .iter()
        .filter(|f| f["properties"]["kind"] == "ridge")
        .collect();
    let got: Vec<&Value> = only["features"].as_array().unwrap().iter().collect();
    assert_eq!(got, want);
}

#[test]
fn sketch_makes_the_asked_grid_deterministically_and_refuses_bad_sketches() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    // The Talas and Kyrgyz ranges, columns 1600–1983, rows 600–983.
    crop("1600,600,384,384", &p("ex.tif"));
    std::fs::write(p("s.geojson"), test_sketch().to_string()).unwrap();
    let sketch = |out: &Path, seed: &str| {
        bin()
            .args(["sketch", "--exemplar"])
            .arg(p("ex.tif"))
            .arg("--sketch")
            .arg(p("s.geojson"))
            .args([
                "--bounds",
                BOUNDS,
                "--cell-size",
                CELL,
                "--seed",
                seed,
                "--output",
            ])
            .arg(out)
            .output()
            .unwrap()
    };
    let first = sketch(&p("a.tif"), "7");
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let summary: Value = serde_json::from_slice(&first.stdout).unwrap();
    assert_eq!(
        (summary["width"].as_u64(), summary["height"].as_u64()),
        (Some(96), Some(96))
    );
    assert!(
        summary["stats"]["feature_patches"].as_u64().unwrap() > 0,
        "{summary}"
    );
    assert!(
        summary["fidelity"]["ridge_to_ridge"].as_f64().unwrap() <= 3.0,
        "{summary}"
    );
    assert!(
        summary["fidelity"]["valley_to_valley"].as_f64().unwrap() <= 3.0,
        "{summary}"
    );

    let g = read_geotiff_file(&p("a.tif"), &ReadLimits::default()).unwrap();
    assert_eq!(g.data.dim(), (96, 96));
    assert!((g.georef.west - 70.0).abs() < 1e-9 && (g.georef.north - 42.4).abs() < 1e-9);
    assert!((g.georef.pixel_width - 1.0 / 240.0).abs() < 1e-12);
    assert!(g.data.iter().all(|v| v.is_finite()));
    // Real exemplar heights, not noise: within the exemplar's range widened by its relief.
    let ex = read_geotiff_file(&p("ex.tif"), &ReadLimits::default()).unwrap();
    let ((lo, hi), (elo, ehi)) = (g.min_max().unwrap(), ex.min_max().unwrap());
    assert!(
        lo > elo - (ehi - elo) && hi < ehi + (ehi - elo),
        "{lo}..{hi} vs {elo}..{ehi}"
    );

    // Same inputs, same bytes.
    assert!(sketch(&p("b.tif"), "7").status.success());
    let same = std::fs::read(p("a.tif")).unwrap() == std::fs::read(p("b.tif")).unwrap();
    assert!(same, "two runs wrote different files");

    // Bad sketches and bounds: exit 1 with a message naming the problem, no output.
    let outside = json!({"type": "Feature", "properties": {"kind": "ridge"},
        "geometry": {"type": "LineString", "coordinates": [[70.1, 42.1], [71.5, 42.2]]}});
    let no_kind = json!({"type": "Feature", "properties": {},
        "geometry": {"type": "LineString", "coordinates": [[70.1, 42.1], [70.3, 42.2]]}});
    let empty = json!({"type": "FeatureCollection", "features": []});
    let cases: Vec<(Value, &str, &str)> = vec![
        (outside, BOUNDS, "outside"),
        (no_kind, BOUNDS, "kind"),
        (empty, BOUNDS, "no ridge"),
        (test_sketch(), "70,42,90,62", "exceed"),
        (test_sketch(), "70.4,42,70,42.4", "west < east"),
    ];
    for (i, (s, bounds, needle)) in cases.into_iter().enumerate() {
        let file = p(&format!("bad{i}.geojson"));
        std::fs::write(&file, s.to_string()).unwrap();
        let out = p(&format!("bad{i}.tif"));
        let o = bin()
            .args(["sketch", "--exemplar"])
            .arg(p("ex.tif"))
            .arg("--sketch")
            .arg(&file)
            .args(["--bounds", bounds, "--cell-size", CELL, "--output"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "case {i}: {err}");
        assert!(err.contains(needle), "case {i}: {err}");
        assert!(!out.exists(), "case {i}");
    }
}

/// A sketched base serves like any world: an amplified tile computed alone equals, bit for bit,
/// the same window of its level computed over a 2 × 2 block of tiles in one call, at the native
/// zoom and two levels deeper.
#[test]
fn a_sketched_base_serves_window_invariant_tiles() {
    use ndarray::s;
    use terrasynth_core::dictionary::MatchWeights;
    use terrasynth_core::raster::{embedded, Grid};
    use terrasynth_core::synth::sketch::geojson::parse_sketch;
    use terrasynth_core::synth::sketch::{synthesize, OutputSpec, SizeLimits, SketchOptions};
    use terrasynth_core::synth::{Amplifier, Field, Window};
    use terrasynth_test_support::{mini_world, small_dictionary_with_vegetation, tile_of};

    // The mini world's grid: 256 × 256 cells of 15″ from 70°E 43°N.
    let cell = 1.0 / 240.0;
    let grid = OutputSpec {
        west: 70.0,
        south: 43.0 - 256.0 * cell,
        east: 70.0 + 256.0 * cell,
        north: 43.0,
        cell_deg: cell,
    }
    .grid(&SizeLimits::default())
    .unwrap();
    let sketch = json!({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"kind": "ridge"}, "geometry": {"type": "LineString",
            "coordinates": [[70.1, 42.5], [70.5, 42.55], [70.95, 42.45]]}},
        {"type": "Feature", "properties": {"kind": "valley"}, "geometry": {"type": "LineString",
            "coordinates": [[70.1, 42.2], [70.5, 42.25], [70.95, 42.15]]}},
    ]});
    let sketch = parse_sketch(&sketch, grid).unwrap();
    let g = embedded::tienshan().unwrap();
    let ex = Grid::new(
        g.data.slice(s![600..984, 1600..1984]).to_owned(),
        g.georef.window(1600, 600),
    );
    let made = synthesize(&sketch, &[ex], &SketchOptions::default(), &mut |_, _| true).unwrap();
    let dict = small_dictionary_with_vegetation(2);
    let world = mini_world(made.grid.data, dict.clone(), "d", 10, 64 << 20);
    for z in [8u8, 10] {
        let (x0, y0) = tile_of(70.3, 42.75, z);
        let block = Window::new(i64::from(x0) * 256, i64::from(y0) * 256, 512, 512);
        let whole = if z == world.z_base() {
            world.elevation_window(z, block).unwrap()
        } else {
            let amp = Amplifier::new(dict.clone(), &MatchWeights::default())
                .unwrap()
                .without_layers();
            let need = amp.parent_window_for(block);
            let parent = Field::elevation_only(need, world.elevation_window(z - 1, need).unwrap());
            amp.amplify(&parent, block, world.level_cell_m(z - 1) as f32)
                .unwrap()
                .elevation
        };
        let alone = world.elevation_tile(z, x0 + 1, y0 + 1).unwrap();
        let window = whole.slice(s![256..512, 256..512]);
        let same = alone
            .iter()
            .zip(window.iter())
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same,
            "zoom {z}: the tile alone differs from its window of the block"
        );
        // Sketched terrain, not only the fill around the world (a zoom-8 tile is wider than it).
        let (lo, hi) = alone
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(
            hi > 300.0 && hi - lo > 50.0,
            "zoom {z}: {lo}..{hi} is not sketched terrain"
        );
    }
}
