//! Sketch synthesis (feature-guided patch synthesis, Zhou et al. 2007, "Terrain synthesis from
//! digital elevation models"): ridge and valley lines drawn by a user become a terrain made of
//! real exemplar patches.
//!
//! 1. The exemplars' ridges and valleys are extracted with the PPA ([`crate::analysis::ppa`]);
//!    the sketch's lines are drawn into the output grid and described the same way — trees of
//!    end points, branch points and paths ([`graph`]).
//! 2. **Feature patches**, in breadth-first order of the sketch's trees: at each centre, every
//!    exemplar feature point of the same kind and class is tried under the rotations (and
//!    mirrorings) that align one of its arms with the sketch's, scored by how close the sketch's
//!    nearby lines (both kinds) fall to the exemplar's features (chamfer distance on
//!    [`distance`] maps) and by the asked height; the best few are warped by a thin-plate spline
//!    ([`tps`]) that moves the exemplar's feature cells onto the sketch's lines, and the one
//!    whose overlap with what is already placed agrees best (with its best height offset) wins.
//! 3. **Fill patches**: the windows of a lattice not yet covered, most-covered first, each filled
//!    with the exemplar window whose overlap agrees best (SSD with a height offset, searched by
//!    FFT over every position: [`ssd`]).
//! 4. Every patch joins the composite along a minimum graph cut ([`graphcut`], [`compose`]), and
//!    a screened Poisson solve over the whole grid removes what is left of the seams
//!    ([`poisson`]).
//!
//! Deterministic for given inputs and seed: fixed orders, total tie-breaks, seeded hashes for
//! the small random choices, no clock, and parallel loops only where each item's result is
//! independent of the others (FFT rows). Global and sequential: run it once, when a world is
//! created (a job), never per tile. [`quality`] measures the result (fidelity to the sketch,
//! seams).

pub mod compose;
pub mod distance;
pub mod exemplar;
pub mod geojson;
pub mod geometry;
pub mod graph;
pub mod graphcut;
pub mod hydro;
pub mod poisson;
pub mod quality;
pub mod ssd;
pub mod tps;

use crate::math;
use ndarray::Array2;
use thiserror::Error;

use crate::analysis::ppa::{FeatureKind, NodeClass};
use crate::dictionary::rng::{hash2, to_unit_f64};
use crate::raster::Grid;

use compose::{Composite, Patch, Protection};
use exemplar::{bilinear, kind_index, PreparedExemplar};
use geometry::{dist, Sketch};
use graph::{sketch_trees, Centre, SketchTrees};
use ssd::Offset;
use tps::Tps;

pub use geometry::{OutputGrid, OutputSpec, SizeLimits, SketchLine};

/// Why a sketch could not become a terrain.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SketchError {
    /// The sketch or its bounds are unusable (no lines, outside the bounds, self-crossing...).
    #[error("invalid sketch: {0}")]
    Invalid(String),
    /// The world asked for exceeds the size limits.
    #[error("sketch too large: {0}")]
    TooLarge(String),
    /// An exemplar is unusable (no valid data, too small for the patch size).
    #[error("exemplar: {0}")]
    Exemplar(String),
    /// Cancelled through the progress callback.
    #[error("cancelled")]
    Cancelled,
}

/// Settings of a synthesis.
#[derive(Clone, Debug, PartialEq)]
pub struct SketchOptions {
    /// Patch side, cells.
    pub patch: usize,
    /// Overlap of neighbouring fill windows, cells.
    pub overlap: usize,
    /// Distance between feature patch centres along a path, cells.
    pub spacing: usize,
    /// Hypotheses warped and compared on their overlap at each feature centre.
    pub finalists: usize,
    /// Most candidate points tried per exemplar, kind and class at a feature centre.
    pub max_candidates: usize,
    /// Seed of the small random choices (ties between near-equal candidates).
    pub seed: u64,
    /// How far (cells) the Poisson correction of a seam reaches (`λ = 1/R²`).
    pub poisson_radius: f64,
    /// Largest exemplar (cells, after resampling) used; larger ones are cropped to their
    /// centre.
    pub max_exemplar_side: usize,
    /// Weight of a fill window's own relief (its standard deviation over the exemplar's
    /// typical step, squared) against its overlap error: fill patches of gentler ground let the
    /// sketched features stand out (Zhou et al. fill with feature-free patches).
    pub fill_smoothness: f64,
    /// Weight (per cell, against 1 for an overlapping cell) with which a fill window is also
    /// matched against the sketch's large-scale relief where nothing is placed yet, so that
    /// ground rises towards sketched ridges and falls towards sketched valleys.
    pub guide_weight: f64,
}

impl Default for SketchOptions {
    fn default() -> Self {
        SketchOptions {
            patch: 48,
            overlap: 12,
            spacing: 24,
            finalists: 8,
            max_candidates: 2500,
            seed: 1,
            poisson_radius: 16.0,
            max_exemplar_side: 2048,
            fill_smoothness: 0.0,
            guide_weight: 0.1,
        }
    }
}

/// Counts of a synthesis.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SketchStats {
    /// Feature patches placed.
    pub feature_patches: usize,
    /// Fill patches placed.
    pub fill_patches: usize,
    /// Edges between cells of different patches after all cuts.
    pub seam_edges: usize,
    /// Flood extent (%) after the Poisson solve, before the seam depressions were drained.
    pub flood_before_conditioning: f64,
    /// What draining the seam depressions did.
    pub conditioned: hydro::Conditioned,
}

/// A synthesized base.
#[derive(Clone, Debug)]
pub struct SketchWorld {
    /// The terrain on the sketch's grid (EPSG:4326).
    pub grid: Grid,
    /// The patch each cell came from (1-based, in placement order).
    pub labels: Array2<u32>,
    /// The sketch's trees (cells and patch centres).
    pub trees: SketchTrees,
    /// Counts.
    pub stats: SketchStats,
}

/// Progress callback: `(stage, fraction 0–1)`; returning `false` cancels.
pub type Progress<'a> = &'a mut dyn FnMut(&str, f64) -> bool;

fn report(progress: &mut Progress<'_>, stage: &str, f: f64) -> Result<(), SketchError> {
    if progress(stage, f.clamp(0.0, 1.0)) {
        Ok(())
    } else {
        Err(SketchError::Cancelled)
    }
}

/// A uniform number in `[0, 1)` from the seed and two integers.
fn jitter(seed: u64, a: usize, b: usize) -> f64 {
    to_unit_f64(hash2(seed, a as i64, b as i64))
}

/// The linear map of a hypothesis: output offsets → exemplar offsets, rotating the sketch's arm
/// `a_s` onto the exemplar's arm `a_e`, mirrored across that arm when `mirror`.
fn arm_map(a_s: f64, a_e: f64, mirror: bool) -> [[f64; 2]; 2] {
    let rot = |t: f64| [[math::cos(t), -math::sin(t)], [math::sin(t), math::cos(t)]];
    let mul = |a: [[f64; 2]; 2], b: [[f64; 2]; 2]| {
        [
            [
                a[0][0] * b[0][0] + a[0][1] * b[1][0],
                a[0][0] * b[0][1] + a[0][1] * b[1][1],
            ],
            [
                a[1][0] * b[0][0] + a[1][1] * b[1][0],
                a[1][0] * b[0][1] + a[1][1] * b[1][1],
            ],
        ]
    };
    if mirror {
        mul(mul(rot(a_e), [[1.0, 0.0], [0.0, -1.0]]), rot(-a_s))
    } else {
        rot(a_e - a_s)
    }
}

fn apply(m: &[[f64; 2]; 2], d: [f64; 2]) -> [f64; 2] {
    [
        m[0][0] * d[0] + m[0][1] * d[1],
        m[1][0] * d[0] + m[1][1] * d[1],
    ]
}

/// A hypothesis at a feature centre: exemplar `ex`, candidate point `point`, linear map.
#[derive(Clone, Debug)]
struct Hypothesis {
    cost: f64,
    ex: usize,
    point: usize,
    map: [[f64; 2]; 2],
    tag: usize,
}

/// Sketch cells near a point, found through a bucket grid.
struct CellIndex {
    bucket: usize,
    bcols: usize,
    brows: usize,
    lists: Vec<Vec<usize>>,
}

impl CellIndex {
    fn new(trees: &SketchTrees, rows: usize, cols: usize, bucket: usize) -> Self {
        let bucket = bucket.max(1);
        let (brows, bcols) = (rows / bucket + 1, cols / bucket + 1);
        let mut lists = vec![Vec::new(); brows * bcols];
        for (k, c) in trees.cells.iter().enumerate() {
            let (bx, by) = (c.pos[0] as usize / bucket, c.pos[1] as usize / bucket);
            lists[by.min(brows - 1) * bcols + bx.min(bcols - 1)].push(k);
        }
        CellIndex {
            bucket,
            bcols,
            brows,
            lists,
        }
    }

    /// Indices of cells within `radius` of `p`, in index order.
    fn near(&self, trees: &SketchTrees, p: [f64; 2], radius: f64) -> Vec<usize> {
        let b = self.bucket as f64;
        let lo_x = ((p[0] - radius) / b).floor().max(0.0) as usize;
        let lo_y = ((p[1] - radius) / b).floor().max(0.0) as usize;
        let hi_x = (((p[0] + radius) / b).floor().max(0.0) as usize).min(self.bcols - 1);
        let hi_y = (((p[1] + radius) / b).floor().max(0.0) as usize).min(self.brows - 1);
        let mut out = Vec::new();
        for by in lo_y..=hi_y {
            for bx in lo_x..=hi_x {
                for &k in &self.lists[by * self.bcols + bx] {
                    if dist(trees.cells[k].pos, p) <= radius {
                        out.push(k);
                    }
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// The output window of a patch centred on `p`: top-left and side, clipped to the grid.
fn window_at(p: [f64; 2], patch: usize, rows: usize, cols: usize) -> (usize, usize, usize, usize) {
    let half = (patch / 2) as f64;
    let r0 = (p[1] - half).round().max(0.0) as usize;
    let c0 = (p[0] - half).round().max(0.0) as usize;
    let r1 = ((p[1] + half).round().max(0.0) as usize).min(rows);
    let c1 = ((p[0] + half).round().max(0.0) as usize).min(cols);
    (r0, c0, r1.saturating_sub(r0), c1.saturating_sub(c0))
}

/// Everything the feature stage needs at once.
struct FeatureStage<'a> {
    exemplars: &'a [PreparedExemplar],
    trees: &'a SketchTrees,
    index: CellIndex,
    opts: &'a SketchOptions,
    rows: usize,
    cols: usize,
}

impl FeatureStage<'_> {
    /// Hypotheses at centre `c` scored by chamfer distance and height, best first, at most
    /// `opts.finalists`.
    fn hypotheses(&self, c: &Centre, local: &[usize]) -> Vec<Hypothesis> {
        let kind = kind_index(c.kind);
        let pts: Vec<([f64; 2], usize, f64)> = local
            .iter()
            .step_by(if local.len() > 96 {
                local.len() / 64
            } else {
                1
            })
            .map(|&k| {
                let cell = &self.trees.cells[k];
                let w = if cell.kind == c.kind { 1.0 } else { 0.5 };
                (
                    [cell.pos[0] - c.pos[0], cell.pos[1] - c.pos[1]],
                    kind_index(cell.kind),
                    w,
                )
            })
            .collect();
        let wsum: f64 = pts.iter().map(|p| p.2).sum::<f64>().max(1e-9);
        let a_s = c.arms.first().copied().unwrap_or(0.0);
        let mut best: Vec<Hypothesis> = Vec::new();
        let keep = self.opts.finalists.max(1);
        for (ei, ex) in self.exemplars.iter().enumerate() {
            let pool = &ex.points[kind];
            let same: Vec<usize> = (0..pool.len())
                .filter(|&i| pool[i].class == c.class)
                .collect();
            let chosen: Vec<usize> = if same.len() >= 8 {
                same
            } else {
                (0..pool.len())
                    .filter(|&i| pool[i].class == NodeClass::Path)
                    .collect()
            };
            let stride = chosen
                .len()
                .div_ceil(self.opts.max_candidates.max(1))
                .max(1);
            for &pi in chosen.iter().step_by(stride) {
                let q = &pool[pi];
                let height_term = match c.height_m {
                    Some(h) => ((h - q.height) / (4.0 * ex.relief)).powi(2),
                    None => 0.0,
                };
                for (ai, &a_e) in q.arms.iter().enumerate() {
                    for mirror in [false, true] {
                        let map = arm_map(a_s, a_e, mirror);
                        let mut s = 0.0;
                        for &(d, k, w) in &pts {
                            let e = apply(&map, d);
                            let v = ex.distance[k].sample(q.pos[0] + e[0], q.pos[1] + e[1]);
                            s += w * v.min(6.0).powi(2);
                        }
                        let cost = s / wsum / 4.0 + height_term;
                        if best.len() < keep || cost < best[best.len() - 1].cost {
                            let h = Hypothesis {
                                cost,
                                ex: ei,
                                point: pi,
                                map,
                                tag: ai * 2 + usize::from(mirror),
                            };
                            let at = best.partition_point(|b| b.cost <= cost);
                            best.insert(at, h);
                            best.truncate(keep);
                        }
                    }
                }
            }
        }
        best
    }

    /// The warped patch of hypothesis `h` at centre `c` (and the exemplar heights of its
    /// corresponding feature cells, for the height offset).
    fn warp(&self, c: &Centre, local: &[usize], h: &Hypothesis) -> (Patch, Vec<f64>) {
        let ex = &self.exemplars[h.ex];
        let q = ex.points[kind_index(c.kind)][h.point].pos;
        let (rows, cols) = ex.dim();
        let to_ex = |p: [f64; 2]| {
            let e = apply(&h.map, [p[0] - c.pos[0], p[1] - c.pos[1]]);
            [q[0] + e[0], q[1] + e[1]]
        };
        // Control points: sketch cells moved onto their nearest exemplar feature cell.
        let mut from = Vec::new();
        let mut to = Vec::new();
        let mut heights = Vec::new();
        for &k in local.iter().step_by(2) {
            let cell = &self.trees.cells[k];
            let e = to_ex(cell.pos);
            let dm = &ex.distance[kind_index(cell.kind)];
            let (ix, iy) = (e[0].round(), e[1].round());
            if ix < 0.0 || iy < 0.0 || ix >= cols as f64 || iy >= rows as f64 {
                continue;
            }
            let i = iy as usize * cols + ix as usize;
            let site = dm.site[i];
            if site == usize::MAX || dm.dist[i] > 4.0 {
                continue;
            }
            let f = [(site % cols) as f64, (site / cols) as f64];
            from.push(cell.pos);
            to.push(f);
            if cell.kind == c.kind {
                heights.push(f64::from(ex.elevation[[site / cols, site % cols]]));
            }
        }
        // Anchors on the window's border keep the rigid placement there.
        let half = (self.opts.patch / 2) as f64 + 2.0;
        for k in 0..16 {
            let t = k as f64 / 16.0 * std::f64::consts::TAU;
            let p = [
                c.pos[0] + half * 1.3 * math::cos(t),
                c.pos[1] + half * 1.3 * math::sin(t),
            ];
            from.push(p);
            to.push(to_ex(p));
        }
        let tps = Tps::fit(&from, &to, 1.0);
        let (r0, c0, wr, wc) = window_at(c.pos, self.opts.patch, self.rows, self.cols);
        let mut values = vec![f64::NAN; wr * wc];
        let mut wet = vec![false; wr * wc];
        for r in 0..wr {
            for cc in 0..wc {
                let p = [(c0 + cc) as f64, (r0 + r) as f64];
                let e = match &tps {
                    Some(t) => t.eval(p),
                    None => to_ex(p),
                };
                if e[0] >= 0.0
                    && e[1] >= 0.0
                    && e[0] <= (cols - 1) as f64
                    && e[1] <= (rows - 1) as f64
                {
                    values[r * wc + cc] = bilinear(&ex.elevation, e[0], e[1]);
                    wet[r * wc + cc] = ex.wet[e[1].round() as usize * cols + e[0].round() as usize];
                }
            }
        }
        (
            Patch {
                row0: r0,
                col0: c0,
                rows: wr,
                cols: wc,
                values,
                wet,
            },
            heights,
        )
    }
}

/// Row-major index of sketch cell `k`.
fn cell_index(trees: &SketchTrees, k: usize, cols: usize) -> usize {
    let p = trees.cells[k].pos;
    p[1] as usize * cols + p[0] as usize
}

/// The patch's value at sketch cell `k`, if it has one there.
fn patch_at(p: &Patch, trees: &SketchTrees, k: usize) -> Option<f64> {
    let pos = trees.cells[k].pos;
    let (r, c) = (pos[1] as usize, pos[0] as usize);
    if r < p.row0 || c < p.col0 || r >= p.row0 + p.rows || c >= p.col0 + p.cols {
        return None;
    }
    let v = p.values[(r - p.row0) * p.cols + (c - p.col0)];
    (!v.is_nan()).then_some(v)
}

/// The patch's mean height on the centre's own lines within 3 cells of it.
fn centre_height(p: &Patch, trees: &SketchTrees, own: &[usize], c: &Centre) -> Option<f64> {
    let (mut sum, mut n) = (0f64, 0usize);
    for &k in own {
        if dist(trees.cells[k].pos, c.pos) <= 3.0 {
            if let Some(v) = patch_at(p, trees, k) {
                sum += v;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// Least-squares slope (metres per cell along the path) of the patch's heights on each of the
/// centre's paths, for paths with at least 4 cells in the patch.
fn profile_slopes(p: &Patch, trees: &SketchTrees, own: &[usize], c: &Centre) -> Vec<(u32, f64)> {
    let mut out = Vec::new();
    for &path in &c.paths {
        let pts: Vec<(f64, f64)> = own
            .iter()
            .filter(|&&k| trees.cells[k].path == path)
            .filter_map(|&k| patch_at(p, trees, k).map(|v| (f64::from(trees.cells[k].along), v)))
            .collect();
        if pts.len() < 4 {
            continue;
        }
        let n = pts.len() as f64;
        let mx = pts.iter().map(|q| q.0).sum::<f64>() / n;
        let my = pts.iter().map(|q| q.1).sum::<f64>() / n;
        let sxx: f64 = pts.iter().map(|q| (q.0 - mx) * (q.0 - mx)).sum();
        let sxy: f64 = pts.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
        if sxx > 0.0 {
            out.push((path, sxy / sxx));
        }
    }
    out
}

/// RMS of `A − B − offset` over the overlap and the overlap's size.
fn overlap_rms(comp: &Composite, patch: &Patch, offset: f64) -> (f64, usize) {
    let (mut sum2, mut n) = (0f64, 0usize);
    for r in 0..patch.rows {
        for c in 0..patch.cols {
            let v = patch.values[r * patch.cols + c];
            let i = (patch.row0 + r) * comp.cols + patch.col0 + c;
            if !v.is_nan() && comp.covered(i) {
                let d = comp.h[i] - v - offset;
                sum2 += d * d;
                n += 1;
            }
        }
    }
    if n == 0 {
        (0.0, 0)
    } else {
        ((sum2 / n as f64).sqrt(), n)
    }
}

/// Synthesizes the terrain of `sketch` from `exemplars`.
pub fn synthesize(
    sketch: &Sketch,
    exemplars: &[Grid],
    opts: &SketchOptions,
    mut progress: Progress<'_>,
) -> Result<SketchWorld, SketchError> {
    let (rows, cols) = (sketch.grid.rows, sketch.grid.cols);
    if exemplars.is_empty() {
        return Err(SketchError::Exemplar("no exemplar given".into()));
    }
    let patch = opts.patch.clamp(16, rows.min(cols));
    let opts = &SketchOptions {
        patch,
        overlap: opts.overlap.clamp(2, patch / 2),
        spacing: opts.spacing.clamp(4, patch),
        ..opts.clone()
    };
    report(&mut progress, "exemplars", 0.0)?;
    let out_cell = sketch.grid.georef.cell_size_m(rows as f64 / 2.0);
    // Candidates must keep a rotated, slightly warped patch inside the exemplar.
    let margin = (patch as f64 * 0.75).ceil() as usize + 4;
    let side = opts.max_exemplar_side.max(4 * margin);
    let mut prepared = Vec::new();
    for (k, g) in exemplars.iter().enumerate() {
        let (er, ec) = (g.rows(), g.cols());
        let crop = if er > side || ec > side {
            let (r0, c0) = (er.saturating_sub(side) / 2, ec.saturating_sub(side) / 2);
            let (r1, c1) = ((r0 + side).min(er), (c0 + side).min(ec));
            Grid {
                data: g.data.slice(ndarray::s![r0..r1, c0..c1]).to_owned(),
                georef: g.georef.window(c0 as i64, r0 as i64),
                valid: g
                    .valid
                    .as_ref()
                    .map(|m| m.slice(ndarray::s![r0..r1, c0..c1]).to_owned()),
            }
        } else {
            g.clone()
        };
        prepared.push(PreparedExemplar::new(
            &crop,
            out_cell,
            margin,
            side.saturating_mul(side).saturating_mul(4),
        )?);
        report(
            &mut progress,
            "exemplars",
            (k + 1) as f64 / exemplars.len() as f64,
        )?;
    }
    let trees = sketch_trees(sketch, opts.spacing);
    if trees.centres.is_empty() {
        return Err(SketchError::Invalid(
            "the sketch's lines leave no feature to place".into(),
        ));
    }
    let mut comp = Composite::new(rows, cols);
    let mut stats = SketchStats::default();
    let guide = guide_field(&trees, rows, cols, &prepared, patch as f64);
    let stage = FeatureStage {
        exemplars: &prepared,
        trees: &trees,
        index: CellIndex::new(&trees, rows, cols, 16),
        opts,
        rows,
        cols,
    };
    let radius = patch as f64 / 2.0;
    let core = patch as f64 / 4.0;
    // Valley floors rise from the exemplars' low valley floors at each tree's outlet, at the
    // exemplars' main-channel gradient (gentler when the longest valley would climb above their
    // high valley floors).
    let n_ex = prepared.len() as f64;
    let base = prepared.iter().map(|e| e.valley_floors.0).sum::<f64>() / n_ex;
    let top = prepared.iter().map(|e| e.valley_floors.1).sum::<f64>() / n_ex;
    let longest = trees
        .centres
        .iter()
        .filter_map(|c| c.drain)
        .fold(1.0f64, f64::max);
    let gradient = (prepared.iter().map(|e| e.valley_gradient).sum::<f64>() / n_ex)
        .min((top - base).max(0.0) / longest);
    for (ci, c) in trees.centres.iter().enumerate() {
        let local = stage.index.near(&trees, c.pos, radius);
        let own_local: Vec<usize> = local
            .iter()
            .copied()
            .filter(|&k| c.paths.contains(&trees.cells[k].path))
            .collect();
        let target = c.drain.map(|d| base + gradient * d);
        let hyps = stage.hypotheses(c, &local);
        let mut chosen: Option<(f64, Patch, f64)> = None;
        for (hi, h) in hyps.iter().enumerate() {
            let (mut p, heights) = stage.warp(c, &local, h);
            let relief = prepared[h.ex].relief;
            let floor = centre_height(&p, &trees, &own_local, c);
            let offset = match (c.height_m, target, floor) {
                (Some(want), _, _) if !heights.is_empty() => {
                    want - heights.iter().sum::<f64>() / heights.len() as f64
                }
                (_, Some(t), Some(f)) => t - f,
                _ => guided_offset(&comp, &p, &guide, opts.guide_weight),
            };
            let (rms, n) = overlap_rms(&comp, &p, offset);
            let overlap_term = if n > 0 { (rms / relief).powi(2) } else { 0.0 };
            let mut profile_term = 0.0;
            if c.kind == FeatureKind::Valley {
                for (path, slope) in profile_slopes(&p, &trees, &own_local, c) {
                    // Floors fall towards the outlet, gently.
                    let fall = -slope * trees.descent[path as usize];
                    let excess = (fall - gradient).abs() * opts.spacing as f64 / relief;
                    profile_term += 0.5 * excess * excess;
                    if fall < 0.0 {
                        profile_term += 1.0 - fall * opts.spacing as f64 / relief;
                    }
                }
            }
            // Offsets far from the exemplar's own heights drift the terrain away from real
            // elevations.
            let offset_term = if c.height_m.is_some() {
                0.0
            } else {
                (offset / (6.0 * relief)).powi(2)
            };
            let guide_term = opts.guide_weight * guide_misfit(&p, &guide, cols, offset, relief);
            let score = h.cost
                + overlap_term
                + profile_term
                + offset_term
                + guide_term
                + 0.02 * jitter(opts.seed, ci, hi * 8 + h.tag);
            if chosen.as_ref().is_none_or(|(s, _, _)| score < *s) {
                for v in p.values.iter_mut() {
                    *v += offset;
                }
                let f = floor.map_or(f64::NAN, |f| f + offset);
                chosen = Some((score, p, f));
            }
        }
        if let Some((_, p, _)) = chosen {
            // The centre's own lines near it go to the new patch and are protected afterwards.
            let own: Vec<usize> = own_local
                .iter()
                .filter(|&&k| dist(trees.cells[k].pos, c.pos) <= core)
                .map(|&k| cell_index(&trees, k, cols))
                .collect();
            comp.place(&p, &own, Protection::Except(&c.paths));
            let mut guard = Vec::new();
            for &i in &own {
                let (r, cc) = (i / cols, i % cols);
                for dr in 0..3usize {
                    for dc in 0..3usize {
                        let (rr, c2) = ((r + dr).wrapping_sub(1), (cc + dc).wrapping_sub(1));
                        if rr < rows && c2 < cols && comp.label[rr * cols + c2] == comp.patches() {
                            guard.push(rr * cols + c2);
                        }
                    }
                }
            }
            let path = c.paths.first().copied().unwrap_or(0);
            comp.protect_cells(&guard, path);
            stats.feature_patches += 1;
        }
        report(
            &mut progress,
            "features",
            (ci + 1) as f64 / trees.centres.len() as f64,
        )?;
    }
    fill(
        &mut comp,
        &guide,
        &prepared,
        opts,
        &mut stats,
        &mut progress,
    )?;
    report(&mut progress, "seams", 0.0)?;
    let b = poisson::divergence(&comp.h, &comp.gx, &comp.gy, rows, cols);
    let lambda = 1.0 / (opts.poisson_radius * opts.poisson_radius).max(1.0);
    let delta = poisson::conjugate_gradient(&b, rows, cols, lambda, 1e-7, 4000);
    let (sh, sv) = comp.seams();
    stats.seam_edges = sh.iter().chain(&sv).filter(|&&s| s).count();
    let mut data = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let i = r * cols + c;
        (comp.h[i] + delta[i]) as f32
    });
    report(&mut progress, "drainage", 0.0)?;
    stats.flood_before_conditioning = crate::analysis::flood_extent(&data);
    let mut ridge = vec![false; rows * cols];
    let mut valley = vec![false; rows * cols];
    for cell in &trees.cells {
        let (r, c) = (cell.pos[1] as usize, cell.pos[0] as usize);
        if cell.kind == FeatureKind::Valley {
            valley[r * cols + c] = true;
            continue;
        }
        for rr in r.saturating_sub(1)..(r + 2).min(rows) {
            for cc in c.saturating_sub(1)..(c + 2).min(cols) {
                ridge[rr * cols + cc] = true;
            }
        }
    }
    let cells_m = sketch.grid.georef.cell_sizes(rows);
    stats.conditioned = hydro::condition(&mut data, &cells_m, &comp.wet, &ridge, &valley);
    let labels = Array2::from_shape_vec((rows, cols), comp.label.clone())
        .map_err(|e| SketchError::Invalid(e.to_string()))?;
    report(&mut progress, "seams", 1.0)?;
    Ok(SketchWorld {
        grid: Grid::new(data, sketch.grid.georef),
        labels,
        trees,
        stats,
    })
}

/// Window starts along a side of `n` cells: every `step`, the last flush with the end.
fn starts(n: usize, size: usize, step: usize) -> Vec<usize> {
    if n <= size {
        return vec![0];
    }
    let mut v: Vec<usize> = (0..)
        .map(|k| k * step)
        .take_while(|&s| s + size < n)
        .collect();
    v.push(n - size);
    v
}

/// The sketch's large-scale relief: high along ridges (the exemplars' 85th percentile of
/// elevation, or the line's own height), low along valleys (their 15th percentile, or the
/// line's height), the exemplars' median far from every line; blended with weights
/// `exp(−(d/σ)²)` of the distance `d` to the nearest ridge and valley cell (σ = the patch side)
/// and a constant weight for the background. Feature patches are chosen to fit it and fill
/// windows are matched against it where nothing is placed yet, so that at large scale the
/// ground rises towards sketched ridges and falls towards sketched valleys.
fn guide_field(
    trees: &SketchTrees,
    rows: usize,
    cols: usize,
    exemplars: &[PreparedExemplar],
    sigma: f64,
) -> Vec<f64> {
    let n = rows * cols;
    let mut levels = [0f64; 3];
    for ex in exemplars {
        let mut v: Vec<f32> = ex.elevation.iter().copied().collect();
        v.sort_by(f32::total_cmp);
        let q = |p: f64| {
            f64::from(
                v.get(((v.len() as f64 - 1.0) * p) as usize)
                    .copied()
                    .unwrap_or(0.0),
            )
        };
        levels[0] += q(0.85);
        levels[1] += q(0.15);
        levels[2] += q(0.5);
    }
    for l in &mut levels {
        *l /= exemplars.len().max(1) as f64;
    }
    let mut maps = Vec::new();
    let mut heights = vec![f64::NAN; n];
    for (k, kind) in [FeatureKind::Ridge, FeatureKind::Valley]
        .into_iter()
        .enumerate()
    {
        let mut mask = vec![false; n];
        for cell in trees.cells.iter().filter(|c| c.kind == kind) {
            let i = cell.pos[1] as usize * cols + cell.pos[0] as usize;
            mask[i] = true;
            heights[i] = cell.height_m.unwrap_or(levels[k]);
        }
        maps.push(distance::distance_transform(&mask, rows, cols));
    }
    let w0 = 0.3;
    (0..n)
        .map(|i| {
            let mut num = w0 * levels[2];
            let mut den = w0;
            for m in &maps {
                let site = m.site[i];
                if site == usize::MAX {
                    continue;
                }
                let w = math::exp(-(m.dist[i] / sigma).powi(2));
                num += w * heights[site];
                den += w;
            }
            num / den
        })
        .collect()
}

/// Mean squared difference between the patch (plus `offset`) and the guide over the patch,
/// over the squared relief.
fn guide_misfit(p: &Patch, guide: &[f64], cols: usize, offset: f64, relief: f64) -> f64 {
    let (mut sum, mut n) = (0f64, 0usize);
    for r in 0..p.rows {
        for c in 0..p.cols {
            let v = p.values[r * p.cols + c];
            if !v.is_nan() {
                let d = v + offset - guide[(p.row0 + r) * cols + p.col0 + c];
                sum += d * d;
                n += 1;
            }
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64 / (relief * relief)
    }
}

/// The offset minimising the squared overlap error plus `weight` times the squared misfit to
/// the guide over the whole patch.
fn guided_offset(comp: &Composite, p: &Patch, guide: &[f64], weight: f64) -> f64 {
    let (mut num, mut den) = (0f64, 0f64);
    for r in 0..p.rows {
        for c in 0..p.cols {
            let v = p.values[r * p.cols + c];
            if v.is_nan() {
                continue;
            }
            let i = (p.row0 + r) * comp.cols + p.col0 + c;
            if comp.covered(i) {
                num += comp.h[i] - v;
                den += 1.0;
            }
            num += weight * (guide[i] - v);
            den += weight;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// Coarse positions refined at full resolution in each fill search.
const REFINE: usize = 4;

/// The best placement of template `t` (mask `m`) in block `bi` of `ex`: the coarse search by FFT
/// over the block's 2 × 2 averages, then the [`REFINE`] best coarse positions refined over the
/// 4 × 4 full-resolution positions each stands for, by direct summation. Cost per overlap cell
/// over the exemplar's squared relief, plus the window's own relief weighted by
/// `fill_smoothness`. Returns `(total, row, column, offset)` in full-resolution exemplar cells.
fn search_block(
    ex: &PreparedExemplar,
    bi: usize,
    t: &Array2<f64>,
    m: &Array2<f64>,
    offset: Offset,
    opts: &SketchOptions,
) -> Option<(f64, usize, usize, f64)> {
    let (wh, ww) = t.dim();
    let (ch, cw) = (wh.div_ceil(2), ww.div_ceil(2));
    // The template and mask averaged 2 × 2 (partly covered blocks weigh less).
    let mut tc = Array2::<f64>::zeros((ch, cw));
    let mut mc = Array2::<f64>::zeros((ch, cw));
    for r in 0..wh {
        for c in 0..ww {
            tc[[r / 2, c / 2]] += m[[r, c]] * t[[r, c]];
            mc[[r / 2, c / 2]] += m[[r, c]];
        }
    }
    for (tv, mv) in tc.iter_mut().zip(mc.iter_mut()) {
        if *mv > 0.0 {
            *tv /= *mv;
        }
        *mv *= 0.25;
    }
    let (br, bc, index) = ex.blocks.get(bi)?;
    let costs = index.costs(&tc, &mc, offset)?;
    let r2 = ex.relief * ex.relief;
    let n = m.sum().max(1.0);
    let nc = mc.sum().max(1e-9);
    let smooth = |u: usize, v: usize| {
        let std = ex.window_std(u, v, wh, ww);
        opts.fill_smoothness * std * std / r2
    };
    // The best coarse positions (ties: first).
    let mut top: Vec<(f64, usize)> = Vec::with_capacity(REFINE + 1);
    for (i, &cost) in costs.cost.iter().enumerate() {
        let (u, v) = (2 * (br + i / costs.cols), 2 * (bc + i % costs.cols));
        let total = cost / nc / r2 + smooth(u, v);
        if top.len() < REFINE || total < top[top.len() - 1].0 {
            let at = top.partition_point(|x| x.0 <= total);
            top.insert(at, (total, i));
            top.truncate(REFINE);
        }
    }
    let shift = t.iter().zip(m.iter()).map(|(a, w)| a * w).sum::<f64>() / n;
    let mut best: Option<(f64, usize, usize, f64)> = None;
    for &(_, i) in &top {
        let (u0, v0) = (2 * (br + i / costs.cols), 2 * (bc + i % costs.cols));
        for du in 0..4usize {
            for dv in 0..4usize {
                let (Some(u), Some(v)) = ((u0 + du).checked_sub(1), (v0 + dv).checked_sub(1))
                else {
                    continue;
                };
                let Some((cost, o)) = ssd::direct_cost(&ex.elevation, u, v, t, m, offset, shift)
                else {
                    continue;
                };
                let total = cost / n / r2 + smooth(u, v);
                if best.is_none_or(|b| total < b.0) {
                    best = Some((total, u, v, o));
                }
            }
        }
    }
    best
}

/// Fills what the feature patches left uncovered.
fn fill(
    comp: &mut Composite,
    guide: &[f64],
    exemplars: &[PreparedExemplar],
    opts: &SketchOptions,
    stats: &mut SketchStats,
    progress: &mut Progress<'_>,
) -> Result<(), SketchError> {
    let (rows, cols) = (comp.rows, comp.cols);
    let size = opts.patch;
    let step = size - opts.overlap;
    let windows: Vec<(usize, usize)> = starts(rows, size, step)
        .into_iter()
        .flat_map(|r| starts(cols, size, step).into_iter().map(move |c| (r, c)))
        .collect();
    let (wh, ww) = (size.min(rows), size.min(cols));
    let count = |comp: &Composite, (r0, c0): (usize, usize)| -> usize {
        let mut n = 0;
        for r in r0..r0 + wh {
            for c in c0..c0 + ww {
                n += usize::from(comp.covered(r * cols + c));
            }
        }
        n
    };
    let mut covered: Vec<usize> = windows.iter().map(|&w| count(comp, w)).collect();
    let total = wh * ww;
    let todo_at_start = covered.iter().filter(|&&n| n < total).count().max(1);
    let mut done = 0usize;
    loop {
        // The most covered window not yet full (first on ties).
        let mut pick: Option<usize> = None;
        for (k, &n) in covered.iter().enumerate() {
            if n < total && pick.is_none_or(|p| n > covered[p]) {
                pick = Some(k);
            }
        }
        let Some(k) = pick else { break };
        let (r0, c0) = windows[k];
        let mut t = Array2::<f64>::zeros((wh, ww));
        let mut m = Array2::<f64>::zeros((wh, ww));
        for r in 0..wh {
            for c in 0..ww {
                let i = (r0 + r) * cols + c0 + c;
                if comp.covered(i) {
                    t[[r, c]] = comp.h[i];
                    m[[r, c]] = 1.0;
                } else {
                    t[[r, c]] = guide[i];
                    m[[r, c]] = opts.guide_weight;
                }
            }
        }
        let offset = Offset::Penalised(0.1);
        // Candidates: the best placement in every block searched (two blocks per exemplar at
        // most, chosen by the seed), then one of those within 10 % of the best, by the seed.
        let mut cands: Vec<(f64, usize, usize, usize, f64)> = Vec::new();
        for (ei, ex) in exemplars.iter().enumerate() {
            let nb = ex.blocks.len();
            let picks: Vec<usize> = if nb <= 2 {
                (0..nb).collect()
            } else {
                let a = (hash2(opts.seed, k as i64, ei as i64) % nb as u64) as usize;
                let b = (a
                    + 1
                    + (hash2(opts.seed ^ 0x5eed, k as i64, ei as i64) % (nb as u64 - 1)) as usize)
                    % nb;
                vec![a, b]
            };
            for bi in picks {
                if let Some((total, u, v, o)) = search_block(ex, bi, &t, &m, offset, opts) {
                    cands.push((total, ei, u, v, o));
                }
            }
        }
        if cands.is_empty() {
            return Err(SketchError::Exemplar(format!(
                "no exemplar can fill a {wh}×{ww} window"
            )));
        }
        let best = cands.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
        let near: Vec<&(f64, usize, usize, usize, f64)> =
            cands.iter().filter(|c| c.0 <= best * 1.1 + 1e-12).collect();
        let which = (hash2(opts.seed, k as i64, -1) % near.len() as u64) as usize;
        let &(_, ei, u, v, o) = near[which];
        let ex = &exemplars[ei];
        let ecols = ex.dim().1;
        let mut values = Vec::with_capacity(wh * ww);
        let mut wet = Vec::with_capacity(wh * ww);
        for r in 0..wh {
            for c in 0..ww {
                values.push(f64::from(ex.elevation[[u + r, v + c]]) + o);
                wet.push(ex.wet[(u + r) * ecols + v + c]);
            }
        }
        let p = Patch {
            row0: r0,
            col0: c0,
            rows: wh,
            cols: ww,
            values,
            wet,
        };
        comp.place(&p, &[], Protection::All);
        stats.fill_patches += 1;
        for (j, &(wr0, wc0)) in windows.iter().enumerate() {
            if wr0 < r0 + wh && r0 < wr0 + wh && wc0 < c0 + ww && c0 < wc0 + ww {
                covered[j] = count(comp, (wr0, wc0));
            }
        }
        done += 1;
        report(
            progress,
            "filling",
            (done as f64 / todo_at_start as f64).min(1.0),
        )?;
    }
    Ok(())
}
