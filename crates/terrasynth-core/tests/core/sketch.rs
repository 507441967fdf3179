//! Sketch synthesis (`synth::sketch`): its kernels against their naive twins on random inputs
//! (exact Euclidean distance transform, FFT SSD search, maximum flow / minimum cut, Poisson
//! solve), and a sketch world made from a crop of the committed Tien Shan grid with acceptance 2
//! checked on it: sketched lines followed, no visible seams, the same bytes from two runs on
//! different thread counts, flood extent within the exemplar's.

use ndarray::{s, Array2};
use proptest::prelude::*;
use serde_json::json;
use terrasynth_core::analysis::{self, ppa::PpaParams};
use terrasynth_core::raster::{embedded, write_geotiff, Grid};
use terrasynth_core::synth::sketch::distance::{distance_transform, naive_transform};
use terrasynth_core::synth::sketch::geojson::parse_sketch;
use terrasynth_core::synth::sketch::graphcut::{naive_min_cut, FlowGraph, HARD};
use terrasynth_core::synth::sketch::poisson::{conjugate_gradient, naive_gauss_seidel};
use terrasynth_core::synth::sketch::ssd::{naive_costs, Offset, SsdIndex};
use terrasynth_core::synth::sketch::{
    quality, synthesize, OutputSpec, SizeLimits, SketchOptions, SketchWorld,
};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The two-pass lower-envelope transform gives exactly the brute-force distances, and a
    /// nearest site at that distance.
    #[test]
    fn distance_transform_equals_naive(
        (rows, cols, mask) in (1usize..20, 1usize..20).prop_flat_map(|(r, c)| {
            (Just(r), Just(c), proptest::collection::vec(proptest::bool::weighted(0.1), r * c))
        })
    ) {
        let fast = distance_transform(&mask, rows, cols);
        let slow = naive_transform(&mask, rows, cols);
        prop_assert_eq!(&fast.dist, &slow.dist);
        for i in 0..rows * cols {
            let s = fast.site[i];
            if s == usize::MAX {
                prop_assert!(slow.site[i] == usize::MAX);
                continue;
            }
            prop_assert!(mask[s]);
            let d = (((i / cols) as f64 - (s / cols) as f64).powi(2)
                + ((i % cols) as f64 - (s % cols) as f64).powi(2)).sqrt();
            prop_assert_eq!(d, fast.dist[i]);
        }
    }

    /// FFT correlations give the directly summed costs and offsets of every placement.
    #[test]
    fn fft_ssd_equals_naive(
        seed in 0u64..10_000,
        (er, ec, tr, tc) in (4usize..40, 4usize..40).prop_flat_map(|(r, c)| (Just(r), Just(c), 1..=r, 1..=c)),
        penalty in proptest::option::of(0.0f64..2.0),
    ) {
        let mut x = seed;
        let mut next = move || {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let e = Array2::from_shape_fn((er, ec), |_| (2000.0 + 800.0 * next()) as f32);
        let t = Array2::from_shape_fn((tr, tc), |_| 2000.0 + 800.0 * next());
        let m = Array2::from_shape_fn((tr, tc), |_| if next() < 0.3 { 0.0 } else { (next() * 4.0).floor() * 0.25 });
        let offset = penalty.map_or(Offset::None, Offset::Penalised);
        let fast = SsdIndex::new(&e).costs(&t, &m, offset).unwrap();
        let slow = naive_costs(&e, &t, &m, offset).unwrap();
        prop_assert_eq!((fast.rows, fast.cols), (slow.rows, slow.cols));
        let scale = slow.cost.iter().fold(1.0f64, |a, b| a.max(b.abs()));
        for (a, b) in fast.cost.iter().zip(&slow.cost) {
            prop_assert!((a - b).abs() <= 1e-9 * scale, "{} vs {}", a, b);
        }
        for (a, b) in fast.offset.iter().zip(&slow.offset) {
            prop_assert!((a - b).abs() <= 1e-6, "{} vs {}", a, b);
        }
    }

    /// Dinic's maximum flow equals the minimum cut found by trying every assignment, and the
    /// cut it returns costs exactly that.
    #[test]
    fn max_flow_equals_naive_min_cut(
        n in 2usize..11,
        edges in proptest::collection::vec((0usize..10, 0usize..10, 0u32..20), 0..30),
        terminals in proptest::collection::vec((0usize..10, 0u32..4, 0u32..4), 1..8),
    ) {
        let mut g = FlowGraph::new(n);
        for (a, b, c) in edges {
            g.add_edge(a % n, b % n, f64::from(c));
        }
        // Hard links as the seam placement makes them: a node is bound to one side at most.
        for (a, s, t) in terminals {
            let (to_s, to_t) = match (s, t) {
                (3, _) => (HARD, 0.0),
                (_, 3) => (0.0, HARD),
                _ => (f64::from(s) * 5.0, f64::from(t) * 5.0),
            };
            g.add_terminal(a % n, to_s, to_t);
        }
        let (best, _) = naive_min_cut(&g).unwrap();
        let flow = g.max_flow();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs());
        prop_assert!(close(flow, best), "flow {} cut {}", flow, best);
        prop_assert!(close(g.cut_cost(&g.source_side()), best));
    }

    /// Conjugate gradients and Gauss–Seidel sweeps agree on the screened Poisson correction.
    #[test]
    fn poisson_equals_naive(
        (rows, cols, b) in (1usize..12, 1usize..12).prop_flat_map(|(r, c)| {
            (Just(r), Just(c), proptest::collection::vec(-50.0f64..50.0, r * c))
        }),
        radius in 1.0f64..8.0,
    ) {
        let lambda = 1.0 / (radius * radius);
        let fast = conjugate_gradient(&b, rows, cols, lambda, 1e-13, 10_000);
        let slow = naive_gauss_seidel(&b, rows, cols, lambda, 1e-12, 200_000);
        for (a, s) in fast.iter().zip(&slow) {
            prop_assert!((a - s).abs() < 1e-6 * (1.0 + s.abs()), "{} vs {}", a, s);
        }
    }
}

/// The committed exemplar of these tests: the Talas and Kyrgyz ranges, 384 × 384 cells of the
/// embedded Tien Shan grid (columns 1600–1983, rows 600–983).
fn exemplar() -> Grid {
    let g = embedded::tienshan().unwrap();
    Grid::new(
        g.data.slice(s![600..984, 1600..1984]).to_owned(),
        g.georef.window(1600, 600),
    )
}

/// The test sketch: a branching ridge, a long valley south of it and two short valleys, on a
/// 256 × 256 grid of 15″ cells at 42° N.
fn sketch() -> terrasynth_core::synth::sketch::geometry::Sketch {
    let cell = 1.0 / 240.0;
    let grid = OutputSpec {
        west: 70.0,
        south: 42.0,
        east: 70.0 + 256.0 * cell,
        north: 42.0 + 256.0 * cell,
        cell_deg: cell,
    }
    .grid(&SizeLimits::default())
    .unwrap();
    let ll = |x: f64, y: f64| {
        let p = grid.to_lonlat([x * 256.0, y * 256.0]);
        json!([p[0], p[1]])
    };
    let line = |kind: &str, pts: &[(f64, f64)]| {
        json!({"type": "Feature", "properties": {"kind": kind}, "geometry": {"type": "LineString",
            "coordinates": pts.iter().map(|&(x, y)| ll(x, y)).collect::<Vec<_>>()}})
    };
    let fc = json!({"type": "FeatureCollection", "features": [
        line("ridge", &[(0.1, 0.5), (0.35, 0.45), (0.6, 0.5), (0.9, 0.42)]),
        line("ridge", &[(0.35, 0.45), (0.45, 0.2)]),
        line("valley", &[(0.1, 0.8), (0.5, 0.75), (0.9, 0.8)]),
        line("valley", &[(0.15, 0.15), (0.3, 0.25)]),
        line("valley", &[(0.6, 0.1), (0.75, 0.3), (0.85, 0.2)]),
    ]});
    parse_sketch(&fc, grid).unwrap()
}

fn run(threads: usize) -> SketchWorld {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (sk, ex) = (sketch(), exemplar());
    pool.install(|| synthesize(&sk, &[ex], &SketchOptions::default(), &mut |_, _| true))
        .unwrap()
}

fn geotiff_bytes(g: &Grid) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    write_geotiff(g, &mut out).unwrap();
    out.into_inner()
}

/// Acceptance 2 on the test sketch (figures in the README, "Sketch a world").
#[test]
fn a_sketch_world_follows_its_sketch_without_seams() {
    let world = run(1);
    let again = run(3);
    assert_eq!(
        geotiff_bytes(&world.grid),
        geotiff_bytes(&again.grid),
        "two runs differ"
    );
    assert_eq!(world.labels, again.labels);

    // Sketched lines lie within 3 cells of extracted features of their kind, on average; and
    // much nearer them than to features of the other kind (a terrain ignoring the sketch
    // scores about the same on both).
    let f = quality::fidelity(&world.grid.data, &world.trees, &PpaParams::default());
    assert!(f.ridge_cells > 200 && f.valley_cells > 200, "{f:?}");
    assert!(
        f.ridge_to_ridge <= 3.0 && f.valley_to_valley <= 3.0,
        "{f:?}"
    );
    assert!(f.ridge_to_ridge * 2.0 < f.ridge_to_valley, "{f:?}");
    assert!(f.valley_to_valley * 2.0 < f.valley_to_ridge, "{f:?}");

    // No visible seams: steps across seams within 1.25× of steps inside patches.
    let seams = quality::seams(&world.grid.data, &world.labels);
    assert!(seams.seam_edges > 1000, "{seams:?}");
    assert!(seams.ratio <= 1.25, "{seams:?}");

    // Flood extent within the range of the exemplar's windows of the same size.
    let ex = exemplar();
    let mut range = (f64::INFINITY, 0.0f64);
    for r in (0..=128).step_by(64) {
        for c in (0..=128).step_by(64) {
            let w = ex.data.slice(s![r..r + 256, c..c + 256]).to_owned();
            let e = analysis::flood_extent(&w);
            range = (range.0.min(e), range.1.max(e));
        }
    }
    let flood = analysis::flood_extent(&world.grid.data);
    assert!(
        flood >= range.0 && flood <= range.1,
        "flood extent {flood:.2} % outside the exemplar's {range:?} (before conditioning {:.2} %)",
        world.stats.flood_before_conditioning
    );
}

/// A sketch is refused when the exemplar cannot hold a rotated patch, and cancelled when the
/// progress callback says so.
#[test]
fn small_exemplars_and_cancellation_are_errors() {
    let ex = exemplar();
    let tiny = Grid::new(ex.data.slice(s![0..40, 0..40]).to_owned(), ex.georef);
    let e = synthesize(
        &sketch(),
        &[tiny],
        &SketchOptions::default(),
        &mut |_, _| true,
    );
    assert!(e.unwrap_err().to_string().contains("too small"));
    let e = synthesize(
        &sketch(),
        &[ex],
        &SketchOptions::default(),
        &mut |stage, _| stage != "features",
    );
    assert_eq!(
        e.unwrap_err(),
        terrasynth_core::synth::sketch::SketchError::Cancelled
    );
}
