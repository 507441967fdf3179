//! A measurement of issue #12's last untried lever, valley carving, on the held-out suite's
//! outputs: does deepening the channels of the amplified terrain (or of its input) by a depth
//! that grows with upstream area add detail that correlates with the truth's?
//!
//! Reads an amplified crop `OUT` (`target/realism/<crop>.out.tif` of `scripts/realism.sh`),
//! computes D8 upstream area (m²) after Priority-Flood on it — or, with `coarse` in `MODE`, on
//! its input (`<crop>.low.tif`, ×4 coarser) bilinearly up-sampled in log10 — and lowers every
//! cell by `K · max(0, log10(area) − A0)` metres (stream-power-like: depth grows with the
//! decades of area above `A0`). With `blur` in `MODE` the carving is smoothed by a 3×3 binomial
//! (a V a few cells wide instead of a one-cell trench); unless `MODE` holds `raw`, the carving's
//! 4×4 block means are subtracted, so the output's box averages — its consistency with the
//! input — do not change. Writes the carved crop to `DST`; `terrasynth eval` on it gives the
//! figures (README, "Valley carving").
//!
//! Usage: `cargo run --release --example carve_trial -- OUT DST K A0 MODE`, e.g. `… 20 6.5 blur`.

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use ndarray::Array2;
use terrasynth_core::analysis::{flow_accumulation_d8, priority_flood_fill};
use terrasynth_core::math;
use terrasynth_core::raster::{read_geotiff_file, write_geotiff_file, CellSizes, Grid, ReadLimits};

/// Upsampling factor between the suite's inputs and outputs (two ×2 levels).
const FACTOR: usize = 4;

/// Square cell size of `g`, metres (the suite's crops are squared, in metres or degrees).
fn cells(g: &Grid) -> CellSizes {
    let w = g.georef.pixel_width.abs();
    let m = if w < 1.0 { w * 111_320.0 } else { w };
    CellSizes::uniform(g.data.nrows(), m)
}

fn log_area(g: &Grid) -> Array2<f64> {
    flow_accumulation_d8(&priority_flood_fill(&g.data), &cells(g)).mapv(|v| math::log10(v.max(1.0)))
}

/// `coarse` bilinearly up-sampled ×[`FACTOR`] to `dim` (pixel centres aligned as the levels'
/// are: fine pixel `x` at coarse coordinate `(x + 0.5)/FACTOR − 0.5`).
fn bilinear_up(coarse: &Array2<f64>, dim: (usize, usize)) -> Array2<f64> {
    let (lr, lc) = coarse.dim();
    let at = |i: usize, n: usize| {
        let p = ((i as f64 + 0.5) / FACTOR as f64 - 0.5).clamp(0.0, (n - 1) as f64);
        let i0 = p.floor() as usize;
        (i0, (i0 + 1).min(n - 1), p - i0 as f64)
    };
    Array2::from_shape_fn(dim, |(i, j)| {
        let (y0, y1, fy) = at(i, lr);
        let (x0, x1, fx) = at(j, lc);
        let top = coarse[[y0, x0]] * (1.0 - fx) + coarse[[y0, x1]] * fx;
        let bottom = coarse[[y1, x0]] * (1.0 - fx) + coarse[[y1, x1]] * fx;
        top * (1.0 - fy) + bottom * fy
    })
}

/// 3×3 binomial smoothing (weights renormalised at the edges).
fn binomial3(a: &Array2<f32>) -> Array2<f32> {
    let (rows, cols) = a.dim();
    let w = [1.0f32, 2.0, 1.0];
    Array2::from_shape_fn((rows, cols), |(i, j)| {
        let (mut sum, mut weight) = (0.0, 0.0);
        for (di, wi) in w.iter().enumerate() {
            for (dj, wj) in w.iter().enumerate() {
                let (r, c) = ((i + di).checked_sub(1), (j + dj).checked_sub(1));
                if let (Some(r), Some(c)) = (r, c) {
                    if r < rows && c < cols {
                        sum += wi * wj * a[[r, c]];
                        weight += wi * wj;
                    }
                }
            }
        }
        sum / weight
    })
}

/// `c` minus its [`FACTOR`]² block means: box averages of the result are 0.
fn without_block_means(c: &Array2<f32>) -> Array2<f32> {
    let mut out = c.clone();
    let (rows, cols) = c.dim();
    for br in 0..rows / FACTOR {
        for bc in 0..cols / FACTOR {
            let block = ndarray::s![
                br * FACTOR..(br + 1) * FACTOR,
                bc * FACTOR..(bc + 1) * FACTOR
            ];
            let mean = c.slice(block).iter().map(|&v| f64::from(v)).sum::<f64>()
                / (FACTOR * FACTOR) as f64;
            out.slice_mut(block).mapv_inplace(|v| v - mean as f32);
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    assert!(args.len() == 6, "usage: carve_trial OUT DST K A0 MODE");
    let (out_path, dst) = (&args[1], Path::new(&args[2]));
    let k: f32 = args[3].parse().expect("K: metres per decade of area");
    let a0: f64 = args[4].parse().expect("A0: log10 of an area in m²");
    let mode = args[5].as_str();
    let limits = ReadLimits::default();
    let out = read_geotiff_file(Path::new(out_path), &limits).unwrap();
    let area = if mode.contains("coarse") {
        let low_path = out_path.replace(".out.tif", ".low.tif");
        let low = read_geotiff_file(Path::new(&low_path), &limits).unwrap();
        bilinear_up(&log_area(&low), out.data.dim())
    } else {
        log_area(&out)
    };
    let mut carve = area.mapv(|l| -k * (l - a0).max(0.0) as f32);
    if mode.contains("blur") {
        carve = binomial3(&carve);
    }
    if !mode.contains("raw") {
        carve = without_block_means(&carve);
    }
    let mut carved = out.clone();
    carved.data = &out.data + &carve;
    write_geotiff_file(&carved, dst).unwrap();
}
