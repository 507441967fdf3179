//! Matching: the fast matcher returns exactly the atom of the naive full scan (ties → lowest
//! index), the elevation term preserves orientation, and weights are validated.

use std::sync::Arc;

use proptest::prelude::*;
use terrasynth_core::dictionary::matching::{
    best_k_naive, best_match_naive, choose_diverse, unit_centred, MatchScratch, Query, Ranked,
    DOT_BATCH,
};
use terrasynth_core::dictionary::{
    AtomSource, Dictionary, DictionaryParams, LayerInfo, LayerKind, Learning, MatchWeights, Matcher,
};

/// A dictionary of `n` random atoms (patch 8: lo 4×4) with one continuous and two class layers.
/// Atoms `dups` are exact copies of atom 0 to create ties.
fn random_dictionary(n: usize, values: &[f32], dups: usize) -> Dictionary {
    let lo2 = 16;
    let hi2 = 64;
    let mut k = 0usize;
    let mut next = || {
        k += 1;
        values[k % values.len()] + (k as f32 * 0.618).fract()
    };
    let mut lo_elev = Vec::new();
    let mut lo_layers = Vec::new();
    let mut mean_alt = Vec::new();
    let mut mean_slope = Vec::new();
    for i in 0..n {
        if i > 0 && i <= dups {
            lo_elev.extend_from_within(0..lo2);
            lo_layers.extend_from_within(0..3 * lo2);
            mean_alt.push(mean_alt[0]);
            mean_slope.push(mean_slope[0]);
            continue;
        }
        let raw: Vec<f32> = (0..lo2).map(|_| next()).collect();
        lo_elev.extend(unit_centred(&raw));
        for _ in 0..3 * lo2 {
            lo_layers.push(next().abs());
        }
        mean_alt.push(next() * 500.0);
        mean_slope.push(next().abs() * 0.3);
    }
    Dictionary {
        params: DictionaryParams {
            patch: 8,
            stride: 4,
            atoms: n,
            learning: Learning::Complete,
            seed: 0,
            cell_m: 100.0,
            sparsity: 1,
        },
        layers: vec![
            LayerInfo {
                name: "log_area".into(),
                kind: LayerKind::Continuous,
            },
            LayerInfo {
                name: "rock".into(),
                kind: LayerKind::Class {
                    group: "soil".into(),
                },
            },
            LayerInfo {
                name: "sand".into(),
                kind: LayerKind::Class {
                    group: "soil".into(),
                },
            },
        ],
        n_atoms: n,
        lo_elev,
        hi_elev: vec![0.0; n * hi2],
        mean_alt,
        mean_slope,
        relief: vec![1.0; n],
        lo_layers,
        hi_layers: vec![0.0; n * 3 * hi2],
        sources: vec![
            AtomSource {
                exemplar: 0,
                row: 0,
                col: 0
            };
            n
        ],
    }
}

fn query_from(values: &[f32], alt: f32, slope: f32, with_layers: bool) -> Query {
    let raw: Vec<f32> = values.iter().cycle().take(16).cloned().collect();
    let layers = if with_layers {
        vec![
            unit_centred(
                &values
                    .iter()
                    .rev()
                    .cycle()
                    .take(16)
                    .cloned()
                    .collect::<Vec<_>>(),
            ),
            values.iter().map(|v| v.abs()).cycle().take(16).collect(),
            values
                .iter()
                .map(|v| (v * 3.0).abs())
                .cycle()
                .take(16)
                .collect(),
        ]
    } else {
        vec![Vec::new(), Vec::new(), Vec::new()]
    };
    Query {
        elevation: unit_centred(&raw),
        mean_alt: alt,
        mean_slope: slope,
        layers,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, .. ProptestConfig::default() })]

    #[test]
    fn fast_matcher_equals_naive_scan(
        n in 1usize..80,
        dups in 0usize..4,
        values in prop::collection::vec(-5.0f32..5.0, 4..40),
        qv in prop::collection::vec(-5.0f32..5.0, 2..20),
        alt in -100.0f32..3000.0,
        slope in 0.0f32..1.0,
        we in 0.0f32..1.0, wa in 0.0f32..1.0, ws in 0.0f32..1.0, wl in 0.0f32..1.0, wc in 0.0f32..1.0,
        with_layers: bool,
        copy_atom in prop::option::of(0usize..80),
    ) {
        let dict = random_dictionary(n, &values, dups.min(n.saturating_sub(1)));
        let weights = MatchWeights {
            elevation: we + 1e-3,
            altitude: wa,
            slope: ws,
            layers: vec![("log_area".into(), wl), ("soil".into(), wc)],
        };
        let matcher = Matcher::new(Arc::new(dict.clone()), &weights).unwrap();
        let mut q = query_from(&qv, alt, slope, with_layers);
        if let Some(i) = copy_atom {
            // An exact atom as the query (ties with its duplicates).
            q.elevation = dict.lo_atom(i % n).to_vec();
        }
        let mut scratch = MatchScratch::default();
        let fast = matcher.best_match(&q, &mut scratch);
        let naive = best_match_naive(&matcher, &q);
        prop_assert_eq!(fast.0, naive.0);
        prop_assert_eq!(fast.1.to_bits(), naive.1.to_bits());
    }

    #[test]
    fn pruned_top_k_equals_naive_ranking(
        n in 1usize..80,
        k in 1usize..10,
        dups in 0usize..4,
        values in prop::collection::vec(-5.0f32..5.0, 4..40),
        qv in prop::collection::vec(-5.0f32..5.0, 2..20),
        alt in -100.0f32..3000.0,
        slope in 0.0f32..1.0,
        we in 0.0f32..1.0, wa in 0.0f32..1.0, ws in 0.0f32..1.0, wl in 0.0f32..1.0,
        with_layers: bool,
        copy_atom in prop::option::of(0usize..80),
    ) {
        let dict = random_dictionary(n, &values, dups.min(n.saturating_sub(1)));
        let weights = MatchWeights {
            elevation: we + 1e-3,
            altitude: wa,
            slope: ws,
            layers: vec![("log_area".into(), wl)],
        };
        let matcher = Matcher::new(Arc::new(dict.clone()), &weights).unwrap();
        let mut q = query_from(&qv, alt, slope, with_layers);
        if let Some(i) = copy_atom {
            q.elevation = dict.lo_atom(i % n).to_vec();
        }
        let mut scratch = MatchScratch::default();
        let mut fast: Vec<Ranked> = Vec::new();
        matcher.best_k(&q, &mut scratch, k, &mut fast);
        let naive = best_k_naive(&matcher, &q, k);
        prop_assert_eq!(fast.len(), k.min(n));
        let bits = |v: &[Ranked]| -> Vec<(usize, u32, u32)> {
            v.iter().map(|r| (r.atom, r.dot.to_bits(), r.score.to_bits())).collect()
        };
        prop_assert_eq!(bits(&fast), bits(&naive));
        // The first ranked atom is the single best match.
        let best = matcher.best_match(&q, &mut scratch);
        prop_assert_eq!(fast[0].atom, best.0);
    }

    /// The diverse pick (shortcut: only the best `r + 1` ranked) takes the atom that
    /// `choose_diverse` takes over the naive ranking, at every lattice point.
    #[test]
    fn diverse_match_equals_the_choice_over_the_naive_ranking(
        n in 1usize..60,
        k in 2usize..10,
        values in prop::collection::vec(-5.0f32..5.0, 4..40),
        qv in prop::collection::vec(-5.0f32..5.0, 2..20),
        alt in -100.0f32..3000.0,
        slope in 0.0f32..1.0,
        ws in 0.0f32..1.0, wl in 0.0f32..1.0,
        with_layers: bool,
        tol in prop::option::of(0.0f32..0.2),
        i0 in -1000i64..1000, j0 in -1000i64..1000,
    ) {
        let dict = random_dictionary(n, &values, 0);
        let weights = MatchWeights {
            elevation: 1.0,
            altitude: 0.2,
            slope: ws,
            layers: vec![("log_area".into(), wl)],
        };
        let matcher = Matcher::new(Arc::new(dict), &weights).unwrap();
        let q = query_from(&qv, alt, slope, with_layers);
        let tol = tol.unwrap_or(f32::INFINITY);
        let naive = best_k_naive(&matcher, &q, k);
        let mut scratch = MatchScratch::default();
        let mut ranked: Vec<Ranked> = Vec::new();
        for (i, j) in (0..12).map(|d| (i0 + d, j0 + 3 * d)) {
            let fast = matcher.diverse_match(&q, (&mut scratch, &mut ranked), (k, tol), i, j);
            let want = choose_diverse(&naive, tol, i, j).unwrap();
            prop_assert_eq!((fast.0, fast.1.to_bits()), (want.0, want.1.to_bits()));
        }
    }
}

proptest! {
    /// Queries prepared in a batch (`Matcher::prepare_batch`: one pass over the atoms for four)
    /// are matched exactly as alone: the diverse pick equals the choice over the naive ranking.
    #[test]
    fn batch_prepared_queries_match_as_the_naive_ranking(
        n in 1usize..80,
        k in 2usize..10,
        values in prop::collection::vec(-5.0f32..5.0, 4..40),
        qvs in prop::collection::vec(prop::collection::vec(-5.0f32..5.0, 16), 4),
        alt in -100.0f32..3000.0,
        slope in 0.0f32..1.0,
        with_layers: bool,
        copy_atom in prop::option::of(0usize..80),
        i0 in -1000i64..1000,
    ) {
        let dict = random_dictionary(n, &values, 0);
        let weights = MatchWeights {
            elevation: 1.0,
            altitude: 0.2,
            slope: 0.1,
            layers: vec![("log_area".into(), 0.2)],
        };
        let matcher = Matcher::new(Arc::new(dict.clone()), &weights).unwrap();
        let mut qs: Vec<Query> = qvs.iter().map(|qv| query_from(qv, alt, slope, with_layers)).collect();
        if let Some(i) = copy_atom {
            qs[1].elevation = dict.lo_atom(i % n).to_vec();
        }
        let mut scratches: [MatchScratch; DOT_BATCH] = Default::default();
        matcher.prepare_batch([&qs[0], &qs[1], &qs[2], &qs[3]], &mut scratches);
        let mut ranked: Vec<Ranked> = Vec::new();
        for (m, (q, scratch)) in qs.iter().zip(scratches.iter_mut()).enumerate() {
            let naive = best_k_naive(&matcher, q, k);
            let (i, j) = (i0 + m as i64, 7 - m as i64);
            let fast = matcher.diverse_match_prepared(q, (scratch, &mut ranked), (k, f32::INFINITY), i, j);
            let want = choose_diverse(&naive, f32::INFINITY, i, j).unwrap();
            prop_assert_eq!((fast.0, fast.1.to_bits()), (want.0, want.1.to_bits()));
            let best = matcher.best_match_prepared(q, scratch);
            let naive_best = best_match_naive(&matcher, q);
            prop_assert_eq!((best.0, best.1.to_bits()), (naive_best.0, naive_best.1.to_bits()));
        }
    }
}

#[test]
fn ties_go_to_the_lowest_index() {
    let dict = random_dictionary(10, &[1.0, -2.0, 0.5, 3.0, -1.5], 3);
    let matcher = Matcher::new(
        Arc::new(dict.clone()),
        &MatchWeights {
            elevation: 1.0,
            altitude: 0.0,
            slope: 0.0,
            layers: vec![],
        },
    )
    .unwrap();
    let q = Query {
        elevation: dict.lo_atom(2).to_vec(), // atom 2 is a copy of atom 0
        ..Query::default()
    };
    assert_eq!(matcher.best_match(&q, &mut MatchScratch::default()).0, 0);
}

#[test]
fn elevation_term_preserves_orientation() {
    // A valley must not match an inverted ridge: with the negated query, the best atom changes
    // and its dot product is positive.
    let dict = random_dictionary(40, &[0.3, -1.2, 2.2, 0.9, -0.4, 1.7, -2.5], 0);
    let w = MatchWeights {
        elevation: 1.0,
        altitude: 0.0,
        slope: 0.0,
        layers: vec![],
    };
    let matcher = Matcher::new(Arc::new(dict.clone()), &w).unwrap();
    let atom = dict.lo_atom(7).to_vec();
    let neg: Vec<f32> = atom.iter().map(|v| -v).collect();
    let mut s = MatchScratch::default();
    let (k, dot) = matcher.best_match(
        &Query {
            elevation: atom,
            ..Query::default()
        },
        &mut s,
    );
    assert_eq!(k, 7);
    assert!((dot - 1.0).abs() < 1e-5);
    let (k2, dot2) = matcher.best_match(
        &Query {
            elevation: neg,
            ..Query::default()
        },
        &mut s,
    );
    assert_ne!(k2, 7, "an inverted ridge must not match the ridge");
    assert!(dot2 > -1.0 + 1e-3);
}

#[test]
fn invalid_weights_are_rejected() {
    let dict = random_dictionary(4, &[1.0, 2.0], 0);
    let bad = |w: MatchWeights| Matcher::new(Arc::new(dict.clone()), &w).is_err();
    assert!(bad(MatchWeights {
        elevation: -1.0,
        ..MatchWeights::default()
    }));
    assert!(bad(MatchWeights {
        elevation: 0.0,
        altitude: 0.0,
        slope: 0.0,
        layers: vec![]
    }));
    assert!(bad(MatchWeights {
        layers: vec![("nope".into(), 0.5)],
        ..MatchWeights::default()
    }));
    assert!(bad(MatchWeights {
        slope: f32::NAN,
        ..MatchWeights::default()
    }));
}

fn ranked(scores: &[f32]) -> Vec<Ranked> {
    scores
        .iter()
        .enumerate()
        .map(|(k, &score)| Ranked {
            atom: 10 + k,
            dot: k as f32 / 10.0,
            score,
        })
        .collect()
}

#[test]
fn diverse_choice_spreads_over_the_candidates_within_the_tolerance() {
    let list = ranked(&[0.9, 0.89, 0.88, 0.5]);
    assert_eq!(choose_diverse(&[], f32::INFINITY, 0, 0), None);
    let mut seen = [0usize; 4];
    for j in -20..20 {
        for i in -20..20 {
            let (atom, dot) = choose_diverse(&list, 0.05, i, j).unwrap();
            // Only the three candidates within 0.05 of the best, with their own dot.
            assert!((10..13).contains(&atom), "{atom}");
            assert_eq!(dot, (atom - 10) as f32 / 10.0);
            seen[atom - 10] += 1;
            // A pure function of the lattice point.
            assert_eq!(choose_diverse(&list, 0.05, i, j), Some((atom, dot)));
        }
    }
    // 1,600 points over three candidates: each taken often (about 533 times).
    assert!(seen[..3].iter().all(|&n| n > 400), "{seen:?}");
    // Tolerance 0: the best alone; infinite: every ranked atom.
    assert!((-5..5).all(|i| choose_diverse(&list, 0.0, i, 3) == Some((10, 0.0))));
    assert!((-50..50).any(|i| choose_diverse(&list, f32::INFINITY, i, 3).map(|p| p.0) == Some(13)));
}
