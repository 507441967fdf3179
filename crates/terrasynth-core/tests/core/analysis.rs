//! Integration tests of `terrasynth_core::analysis`: optimised implementations against the naive
//! references (property tests), hand-computed values, realism sanity checks and edge cases.

use ndarray::Array2;
use proptest::prelude::*;
use terrasynth_core::analysis::{self, naive, Complex, D8_NONE, D8_OFFSETS, MFD_EXPONENT};
use terrasynth_core::math;
use terrasynth_core::raster::CellSizes;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A small deterministic LCG in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Accumulation by Kahn's algorithm with an explicit stack seeded with the cells nobody drains
/// into, last row-major first (the order the drainage layer's sums were defined by).
fn kahn_stack_accumulation(receivers: &Array2<u8>, sources: &Array2<f64>) -> Array2<f64> {
    let (rows, cols) = receivers.dim();
    let n = rows * cols;
    let mut acc: Vec<f64> = sources.iter().copied().collect();
    let mut rcv = vec![usize::MAX; n];
    let mut indeg = vec![0u8; n];
    for ((r, c), &code) in receivers.indexed_iter() {
        let Some(&(dr, dc)) = D8_OFFSETS.get(code as usize) else {
            continue;
        };
        let (nr, nc) = (r as isize + dr, c as isize + dc);
        if nr >= 0 && nc >= 0 && (nr as usize) < rows && (nc as usize) < cols {
            let j = nr as usize * cols + nc as usize;
            rcv[r * cols + c] = j;
            indeg[j] += 1;
        }
    }
    let mut stack: Vec<usize> = (0..n).filter(|&i| indeg[i] == 0).rev().collect();
    while let Some(i) = stack.pop() {
        let j = rcv[i];
        if j != usize::MAX {
            acc[j] += acc[i];
            indeg[j] -= 1;
            if indeg[j] == 0 {
                stack.push(j);
            }
        }
    }
    Array2::from_shape_vec((rows, cols), acc).unwrap()
}

/// Plane `z = f(x_m, y_m)` with x east and y north (row 0 at the top, so y = −row·dy).
fn plane(rows: usize, cols: usize, cell: f64, f: impl Fn(f64, f64) -> f64) -> Array2<f32> {
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        f(c as f64 * cell, -(r as f64) * cell) as f32
    })
}

fn interior(rows: usize, cols: usize) -> impl Iterator<Item = (usize, usize)> {
    (1..rows.saturating_sub(1)).flat_map(move |r| (1..cols.saturating_sub(1)).map(move |c| (r, c)))
}

fn has_lower_neighbour(z: &Array2<f32>, r: usize, c: usize) -> bool {
    let (rows, cols) = z.dim();
    D8_OFFSETS.iter().any(|&(dr, dc)| {
        let (nr, nc) = (r as isize + dr, c as isize + dc);
        if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
            return false;
        }
        let v = z[[nr as usize, nc as usize]];
        v.is_nan() || v < z[[r, c]]
    })
}

/// Sum of accumulation over the sinks (cells whose flow leaves the grid).
fn sink_total(acc: &Array2<f64>, rcv: &Array2<u8>) -> f64 {
    acc.iter()
        .zip(rcv.iter())
        .filter(|(_, &d)| d == D8_NONE)
        .map(|(a, _)| *a)
        .sum()
}

fn total_area(cs: &CellSizes, rows: usize, cols: usize) -> f64 {
    (0..rows).map(|r| cs.area(r) * cols as f64).sum()
}

/// Random grid with quantised heights (few levels, so plateaus and ties are common) and
/// integer per-row cell sizes (so D8 area sums are exact in f64).
fn grid_strategy() -> impl Strategy<Value = (Array2<f32>, CellSizes)> {
    (3usize..24, 3usize..24, 1u32..6, 0.0f32..7000.0).prop_flat_map(|(rows, cols, levels, base)| {
        (
            proptest::collection::vec(0..=levels, rows * cols),
            proptest::collection::vec(1u32..4, rows),
            proptest::collection::vec(1u32..4, rows),
        )
            .prop_map(move |(h, dx, dy)| {
                let z = Array2::from_shape_vec(
                    (rows, cols),
                    h.iter().map(|&v| base + v as f32 * 3.0).collect(),
                )
                .unwrap();
                let cs = CellSizes {
                    dx: dx.iter().map(|&v| v as f64 * 10.0).collect(),
                    dy: dy.iter().map(|&v| v as f64 * 10.0).collect(),
                };
                (z, cs)
            })
    })
}

/// Random grid with continuous heights (a few NaN cells, steps down to single ulps after
/// Priority-Flood+ε) and non-integer per-row cell sizes.
fn real_grid_strategy() -> impl Strategy<Value = (Array2<f32>, CellSizes)> {
    (1usize..40, 1usize..70).prop_flat_map(|(rows, cols)| {
        (
            proptest::collection::vec(
                prop_oneof![20 => -50.0f32..4000.0, 1 => Just(f32::NAN)],
                rows * cols,
            ),
            proptest::collection::vec(5.0f64..40.0, rows),
            proptest::collection::vec(5.0f64..40.0, rows),
        )
            .prop_map(move |(h, dx, dy)| {
                let z = Array2::from_shape_vec((rows, cols), h).unwrap();
                (z, CellSizes { dx, dy })
            })
    })
}

/// A grid's values as bit patterns, for comparisons bit for bit (NaN equal to NaN).
fn bits(a: &Array2<f32>) -> Vec<u32> {
    a.iter().map(|v| v.to_bits()).collect()
}

fn rel_close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-300)
}

// ---------------------------------------------------------------------------------------------
// Property tests: optimised vs naive
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Drainage across flats (breadth-first distances and one pass) equals the relaxation
    /// reference on grids full of flats, with NaN cells (outlets) sprinkled in or not; and it
    /// drains every cell: each chain of receivers runs without ascending to a cell without a
    /// receiver that is an outlet (on the border, NaN or next to NaN), never to a flat one.
    /// Flats wider than `max_span` (0: none resolved in full; up to the whole grid) and flats on
    /// the border ring drain towards their low edges and the guide cells (none, or a random
    /// tenth of the cells) only, in both.
    #[test]
    fn flat_resolution_equals_naive_and_drains_every_cell(
        (z, cs) in grid_strategy(),
        seed in 0u64..1000,
        holes in 0usize..3,
        max_span in prop_oneof![0usize..24, Just(usize::MAX)],
        guided in proptest::bool::ANY,
    ) {
        let mut z = z;
        let mut lcg = Lcg(seed);
        for _ in 0..holes {
            let (rows, cols) = z.dim();
            let r = (lcg.next() * rows as f64) as usize;
            let c = (lcg.next() * cols as f64) as usize;
            z[[r, c]] = f32::NAN;
        }
        let guide_cells = z.mapv(|_| lcg.next() < 0.1);
        let is_guide = |r: usize, c: usize| guide_cells[[r, c]];
        let guide = guided.then_some(&is_guide as &dyn Fn(usize, usize) -> bool);
        let filled = analysis::priority_flood_fill_flat(&z);
        let mut fast = analysis::d8_receivers(&filled, &cs);
        let mut slow = fast.clone();
        analysis::resolve_flats(&filled, &cs, max_span, guide, &mut fast);
        naive::resolve_flats(&filled, &cs, max_span, guide, &mut slow);
        prop_assert_eq!(&fast, &slow);
        prop_assert_eq!(
            &fast,
            &analysis::d8_receivers_over_flats(&filled, &cs, max_span, guide)
        );
        let (rows, cols) = z.dim();
        let outlet = |r: usize, c: usize| {
            r == 0 || c == 0 || r + 1 == rows || c + 1 == cols || filled[[r, c]].is_nan()
                || D8_OFFSETS.iter().any(|&(dr, dc)| {
                    filled[[(r as isize + dr) as usize, (c as isize + dc) as usize]].is_nan()
                })
        };
        for ((r0, c0), _) in z.indexed_iter() {
            let (mut r, mut c) = (r0, c0);
            let mut steps = 0;
            while let Some(&(dr, dc)) = D8_OFFSETS.get(fast[[r, c]] as usize) {
                let (nr, nc) = ((r as isize + dr) as usize, (c as isize + dc) as usize);
                prop_assert!(filled[[nr, nc]] <= filled[[r, c]], "ascends at ({}, {})", r, c);
                (r, c) = (nr, nc);
                steps += 1;
                prop_assert!(steps <= rows * cols, "a cycle through ({}, {})", r0, c0);
            }
            prop_assert!(outlet(r, c), "({}, {}) ends at ({}, {}), not an outlet", r0, c0, r, c);
        }
    }

    /// Priority-Flood without ε equals Planchon–Darboux relaxation bit for bit, on quantised
    /// heights full of ties and flats and on continuous heights with NaN outlets.
    #[test]
    fn flat_fill_equals_naive(
        (tied, _c) in grid_strategy(),
        (real, _r) in real_grid_strategy(),
    ) {
        for z in [&tied, &real] {
            let fast = analysis::priority_flood_fill_flat(z);
            let slow = naive::fill_flat(z);
            prop_assert_eq!(bits(&fast), bits(&slow));
        }
    }

    /// Priority-Flood+ε on its ranked bitset queue equals the same flood on the standard binary
    /// heap bit for bit (quantised heights full of ties, and continuous heights with NaN cells).
    #[test]
    fn eps_fill_equals_the_binary_heap_flood(
        (tied, _c) in grid_strategy(),
        (real, _r) in real_grid_strategy(),
    ) {
        for z in [&tied, &real] {
            let fast = analysis::priority_flood_fill(z);
            let slow = naive::priority_flood_fill_binary_heap(z);
            prop_assert_eq!(bits(&fast), bits(&slow));
        }
    }

    /// Source accumulation (used with injected inflows by the drainage layer) equals the naive
    /// chain walk, with integer sources so that sums are exact. With fractional sources the
    /// sums depend on their order: it adds them in the order of Kahn's algorithm on a stack
    /// seeded with the row-major cells nobody drains into, which the served drainage bytes were
    /// defined by, bit for bit.
    #[test]
    fn source_accumulation_equals_naive_in_kahn_stack_order(
        (z, cs) in grid_strategy(),
        seed in 0u64..1000,
    ) {
        let filled = analysis::priority_flood_fill(&z);
        let rcv = analysis::d8_receivers(&filled, &cs);
        let mut lcg = Lcg(seed);
        let whole = Array2::from_shape_fn(z.dim(), |_| (lcg.next() * 50.0).floor());
        let fast = analysis::accumulate_sources(&rcv, &whole);
        prop_assert_eq!(fast, naive::accumulate_sources(&rcv, &whole));
        let fractional = Array2::from_shape_fn(z.dim(), |_| lcg.next() * 1e3 + 1e-7);
        let fast = analysis::accumulate_sources(&rcv, &fractional);
        let reference = kahn_stack_accumulation(&rcv, &fractional);
        prop_assert!(fast.iter().zip(&reference).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    /// Source accumulation equals the naive chain walk on any acyclic receivers, including
    /// codes that point off the grid (border cells) and sink codes: each cell picks a random
    /// direction towards a lower cell of a random potential or off the grid, else none.
    #[test]
    fn source_accumulation_equals_naive_on_any_acyclic_receivers(
        rows in 1usize..24,
        cols in 1usize..24,
        seed in 0u64..10_000,
    ) {
        let mut lcg = Lcg(seed);
        let potential = Array2::from_shape_fn((rows, cols), |_| lcg.next());
        let rcv = Array2::from_shape_fn((rows, cols), |(r, c)| {
            let allowed: Vec<u8> = (0..8u8)
                .filter(|&d| {
                    let (dr, dc) = D8_OFFSETS[d as usize];
                    let (nr, nc) = (r as isize + dr, c as isize + dc);
                    let off = nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize;
                    off || potential[[nr as usize, nc as usize]] < potential[[r, c]]
                })
                .collect();
            let pick = (lcg.next() * (allowed.len() + 1) as f64) as usize;
            allowed.get(pick).copied().unwrap_or(D8_NONE)
        });
        let whole = Array2::from_shape_fn((rows, cols), |_| (lcg.next() * 50.0).floor());
        prop_assert_eq!(
            analysis::accumulate_sources(&rcv, &whole),
            naive::accumulate_sources(&rcv, &whole)
        );
    }

    /// Priority-Flood+ε: above the input and the flat fill, every interior cell drains, only
    /// a few ulps above the flat fill, and a fixed point of both fills.
    #[test]
    fn eps_fill_properties((z, _cs) in grid_strategy()) {
        let (rows, cols) = z.dim();
        let eps = analysis::priority_flood_fill(&z);
        let flat = analysis::priority_flood_fill_flat(&z);
        for ((e, f), v) in eps.iter().zip(flat.iter()).zip(z.iter()) {
            prop_assert!(e >= v && e >= f);
            // At most one ulp per cell of the grid above the flat fill.
            let mut bound = *f;
            for _ in 0..rows * cols {
                bound = analysis::next_up(bound);
            }
            prop_assert!(*e <= bound);
        }
        for (r, c) in interior(rows, cols) {
            prop_assert!(has_lower_neighbour(&eps, r, c), "cell ({r},{c}) does not drain");
        }
        // Border cells are outlets and keep their height.
        for r in 0..rows {
            for c in 0..cols {
                if r == 0 || c == 0 || r == rows - 1 || c == cols - 1 {
                    prop_assert_eq!(eps[[r, c]], z[[r, c]]);
                }
            }
        }
        prop_assert_eq!(&analysis::priority_flood_fill(&eps), &eps);
        prop_assert_eq!(&analysis::priority_flood_fill_flat(&eps), &eps);
    }

    /// D8 accumulation on the ε-filled DEM equals the chain-following reference exactly
    /// (integer areas), every interior cell has a receiver, and the sinks receive all the area.
    #[test]
    fn d8_equals_naive((z, cs) in grid_strategy()) {
        let (rows, cols) = z.dim();
        let filled = analysis::priority_flood_fill(&z);
        let fast = analysis::flow_accumulation_d8(&filled, &cs);
        let slow = naive::flow_accumulation_d8(&filled, &cs);
        prop_assert_eq!(&fast, &slow);
        let rcv = analysis::d8_receivers(&filled, &cs);
        for (r, c) in interior(rows, cols) {
            prop_assert!(rcv[[r, c]] < 8);
        }
        prop_assert_eq!(sink_total(&fast, &rcv), total_area(&cs, rows, cols));
        // Also on the raw (unfilled) DEM, where pits and flats are sinks.
        let raw_fast = analysis::flow_accumulation_d8(&z, &cs);
        prop_assert_eq!(&raw_fast, &naive::flow_accumulation_d8(&z, &cs));
        let raw_rcv = analysis::d8_receivers(&z, &cs);
        prop_assert_eq!(sink_total(&raw_fast, &raw_rcv), total_area(&cs, rows, cols));
    }

    /// The row-wise, vectorised D8 receivers equal the per-cell scan code for code: on plateaus
    /// and ties (quantised heights), on continuous heights with NaN cells, raw and ε-filled.
    #[test]
    fn d8_receivers_equal_naive(
        (tied, tied_cs) in grid_strategy(),
        (real, real_cs) in real_grid_strategy(),
    ) {
        for (z, cs) in [(&tied, &tied_cs), (&real, &real_cs)] {
            let filled = analysis::priority_flood_fill(z);
            for g in [z, &filled] {
                prop_assert_eq!(analysis::d8_receivers(g, cs), naive::d8_receivers(g, cs));
            }
        }
    }

    /// MFD accumulation matches the relaxation reference within 1e-9 relative and conserves
    /// area at the sinks, on quantised heights full of flats and on continuous heights with
    /// NaN outlets.
    #[test]
    fn mfd_matches_naive(
        (tied, tied_cs) in grid_strategy(),
        (real, real_cs) in real_grid_strategy(),
        p in 0.5f64..8.0,
    ) {
        for (z, cs) in [(&tied, &tied_cs), (&real, &real_cs)] {
            let (rows, cols) = z.dim();
            let filled = analysis::priority_flood_fill(z);
            for exponent in [MFD_EXPONENT, p] {
                let fast = analysis::flow_accumulation_mfd(&filled, cs, exponent);
                let slow = naive::flow_accumulation_mfd(&filled, cs, exponent);
                for (a, b) in fast.iter().zip(slow.iter()) {
                    prop_assert!(rel_close(*a, *b, 1e-9), "{a} vs {b}");
                }
                let rcv = analysis::d8_receivers(&filled, cs);
                let sinks = sink_total(&fast, &rcv);
                prop_assert!(rel_close(sinks, total_area(cs, rows, cols), 1e-9));
                let areas = fast.indexed_iter().map(|((r, _), _)| cs.area(r));
                for (a, area) in fast.iter().zip(areas) {
                    prop_assert!(*a >= area * (1.0 - 1e-12));
                }
            }
        }
    }

    /// Horn gradient matches the per-cell reference, on quantised heights and on continuous
    /// heights with NaN cells (NaN where the reference has NaN).
    #[test]
    fn gradient_matches_naive(
        (tied, tied_cs) in grid_strategy(),
        (real, real_cs) in real_grid_strategy(),
    ) {
        for (z, cs) in [(&tied, &tied_cs), (&real, &real_cs)] {
            let (gx, gy) = analysis::gradient(z, cs);
            let (nx, ny) = naive::gradient(z, cs);
            for (a, b) in gx.iter().chain(gy.iter()).zip(nx.iter().chain(ny.iter())) {
                prop_assert_eq!(a.is_nan(), b.is_nan(), "{} vs {}", a, b);
                if !a.is_nan() {
                    prop_assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} vs {b}");
                }
            }
        }
    }

    /// FFT (radix-2 and Bluestein) vs naive DFT within 1e-9 of the signal norm, forward and
    /// inverse; inverse round-trips.
    #[test]
    fn fft_matches_dft(v in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 1..70)) {
        let x: Vec<Complex> = v.iter().map(|&(a, b)| Complex::new(a, b)).collect();
        let norm = x.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt().max(1.0);
        let n = x.len() as f64;
        let mut f = x.clone();
        analysis::fft(&mut f, false);
        let d = analysis::dft_naive(&x, false);
        for (a, b) in f.iter().zip(&d) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9 * norm * n.sqrt());
        }
        let mut g = x.clone();
        analysis::fft(&mut g, true);
        let di = analysis::dft_naive(&x, true);
        for (a, b) in g.iter().zip(&di) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9 * norm / n.sqrt());
        }
        analysis::fft(&mut f, true);
        for (a, b) in f.iter().zip(&x) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9 * norm);
        }
    }

    /// The radix-2 plan (used directly by the sketch SSD search) vs the naive DFT: forward, and
    /// inverse (unnormalised, so N times the naive inverse).
    #[test]
    fn radix2_matches_dft_both_ways(
        log_n in 0u32..8,
        v in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 128),
    ) {
        let n = 1usize << log_n;
        let x: Vec<Complex> = v[..n].iter().map(|&(a, b)| Complex::new(a, b)).collect();
        let norm = x.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt().max(1.0);
        let nf = n as f64;
        let plan = analysis::Radix2::new(n);
        let mut f = x.clone();
        plan.run(&mut f, false);
        for (a, b) in f.iter().zip(&analysis::dft_naive(&x, false)) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9 * norm * nf.sqrt());
        }
        let mut g = x.clone();
        plan.run(&mut g, true);
        for (a, b) in g.iter().zip(&analysis::dft_naive(&x, true)) {
            prop_assert!(a.sub(b.scale(nf)).norm_sqr().sqrt() <= 1e-9 * norm * nf.sqrt());
        }
    }

    /// 2D FFT vs the naive 2D DFT, forward and inverse.
    #[test]
    fn fft2_matches_dft2(rows in 1usize..20, cols in 1usize..20, seed in any::<u64>()) {
        let mut g = Lcg(seed);
        let x = Array2::from_shape_fn((rows, cols), |_| Complex::new(g.next() - 0.5, g.next() - 0.5));
        let mut f = x.clone();
        analysis::fft2(&mut f, false);
        let d = naive::dft2(&x, false);
        let scale = (rows * cols) as f64;
        for (a, b) in f.iter().zip(d.iter()) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9 * scale);
        }
        let mut g = x.clone();
        analysis::fft2(&mut g, true);
        let di = naive::dft2(&x, true);
        for (a, b) in g.iter().zip(di.iter()) {
            prop_assert!(a.sub(*b).norm_sqr().sqrt() <= 1e-9);
        }
    }

    /// wasserstein1 equals the mean absolute difference of sorted samples for equal sizes,
    /// is symmetric, and replicating a sample does not change its distribution.
    #[test]
    fn wasserstein_properties(
        a in proptest::collection::vec(-100.0f64..100.0, 1..40),
        b in proptest::collection::vec(-100.0f64..100.0, 1..40),
    ) {
        let w = analysis::wasserstein1(&a, &b);
        prop_assert!(rel_close(w, analysis::wasserstein1(&b, &a), 1e-12) || w < 1e-12);
        let a2: Vec<f64> = a.iter().chain(a.iter()).copied().collect();
        let w2 = analysis::wasserstein1(&a2, &b);
        prop_assert!((w - w2).abs() <= 1e-9 * w.max(1.0));
        let n = a.len().min(b.len());
        let (mut sa, mut sb) = (a[..n].to_vec(), b[..n].to_vec());
        sa.sort_by(f64::total_cmp);
        sb.sort_by(f64::total_cmp);
        let brute = sa.iter().zip(&sb).map(|(x, y)| (x - y).abs()).sum::<f64>() / n as f64;
        prop_assert!((analysis::wasserstein1(&a[..n], &b[..n]) - brute).abs() <= 1e-9 * brute.max(1.0));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The fused slope, northness and hillshade are the separate functions' bits, on grids with
    /// flats (zero gradient) and on grids with NaN cells, for any light.
    #[test]
    fn fused_surface_derivatives_equal_the_separate_ones(
        (flat, flat_cs) in grid_strategy(),
        (real, real_cs) in real_grid_strategy(),
        azimuth in 0.0f32..360.0,
        altitude in 1.0f32..89.0,
    ) {
        for (z, cs) in [(&flat, &flat_cs), (&real, &real_cs)] {
            let [slope, north, shade] = analysis::slope_northness_shade(z, cs, azimuth, altitude);
            prop_assert_eq!(bits(&slope), bits(&analysis::slope_degrees(z, cs)));
            prop_assert_eq!(bits(&north), bits(&analysis::northness(z, cs)));
            prop_assert_eq!(bits(&shade), bits(&analysis::hillshade(z, cs, azimuth, altitude)));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-computed derivatives and hillshade
// ---------------------------------------------------------------------------------------------

#[test]
fn slope_of_plane_is_its_gradient() {
    let cell = 30.0;
    let z = plane(9, 11, cell, |x, _| 0.1 * x);
    let cs = CellSizes::uniform(9, cell);
    let s = analysis::slope(&z, &cs);
    let deg = analysis::slope_degrees(&z, &cs);
    for (r, c) in interior(9, 11) {
        assert!((s[[r, c]] - 0.1).abs() < 1e-5, "{}", s[[r, c]]);
        assert!((deg[[r, c]] as f64 - math::atan(0.1f64).to_degrees()).abs() < 1e-3);
    }
}

#[test]
fn aspect_and_northness_of_planes() {
    let cs = CellSizes::uniform(7, 10.0);
    type PlaneCase = (fn(f64, f64) -> f64, f32, f32);
    let cases: [PlaneCase; 4] = [
        (|x, _| -0.2 * x, 90.0, 0.0),  // descends to the east
        (|_, y| -0.2 * y, 0.0, 1.0),   // descends to the north
        (|x, _| 0.2 * x, 270.0, 0.0),  // descends to the west
        (|_, y| 0.2 * y, 180.0, -1.0), // descends to the south
    ];
    for (f, want_aspect, want_north) in cases {
        let z = plane(7, 7, 10.0, f);
        let a = analysis::aspect(&z, &cs);
        let n = analysis::northness(&z, &cs);
        for (r, c) in interior(7, 7) {
            assert!(
                (a[[r, c]] - want_aspect).abs() < 1e-3,
                "{} vs {want_aspect}",
                a[[r, c]]
            );
            assert!((n[[r, c]] - want_north).abs() < 1e-5);
        }
    }
    // South-east facing: 135°.
    let z = plane(7, 7, 10.0, |x, y| -0.1 * x + 0.1 * y);
    assert!((analysis::aspect(&z, &cs)[[3, 3]] - 135.0).abs() < 1e-3);
    // Flat: aspect 0, northness 0.
    let flat = Array2::from_elem((5, 5), 1234.5f32);
    let cs5 = CellSizes::uniform(5, 10.0);
    assert!(analysis::aspect(&flat, &cs5).iter().all(|&v| v == 0.0));
    assert!(analysis::northness(&flat, &cs5).iter().all(|&v| v == 0.0));
    // Aspect always lies in [0, 360).
    let mut g = Lcg(7);
    let rnd = Array2::from_shape_fn((20, 20), |_| (g.next() * 100.0) as f32);
    let a = analysis::aspect(&rnd, &CellSizes::uniform(20, 5.0));
    assert!(a.iter().all(|&v| (0.0..360.0).contains(&v)));
}

#[test]
fn halving_dx_doubles_x_slope() {
    let z = plane(6, 8, 10.0, |x, y| 0.05 * x + 0.02 * y);
    let cs = CellSizes::uniform(6, 10.0);
    let half = CellSizes {
        dx: vec![5.0; 6],
        dy: vec![10.0; 6],
    };
    let (gx, gy) = analysis::gradient(&z, &cs);
    let (hx, hy) = analysis::gradient(&z, &half);
    for (r, c) in interior(6, 8) {
        assert!((gx[[r, c]] - 0.05).abs() < 1e-5);
        assert!((gy[[r, c]] - 0.02).abs() < 1e-5);
        assert!((hx[[r, c]] - 2.0 * gx[[r, c]]).abs() < 1e-5);
        assert!((hy[[r, c]] - gy[[r, c]]).abs() < 1e-7);
    }
}

#[test]
fn hillshade_values() {
    let cs = CellSizes::uniform(5, 10.0);
    let flat = Array2::from_elem((5, 5), 500.0f32);
    for alt in [10.0f32, 45.0, 80.0] {
        let h = analysis::hillshade(&flat, &cs, 315.0, alt);
        assert!(h
            .iter()
            .all(|&v| (v as f64 - math::sin((alt as f64).to_radians())).abs() < 1e-6));
    }
    let hu = analysis::hillshade_u8(&flat, &cs, 315.0, 45.0);
    assert!(hu.iter().all(|&v| v == 180)); // round(255·sin 45°)
                                           // A slope facing the light (descending to the north-west) is brighter than one facing away.
    let towards = plane(5, 5, 10.0, |x, y| 0.5 * x - 0.5 * y);
    let away = plane(5, 5, 10.0, |x, y| -0.5 * x + 0.5 * y);
    let ht = analysis::hillshade(&towards, &cs, 315.0, 45.0)[[2, 2]];
    let ha = analysis::hillshade(&away, &cs, 315.0, 45.0)[[2, 2]];
    // Slope angle β = atan(√0.5); facing the light: cos(45° − β), facing away: cos(45° + β).
    let beta = math::atan(0.5f64.sqrt());
    let q = std::f64::consts::FRAC_PI_4;
    assert!((ht as f64 - math::cos(q - beta)).abs() < 1e-6, "{ht}");
    assert!((ha as f64 - math::cos(q + beta)).abs() < 1e-6, "{ha}");
    // Facing the light exactly at slope = 90° − altitude: fully lit.
    let lit = plane(5, 5, 10.0, |_, y| -y); // 45° slope facing north
    assert!((analysis::hillshade(&lit, &cs, 0.0, 45.0)[[2, 2]] - 1.0).abs() < 1e-6);
}

#[test]
fn curvature_of_paraboloids() {
    let cell = 2.0;
    let bowl = plane(9, 9, cell, |x, y| (x - 8.0).powi(2) + (y + 8.0).powi(2));
    let dome = bowl.mapv(|v| -v);
    let cs = CellSizes::uniform(9, cell);
    let cb = analysis::curvature(&bowl, &cs);
    let cd = analysis::curvature(&dome, &cs);
    for (r, c) in interior(9, 9) {
        assert!((cb[[r, c]] + 4.0).abs() < 1e-4, "{}", cb[[r, c]]);
        assert!((cd[[r, c]] - 4.0).abs() < 1e-4);
    }
    let tilted = plane(6, 6, 3.0, |x, y| 0.3 * x - 0.7 * y + 100.0);
    let ct = analysis::curvature(&tilted, &CellSizes::uniform(6, 3.0));
    for (r, c) in interior(6, 6) {
        assert!(ct[[r, c]].abs() < 1e-5);
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-computed flooding and flow
// ---------------------------------------------------------------------------------------------

#[test]
fn flood_extent_of_known_pit() {
    let mut z = Array2::from_elem((5, 5), 10.0f32);
    z[[2, 2]] = 5.0;
    assert!((analysis::flood_extent(&z) - 4.0).abs() < 1e-12);
    let flat = analysis::priority_flood_fill_flat(&z);
    assert_eq!(flat[[2, 2]], 10.0);
    // A 2×2 pit behind a rim with a lower spill point.
    let mut z = Array2::from_elem((6, 6), 20.0f32);
    for r in 1..5 {
        for c in 1..5 {
            z[[r, c]] = 15.0;
        }
    }
    z[[2, 2]] = 1.0;
    z[[2, 3]] = 2.0;
    z[[3, 2]] = 3.0;
    z[[3, 3]] = 4.0;
    z[[0, 3]] = 12.0; // spill point on the border
    let flat = analysis::priority_flood_fill_flat(&z);
    for (r, c) in [(2, 2), (2, 3), (3, 2), (3, 3)] {
        assert_eq!(flat[[r, c]], 15.0);
    }
    assert!((analysis::flood_extent(&z) - 400.0 / 36.0).abs() < 1e-12);
}

/// A flat valley floor 11 cells wide between walls that rise away from it, closed at its east
/// end, its west end stepping down to the grid's border (or, with `open_west`, lying on the
/// border ring itself), as accumulated by D8 over flats with `max_span` and the cells of
/// `guide_row` as guides.
fn flat_valley_accumulation(
    open_west: bool,
    max_span: usize,
    guide_row: Option<usize>,
) -> (Array2<f32>, Array2<f64>) {
    let (rows, cols) = (21usize, 43usize);
    let z = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let off_floor = (r as f32 - 10.0).abs() - 5.0;
        if off_floor > 0.0 {
            10.0 * off_floor
        } else if c + 2 >= cols {
            50.0 // the valley's closed east end
        } else if open_west || c >= 2 {
            0.0
        } else {
            c as f32 - 2.0 // two steps down to the border: the floor's outlet
        }
    });
    let cs = CellSizes {
        dx: vec![1.0; rows],
        dy: vec![1.0; rows],
    };
    // Already without depressions: the floor drains through its west end.
    let filled = analysis::priority_flood_fill_flat(&z);
    assert_eq!(filled, z, "no depression to fill");
    let on_guide_row = |r: usize, _c: usize| Some(r) == guide_row;
    let guide = guide_row.map(|_| &on_guide_row as &dyn Fn(usize, usize) -> bool);
    let acc = analysis::flow_accumulation_from_receivers(
        &analysis::d8_receivers_over_flats(&filled, &cs, max_span, guide),
        &cs,
    );
    (z, acc)
}

/// Resolved in full (inside the grid, narrower than `max_span`), the flow over the valley floor
/// converges into its middle row, which carries nearly the whole valley to the outlet, where
/// Priority-Flood+ε sends each row down its own parallel line. An open flat (on the border ring,
/// or wider than `max_span`) drains towards its low edges only: parallel lines again; with
/// guide cells, it converges on them.
#[test]
fn flow_over_a_flat_valley_floor_converges_into_its_middle() {
    let (z, over_flats) = flat_valley_accumulation(false, 64, None);
    // At the floor's west end (column 2, the low edge). The floor holds 11 × 39 cells of 1 m²
    // (columns 2–40; its flat part, columns 3–40, spans 38); the closed end and the inner walls
    // drain into it too.
    assert!(
        over_flats[[10, 2]] >= 650.0,
        "middle row carries {}",
        over_flats[[10, 2]]
    );
    for r in (5..=15).filter(|&r| r != 10) {
        assert!(
            over_flats[[r, 2]] < 20.0,
            "row {r} carries {}",
            over_flats[[r, 2]]
        );
    }
    let cs = CellSizes {
        dx: vec![1.0; z.nrows()],
        dy: vec![1.0; z.nrows()],
    };
    // The ε-gradient: every row inside the floor carries its own 39 cells and the closed end's.
    let eps = analysis::flow_accumulation_d8(&analysis::priority_flood_fill(&z), &cs);
    for r in 6..=14 {
        assert!(
            (39.0..=41.0).contains(&eps[[r, 2]]),
            "row {r} carries {}",
            eps[[r, 2]]
        );
    }
    // Open flats: wider (38 columns) than a span of 37, or on the border ring.
    for (open_west, max_span, column) in [(false, 37, 2), (true, 64, 1)] {
        let (_, open) = flat_valley_accumulation(open_west, max_span, None);
        for r in 6..=14 {
            assert!(
                open[[r, column]] < 100.0,
                "open {open_west}, span {max_span}: row {r} carries {}",
                open[[r, column]]
            );
        }
    }
    // An open flat with guides (row 12, off the floor's middle): the flow converges on them.
    let (_, guided) = flat_valley_accumulation(false, 37, Some(12));
    assert!(
        guided[[12, 2]] >= 650.0,
        "guide row carries {}",
        guided[[12, 2]]
    );
    for r in (5..=15).filter(|&r| r != 12) {
        assert!(guided[[r, 2]] < 20.0, "row {r} carries {}", guided[[r, 2]]);
    }
    // A guide on a flat resolved in full changes nothing.
    let (_, closed) = flat_valley_accumulation(false, 64, Some(12));
    assert_eq!(closed, over_flats);
}

#[test]
fn eps_fill_drains_at_high_elevation() {
    // A 7000 m plateau with a pit: a fixed ε of 1e-5 would vanish here (ulp ≈ 0.0005).
    let mut z = Array2::from_elem((30, 30), 7000.0f32);
    z[[15, 15]] = 6990.0;
    let f = analysis::priority_flood_fill(&z);
    for (r, c) in interior(30, 30) {
        assert!(has_lower_neighbour(&f, r, c));
        assert!(f[[r, c]] > 7000.0 && f[[r, c]] < 7000.1);
    }
}

#[test]
fn d8_on_tilted_plane_sums_columns() {
    // Descends to the south; rows have different widths (as in EPSG:4326).
    let rows = 8;
    let cols = 5;
    let z = Array2::from_shape_fn((rows, cols), |(r, _)| 1000.0 - 10.0 * r as f32);
    let cs = CellSizes {
        dx: (0..rows).map(|r| 20.0 + r as f64).collect(),
        dy: vec![25.0; rows],
    };
    let rcv = analysis::d8_receivers(&z, &cs);
    for r in 0..rows - 1 {
        for c in 0..cols {
            assert_eq!(rcv[[r, c]], 6, "south");
        }
    }
    assert!(rcv.row(rows - 1).iter().all(|&d| d == D8_NONE));
    let acc = analysis::flow_accumulation_d8(&z, &cs);
    let column: f64 = (0..rows).map(|r| cs.area(r)).sum();
    for c in 0..cols {
        assert_eq!(acc[[rows - 1, c]], column);
        assert_eq!(acc[[0, c]], cs.area(0));
    }
    let log = analysis::log_upstream_area(&acc);
    assert!((log[[rows - 1, 0]] as f64 - math::log10(column)).abs() < 1e-6);
    // MFD on the same plane: the southern row also receives exactly the total area.
    let mfd = analysis::flow_accumulation_mfd(&z, &cs, MFD_EXPONENT);
    let south: f64 = mfd.row(rows - 1).sum();
    assert!(rel_close(south, total_area(&cs, rows, cols), 1e-12));
}

#[test]
fn d8_ties_take_lowest_direction() {
    // Centre cell with equal drops to E and W: E (index 0) wins; to N and S: N (2) wins.
    let mut z = Array2::from_elem((3, 3), 10.0f32);
    z[[1, 1]] = 5.0;
    z[[1, 0]] = 0.0;
    z[[1, 2]] = 0.0;
    assert_eq!(
        analysis::d8_receivers(&z, &CellSizes::uniform(3, 1.0))[[1, 1]],
        0
    );
    let mut z = Array2::from_elem((3, 3), 10.0f32);
    z[[1, 1]] = 5.0;
    z[[0, 1]] = 0.0;
    z[[2, 1]] = 0.0;
    assert_eq!(
        analysis::d8_receivers(&z, &CellSizes::uniform(3, 1.0))[[1, 1]],
        2
    );
}

// ---------------------------------------------------------------------------------------------
// Metrics and spectrum
// ---------------------------------------------------------------------------------------------

#[test]
fn wasserstein_of_shifted_sets_is_the_shift() {
    let mut g = Lcg(3);
    let a: Vec<f64> = (0..50).map(|_| g.next() * 10.0).collect();
    let b: Vec<f64> = a.iter().map(|v| v + 2.5).collect();
    assert!((analysis::wasserstein1(&a, &b) - 2.5).abs() < 1e-12);
    // Different sizes: {0, 1} vs {0, 0.5, 1} → ∫|F_a⁻¹ − F_b⁻¹| = 1/6·0.5 + 1/6·0.5 = 1/6.
    assert!((analysis::wasserstein1(&[0.0, 1.0], &[0.0, 0.5, 1.0]) - 1.0 / 6.0).abs() < 1e-15);
    assert_eq!(analysis::wasserstein1(&[], &[]), 0.0);
    assert!(analysis::wasserstein1(&[1.0], &[]).is_nan());
}

#[test]
fn rmse_relief_box_down() {
    let a = Array2::from_shape_vec((2, 2), vec![1.0f32, 2.0, 3.0, 4.0]).unwrap();
    let b = Array2::from_shape_vec((2, 2), vec![1.0f32, 2.0, 3.0, 6.0]).unwrap();
    assert!((analysis::rmse(&a, &b) - 1.0).abs() < 1e-12);
    assert!(analysis::rmse(&a, &Array2::zeros((3, 2))).is_nan());
    assert_eq!(analysis::relief(&a), 3.0);
    let z = Array2::from_shape_fn((4, 6), |(r, c)| (r * 6 + c) as f32);
    let d = analysis::box_down(&z, 2).unwrap();
    assert_eq!(d.dim(), (2, 3));
    assert_eq!(d[[0, 0]], (0.0 + 1.0 + 6.0 + 7.0) / 4.0);
    assert_eq!(d[[1, 2]], (16.0 + 17.0 + 22.0 + 23.0) / 4.0);
    assert!(analysis::box_down(&z, 4).is_err());
    assert!(analysis::box_down(&z, 0).is_err());
    assert_eq!(analysis::box_down(&z, 1).unwrap(), z);
}

#[test]
fn band_energy_of_sinusoid() {
    let n = 64;
    let f0 = 0.25; // cycles per pixel, along x
    let z = Array2::from_shape_fn((n, n), |(_, c)| {
        math::sin(2.0 * std::f64::consts::PI * f0 * c as f64) as f32 * 50.0
    });
    let total = analysis::band_energy(&z, 0.0, 1.0);
    let band = analysis::band_energy(&z, 0.2, 0.3);
    assert!(total > 0.0);
    assert!(band > 0.999 * total, "{band} of {total}");
    assert!(analysis::band_energy(&z, 0.0, 0.125) < 1e-9 * total);
    // Removed by ×4 down-sampling.
    assert!(analysis::band_energy(&z, 0.5 / 4.0, 0.5) > 0.999 * total);
    // A slow sinusoid (1/32 cycles/pixel) is kept by ×4 down-sampling.
    let slow = Array2::from_shape_fn((n, 48), |(r, _)| {
        math::cos(2.0 * std::f64::consts::PI * r as f64 / 32.0) as f32
    });
    let t = analysis::band_energy(&slow, 0.0, 1.0);
    assert!(analysis::band_energy(&slow, 0.125, 0.5) < 1e-6 * t);
    // Constant grid: no energy after mean removal.
    assert!(analysis::band_energy(&Array2::from_elem((8, 8), 3.0f32), 0.0, 1.0) < 1e-20);
}

// ---------------------------------------------------------------------------------------------
// Realism sanity (Tien Shan-like expectations)
// ---------------------------------------------------------------------------------------------

#[test]
fn flood_extent_random_vs_tilted() {
    let mut g = Lcg(42);
    let rnd = Array2::from_shape_fn((100, 120), |_| (g.next() * 3000.0 + 2000.0) as f32);
    let fe = analysis::flood_extent(&rnd);
    assert!(fe > 30.0, "random heights flood {fe}%");
    let tilted = plane(100, 120, 90.0, |x, y| 4000.0 - 0.2 * x + 0.3 * y);
    assert_eq!(analysis::flood_extent(&tilted), 0.0);
    assert_eq!(analysis::priority_flood_fill_flat(&tilted), tilted);
}

// ---------------------------------------------------------------------------------------------
// Edge cases: empty, tiny and NaN grids never panic
// ---------------------------------------------------------------------------------------------

#[test]
fn tiny_and_empty_grids() {
    for (rows, cols) in [(0, 0), (0, 5), (1, 1), (1, 7), (2, 2), (2, 9), (7, 1)] {
        let z = Array2::from_shape_fn((rows, cols), |(r, c)| (r * 3 + c) as f32);
        let cs = CellSizes::uniform(rows, 10.0);
        let empty_cs = CellSizes {
            dx: vec![],
            dy: vec![],
        };
        for cs in [&cs, &empty_cs] {
            let _ = analysis::gradient(&z, cs);
            let _ = analysis::slope_degrees(&z, cs);
            let _ = analysis::aspect(&z, cs);
            let _ = analysis::northness(&z, cs);
            let _ = analysis::curvature(&z, cs);
            let _ = analysis::hillshade_u8(&z, cs, 315.0, 45.0);
            let fused = analysis::slope_northness_shade(&z, cs, 315.0, 45.0);
            assert!(fused.iter().all(|a| a.dim() == (rows, cols)));
            let _ = analysis::flow_accumulation_mfd(&z, cs, MFD_EXPONENT);
            let acc = analysis::flow_accumulation_d8(&z, cs);
            assert_eq!(acc.dim(), (rows, cols));
        }
        assert_eq!(analysis::priority_flood_fill(&z), z);
        assert_eq!(analysis::priority_flood_fill_flat(&z), z);
        assert_eq!(analysis::flood_extent(&z), 0.0);
        let _ = analysis::band_energy(&z, 0.0, 0.5);
        let _ = analysis::relief(&z);
        let _ = analysis::rmse(&z, &z);
    }
}

#[test]
fn nan_cells_are_outlets() {
    // A pit whose bottom is nodata: it drains into the NaN, nothing floods.
    let mut z = Array2::from_elem((7, 7), 10.0f32);
    for r in 2..5 {
        for c in 2..5 {
            z[[r, c]] = 5.0;
        }
    }
    z[[3, 3]] = f32::NAN;
    let flat = analysis::priority_flood_fill_flat(&z);
    assert!(flat[[3, 3]].is_nan());
    assert_eq!(flat[[2, 2]], 5.0);
    assert_eq!(analysis::flood_extent(&z), 0.0);
    let eps = analysis::priority_flood_fill(&z);
    assert!(eps[[3, 3]].is_nan());
    for (r, c) in interior(7, 7) {
        if !z[[r, c]].is_nan() {
            assert!(has_lower_neighbour(&eps, r, c));
        }
    }
    assert_eq!(
        naive::fill_flat(&z).iter().filter(|v| v.is_nan()).count(),
        1
    );
    let cs = CellSizes::uniform(7, 10.0);
    let acc = analysis::flow_accumulation_d8(&eps, &cs);
    let rcv = analysis::d8_receivers(&eps, &cs);
    assert_eq!(rcv[[3, 3]], D8_NONE);
    assert_eq!(sink_total(&acc, &rcv), 49.0 * 100.0);
    let mfd = analysis::flow_accumulation_mfd(&eps, &cs, MFD_EXPONENT);
    assert!(mfd.iter().all(|v| v.is_finite()));
    let all_nan = Array2::from_elem((4, 4), f32::NAN);
    assert!(analysis::priority_flood_fill(&all_nan)
        .iter()
        .all(|v| v.is_nan()));
    assert_eq!(analysis::relief(&all_nan), 0.0);
    let _ = analysis::aspect(&all_nan, &cs);
    let _ = analysis::band_energy(&all_nan, 0.0, 0.5);
}

// ---------------------------------------------------------------------------------------------
// Realism measures: pixel-axis anisotropy, drainage density
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, .. ProptestConfig::default() })]

    /// The FFT-based anisotropy equals the naive DFT twin (plane by normal equations, wedges by
    /// angle in degrees) on random grids of any size.
    #[test]
    fn axis_anisotropy_matches_naive(rows in 4usize..22, cols in 4usize..22, seed in any::<u64>()) {
        let mut g = Lcg(seed);
        let z = Array2::from_shape_fn((rows, cols), |(r, c)| {
            (g.next() * 50.0 + 3.0 * r as f64 - 2.0 * c as f64) as f32
        });
        let fast = analysis::axis_anisotropy(&z);
        let slow = naive::axis_anisotropy(&z);
        prop_assert!(
            (fast.is_nan() && slow.is_nan()) || rel_close(fast, slow, 1e-9),
            "{fast} vs {slow}"
        );
    }
}

/// White noise in [0, 100) from the test LCG.
fn noise(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
    let mut g = Lcg(seed);
    Array2::from_shape_fn((rows, cols), |_| (g.next() * 100.0) as f32)
}

#[test]
fn axis_anisotropy_sees_ribbing_and_ignores_planes() {
    let white = noise(64, 64, 5);
    let a_white = analysis::axis_anisotropy(&white);
    assert!((0.6..1.6).contains(&a_white), "white noise {a_white}");
    // A tilted plane adds nothing: it is detrended away.
    let tilted = Array2::from_shape_fn((64, 64), |(r, c)| {
        white[[r, c]] + 40.0 * r as f32 - 25.0 * c as f32
    });
    assert!((analysis::axis_anisotropy(&tilted) - a_white).abs() < 1e-6 * a_white);
    // Ribs along the columns (frequency 0.4 cycles/pixel along x) dominate the axis wedge.
    let ribbed = Array2::from_shape_fn((64, 64), |(r, c)| {
        white[[r, c]] + 60.0 * math::cosf(2.0 * std::f32::consts::PI * 0.4 * c as f32)
    });
    assert!(analysis::axis_anisotropy(&ribbed) > 10.0 * a_white);
    // The same ribs along a diagonal weigh on the other side of the ratio.
    let diagonal = Array2::from_shape_fn((64, 64), |(r, c)| {
        white[[r, c]] + 60.0 * math::cosf(2.0 * std::f32::consts::PI * 0.3 * (r + c) as f32)
    });
    assert!(analysis::axis_anisotropy(&diagonal) < 0.1 * a_white);
    // Transposing a square grid swaps the two axes: same ratio.
    let t = white.t().to_owned();
    assert!((analysis::axis_anisotropy(&t) - a_white).abs() < 1e-9 * a_white);
    assert!(analysis::axis_anisotropy(&Array2::zeros((3, 8))).is_nan());
}

#[test]
fn drainage_density_of_an_eastward_plane() {
    // Every row drains east along its own chain: cell c has (c + 1) cells upstream. With a
    // threshold of 3 cells, columns 2..=8 carry a 100 m link each (column 9 is an outlet):
    // 7 links × 100 m × 5 rows over 50 cells of 1e4 m² = 3.5 km / 0.5 km² = 7 km per km².
    let z = plane(5, 10, 100.0, |x, _| -x);
    let cs = CellSizes::uniform(5, 100.0);
    let d = analysis::drainage_density(&z, &cs, 3e4);
    assert!((d - 7.0).abs() < 1e-9, "{d}");
    // A higher threshold (6 cells: columns 5..=8) shortens the network.
    let d6 = analysis::drainage_density(&z, &cs, 6e4);
    assert!((d6 - 4.0).abs() < 1e-9, "{d6}");
    assert_eq!(
        analysis::drainage_density(&Array2::zeros((0, 0)), &cs, 1.0),
        0.0
    );
}

// ---------------------------------------------------------------------------------------------
// Bounded pit breaching
// ---------------------------------------------------------------------------------------------

use terrasynth_core::analysis::banks::widen_channels;
use terrasynth_core::analysis::breach::{
    breach_margin, breach_pits, breach_pits_naive, breach_pits_naive_with, breach_pits_with,
    BreachRule,
};

/// Rough random terrain: a tilt plus noise, rounded to 1/4 m so that ties (flats) occur.
fn rough_terrain(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
    let mut g = Lcg(seed);
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        ((0.3 * r as f64 - 0.2 * c as f64 + 6.0 * g.next()) * 4.0).round() as f32 / 4.0
    })
}

/// Whether `(r, c)` is below all 8 neighbours in the order (value, global row, global column).
fn is_pit_in(z: &Array2<f32>, origin: (i64, i64), r: usize, c: usize) -> bool {
    let key = |r: usize, c: usize| (origin.0 + r as i64, origin.1 + c as i64);
    D8_OFFSETS.iter().all(|&(dr, dc)| {
        let (nr, nc) = ((r as isize + dr) as usize, (c as isize + dc) as usize);
        let (a, b) = (z[[nr, nc]], z[[r, c]]);
        a > b || (a == b && key(nr, nc) > key(r, c))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// The Dijkstra version equals the Bellman-Ford reference bit for bit.
    #[test]
    fn breach_matches_naive(rows in 9usize..26, cols in 9usize..26, radius in 1usize..4,
                            seed in any::<u64>(), r0 in -50i64..50, c0 in -50i64..50) {
        let z = rough_terrain(rows, cols, seed);
        let fast = breach_pits(&z, (r0, c0), radius);
        let slow = breach_pits_naive(&z, (r0, c0), radius);
        prop_assert_eq!(fast.dim(), slow.dim());
        prop_assert!(fast.iter().zip(slow.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    /// With a reach per pit (steep pits far, flat pits near or not at all), the Dijkstra
    /// version still equals the reference bit for bit, and stays window-invariant.
    #[test]
    fn breach_rule_matches_naive_and_is_window_invariant(
        rows in 14usize..30, cols in 14usize..30, radius in 2usize..5, flat in 0usize..3,
        rise in 0.0f32..4.0, volume in any::<bool>(), corner in prop_oneof![Just(0.0f32), 0.05f32..1.0],
        corner_rise in 0.0f32..6.0, seed in any::<u64>(), r0 in 0usize..4, c0 in 0usize..4) {
        let rule = BreachRule {
            radius,
            flat_radius: flat.min(radius),
            steep_rise: rise,
            volume,
            corner_depth: corner,
            corner_rise,
        };
        let z = rough_terrain(rows, cols, seed);
        let fast = breach_pits_with(&z, (3, -4), rule);
        let slow = breach_pits_naive_with(&z, (3, -4), rule);
        prop_assert_eq!(fast.dim(), slow.dim());
        prop_assert!(fast.iter().zip(slow.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
        let m = breach_margin(radius);
        let sub = z.slice(ndarray::s![r0.., c0..]).to_owned();
        prop_assume!(sub.nrows() > 2 * m && sub.ncols() > 2 * m);
        let part = breach_pits_with(&sub, (3 + r0 as i64, -4 + c0 as i64), rule);
        for ((r, c), v) in part.indexed_iter() {
            prop_assert_eq!(v.to_bits(), fast[[r + r0, c + c0]].to_bits(), "({}, {})", r, c);
        }
    }

    /// A cell's result depends only on its neighbourhood: breaching a sub-window (with its global
    /// origin) gives the same inner values as breaching the whole grid.
    #[test]
    fn breach_is_window_invariant(seed in any::<u64>(), radius in 1usize..5,
                                  r0 in 0usize..20, c0 in 0usize..20, h in 12usize..40, w in 12usize..40) {
        let z = rough_terrain(64, 64, seed);
        let m = breach_margin(radius);
        let whole = breach_pits(&z, (100, -7), radius);
        let (h, w) = (h.min(64 - r0), w.min(64 - c0));
        prop_assume!(h > 2 * m && w > 2 * m);
        let sub = z.slice(ndarray::s![r0..r0 + h, c0..c0 + w]).to_owned();
        let part = breach_pits(&sub, (100 + r0 as i64, -7 + c0 as i64), radius);
        for ((r, c), v) in part.indexed_iter() {
            let (wr, wc) = (r + r0, c + c0);
            prop_assert_eq!(v.to_bits(), whole[[wr, wc]].to_bits(), "({}, {})", wr, wc);
        }
    }

    /// Breaching only lowers cells, and every pit of the result (away from the window's edge)
    /// was already a pit: channels descend strictly, so they create none; nor do the corners
    /// of their diagonal steps, which stay above the step's lower end.
    #[test]
    fn breach_lowers_and_creates_no_pit(seed in any::<u64>(), radius in 1usize..5,
                                        corner in prop_oneof![Just(0.0f32), 0.05f32..1.0]) {
        let z = rough_terrain(40, 40, seed);
        let m = breach_margin(radius);
        let rule = BreachRule { corner_depth: corner, corner_rise: 0.0, ..BreachRule::uniform(radius) };
        let b = breach_pits_with(&z, (0, 0), rule);
        let inner = z.slice(ndarray::s![m..40 - m, m..40 - m]).to_owned();
        prop_assert!(b.iter().zip(inner.iter()).all(|(x, y)| x <= y));
        let (rows, cols) = b.dim();
        for r in 1..rows - 1 {
            for c in 1..cols - 1 {
                if is_pit_in(&b, (m as i64, m as i64), r, c) {
                    prop_assert!(is_pit_in(&inner, (m as i64, m as i64), r, c), "new pit at ({}, {})", r, c);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// Banks beside breached channels (`analysis::banks`): they only lower cells the breaching
    /// left, create no pit, keep the trench, and a sub-window gives the same values as the whole.
    #[test]
    fn banks_lower_create_no_pit_and_are_window_invariant(seed in any::<u64>(), rings in 1usize..4,
            share in 0.1f32..1.0, r0 in 0usize..8, c0 in 0usize..8, h in 12usize..30, w in 12usize..30) {
        let z = rough_terrain(44, 44, seed);
        let m = breach_margin(3);
        let carved = breach_pits(&z, (0, 0), 3);
        let raw = z.slice(ndarray::s![m..44 - m, m..44 - m]).to_owned();
        let banked = widen_channels(&raw, &carved, rings, share);
        let n = carved.nrows() - 2 * rings;
        prop_assert_eq!(banked.dim(), (n, n));
        let inner = |a: &Array2<f32>| a.slice(ndarray::s![rings..rings + n, rings..rings + n]).to_owned();
        let (raw_i, carved_i) = (inner(&raw), inner(&carved));
        let mut lowered = 0;
        for ((rc, &b), (&c, &r)) in banked.indexed_iter().zip(carved_i.iter().zip(raw_i.iter())) {
            prop_assert!(b <= c, "{:?} rises", rc);
            if c < r {
                prop_assert_eq!(b.to_bits(), c.to_bits(), "trench {:?} moved", rc);
            }
            lowered += usize::from(b < c);
        }
        let origin = ((m + rings) as i64, (m + rings) as i64);
        for r in 1..n - 1 {
            for c in 1..n - 1 {
                if is_pit_in(&banked, origin, r, c) {
                    prop_assert!(is_pit_in(&carved_i, origin, r, c), "new pit at ({}, {})", r, c);
                }
            }
        }
        // Rough terrain has pits to breach, so some banks appear.
        prop_assert!(lowered > 0);
        let (h, w) = (h.min(raw.nrows() - r0), w.min(raw.ncols() - c0));
        prop_assume!(h > 2 * rings && w > 2 * rings);
        let cut = |a: &Array2<f32>| a.slice(ndarray::s![r0..r0 + h, c0..c0 + w]).to_owned();
        let part = widen_channels(&cut(&raw), &cut(&carved), rings, share);
        for ((r, c), v) in part.indexed_iter() {
            prop_assert_eq!(v.to_bits(), banked[[r + r0, c + c0]].to_bits(), "({}, {})", r, c);
        }
    }
}

/// [`breach_pits_with`] of `z` at origin `(0, 0)`, checked bit for bit against its reference.
fn breach_checked(z: &Array2<f32>, rule: BreachRule) -> Array2<f32> {
    let fast = breach_pits_with(z, (0, 0), rule);
    let slow = breach_pits_naive_with(z, (0, 0), rule);
    assert!(fast
        .iter()
        .zip(slow.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    fast
}

/// By volume, a channel costs the same per metre in every direction; by depth alone, a diagonal
/// step carves √2 of channel for the price of one. A pit 10 m below a plateau with two lower
/// cells: one 5 cells east (4 plateau cells to cut, 4 m of trench each 10 m deep), one 4 cells
/// along the diagonal (3 plateau cells, 3√2 ≈ 4.24 m). By volume the nearer one, east, drains
/// the pit; by depth alone the diagonal one.
#[test]
fn breach_by_volume_takes_the_shorter_channel_not_the_diagonal() {
    let mut z = Array2::from_elem((40, 40), 100.0f32);
    z[[20, 20]] = 90.0; // the pit
    z[[20, 25]] = 80.0; // 5 cells east
    z[[24, 24]] = 80.0; // 4 cells along the diagonal
    let m = breach_margin(6);
    let by = |volume| {
        breach_checked(
            &z,
            BreachRule {
                volume,
                ..BreachRule::uniform(6)
            },
        )
    };
    let cut = |b: &Array2<f32>, cells: &[(usize, usize)]| {
        cells.iter().all(|&(r, c)| b[[r - m, c - m]] < 100.0)
    };
    let east = [(20, 21), (20, 22), (20, 23), (20, 24)];
    let diagonal = [(21, 21), (22, 22), (23, 23)];
    let volume = by(true);
    assert!(cut(&volume, &east) && !cut(&volume, &diagonal));
    let depth = by(false);
    assert!(cut(&depth, &diagonal) && !cut(&depth, &east));
    // Either way the channel descends from the pit to its goal.
    assert!(volume[[20 - m, 21 - m]] > volume[[20 - m, 24 - m]]);
}

/// A pit whose only outlet lies along the diagonal: the channel runs (21, 21), (22, 22),
/// (23, 23) to the goal at (24, 24). With corners, each diagonal step from `(r, c)` to
/// `(r + 1, c + 1)` also lowers the two cells it passes between, `(r, c + 1)` and `(r + 1, c)`,
/// `corner_depth` of the way down to the channel value at the step's start; without, nothing
/// beside the path moves. Pits whose neighbourhood rises less than `corner_rise` get no corners.
#[test]
fn breach_corners_widen_diagonal_channels_of_steep_pits() {
    let mut z = Array2::from_shape_fn((40, 40), |(_, c)| 100.0 - 0.01 * c as f32);
    z[[20, 20]] = 90.0; // the pit
    z[[24, 24]] = 80.0; // its goal, 4 cells along the diagonal
    for c in 0..40 {
        // A ridge just north of the pit: its neighbourhood rises 40 m.
        z[[19, c]] = 130.0;
    }
    let m = breach_margin(6);
    let run = |corner_depth: f32, corner_rise: f32| {
        breach_checked(
            &z,
            BreachRule {
                corner_depth,
                corner_rise,
                ..BreachRule::uniform(6)
            },
        )
    };
    let at = |b: &Array2<f32>, r: usize, c: usize| b[[r - m, c - m]];
    let plain = run(0.0, 0.0);
    let path = [(21, 21), (22, 22), (23, 23)];
    for (i, &(r, c)) in path.iter().enumerate() {
        // The straight grade from 90 to 80 over four steps.
        assert_eq!(at(&plain, r, c), 90.0 - 2.5 * (i + 1) as f32);
    }
    // Step i runs from (20 + i, 20 + i), where the channel stands at 90 − 2.5 i.
    let corners: Vec<((usize, usize), f32)> = (0..4)
        .flat_map(|i| {
            let (r, t) = (20 + i, 90.0 - 2.5 * i as f32);
            [((r, r + 1), t), ((r + 1, r), t)]
        })
        .collect();
    for &((r, c), _) in &corners {
        assert_eq!(
            at(&plain, r, c),
            z[[r, c]],
            "no corner without corner_depth"
        );
    }
    let wide = run(0.5, 20.0);
    for &((r, c), t) in &corners {
        let own = z[[r, c]];
        let want = (f64::from(own) - (f64::from(own) - f64::from(t)) * 0.5) as f32;
        assert_eq!(at(&wide, r, c), want, "corner ({r}, {c})");
    }
    for &(r, c) in &path {
        assert_eq!(
            at(&wide, r, c),
            at(&plain, r, c),
            "the channel itself is unchanged"
        );
    }
    // Nothing else moves: the path, the corners, and the rest as it was.
    let moved = wide
        .indexed_iter()
        .filter(|&((r, c), v)| *v != z[[r + m, c + m]])
        .count();
    assert_eq!(moved, path.len() + corners.len());
    // The pit's neighbourhood rises 40 m (the ridge): a corner_rise above that leaves it plain.
    assert_eq!(run(0.5, 50.0), plain);
}

#[test]
fn breach_rule_leaves_flat_pits_and_cuts_steep_ones() {
    // Two pits 2 m deep below their 1-cell rims, both drainable within 3 cells: one on a plain
    // (nothing within 2 cells rises more than 2 m above it), one at the foot of a 50 m wall.
    let mut z = Array2::from_elem((60, 70), 100.0f32);
    for c in 0..70 {
        z[[28, c]] = 100.0 - 0.5 * c as f32; // a channel falling east along row 28
    }
    z[[24, 22]] = 98.0; // flat pit: its rim is the 100 m plain
    z[[24, 46]] = 98.0; // steep pit: a wall rises behind it
    for r in 21..24 {
        for c in 44..49 {
            z[[r, c]] = 150.0;
        }
    }
    let rule = BreachRule {
        radius: 8,
        flat_radius: 0,
        steep_rise: 20.0,
        volume: true,
        corner_depth: 0.0,
        corner_rise: f32::INFINITY,
    };
    let m = breach_margin(8);
    let out = breach_pits_with(&z, (0, 0), rule);
    assert_eq!(out[[24 - m, 22 - m]], 98.0);
    let uniform = breach_pits(&z, (0, 0), 8);
    // Uniformly, both pits get a channel: some cell around each is lowered.
    let lowered = |a: &Array2<f32>, r: usize, c: usize| {
        (r - 1..=r + 1).any(|rr| (c - 1..=c + 1).any(|cc| a[[rr - m, cc - m]] < z[[rr, cc]]))
    };
    assert!(lowered(&uniform, 24, 22) && lowered(&uniform, 24, 46));
    assert!(!lowered(&out, 24, 22), "the flat pit is left");
    assert!(lowered(&out, 24, 46), "the steep pit is breached");
}

#[test]
fn breach_cuts_the_cheapest_rim_and_keeps_unreachable_pits() {
    // A plane falling 10 m per cell eastwards with a pit of −15 m at (10, 10) (the plane is 0 m
    // there): its east neighbour (−10 m) is a one-cell rim, the cell beyond (−20 m) is lower.
    // The cheapest channel (carve 5 m) goes straight east; its one inner cell takes the straight
    // grade from −15 to −20 over two steps: −17.5.
    let mut z = plane(21, 21, 1.0, |x, _| 100.0 - 10.0 * x);
    let base = z[[10, 10]];
    z[[10, 10]] = base - 15.0;
    let m = breach_margin(3);
    let b = breach_pits(&z, (0, 0), 3);
    assert_eq!(b[[10 - m, 11 - m]], base - 17.5);
    // The pit and the goal keep their values, and nothing else moves.
    assert_eq!(b[[10 - m, 10 - m]], base - 15.0);
    assert_eq!(b[[10 - m, 12 - m]], z[[10, 12]]);
    let moved = b
        .indexed_iter()
        .filter(|&((r, c), v)| *v != z[[r + m, c + m]])
        .count();
    assert_eq!(moved, 1);
    // A pit deeper than every cell within the radius stays as it is.
    let mut deep = plane(21, 21, 1.0, |x, _| 100.0 - 0.1 * x);
    deep[[10, 10]] = 10.0;
    let bd = breach_pits(&deep, (0, 0), 2);
    assert_eq!(bd, deep.slice(ndarray::s![4..17, 4..17]).to_owned());
    assert_eq!(breach_pits(&Array2::zeros((6, 6)), (0, 0), 2).len(), 0);
}

// ---------------------------------------------------------------------------------------------
// Block means given back after breaching
// ---------------------------------------------------------------------------------------------

use terrasynth_core::analysis::block_means::{restore_block_means, restore_block_means_naive};

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, .. ProptestConfig::default() })]

    /// The block-by-block pass equals its per-cell reference bit for bit; it raises only cells
    /// the breaching left, never a channel; with a share of 1 each whole block's sum returns to
    /// the raw surface's (where the block kept a cell); and a sub-window gives the same values on
    /// its whole blocks.
    #[test]
    fn block_means_match_naive_restore_and_are_window_invariant(seed in any::<u64>(),
            share in 0.0f32..1.0, or in -5i64..5, oc in -5i64..5, r0 in 0usize..6, c0 in 0usize..6,
            h in 4usize..20, w in 4usize..20) {
        let z = rough_terrain(44, 44, seed);
        let m = breach_margin(3);
        let carved = breach_pits(&z, (or, oc), 3);
        let raw = z.slice(ndarray::s![m..44 - m, m..44 - m]).to_owned();
        let origin = (or + m as i64, oc + m as i64);
        let mut fast = carved.clone();
        restore_block_means(raw.view(), &mut fast, origin, share);
        let slow = restore_block_means_naive(&raw, &carved, origin, share);
        prop_assert!(fast.iter().zip(slow.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
        for ((p, &f), (&c, &r)) in fast.indexed_iter().zip(carved.iter().zip(raw.iter())) {
            if c < r {
                prop_assert_eq!(f.to_bits(), c.to_bits(), "channel {:?} moved", p);
            } else {
                prop_assert!(f >= c, "{:?} lowered", p);
            }
        }
        let mut full = carved.clone();
        restore_block_means(raw.view(), &mut full, origin, 1.0);
        let (rows, cols) = raw.dim();
        let (fr, fc) = (origin.0.rem_euclid(2) as usize, origin.1.rem_euclid(2) as usize);
        let mut restored_blocks = 0;
        for r in (fr..rows - 1).step_by(2) {
            for c in (fc..cols - 1).step_by(2) {
                let cells = [(r, c), (r, c + 1), (r + 1, c), (r + 1, c + 1)];
                let kept = cells.iter().any(|&p| carved[p] >= raw[p]);
                if kept {
                    let sum = |a: &Array2<f32>| cells.iter().map(|&p| f64::from(a[p])).sum::<f64>();
                    prop_assert!((sum(&full) - sum(&raw)).abs() < 1e-3, "block ({}, {})", r, c);
                    restored_blocks += usize::from(cells.iter().any(|&p| carved[p] < raw[p]));
                }
            }
        }
        // Rough terrain has channels, so some blocks are restored.
        prop_assert!(restored_blocks > 0);
        let (h, w) = (h.min(rows - r0), w.min(cols - c0));
        let cut = |a: &Array2<f32>| a.slice(ndarray::s![r0..r0 + h, c0..c0 + w]).to_owned();
        let mut part = cut(&carved);
        let sub_origin = (origin.0 + r0 as i64, origin.1 + c0 as i64);
        restore_block_means(cut(&raw).view(), &mut part, sub_origin, share);
        for ((r, c), v) in part.indexed_iter() {
            // Whole blocks of the sub-window: the block's first cell and its last inside it.
            let (gr, gc) = (sub_origin.0 + r as i64, sub_origin.1 + c as i64);
            let (br, bc) = (gr.div_euclid(2) * 2 - sub_origin.0, gc.div_euclid(2) * 2 - sub_origin.1);
            if br >= 0 && bc >= 0 && br + 1 < h as i64 && bc + 1 < w as i64 {
                prop_assert_eq!(v.to_bits(), fast[[r + r0, c + c0]].to_bits(), "({}, {})", r, c);
            }
        }
    }
}
