//! Vegetation from the niche model: per-species suitability (the product of the niche's weight
//! curves), the seeding/survival simulation that makes densities patchy (DESIGN.md method 4), the
//! densities derived on an exemplar at dictionary build time, and the viability gate applied on
//! served terrain.
//!
//! The simulation draws every random number from `hash2(seed, x, y)` of *global* cell coordinates,
//! and its neighbourhoods are fixed-radius boxes clamped to the grid, so its result depends only on
//! the grid, its origin and the configuration.

use ndarray::Array2;

use super::model::{Clustering, LandscapeConfig, Species};
use crate::analysis;
use crate::dictionary::rng::{hash2, mix64, to_unit_f64};
use crate::dictionary::LayerKind;
use crate::raster::CellSizes;

/// Niche suitability in [0, 1] of `sp` at a point (`slope` in degrees, `wetness` log10 m²).
pub fn suitability(sp: &Species, elevation: f32, slope: f32, northness: f32, wetness: f32) -> f32 {
    let mut w = 1.0f32;
    for (t, x) in [
        (sp.elevation, elevation),
        (sp.slope, slope),
        (sp.northness, northness),
        (sp.wetness, wetness),
    ] {
        if let Some(t) = t {
            w *= t.weight(x);
        }
    }
    w
}

/// The key of biome `name`'s weights among the class weights a world gives ([`class_factor`],
/// the splat's inputs): `biome.<name>` (no class name holds a `.`).
pub fn biome_key(name: &str) -> String {
    format!("{BIOME_PREFIX}{name}")
}

/// The prefix of [`biome_key`].
pub const BIOME_PREFIX: &str = "biome.";

/// The `class.<name>` and `biome.<name>` factor of `sp` per pixel: the product of its class and
/// biome terms' weight curves over the weights `classes` (by name, biomes under
/// [`biome_key`]; a class or biome absent from them weighs 0). `None` when `sp` has no such
/// terms or no weights are given (dictionary builds: no classes).
pub fn class_factor(sp: &Species, classes: &[(String, Array2<f32>)]) -> Option<Array2<f32>> {
    let first = classes.first()?;
    if sp.class.is_empty() && sp.biome.is_empty() {
        return None;
    }
    let mut out = Array2::from_elem(first.1.dim(), 1.0f32);
    let terms = sp
        .class
        .iter()
        .map(|(n, t)| (n.clone(), t))
        .chain(sp.biome.iter().map(|(n, t)| (biome_key(n), t)));
    for (name, t) in terms {
        match classes.iter().find(|(n, _)| *n == name) {
            Some((_, w)) => ndarray::Zip::from(&mut out)
                .and(w)
                .for_each(|o, &x| *o *= t.weight(x)),
            None => out.fill(0.0),
        }
    }
    Some(out)
}

/// The viability step on served terrain: a factor in [0, 1] that is 0 where the suitability is 0
/// and 1 at and above `viability` (smoothstep in between).
pub fn viability_gate(suit: f32, viability: f32) -> f32 {
    if suit.is_nan() || suit <= 0.0 {
        return 0.0;
    }
    if viability <= 0.0 {
        return 1.0;
    }
    let t = (suit / viability).min(1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Redistributes densities inside each 2×2 block of a level's lattice according to a weight
/// (the niche suitability on the served terrain): child `i` of a block gets
/// `d_i · g_i · Σd / Σ(d·g)`, clamped to 1. The block's sum, hence the parent's density that the
/// 2×2 average reproduces, is kept, while density moves from the block's poorly suited children to
/// its well suited ones; a child whose weight is 0 gets 0, and a block whose children are all
/// excluded loses its density. Blocks are aligned on even global coordinates: `row0`, `col0` are
/// the global coordinates of `density[[0, 0]]`. Negative densities and NaN or negative weights
/// count as 0.
pub fn redistribute_in_blocks(
    density: &mut Array2<f32>,
    weight: &Array2<f32>,
    row0: i64,
    col0: i64,
) {
    let (rows, cols) = density.dim();
    debug_assert_eq!(weight.dim(), (rows, cols));
    // Local index ranges of the block rows (columns) covering the grid.
    let spans = |n: usize, o: i64| -> Vec<(usize, usize)> {
        let mut out = Vec::with_capacity(n / 2 + 2);
        let mut i = 0usize;
        while i < n {
            let end = if (o + i as i64).rem_euclid(2) == 0 {
                (i + 2).min(n)
            } else {
                i + 1
            };
            out.push((i, end));
            i = end;
        }
        out
    };
    let col_spans = spans(cols, col0);
    // NaN (no terrain) and negative weights count as 0.
    let usable = |g: f32| if g > 0.0 { g } else { 0.0 };
    for (r0, r1) in spans(rows, row0) {
        for &(c0, c1) in &col_spans {
            let (mut sum, mut weighted) = (0.0f32, 0.0f32);
            for r in r0..r1 {
                for c in c0..c1 {
                    let d = density[[r, c]].max(0.0);
                    sum += d;
                    weighted += d * usable(weight[[r, c]]);
                }
            }
            let scale = if weighted > 0.0 { sum / weighted } else { 0.0 };
            for r in r0..r1 {
                for c in c0..c1 {
                    let d = density[[r, c]].max(0.0);
                    density[[r, c]] = (d * usable(weight[[r, c]]) * scale).min(1.0);
                }
            }
        }
    }
}

/// Integral image of a 0/1 grid (`(rows+1) × (cols+1)`).
fn integral(occ: &[u8], rows: usize, cols: usize) -> Vec<u32> {
    let mut s = vec![0u32; (rows + 1) * (cols + 1)];
    for r in 0..rows {
        let mut run = 0u32;
        for c in 0..cols {
            run += u32::from(occ[r * cols + c]);
            s[(r + 1) * (cols + 1) + c + 1] = s[r * (cols + 1) + c + 1] + run;
        }
    }
    s
}

/// Fraction of occupied cells in the `(2rad+1)²` box around `(r, c)`, clamped to the grid.
fn box_fraction(s: &[u32], rows: usize, cols: usize, r: usize, c: usize, rad: usize) -> f32 {
    let (r0, r1) = (r.saturating_sub(rad), (r + rad + 1).min(rows));
    let (c0, c1) = (c.saturating_sub(rad), (c + rad + 1).min(cols));
    let w = cols + 1;
    let sum = s[r1 * w + c1] + s[r0 * w + c0] - s[r0 * w + c1] - s[r1 * w + c0];
    sum as f32 / ((r1 - r0) * (c1 - c0)) as f32
}

/// Patchy densities from a suitability grid whose cell `(0, 0)` has global coordinates
/// `(row0, col0)`: seeds fall with probability `0.3·s`, then each round an empty cell is colonised
/// with probability `s · (occupied share of its box)` and an occupied one survives with
/// probability `0.2 + 0.5·s` (so even fully suitable ground keeps gaps); the density is `s · (floor + (1 − floor) · share)` with the final
/// occupied share in the box. `stream` separates species.
///
/// A cell whose suitability is not positive is never occupied, so its random numbers are not
/// drawn; each round's rows are computed in parallel (every cell reads only the previous round).
/// [`cluster_densities_naive`] is the straightforward twin; a property test holds them equal bit
/// for bit.
pub fn cluster_densities(
    suit: &Array2<f32>,
    row0: i64,
    col0: i64,
    cl: &Clustering,
    stream: u64,
) -> Array2<f32> {
    use rayon::prelude::*;
    let (rows, cols) = suit.dim();
    if rows == 0 || cols == 0 {
        return Array2::zeros((rows, cols));
    }
    let s: Vec<f32> = suit.iter().copied().collect();
    let rad = cl.radius as usize;
    let seed = mix64(cl.seed ^ mix64(stream.wrapping_add(0x5eed)));
    let draw = |round: u64, r: usize, c: usize| {
        to_unit_f64(hash2(
            seed.wrapping_add(round),
            col0 + c as i64,
            row0 + r as i64,
        )) as f32
    };
    let mut occ = vec![0u8; rows * cols];
    occ.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
        let sr = &s[r * cols..(r + 1) * cols];
        for (c, (o, &sv)) in row.iter_mut().zip(sr).enumerate() {
            *o = u8::from(sv > 0.0 && draw(0, r, c) < 0.3 * sv);
        }
    });
    let mut next = vec![0u8; rows * cols];
    for round in 1..=u64::from(cl.iterations) {
        let sums = integral(&occ, rows, cols);
        let prev = &occ;
        next.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
            let sr = &s[r * cols..(r + 1) * cols];
            let pr = &prev[r * cols..(r + 1) * cols];
            for (c, o) in row.iter_mut().enumerate() {
                let sv = sr[c];
                *o = if sv > 0.0 {
                    let u = draw(round, r, c);
                    let ok = if pr[c] == 1 {
                        u < 0.2 + 0.5 * sv
                    } else {
                        u < sv * box_fraction(&sums, rows, cols, r, c, rad)
                    };
                    u8::from(ok)
                } else {
                    0
                };
            }
        });
        std::mem::swap(&mut occ, &mut next);
    }
    let sums = integral(&occ, rows, cols);
    let floor = cl.floor;
    let mut out = vec![0f32; rows * cols];
    out.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
        for (c, o) in row.iter_mut().enumerate() {
            let share = box_fraction(&sums, rows, cols, r, c, rad);
            *o = s[r * cols + c] * (floor + (1.0 - floor) * share);
        }
    });
    Array2::from_shape_fn((rows, cols), |(r, c)| out[r * cols + c])
}

/// The naive twin of [`cluster_densities`]: every cell's random numbers drawn, one thread.
pub fn cluster_densities_naive(
    suit: &Array2<f32>,
    row0: i64,
    col0: i64,
    cl: &Clustering,
    stream: u64,
) -> Array2<f32> {
    let (rows, cols) = suit.dim();
    let s: Vec<f32> = suit.iter().copied().collect();
    let rad = cl.radius as usize;
    let seed = mix64(cl.seed ^ mix64(stream.wrapping_add(0x5eed)));
    let draw = |round: u64, i: usize| {
        let (r, c) = ((i / cols.max(1)) as i64, (i % cols.max(1)) as i64);
        to_unit_f64(hash2(seed.wrapping_add(round), col0 + c, row0 + r)) as f32
    };
    let mut occ: Vec<u8> = (0..rows * cols)
        .map(|i| u8::from(draw(0, i) < 0.3 * s[i]))
        .collect();
    for round in 1..=u64::from(cl.iterations) {
        let sums = integral(&occ, rows, cols);
        occ = (0..rows * cols)
            .map(|i| {
                let u = draw(round, i);
                let ok = if occ[i] == 1 {
                    u < 0.2 + 0.5 * s[i]
                } else {
                    let share = box_fraction(&sums, rows, cols, i / cols, i % cols, rad);
                    u < s[i] * share
                };
                u8::from(ok && s[i] > 0.0)
            })
            .collect();
    }
    let sums = integral(&occ, rows, cols);
    let floor = cl.floor;
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let share = box_fraction(&sums, rows, cols, r, c, rad);
        s[r * cols + c] * (floor + (1.0 - floor) * share)
    })
}

/// Suitability grid of `sp` on `elevation` given slope (degrees), northness and wetness grids of
/// the same shape: [`suitability`] at every pixel, computed term by term over the grid (each
/// pixel's product in `suitability`'s order, so the same bits).
pub fn suitability_grid(
    sp: &Species,
    elevation: &Array2<f32>,
    slope_deg: &Array2<f32>,
    northness: &Array2<f32>,
    wetness: &Array2<f32>,
) -> Array2<f32> {
    let mut out = Array2::from_elem(elevation.dim(), 1.0f32);
    for (t, grid) in [
        (sp.elevation, elevation),
        (sp.slope, slope_deg),
        (sp.northness, northness),
        (sp.wetness, wetness),
    ] {
        if let Some(t) = t {
            ndarray::Zip::from(&mut out)
                .and(grid)
                .for_each(|o, &x| *o *= t.weight(x));
        }
    }
    out
}

/// Patchy densities of every species on a grid whose cell `(0, 0)` is global `(row0, col0)`:
/// [`suitability_grid`] then [`cluster_densities`], one species at a time.
///
/// `classes`: the land-cover class weights of the grid by name (empty: none), for the species'
/// `class.<name>` terms ([`class_factor`]), applied to the suitability before the seeding.
pub fn densities(
    cfg: &LandscapeConfig,
    elevation: &Array2<f32>,
    cells: &CellSizes,
    wetness: &Array2<f32>,
    origin: (i64, i64),
    classes: &[(String, Array2<f32>)],
) -> Vec<Array2<f32>> {
    let slope = analysis::slope_degrees(elevation, cells);
    let north = analysis::northness(elevation, cells);
    // One species' suitability grid at a time: whole-world grids are large.
    cfg.species
        .iter()
        .enumerate()
        .map(|(k, sp)| {
            let mut suit = suitability_grid(sp, elevation, &slope, &north, wetness);
            if let Some(f) = class_factor(sp, classes) {
                suit *= &f;
            }
            cluster_densities(&suit, origin.0, origin.1, &cfg.clustering, k as u64)
        })
        .collect()
}

/// The vegetation layers of an exemplar (filled elevation, metric cells), one continuous
/// dictionary layer per species named after it: the niche model on the exemplar's elevation,
/// slope, northness and wetness (log10 of its D8 upstream area after priority-flood filling),
/// made patchy by the seeding simulation.
pub fn exemplar_vegetation(
    cfg: &LandscapeConfig,
    elevation: &Array2<f32>,
    cells: &CellSizes,
) -> Vec<(String, Array2<f32>, LayerKind)> {
    let filled = analysis::priority_flood_fill(elevation);
    let area = analysis::flow_accumulation_d8(&filled, cells);
    let wet = analysis::log_upstream_area(&area);
    densities(cfg, elevation, cells, &wet, (0, 0), &[])
        .into_iter()
        .zip(&cfg.species)
        .map(|(d, sp)| (sp.name.clone(), d, LayerKind::Continuous))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landscape::Trapezoid;

    fn species() -> Species {
        Species {
            name: "a".into(),
            colour: [0, 0, 0],
            elevation: Some(Trapezoid {
                min: 100.0,
                max: 200.0,
                falloff: 10.0,
            }),
            slope: None,
            northness: Some(Trapezoid {
                min: 0.0,
                max: 1.0,
                falloff: 0.0,
            }),
            wetness: None,
            class: Default::default(),
            biome: Default::default(),
        }
    }

    #[test]
    fn class_terms_multiply_the_suitability_by_the_class_weights() {
        let mut sp = species();
        // No class weights given (a dictionary build): no factor, whatever the terms.
        assert!(class_factor(&sp, &[]).is_none());
        let grass = ndarray::arr2(&[[1.0f32, 0.75, 0.25, 0.0]]);
        let classes = vec![("grass".to_string(), grass)];
        assert!(class_factor(&sp, &classes).is_none(), "no terms, no factor");
        sp.class.insert(
            "grass".into(),
            Trapezoid {
                min: 0.5,
                max: 1.0,
                falloff: 0.0,
            },
        );
        // A box on [0.5, 1]: 1, 1, 0, 0 by hand.
        let f = class_factor(&sp, &classes).unwrap();
        assert_eq!(f, ndarray::arr2(&[[1.0f32, 1.0, 0.0, 0.0]]));
        // A class the weights lack weighs 0.
        sp.class.insert(
            "rock".into(),
            Trapezoid {
                min: 0.0,
                max: 1.0,
                falloff: 0.0,
            },
        );
        assert!(class_factor(&sp, &classes)
            .unwrap()
            .iter()
            .all(|&v| v == 0.0));
    }

    #[test]
    fn suitability_is_the_product_of_the_curves() {
        let sp = species();
        assert_eq!(suitability(&sp, 150.0, 30.0, 0.5, 0.0), 1.0);
        assert_eq!(suitability(&sp, 250.0, 30.0, 0.5, 0.0), 0.0);
        assert_eq!(suitability(&sp, 150.0, 30.0, -0.5, 0.0), 0.0);
        assert!((suitability(&sp, 105.0, 0.0, 0.5, 0.0) - 0.5).abs() < 1e-6);
        assert_eq!(viability_gate(0.0, 0.2), 0.0);
        assert_eq!(viability_gate(0.3, 0.2), 1.0);
        assert!((viability_gate(0.1, 0.2) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn redistribution_keeps_block_sums_and_follows_the_weight() {
        // Global origin (1, 0): local row 0 is the lower half of block row 0, rows 1–2 form block
        // row 1. Worked by hand.
        let mut d = ndarray::array![[0.4f32, 0.4, 0.2], [0.5, 0.5, 0.3], [0.5, 0.5, 0.1]];
        let g = ndarray::array![[1.0f32, 0.0, 0.5], [1.0, 0.25, 0.0], [0.5, 0.25, 0.0]];
        redistribute_in_blocks(&mut d, &g, 1, 0);
        // Block {(0,0), (0,1)}: sum 0.8, weighted 0.4, so child 0 gets 0.4·1·2 = 0.8, child 1 0.
        assert_eq!(d.row(0).to_vec()[..2], [0.8, 0.0]);
        // Block {(0,2)} alone: kept.
        assert_eq!(d[[0, 2]], 0.2);
        // Block rows 1–2, columns 0–1: sum 2.0, weighted 0.5 + 0.125 + 0.25 + 0.125 = 1.0.
        assert_eq!(d[[1, 0]], 1.0);
        assert_eq!(d[[1, 1]], 0.25);
        assert_eq!(d[[2, 0]], 0.5);
        assert_eq!(d[[2, 1]], 0.25);
        // Column 2 of rows 1–2: all weights 0, the density is lost.
        assert_eq!((d[[1, 2]], d[[2, 2]]), (0.0, 0.0));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
        #[test]
        fn suitability_grid_equals_the_pointwise_suitability_bit_for_bit(
            rows in 0usize..24,
            cols in 0usize..24,
            salt in 0u64..1000,
        ) {
            let sp: Species = toml::from_str(
                r#"
                name = "spruce"
                elevation = { min = 1500, max = 2900, falloff = 250 }
                slope = { min = -1, max = 40, falloff = 8 }
                northness = { min = -0.2, max = 1.1, falloff = 0.4 }
                wetness = { min = 3, max = 30, falloff = 1 }
                "#,
            )
            .unwrap();
            let grid = |k: u64, lo: f32, hi: f32| {
                Array2::from_shape_fn((rows, cols), |(r, c)| {
                    let h = mix64(salt ^ (k << 48) ^ ((r as u64) << 24) ^ c as u64);
                    lo + (hi - lo) * ((h >> 40) as f32 / (1u64 << 24) as f32)
                })
            };
            let (e, s, n, w) = (
                grid(1, 1000.0, 3400.0),
                grid(2, 0.0, 60.0),
                grid(3, -1.0, 1.0),
                grid(4, 1.0, 9.0),
            );
            let fast = suitability_grid(&sp, &e, &s, &n, &w);
            for ((r, c), v) in fast.indexed_iter() {
                let want = suitability(&sp, e[[r, c]], s[[r, c]], n[[r, c]], w[[r, c]]);
                proptest::prop_assert_eq!(v.to_bits(), want.to_bits(), "({}, {})", r, c);
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        #[test]
        fn cluster_densities_equal_their_naive_twin(
            rows in 0usize..40,
            cols in 0usize..40,
            row0 in -1000i64..1000,
            col0 in -1000i64..1000,
            stream in 0u64..8,
            salt in 0u64..1000,
        ) {
            // Suitability with zeros, negatives, ones and fractions, as real grids have.
            let suit = Array2::from_shape_fn((rows, cols), |(r, c)| {
                let h = mix64(salt ^ ((r as u64) << 32) ^ c as u64);
                match h % 5 {
                    0 => 0.0,
                    1 => -0.25,
                    2 => 1.0,
                    _ => (h >> 40) as f32 / (1u64 << 24) as f32,
                }
            });
            let cl = Clustering::default();
            let fast = cluster_densities(&suit, row0, col0, &cl, stream);
            let naive = cluster_densities_naive(&suit, row0, col0, &cl, stream);
            let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            proptest::prop_assert_eq!(fast.dim(), naive.dim());
            proptest::prop_assert_eq!(bits(&fast), bits(&naive));
        }
    }

    #[test]
    fn clusters_are_patchy_zero_where_unsuitable_and_window_invariant_inside() {
        let cl = Clustering::default();
        let suit = Array2::from_shape_fn((64, 64), |(r, _)| if r < 32 { 1.0 } else { 0.0 });
        let d = cluster_densities(&suit, 10, -5, &cl, 3);
        assert!(d.slice(ndarray::s![32.., ..]).iter().all(|&v| v == 0.0));
        let top: Vec<f32> = d.slice(ndarray::s![..30, ..]).iter().copied().collect();
        let min = top.iter().cloned().fold(f32::MAX, f32::min);
        let max = top.iter().cloned().fold(f32::MIN, f32::max);
        assert!(min >= cl.floor - 1e-6 && max <= 1.0);
        assert!(max - min > 0.2, "patchy: {min}..{max}");
        // Same inputs, same bits.
        assert_eq!(d, cluster_densities(&suit, 10, -5, &cl, 3));
        // Another origin gives other patches.
        assert_ne!(d, cluster_densities(&suit, 11, -5, &cl, 3));
    }
}
