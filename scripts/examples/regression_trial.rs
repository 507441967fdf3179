//! A measurement for issue #12's acceptance 4: how much of the truth's detail above the input's
//! Nyquist can a linear (or piecewise-linear) predictor of the input recover? It fits, by
//! ridge-regularised least squares, one linear filter per sub-pixel phase (16 for the suite's ×4) from the input's
//! `(2R+1)²` neighbourhood (each value minus the centre cell's, so flat input predicts nothing)
//! to the truth's detail over the bicubic surface, on training pairs cut from the part of the
//! committed grid the held-out dictionary learns from; then predicts the held-out crops. Its
//! output is bicubic + the prediction: the MSE-optimal linear up-sampler of that neighbourhood.
//! `terrasynth eval` on it gives the RMSE against bicubic's and the detail's correlation with the
//! truth's, by octave (README, "How much of the band the input predicts").
//!
//! Usage: `cargo run --release --example regression_trial -- R LAMBDA TRAIN_DIR TEST_DIR DST_DIR
//! [GAIN [TEXTURE]]`: `TRAIN_DIR` holds `<name>.truth.tif` / `<name>.low.tif` pairs
//! (`terrasynth crop --square [--down 4]`), `TEST_DIR` the suite's crops and served outputs
//! (`target/realism` after `scripts/realism.sh`); writes `DST_DIR/<crop>.out.tif` for each
//! `<crop>.low.tif` of `TEST_DIR`. `GAIN` scales the prediction (default 1). `TEXTURE` (default 0)
//! adds that much of the served output's detail above the input's Nyquist (an FFT high-pass of
//! output − bicubic). With `CLASSES=K` in the environment, one regression per class and phase:
//! the neighbourhood's gradient orientation in `K / 2` sectors times its Laplacian's sign. With
//! `MATCHED=1`, `TEXTURE` is instead the ratio of the output's energy above the input's Nyquist
//! to the prediction's own, and each crop's texture weight is solved from it (both energies as
//! `terrasynth eval` measures the band: `analysis::band_energy`), so the texture's amplitude
//! follows what the input predicts. With `BASE_DIR=DIR`, the surface below the input's Nyquist
//! is `DIR/<crop>.out.tif`'s (bicubic plus the low-pass of that output's detail) instead of
//! bicubic, so the part of an output's error that lies below the Nyquist can be swapped for
//! another output's (with `GAIN` 0 and `TEXTURE` 1: that output below, the served one above).
//! With `HIGH_GAIN=K`, the prediction's part above the input's Nyquist is scaled by `K` and its
//! part below kept: the band's energy then comes from the correlated prediction instead of
//! texture (README, "Scaled instead of topped up").

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use ndarray::Array2;
use terrasynth_core::analysis::{band_energy, fft2, Complex};
use terrasynth_core::dictionary::omp::solve;
use terrasynth_core::math;
use terrasynth_core::raster::{read_geotiff_file, write_geotiff_file, ReadLimits};
use terrasynth_core::synth::baselines::bicubic_upsample;

/// Up-sampling factor between the suite's inputs and outputs (two ×2 levels).
const FACTOR: usize = 4;

/// The features of fine pixel `(i, j)` into `f`: the input's neighbourhood of radius `r` around
/// the coarse cell holding it, minus that cell's value (edge cells repeated when `clamp`).
/// Returns false, leaving `f` as it was, where the neighbourhood leaves the grid and `clamp` is
/// false.
fn features(low: &Array2<f32>, i: usize, j: usize, r: i64, clamp: bool, f: &mut Vec<f64>) -> bool {
    let (lr, lc) = (low.nrows() as i64, low.ncols() as i64);
    let (ci, cj) = ((i / FACTOR) as i64, (j / FACTOR) as i64);
    if !clamp && (ci - r < 0 || cj - r < 0 || ci + r >= lr || cj + r >= lc) {
        return false;
    }
    let centre = f64::from(low[[ci as usize, cj as usize]]);
    f.clear();
    for di in -r..=r {
        for dj in -r..=r {
            let (a, b) = ((ci + di).clamp(0, lr - 1), (cj + dj).clamp(0, lc - 1));
            f.push(f64::from(low[[a as usize, b as usize]]) - centre);
        }
    }
    true
}

/// `a` without its frequencies below `cut` cycles per cell (radially; an FFT of the whole grid).
fn high_pass(a: &Array2<f32>, cut: f64) -> Array2<f32> {
    let (rows, cols) = a.dim();
    let mut c = a.mapv(|v| Complex::new(f64::from(v), 0.0));
    fft2(&mut c, false);
    let freq = |k: usize, n: usize| {
        let k = if k > n / 2 {
            k as f64 - n as f64
        } else {
            k as f64
        };
        k / n as f64
    };
    for ((i, j), v) in c.indexed_iter_mut() {
        if math::hypot(freq(i, rows), freq(j, cols)) < cut {
            *v = Complex::new(0.0, 0.0);
        }
    }
    fft2(&mut c, true);
    c.mapv(|v| v.re as f32)
}

/// With `classes` > 1, the class of a neighbourhood `f` (radius `r`): its gradient's orientation
/// (modulo 180°) in `classes / 2` sectors, times the sign of its Laplacian (ridge or valley).
fn class_of(f: &[f64], r: i64, classes: usize) -> usize {
    if classes <= 1 {
        return 0;
    }
    let side = (2 * r + 1) as usize;
    let at = |di: i64, dj: i64| f[((di + r) as usize) * side + (dj + r) as usize];
    let (gx, gy) = (at(0, 1) - at(0, -1), at(1, 0) - at(-1, 0));
    let lap = at(0, 1) + at(0, -1) + at(1, 0) + at(-1, 0);
    let sectors = classes / 2;
    let angle = math::atan2(gy, gx).rem_euclid(std::f64::consts::PI);
    let sector = ((angle / std::f64::consts::PI * sectors as f64) as usize).min(sectors - 1);
    sector * 2 + usize::from(lap > 0.0)
}

/// The regression of fine pixel `(i, j)` with features `f`: its class's filter for its phase.
fn slot(f: &[f64], r: i64, classes: usize, i: usize, j: usize) -> usize {
    class_of(f, r, classes) * FACTOR * FACTOR + (i % FACTOR) * FACTOR + j % FACTOR
}

/// The files of `dir` whose names end in `suffix`, by name (the name without the suffix).
fn pairs(dir: &Path, suffix: &str) -> Vec<(String, PathBuf)> {
    let mut out: Vec<(String, PathBuf)> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.ok()?.path();
            let name = p.file_name()?.to_str()?.strip_suffix(suffix)?.to_string();
            Some((name, p))
        })
        .collect();
    out.sort();
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    assert!(
        (6..=8).contains(&args.len()),
        "usage: regression_trial R LAMBDA TRAIN_DIR TEST_DIR DST_DIR [GAIN [TEXTURE]]"
    );
    let r: i64 = args[1]
        .parse()
        .expect("R: neighbourhood radius in input cells");
    let lambda: f64 = args[2].parse().expect("LAMBDA: ridge weight (relative)");
    let (train, test, dst) = (
        Path::new(&args[3]),
        Path::new(&args[4]),
        Path::new(&args[5]),
    );
    let gain: f32 = args.get(6).map_or(1.0, |g| g.parse().expect("GAIN"));
    let texture_gain: f32 = args.get(7).map_or(0.0, |g| g.parse().expect("TEXTURE"));
    let limits = ReadLimits::default();
    let n = ((2 * r + 1) * (2 * r + 1)) as usize;
    let classes: usize = std::env::var("CLASSES").map_or(1, |c| c.parse().expect("CLASSES"));
    let phases = FACTOR * FACTOR * classes;
    let mut ata = vec![vec![0.0f64; n * n]; phases];
    let mut atb = vec![vec![0.0f64; n]; phases];
    let mut f = Vec::with_capacity(n);
    for (name, low_path) in pairs(train, ".low.tif") {
        let low = read_geotiff_file(&low_path, &limits).unwrap().data;
        let truth = read_geotiff_file(&train.join(format!("{name}.truth.tif")), &limits)
            .unwrap()
            .data;
        let bicubic = bicubic_upsample(&low, FACTOR);
        let (rows, cols) = (
            truth.nrows().min(bicubic.nrows()),
            truth.ncols().min(bicubic.ncols()),
        );
        for i in 0..rows {
            for j in 0..cols {
                if !features(&low, i, j, r, false, &mut f) {
                    continue;
                }
                let target = f64::from(truth[[i, j]] - bicubic[[i, j]]);
                let p = slot(&f, r, classes, i, j);
                for a in 0..n {
                    atb[p][a] += f[a] * target;
                    for b in 0..=a {
                        ata[p][a * n + b] += f[a] * f[b];
                    }
                }
            }
        }
        eprintln!("trained on {name}");
    }
    let weights: Vec<Vec<f64>> = (0..phases)
        .map(|p| {
            let mut a = ata[p].clone();
            for i in 0..n {
                for j in 0..i {
                    a[j * n + i] = a[i * n + j];
                }
            }
            let trace: f64 = (0..n).map(|i| a[i * n + i]).sum::<f64>() / n as f64;
            for i in 0..n {
                a[i * n + i] += lambda * trace;
            }
            let mut b = atb[p].clone();
            solve(&mut a, &mut b, n).expect("a singular normal matrix")
        })
        .collect();
    std::fs::create_dir_all(dst).unwrap();
    for (name, low_path) in pairs(test, ".low.tif") {
        let low = read_geotiff_file(&low_path, &limits).unwrap().data;
        let Ok(mut out) = read_geotiff_file(&test.join(format!("{name}.out.tif")), &limits) else {
            continue;
        };
        let bicubic = bicubic_upsample(&low, FACTOR);
        let (rows, cols) = out.data.dim();
        let bic =
            |i: usize, j: usize| bicubic[[i.min(bicubic.nrows() - 1), j.min(bicubic.ncols() - 1)]];
        // With a texture weight, the served output's detail above the input's Nyquist is added.
        let texture = (texture_gain != 0.0).then(|| {
            let detail = Array2::from_shape_fn((rows, cols), |(i, j)| out.data[[i, j]] - bic(i, j));
            high_pass(&detail, 0.5 / FACTOR as f64)
        });
        let pred = Array2::from_shape_fn((rows, cols), |(i, j)| {
            let mut f = Vec::with_capacity(n);
            features(&low, i, j, r, true, &mut f);
            let w = &weights[slot(&f, r, classes, i, j)];
            gain * f.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() as f32
        });
        // With `HIGH_GAIN=K`, the prediction's part above the input's Nyquist is scaled by `K`
        // (its part below stays): the band's energy comes from the correlated prediction.
        let pred = match std::env::var("HIGH_GAIN") {
            Ok(k) => {
                let k: f32 = k.parse().expect("HIGH_GAIN");
                let high = high_pass(&pred, 0.5 / FACTOR as f64);
                &pred + &(high * (k - 1.0))
            }
            Err(_) => pred,
        };
        // With `MATCHED=1`, the texture's weight is set so that the output's energy above the
        // input's Nyquist is `TEXTURE` times the prediction's (both measured on the crop).
        let texture_weight = match (&texture, std::env::var("MATCHED").is_ok()) {
            (Some(t), true) => {
                // Every radius from the input's Nyquist out (the spectrum's corners lie below 1).
                let energy = |a: &Array2<f32>| band_energy(a, 0.5 / FACTOR as f64, 1.0);
                let (ep, et) = (energy(&pred), energy(t));
                let w = ((f64::from(texture_gain) - 1.0).max(0.0) * ep / et.max(1e-30)).sqrt();
                eprintln!("{name}: texture weight {w:.3}");
                w as f32
            }
            _ => texture_gain,
        };
        // With `BASE_DIR`, the surface below the input's Nyquist is that of another output of
        // the same crop (bicubic plus its detail's low-pass) instead of bicubic.
        let below_nyquist = std::env::var("BASE_DIR").ok().map(|dir| {
            let other =
                read_geotiff_file(&Path::new(&dir).join(format!("{name}.out.tif")), &limits)
                    .unwrap()
                    .data;
            let detail = Array2::from_shape_fn(other.dim(), |(i, j)| other[[i, j]] - bic(i, j));
            &other - &high_pass(&detail, 0.5 / FACTOR as f64)
        });
        out.data = Array2::from_shape_fn((rows, cols), |(i, j)| {
            let tex = texture.as_ref().map_or(0.0, |t| texture_weight * t[[i, j]]);
            let base = below_nyquist.as_ref().map_or(bic(i, j), |b| b[[i, j]]);
            base + pred[[i, j]] + tex
        });
        write_geotiff_file(&out, &dst.join(format!("{name}.out.tif"))).unwrap();
        eprintln!("predicted {name}");
    }
}
