//! An exemplar prepared for sketch synthesis: its elevation (NaN filled, resampled when its metric
//! cells differ from the output's by more than 2 %), its PPA ridges and valleys, a distance map
//! to each (with the nearest feature cell), the candidate feature points patches are centred on
//! (every key point and every other path cell, far enough from the borders for a rotated patch),
//! and its SSD index for filling (of its 2 × 2 box average: the fill search is coarse to fine).

use ndarray::Array2;

use crate::analysis::ppa::{features, FeatureKind, Features, NodeClass, PpaParams};
use crate::math;
use crate::raster::Grid;

use super::distance::{distance_transform, DistanceMap};
use super::ssd::SsdIndex;
use super::SketchError;

/// A point of an exemplar's feature tree a patch can be centred on.
#[derive(Clone, Debug, PartialEq)]
pub struct FeaturePoint {
    /// Cell coordinates `(x, y)`.
    pub pos: [f64; 2],
    /// End, path or branch point.
    pub class: NodeClass,
    /// Directions of its arms (radians in cell coordinates).
    pub arms: Vec<f64>,
    /// Its elevation, metres.
    pub height: f64,
    /// How much it stands out: for a ridge, its height above the mean of the cells
    /// [`STRENGTH_REACH`] cells away across it (for a valley, their height above it), metres.
    pub strength: f64,
}

/// How far across a feature its strength is measured, cells.
pub const STRENGTH_REACH: f64 = 10.0;

/// Share of each pool's points kept as candidates: the strongest features (sketched lines are
/// main ridges and valleys, not any crease the PPA finds).
pub const STRONG_SHARE: f64 = 0.4;

/// An exemplar ready for matching.
#[derive(Clone, Debug)]
pub struct PreparedExemplar {
    /// Elevation, metres (finite everywhere).
    pub elevation: Array2<f32>,
    /// Ridges and valleys.
    pub features: Features,
    /// Distance to the nearest ridge cell, then valley cell.
    pub distance: [DistanceMap; 2],
    /// Candidate points on ridges, then valleys.
    pub points: [Vec<FeaturePoint>; 2],
    /// Typical height difference between cells 4 apart (RMS, metres): the scale of overlap
    /// errors.
    pub relief: f64,
    /// The 10th and 90th percentiles of the heights of its strong valley points, metres.
    pub valley_floors: (f64, f64),
    /// Cells holding water at steady state in the exemplar itself (its natural depressions).
    pub wet: Vec<bool>,
    /// How fast main valley floors fall, metres per cell ([`main_channel_gradient`]).
    pub valley_gradient: f64,
    /// The elevation box-averaged 2 × 2 (the coarse level of the fill search).
    pub coarse: Array2<f32>,
    /// SSD indexes of blocks of the coarse elevation (top-left coarse row, column, index).
    pub blocks: Vec<(usize, usize, SsdIndex)>,
    /// Summed-area tables of the elevation and its square (`(rows + 1) × (cols + 1)`, f64), for
    /// the relief of any window.
    sat: (Vec<f64>, Vec<f64>),
}

/// Largest side of one SSD block (a power of two keeps the FFT cheap).
pub const SSD_BLOCK: usize = 512;

/// Index of a kind in the per-kind arrays.
pub fn kind_index(kind: FeatureKind) -> usize {
    match kind {
        FeatureKind::Ridge => 0,
        FeatureKind::Valley => 1,
    }
}

/// Bilinear resampling of `a` to `rows × cols` cells covering the same extent (cell-centred).
pub fn resample(a: &Array2<f32>, rows: usize, cols: usize) -> Array2<f32> {
    let (sr, sc) = a.dim();
    let fy = sr as f64 / rows.max(1) as f64;
    let fx = sc as f64 / cols.max(1) as f64;
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let y = ((r as f64 + 0.5) * fy - 0.5).clamp(0.0, (sr - 1) as f64);
        let x = ((c as f64 + 0.5) * fx - 0.5).clamp(0.0, (sc - 1) as f64);
        bilinear(a, x, y) as f32
    })
}

/// Bilinear value of `a` at cell coordinates `(x, y)` (clamped to the grid).
pub fn bilinear(a: &Array2<f32>, x: f64, y: f64) -> f64 {
    let (rows, cols) = a.dim();
    if rows == 0 || cols == 0 {
        return 0.0;
    }
    let xc = x.clamp(0.0, (cols - 1) as f64);
    let yc = y.clamp(0.0, (rows - 1) as f64);
    let (c0, r0) = (xc.floor() as usize, yc.floor() as usize);
    let (c1, r1) = ((c0 + 1).min(cols - 1), (r0 + 1).min(rows - 1));
    let (tx, ty) = (xc - c0 as f64, yc - r0 as f64);
    let v = |r: usize, c: usize| f64::from(a[[r, c]]);
    let top = v(r0, c0) * (1.0 - tx) + v(r0, c1) * tx;
    let bottom = v(r1, c0) * (1.0 - tx) + v(r1, c1) * tx;
    top * (1.0 - ty) + bottom * ty
}

impl PreparedExemplar {
    /// Prepares `grid` for an output whose cells measure `out_cell_m = (dx, dy)` metres;
    /// candidate points keep `margin` cells from the borders. `max_cells` bounds the resampled
    /// size.
    pub fn new(
        grid: &Grid,
        out_cell_m: (f64, f64),
        margin: usize,
        max_cells: usize,
    ) -> Result<PreparedExemplar, SketchError> {
        let filled = grid
            .filled()
            .map_err(|e| SketchError::Exemplar(e.to_string()))?;
        let (rows, cols) = filled.dim();
        let (ex_dx, ex_dy) = grid.georef.cell_size_m(rows as f64 / 2.0);
        let (sx, sy) = (ex_dx / out_cell_m.0, ex_dy / out_cell_m.1);
        let elevation = if (sx - 1.0).abs() > 0.02 || (sy - 1.0).abs() > 0.02 {
            let (nr, nc) = (
                (rows as f64 * sy).round() as usize,
                (cols as f64 * sx).round() as usize,
            );
            if nr.saturating_mul(nc) > max_cells {
                return Err(SketchError::Exemplar(format!(
                    "resampled to the output's cell size the exemplar would be {nc}×{nr} cells"
                )));
            }
            resample(&filled, nr, nc)
        } else {
            filled
        };
        let (rows, cols) = elevation.dim();
        if rows < 2 * margin + 8 || cols < 2 * margin + 8 {
            return Err(SketchError::Exemplar(format!(
                "the exemplar ({cols}×{rows} cells at the output's cell size) is too small for \
                 patches of this size: it needs at least {0}×{0}",
                2 * margin + 8
            )));
        }
        let features = features(&elevation, &PpaParams::default());
        let mut distance = Vec::new();
        let mut points: [Vec<FeaturePoint>; 2] = [Vec::new(), Vec::new()];
        for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
            let tree = features.tree(kind);
            let mask: Vec<bool> = tree.mask().iter().copied().collect();
            distance.push(distance_transform(&mask, rows, cols));
            points[kind_index(kind)] = strongest(feature_points(&elevation, tree, kind, margin));
        }
        let [dr, dv]: [DistanceMap; 2] = distance
            .try_into()
            .map_err(|_| SketchError::Exemplar("distance maps".into()))?;
        let mut sum = 0f64;
        let mut count = 0usize;
        for r in 0..rows {
            for c in 0..cols.saturating_sub(4) {
                let d = f64::from(elevation[[r, c + 4]]) - f64::from(elevation[[r, c]]);
                sum += d * d;
                count += 1;
            }
        }
        let relief = (sum / count.max(1) as f64).sqrt().max(1.0);
        let coarse = Array2::from_shape_fn((rows / 2, cols / 2), |(r, c)| {
            crate::raster::box2([
                elevation[[2 * r, 2 * c]],
                elevation[[2 * r, 2 * c + 1]],
                elevation[[2 * r + 1, 2 * c]],
                elevation[[2 * r + 1, 2 * c + 1]],
            ])
        });
        let blocks = ssd_blocks(&coarse);
        let valley_gradient = main_channel_gradient(&elevation);
        let mut floors: Vec<f64> = points[1].iter().map(|p| p.height).collect();
        floors.sort_by(f64::total_cmp);
        let pick = |q: f64| {
            floors
                .get(((floors.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(0.0)
        };
        let valley_floors = (pick(0.1), pick(0.9));
        let sat = summed_area(&elevation);
        let flat = crate::analysis::priority_flood_fill_flat(&elevation);
        let wet = flat
            .iter()
            .zip(elevation.iter())
            .map(|(f, h)| f > h)
            .collect();
        Ok(PreparedExemplar {
            coarse,
            wet,
            sat,
            valley_floors,
            valley_gradient,
            elevation,
            features,
            distance: [dr, dv],
            points,
            relief,
            blocks,
        })
    }

    /// Rows and columns.
    pub fn dim(&self) -> (usize, usize) {
        self.elevation.dim()
    }

    /// Standard deviation of the elevation over the `h × w` window whose top-left cell is
    /// `(r, c)` (0 outside the exemplar).
    pub fn window_std(&self, r: usize, c: usize, h: usize, w: usize) -> f64 {
        let (rows, cols) = self.dim();
        if r + h > rows || c + w > cols || h == 0 || w == 0 {
            return 0.0;
        }
        let stride = cols + 1;
        let sum = |t: &[f64]| {
            t[(r + h) * stride + c + w] - t[r * stride + c + w] - t[(r + h) * stride + c]
                + t[r * stride + c]
        };
        let n = (h * w) as f64;
        let mean = sum(&self.sat.0) / n;
        (sum(&self.sat.1) / n - mean * mean).max(0.0).sqrt()
    }
}

/// Summed-area tables of `z − z[0,0]` and its square (the shift keeps sums small).
fn summed_area(z: &Array2<f32>) -> (Vec<f64>, Vec<f64>) {
    let (rows, cols) = z.dim();
    let stride = cols + 1;
    let shift = z.iter().next().map_or(0.0, |&v| f64::from(v));
    let mut s1 = vec![0f64; (rows + 1) * stride];
    let mut s2 = vec![0f64; (rows + 1) * stride];
    for r in 0..rows {
        let (mut row1, mut row2) = (0f64, 0f64);
        for c in 0..cols {
            let v = f64::from(z[[r, c]]) - shift;
            row1 += v;
            row2 += v * v;
            s1[(r + 1) * stride + c + 1] = s1[r * stride + c + 1] + row1;
            s2[(r + 1) * stride + c + 1] = s2[r * stride + c + 1] + row2;
        }
    }
    (s1, s2)
}

/// Most SSD blocks kept per exemplar (each holds two transforms of [`SSD_BLOCK`]² complex
/// values, 8 MiB).
pub const MAX_BLOCKS: usize = 6;

/// Upstream area (m²) from which a D8 channel counts as a main valley.
pub const MAIN_CHANNEL_M2: f64 = 1e8;

/// The median fall (metres per cell step) of the D8 channels draining at least
/// [`MAIN_CHANNEL_M2`] (on the priority-flood-filled exemplar, cells taken as 1 × 1 km apart
/// only for the area threshold's sake... no: cells at the exemplar's mean cell size), clamped to
/// 0.2–10; 2 when the exemplar has no such channel.
pub fn main_channel_gradient(z: &Array2<f32>) -> f64 {
    let (rows, cols) = z.dim();
    let cells = crate::raster::CellSizes::uniform(rows, 400.0);
    let filled = crate::analysis::priority_flood_fill(z);
    let rcv = crate::analysis::d8_receivers(&filled, &cells);
    let area = crate::analysis::flow_accumulation_from_receivers(&rcv, &cells);
    let mut falls = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let d = rcv[[r, c]];
            if area[[r, c]] < MAIN_CHANNEL_M2 || d as usize >= 8 {
                continue;
            }
            let (dr, dc) = crate::analysis::D8_OFFSETS[d as usize];
            let (Some(nr), Some(nc)) = (r.checked_add_signed(dr), c.checked_add_signed(dc)) else {
                continue;
            };
            if nr >= rows || nc >= cols {
                continue;
            }
            let step = if dr != 0 && dc != 0 {
                std::f64::consts::SQRT_2
            } else {
                1.0
            };
            falls.push((f64::from(z[[r, c]]) - f64::from(z[[nr, nc]])).max(0.0) / step);
        }
    }
    if falls.is_empty() {
        return 2.0;
    }
    falls.sort_by(f64::total_cmp);
    falls[falls.len() / 2].clamp(0.2, 10.0)
}

/// SSD indexes of blocks of at most [`SSD_BLOCK`] cells a side, overlapping by half a block, so
/// that every window of up to half a block lies wholly in one; of more than [`MAX_BLOCKS`], an
/// evenly spread selection.
fn ssd_blocks(e: &Array2<f32>) -> Vec<(usize, usize, SsdIndex)> {
    let (rows, cols) = e.dim();
    let starts = |n: usize| -> Vec<usize> {
        if n <= SSD_BLOCK {
            return vec![0];
        }
        let step = SSD_BLOCK / 2;
        let mut v: Vec<usize> = (0..)
            .map(|k| k * step)
            .take_while(|&s| s + SSD_BLOCK < n)
            .collect();
        v.push(n - SSD_BLOCK);
        v
    };
    let mut all = Vec::new();
    for &r in &starts(rows) {
        for &c in &starts(cols) {
            all.push((r, c));
        }
    }
    let keep: Vec<(usize, usize)> = if all.len() <= MAX_BLOCKS {
        all
    } else {
        (0..MAX_BLOCKS)
            .map(|k| all[k * (all.len() - 1) / (MAX_BLOCKS - 1)])
            .collect()
    };
    let mut out = Vec::new();
    for (r, c) in keep {
        let block = e
            .slice(ndarray::s![
                r..(r + SSD_BLOCK).min(rows),
                c..(c + SSD_BLOCK).min(cols)
            ])
            .to_owned();
        out.push((r, c, SsdIndex::new(&block)));
    }
    out
}

/// Candidate points of a tree: key points and every other path cell, at least `margin` cells
/// from the borders, each with its arms' directions (5 cells along the tree).
fn feature_points(
    z: &Array2<f32>,
    tree: &crate::analysis::ppa::FeatureTree,
    kind: FeatureKind,
    margin: usize,
) -> Vec<FeaturePoint> {
    let (rows, cols) = (tree.rows, tree.cols);
    let n = rows * cols;
    let mut adj = vec![Vec::new(); n];
    for &(a, b) in &tree.edges {
        adj[a].push(b);
        adj[b].push(a);
    }
    for l in &mut adj {
        l.sort_unstable();
    }
    let mut take = vec![false; n];
    for p in &tree.paths {
        for (k, &i) in p.cells.iter().enumerate() {
            if k % 2 == 0 || adj[i].len() != 2 {
                take[i] = true;
            }
        }
    }
    let walk = |from: usize, first: usize| {
        let (mut prev, mut cur) = (from, first);
        for _ in 1..5 {
            if adj[cur].len() != 2 {
                break;
            }
            let next = if adj[cur][0] == prev {
                adj[cur][1]
            } else {
                adj[cur][0]
            };
            prev = cur;
            cur = next;
        }
        cur
    };
    let mut out = Vec::new();
    for i in 0..n {
        if !take[i] {
            continue;
        }
        let (r, c) = (i / cols, i % cols);
        if r < margin || c < margin || r + margin >= rows || c + margin >= cols {
            continue;
        }
        let arms: Vec<f64> = adj[i]
            .iter()
            .map(|&f| {
                let e = walk(i, f);
                let (er, ec) = ((e / cols) as f64, (e % cols) as f64);
                math::atan2(er - r as f64, ec - c as f64)
            })
            .collect();
        let height = f64::from(z[[r, c]]);
        let (x, y) = (c as f64, r as f64);
        // Across a path: the normal of its arms' mean direction; elsewhere: all around.
        let around: Vec<f64> = match arms.as_slice() {
            [a, b] => {
                let t = math::atan2(math::sin(*a) - math::sin(*b), math::cos(*a) - math::cos(*b))
                    + std::f64::consts::FRAC_PI_2;
                vec![t, t + std::f64::consts::PI]
            }
            _ => (0..8)
                .map(|k| k as f64 * std::f64::consts::FRAC_PI_4)
                .collect(),
        };
        let mean = around
            .iter()
            .map(|t| {
                bilinear(
                    z,
                    x + STRENGTH_REACH * math::cos(*t),
                    y + STRENGTH_REACH * math::sin(*t),
                )
            })
            .sum::<f64>()
            / around.len() as f64;
        let strength = match kind {
            FeatureKind::Ridge => height - mean,
            FeatureKind::Valley => mean - height,
        };
        out.push(FeaturePoint {
            pos: [x, y],
            class: NodeClass::of_degree(adj[i].len()),
            arms,
            height,
            strength,
        });
    }
    out
}

/// The strongest [`STRONG_SHARE`] of each class's points (all of a class with fewer than 16),
/// in their original order.
fn strongest(points: Vec<FeaturePoint>) -> Vec<FeaturePoint> {
    let mut keep = vec![false; points.len()];
    for class in [NodeClass::End, NodeClass::Path, NodeClass::Branch] {
        let mut idx: Vec<usize> = (0..points.len())
            .filter(|&i| points[i].class == class)
            .collect();
        if idx.len() < 16 {
            for i in idx {
                keep[i] = true;
            }
            continue;
        }
        idx.sort_by(|&a, &b| {
            points[b]
                .strength
                .total_cmp(&points[a].strength)
                .then(a.cmp(&b))
        });
        let n = ((idx.len() as f64 * STRONG_SHARE).ceil() as usize).max(16);
        for &i in idx.iter().take(n) {
            keep[i] = true;
        }
    }
    points
        .into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect()
}
