//! Contour tiles (#19) on the synthetic world of `instances.rs`: on a 3×3 block, every line
//! end on an interior tile border meets a line end of the same elevation in the neighbour; a
//! tile alone has the segments of the same window of the block's lines; every point lies on the
//! served elevation at its line's level; the interval rule, `?interval=` and the index flags;
//! the same MVT bytes from two worlds, read back with an independent decoder.

use terrasynth_core::analysis::contour::contour_lines;
use terrasynth_core::synth::Window;
use terrasynth_tiles::contours::{
    auto_interval, clip_polyline, contour_tile, encode_contours_mvt, Contour, BUFFER_PX,
};
use terrasynth_tiles::World;

use terrasynth_test_support::mvt::{decode, Value};
use terrasynth_test_support::{mini_world, small_dictionary_with_vegetation, synthetic_terrain};

/// A segment of a contour line: elevation and its two ends.
type Seg = (f64, (f64, f64), (f64, f64));

fn world() -> World {
    mini_world(
        synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0),
        small_dictionary_with_vegetation(2),
        "test-dictionary",
        16,
        256 << 20,
    )
}

/// The centre tile of the block at zoom 12 (amplified: native zoom 8), with hilly terrain.
const C12: (u32, u32) = (356 * 8 + 2, 190 * 8 + 3);

/// Line ends of `lines` (tile pixels of tile `(tx, ty)`) on the tile's own border, after
/// clipping to the tile: global pixel coordinates with the elevation.
fn border_ends(lines: &[Contour], tx: u32, ty: u32) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for l in lines {
        for piece in clip_polyline(&l.points, 0.0, 256.0) {
            for p in [piece[0], piece[piece.len() - 1]] {
                // Clipping computes the crossing, so an end lies on the border up to rounding.
                let on = |v: f64| v.abs() < 1e-6 || (v - 256.0).abs() < 1e-6;
                if on(p.0) || on(p.1) {
                    out.push((
                        p.0 + f64::from(tx) * 256.0,
                        p.1 + f64::from(ty) * 256.0,
                        l.elevation_m,
                    ));
                }
            }
        }
    }
    out
}

#[test]
fn lines_meet_across_the_borders_of_a_three_by_three_block() {
    let w = world();
    let (cx, cy) = C12;
    let z = 12;
    let tiles: Vec<((u32, u32), Vec<Contour>)> = (0..3)
        .flat_map(|dy| (0..3).map(move |dx| (cx + dx - 1, cy + dy - 1)))
        .map(|(x, y)| ((x, y), contour_tile(&w, z, x, y, None).unwrap()))
        .collect();
    let (x0, y0, x1, y1) = (
        f64::from(cx - 1) * 256.0,
        f64::from(cy - 1) * 256.0,
        f64::from(cx + 2) * 256.0,
        f64::from(cy + 2) * 256.0,
    );
    let mut checked = 0;
    for ((x, y), lines) in &tiles {
        for (gx, gy, e) in border_ends(lines, *x, *y) {
            // Ends on the block's outer border have no neighbour in the block.
            let near = |a: f64, b: f64| (a - b).abs() < 1e-6;
            if near(gx, x0) || near(gx, x1) || near(gy, y0) || near(gy, y1) {
                continue;
            }
            // The neighbour across the border the end lies on (a corner: any tile sharing it).
            let matched = tiles
                .iter()
                .filter(|(t, _)| t != &(*x, *y))
                .any(|((nx, ny), nl)| {
                    let (left, top) = (f64::from(*nx) * 256.0, f64::from(*ny) * 256.0);
                    let touches =
                        gx >= left && gx <= left + 256.0 && gy >= top && gy <= top + 256.0;
                    touches
                        && border_ends(nl, *nx, *ny).iter().any(|&(hx, hy, he)| {
                            he == e && (hx - gx).abs() <= 1.0 && (hy - gy).abs() <= 1.0
                        })
                });
            assert!(
                matched,
                "tile {x}/{y}: end ({gx}, {gy}) at {e} m has no match"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 20,
        "only {checked} line ends on interior borders"
    );
}

#[test]
fn a_tile_alone_has_the_segments_of_the_same_window_of_a_block() {
    let w = world();
    let (x, y) = C12;
    let z = 12;
    let alone = contour_tile(&w, z, x, y, None).unwrap();
    let interval = auto_interval(w.level_cell_m(z));
    // The block's lines, computed in one piece over the 3×3 block plus border.
    let b = BUFFER_PX as i64 + 1;
    let block = Window::new(
        (i64::from(x) - 1) * 256 - b,
        (i64::from(y) - 1) * 256 - b,
        768 + 2 * b as usize,
        768 + 2 * b as usize,
    );
    let heights = w.elevation_window(z, block).unwrap();
    let levels: Vec<f64> = alone
        .iter()
        .map(|c| c.elevation_m)
        .fold(Vec::new(), |mut v, e| {
            if !v.contains(&e) {
                v.push(e);
            }
            v
        });
    assert!(levels.len() >= 3, "{levels:?} at {interval} m");
    let shift = 0.5 - b as f64 - 256.0;
    let mut from_block = Vec::new();
    for line in contour_lines(&heights, &levels) {
        let pts: Vec<(f64, f64)> = line
            .points
            .iter()
            .map(|p| (p.0 + shift, p.1 + shift))
            .collect();
        for piece in clip_polyline(&pts, -BUFFER_PX, 256.0 + BUFFER_PX) {
            for s in piece.windows(2) {
                from_block.push((levels[line.level], s[0], s[1]));
            }
        }
    }
    let mut from_tile: Vec<_> = alone
        .iter()
        .flat_map(|c| c.points.windows(2).map(|s| (c.elevation_m, s[0], s[1])))
        .collect();
    let norm = |v: &mut Vec<Seg>| {
        for s in v.iter_mut() {
            if (s.2 .0, s.2 .1) < (s.1 .0, s.1 .1) {
                std::mem::swap(&mut s.1, &mut s.2);
            }
        }
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    };
    norm(&mut from_block);
    norm(&mut from_tile);
    assert_eq!(from_block.len(), from_tile.len());
    for (a, t) in from_block.iter().zip(&from_tile) {
        assert_eq!(a.0, t.0);
        for (p, q) in [(a.1, t.1), (a.2, t.2)] {
            assert!(
                (p.0 - q.0).abs() < 1e-6 && (p.1 - q.1).abs() < 1e-6,
                "{a:?} vs {t:?}"
            );
        }
    }
}

#[test]
fn lines_lie_on_the_served_elevation_and_follow_the_interval_rule() {
    let w = world();
    let (x, y) = C12;
    let z = 12;
    // The served heights of the tile plus one pixel (the EXR tile's values and its neighbours').
    let grid = w
        .elevation_window(
            z,
            Window::new(i64::from(x) * 256 - 1, i64::from(y) * 256 - 1, 258, 258),
        )
        .unwrap();
    let at = |r: i64, c: i64| f64::from(grid[[(r + 1) as usize, (c + 1) as usize]]);
    for interval in [None, Some(10.0), Some(40.0)] {
        let step = interval.unwrap_or_else(|| auto_interval(w.level_cell_m(z)));
        let lines = contour_tile(&w, z, x, y, interval).unwrap();
        assert!(!lines.is_empty());
        let mut on_edge = 0;
        for l in &lines {
            let k = (l.elevation_m / step).round();
            assert!(
                (l.elevation_m - k * step).abs() < 1e-6,
                "{} / {step}",
                l.elevation_m
            );
            assert_eq!(l.index, (k as i64).rem_euclid(5) == 0, "{}", l.elevation_m);
            for &(px, py) in &l.points {
                // A point on the edge between two pixel centres (px = c + ½ on a vertical edge,
                // py = r + ½ on a horizontal one) is the level interpolated between them.
                let (gx, gy) = (px - 0.5, py - 0.5);
                if !(0.0..254.0).contains(&gx) || !(0.0..254.0).contains(&gy) {
                    continue;
                }
                let (c, r) = (gx.floor() as i64, gy.floor() as i64);
                let v = if gx == gx.floor() {
                    let t = gy - r as f64;
                    at(r, c) * (1.0 - t) + at(r + 1, c) * t
                } else {
                    let t = gx - c as f64;
                    at(r, c) * (1.0 - t) + at(r, c + 1) * t
                };
                assert!(
                    (v - l.elevation_m).abs() < 1e-3,
                    "({px}, {py}): {v} vs {}",
                    l.elevation_m
                );
                on_edge += 1;
            }
        }
        assert!(on_edge > 100, "{on_edge}");
        // Index lines exist when the tile spans five intervals.
        if step <= 10.0 {
            assert!(lines.iter().any(|l| l.index) && lines.iter().any(|l| !l.index));
        }
    }
}

#[test]
fn contour_tiles_are_deterministic_and_read_back_as_mvt() {
    let (x, y) = C12;
    let a = encode_contours_mvt(&contour_tile(&world(), 12, x, y, None).unwrap()).unwrap();
    let b = encode_contours_mvt(&contour_tile(&world(), 12, x, y, None).unwrap()).unwrap();
    assert!(a == b, "two worlds gave different bytes");
    let layers = decode(&a);
    assert_eq!(layers.len(), 1);
    assert_eq!(layers[0].name, "contours");
    assert_eq!(layers[0].extent, 4096);
    assert!(!layers[0].features.is_empty());
    for f in &layers[0].features {
        assert_eq!(f.geom_type, 2);
        assert!(matches!(f.get("elevation_m"), Some(Value::Number(_))));
        assert!(matches!(f.get("index"), Some(Value::Bool(_))));
        for p in f.parts.iter().flatten() {
            assert!((-64..=4096 + 64).contains(&p.0) && (-64..=4096 + 64).contains(&p.1));
        }
    }
}

/// Line ends of a decoded contour tile `(tx, ty)` on its own border (after clipping its parts
/// to the tile), in global pixels (1/16 px resolution) with their elevation.
fn decoded_border_ends(bytes: &[u8], tx: u32, ty: u32) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for layer in decode(bytes) {
        assert_eq!(layer.name, "contours");
        for f in &layer.features {
            let Some(Value::Number(e)) = f.get("elevation_m") else {
                panic!("no elevation_m: {f:?}");
            };
            for part in &f.parts {
                let px: Vec<(f64, f64)> = part
                    .iter()
                    .map(|&(x, y)| (x as f64 / 16.0, y as f64 / 16.0))
                    .collect();
                for piece in clip_polyline(&px, 0.0, 256.0) {
                    for p in [piece[0], piece[piece.len() - 1]] {
                        let on = |v: f64| v.abs() < 1e-6 || (v - 256.0).abs() < 1e-6;
                        if on(p.0) || on(p.1) {
                            out.push((
                                p.0 + f64::from(tx) * 256.0,
                                p.1 + f64::from(ty) * 256.0,
                                *e,
                            ));
                        }
                    }
                }
            }
        }
    }
    out
}

/// Where the lines of a decoded contour tile `(tx, ty)` (its buffer included) meet the tile's
/// four border lines, in global pixels with their elevation: a line that only touches the border
/// after the 1/16-px rounding has no piece inside the neighbour, but it does reach the border.
fn decoded_border_crossings(bytes: &[u8], tx: u32, ty: u32) -> Vec<(f64, f64, f64)> {
    let (x0, y0) = (f64::from(tx) * 256.0, f64::from(ty) * 256.0);
    let mut out = Vec::new();
    for layer in decode(bytes) {
        for f in &layer.features {
            let Some(Value::Number(e)) = f.get("elevation_m") else {
                panic!("no elevation_m: {f:?}");
            };
            for part in &f.parts {
                let g: Vec<(f64, f64)> = part
                    .iter()
                    .map(|&(x, y)| (x0 + x as f64 / 16.0, y0 + y as f64 / 16.0))
                    .collect();
                for s in g.windows(2) {
                    let (p, q) = (s[0], s[1]);
                    for bx in [x0, x0 + 256.0] {
                        if (p.0 - bx) * (q.0 - bx) <= 0.0 && p.0 != q.0 {
                            let t = (bx - p.0) / (q.0 - p.0);
                            out.push((bx, p.1 + t * (q.1 - p.1), *e));
                        }
                    }
                    for by in [y0, y0 + 256.0] {
                        if (p.1 - by) * (q.1 - by) <= 0.0 && p.1 != q.1 {
                            let t = (by - p.1) / (q.1 - p.1);
                            out.push((p.0 + t * (q.0 - p.0), by, *e));
                        }
                    }
                    for v in [p, q] {
                        if v.0 == x0 || v.0 == x0 + 256.0 || v.1 == y0 || v.1 == y0 + 256.0 {
                            out.push((v.0, v.1, *e));
                        }
                    }
                }
            }
        }
    }
    out
}

#[test]
fn served_contour_tiles_meet_across_borders_and_are_the_same_from_two_processes() {
    // The default world on the real binary: a 3×3 block of zoom-11 contour tiles over the Kyrgyz
    // Ala-Too (amplified three times), read with the independent decoder.
    let store = tempfile::tempdir().unwrap();
    let start = |store: &std::path::Path| {
        crate::support::start(
            &[],
            &[
                ("TERRASYNTH_CACHE_MB", "256"),
                ("TERRASYNTH_REQUEST_TIMEOUT_S", "900"),
            ],
            store,
        )
    };
    let (cx, cy) = (1448u32, 756u32);
    let a = start(store.path());
    let mut block = Vec::new();
    for dy in 0..3 {
        for dx in 0..3 {
            let (x, y) = (cx + dx - 1, cy + dy - 1);
            let (st, body) = crate::support::proc::get(
                &a,
                &format!("/tiles/tienshan/contours/11/{x}/{y}.mvt"),
                None,
            );
            assert_eq!(st, 200);
            block.push(((x, y), body));
        }
    }
    let mut checked = 0;
    for ((x, y), bytes) in &block {
        for (gx, gy, e) in decoded_border_ends(bytes, *x, *y) {
            let outer = |v: f64, lo: u32| {
                (v - f64::from(lo - 1) * 256.0).abs() < 1e-6
                    || (v - f64::from(lo + 2) * 256.0).abs() < 1e-6
            };
            if outer(gx, cx) || outer(gy, cy) {
                continue;
            }
            let matched = block
                .iter()
                .filter(|(t, _)| t != &(*x, *y))
                .any(|((nx, ny), nb)| {
                    decoded_border_crossings(nb, *nx, *ny)
                        .iter()
                        .any(|&(hx, hy, he)| {
                            he == e && (hx - gx).abs() <= 1.0 && (hy - gy).abs() <= 1.0
                        })
                });
            assert!(
                matched,
                "tile {x}/{y}: end ({gx}, {gy}) at {e} m has no match"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 20,
        "only {checked} line ends on interior borders"
    );
    // Bad intervals: problem+json 400 naming the parameter.
    for q in [
        "interval=0",
        "interval=-10",
        "interval=abc",
        "interval=0.5",
        "interval=10&interval=20",
    ] {
        let (st, body) = crate::support::proc::get(
            &a,
            &format!("/tiles/tienshan/contours/11/{cx}/{cy}.mvt?{q}"),
            None,
        );
        assert_eq!(st, 400, "{q}");
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert!(
            v["detail"].as_str().unwrap().contains("interval"),
            "{q}: {v}"
        );
    }
    let (st, tj) = crate::support::proc::get(&a, "/tiles/tienshan/contours.json", None);
    assert_eq!(st, 200);
    let tj: serde_json::Value = serde_json::from_slice(&tj).unwrap();
    assert_eq!(tj["vector_layers"][0]["id"], "contours");
    assert_eq!(tj["vector_layers"][0]["fields"]["index"], "Boolean");
    assert!(tj["tiles"][0]
        .as_str()
        .unwrap()
        .ends_with("/tiles/tienshan/contours/{z}/{x}/{y}.mvt"));
    let (_, style) = crate::support::proc::get(&a, "/styles/tienshan.json", None);
    let style: serde_json::Value = serde_json::from_slice(&style).unwrap();
    let ids: Vec<&str> = style["layers"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|l| l["source"] == "contours")
        .map(|l| l["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["contours", "contours-index"]);
    // Gzip-coded for clients that accept it, the same bytes from both processes.
    let centre_path = format!("/tiles/tienshan/contours/11/{cx}/{cy}.mvt");
    let gz = crate::support::check_gzip_coding(&a, &centre_path, &block[4].1);
    drop(a);
    // The second process is asked for the gzip-coded tile first (compressed as it is computed;
    // the first process compressed the identity bytes it had cached), then for the identity one
    // (decompressed from the cached gzip bytes).
    let b = start(store.path());
    let gz_b = crate::support::proc::get_with(&b, &centre_path, &[("Accept-Encoding", "gzip")]);
    assert!(
        gz_b.body == gz,
        "the gzip-coded tile differs between processes"
    );
    let (st, centre) = crate::support::proc::get(&b, &centre_path, None);
    assert_eq!(st, 200);
    assert!(
        centre == block[4].1,
        "the centre tile differs between processes"
    );
}
