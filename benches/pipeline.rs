//! Criterion benchmarks of the pipeline on deterministic real data (the embedded Tien Shan grid):
//! matching (patches per second) and one amplification level (output points per second) with a
//! warm default dictionary; OMP (codes per second at sparsity 1, 4 and 8 over the default
//! dictionary's high-resolution atoms), compact-terrain decoding (output points per second) and
//! the instances of a zoom-15 forest tile (instances per second); one gradient-domain level
//! (`gradient_level`, output points per second, issue #20) with a default tile set built from the
//! same grid; the drainage routing of one tile's region (`routing`: Priority-Flood+ε, D8
//! receivers, accumulation, and the layer's Priority-Flood to the spill levels and D8 receivers
//! with the flats resolved, on 512² of the real terrain; `routing/512² amplified`: the layer's
//! routing on one amplification level of it, whose continuous heights are the drainage tiles').
//! Run with `cargo bench --bench pipeline` (or `-- omp`, `-- compact`, `-- instances`, `-- gradient_level`, `-- routing` for a part).

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use ndarray::{s, Array2};
use terrasynth_core::dictionary::build::{build, BuildOptions, Exemplar};
use terrasynth_core::dictionary::derive::derived_layers;
use terrasynth_core::dictionary::features::centre_normalise;
use terrasynth_core::dictionary::format::{read_dictionary, write_dictionary};
use terrasynth_core::dictionary::matching::{best_match_naive, MatchScratch, Query};
use terrasynth_core::dictionary::{Dictionary, MatchWeights, Matcher};
use terrasynth_core::raster::embedded;
use terrasynth_core::synth::{Amplifier, Field, GradientAmplifier, Window};

/// The default dictionary (embedded exemplar, default options, derived layers), cached under
/// `target/` so that repeated bench runs do not rebuild it.
fn default_dictionary(base: &Array2<f32>, cell_m: f64, derived: bool) -> Dictionary {
    let name = if derived {
        "bench-default.dict"
    } else {
        "bench-elevation.dict"
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("target")
        .join(name);
    if let Ok(f) = std::fs::File::open(&path) {
        if let Ok(d) = read_dictionary(std::io::BufReader::new(f), 1 << 32) {
            return d;
        }
    }
    let grid = embedded::tienshan().expect("embedded grid");
    let layers = if derived {
        derived_layers(base, &grid.georef.cell_sizes(grid.rows()))
    } else {
        Vec::new()
    };
    let ex = Exemplar {
        elevation: base.clone(),
        valid: None,
        cell_m,
        layers,
    };
    let d = build(&[ex], &BuildOptions::default(), &mut |_, _| {}).expect("build");
    let mut bytes = Vec::new();
    write_dictionary(&d, &mut bytes).expect("serialise");
    let _ = std::fs::write(&path, bytes);
    d
}

/// The elevation of `base` over window `need` (an amplifier's parent window inside it).
fn parent_field(base: &Array2<f32>, need: Window) -> Field {
    let (r, c) = (need.row0 as usize, need.col0 as usize);
    Field::elevation_only(
        need,
        base.slice(s![r..r + need.rows, c..c + need.cols])
            .to_owned(),
    )
}

fn bench(c: &mut Criterion) {
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let cell_m = grid.georef.cell_sizes(grid.rows()).mean_cell();
    let weights = MatchWeights::default();

    for derived in [false, true] {
        let dict = std::sync::Arc::new(default_dictionary(&base, cell_m, derived));
        let label = if derived { "default" } else { "elevation-only" };

        // Matching: low patches of the real terrain as queries.
        let matcher = Matcher::new(dict.clone(), &weights).expect("matcher");
        let lo = dict.lo_patch();
        let queries: Vec<Query> = (0..1024)
            .map(|k| {
                let (r, c) = (100 + (k / 32) * 53, 100 + (k % 32) * 79);
                let raw: Vec<f32> = base
                    .slice(s![r..r + lo, c..c + lo])
                    .iter()
                    .cloned()
                    .collect();
                let mut q = Query {
                    elevation: vec![0.0; lo * lo],
                    ..Query::default()
                };
                let (m, _) = centre_normalise(&raw, &mut q.elevation);
                q.mean_alt = m;
                q
            })
            .collect();
        let mut g = c.benchmark_group(format!("matching/{label}"));
        g.throughput(Throughput::Elements(queries.len() as u64));
        g.bench_function("fast", |b| {
            let mut scratch = MatchScratch::default();
            b.iter(|| {
                queries
                    .iter()
                    .map(|q| matcher.best_match(q, &mut scratch).0)
                    .sum::<usize>()
            })
        });
        g.bench_function("naive", |b| {
            b.iter(|| {
                queries
                    .iter()
                    .map(|q| best_match_naive(&matcher, q).0)
                    .sum::<usize>()
            })
        });
        g.finish();

        // One amplification level: output windows of the real terrain.
        let amp = Amplifier::new(dict.clone(), &weights).expect("amplifier");
        let mut g = c.benchmark_group(format!("amplify_level/{label}"));
        for side in [256usize, 1024] {
            let out = Window::new(1000, 1200, side, side);
            let parent = parent_field(&base, amp.parent_window_for(out));
            g.throughput(Throughput::Elements(out.len() as u64));
            g.bench_with_input(BenchmarkId::from_parameter(side), &parent, |b, p| {
                b.iter(|| amp.amplify(p, out, cell_m as f32).expect("amplify"))
            });
        }
        g.finish();
    }
}

fn bench_sparse(c: &mut Criterion) {
    use terrasynth_core::dictionary::omp::{Omp, OmpScratch};
    use terrasynth_core::synth::compact::compress;
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let cell_m = grid.georef.cell_sizes(grid.rows()).mean_cell();
    let dict = default_dictionary(&base, cell_m, true);
    let atoms = terrasynth_core::synth::compact::unit_hi_atoms(&dict);
    let p = dict.patch();
    // 1024 real 16² windows, centred, as signals.
    let signals: Vec<Vec<f32>> = (0..1024)
        .map(|k| {
            let (r, col) = (100 + (k / 32) * 53, 100 + (k % 32) * 79);
            let w: Vec<f32> = base
                .slice(s![r..r + p, col..col + p])
                .iter()
                .cloned()
                .collect();
            let mean = w.iter().sum::<f32>() / w.len() as f32;
            w.iter().map(|v| v - mean).collect()
        })
        .collect();
    let omp = Omp::new(&atoms, p * p);
    let mut g = c.benchmark_group("omp/default-dictionary");
    g.throughput(Throughput::Elements(signals.len() as u64));
    for sparsity in [1usize, 4, 8] {
        g.bench_with_input(BenchmarkId::from_parameter(sparsity), &sparsity, |b, &s| {
            let mut scratch = OmpScratch::default();
            b.iter(|| {
                signals
                    .iter()
                    .map(|y| omp.code(y, s, &mut scratch).len())
                    .sum::<usize>()
            })
        });
    }
    g.finish();
    // Decoding a 1024² compact terrain (sparsity 4).
    let crop = base.slice(s![600..1624, 1200..2224]).to_owned();
    let terrain = compress(&crop, &atoms, p, 4, 32.0, 0);
    let mut g = c.benchmark_group("compact/decode");
    g.throughput(Throughput::Elements(crop.len() as u64));
    g.bench_function("1024²,s=4", |b| b.iter(|| terrain.decode()));
    g.finish();
}

/// Instances (#17): every scattering rule of the default world over a zoom-15 tile (3.56 m
/// pixels at the Tien Shan's latitude) of forest — spruce density 0.8, juniper 0.2, meadow and
/// steppe 0.3, scree 0.2 — with its halo; instances generated per second.
fn bench_instances(c: &mut Criterion) {
    use terrasynth_core::landscape::scatter::{halo_px, scatter, RuleField};
    use terrasynth_core::landscape::LandscapeConfig;
    let l = LandscapeConfig::tienshan();
    let cell_m = 3.56;
    let halo = l
        .scatter
        .iter()
        .map(|r| halo_px(r, cell_m))
        .fold(0.0, f64::max) as usize;
    let n = 256 + 2 * halo;
    let value = |name: &str| match name {
        "spruce" => 0.8,
        "juniper" => 0.2,
        "meadow" | "steppe" => 0.3,
        "scree" => 0.2,
        _ => 0.0,
    };
    let (x, y) = (23187.0 * 256.0, 12082.0 * 256.0);
    let run = || {
        let mut count = 0;
        for (k, rule) in l.scatter.iter().enumerate() {
            let layers: Vec<Array2<f32>> = rule
                .source_names()
                .iter()
                .map(|s| Array2::from_elem((n, n), value(s)))
                .collect();
            let sources: Vec<&Array2<f32>> = layers.iter().collect();
            let field = RuleField {
                row0: y as i64 - halo as i64,
                col0: x as i64 - halo as i64,
                sources: &sources,
                exclude: &[],
                exclude_weight: 0.5,
            };
            count += scatter(rule, k as u64, cell_m, &field, [x, y, x + 256.0, y + 256.0]).len();
        }
        count
    };
    let count = run();
    let mut g = c.benchmark_group("instances");
    g.throughput(Throughput::Elements(count as u64));
    g.bench_function("z15 forest tile", |b| b.iter(run));
    g.finish();
}

/// One gradient-domain level on windows of the real terrain (elevation only).
fn bench_gradient(c: &mut Criterion) {
    use terrasynth_core::dictionary::{build_gradient_tiles, GradientParams};
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let set = build_gradient_tiles(std::slice::from_ref(&base), &GradientParams::default())
        .expect("tile set");
    let amp = GradientAmplifier::new(std::sync::Arc::new(set)).expect("amplifier");
    let mut g = c.benchmark_group("gradient_level");
    for side in [256usize, 1024] {
        let out = Window::new(1000, 1200, side, side);
        let need = amp.parent_window_for(out);
        let parent = Field::elevation_only(
            need,
            base.slice(s![
                need.row0 as usize..need.row0 as usize + need.rows,
                need.col0 as usize..need.col0 as usize + need.cols
            ])
            .to_owned(),
        );
        g.throughput(Throughput::Elements(out.len() as u64));
        g.bench_with_input(BenchmarkId::from_parameter(side), &parent, |b, p| {
            b.iter(|| amp.amplify(p, out, 100.0).expect("amplify"))
        });
    }
    g.finish();
}

/// 512² of the real terrain (rows 600–1111, columns 900–1411 of the embedded grid) and its
/// cell sizes: the routing and layer benches' input.
fn real_terrain_512() -> (Array2<f32>, terrasynth_core::raster::CellSizes) {
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let z = base.slice(s![600..1112, 900..1412]).to_owned();
    let cells = grid.georef.cell_sizes(grid.rows());
    let cells = terrasynth_core::raster::CellSizes {
        dx: cells.dx[600..1112].to_vec(),
        dy: cells.dy[600..1112].to_vec(),
    };
    (z, cells)
}

/// The drainage layer's routing of one amplified tile's region up to zoom 13 (the tile and its
/// 128-px halo: 512²) on a window of the real terrain: Priority-Flood+ε, D8 receivers and the
/// accumulation, and the layer's routing, Priority-Flood to the spill levels and D8 receivers
/// with the flats resolved (cells per second).
fn bench_routing(c: &mut Criterion) {
    use terrasynth_core::analysis;
    let (z, cells) = real_terrain_512();
    let filled = analysis::priority_flood_fill(&z);
    let receivers = analysis::d8_receivers(&filled, &cells);
    let mut g = c.benchmark_group("routing/512²");
    g.throughput(Throughput::Elements(z.len() as u64));
    g.bench_function("priority_flood_fill", |b| {
        b.iter(|| analysis::priority_flood_fill(&z))
    });
    g.bench_function("d8_receivers", |b| {
        b.iter(|| analysis::d8_receivers(&filled, &cells))
    });
    bench_layer_routing(&mut g, &z, &cells, &receivers);
    g.finish();
}

/// The drainage layer's own routing of `z` (cells `cells`) in group `g`: Priority-Flood to the
/// spill levels, D8 receivers with the flats resolved (a 128-px span, the halo up to zoom 13),
/// and the accumulation of the cell areas along `receivers`.
fn bench_layer_routing(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    z: &Array2<f32>,
    cells: &terrasynth_core::raster::CellSizes,
    receivers: &Array2<u8>,
) {
    use terrasynth_core::analysis;
    let filled_flat = analysis::priority_flood_fill_flat(z);
    let sources = Array2::from_shape_fn(z.dim(), |(r, _)| cells.area(r));
    g.bench_function("priority_flood_fill_flat", |b| {
        b.iter(|| analysis::priority_flood_fill_flat(z))
    });
    g.bench_function("d8_receivers_over_flats", |b| {
        b.iter(|| analysis::d8_receivers_over_flats(&filled_flat, cells, 128, None))
    });
    g.bench_function("accumulate_sources", |b| {
        b.iter(|| analysis::accumulate_sources(receivers, &sources))
    });
}

/// The drainage layer's routing on a served-like region: one amplification level of the real
/// terrain with the default dictionary (512² out of the 256² at rows 600, columns 900 of the
/// embedded grid, the window `routing/512²` reads at full size). Its continuous heights route
/// slower per cell than the GEBCO window's whole metres, as the drainage tiles do (cells per
/// second): the layer's Priority-Flood to the spill levels, D8 receivers with the flats
/// resolved and the accumulation of the cell areas.
fn bench_routing_amplified(c: &mut Criterion) {
    use terrasynth_core::analysis;
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let cell_m = grid.georef.cell_sizes(grid.rows()).mean_cell();
    let dict = std::sync::Arc::new(default_dictionary(&base, cell_m, true));
    let amp = Amplifier::new(dict, &MatchWeights::default()).expect("amplifier");
    let out = Window::new(1800, 1200, 512, 512);
    let parent = parent_field(&base, amp.parent_window_for(out));
    let z = amp
        .amplify(&parent, out, cell_m as f32)
        .expect("amplify")
        .elevation;
    let half = cell_m / 2.0;
    let cells = terrasynth_core::raster::CellSizes {
        dx: vec![half; out.rows],
        dy: vec![half; out.rows],
    };
    let filled_flat = analysis::priority_flood_fill_flat(&z);
    let receivers = analysis::d8_receivers_over_flats(&filled_flat, &cells, 128, None);
    let mut g = c.benchmark_group("routing/512² amplified");
    g.throughput(Throughput::Elements(z.len() as u64));
    bench_layer_routing(&mut g, &z, &cells, &receivers);
    g.finish();
}

/// The default world's material weights (the splat, colour and instance tiles' per-pixel work)
/// and every species' niche suitability (the vegetation tiles') over 512² of the real terrain,
/// with the terrain's own slope, northness and curvature and uniform vegetation and wetness,
/// and the slope, northness and hillshade a landscape tile's terrain needs (pixels per second).
fn bench_layers(c: &mut Criterion) {
    use terrasynth_core::analysis;
    use terrasynth_core::landscape::{material_weights, LandscapeConfig, LayerInputs};
    let l = LandscapeConfig::tienshan();
    let (z, cells) = real_terrain_512();
    let slope = analysis::slope_degrees(&z, &cells);
    let northness = analysis::northness(&z, &cells);
    let curvature = analysis::curvature(&z, &cells);
    let wetness = Array2::from_elem(z.dim(), 6.5f32);
    let vegetation: Vec<Array2<f32>> = (0..l.species.len())
        .map(|k| Array2::from_elem(z.dim(), 0.15 * k as f32))
        .collect();
    let inp = LayerInputs {
        elevation: &z,
        slope: &slope,
        northness: &northness,
        curvature: &curvature,
        wetness: &wetness,
        vegetation: &vegetation,
        classes: &[],
        origin: (1_545_000, 2_975_000),
        pixel_m: 9.55,
    };
    let mut g = c.benchmark_group("layers/512²");
    g.throughput(Throughput::Elements(z.len() as u64));
    g.bench_function("material_weights", |b| {
        b.iter(|| material_weights(&l, &inp))
    });
    g.bench_function("suitability", |b| {
        b.iter(|| {
            l.species
                .iter()
                .map(|sp| {
                    terrasynth_core::landscape::vegetation::suitability_grid(
                        sp, &z, &slope, &northness, &wetness,
                    )
                })
                .collect::<Vec<_>>()
        })
    });
    // A landscape tile's terrain (`terrain::Terrain::of`): slope, northness and hillshade one
    // function at a time (three gradients), then from one gradient.
    let light = (
        analysis::DEFAULT_AZIMUTH_DEG,
        analysis::DEFAULT_ALTITUDE_DEG,
    );
    g.bench_function("slope_northness_shade/separate", |b| {
        b.iter(|| {
            (
                analysis::slope_degrees(&z, &cells),
                analysis::northness(&z, &cells),
                analysis::hillshade(&z, &cells, light.0, light.1),
            )
        })
    });
    g.bench_function("slope_northness_shade/fused", |b| {
        b.iter(|| analysis::slope_northness_shade(&z, &cells, light.0, light.1))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = bench, bench_sparse, bench_instances, bench_gradient, bench_routing,
        bench_routing_amplified, bench_layers
}
criterion_main!(benches);
