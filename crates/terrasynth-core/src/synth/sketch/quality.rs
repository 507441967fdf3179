//! Measures of a sketch world: how closely its extracted ridges and valleys follow the sketch's
//! lines, and whether the patches' seams show (steps across seam edges against steps inside
//! patches). Used by the tests, the benchmark report and `terrasynth sketch`.

use ndarray::Array2;

use crate::analysis::ppa::{features, FeatureKind, PpaParams};

use super::distance::distance_transform;
use super::exemplar::kind_index;
use super::graph::SketchTrees;

/// How well a terrain follows a sketch.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Fidelity {
    /// Mean distance (cells) from the sketch's ridge cells to the nearest extracted ridge.
    pub ridge_to_ridge: f64,
    /// Mean distance from the sketch's valley cells to the nearest extracted valley.
    pub valley_to_valley: f64,
    /// The same from ridge cells to the nearest extracted *valley* (a terrain that ignored the
    /// sketch scores about the same on both; one that follows it scores far higher here).
    pub ridge_to_valley: f64,
    /// From valley cells to the nearest extracted ridge.
    pub valley_to_ridge: f64,
    /// Sketch ridge cells measured.
    pub ridge_cells: usize,
    /// Sketch valley cells measured.
    pub valley_cells: usize,
}

/// The fidelity of terrain `z` to the sketch trees `trees` (cells on `z`'s grid), with the PPA's
/// parameters `params`.
pub fn fidelity(z: &Array2<f32>, trees: &SketchTrees, params: &PpaParams) -> Fidelity {
    let (rows, cols) = z.dim();
    let f = features(z, params);
    let maps: Vec<_> = [FeatureKind::Ridge, FeatureKind::Valley]
        .iter()
        .map(|&k| {
            let mask: Vec<bool> = f.tree(k).mask().iter().copied().collect();
            distance_transform(&mask, rows, cols)
        })
        .collect();
    let mut sums = [[0f64; 2]; 2];
    let mut counts = [0usize; 2];
    for c in &trees.cells {
        let (x, y) = (c.pos[0] as usize, c.pos[1] as usize);
        if x >= cols || y >= rows {
            continue;
        }
        let k = kind_index(c.kind);
        counts[k] += 1;
        for (m, map) in maps.iter().enumerate() {
            sums[k][m] += map.dist[y * cols + x].min(1e6);
        }
    }
    let mean = |k: usize, m: usize| sums[k][m] / counts[k].max(1) as f64;
    Fidelity {
        ridge_to_ridge: mean(0, 0),
        valley_to_valley: mean(1, 1),
        ridge_to_valley: mean(0, 1),
        valley_to_ridge: mean(1, 0),
        ridge_cells: counts[0],
        valley_cells: counts[1],
    }
}

/// Steps across seams against steps inside patches.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Seams {
    /// Mean |Δh| (metres) across edges between cells of different patches.
    pub seam_step: f64,
    /// Mean |Δh| across edges inside patches.
    pub interior_step: f64,
    /// `seam_step / interior_step`.
    pub ratio: f64,
    /// Seam edges measured.
    pub seam_edges: usize,
}

/// The seam measure of terrain `z` whose cells came from patches `labels`.
pub fn seams(z: &Array2<f32>, labels: &Array2<u32>) -> Seams {
    let (rows, cols) = z.dim();
    let (mut s, mut ns, mut i, mut ni) = (0f64, 0usize, 0f64, 0usize);
    if labels.dim() != (rows, cols) {
        return Seams::default();
    }
    for r in 0..rows {
        for c in 0..cols {
            for (rr, cc) in [(r, c + 1), (r + 1, c)] {
                if rr >= rows || cc >= cols {
                    continue;
                }
                let d = (f64::from(z[[rr, cc]]) - f64::from(z[[r, c]])).abs();
                if labels[[r, c]] != labels[[rr, cc]] {
                    s += d;
                    ns += 1;
                } else {
                    i += d;
                    ni += 1;
                }
            }
        }
    }
    let seam_step = s / ns.max(1) as f64;
    let interior_step = i / ni.max(1) as f64;
    Seams {
        seam_step,
        interior_step,
        ratio: if interior_step > 0.0 {
            seam_step / interior_step
        } else {
            0.0
        },
        seam_edges: ns,
    }
}
