//! Coverage (#15, acceptance 1): on a small base (0.4° × 0.4° at 15″) with a nodata hole, every
//! overlay layer — colour, splat, vegetation (raw and overlay), drainage (PNG and EXR) and
//! instances — is transparent, zero or empty at every pixel whose centre lies outside the base
//! or deep in the hole, and the colour map is opaque at every pixel whose centre lies inside
//! the data; the elevation there is the world's fill. Pixel centres are placed with the
//! slippy-map formulas written here, independently of the tiles crate; PNGs are decoded with the
//! `png` crate.

use std::collections::HashMap;

use ndarray::Array2;

use terrasynth_core::math;
use terrasynth_tiles::instances::instances_tile;
use terrasynth_tiles::{parse_request, render, World};

use terrasynth_test_support::{mini_world, small_dictionary_with_vegetation, synthetic_terrain};

/// Base cells per side, and the hole's cell range (rows and columns).
const N: usize = 96;
const HOLE: std::ops::Range<usize> = 20..76;
const CELL: f64 = 1.0 / 240.0;
const WEST: f64 = 70.0;
const NORTH: f64 = 43.0;

fn world() -> World {
    let mut h = synthetic_terrain(N, N, 5).mapv(|v| v + 1000.0);
    for r in HOLE {
        for c in HOLE {
            h[[r, c]] = f32::NAN;
        }
    }
    mini_world(h, small_dictionary_with_vegetation(2), "d", 12, 256 << 20)
}

/// Where a pixel centre of zoom `z` falls: `Some(true)` surely covered (inside the base, over a
/// cell whose every bilinear neighbour is valid), `Some(false)` surely uncovered (outside the
/// base, or deeper than one cell in the hole), `None` on the hole's one-cell rim.
fn covered(z: u8, px: i64, py: i64) -> Option<bool> {
    let n = 256.0 * f64::from(1u32 << z);
    let lon = (px as f64 + 0.5) / n * 360.0 - 180.0;
    let lat = math::atan(math::sinh(
        std::f64::consts::PI * (1.0 - 2.0 * (py as f64 + 0.5) / n),
    ))
    .to_degrees();
    let (u, v) = ((lon - WEST) / CELL, (NORTH - lat) / CELL);
    if !(0.0..N as f64).contains(&u) || !(0.0..N as f64).contains(&v) {
        return Some(false);
    }
    let (h0, h1) = (HOLE.start as f64, HOLE.end as f64);
    let inside = |lo: f64, hi: f64| u > lo && u < hi && v > lo && v < hi;
    if inside(h0 + 1.0, h1 - 1.0) {
        Some(false)
    } else if inside(h0 - 1.0, h1 + 1.0) {
        None
    } else {
        Some(true)
    }
}

fn rgba(
    world: &World,
    layer: &str,
    z: u8,
    x: u32,
    y: u32,
    ext: &str,
    q: &[(&str, &str)],
) -> Array2<[u8; 4]> {
    let query: HashMap<String, String> = q
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let req = parse_request(
        world.name(),
        layer,
        &z.to_string(),
        &x.to_string(),
        &format!("{y}.{ext}"),
        &query,
    )
    .unwrap();
    let bytes = render(world, &req).unwrap();
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba, "{layer}");
    Array2::from_shape_fn((256, 256), |(r, c)| {
        let i = 4 * (r * 256 + c);
        [buf[i], buf[i + 1], buf[i + 2], buf[i + 3]]
    })
}

/// The tiles of zoom `z` the world serves.
fn tiles(world: &World, z: u8) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for y in 0..(1u32 << z) {
        for x in 0..(1u32 << z) {
            if world.check_tile(z, x, y).is_ok() {
                out.push((x, y));
            }
        }
    }
    out
}

#[test]
fn overlays_are_transparent_exactly_outside_the_coverage() {
    let w = world();
    let mut fully_uncovered_tiles = 0;
    let (mut seen_out, mut seen_in) = (0usize, 0usize);
    for z in 8..=12u8 {
        for (x, y) in tiles(&w, z) {
            let colour = rgba(&w, "color", z, x, y, "png", &[]);
            let splat = rgba(&w, "splat", z, x, y, "png", &[]);
            let veg = rgba(&w, "vegetation", z, x, y, "png", &[]);
            let overlay = rgba(&w, "vegetation", z, x, y, "png", &[("style", "overlay")]);
            let drain = rgba(&w, "drainage", z, x, y, "png", &[]);
            let area = w.drainage_tile(z, x, y).unwrap();
            let elev = w.elevation_tile(z, x, y).unwrap();
            let mut all_out = true;
            for r in 0..256 {
                for c in 0..256 {
                    let (px, py) = (i64::from(x) * 256 + c as i64, i64::from(y) * 256 + r as i64);
                    match covered(z, px, py) {
                        Some(false) => {
                            seen_out += 1;
                            let at = format!("z{z} {x}/{y} pixel {r},{c}");
                            assert_eq!(colour[[r, c]][3], 0, "colour alpha at {at}");
                            assert_eq!(splat[[r, c]], [0; 4], "splat at {at}");
                            assert_eq!(veg[[r, c]], [0; 4], "vegetation at {at}");
                            assert_eq!(overlay[[r, c]][3], 0, "overlay alpha at {at}");
                            assert_eq!(drain[[r, c]][3], 0, "drainage alpha at {at}");
                            assert_eq!(area[[r, c]], 0.0, "upstream area at {at}");
                            assert_eq!(elev[[r, c]], w.fill_m(), "elevation at {at}");
                        }
                        Some(true) => {
                            all_out = false;
                            seen_in += 1;
                            assert_eq!(colour[[r, c]][3], 255, "z{z} {x}/{y} pixel {r},{c}");
                            let s: u32 = splat[[r, c]].iter().map(|&v| u32::from(v)).sum();
                            // The default landscape has more than four materials: set 0 holds
                            // part of the 255.
                            assert!(s <= 255);
                        }
                        None => all_out = false,
                    }
                }
            }
            if all_out {
                fully_uncovered_tiles += 1;
            }
            // No instance outside the coverage.
            if z >= w.landscape().instances_min_zoom {
                for p in instances_tile(&w, z, x, y).unwrap() {
                    let (px, py) = (p.instance.x.floor() as i64, p.instance.y.floor() as i64);
                    assert_ne!(covered(z, px, py), Some(false), "instance at {px},{py}");
                }
            }
        }
    }
    assert!(
        seen_out > 10_000 && seen_in > 10_000,
        "{seen_out} {seen_in}"
    );
    // A tile wholly inside the hole is wholly transparent (checked pixel by pixel above).
    assert!(fully_uncovered_tiles > 0);
}
