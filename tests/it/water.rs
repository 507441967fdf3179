//! Water (#15, acceptance 2): a synthetic base with a flat-bottomed bowl becomes a lake at its
//! spill level, and the committed Tien Shan base with `sea_level_m` raised becomes a coast.
//! Checked: the lake's surface is flat at every zoom (max |Δh| = 0) and its flat bed gets no
//! amplifier detail; no drainage channel pixel lies under water and channels reaching the coast
//! end there while the lake passes its inflow on at its outlet; water tiles are seamless (a tile
//! alone equals the same window of a block) and deterministic across processes (same bytes from
//! two `terrasynth serve` processes); overview depths are 2×2 averages of their children;
//! vegetation is 0 and the splat's `water` weight 255 under water.

use std::collections::HashMap;

use ndarray::Array2;

use terrasynth_core::math;
use terrasynth_core::synth::Window;
use terrasynth_tiles::layer_file::Refused;
use terrasynth_tiles::{parse_request, render, LayerStore, Obtained, World};

use terrasynth_test_support::{small_dictionary_with_vegetation, synthetic_terrain};

const N: usize = 120;
/// The bowl: centre cell, flat-bottom radius and outer radius (cells), bottom elevation.
const CENTRE: (f64, f64) = (60.0, 60.0);
const FLAT_R: f64 = 14.0;
const RIM_R: f64 = 30.0;
const BOTTOM: f32 = 500.0;

/// Gentle synthetic terrain (around 1,000–1,800 m) with a bowl whose bottom is exactly flat.
fn lake_base() -> Array2<f32> {
    let t = synthetic_terrain(N, N, 9).mapv(|v| 0.3 * v + 1200.0);
    Array2::from_shape_fn((N, N), |(r, c)| {
        let d = ((r as f64 - CENTRE.0).powi(2) + (c as f64 - CENTRE.1).powi(2)).sqrt();
        if d <= FLAT_R {
            BOTTOM
        } else if d < RIM_R {
            let f = ((d - FLAT_R) / (RIM_R - FLAT_R)) as f32;
            BOTTOM + f * (t[[r, c]] - BOTTOM)
        } else {
            t[[r, c]]
        }
    })
}

/// Whether the centre of pixel `(px, py)` of zoom `z` lies in the bowl (within its rim), by the
/// slippy-map formulas.
fn in_bowl(z: u8, px: i64, py: i64) -> bool {
    within(z, px, py, RIM_R + 1.0)
}

/// Whether the centre of pixel `(px, py)` of zoom `z` lies within `radius` cells of the bowl's
/// centre.
fn within(z: u8, px: i64, py: i64, radius: f64) -> bool {
    let n = 256.0 * f64::from(1u32 << z);
    let lon = (px as f64 + 0.5) / n * 360.0 - 180.0;
    let lat = math::atan(math::sinh(
        std::f64::consts::PI * (1.0 - 2.0 * (py as f64 + 0.5) / n),
    ))
    .to_degrees();
    let (c, r) = ((lon - 70.0) * 240.0 - 0.5, (43.0 - lat) * 240.0 - 0.5);
    ((r - CENTRE.0).powi(2) + (c - CENTRE.1).powi(2)).sqrt() < radius
}

/// The mini world's place and settings (70°E 43°N, 15″, native zoom 8) with lakes on.
fn lake_world() -> World {
    lake_world_with(terrasynth_core::landscape::WaterConfig {
        lakes: true,
        ..Default::default()
    })
}

/// The mini world with water settings `water`.
fn lake_world_with(water: terrasynth_core::landscape::WaterConfig) -> World {
    use terrasynth_core::raster::{Crs, Georef, Grid};
    let base = Grid::new(
        lake_base(),
        Georef {
            crs: Crs::Epsg4326,
            west: 70.0,
            north: 43.0,
            pixel_width: 1.0 / 240.0,
            pixel_height: 1.0 / 240.0,
        },
    );
    World::new(terrasynth_tiles::WorldParts {
        name: "mini".into(),
        title: "Mini".into(),
        attribution: "synthetic".into(),
        base,
        z_base: Some(8),
        max_zoom: 12,
        fill_m: 0.0,
        dictionaries: vec![terrasynth_tiles::DictionaryBand::every_zoom(
            small_dictionary_with_vegetation(2),
            "d",
        )],
        weights: Default::default(),
        cache_bytes: 128 << 20,
        landscape: terrasynth_core::landscape::LandscapeConfig::tienshan(),
        center: None,
        sparsity: None,
        water,
        classes: None,
        biomes: Vec::new(),
        controls: Vec::new(),
    })
    .unwrap()
}

/// The tiles of zoom `z` the world serves.
fn tiles(world: &World, z: u8) -> Vec<(u32, u32)> {
    let (x0, y0) = (0u32, 0u32);
    let mut out = Vec::new();
    for y in y0..(1u32 << z) {
        for x in x0..(1u32 << z) {
            if world.check_tile(z, x, y).is_ok() {
                out.push((x, y));
            }
        }
    }
    out
}

#[test]
fn a_bowl_is_a_flat_lake_whose_bed_gets_no_detail_and_drainage_stops_at_its_shore() {
    let w = lake_world();
    let mut wet_pixels = 0usize;
    let mut flat_bed_pixels = 0usize;
    let mut spill = None;
    for z in 8..=12u8 {
        for (x, y) in tiles(&w, z) {
            let (depth, surface) = w.water_tile(z, x, y).unwrap();
            let elev = w.elevation_tile(z, x, y).unwrap();
            let area = w.drainage_tile(z, x, y).unwrap();
            let veg = w.vegetation_tile(z, x, y).unwrap();
            for ((r, c), &d) in depth.indexed_iter() {
                if d <= 0.0 {
                    assert!(surface[[r, c]].is_nan());
                    continue;
                }
                assert_eq!(d, surface[[r, c]] - elev[[r, c]], "depth is surface − bed");
                assert_eq!(area[[r, c]], 0.0, "a channel under water at z{z} {r},{c}");
                for sp in veg.iter() {
                    assert_eq!(sp[[r, c]], 0.0, "vegetation under water");
                }
                let (px, py) = (i64::from(x) * 256 + c as i64, i64::from(y) * 256 + r as i64);
                if !within(z, px, py, RIM_R - 1.0) {
                    // Another depression of the synthetic terrain (one lies against the rim:
                    // its shore may follow the amplified bed just inside it).
                    continue;
                }
                wet_pixels += 1;
                // The bowl's lake: one flat surface at every zoom (max |Δh| over it is 0).
                let s = *spill.get_or_insert(surface[[r, c]]);
                assert_eq!(surface[[r, c]], s, "z{z} {x}/{y} {r},{c}");
                // The flat bed (well inside the flat bottom) has no detail.
                if elev[[r, c]] == BOTTOM {
                    flat_bed_pixels += 1;
                }
            }
        }
    }
    let s = spill.expect("a lake");
    assert!(s > BOTTOM + 20.0, "spill level {s}");
    assert!(wet_pixels > 1000, "{wet_pixels}");
    // Deep inside the flat bottom every amplified pixel is the bottom, bit for bit.
    let z = 12u8;
    let (cx, cy) = terrasynth_tiles::lonlat_to_global_pixel(
        z,
        70.0 + (CENTRE.1 + 0.5) / 240.0,
        43.0 - (CENTRE.0 + 0.5) / 240.0,
    );
    let block = Window::new(cx as i64 - 40, cy as i64 - 40, 80, 80);
    let e = w.elevation_window(z, block).unwrap();
    assert!(
        e.iter().all(|&v| v == BOTTOM),
        "detail on the flat lake bed"
    );
    assert!(flat_bed_pixels > 6000, "{flat_bed_pixels}");
}

/// The bowl's exactly flat bottom (radius 14 cells, about 90 km²) as a lake the base records as
/// a flat surface, with depression lakes off.
fn surface_lake_world(min_area_m2: f64) -> World {
    lake_world_with(terrasynth_core::landscape::WaterConfig {
        surface_lake_min_area_m2: Some(min_area_m2),
        ..Default::default()
    })
}

#[test]
fn a_flat_the_base_records_is_a_lake_at_its_surface_over_a_sunk_bed() {
    let w = surface_lake_world(1e6);
    let mut wet_pixels = 0usize;
    let mut grown = 0usize;
    for z in 8..=12u8 {
        for (x, y) in tiles(&w, z) {
            let (depth, surface) = w.water_tile(z, x, y).unwrap();
            let elev = w.elevation_tile(z, x, y).unwrap();
            let area = w.drainage_tile(z, x, y).unwrap();
            let parent = (z > 8).then(|| w.water_tile(z - 1, x / 2, y / 2).unwrap().0);
            for ((r, c), &d) in depth.indexed_iter() {
                if d <= 0.0 {
                    assert!(surface[[r, c]].is_nan());
                    continue;
                }
                wet_pixels += 1;
                let (px, py) = (i64::from(x) * 256 + c as i64, i64::from(y) * 256 + r as i64);
                assert!(
                    in_bowl(z, px, py),
                    "water outside the bowl at z{z} {px},{py}"
                );
                // The lake's level is the flat's elevation, over a bed below it.
                assert_eq!(surface[[r, c]], BOTTOM, "z{z} {px},{py}");
                assert_eq!(d, BOTTOM - elev[[r, c]], "depth is surface − bed");
                assert_eq!(area[[r, c]], 0.0, "a channel under water at z{z} {r},{c}");
                if let Some(p) = &parent {
                    let (pr, pc) = ((py % 512) as usize / 2, (px % 512) as usize / 2);
                    if p[[pr, pc]] <= 0.0 {
                        grown += 1;
                    }
                }
            }
        }
    }
    assert!(wet_pixels > 10_000, "{wet_pixels}");
    // The shoreline follows the amplified bed beyond its dry parents in places.
    assert!(grown > 0, "no pixel wet below a dry parent");
    // The bed deepens away from the shore: 1 m per 100 m beyond the lake's outer ring, so the
    // middle (about 14 cells of 340–460 m from the shore) lies 30–80 m below the surface at the
    // native zoom.
    let z = 8u8;
    let (cx, cy) = terrasynth_tiles::lonlat_to_global_pixel(
        z,
        70.0 + (CENTRE.1 + 0.5) / 240.0,
        43.0 - (CENTRE.0 + 0.5) / 240.0,
    );
    let middle = Window::new(cx as i64, cy as i64, 1, 1);
    let bed = w.elevation_window(z, middle).unwrap()[[0, 0]];
    assert!(bed < BOTTOM - 30.0 && bed > BOTTOM - 80.0, "bed {bed}");
    // A minimum above the flat's area: no lake, and the flat bottom keeps its elevation.
    let dry = surface_lake_world(1e9);
    assert_eq!(dry.elevation_window(z, middle).unwrap()[[0, 0]], BOTTOM);
    for (x, y) in tiles(&dry, z) {
        assert!(dry.water_tile(z, x, y).unwrap().0.iter().all(|&d| d == 0.0));
    }
}

#[test]
fn tiles_far_from_the_surface_lakes_do_not_wait_for_the_worlds_water() {
    let w = surface_lake_world(1e6);
    // Zoom 12 over the base's north-west corner: its cells 0–22, the lake's blocks start at
    // cell 32 (the flat bottom spans cells 46–74). (Its elevation tile would amplify parent
    // tiles that reach the lake: at zoom 9 one tile holds the whole base.)
    let z = 12u8;
    let (px, py) = terrasynth_tiles::lonlat_to_global_pixel(z, 70.001, 42.999);
    let (x, y) = ((px / 256.0) as u32, (py / 256.0) as u32);
    let (depth, surface) = w.water_tile(z, x, y).unwrap();
    assert!(depth.iter().all(|&d| d == 0.0));
    assert!(surface.iter().all(|s| s.is_nan()));
    assert!(
        !w.base_water_known(),
        "a tile far from the lake computed the world's water"
    );
    // Over the bowl the world's water is computed, and the tile is wet.
    let (bx, by) = terrasynth_tiles::lonlat_to_global_pixel(
        z,
        70.0 + (CENTRE.1 + 0.5) / 240.0,
        43.0 - (CENTRE.0 + 0.5) / 240.0,
    );
    let (wet, _) = w
        .water_tile(z, (bx / 256.0) as u32, (by / 256.0) as u32)
        .unwrap();
    assert!(wet.iter().any(|&d| d > 0.0));
    assert!(w.base_water_known());
    // Known or not, the far tile is dry.
    let (again, level) = w.water_tile(z, x, y).unwrap();
    assert_eq!(again, depth);
    assert!(level.iter().all(|s| s.is_nan()));
}

#[test]
fn the_lake_passes_its_inflow_on_at_its_outlet() {
    let w = lake_world();
    // The native zoom, routed over the whole world.
    let z = 8u8;
    let ww = w.extent().world_window(z);
    let depth = w.water_depth_window(z, ww).unwrap();
    let area = w.drainage_window(z, ww).unwrap();
    let cells = w.cell_sizes(z, ww.row0, ww.rows);
    let elev = w.elevation_window(z, ww).unwrap();
    let bowl = |r: usize, c: usize| in_bowl(z, ww.col0 + c as i64, ww.row0 + r as i64);
    // The bowl's lake: the wet pixels at the surface of the pixel over the bowl's deepest point
    // (the bowl's walls may hold other, smaller lakes at other levels).
    let (_, centre) = depth
        .indexed_iter()
        .filter(|((r, c), _)| bowl(*r, *c))
        .fold(
            (0.0f32, (0, 0)),
            |best, (rc, &d)| if d > best.0 { (d, rc) } else { best },
        );
    let level = elev[centre] + depth[centre];
    let in_lake = |r: usize, c: usize| {
        depth[[r, c]] > 0.0 && (elev[[r, c]] + depth[[r, c]] - level).abs() < 1e-2
    };
    let lake_area: f64 = depth
        .indexed_iter()
        .filter(|((r, c), _)| in_lake(*r, *c))
        .map(|((r, _), _)| cells.area(r))
        .sum();
    // The outlet: a dry pixel next to the lake carrying at least the lake's own area.
    let (rows, cols) = depth.dim();
    let mut best = 0.0f64;
    for r in 1..rows - 1 {
        for c in 1..cols - 1 {
            if depth[[r, c]] > 0.0 {
                continue;
            }
            let shore = (0..3).any(|dr| (0..3).any(|dc| in_lake(r + dr - 1, c + dc - 1)));
            if shore {
                best = best.max(f64::from(area[[r, c]]));
            }
        }
    }
    assert!(lake_area > 1e6, "{lake_area}");
    assert!(best >= lake_area, "outlet {best} m² < lake {lake_area} m²");
}

#[test]
fn water_tiles_are_seamless_and_overviews_average_depth() {
    let w = lake_world();
    let fresh = lake_world();
    for z in [9u8, 10, 11] {
        let ts = tiles(&w, z);
        let (x0, y0) = ts[0];
        let (x1, y1) = ts[ts.len() - 1];
        let block = Window::new(
            i64::from(x0) * 256,
            i64::from(y0) * 256,
            (x1 - x0 + 1) as usize * 256,
            (y1 - y0 + 1) as usize * 256,
        );
        let big = w.water_depth_window(z, block).unwrap();
        for &(x, y) in &ts {
            let (alone, _) = fresh.water_tile(z, x, y).unwrap();
            let r0 = (y - y0) as usize * 256;
            let c0 = (x - x0) as usize * 256;
            let part = big.slice(ndarray::s![r0..r0 + 256, c0..c0 + 256]);
            assert_eq!(alone.view(), part, "z{z} {x}/{y}");
        }
    }
    // Below the native zoom (8) depth is the 2×2 average of the children.
    let z = 7u8;
    for (x, y) in tiles(&w, z) {
        let (d, _) = w.water_tile(z, x, y).unwrap();
        let child = w
            .water_depth_window(
                z + 1,
                Window::new(i64::from(x) * 512, i64::from(y) * 512, 512, 512),
            )
            .unwrap();
        for ((r, c), &v) in d.indexed_iter() {
            let s = child[[2 * r, 2 * c]]
                + child[[2 * r, 2 * c + 1]]
                + child[[2 * r + 1, 2 * c]]
                + child[[2 * r + 1, 2 * c + 1]];
            assert!((v - 0.25 * s).abs() <= 1e-3 * v.abs().max(1.0), "{r},{c}");
        }
    }
}

fn png_rgba(world: &World, layer: &str, z: u8, x: u32, y: u32, q: &[(&str, &str)]) -> Vec<u8> {
    let query: HashMap<String, String> = q
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let req = parse_request(
        world.name(),
        layer,
        &z.to_string(),
        &x.to_string(),
        &format!("{y}.png"),
        &query,
    )
    .unwrap();
    let bytes = render(world, &req).unwrap();
    crate::support::decode_rgba(&bytes).2
}

#[test]
fn submerged_pixels_are_water_in_splat_colour_and_drainage_tiles() {
    let w = lake_world();
    let names = terrasynth_tiles::materials::splat_names(w.landscape());
    let k = names.iter().position(|n| *n == "water").unwrap();
    let z = 10u8;
    for (x, y) in tiles(&w, z) {
        let (depth, _) = w.water_tile(z, x, y).unwrap();
        let splat = png_rgba(&w, "splat", z, x, y, &[("set", &(k / 4).to_string())]);
        let water = png_rgba(&w, "water", z, x, y, &[]);
        let drain = png_rgba(&w, "drainage", z, x, y, &[]);
        for ((r, c), &d) in depth.indexed_iter() {
            let i = 4 * (r * 256 + c);
            if d > 0.0 {
                assert_eq!(splat[i + k % 4], 255, "water weight at {r},{c}");
                assert_eq!(drain[i + 3], 0, "a river under water at {r},{c}");
                assert!(water[i + 3] > 0);
            } else {
                assert_eq!(water[i + 3], 0, "water alpha on land at {r},{c}");
            }
        }
    }
}

/// The committed Tien Shan base with the sea raised to 1,200 m: the lowlands around the range
/// become sea (the base's edge cells below 1,200 m).
const COAST_LEVEL: f32 = 1200.0;

fn coast_world() -> World {
    let base = terrasynth_core::raster::embedded::tienshan().unwrap();
    World::new(terrasynth_tiles::WorldParts {
        name: "coast".into(),
        title: "Coast".into(),
        attribution: "GEBCO".into(),
        base,
        z_base: Some(8),
        max_zoom: 10,
        fill_m: 0.0,
        dictionaries: vec![terrasynth_tiles::DictionaryBand::every_zoom(
            small_dictionary_with_vegetation(2),
            "d",
        )],
        weights: Default::default(),
        cache_bytes: 256 << 20,
        landscape: terrasynth_core::landscape::LandscapeConfig::tienshan(),
        center: None,
        sparsity: None,
        water: terrasynth_core::landscape::WaterConfig {
            sea_level_m: Some(COAST_LEVEL),
            ..Default::default()
        },
        classes: None,
        biomes: Vec::new(),
        controls: Vec::new(),
    })
    .unwrap()
}

#[test]
fn channels_of_a_coast_end_at_the_sea() {
    let w = coast_world();
    for z in [8u8, 9] {
        let ww = w.extent().world_window(z);
        let depth = w.water_depth_window(z, ww).unwrap();
        let area = w.drainage_window(z, ww).unwrap();
        let sea = depth.iter().filter(|&&d| d > 0.0).count();
        assert!(sea > 1000, "z{z}: {sea} sea pixels");
        // No channel pixel under water.
        for ((r, c), &d) in depth.indexed_iter() {
            if d > 0.0 {
                assert_eq!(area[[r, c]], 0.0, "z{z}: channel under water at {r},{c}");
            }
        }
        // Channels reach the coast: big rivers (≥ 100 km²) with a sea pixel next to them.
        let (rows, cols) = depth.dim();
        let mut mouths = 0;
        for r in 1..rows - 1 {
            for c in 1..cols - 1 {
                if area[[r, c]] >= 1e8
                    && (0..3).any(|dr| (0..3).any(|dc| depth[[r + dr - 1, c + dc - 1]] > 0.0))
                {
                    mouths += 1;
                }
            }
        }
        assert!(mouths >= 3, "z{z}: {mouths} river mouths");
    }
}

#[test]
fn water_tiles_are_the_same_bytes_from_two_processes() {
    let dir = tempfile::tempdir().unwrap();
    let world = dir.path().join("coast.toml");
    std::fs::write(
        &world,
        format!(
            "name = \"coast\"\nbase = \"embedded:tienshan\"\nz_base = 8\nmax_zoom = 10\n\
             sea_level_m = {COAST_LEVEL}\n[dictionary]\nexemplars = [\"embedded:tienshan\"]\n\
             atoms = 32\npatch = 16\nstride = 8\nseed = 1\n"
        ),
    )
    .unwrap();
    let cfg = dir.path().join("server.toml");
    std::fs::write(&cfg, format!("worlds = [{:?}]\n", world.to_str().unwrap())).unwrap();
    let mut bodies: Vec<Vec<Vec<u8>>> = Vec::new();
    // Runs 0 and 1 on fresh stores; run 2 on run 0's store, whose stored whole-world layers
    // (base water included) it reads instead of computing them.
    let layers = dir.path().join("store0/landscape/coast.layers");
    let stamp = |p: &std::path::Path| {
        let m = std::fs::metadata(p).unwrap();
        (m.len(), m.modified().unwrap())
    };
    let mut stored = None;
    for run in 0..3 {
        let s = crate::support::start(
            &["--config", cfg.to_str().unwrap()],
            &[],
            &dir.path().join(format!("store{}", run % 2)),
        );
        // Every zoom-8 tile of the world (EXR and PNG) and a zoom-6 overview.
        let (_, tj) = terrasynth_test_support::process::get(&s, "/tiles/coast/water.json", None);
        let b = terrasynth_test_support::process::json(&tj)["bounds"].clone();
        let f = |i: usize| b[i].as_f64().unwrap();
        let (x0, y0) = terrasynth_test_support::tile_of(f(0), f(3), 8);
        let (x1, y1) = terrasynth_test_support::tile_of(f(2), f(1), 8);
        let mut urls = vec!["/tiles/coast/water/6/45/23.png".to_string()];
        for y in y0..=y1 {
            for x in x0..=x1 {
                urls.push(format!("/tiles/coast/water/8/{x}/{y}.exr"));
                urls.push(format!("/tiles/coast/water/8/{x}/{y}.png"));
            }
        }
        let mut got = Vec::new();
        for u in &urls {
            let (status, body) = terrasynth_test_support::process::get(&s, u, None);
            if status == 404 {
                // A tile of the bounds' box the world does not touch.
                continue;
            }
            assert_eq!(status, 200, "{u}");
            got.push(body);
        }
        if run == 0 {
            // Stored by the background thread once computed.
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
            while !layers.exists() {
                assert!(std::time::Instant::now() < deadline, "layers never stored");
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
            stored = Some(stamp(&layers));
        }
        s.kill();
        bodies.push(got);
    }
    assert_eq!(bodies[0], bodies[1]);
    assert_eq!(bodies[0], bodies[2]);
    // Read, not computed and rewritten.
    assert_eq!(Some(stamp(&layers)), stored);
    // The EXRs carry a `depth` channel, with water in some of them.
    let mut wet = 0;
    for b in bodies[0]
        .iter()
        .filter(|b| b.starts_with(&[0x76, 0x2f, 0x31, 0x01]))
    {
        // The tiles crate's reader refuses a raster with no finite value: a wholly dry tile
        // (its `surface` channel is all NaN).
        let Ok(layers) = terrasynth_tiles::decode_float_exr(b) else {
            continue;
        };
        let depth = &layers.iter().find(|(n, _)| n == "depth").unwrap().1;
        wet += depth.iter().filter(|&&d| d > 0.0).count();
    }
    assert!(wet > 1000, "{wet} wet pixels");
}

/// The whole-world layers of `world` as bits: upstream area and each species' densities of every
/// tile of zooms 8 and 9, then the water tiles' depth and surface.
fn landscape_bits(world: &World) -> Vec<u32> {
    let mut out = Vec::new();
    for z in 8..=9u8 {
        for (x, y) in tiles(world, z) {
            out.extend(
                world
                    .drainage_tile(z, x, y)
                    .unwrap()
                    .iter()
                    .map(|v| v.to_bits()),
            );
            for sp in world.vegetation_tile(z, x, y).unwrap().iter() {
                out.extend(sp.iter().map(|v| v.to_bits()));
            }
            let (depth, surface) = world.water_tile(z, x, y).unwrap();
            out.extend(depth.iter().chain(surface.iter()).map(|v| v.to_bits()));
        }
    }
    out
}

/// A [`LayerStore`] in memory: the file, the build, and how the layers were obtained.
#[derive(Debug)]
struct MemoryLayers {
    file: std::sync::Mutex<Option<Vec<u8>>>,
    build: &'static [u8],
    obtained: std::sync::Mutex<Vec<Obtained>>,
}

impl MemoryLayers {
    fn new(file: Option<Vec<u8>>, build: &'static [u8]) -> std::sync::Arc<Self> {
        std::sync::Arc::new(MemoryLayers {
            file: std::sync::Mutex::new(file),
            build,
            obtained: std::sync::Mutex::new(Vec::new()),
        })
    }
    fn file(&self) -> Option<Vec<u8>> {
        self.file.lock().unwrap().clone()
    }
    fn obtained(&self) -> Vec<Obtained> {
        self.obtained.lock().unwrap().clone()
    }
}

impl LayerStore for MemoryLayers {
    fn load(&self) -> Option<Vec<u8>> {
        self.file()
    }
    fn save(&self, file: &[u8]) {
        *self.file.lock().unwrap() = Some(file.to_vec());
    }
    fn build(&self) -> &[u8] {
        self.build
    }
    fn obtained(&self, how: Obtained) {
        self.obtained.lock().unwrap().push(how);
    }
}

/// `world` keeping its layers in `store`.
fn kept_in(world: World, store: &std::sync::Arc<MemoryLayers>) -> World {
    world.keep_landscape_in(store.clone());
    world
}

#[test]
fn whole_world_layers_read_back_from_their_file_are_the_computed_ones() {
    let want = landscape_bits(&lake_world());

    // Computed (by the first tile that needs them) and stored.
    let store = MemoryLayers::new(None, b"build 1");
    assert_eq!(landscape_bits(&kept_in(lake_world(), &store)), want);
    assert_eq!(store.obtained(), [Obtained::Computed]);
    let file = store.file().expect("computed layers are stored");

    // The same world, later: read from the file (the base water with them), not computed.
    let again = MemoryLayers::new(Some(file.clone()), b"build 1");
    assert_eq!(landscape_bits(&kept_in(lake_world(), &again)), want);
    assert_eq!(again.obtained(), [Obtained::Read]);
    assert_eq!(again.file(), Some(file.clone()), "read, not rewritten");

    // Another build, a damaged file, a file of another world: computed again, same layers,
    // and stored again.
    let mut flipped = file.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 1;
    // The mini world without its lake: same window and species, other inputs.
    let other = MemoryLayers::new(None, b"build 1");
    let _ = landscape_bits(&kept_in(lake_world_with(Default::default()), &other));
    let other = other.file().unwrap();
    for (bytes, build, why) in [
        (&file, &b"build 2"[..], Refused::Key),
        (&flipped, &b"build 1"[..], Refused::Checksum),
        (&other, &b"build 1"[..], Refused::Key),
    ] {
        let store = MemoryLayers::new(Some(bytes.clone()), build);
        assert_eq!(
            landscape_bits(&kept_in(lake_world(), &store)),
            want,
            "{why:?}"
        );
        assert_eq!(store.obtained(), [Obtained::Refused(why)]);
        assert_ne!(store.file().as_ref(), Some(bytes), "{why:?}: stored again");
    }
}
