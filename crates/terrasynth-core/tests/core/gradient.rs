//! The gradient-domain amplifier (issue #20): tile set building and its format, the precomputed
//! reconstruction against its naive dense solve, and the amplifier's invariants (window
//! invariance, thread-count independence, zoom consistency, detail).

use std::sync::Arc;

use ndarray::Array2;
use proptest::prelude::*;
use terrasynth_core::dictionary::gradient_format::{content_id, from_bytes, is_gradient, to_bytes};
use terrasynth_core::dictionary::{
    build_gradient_tiles, DictionaryError, GradientParams, GradientTileSet,
};
use terrasynth_core::synth::gradient_solve::{
    apply_naive, input_count, solve_naive, Reconstruction,
};
use terrasynth_core::synth::{
    amplify_chain, AnyAmplifier, ClampedRaster, Field, GradientAmplifier, Window,
};
use terrasynth_test_support::synthetic_terrain;

fn tile_set(params: &GradientParams) -> Arc<GradientTileSet> {
    let ex = [
        synthetic_terrain(160, 160, 3),
        synthetic_terrain(128, 144, 8),
    ];
    Arc::new(build_gradient_tiles(&ex, params).unwrap())
}

fn box2(a: &Array2<f32>) -> Array2<f32> {
    Array2::from_shape_fn((a.nrows() / 2, a.ncols() / 2), |(r, c)| {
        (a[[2 * r, 2 * c]]
            + a[[2 * r, 2 * c + 1]]
            + a[[2 * r + 1, 2 * c]]
            + a[[2 * r + 1, 2 * c + 1]])
            / 4.0
    })
}

fn same_bits(a: &Array2<f32>, b: &Array2<f32>) -> bool {
    a.dim() == b.dim()
        && a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

// --- building and the format ---

#[test]
fn a_built_set_round_trips_and_its_id_is_its_checksum() {
    let set = tile_set(&GradientParams::default());
    let bytes = to_bytes(&set).unwrap();
    assert!(is_gradient(&bytes));
    assert_eq!(&bytes[..8], b"TSGRAD\0\x01");
    assert_eq!(from_bytes(&bytes).unwrap(), *set);
    let tail: String = bytes[bytes.len() - 32..]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(content_id(&set).unwrap(), tail);
    // The same exemplars and parameters give the same bytes.
    assert_eq!(
        to_bytes(&tile_set(&GradientParams::default())).unwrap(),
        bytes
    );
    // The dictionary reader refuses it by its magic, and the gradient reader refuses a dictionary.
    assert!(matches!(
        terrasynth_core::dictionary::from_bytes(&bytes),
        Err(DictionaryError::BadMagic)
    ));
    let dict = terrasynth_core::dictionary::to_bytes(&terrasynth_test_support::small_dictionary(1))
        .unwrap();
    assert!(!is_gradient(&dict));
    assert!(matches!(from_bytes(&dict), Err(DictionaryError::BadMagic)));
}

#[test]
fn every_truncation_and_flipped_byte_is_an_error() {
    let set = tile_set(&GradientParams {
        tile: 4,
        colours: 2,
        alternatives: 1,
        ..Default::default()
    });
    let bytes = to_bytes(&set).unwrap();
    for cut in 0..bytes.len() {
        assert!(from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    for i in (0..bytes.len()).step_by(7) {
        let mut b = bytes.clone();
        b[i] ^= 0x20;
        assert!(from_bytes(&b).is_err(), "flip at {i}");
    }
    let mut long = bytes.clone();
    long.push(0);
    assert!(from_bytes(&long).is_err());
}

#[test]
fn bad_parameters_and_exemplars_are_clear_errors() {
    let ex = [synthetic_terrain(64, 64, 1)];
    let e = build_gradient_tiles(
        &ex,
        &GradientParams {
            tile: 10,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("tile 10"), "{e}");
    let e = build_gradient_tiles(
        &ex,
        &GradientParams {
            mixing: 1.5,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("mixing"), "{e}");
    assert!(matches!(
        build_gradient_tiles(&[], &GradientParams::default()),
        Err(DictionaryError::InvalidParams(_))
    ));
    assert!(matches!(
        build_gradient_tiles(&[synthetic_terrain(8, 8, 1)], &GradientParams::default()),
        Err(DictionaryError::NoPatches)
    ));
    assert!(matches!(
        build_gradient_tiles(
            &[Array2::from_elem((64, 64), f32::NAN)],
            &GradientParams::default()
        ),
        Err(DictionaryError::NoPatches)
    ));
}

#[test]
fn every_combination_has_its_alternatives_and_found_counts_add_up() {
    let params = GradientParams::default();
    let set = tile_set(&params);
    let combos = params.combinations();
    assert_eq!(set.found.len(), 2 * combos);
    // Both axes see every candidate window once.
    let (x, y): (u32, u32) = (
        set.found[..combos].iter().sum(),
        set.found[combos..].iter().sum(),
    );
    assert_eq!(x, y);
    assert!(x > 100, "{x} candidates");
    // The detail tiles are not empty.
    let energy: f32 = set.tiles.iter().map(|v| v * v).sum();
    assert!(energy > 0.0);
}

// --- the reconstruction against its naive twin ---

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, .. ProptestConfig::default() })]

    #[test]
    fn precomputed_reconstruction_equals_the_dense_solve(t in prop::sample::select(vec![4usize, 8]), seed in 0u64..1000) {
        let recon = Reconstruction::new(t).unwrap();
        let mut rng = terrasynth_core::dictionary::Rng::new(seed);
        let inputs: Vec<f32> = (0..input_count(t)).map(|_| (rng.normal() * 50.0) as f32).collect();
        let mut fast = vec![0.0f32; t * t];
        recon.apply(&inputs, &mut fast);
        let naive = solve_naive(t, &inputs).unwrap();
        for (a, b) in fast.iter().zip(&naive) {
            prop_assert!((f64::from(*a) - b).abs() < 1e-3 * (1.0 + b.abs()), "{a} vs {b}");
        }
        // The constraint: each 2×2 box average is its control point.
        let p0 = 2 * t * (t - 1);
        for br in 0..t / 2 {
            for bc in 0..t / 2 {
                let m = (naive[2 * br * t + 2 * bc] + naive[2 * br * t + 2 * bc + 1]
                    + naive[(2 * br + 1) * t + 2 * bc] + naive[(2 * br + 1) * t + 2 * bc + 1]) / 4.0;
                prop_assert!((m - f64::from(inputs[p0 + br * (t / 2) + bc])).abs() < 1e-6);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, .. ProptestConfig::default() })]

    /// The sized (register, AVX2) kernels sum in the reference's order: the same bits.
    #[test]
    fn sized_reconstruction_kernels_equal_the_naive_sum_bit_for_bit(t in prop::sample::select(vec![4usize, 8, 12, 16]), seed in 0u64..1000) {
        let recon = Reconstruction::new(t).unwrap();
        let mut rng = terrasynth_core::dictionary::Rng::new(seed);
        let inputs: Vec<f32> = (0..input_count(t)).map(|_| (rng.normal() * 50.0) as f32).collect();
        let mut fast = vec![1.0f32; t * t];
        recon.apply(&inputs, &mut fast);
        let mut naive = vec![0.0f32; t * t];
        apply_naive(recon.weights(), t * t, &inputs, &mut naive);
        for (a, b) in fast.iter().zip(&naive) {
            prop_assert_eq!(a.to_bits(), b.to_bits());
        }
    }
}

#[test]
fn a_consistent_gradient_field_is_reproduced_exactly() {
    // h = x² + 3y: its exact gradients and its box averages give h back.
    let t = 8;
    let h = |r: usize, c: usize| (c * c) as f64 + 3.0 * r as f64;
    let mut inputs = Vec::new();
    for r in 0..t {
        for c in 0..t - 1 {
            inputs.push((h(r, c + 1) - h(r, c)) as f32);
        }
    }
    for r in 0..t - 1 {
        for c in 0..t {
            inputs.push((h(r + 1, c) - h(r, c)) as f32);
        }
    }
    for br in 0..t / 2 {
        for bc in 0..t / 2 {
            let m = (h(2 * br, 2 * bc)
                + h(2 * br, 2 * bc + 1)
                + h(2 * br + 1, 2 * bc)
                + h(2 * br + 1, 2 * bc + 1))
                / 4.0;
            inputs.push(m as f32);
        }
    }
    let mut out = vec![0.0f32; t * t];
    Reconstruction::new(t).unwrap().apply(&inputs, &mut out);
    for r in 0..t {
        for c in 0..t {
            assert!((f64::from(out[r * t + c]) - h(r, c)).abs() < 1e-3);
        }
    }
}

// --- the amplifier's invariants ---

fn gradient_levels(n: usize) -> Vec<AnyAmplifier> {
    let set = tile_set(&GradientParams::default());
    (0..n)
        .map(|_| AnyAmplifier::Gradient(GradientAmplifier::new(set.clone()).unwrap()))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    #[test]
    fn gradient_levels_are_window_invariant(c0 in -30i64..300, r0 in -30i64..300, w in 1usize..90, h in 1usize..90) {
        let base = synthetic_terrain(80, 80, 5);
        let layer = synthetic_terrain(80, 80, 6);
        let src = ClampedRaster { elevation: &base, layers: vec![("moisture".into(), &layer)] };
        let amps = gradient_levels(2);
        let big = Window::new(-40, -40, 440, 440);
        let whole = amplify_chain(&amps, &src, big, 100.0).unwrap();
        let part_w = Window::new(c0, r0, w, h);
        let part = amplify_chain(&amps, &src, part_w, 100.0).unwrap();
        let expect = whole.crop(part_w).unwrap();
        prop_assert!(same_bits(&part.elevation, &expect.elevation));
        prop_assert_eq!(part.layers.len(), 1);
        prop_assert!(same_bits(&part.layers[0].1, &expect.layers[0].1));
    }
}

#[test]
fn gradient_levels_do_not_depend_on_the_thread_count() {
    let base = synthetic_terrain(64, 64, 11);
    let run = |threads: usize| -> Field {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let src = ClampedRaster {
                elevation: &base,
                layers: vec![],
            };
            amplify_chain(
                &gradient_levels(2),
                &src,
                Window::new(-7, 3, 250, 256),
                100.0,
            )
            .unwrap()
        })
    };
    assert!(same_bits(&run(1).elevation, &run(3).elevation));
}

#[test]
fn gradient_levels_box_average_back_to_the_input_and_add_detail() {
    let base = synthetic_terrain(64, 64, 21);
    let src = ClampedRaster {
        elevation: &base,
        layers: vec![],
    };
    let out = amplify_chain(
        &gradient_levels(2),
        &src,
        Window::new(0, 0, 256, 256),
        100.0,
    )
    .unwrap();
    let back = box2(&box2(&out.elevation));
    let relief = base.iter().cloned().fold(f32::MIN, f32::max)
        - base.iter().cloned().fold(f32::MAX, f32::min);
    let worst = back
        .iter()
        .zip(base.iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    // The dictionary amplifier's tolerance is an RMSE of 1 % of the relief; the constrained
    // solve reproduces every parent pixel up to rounding.
    assert!(worst < 1e-4 * relief, "worst {worst} vs relief {relief}");
    // Detail: the result differs from the same reconstruction without tiles.
    let smooth = {
        let set = tile_set(&GradientParams::default());
        let mut zero = (*set).clone();
        zero.tiles.iter_mut().for_each(|v| *v = 0.0);
        let z = Arc::new(zero);
        let amps = vec![
            GradientAmplifier::new(z.clone()).unwrap(),
            GradientAmplifier::new(z).unwrap(),
        ];
        amplify_chain(&amps, &src, Window::new(0, 0, 256, 256), 100.0).unwrap()
    };
    let diff: f64 = out
        .elevation
        .iter()
        .zip(smooth.elevation.iter())
        .map(|(a, b)| f64::from(a - b).powi(2))
        .sum::<f64>()
        / out.elevation.len() as f64;
    assert!(diff.sqrt() > 0.05, "detail rms {}", diff.sqrt());
    assert!(out.elevation.iter().all(|v| v.is_finite()));
}

#[test]
fn a_too_small_parent_is_an_error_and_flat_stays_flat() {
    let amp = GradientAmplifier::new(tile_set(&GradientParams::default())).unwrap();
    let out = Window::new(0, 0, 32, 32);
    let small = Field::elevation_only(Window::new(0, 0, 16, 16), Array2::zeros((16, 16)));
    assert!(amp.amplify(&small, out, 100.0).is_err());
    let pw = amp.parent_window_for(out);
    let flat = Field::elevation_only(pw, Array2::from_elem((pw.rows, pw.cols), 512.0));
    let f = amp.amplify(&flat, out, 100.0).unwrap();
    assert!(
        f.elevation.iter().all(|v| (v - 512.0).abs() < 1e-2),
        "{f:?}"
    );
    let mut nan = flat.clone();
    nan.elevation[[3, 3]] = f32::NAN;
    assert!(amp.amplify(&nan, out, 100.0).is_err());
}
