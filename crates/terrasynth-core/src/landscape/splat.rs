//! Splat and colour maps (DESIGN.md method 4): per material a weight that is the product of its
//! weight curves over the pixel's parameters, modulated by a deterministic value noise of
//! geographic position; weights normalised to sum 1 (a pixel no material admits goes wholly to the
//! fallback material); quantised so that the bytes of all sets sum to exactly 255; and the colour
//! `Σ w_m colour_m`.

use ndarray::Array2;

use super::model::{LandscapeConfig, Material, Trapezoid};
use crate::dictionary::rng::{hash2, mix64, to_unit_f64};

/// The parameters of a block of pixels, all arrays of one shape.
#[derive(Clone, Debug)]
pub struct LayerInputs<'a> {
    /// Elevation, metres.
    pub elevation: &'a Array2<f32>,
    /// Slope, degrees.
    pub slope: &'a Array2<f32>,
    /// Northness, −1..1.
    pub northness: &'a Array2<f32>,
    /// Curvature, 1/m.
    pub curvature: &'a Array2<f32>,
    /// Wetness, log10 m².
    pub wetness: &'a Array2<f32>,
    /// Vegetation densities in species order.
    pub vegetation: &'a [Array2<f32>],
    /// Land-cover class weights by class name (`class.<name>` terms; empty for a world without
    /// classes), and painted biome weights under `biome.<name>` (`biome.<name>` terms,
    /// [`super::vegetation::biome_key`]).
    pub classes: &'a [(String, Array2<f32>)],
    /// Global pixel coordinates `(row, col)` of element `(0, 0)`.
    pub origin: (i64, i64),
    /// Web Mercator metres per pixel (places the noise geographically).
    pub pixel_m: f64,
}

/// Value noise in [−1, 1] at Mercator metres `(x, y)` with wavelength `scale` (smoothstep
/// interpolation of hashed lattice values), point by point: the reference of [`SweptNoise`],
/// which the weights use.
#[cfg(test)]
fn value_noise(seed: u64, x: f64, y: f64, scale: f64) -> f32 {
    let (u, v) = (x / scale, y / scale);
    let (i, j) = (u.floor(), v.floor());
    interpolate(
        &lattice(seed, i as i64, j as i64),
        smooth(u - i),
        smooth(v - j),
    )
}

/// The hashed values in [−1, 1] at the corners `(i, j)`, `(i + 1, j)`, `(i, j + 1)` and
/// `(i + 1, j + 1)` of a lattice cell.
fn lattice(seed: u64, i: i64, j: i64) -> [f64; 4] {
    let h = |a: i64, b: i64| 2.0 * to_unit_f64(hash2(seed, a, b)) - 1.0;
    [h(i, j), h(i + 1, j), h(i, j + 1), h(i + 1, j + 1)]
}

/// The smoothstep `t²(3 − 2t)` of a lattice fraction.
fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

/// Interpolation of a lattice cell's corner values at smoothstepped fractions `(su, sv)`.
fn interpolate(h: &[f64; 4], su: f64, sv: f64) -> f32 {
    let top = h[0] + (h[1] - h[0]) * su;
    let bot = h[2] + (h[3] - h[2]) * su;
    (top + (bot - top) * sv) as f32
}

/// A lattice coordinate `u` split into its cell and its smoothstepped fraction.
fn cell_of(u: f64) -> (i64, f64) {
    let i = u.floor();
    (i as i64, smooth(u - i))
}

/// [`value_noise`] of one seed and wavelength over the pixels of a block: each column's lattice
/// cell and fraction are computed once, each row's once, and the corner values of the last cell
/// read are kept, so that a row of pixels hashes each cell once. Equal bit for bit to
/// `value_noise`.
struct SweptNoise {
    seed: u64,
    scale: f64,
    /// Per column of the block: its lattice cell and smoothstepped fraction.
    columns: Vec<(i64, f64)>,
    cell: Option<(i64, i64, [f64; 4])>,
}

impl SweptNoise {
    /// The noise over columns at Mercator metres `xs`.
    fn new(seed: u64, scale: f64, xs: impl Iterator<Item = f64>) -> Self {
        Self {
            seed,
            scale,
            columns: xs.map(|x| cell_of(x / scale)).collect(),
            cell: None,
        }
    }

    /// The lattice cell and fraction of a row at Mercator metres `y`.
    fn row(&self, y: f64) -> (i64, f64) {
        cell_of(y / self.scale)
    }

    /// The noise at column `c` of row `row` ([`SweptNoise::row`]).
    fn value(&mut self, c: usize, row: (i64, f64)) -> f32 {
        let (ci, su) = self.columns[c];
        let (cj, sv) = row;
        let corners = match self.cell {
            Some((a, b, h)) if a == ci && b == cj => h,
            _ => {
                let h = lattice(self.seed, ci, cj);
                self.cell = Some((ci, cj, h));
                h
            }
        };
        interpolate(&corners, su, sv)
    }
}

/// One material's weight terms with their inputs resolved once per block: the grid each
/// vegetation, class and biome term reads (`None`: the term reads 0), in the order
/// `raw_weight` multiplies them.
struct CompiledMaterial<'a> {
    material: &'a Material,
    vegetation: Vec<(Option<&'a Array2<f32>>, &'a Trapezoid)>,
    class: Vec<(Option<&'a Array2<f32>>, &'a Trapezoid)>,
    biome: Vec<(Option<&'a Array2<f32>>, &'a Trapezoid)>,
    noise: Option<SweptNoise>,
}

impl<'a> CompiledMaterial<'a> {
    fn new(k: usize, m: &'a Material, cfg: &'a LandscapeConfig, inp: &LayerInputs<'a>) -> Self {
        let vegetation = m
            .vegetation
            .iter()
            .map(|(name, t)| {
                let grid = cfg
                    .species
                    .iter()
                    .position(|sp| &sp.name == name)
                    .and_then(|k| inp.vegetation.get(k));
                (grid, t)
            })
            .collect();
        // Class weights by name, biome weights under their key (`biome.<name>`).
        let named = |key: &str| inp.classes.iter().find(|(n, _)| n == key).map(|(_, a)| a);
        let class = m.class.iter().map(|(name, t)| (named(name), t)).collect();
        let biome = m
            .biome
            .iter()
            .map(|(name, t)| (named(&super::vegetation::biome_key(name)), t))
            .collect();
        let cols = inp.elevation.ncols() as i64;
        let noise = (m.spread > 0.0).then(|| {
            let xs = (0..cols).map(|c| ((inp.origin.1 + c) as f64 + 0.5) * inp.pixel_m);
            SweptNoise::new(mix64(0x5b1a7 ^ k as u64), f64::from(m.spread_scale_m), xs)
        });
        Self {
            material: m,
            vegetation,
            class,
            biome,
            noise,
        }
    }

    /// The material's modulated weights along row `r` of the block into `v` (one per column):
    /// `raw_weight` times the noise factor, term by term over the row (each pixel's product
    /// taken in `raw_weight`'s order). `y` is the row's Mercator metres.
    fn weights_of_row(&mut self, inp: &LayerInputs<'_>, r: usize, y: f64, v: &mut [f32]) {
        let m = self.material;
        v.fill(1.0);
        for (t, grid) in [
            (m.elevation, inp.elevation),
            (m.slope, inp.slope),
            (m.northness, inp.northness),
            (m.curvature, inp.curvature),
            (m.wetness, inp.wetness),
        ] {
            if let Some(t) = t {
                multiply_row(v, &t, Some(grid), r);
            }
        }
        for terms in [&self.vegetation, &self.class, &self.biome] {
            for (grid, t) in terms {
                multiply_row(v, t, *grid, r);
            }
        }
        if let Some(noise) = &mut self.noise {
            let row = noise.row(y);
            for (c, o) in v.iter_mut().enumerate() {
                if *o > 0.0 {
                    *o *= (1.0 + m.spread * noise.value(c, row)).max(0.0);
                }
            }
        }
    }
}

/// Multiplies `v` by the weight of trapezoid `t` of row `r` of `grid` (`None`: of 0).
fn multiply_row(v: &mut [f32], t: &Trapezoid, grid: Option<&Array2<f32>>, r: usize) {
    match grid {
        Some(a) => {
            for (o, &x) in v.iter_mut().zip(a.row(r)) {
                *o *= t.weight(x);
            }
        }
        None => {
            let w = t.weight(0.0);
            for o in v.iter_mut() {
                *o *= w;
            }
        }
    }
}

/// Normalised material weights (one grid per material, summing to 1 at every pixel). Each
/// material's terms are resolved to their grids once (`CompiledMaterial`) and its noise keeps
/// the lattice cell it last read; equal bit for bit to the plain per-pixel evaluation.
pub fn material_weights(cfg: &LandscapeConfig, inp: &LayerInputs<'_>) -> Vec<Array2<f32>> {
    let (rows, cols) = inp.elevation.dim();
    let nm = cfg.materials.len();
    let fallback = cfg.fallback_index();
    let mut compiled: Vec<CompiledMaterial<'_>> = cfg
        .materials
        .iter()
        .enumerate()
        .map(|(k, m)| CompiledMaterial::new(k, m, cfg, inp))
        .collect();
    let mut out: Vec<Array2<f32>> = (0..nm).map(|_| Array2::zeros((rows, cols))).collect();
    if cols == 0 {
        return out;
    }
    // Row `r`'s weights, material after material, and their sums.
    let mut w = vec![0.0f32; nm * cols];
    let mut total = vec![0.0f32; cols];
    for r in 0..rows {
        let y = ((inp.origin.0 + r as i64) as f64 + 0.5) * inp.pixel_m;
        total.fill(0.0);
        for (row, m) in w.chunks_exact_mut(cols).zip(&mut compiled) {
            m.weights_of_row(inp, r, y, row);
            for (t, &v) in total.iter_mut().zip(row.iter()) {
                *t += v;
            }
        }
        for (k, (o, row)) in out.iter_mut().zip(w.chunks_exact(cols)).enumerate() {
            let mut o = o.row_mut(r);
            for ((o, &v), &t) in o.iter_mut().zip(row).zip(&total) {
                *o = if t > 0.0 {
                    v / t
                } else if k == fallback {
                    1.0
                } else {
                    0.0
                };
            }
        }
    }
    out
}

/// The unnormalised weight of material `m` at one pixel (the plain evaluation).
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
fn raw_weight(
    m: &Material,
    cfg: &LandscapeConfig,
    e: f32,
    s: f32,
    n: f32,
    c: f32,
    w: f32,
    veg: &dyn Fn(usize) -> f32,
    class: &dyn Fn(&str) -> f32,
    biome: &dyn Fn(&str) -> f32,
) -> f32 {
    let mut out = 1.0f32;
    for (t, x) in [
        (m.elevation, e),
        (m.slope, s),
        (m.northness, n),
        (m.curvature, c),
        (m.wetness, w),
    ] {
        if let Some(t) = t {
            out *= t.weight(x);
        }
    }
    for (name, t) in &m.vegetation {
        let d = cfg
            .species
            .iter()
            .position(|sp| &sp.name == name)
            .map_or(0.0, veg);
        out *= t.weight(d);
    }
    for (name, t) in &m.class {
        out *= t.weight(class(name));
    }
    for (name, t) in &m.biome {
        out *= t.weight(biome(name));
    }
    out
}

/// [`material_weights`] written plainly, every term looked up by name at every pixel: the
/// reference the compiled version is tested against.
#[cfg(test)]
fn material_weights_naive(cfg: &LandscapeConfig, inp: &LayerInputs<'_>) -> Vec<Array2<f32>> {
    let (rows, cols) = inp.elevation.dim();
    let nm = cfg.materials.len();
    let fallback = cfg.fallback_index();
    let mut out: Vec<Array2<f32>> = (0..nm).map(|_| Array2::zeros((rows, cols))).collect();
    let mut w = vec![0.0f32; nm];
    for r in 0..rows {
        let y = (inp.origin.0 + r as i64) as f64 + 0.5;
        for c in 0..cols {
            let x = (inp.origin.1 + c as i64) as f64 + 0.5;
            let veg = |k: usize| inp.vegetation.get(k).map_or(0.0, |a| a[[r, c]]);
            let class = |name: &str| {
                inp.classes
                    .iter()
                    .find(|(n, _)| n == name)
                    .map_or(0.0, |(_, a)| a[[r, c]])
            };
            let biome = |name: &str| {
                inp.classes
                    .iter()
                    .find(|(n, _)| n.strip_prefix(super::vegetation::BIOME_PREFIX) == Some(name))
                    .map_or(0.0, |(_, a)| a[[r, c]])
            };
            let mut total = 0.0f32;
            for (k, m) in cfg.materials.iter().enumerate() {
                let mut v = raw_weight(
                    m,
                    cfg,
                    inp.elevation[[r, c]],
                    inp.slope[[r, c]],
                    inp.northness[[r, c]],
                    inp.curvature[[r, c]],
                    inp.wetness[[r, c]],
                    &veg,
                    &class,
                    &biome,
                );
                if v > 0.0 && m.spread > 0.0 {
                    let seed = mix64(0x5b1a7 ^ k as u64);
                    let nz = value_noise(
                        seed,
                        x * inp.pixel_m,
                        y * inp.pixel_m,
                        f64::from(m.spread_scale_m),
                    );
                    v *= (1.0 + m.spread * nz).max(0.0);
                }
                w[k] = v;
                total += v;
            }
            for (k, o) in out.iter_mut().enumerate() {
                o[[r, c]] = if total > 0.0 {
                    w[k] / total
                } else if k == fallback {
                    1.0
                } else {
                    0.0
                };
            }
        }
    }
    out
}

/// Quantises normalised weights to bytes summing to exactly 255 (largest remainder; ties to the
/// lowest index). A zero weight stays 0.
pub fn quantise_weights(w: &[f32], out: &mut [u8]) {
    let mut sum = 0u32;
    for (o, &v) in out.iter_mut().zip(w) {
        let q = (v.max(0.0) * 255.0).floor().min(255.0);
        *o = q as u8;
        sum += u32::from(*o);
    }
    // Hand out the deficit to the largest remainders among positive weights.
    while sum < 255 {
        let mut best: Option<(usize, f32)> = None;
        for (k, &v) in w.iter().enumerate() {
            if v > 0.0 && out[k] < 255 {
                let rem = v * 255.0 - f32::from(out[k]);
                if best.is_none_or(|(_, b)| rem > b) {
                    best = Some((k, rem));
                }
            }
        }
        match best {
            Some((k, _)) => out[k] += 1,
            None => break,
        }
        sum += 1;
    }
    while sum > 255 {
        let k = (0..out.len()).max_by_key(|&k| out[k]).unwrap_or(0);
        out[k] -= 1;
        sum -= 1;
    }
}

/// The colour `Σ w_m colour_m` of normalised weights `w`, as `f32` RGB in 0..255.
pub fn colour_of(cfg: &LandscapeConfig, w: &[f32]) -> [f32; 3] {
    let mut rgb = [0.0f32; 3];
    for (m, &v) in cfg.materials.iter().zip(w) {
        for (o, &c) in rgb.iter_mut().zip(&m.colour) {
            *o += v * f32::from(c);
        }
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_weights_sum_to_255_and_keep_zeros() {
        let cases: [&[f32]; 4] = [
            &[1.0, 0.0, 0.0],
            &[1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            &[0.5, 0.0, 0.25, 0.25, 0.0],
            &[0.001, 0.999, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ];
        for w in cases {
            let mut q = vec![0u8; w.len()];
            quantise_weights(w, &mut q);
            assert_eq!(q.iter().map(|&v| u32::from(v)).sum::<u32>(), 255, "{w:?}");
            for (a, b) in w.iter().zip(&q) {
                if *a == 0.0 {
                    assert_eq!(*b, 0);
                }
                assert!((f32::from(*b) - a * 255.0).abs() <= 1.0);
            }
        }
    }

    #[test]
    fn class_terms_make_weights_follow_the_classes() {
        // Two materials: `meadow` admits class weights of `grass` in [0.5, 1] (a box), `scree`
        // those of `rock` in [0, 1] with falloff 0.5 (smoothstep up to weight 0.5).
        let toml = r#"
            [[materials]]
            name = "meadow"
            colour = [0, 200, 0]
            class.grass = { min = 0.5, max = 1.0 }
            [[materials]]
            name = "scree"
            colour = [120, 120, 120]
            class.rock = { min = 0.0, max = 2.0, falloff = 1.0 }
        "#;
        let cfg: LandscapeConfig = toml::from_str(toml).unwrap();
        cfg.validate().unwrap();
        cfg.check_classes(&["grass".into(), "rock".into()]).unwrap();
        let e = cfg
            .check_classes(&["grass".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("scree") && e.contains("`rock`"), "{e}");
        let z = Array2::zeros((1, 4));
        // Pixels: grass 1 / rock 0; grass 0.6 / rock 0.4; grass 0.2 / rock 0.8; neither.
        let grass = ndarray::arr2(&[[1.0f32, 0.6, 0.2, 0.0]]);
        let rock = ndarray::arr2(&[[0.0f32, 0.4, 0.8, 0.0]]);
        let classes = vec![("grass".to_string(), grass), ("rock".to_string(), rock)];
        let inp = LayerInputs {
            elevation: &z,
            slope: &z,
            northness: &z,
            curvature: &z,
            wetness: &z,
            vegetation: &[],
            classes: &classes,
            origin: (0, 0),
            pixel_m: 1.0,
        };
        let w = material_weights(&cfg, &inp);
        // By hand. Pixel 0: meadow 1 (1 in [0.5, 1]), scree 0 (rock 0 is the range's end) →
        // (1, 0). Pixel 1: meadow 1, scree t = 0.4 → 0.4²(3 − 0.8) = 0.352 → normalised
        // (1/1.352, 0.352/1.352). Pixel 2: meadow 0 (0.2 < 0.5), scree t = 0.8 → 0.896 → (0, 1).
        // Pixel 3: neither admits it → the fallback (the first material).
        let want = [
            (1.0, 0.0),
            (1.0 / 1.352, 0.352 / 1.352),
            (0.0, 1.0),
            (1.0, 0.0),
        ];
        for (c, (a, b)) in want.iter().enumerate() {
            assert!(
                (w[0][[0, c]] - a).abs() < 1e-5,
                "meadow {c}: {}",
                w[0][[0, c]]
            );
            assert!(
                (w[1][[0, c]] - b).abs() < 1e-5,
                "scree {c}: {}",
                w[1][[0, c]]
            );
        }
    }

    /// A landscape whose materials use every kind of term: ranges of every parameter, a
    /// species term (and one naming a species the block lacks), class and biome terms (and ones
    /// naming grids the block lacks), noise of several wavelengths, and one material admitting
    /// nothing, so that some pixels fall back.
    const ALL_TERMS: &str = r#"
        [[species]]
        name = "pine"
        [[species]]
        name = "fern"
        [[materials]]
        name = "rock"
        colour = [120, 112, 105]
        slope = { min = 18, max = 91, falloff = 12 }
        elevation = { min = 100, max = 900, falloff = 150 }
        spread = 0.4
        spread_scale_m = 700
        [[materials]]
        name = "forest"
        colour = [45, 75, 40]
        vegetation = { pine = { min = 0.05, max = 1.01, falloff = 0.3 }, fern = { min = -1, max = 0.8, falloff = 0.3 } }
        northness = { min = -0.5, max = 1.0, falloff = 0.2 }
        spread = 0.2
        spread_scale_m = 90
        [[materials]]
        name = "marsh"
        colour = [70, 95, 110]
        wetness = { min = 3.0, max = 30, falloff = 1 }
        curvature = { min = -1, max = 0.002, falloff = 0.001 }
        class.wet = { min = 0.2, max = 1.0, falloff = 0.1 }
        biome.lowland = { min = 0.1, max = 1.0 }
        [[materials]]
        name = "missing"
        colour = [1, 2, 3]
        class.absent = { min = 0.5, max = 1.0 }
        biome.absent = { min = -1.0, max = 1.0 }
        spread = 0.9
        spread_scale_m = 40
    "#;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        #[test]
        fn compiled_weights_equal_the_plain_evaluation_bit_for_bit(
            rows in 0usize..24,
            cols in 0usize..24,
            row0 in -3000i64..3000,
            col0 in -3000i64..3000,
            pixel_m in 0.5f64..60.0,
            seed in proptest::prelude::any::<u64>(),
        ) {
            let cfg: LandscapeConfig = toml::from_str(ALL_TERMS).unwrap();
            let grid = |k: u64, lo: f32, hi: f32| {
                Array2::from_shape_fn((rows, cols), |(r, c)| {
                    let u = to_unit_f64(hash2(seed ^ k, r as i64, c as i64)) as f32;
                    lo + (hi - lo) * u
                })
            };
            let (elevation, slope) = (grid(1, 0.0, 1000.0), grid(2, 0.0, 60.0));
            let (northness, curvature) = (grid(3, -1.0, 1.0), grid(4, -0.004, 0.004));
            let wetness = grid(5, 1.0, 9.0);
            // Only the first species has a grid: the `fern` term reads 0.
            let vegetation = vec![grid(6, 0.0, 1.0)];
            let classes = vec![
                ("wet".to_string(), grid(7, 0.0, 1.0)),
                (super::super::vegetation::biome_key("lowland"), grid(8, 0.0, 1.0)),
            ];
            let inp = LayerInputs {
                elevation: &elevation,
                slope: &slope,
                northness: &northness,
                curvature: &curvature,
                wetness: &wetness,
                vegetation: &vegetation,
                classes: &classes,
                origin: (row0, col0),
                pixel_m,
            };
            let fast = material_weights(&cfg, &inp);
            let naive = material_weights_naive(&cfg, &inp);
            proptest::prop_assert_eq!(fast.len(), naive.len());
            for (k, (a, b)) in fast.iter().zip(&naive).enumerate() {
                for ((r, c), v) in a.indexed_iter() {
                    proptest::prop_assert_eq!(
                        v.to_bits(), b[[r, c]].to_bits(), "material {} at ({}, {})", k, r, c
                    );
                }
            }
        }
    }

    #[test]
    fn swept_noise_equals_the_noise_bit_for_bit() {
        let xs: Vec<f64> = (-400..400).map(|k| f64::from(k) * 7.3).collect();
        let mut swept = SweptNoise::new(11, 350.0, xs.iter().copied());
        for k in 0..40 {
            let y = 1000.0 + f64::from(k) * 91.1;
            let row = swept.row(y);
            for (c, &x) in xs.iter().enumerate() {
                assert_eq!(
                    swept.value(c, row).to_bits(),
                    value_noise(11, x, y, 350.0).to_bits(),
                    "({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn noise_is_bounded_and_continuous() {
        for k in 0..200 {
            let x = k as f64 * 37.3;
            let a = value_noise(9, x, 2.0 * x, 500.0);
            let b = value_noise(9, x + 0.5, 2.0 * x, 500.0);
            assert!((-1.0..=1.0).contains(&a));
            assert!((a - b).abs() < 0.01);
        }
    }
}
