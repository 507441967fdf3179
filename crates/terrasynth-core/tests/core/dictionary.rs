//! Integration tests of dictionary building and the binary format.

use std::sync::atomic::{AtomicBool, Ordering};

use ndarray::Array2;
use terrasynth_core::dictionary::{
    box_down2, build, build_cancellable, from_bytes, read_dictionary, to_bytes, write_dictionary,
    BuildOptions, Dictionary, DictionaryError, Exemplar, LayerKind, Learning, Rng,
};
use terrasynth_core::math;

/// Sum of sinusoids plus two straight ridges and a valley, metres; independent of the code under
/// test.
fn terrain(rows: usize, cols: usize) -> Array2<f32> {
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let (y, x) = (r as f64, c as f64);
        let mut z = 800.0
            + 150.0 * math::sin(y / 23.0) * math::cos(x / 31.0)
            + 40.0 * math::sin((x + 2.0 * y) / 9.0);
        z += 120.0 * math::exp(-((x - 0.6 * y - 20.0) / 6.0).powi(2));
        z += 90.0 * math::exp(-((x + 0.3 * y - 140.0) / 4.0).powi(2));
        z -= 70.0 * math::exp(-((y - 0.2 * x - 50.0) / 5.0).powi(2));
        z += 7.0 * math::sin(x * 1.7) * math::cos(y * 1.3);
        z as f32
    })
}

fn vegetation(rows: usize, cols: usize) -> Array2<f32> {
    Array2::from_shape_fn((rows, cols), |(r, c)| ((r * 7 + c * 3) % 11) as f32 / 10.0)
}

fn exemplar(rows: usize, cols: usize) -> Exemplar {
    Exemplar {
        elevation: terrain(rows, cols),
        valid: None,
        cell_m: 10.0,
        layers: vec![
            ("veg".into(), vegetation(rows, cols), LayerKind::Continuous),
            (
                "spruce".into(),
                Array2::from_elem((rows, cols), 0.25),
                LayerKind::Class {
                    group: "forest".into(),
                },
            ),
        ],
    }
}

fn opts(patch: usize, stride: usize, atoms: usize, learning: Learning) -> BuildOptions {
    BuildOptions {
        patch,
        stride,
        atoms,
        learning,
        seed: 5,
        sparsity: 1,
    }
}

fn quiet() -> impl FnMut(&str, f64) {
    |_, _| {}
}

fn small_dict() -> Dictionary {
    let ex = exemplar(40, 48);
    build(
        &[ex],
        &opts(8, 4, 6, Learning::Medoids { iterations: 3 }),
        &mut quiet(),
    )
    .unwrap()
}

// ---- Binary format: round trip, truncation, corruption, headers ----

#[test]
fn round_trip_is_identical() {
    let d = small_dict();
    let bytes = to_bytes(&d).unwrap();
    assert_eq!(from_bytes(&bytes).unwrap(), d);
    let mut written = Vec::new();
    write_dictionary(&d, &mut written).unwrap();
    assert_eq!(written, bytes);
    let back = read_dictionary(&written[..], u64::MAX).unwrap();
    assert_eq!(back, d);
    assert_eq!(to_bytes(&back).unwrap(), bytes);
    // The content id is the hex of the trailing checksum.
    let id = terrasynth_core::dictionary::content_id(&d).unwrap();
    let tail: String = bytes[bytes.len() - 32..]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(id, tail);
    assert_eq!(&bytes[..8], b"TSDICT\0\x01");
    assert_eq!(&bytes[8..12], &1u32.to_le_bytes());
}

#[test]
fn header_floats_read_back_bit_for_bit() {
    // The mean cell of a square-celled 15″ exemplar at 42° N (the admin sketch test's): read back
    // by serde_json's fast float parser it came out one unit in the last place off, so the
    // re-serialised header, and the content id, no longer matched the stored file's.
    let mut d = small_dict();
    for cell_m in [
        463.311_508_384_980_13,
        0.1 + 0.2,
        1e-300,
        123_456.789_012_345_67,
    ] {
        d.params.cell_m = cell_m;
        let bytes = to_bytes(&d).unwrap();
        let back = read_dictionary(&bytes[..], u64::MAX).unwrap();
        assert_eq!(back.params.cell_m.to_bits(), cell_m.to_bits(), "{cell_m}");
        assert_eq!(to_bytes(&back).unwrap(), bytes, "{cell_m}");
    }
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = to_bytes(&small_dict()).unwrap();
    for len in 0..bytes.len() {
        assert!(
            from_bytes(&bytes[..len]).is_err(),
            "prefix of {len} bytes accepted"
        );
        // A stream that ends early (no size hint) is reported as truncated once past the header.
        let r = read_dictionary(&bytes[..len], u64::MAX);
        assert!(r.is_err(), "stream prefix of {len} bytes accepted");
    }
    let header_end = 20 + u64::from_le_bytes(bytes[12..20].try_into().unwrap()) as usize;
    for len in [header_end, header_end + 5, bytes.len() - 1] {
        assert!(matches!(
            read_dictionary(&bytes[..len], u64::MAX),
            Err(DictionaryError::Truncated)
        ));
    }
    let mut extra = bytes.clone();
    extra.push(0);
    assert!(matches!(
        from_bytes(&extra),
        Err(DictionaryError::Malformed(_))
    ));
}

#[test]
fn flipped_bytes_are_detected() {
    let bytes = to_bytes(&small_dict()).unwrap();
    let header_end = 20 + u64::from_le_bytes(bytes[12..20].try_into().unwrap()) as usize;
    // Every byte of the prefix and header, then a sample of the arrays and the checksum.
    let positions = (0..header_end)
        .chain((header_end..bytes.len()).step_by(7))
        .chain([bytes.len() - 1]);
    for i in positions {
        for mask in [0x01u8, 0x80] {
            let mut bad = bytes.clone();
            bad[i] ^= mask;
            let r = from_bytes(&bad);
            assert!(r.is_err(), "flip of byte {i} (mask {mask:#x}) accepted");
            if i >= header_end {
                assert!(
                    matches!(r, Err(DictionaryError::ChecksumMismatch)),
                    "byte {i}: {r:?}"
                );
            }
        }
    }
}

#[test]
fn magic_version_and_size_limit() {
    let bytes = to_bytes(&small_dict()).unwrap();
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(matches!(from_bytes(&bad), Err(DictionaryError::BadMagic)));
    let mut v2 = bytes.clone();
    v2[8..12].copy_from_slice(&2u32.to_le_bytes());
    assert!(matches!(
        from_bytes(&v2),
        Err(DictionaryError::UnsupportedVersion { found: 2 })
    ));
    // A header length claiming terabytes is rejected before allocating.
    let mut huge = bytes.clone();
    huge[12..20].copy_from_slice(&(1u64 << 40).to_le_bytes());
    assert!(matches!(
        from_bytes(&huge),
        Err(DictionaryError::Malformed(_))
    ));
    // max_bytes smaller than the dictionary.
    let r = read_dictionary(&bytes[..], bytes.len() as u64 - 1);
    assert!(matches!(r, Err(DictionaryError::Malformed(_))), "{r:?}");
    assert!(read_dictionary(&bytes[..], bytes.len() as u64).is_ok());
    assert!(matches!(
        from_bytes(b"TSD"),
        Err(DictionaryError::Truncated)
    ));
}

#[test]
fn header_claiming_many_atoms_is_rejected_without_allocating() {
    // Hand-made header: 10^12 atoms, consistent lengths, nothing after it.
    let n: u64 = 1_000_000_000_000;
    let json = format!(
        concat!(
            r#"{{"params":{{"patch":16,"stride":8,"atoms":0,"learning":"complete","seed":1,"cell_m":10.0}},"#,
            r#""layers":[],"n_atoms":{n},"lengths":{{"lo_elev":{lo},"hi_elev":{hi},"mean_alt":{n},"#,
            r#""mean_slope":{n},"relief":{n},"lo_layers":0,"hi_layers":0,"sources":{n}}}}}"#
        ),
        n = n,
        lo = n * 64,
        hi = n * 256
    );
    let mut bytes = b"TSDICT\0\x01".to_vec();
    bytes.extend_from_slice(&1u32.to_le_bytes());
    bytes.extend_from_slice(&(json.len() as u64).to_le_bytes());
    bytes.extend_from_slice(json.as_bytes());
    let r = read_dictionary(&bytes[..], 1 << 30);
    assert!(matches!(r, Err(DictionaryError::Malformed(_))), "{r:?}");
    // With an unlimited max_bytes the stream simply ends: truncated, no giant allocation.
    let r = read_dictionary(&bytes[..], u64::MAX);
    assert!(matches!(r, Err(DictionaryError::Truncated)), "{r:?}");
}

// ---- Atom invariants and provenance ----

#[test]
fn atoms_satisfy_the_multiresolution_invariant() {
    let ex = exemplar(96, 120);
    let d = build(
        std::slice::from_ref(&ex),
        &opts(16, 8, 40, Learning::Medoids { iterations: 4 }),
        &mut quiet(),
    )
    .unwrap();
    assert_eq!(d.n_atoms, 40);
    assert_eq!(d.layers.len(), 2);
    let (p, lo) = (16, 8);
    let mut down = vec![0.0; lo * lo];
    for i in 0..d.n_atoms {
        box_down2(d.hi_atom(i), p, &mut down);
        let l = d.lo_atom(i);
        for (a, b) in down.iter().zip(l) {
            assert!((a - b).abs() < 1e-5, "atom {i}: box_down(hi) {a} vs lo {b}");
        }
        let norm: f64 = l.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-5, "atom {i}: ‖lo‖ = {norm}");
        let mean: f64 = l.iter().map(|&x| f64::from(x)).sum::<f64>() / 64.0;
        assert!(mean.abs() < 1e-6);
        // Real patch: hi × relief + mean gives back the exemplar cells.
        let src = d.sources[i];
        assert_eq!(src.exemplar, 0);
        assert_eq!(src.row % 8, 0);
        assert_eq!(src.col % 8, 0);
        let (r0, c0) = (src.row as usize, src.col as usize);
        for r in 0..p {
            for c in 0..p {
                let rebuilt = d.hi_atom(i)[r * p + c] * d.relief[i] + d.mean_alt[i];
                let want = ex.elevation[[r0 + r, c0 + c]];
                assert!(
                    (rebuilt - want).abs() < 1e-3,
                    "atom {i} ({r},{c}): {rebuilt} vs {want}"
                );
                assert_eq!(
                    d.hi_layer(i, 0)[r * p + c],
                    ex.layers[0].1[[r0 + r, c0 + c]]
                );
            }
        }
        // Low layers are plain 2×2 means of the exemplar layer.
        for r in 0..lo {
            for c in 0..lo {
                let v = &ex.layers[0].1;
                let want = (v[[r0 + 2 * r, c0 + 2 * c]]
                    + v[[r0 + 2 * r, c0 + 2 * c + 1]]
                    + v[[r0 + 2 * r + 1, c0 + 2 * c]]
                    + v[[r0 + 2 * r + 1, c0 + 2 * c + 1]])
                    / 4.0;
                assert!((d.lo_layer(i, 0)[r * lo + c] - want).abs() < 1e-6);
            }
        }
    }
    // Atoms are distinct patches, sorted by provenance.
    for w in d.sources.windows(2) {
        assert!((w[0].exemplar, w[0].row, w[0].col) < (w[1].exemplar, w[1].row, w[1].col));
    }
}

#[test]
fn mean_slope_of_a_tilted_plane() {
    // z = 0.3·x + 0.1·y in metres on 10 m cells (plus no noise): slope √(0.09 + 0.01) everywhere.
    let elevation =
        Array2::from_shape_fn((48, 48), |(r, c)| (3.0 * c as f64 + 1.0 * r as f64) as f32);
    let ex = Exemplar {
        elevation,
        valid: None,
        cell_m: 10.0,
        layers: vec![],
    };
    let d = build(&[ex], &opts(8, 4, 0, Learning::Complete), &mut quiet()).unwrap();
    assert_eq!(d.n_atoms, 11 * 11);
    let want = 0.1f32.sqrt();
    for &s in &d.mean_slope {
        assert!((s - want).abs() < 1e-4, "{s} vs {want}");
    }
    assert_eq!(d.params.cell_m, 10.0);
}

#[test]
fn invalid_cells_are_never_inside_atoms() {
    let mut ex = exemplar(64, 64);
    ex.elevation[[20, 30]] = f32::NAN;
    let mut valid = Array2::from_elem((64, 64), true);
    valid[[50, 5]] = false;
    ex.valid = Some(valid);
    let d = build(&[ex], &opts(8, 2, 0, Learning::Complete), &mut quiet()).unwrap();
    let covers = |s: &terrasynth_core::dictionary::AtomSource, r: u32, c: u32| {
        (s.row..s.row + 8).contains(&r) && (s.col..s.col + 8).contains(&c)
    };
    assert!(d
        .sources
        .iter()
        .all(|s| !covers(s, 20, 30) && !covers(s, 50, 5)));
    // 29×29 positions; (20, 30) lies in 4 row × 4 column positions, (50, 5) in 4 × 3 (columns
    // 0, 2, 4).
    assert_eq!(d.n_atoms, 29 * 29 - 16 - 12);
}

#[test]
fn complete_subset_is_evenly_spaced() {
    let ex = exemplar(64, 64);
    let all = build(
        std::slice::from_ref(&ex),
        &opts(8, 8, 0, Learning::Complete),
        &mut quiet(),
    )
    .unwrap();
    // Positions 0, 8, ..., 56 on both axes.
    assert_eq!(all.n_atoms, 64);
    let some = build(&[ex], &opts(8, 8, 7, Learning::Complete), &mut quiet()).unwrap();
    assert_eq!(some.n_atoms, 7);
    // ⌊i·64/7⌋ = 0, 9, 18, 27, 36, 45, 54.
    let want: Vec<_> = [0, 9, 18, 27, 36, 45, 54]
        .iter()
        .map(|&i| all.sources[i])
        .collect();
    assert_eq!(some.sources, want);
}

// ---- Determinism ----

#[test]
fn builds_are_deterministic_across_runs_and_thread_counts() {
    let ex = [exemplar(180, 260)];
    let o = opts(8, 4, 48, Learning::Medoids { iterations: 5 });
    let a = to_bytes(&build(&ex, &o, &mut quiet()).unwrap()).unwrap();
    let b = to_bytes(&build(&ex, &o, &mut quiet()).unwrap()).unwrap();
    assert_eq!(a, b);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let c = one.install(|| to_bytes(&build(&ex, &o, &mut quiet()).unwrap()).unwrap());
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let d = two.install(|| to_bytes(&build(&ex, &o, &mut quiet()).unwrap()).unwrap());
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let e = three.install(|| to_bytes(&build(&ex, &o, &mut quiet()).unwrap()).unwrap());
    assert_eq!(a, c);
    assert_eq!(a, d);
    assert_eq!(a, e);
    // A different seed gives a different dictionary.
    let o2 = BuildOptions { seed: 6, ..o };
    assert_ne!(
        a,
        to_bytes(&build(&ex, &o2, &mut quiet()).unwrap()).unwrap()
    );
}

// ---- Failure modes: flat/small exemplars, bad layers, cancellation ----

#[test]
fn flat_or_tiny_exemplars_have_no_patches() {
    let flat = Exemplar {
        elevation: Array2::from_elem((64, 64), 312.0),
        valid: None,
        cell_m: 5.0,
        layers: vec![],
    };
    let r = build(&[flat], &BuildOptions::default(), &mut quiet());
    assert!(matches!(r, Err(DictionaryError::NoPatches)), "{r:?}");
    // Relief of a few centimetres is still flat.
    let almost = Exemplar {
        elevation: Array2::from_shape_fn((64, 64), |(r, c)| 100.0 + ((r + c) % 2) as f32 * 0.01),
        valid: None,
        cell_m: 5.0,
        layers: vec![],
    };
    assert!(matches!(
        build(&[almost], &BuildOptions::default(), &mut quiet()),
        Err(DictionaryError::NoPatches)
    ));
    let tiny = exemplar(15, 200);
    assert!(matches!(
        build(&[tiny], &BuildOptions::default(), &mut quiet()),
        Err(DictionaryError::NoPatches)
    ));
    let mut masked = exemplar(64, 64);
    masked.valid = Some(Array2::from_elem((64, 64), false));
    assert!(matches!(
        build(&[masked], &BuildOptions::default(), &mut quiet()),
        Err(DictionaryError::NoPatches)
    ));
}

#[test]
fn mismatched_layers_across_exemplars_are_rejected() {
    let a = exemplar(64, 64);
    let mut b = exemplar(64, 64);
    b.layers[1].2 = LayerKind::Continuous;
    let r = build(&[a.clone(), b], &BuildOptions::default(), &mut quiet());
    assert!(matches!(r, Err(DictionaryError::InvalidParams(_))));
    let mut c = exemplar(64, 64);
    c.layers.swap(0, 1);
    assert!(matches!(
        build(&[a.clone(), c], &BuildOptions::default(), &mut quiet()),
        Err(DictionaryError::InvalidParams(_))
    ));
    let mut d = a.clone();
    d.cell_m = 0.0;
    assert!(matches!(
        build(&[d], &BuildOptions::default(), &mut quiet()),
        Err(DictionaryError::InvalidParams(_))
    ));
    // Two exemplars with the same layers build fine and record both sources.
    let two = build(
        &[a.clone(), exemplar(48, 80)],
        &opts(8, 8, 0, Learning::Complete),
        &mut quiet(),
    )
    .unwrap();
    assert!(two.sources.iter().any(|s| s.exemplar == 1));
}

#[test]
fn cancellation_stops_the_build() {
    let ex = [exemplar(128, 128)];
    let flag = AtomicBool::new(true);
    let r = build_cancellable(&ex, &BuildOptions::default(), &flag, &mut quiet());
    assert!(matches!(r, Err(DictionaryError::Cancelled)));
    // Cancelled from the progress callback once learning has started.
    let flag = AtomicBool::new(false);
    let mut stages = Vec::new();
    let r = build_cancellable(
        &ex,
        &opts(8, 4, 32, Learning::Medoids { iterations: 6 }),
        &flag,
        &mut |s, _| {
            stages.push(s.to_string());
            if s == "learning" {
                flag.store(true, Ordering::Relaxed);
            }
        },
    );
    assert!(matches!(r, Err(DictionaryError::Cancelled)), "{r:?}");
    assert!(!stages.iter().any(|s| s == "done"));
}

#[test]
fn progress_reports_stages_in_order() {
    let mut seen: Vec<(String, f64)> = Vec::new();
    build(
        &[exemplar(64, 64)],
        &opts(8, 4, 10, Learning::Medoids { iterations: 2 }),
        &mut |s, f| seen.push((s.to_string(), f)),
    )
    .unwrap();
    assert!(seen.iter().all(|(_, f)| (0.0..=1.0).contains(f)));
    let first_learning = seen.iter().position(|(s, _)| s == "learning").unwrap();
    assert!(seen[..first_learning].iter().all(|(s, _)| s == "patches"));
    assert!(seen.iter().any(|(s, f)| s == "patches" && *f == 1.0));
    assert_eq!(seen.last().unwrap(), &("done".to_string(), 1.0));
}

// ---- Learning quality ----

/// Mean over every patch of its best (signed) dot product with the atoms.
fn mean_best_dot(all: &Dictionary, atoms: &[Vec<f32>]) -> f64 {
    let mut total = 0.0;
    for i in 0..all.n_atoms {
        let p = all.lo_atom(i);
        let best = atoms
            .iter()
            .map(|a| {
                p.iter()
                    .zip(a)
                    .map(|(x, y)| f64::from(*x) * f64::from(*y))
                    .sum::<f64>()
            })
            .fold(f64::NEG_INFINITY, f64::max);
        total += best;
    }
    total / all.n_atoms as f64
}

#[test]
fn learning_beats_a_random_subset() {
    let ex = [exemplar(160, 200)];
    let all = build(&ex, &opts(8, 4, 0, Learning::Complete), &mut quiet()).unwrap();
    let k = 24;
    let learned = build(
        &ex,
        &opts(8, 4, k, Learning::Medoids { iterations: 6 }),
        &mut quiet(),
    )
    .unwrap();
    assert_eq!(learned.n_atoms, k);
    let learned_atoms: Vec<Vec<f32>> = (0..k).map(|i| learned.lo_atom(i).to_vec()).collect();
    // A random subset of the same size drawn with the same seed.
    let mut rng = Rng::new(5);
    let mut picked: Vec<usize> = Vec::new();
    while picked.len() < k {
        let i = rng.below(all.n_atoms as u64) as usize;
        if !picked.contains(&i) {
            picked.push(i);
        }
    }
    let random_atoms: Vec<Vec<f32>> = picked.iter().map(|&i| all.lo_atom(i).to_vec()).collect();
    let l = mean_best_dot(&all, &learned_atoms);
    let r = mean_best_dot(&all, &random_atoms);
    assert!(l > r + 0.01, "learned {l} vs random {r}");
    // Learned atoms are real patches of the complete dictionary.
    for i in 0..k {
        let j = all
            .sources
            .iter()
            .position(|s| *s == learned.sources[i])
            .unwrap();
        assert_eq!(all.lo_atom(j), learned.lo_atom(i));
        assert_eq!(all.hi_atom(j), learned.hi_atom(i));
    }
}

// ---- Class layers (#15): matching with the class term picks class-consistent atoms ----

/// Hashed value noise, metres: the same statistics everywhere, so elevation alone says nothing
/// of the class a patch lies in.
fn noise_terrain(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
    let h = |x: i64, y: i64| {
        (terrasynth_core::dictionary::hash2(seed, x, y) >> 11) as f64 / (1u64 << 53) as f64
    };
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let mut z = 1000.0;
        for (scale, amp) in [(16.0, 120.0), (7.0, 40.0), (3.0, 12.0)] {
            let (u, v) = (c as f64 / scale, r as f64 / scale);
            let (i, j) = (u.floor() as i64, v.floor() as i64);
            let (fu, fv) = (u - u.floor(), v - v.floor());
            let top = h(i, j) + (h(i + 1, j) - h(i, j)) * fu;
            let bot = h(i, j + 1) + (h(i + 1, j + 1) - h(i, j + 1)) * fu;
            z += amp * (top + (bot - top) * fv);
        }
        z as f32
    })
}

/// The class (1 or 2) holding most of the `side`² patch at `(r, c)` of `classes`.
fn majority(classes: &Array2<f32>, r: usize, c: usize, side: usize) -> f32 {
    let ones = classes
        .slice(ndarray::s![r..r + side, c..c + side])
        .iter()
        .filter(|&&v| v == 1.0)
        .count();
    if 2 * ones >= side * side {
        1.0
    } else {
        2.0
    }
}

#[test]
fn a_dictionary_with_a_class_layer_matches_class_consistent_atoms_more_often() {
    use terrasynth_core::dictionary::{centre_normalise, patch_mean_slope, MatchWeights, Matcher};
    use terrasynth_core::landscape::classes::{class_layers, class_values};
    let (n, patch, cell_m) = (96usize, 8usize, 10.0f64);
    // The exemplar: class 1 on the west half, class 2 on the east half.
    let elevation = noise_terrain(n, n, 11);
    let classes = Array2::from_shape_fn((n, n), |(_, c)| if c < n / 2 { 1.0f32 } else { 2.0 });
    let values = class_values(&classes).unwrap();
    assert_eq!(values, [1, 2]);
    let with = Exemplar {
        elevation: elevation.clone(),
        valid: None,
        cell_m,
        layers: class_layers("classes", &classes, &values),
    };
    let without = Exemplar {
        layers: Vec::new(),
        ..with.clone()
    };
    let o = opts(patch, 4, 48, Learning::Medoids { iterations: 3 });
    let dict_with = std::sync::Arc::new(build(&[with], &o, &mut quiet()).unwrap());
    let dict_without = std::sync::Arc::new(build(&[without], &o, &mut quiet()).unwrap());
    assert_eq!(
        dict_with.layers[0].kind,
        LayerKind::Class {
            group: "classes".into()
        }
    );
    let elevation_only = MatchWeights {
        elevation: 1.0,
        altitude: 0.0,
        slope: 0.0,
        layers: Vec::new(),
    };
    let with_class_term = MatchWeights {
        layers: vec![("classes".into(), 1.0)],
        ..elevation_only.clone()
    };
    let m_with = Matcher::new(dict_with.clone(), &with_class_term).unwrap();
    let m_without = Matcher::new(dict_without.clone(), &elevation_only).unwrap();
    // Queries from other terrain with classes split north/south (so the exemplar's west/east
    // split cannot be read from position either): the low-resolution patch (2×2 means) of
    // every 8² window, and for the class term its class probabilities.
    let q_elev = noise_terrain(n, n, 29);
    let q_classes = Array2::from_shape_fn((n, n), |(r, _)| if r < n / 2 { 1.0f32 } else { 2.0 });
    let lo = patch / 2;
    let (mut agree_with, mut agree_without, mut total) = (0usize, 0usize, 0usize);
    let mut scratch = Default::default();
    for r in (0..n - patch).step_by(patch) {
        for c in (0..n - patch).step_by(patch) {
            let down = |a: &Array2<f32>, pred: &dyn Fn(f32) -> f32| -> Vec<f32> {
                let mut v = Vec::with_capacity(lo * lo);
                for i in 0..lo {
                    for j in 0..lo {
                        let s: f32 = (0..4)
                            .map(|k| pred(a[[r + 2 * i + k / 2, c + 2 * j + k % 2]]))
                            .sum();
                        v.push(s / 4.0);
                    }
                }
                v
            };
            let raw = down(&q_elev, &|x| x);
            let mut elev = vec![0.0f32; lo * lo];
            let (mean, _) = centre_normalise(&raw, &mut elev);
            let base = terrasynth_core::dictionary::matching::Query {
                elevation: elev,
                mean_alt: mean,
                mean_slope: patch_mean_slope(&raw, lo, (2.0 * cell_m) as f32),
                layers: Vec::new(),
            };
            let q_with = terrasynth_core::dictionary::matching::Query {
                layers: vec![
                    down(&q_classes, &|x| f32::from(x == 1.0)),
                    down(&q_classes, &|x| f32::from(x == 2.0)),
                ],
                ..base.clone()
            };
            let want = majority(&q_classes, r, c, patch);
            let class_of = |d: &Dictionary, i: usize| {
                let s = d.sources[i];
                majority(&classes, s.row as usize, s.col as usize, patch)
            };
            let (a, _) = m_with.best_match(&q_with, &mut scratch);
            let (b, _) = m_without.best_match(&base, &mut scratch);
            agree_with += usize::from(class_of(&dict_with, a) == want);
            agree_without += usize::from(class_of(&dict_without, b) == want);
            total += 1;
        }
    }
    let (fw, fo) = (
        agree_with as f64 / total as f64,
        agree_without as f64 / total as f64,
    );
    eprintln!(
        "class-consistent matches: with {agree_with}/{total}, without {agree_without}/{total}"
    );
    // With the class term nearly every match lies in the query's class; without it, elevation
    // alone (the same statistics on both halves) picks either class.
    assert!(fw >= 0.9, "with the class term: {agree_with}/{total}");
    assert!(
        fw >= fo + 0.2,
        "with {fw:.2} vs without {fo:.2} ({total} queries)"
    );
}
