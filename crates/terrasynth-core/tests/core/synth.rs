//! Amplifier invariants: window invariance (seamlessness), determinism across thread counts, zoom
//! consistency, robustness on flat and nodata input, and error handling.

use ndarray::{s, Array2};
use proptest::prelude::*;
use std::sync::Arc;

use terrasynth_core::dictionary::{Dictionary, MatchWeights};
use terrasynth_core::math;
use terrasynth_core::synth::{
    amplify_chain, Amplifier, ClampedRaster, Field, KernelKind, Levers, SynthError, Window,
};

use terrasynth_test_support::{
    small_dictionary, small_dictionary_with_vegetation, synthetic_terrain,
};

fn box2(a: &Array2<f32>) -> Array2<f32> {
    Array2::from_shape_fn((a.nrows() / 2, a.ncols() / 2), |(r, c)| {
        (a[[2 * r, 2 * c]]
            + a[[2 * r, 2 * c + 1]]
            + a[[2 * r + 1, 2 * c]]
            + a[[2 * r + 1, 2 * c + 1]])
            / 4.0
    })
}

fn rmse(a: &Array2<f32>, b: &Array2<f32>) -> f64 {
    let n = a.len() as f64;
    (a.iter()
        .zip(b.iter())
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
}

// --- window invariance: a pixel's value does not depend on the window it is computed in ---

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    #[test]
    fn one_level_is_window_invariant(c0 in -40i64..120, r0 in -40i64..120, w in 1usize..70, h in 1usize..70) {
        let dict = small_dictionary(3);
        let base = synthetic_terrain(96, 96, 9);
        let src = ClampedRaster { elevation: &base, layers: vec![] };
        let amps = vec![Amplifier::new(dict.clone(), &MatchWeights::default()).unwrap()];
        let big = Window::new(-48, -48, 256, 256);
        let whole = amplify_chain(&amps, &src, big, 100.0).unwrap();
        let part_w = Window::new(c0, r0, w, h);
        let part = amplify_chain(&amps, &src, part_w, 100.0).unwrap();
        let expect = whole.crop(part_w).unwrap();
        // Bit-for-bit equality.
        prop_assert!(part.elevation.iter().zip(expect.elevation.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
        for ((na, a), (nb, b)) in part.layers.iter().zip(&expect.layers) {
            prop_assert_eq!(na, nb);
            prop_assert!(a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    #[test]
    fn two_levels_are_window_invariant(c0 in -20i64..300, r0 in -20i64..300, w in 1usize..90, h in 1usize..90) {
        let dict = small_dictionary(4);
        let base = synthetic_terrain(80, 80, 2);
        let src = ClampedRaster { elevation: &base, layers: vec![] };
        let weights = MatchWeights::default();
        let amps = vec![Amplifier::new(dict.clone(), &weights).unwrap(), Amplifier::new(dict.clone(), &weights).unwrap()];
        let big = Window::new(-32, -32, 420, 420);
        let whole = amplify_chain(&amps, &src, big, 100.0).unwrap();
        let part_w = Window::new(c0, r0, w, h);
        let part = amplify_chain(&amps, &src, part_w, 100.0).unwrap();
        let expect = whole.crop(part_w).unwrap();
        prop_assert!(part.elevation.iter().zip(expect.elevation.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

// --- every lever keeps the invariants (issue #12's ablations run them all) ---

/// The lever sets of the ablation: the baseline, each lever alone, and the default.
fn lever_sets() -> Vec<Levers> {
    let base = Levers::baseline();
    vec![
        base,
        Levers {
            consistent_split: true,
            ..base
        },
        Levers {
            parent_smooth: true,
            ..base
        },
        Levers {
            blend_power: 3,
            ..base
        },
        Levers {
            roughness: 0.6,
            ..base
        },
        Levers {
            kernel: KernelKind::Kaiser6,
            passes: 2,
            ..base
        },
        Levers {
            kernel: KernelKind::Kaiser4,
            ..base
        },
        Levers { breach: 3, ..base },
        Levers {
            slope_mod: true,
            ..base
        },
        Levers::default(),
        Levers {
            sparsity: 3,
            ..base
        },
        Levers {
            sparsity: 4,
            ..Levers::default()
        },
        Levers {
            banks: 2,
            ..Levers::default()
        },
        Levers {
            mean_k: 3,
            ..Levers::default()
        },
        Levers {
            plains_roughness: 0.3,
            plains_slope: 0.5,
            sparsity: 2,
            ..Levers::default()
        },
        Levers {
            corner_depth: 0.3,
            corner_slope: 0.0,
            restore: 0.2,
            ..Levers::default()
        },
    ]
}

/// Two amplification levels over `dict` with `levers` and the default match weights.
fn two_levels(dict: &Arc<Dictionary>, levers: Levers) -> Vec<Amplifier> {
    let w = MatchWeights::default();
    (0..2)
        .map(|_| {
            Amplifier::new(dict.clone(), &w)
                .unwrap()
                .with_levers(levers)
        })
        .collect()
}

/// Two levels with `levers` over the window `(c0, r0, w, h)` equal the same cells of a larger
/// window, bit for bit.
fn check_window_invariant(
    levers: Levers,
    (c0, r0, w, h): (i64, i64, usize, usize),
) -> Result<(), TestCaseError> {
    let dict = small_dictionary(3);
    let base = synthetic_terrain(72, 72, 5);
    let src = ClampedRaster {
        elevation: &base,
        layers: vec![],
    };
    let amps = two_levels(&dict, levers);
    let big = Window::new(-40, -40, 260, 260);
    let whole = amplify_chain(&amps, &src, big, 100.0).unwrap();
    let part_w = Window::new(c0, r0, w, h);
    let part = amplify_chain(&amps, &src, part_w, 100.0).unwrap();
    let expect = whole.crop(part_w).unwrap();
    prop_assert!(
        part.elevation
            .iter()
            .zip(expect.elevation.iter())
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "{:?}",
        levers
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20, .. ProptestConfig::default() })]

    #[test]
    fn every_lever_set_is_window_invariant(which in 0usize..16, c0 in -30i64..150, r0 in -30i64..150, w in 1usize..60, h in 1usize..60) {
        check_window_invariant(lever_sets()[which], (c0, r0, w, h))?;
    }

    /// Corners and block means (the last lever set) in every case: the block means need one
    /// more cell around the output, whose parity follows the window's origin.
    #[test]
    fn corners_and_block_means_are_window_invariant(c0 in -30i64..150, r0 in -30i64..150, w in 1usize..60, h in 1usize..60) {
        let sets = lever_sets();
        check_window_invariant(sets[sets.len() - 1], (c0, r0, w, h))?;
    }
}

#[test]
fn every_lever_set_is_deterministic_across_threads_and_consistent() {
    let dict = small_dictionary(5);
    let base = synthetic_terrain(48, 48, 11);
    let relief = base.iter().cloned().fold(f32::MIN, f32::max)
        - base.iter().cloned().fold(f32::MAX, f32::min);
    for levers in lever_sets() {
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
                let amps = two_levels(&dict, levers);
                amplify_chain(&amps, &src, Window::new(0, 0, 192, 192), 100.0).unwrap()
            })
        };
        let one = run(1);
        let four = run(4);
        assert!(
            one.elevation
                .iter()
                .zip(four.elevation.iter())
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{levers:?}"
        );
        // Zoom consistency: the box averages reproduce the base (breach channels and fewer
        // passes cost some of it, never more than 1 % of the relief here).
        let err = rmse(&box2(&box2(&one.elevation)), &base);
        assert!(err < 0.01 * f64::from(relief), "{levers:?}: rmse {err}");
    }
}

#[test]
fn breaching_drains_the_pits_detail_opens() {
    // The same level with and without breaching: the breached one has far fewer closed
    // depressions, and moves few cells. Breaching alone only lowers cells; giving part of the
    // carved volume back to each parent cell (`restore`) raises only cells it did not lower.
    let dict = small_dictionary(6);
    let base = synthetic_terrain(64, 64, 21);
    let src = ClampedRaster {
        elevation: &base,
        layers: vec![],
    };
    let w = MatchWeights::default();
    let run = |breach: u32, restore: f32| {
        let levers = Levers {
            breach,
            restore,
            ..Levers::default()
        };
        let amps = vec![Amplifier::new(dict.clone(), &w)
            .unwrap()
            .with_levers(levers)];
        amplify_chain(&amps, &src, Window::new(0, 0, 128, 128), 100.0).unwrap()
    };
    let open = run(0, 0.0);
    let drained = run(6, 0.0);
    let restored = run(6, 0.2);
    let flood =
        |f: &terrasynth_core::synth::Field| terrasynth_core::analysis::flood_extent(&f.elevation);
    let (f_open, f_drained, f_restored) = (flood(&open), flood(&drained), flood(&restored));
    assert!(f_open > 1.0, "the unbreached level has pits: {f_open} %");
    assert!(f_drained < 0.5 * f_open, "{f_drained} % vs {f_open} %");
    assert!(f_restored < 0.5 * f_open, "{f_restored} % vs {f_open} %");
    let moved = open
        .elevation
        .iter()
        .zip(drained.elevation.iter())
        .filter(|(a, b)| a != b)
        .count();
    assert!(moved * 10 < open.elevation.len(), "{moved} cells moved");
    assert!(drained
        .elevation
        .iter()
        .zip(open.elevation.iter())
        .all(|(d, o)| d <= o));
    let (mut raised, mut crossed) = (0, 0);
    for ((r, d), o) in restored
        .elevation
        .iter()
        .zip(drained.elevation.iter())
        .zip(open.elevation.iter())
    {
        raised += usize::from(r > d);
        // A channel cell (lowered by the breaching) is never raised.
        crossed += usize::from(d < o && r != d);
    }
    assert!(raised > 0, "restore raised nothing");
    assert_eq!(crossed, 0, "restore moved channel cells");
}

// --- determinism across rayon thread counts ---

#[test]
fn result_is_identical_with_one_and_several_threads() {
    let dict = small_dictionary(5);
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
            let w = MatchWeights::default();
            let amps = vec![
                Amplifier::new(dict.clone(), &w).unwrap(),
                Amplifier::new(dict.clone(), &w).unwrap(),
            ];
            amplify_chain(&amps, &src, Window::new(0, 0, 256, 256), 100.0).unwrap()
        })
    };
    let one = run(1);
    let four = run(4);
    assert!(one
        .elevation
        .iter()
        .zip(four.elevation.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

// --- zoom consistency: box averages of the result reproduce the input ---

#[test]
fn two_levels_box_average_back_to_the_input() {
    let dict = small_dictionary(6);
    let base = synthetic_terrain(64, 64, 21);
    let src = ClampedRaster {
        elevation: &base,
        layers: vec![],
    };
    let w = MatchWeights::default();
    let amps = vec![
        Amplifier::new(dict.clone(), &w).unwrap(),
        Amplifier::new(dict.clone(), &w).unwrap(),
    ];
    let out = amplify_chain(&amps, &src, Window::new(0, 0, 256, 256), 100.0).unwrap();
    let back = box2(&box2(&out.elevation));
    let relief = base.iter().cloned().fold(f32::MIN, f32::max)
        - base.iter().cloned().fold(f32::MAX, f32::min);
    let err = rmse(&back, &base);
    assert!(
        err < 0.01 * f64::from(relief),
        "rmse {err} vs relief {relief}"
    );
    // It adds detail: the result is not a smooth interpolation of the input.
    let nn = Array2::from_shape_fn((256, 256), |(r, c)| base[[r / 4, c / 4]]);
    assert!(rmse(&out.elevation, &nn) > 1.0);
}

// --- flat and degenerate input ---

#[test]
fn flat_input_stays_flat_and_finite() {
    let dict = small_dictionary(7);
    let base = Array2::from_elem((40, 40), 1234.5f32);
    let src = ClampedRaster {
        elevation: &base,
        layers: vec![],
    };
    let w = MatchWeights::default();
    let amps = vec![Amplifier::new(dict.clone(), &w).unwrap()];
    let out = amplify_chain(&amps, &src, Window::new(0, 0, 80, 80), 50.0).unwrap();
    assert!(
        out.elevation.iter().all(|v| (v - 1234.5).abs() < 1e-2),
        "flat stays flat"
    );
}

#[test]
fn parent_too_small_is_an_error() {
    let dict = small_dictionary(8);
    let amp = Amplifier::new(dict.clone(), &MatchWeights::default()).unwrap();
    let out = Window::new(0, 0, 32, 32);
    let need = amp.parent_window_for(out);
    let short = Window::new(need.col0 + 1, need.row0, need.cols - 1, need.rows);
    let parent = Field::elevation_only(short, Array2::zeros((short.rows, short.cols)));
    assert!(matches!(
        amp.amplify(&parent, out, 100.0),
        Err(SynthError::ParentTooSmall { .. })
    ));
    let full = Field::elevation_only(need, Array2::from_elem((need.rows, need.cols), f32::NAN));
    assert!(matches!(
        amp.amplify(&full, out, 100.0),
        Err(SynthError::NonFinite)
    ));
}

#[test]
fn parent_window_is_what_amplify_reads() {
    // Values outside the announced parent window must not matter: poison them.
    let dict = small_dictionary(9);
    let amp = Amplifier::new(dict.clone(), &MatchWeights::default()).unwrap();
    let out = Window::new(13, -7, 40, 33);
    let need = amp.parent_window_for(out);
    let base = synthetic_terrain(200, 200, 4);
    let at = |w: Window| {
        Array2::from_shape_fn((w.rows, w.cols), |(r, c)| {
            base[[
                (w.row0 + r as i64 + 50) as usize,
                (w.col0 + c as i64 + 50) as usize,
            ]]
        })
    };
    let exact = Field::elevation_only(need, at(need));
    let wide_w = Window::new(need.col0 - 5, need.row0 - 5, need.cols + 10, need.rows + 10);
    let mut wide = at(wide_w);
    wide.slice_mut(s![0..5, ..]).fill(1e6);
    wide.slice_mut(s![.., 0..5]).fill(-1e6);
    let a = amp.amplify(&exact, out, 100.0).unwrap();
    let b = amp
        .amplify(&Field::elevation_only(wide_w, wide), out, 100.0)
        .unwrap();
    assert_eq!(a.elevation, b.elevation);
}

// --- the extra layers alone ---

/// A parent field over `w` from `base` (offset 60 cells), with every layer of `dict` but its
/// last as a smooth field in [0, 1] (the last is left to the layer's own blend).
fn layered_parent(dict: &Dictionary, base: &Array2<f32>, w: Window) -> Field {
    let at = |r: usize, c: usize| {
        base[[
            (w.row0 + r as i64 + 60) as usize,
            (w.col0 + c as i64 + 60) as usize,
        ]]
    };
    let n = dict.layers.len().saturating_sub(1);
    Field {
        window: w,
        elevation: Array2::from_shape_fn((w.rows, w.cols), |(r, c)| at(r, c)),
        layers: dict.layers[..n]
            .iter()
            .enumerate()
            .map(|(k, info)| {
                let layer = Array2::from_shape_fn((w.rows, w.cols), |(r, c)| {
                    let x = (w.col0 + c as i64) as f32 * 0.05 + k as f32;
                    let y = (w.row0 + r as i64) as f32 * 0.07;
                    0.5 + 0.5 * (math::sinf(x) * math::cosf(y))
                });
                (info.name.clone(), layer)
            })
            .collect(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, .. ProptestConfig::default() })]

    /// `amplify_layers` from a parent that covers only its own (smaller) window gives the layers
    /// of `amplify` bit for bit, and `upsample_layer` needs no more than that window either.
    #[test]
    fn the_layers_alone_are_amplify_s_layers(c0 in -40i64..40, r0 in -40i64..40, w in 1usize..48, h in 1usize..48) {
        let dict = small_dictionary_with_vegetation(12);
        prop_assume!(dict.layers.len() >= 2);
        let base = synthetic_terrain(260, 260, 6);
        let amp = Amplifier::new(dict.clone(), &MatchWeights::default()).unwrap();
        let out = Window::new(c0, r0, w, h);
        let full = amp.parent_window_for(out);
        let need = amp.layers_parent_window_for(out);
        prop_assert!(full.contains(&need) && need != full, "{need} inside {full}");
        let full_parent = layered_parent(&dict, &base, full);
        let whole = amp.amplify(&full_parent, out, 100.0).unwrap();
        let parent = layered_parent(&dict, &base, need);
        let layers = amp.amplify_layers(&parent, out, 100.0).unwrap();
        prop_assert_eq!(layers.len(), dict.layers.len());
        for ((n1, a), (n2, b)) in layers.iter().zip(&whole.layers) {
            prop_assert_eq!(n1, n2);
            prop_assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()), "{}", n1);
        }
        // The atoms an elevation-only amplifier keeps, from a parent without the layers (as
        // the elevation tiles are amplified), give the same layers without matching again.
        let elevation_only = Amplifier::new(dict.clone(), &MatchWeights::default())
            .unwrap()
            .without_layers();
        let bare = Field::elevation_only(full, full_parent.elevation.clone());
        let (field, atoms) = elevation_only.amplify_keeping_atoms(&bare, out, 100.0).unwrap();
        prop_assert_eq!(&field.elevation, &whole.elevation);
        prop_assert!(field.layers.is_empty());
        prop_assert_eq!(atoms.window(), out);
        let reused = amp.amplify_layers_with(&parent, out, &atoms).unwrap();
        for ((n1, a), (n2, b)) in reused.iter().zip(&whole.layers) {
            prop_assert_eq!(n1, n2);
            prop_assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()), "{}", n1);
        }
        let up = amp.upsample_layer(&parent.layers[0].1, need, out).unwrap();
        let up_full = amp.upsample_layer(&full_parent.layers[0].1, full, out).unwrap();
        prop_assert!(up.iter().zip(&up_full).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
}

#[test]
fn the_layers_alone_refuse_what_does_not_fit() {
    let dict = small_dictionary_with_vegetation(12);
    let base = synthetic_terrain(200, 200, 6);
    let amp = Amplifier::new(dict.clone(), &MatchWeights::default()).unwrap();
    let out = Window::new(0, 0, 32, 32);
    let need = amp.layers_parent_window_for(out);
    let short = Window::new(need.col0 + 1, need.row0, need.cols - 1, need.rows);
    assert!(matches!(
        amp.amplify_layers(&layered_parent(&dict, &base, short), out, 100.0),
        Err(SynthError::ParentTooSmall { .. })
    ));
    let mut nan = layered_parent(&dict, &base, need);
    nan.elevation[[3, 3]] = f32::NAN;
    assert!(matches!(
        amp.amplify_layers(&nan, out, 100.0),
        Err(SynthError::NonFinite)
    ));
    // Kept atoms serve only their window and their dictionary.
    let full = layered_parent(&dict, &base, amp.parent_window_for(out));
    let (_, atoms) = amp.amplify_keeping_atoms(&full, out, 100.0).unwrap();
    assert!(amp.amplify_layers_with(&full, out, &atoms).is_ok());
    let other_window = Window::new(2, 0, 32, 32);
    assert!(matches!(
        amp.amplify_layers_with(&full, other_window, &atoms),
        Err(SynthError::BadWindow(_))
    ));
    // The same atoms, another copy of the dictionary: refused, not trusted.
    let copy = Arc::new((*dict).clone());
    let other = Amplifier::new(copy, &MatchWeights::default()).unwrap();
    assert!(matches!(
        other.amplify_layers_with(&full, out, &atoms),
        Err(SynthError::BadWindow(_))
    ));
}

// --- sparse codes in the amplifier (issue #21) ---

/// One level of `base` with `levers`, on a fixed window.
fn one_level(levers: Levers, base: &Array2<f32>) -> Field {
    let dict = small_dictionary(6);
    let src = ClampedRaster {
        elevation: base,
        layers: vec![],
    };
    let amps = vec![Amplifier::new(dict, &MatchWeights::default())
        .unwrap()
        .with_levers(levers)];
    amplify_chain(&amps, &src, Window::new(0, 0, 128, 128), 100.0).unwrap()
}

#[test]
fn sparsity_zero_takes_at_least_two_atoms_and_more_atoms_fit_the_parent_better() {
    let base = synthetic_terrain(64, 64, 21);
    // Sparsity 0 takes the dictionary's own (1 for a constrained dictionary) but at least 2:
    // the same amplifier as an explicit 2, bit for bit.
    let own = one_level(
        Levers {
            sparsity: 0,
            ..Levers::default()
        },
        &base,
    );
    let explicit = one_level(
        Levers {
            sparsity: 2,
            ..Levers::default()
        },
        &base,
    );
    assert!(own
        .elevation
        .iter()
        .zip(explicit.elevation.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // With more atoms per primitive the blended smooth part (before any residual correction)
    // reproduces the parent more closely: its 2×2 box averages are nearer the base.
    let smooth_only = |sparsity: u32| {
        let f = one_level(
            Levers {
                sparsity,
                passes: 0,
                breach: 0,
                roughness: 0.0,
                ..Levers::baseline()
            },
            &base,
        );
        rmse(&box2(&f.elevation), &base)
    };
    let (e1, e2, e4) = (smooth_only(1), smooth_only(2), smooth_only(4));
    assert!(
        e2 < e1 && e4 < e2,
        "parent fit: s=1 {e1}, s=2 {e2}, s=4 {e4}"
    );
    // One atom is another amplifier.
    let one = one_level(
        Levers {
            sparsity: 1,
            ..Levers::default()
        },
        &base,
    );
    assert!(one
        .elevation
        .iter()
        .zip(own.elevation.iter())
        .any(|(a, b)| a != b));
}
