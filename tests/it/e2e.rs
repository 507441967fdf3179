//! End to end on the real binary and real sockets: `terrasynth serve` on the embedded default
//! world builds its dictionary into a fresh store, serves plausible zoom-12 terrain over the
//! Tien Shan, and two separately started processes return byte-identical tiles of every layer (at
//! the native zoom and at amplified zooms). The second process reuses the store the first one
//! filled, and glibc gives it the builds of its functions for a CPU without AVX2 and FMA.
//! Issue #4's acceptance 3 and 4 on the default world, from tiles fetched over HTTP: vegetation
//! follows the niche model on the served elevation, and drainage agrees with D8 on it.

use ndarray::Array2;
use terrasynth_core::landscape::LandscapeConfig;
use terrasynth_core::math;
use terrasynth_tiles::{decode_float_exr, decode_terrarium_png};

use crate::support::{proc, start as start_server, start_logging, Server};
use terrasynth_test_support::coherence;

/// `terrasynth serve` on the default world with its store in `store`.
fn start(store: &std::path::Path) -> Server {
    start_server(&[], &[("TERRASYNTH_CACHE_MB", "256")], store)
}

fn fetch(server: &Server, path: &str) -> (u16, Vec<u8>) {
    proc::get(server, path, None)
}

#[test]
fn default_world_is_plausible_and_deterministic_across_processes() {
    let store = tempfile::tempdir().unwrap();
    // Zoom 12 over the Kyrgyz Ala-Too south of Bishkek (74.6°E, 42.55°N), zoom 8 (native), and
    // zoom 10 (amplified), elevation and every landscape layer.
    let paths = [
        "/tiles/tienshan/elevation/12/2896/1512.png",
        "/tiles/tienshan/elevation/8/181/94.png",
        "/tiles/tienshan/elevation/10/724/378.png",
        "/tiles/tienshan/hillshade/10/724/378.png",
        // Every landscape layer, at the native zoom and an amplified one.
        "/tiles/tienshan/vegetation/8/181/94.png",
        "/tiles/tienshan/drainage/8/181/94.exr",
        "/tiles/tienshan/vegetation/10/724/378.exr",
        "/tiles/tienshan/vegetation/10/724/378.png",
        "/tiles/tienshan/drainage/10/724/378.exr",
        "/tiles/tienshan/drainage/10/724/378.png",
        "/tiles/tienshan/splat/10/724/378.png?set=0",
        "/tiles/tienshan/splat/10/724/378.png?set=1",
        "/tiles/tienshan/color/10/724/378.png",
    ];
    let first: Vec<Vec<u8>> = {
        let a = start(store.path());
        let (status, json) = fetch(&a, "/worlds/tienshan");
        assert_eq!(status, 200);
        let v: serde_json::Value = serde_json::from_slice(&json).unwrap();
        assert_eq!(v["native_zoom"], 8);
        assert_eq!(v["maxzoom"], 16);
        paths
            .iter()
            .map(|p| {
                let (status, body) = fetch(&a, p);
                assert_eq!(status, 200, "{p}");
                body
            })
            .collect()
    };
    let heights = decode_terrarium_png(&first[0]).unwrap();
    assert_eq!(heights.dim(), (256, 256));
    let (lo, hi) = heights
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    // The Kyrgyz Ala-Too there rises from about 1000 m to over 4000 m.
    assert!(
        lo > 500.0 && hi < 5500.0 && hi - lo > 300.0,
        "heights {lo}..{hi}"
    );
    // A second process (reusing the store the first filled) returns the same bytes. It logs
    // every level tile it computes (`RUST_LOG=…,terrasynth_tiles::levels=debug`, README "Cold
    // tiles"). To glibc it runs on a CPU without AVX2 and FMA (a tunable other C libraries
    // ignore), so every C library function it calls takes another build than the first
    // process's: tiles must not depend on them (`terrasynth_core::math`).
    let log = store.path().join("server-b.log");
    let b = start_logging(
        &[],
        &[
            ("TERRASYNTH_CACHE_MB", "256"),
            ("RUST_LOG", "info,terrasynth_tiles::levels=debug"),
            ("GLIBC_TUNABLES", "glibc.cpu.hwcaps=-AVX2,-FMA"),
        ],
        store.path(),
        &log,
    );
    for (p, want) in paths.iter().zip(&first) {
        let (status, body) = fetch(&b, p);
        assert_eq!(status, 200, "{p}");
        assert!(body == *want, "{p} differs between processes");
    }
    // Every level tile behind those requests was computed once, however many requests read it:
    // the zoom-10 elevation tile 724/378 serves the elevation, hillshade, drainage, vegetation,
    // splat and colour tiles there (and their neighbours' routing regions).
    let text = std::fs::read_to_string(&log).unwrap();
    let computed = |layer: &str, z: u8, x: u32, y: u32| {
        let key = format!("level tile computed layer=\"{layer}\" z={z} x={x} y={y} ms=");
        text.lines().filter(|l| l.contains(&key)).count()
    };
    for (layer, z, x, y) in [
        ("elevation", 12, 2896, 1512),
        ("elevation", 10, 724, 378),
        ("drainage", 10, 724, 378),
        ("vegetation", 10, 724, 378),
        ("materials", 10, 724, 378),
    ] {
        assert_eq!(
            computed(layer, z, x, y),
            1,
            "{layer} {z}/{x}/{y} in the level log:\n{text}"
        );
    }
    // And the same bytes as the committed list recorded before the workspace move.
    crate::tile_hashes::assert_default_world_tiles(&b);
    // Errors on the real socket.
    assert_eq!(fetch(&b, "/tiles/tienshan/elevation/17/0/0.png").0, 404);
    assert_eq!(fetch(&b, "/tiles/tienshan/elevation/x/0/0.png").0, 400);
}

#[test]
fn default_world_landscape_agrees_with_its_served_elevation() {
    // A 4×4 mosaic of amplified zoom-10 tiles over the Talas range, decoded as a client would:
    // terrarium elevation, the vegetation EXR (one named channel per species) and the drainage
    // EXR (m²).
    let store = tempfile::tempdir().unwrap();
    let server = start(store.path());
    let (z, x0, y0, n) = (10u8, 716u32, 379u32, 4u32);
    let species = LandscapeConfig::tienshan().species;
    let mut elev = Array2::zeros((256 * n as usize, 256 * n as usize));
    let mut area = elev.clone();
    let mut densities = vec![elev.clone(); species.len()];
    let put = |dst: &mut Array2<f32>, dx: u32, dy: u32, t: &Array2<f32>| {
        assert_eq!(t.dim(), (256, 256));
        let (r, c) = (dy as usize * 256, dx as usize * 256);
        dst.slice_mut(ndarray::s![r..r + 256, c..c + 256]).assign(t);
    };
    for dy in 0..n {
        for dx in 0..n {
            let (x, y) = (x0 + dx, y0 + dy);
            let get = |layer: &str, ext: &str| {
                let path = format!("/tiles/tienshan/{layer}/{z}/{x}/{y}.{ext}");
                let (status, body) = fetch(&server, &path);
                assert_eq!(status, 200, "{path}");
                body
            };
            put(
                &mut elev,
                dx,
                dy,
                &decode_terrarium_png(&get("elevation", "png")).unwrap(),
            );
            let drainage = decode_float_exr(&get("drainage", "exr")).unwrap();
            assert_eq!(drainage.len(), 1);
            put(&mut area, dx, dy, &drainage[0].1);
            let vegetation = decode_float_exr(&get("vegetation", "exr")).unwrap();
            for (k, sp) in species.iter().enumerate() {
                let (_, grid) = vegetation
                    .iter()
                    .find(|(name, _)| *name == sp.name)
                    .unwrap_or_else(|| panic!("no {} channel", sp.name));
                put(&mut densities[k], dx, dy, grid);
            }
        }
    }
    // Acceptance 3: Pearson ≥ 0.6 per species present, density < 0.05 where the niche excludes.
    let wet = area.mapv(math::log10f);
    let fits = coherence::vegetation_fit_of(&species, z, y0, &elev, &wet, &densities);
    let mut tested = 0;
    for f in &fits {
        eprintln!("{f:?}");
        assert!(f.worst_excluded < 0.05, "{f:?}");
        if f.present > 0.02 {
            assert!(f.pearson >= 0.6, "{f:?}");
            tested += 1;
        }
    }
    assert!(
        tested >= 3,
        "at least three species grow over the Talas range"
    );
    // Acceptance 4: Spearman ≥ 0.7 against D8 on the decoded elevation, channels walked across
    // tile borders without a break.
    let fit = coherence::drainage_fit_of(z, y0, &elev, &area);
    eprintln!("{fit:?}");
    assert!(fit.spearman >= 0.7, "{fit:?}");
    assert!(fit.crossings >= 10, "{fit:?}");
    assert!(fit.breaks.is_empty(), "{:?}", fit.breaks);
}

#[test]
fn default_world_instance_tiles_are_deterministic_and_stand_on_the_served_ground() {
    // Issue #17 on the real binary: a zoom-15 tile of spruce forest and steppe east of the
    // Ala-Archa (74.75°E, 42.66°N). Two processes serve the same `.mvt` and `.json` bytes; the
    // GeoJSON's points lie inside the tile and their third coordinate is the elevation EXR
    // tile's pixel holding them.
    let store = tempfile::tempdir().unwrap();
    let (z, x, y) = (15u8, 23187u32, 12082u32);
    let paths = [
        format!("/tiles/tienshan/instances/{z}/{x}/{y}.mvt"),
        format!("/tiles/tienshan/instances/{z}/{x}/{y}.json"),
        format!("/tiles/tienshan/elevation/{z}/{x}/{y}.exr"),
    ];
    // A cold zoom-15 tile of a fresh process (whole-world layers, then seven amplified zooms)
    // may take longer than the default deadline on a busy machine.
    let start = |store: &std::path::Path| {
        start_server(
            &[],
            &[
                ("TERRASYNTH_CACHE_MB", "256"),
                ("TERRASYNTH_REQUEST_TIMEOUT_S", "900"),
            ],
            store,
        )
    };
    let a = start(store.path());
    let first: Vec<Vec<u8>> = paths
        .iter()
        .map(|p| {
            let (status, body) = fetch(&a, p);
            assert_eq!(status, 200, "{p}");
            body
        })
        .collect();
    let (st, tj) = fetch(&a, "/tiles/tienshan/instances.json");
    assert_eq!(st, 200);
    let tj: serde_json::Value = serde_json::from_slice(&tj).unwrap();
    assert_eq!(tj["minzoom"], 14);
    let ids: Vec<&str> = tj["vector_layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["trees", "grass", "rocks"]);
    assert_eq!(
        fetch(&a, "/tiles/tienshan/instances/13/5796/3020.mvt").0,
        404
    );
    assert_eq!(fetch(&a, "/tiles/tienshan/instances/17/0/0.mvt").0, 404);
    assert_eq!(
        fetch(&a, "/tiles/tienshan/instances/15/23187/12082.png").0,
        404
    );
    assert_eq!(
        fetch(&a, "/tiles/tienshan/instances/15/23187/12082.mvt?set=1").0,
        400
    );
    // The vector and GeoJSON tiles gzip-coded for clients that accept it (the GeoJSON shrinks
    // most), the same bytes from both processes.
    let coded: Vec<Vec<u8>> = paths[..2]
        .iter()
        .zip(&first)
        .map(|(p, identity)| crate::support::check_gzip_coding(&a, p, identity))
        .collect();
    assert!(
        coded[1].len() * 4 < first[1].len(),
        "GeoJSON {} → {}",
        first[1].len(),
        coded[1].len()
    );
    drop(a);
    // The second process is asked for the gzip-coded tiles first: compressed as they are
    // computed, where the first process compressed the identity bytes it had cached.
    let b = start(store.path());
    for (p, want) in paths[..2].iter().zip(&coded) {
        let gz = proc::get_with(&b, p, &[("Accept-Encoding", "gzip")]);
        assert!(
            gz.body == *want,
            "{p}: the gzip-coded tile differs between processes"
        );
    }
    for (p, want) in paths.iter().zip(&first) {
        let (status, body) = fetch(&b, p);
        assert_eq!(status, 200, "{p}");
        assert!(body == *want, "{p} differs between processes");
    }
    // The GeoJSON, read as any client would.
    let fc: serde_json::Value = serde_json::from_slice(&first[1]).unwrap();
    assert_eq!(fc["type"], "FeatureCollection");
    let elev = decode_float_exr(&first[2]).unwrap();
    let elev = &elev[0].1;
    let n = f64::from(1u32 << z);
    let lon_of = |px: f64| px / n * 360.0 - 180.0;
    let lat_of =
        |py: f64| math::atan(math::sinh(std::f64::consts::PI * (1.0 - 2.0 * py / n))).to_degrees();
    let (west, east) = (lon_of(f64::from(x)), lon_of(f64::from(x + 1)));
    let (north, south) = (lat_of(f64::from(y)), lat_of(f64::from(y + 1)));
    let features = fc["features"].as_array().unwrap();
    let mut species = std::collections::BTreeSet::new();
    let mut checked = 0;
    for f in features {
        assert_eq!(f["type"], "Feature");
        assert_eq!(f["geometry"]["type"], "Point");
        let c = f["geometry"]["coordinates"].as_array().unwrap();
        let (lon, lat, h) = (
            c[0].as_f64().unwrap(),
            c[1].as_f64().unwrap(),
            c[2].as_f64().unwrap(),
        );
        assert!(
            lon >= west && lon < east && lat <= north && lat > south,
            "{c:?}"
        );
        let p = &f["properties"];
        for k in ["species", "height_m", "radius_m", "rotation_deg", "age"] {
            assert!(!p[k].is_null(), "{k} missing: {p}");
        }
        species.insert(p["species"].as_str().unwrap().to_string());
        // The pixel holding the point, by the slippy-map formula (independent of the tiles
        // crate); points within 1e-6 px of a pixel edge are skipped (the lon/lat round trip).
        let fx = ((lon + 180.0) / 360.0 * n - f64::from(x)) * 256.0;
        let lr = lat.to_radians();
        let fy = ((1.0 - math::log(math::tan(lr) + 1.0 / math::cos(lr)) / std::f64::consts::PI)
            / 2.0
            * n
            - f64::from(y))
            * 256.0;
        let edge = |v: f64| (v - v.round()).abs() < 1e-6;
        if edge(fx) || edge(fy) {
            continue;
        }
        let want = elev[[fy.floor() as usize, fx.floor() as usize]];
        assert_eq!(h, f64::from(want), "ground of {c:?}");
        checked += 1;
    }
    eprintln!(
        "{} instances ({species:?}), {checked} grounds checked",
        features.len()
    );
    assert!(checked > 100 && species.len() >= 2, "{species:?}");
}
