//! Instance tiles (#17) on a synthetic world with the default world's scattering rules: a tile
//! computed alone has exactly the instances of the same window of a 3×3 block (bit for bit, at
//! zooms 14 and 15), no two instances of a rule are closer than its minimum distance across tile
//! borders, instances stand where their layers are positive, their ground is the elevation
//! tile's pixel, and instance counts follow the vegetation density (Pearson ≥ 0.9 on a 4×4
//! mosaic at zoom 15).

use terrasynth_core::synth::Window;
use terrasynth_tiles::instances::{instances_in, instances_tile, Placed};
use terrasynth_tiles::World;

use terrasynth_test_support::coherence::pearson;
use terrasynth_test_support::{mini_world, small_dictionary_with_vegetation, synthetic_terrain};

/// The synthetic world of `server.rs` (70–76°E, 38–43°N, 15″), served to zoom 16.
fn world() -> World {
    mini_world(
        synthetic_terrain(1200, 1440, 3).mapv(|v| v + 1000.0),
        small_dictionary_with_vegetation(2),
        "test-dictionary",
        16,
        256 << 20,
    )
}

/// Zoom-15 tile of the block the tests use (inside the zoom-9 mosaic where the vegetation test
/// of `server.rs` finds several species), and its zoom-14 parent.
const Z15: (u32, u32) = (356 * 64 + 20, 190 * 64 + 30);

fn in_window(p: &Placed, w: Window) -> bool {
    let i = &p.instance;
    i.x >= w.col0 as f64 && i.x < w.col1() as f64 && i.y >= w.row0 as f64 && i.y < w.row1() as f64
}

#[test]
fn an_instance_tile_alone_is_the_window_of_a_block_and_distances_hold_across_borders() {
    let w = world();
    let fresh = world();
    for (z, (x, y)) in [(15u8, Z15), (14, (Z15.0 / 2, Z15.1 / 2))] {
        let block = Window::new((i64::from(x) - 1) * 256, (i64::from(y) - 1) * 256, 768, 768);
        let all = instances_tile(&fresh, z, x, y).unwrap();
        let big = instances_in(&w, z, block).unwrap();
        let tile = Window::new(i64::from(x) * 256, i64::from(y) * 256, 256, 256);
        let window: Vec<Placed> = big.iter().filter(|p| in_window(p, tile)).copied().collect();
        eprintln!(
            "z{z}: {} instances in the tile, {} in the block",
            all.len(),
            big.len()
        );
        assert!(all.len() > 100, "z{z}: {} instances", all.len());
        // Same set, bit for bit (positions, sizes, ages, ground).
        assert_eq!(all.len(), window.len(), "z{z}");
        for (a, b) in all.iter().zip(&window) {
            assert_eq!(a.rule, b.rule);
            assert_eq!(a.instance.x.to_bits(), b.instance.x.to_bits());
            assert_eq!(a.instance.y.to_bits(), b.instance.y.to_bits());
            assert_eq!(a.instance, b.instance);
            assert_eq!(a.ground_m.to_bits(), b.ground_m.to_bits());
        }
    }
    // The nine zoom-15 tiles computed alone: no instance twice, and no pair of one rule closer
    // than its minimum distance, across borders too.
    let (x, y) = Z15;
    let mut union: Vec<Placed> = Vec::new();
    for k in 0..9u32 {
        union.extend(instances_tile(&w, 15, x - 1 + k % 3, y - 1 + k / 3).unwrap());
    }
    let cell_m = w.level_cell_m(15);
    let rules = &w.landscape().scatter;
    let mut crossing = 0;
    for (k, a) in union.iter().enumerate() {
        for b in &union[k + 1..] {
            if a.rule != b.rule {
                continue;
            }
            let (ia, ib) = (&a.instance, &b.instance);
            let d = ((ia.x - ib.x).powi(2) + (ia.y - ib.y).powi(2)).sqrt() * cell_m;
            assert!(d > 0.0, "an instance appears twice");
            let min = f64::from(rules[a.rule].min_distance_m);
            assert!(
                d >= min * (1.0 - 1e-9),
                "{} and {}: {d} m < {min} m",
                ia.x,
                ib.x
            );
            let tile_of = |i: &terrasynth_core::landscape::Instance| {
                ((i.x / 256.0).floor(), (i.y / 256.0).floor())
            };
            if d < 2.0 * min && tile_of(ia) != tile_of(ib) {
                crossing += 1;
            }
        }
    }
    eprintln!(
        "{} instances on 3×3 tiles, {crossing} close pairs across borders",
        union.len()
    );
    assert!(
        crossing > 10,
        "the border test saw close pairs across borders"
    );
}

/// A tile's splat sets and colour map read one material computation from the world's cache.
#[test]
fn a_tiles_splat_sets_and_colour_map_share_one_material_computation() {
    let (x, y) = Z15;
    let w = world();
    let first = w.material_tile(15, x, y).unwrap();
    // The second splat set (or the colour map) of the same tile reads the cached tile: the same
    // allocation, not a second computation.
    let again = w.material_tile(15, x, y).unwrap();
    assert!(std::sync::Arc::ptr_eq(&first, &again));
    // What is cached is what the uncached path computes, bit for bit, on a world of its own.
    let fresh = world()
        .material_weights_at(15, i64::from(x), i64::from(y))
        .unwrap();
    assert_eq!(*first, fresh);
    assert!(first.weights.iter().any(|m| m.iter().any(|&v| v > 0.0)));
}

/// The instance halos read material weights over windows that cut tiles: a window computed
/// directly equals the same pixels of the tiles' own weights, bit for bit, on a window straddling
/// four zoom-15 tiles (the world that computes the window has computed no tile's weights).
#[test]
fn material_weights_of_a_window_are_the_tiles_weights_bit_for_bit() {
    let (x, y) = Z15;
    let (tiles_world, window_world) = (world(), world());
    let w = Window::new(i64::from(x) * 256 + 170, i64::from(y) * 256 + 90, 200, 230);
    let direct = window_world.material_window(15, w).unwrap();
    assert!(!direct.is_empty());
    let mut compared = 0usize;
    for (dx, dy) in [(0i64, 0i64), (1, 0), (0, 1), (1, 1)] {
        let (tx, ty) = (i64::from(x) + dx, i64::from(y) + dy);
        let weights = tiles_world.material_weights_at(15, tx, ty).unwrap().weights;
        assert_eq!(weights.len(), direct.len());
        for r in 0..w.rows {
            for c in 0..w.cols {
                let (gr, gc) = (w.row0 + r as i64, w.col0 + c as i64);
                if gr.div_euclid(256) != ty || gc.div_euclid(256) != tx {
                    continue;
                }
                let (tr, tc) = (gr.rem_euclid(256) as usize, gc.rem_euclid(256) as usize);
                for (t, d) in weights.iter().zip(&direct) {
                    assert_eq!(
                        t[[tr, tc]].to_bits(),
                        d[[r, c]].to_bits(),
                        "tile ({tx}, {ty}) pixel ({tr}, {tc})"
                    );
                }
                compared += 1;
            }
        }
    }
    assert_eq!(compared, w.rows * w.cols);
    // Not all one material: the comparison covers varied weights.
    assert!(direct.iter().any(|m| m.iter().any(|&v| v > 0.0 && v < 1.0)));
}

#[test]
fn instances_stand_on_their_layers_and_on_the_elevation_tiles_ground() {
    let w = world();
    let (x, y) = Z15;
    let placed = instances_tile(&w, 15, x, y).unwrap();
    let veg = w.vegetation_tile(15, x, y).unwrap();
    let mats = &w.material_tile(15, x, y).unwrap().weights;
    let elev = w.elevation_tile(15, x, y).unwrap();
    let l = w.landscape();
    let mut kinds = std::collections::BTreeSet::new();
    for p in &placed {
        let i = &p.instance;
        let (r, c) = (
            (i.y.floor() as i64 - i64::from(y) * 256) as usize,
            (i.x.floor() as i64 - i64::from(x) * 256) as usize,
        );
        let rule = &l.scatter[p.rule];
        kinds.insert(rule.kind.clone());
        let name = rule.source_names()[i.source];
        let value = match l.species.iter().position(|s| s.name == name) {
            Some(k) => veg[k][[r, c]],
            None => mats[l.materials.iter().position(|m| m.name == name).unwrap()][[r, c]],
        };
        assert!(value > 0.0, "{name} instance where its layer is {value}");
        for m in &rule.exclude_materials {
            let k = l.materials.iter().position(|o| &o.name == m).unwrap();
            assert!(
                mats[k][[r, c]] < rule.exclude_weight,
                "{} on {m}",
                rule.kind
            );
        }
        assert_eq!(p.ground_m.to_bits(), elev[[r, c]].to_bits());
    }
    eprintln!("kinds present: {kinds:?}");
    assert!(kinds.len() >= 2, "{kinds:?}");
}

#[test]
fn instance_counts_follow_the_vegetation_density() {
    // A 4×4 mosaic of zoom-15 tiles in cells of 64 px: grass instances (meadow and steppe on a
    // jittered grid) per cell against the mean of min(1, meadow + steppe) there.
    let w = world();
    let (x0, y0) = (Z15.0 - 1, Z15.1 - 1);
    let win = Window::new(i64::from(x0) * 256, i64::from(y0) * 256, 1024, 1024);
    let placed = instances_in(&w, 15, win).unwrap();
    let veg = w.vegetation_window(15, win).unwrap();
    let l = w.landscape();
    let idx = |n: &str| l.species.iter().position(|s| s.name == n).unwrap();
    let (meadow, steppe) = (idx("meadow"), idx("steppe"));
    let grass: Vec<usize> = (0..l.scatter.len())
        .filter(|&k| l.scatter[k].kind == "grass")
        .collect();
    let (mut counts, mut density) = (vec![0.0f64; 256], vec![0.0f64; 256]);
    for p in placed.iter().filter(|p| grass.contains(&p.rule)) {
        let (c, r) = (
            (p.instance.x as i64 - win.col0) as usize / 64,
            (p.instance.y as i64 - win.row0) as usize / 64,
        );
        counts[r * 16 + c] += 1.0;
    }
    for r in 0..1024 {
        for c in 0..1024 {
            let d = (veg[meadow][[r, c]] + veg[steppe][[r, c]]).min(1.0);
            density[(r / 64) * 16 + c / 64] += f64::from(d) / 4096.0;
        }
    }
    let rho = pearson(&counts, &density);
    let total: f64 = counts.iter().sum();
    eprintln!("grass: {total} instances, Pearson(count, density) over 256 cells = {rho:.3}");
    assert!(total > 1000.0);
    assert!(rho >= 0.9, "Pearson {rho}");
}
