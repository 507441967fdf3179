//! Gradient tile sets (DESIGN.md method 3, issue #20): tiles of exemplar *detail gradients*
//! indexed by the colours of their two constrained edges, and the rules that give a tile its
//! colours and its scale. The rules ([`ColourTable`], [`tile_stats`], [`coarse_gx`],
//! [`coarse_gy`]) are shared by the build here and by the synthesis
//! ([`crate::synth::gradient`]), so a tile is looked up with exactly the colours it was filed
//! under.
//!
//! Geometry (child pixels of a ×2 level; the parent is the box-down of the child plane): a tile
//! covers `T × T` child pixels with its origin `(x0, y0)` on even coordinates, i.e. on parent
//! pixel `(x0/2, y0/2)`. An *x-tile* holds detail x-gradients `h[y][x+1] − h[y][x] − coarse` for
//! `x ∈ [x0, x0+T)`, its colours are those of the parent's x-gradient across its left edge
//! (`x = x0`) and its right edge (`x = x0 + T`); a *y-tile* likewise with y-gradients and its top
//! and bottom edges. The coarse gradient is the derivative of the parent's cubic Hermite
//! interpolant (central-difference tangents): the Hermite preconditioning. Tile values are
//! divided by the tile's scale `σ/2` (`σ`: RMS of the parent's gradients over the tile), so a
//! tile fits any relief.
//!
//! An edge colour is the parent's mean gradient across the edge divided by `σ`, quantised through
//! the Gaussian CDF: colour `c` of `C` holds the `z` with `Φ(z) ∈ [c/C, (c+1)/C)`
//! ([`ColourTable`] stores the `C − 1` thresholds `Φ⁻¹(c/C)`).

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use super::error::DictionaryError;
use super::exemplar::PixelWindow;
use crate::math;
use crate::raster::boxfilter::{box2, reduce2x2};
use crate::raster::Grid;

/// Smallest and largest tile size (child pixels; a multiple of 4).
pub const TILE_RANGE: (usize, usize) = (4, 16);
/// Largest number of edge colours per layer.
pub const MAX_COLOURS: usize = 16;
/// Largest number of alternatives per colour combination.
pub const MAX_ALTERNATIVES: usize = 64;
/// Smallest gradient scale `σ` (metres per parent pixel) a tile is divided by.
pub const MIN_SIGMA: f32 = 1e-3;

/// The parameters of a gradient tile set (the paper's: tile size, edge colours per layer,
/// alternatives per colour combination, exemplar mixing).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GradientParams {
    /// Tile side in child pixels: a multiple of 4 in 4–16.
    pub tile: usize,
    /// Edge colours per layer (quantisation levels of an edge's gradient), 2–16.
    pub colours: usize,
    /// Alternatives stored per colour combination, 1–64.
    pub alternatives: usize,
    /// Exemplar mixing in `[0, 1]`: each stored tile is `(1 − m)·A + m·B` (renormalised to A's
    /// RMS scale) with `B` a second patch of the same colours, from another exemplar where the
    /// candidates allow.
    pub mixing: f32,
    /// Seed of the alternative choice (hashed with the world tile coordinates).
    pub seed: u64,
}

impl Default for GradientParams {
    fn default() -> Self {
        GradientParams {
            tile: 8,
            colours: 4,
            alternatives: 4,
            mixing: 0.25,
            seed: 0x6772_6164,
        }
    }
}

impl GradientParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<(), DictionaryError> {
        let bad = |m: String| Err(DictionaryError::InvalidParams(m));
        let (lo, hi) = TILE_RANGE;
        if !(lo..=hi).contains(&self.tile) || self.tile % 4 != 0 {
            return bad(format!(
                "tile {} must be a multiple of 4 between {lo} and {hi}",
                self.tile
            ));
        }
        if !(2..=MAX_COLOURS).contains(&self.colours) {
            return bad(format!(
                "colours {} must be between 2 and {MAX_COLOURS}",
                self.colours
            ));
        }
        if !(1..=MAX_ALTERNATIVES).contains(&self.alternatives) {
            return bad(format!(
                "alternatives {} must be between 1 and {MAX_ALTERNATIVES}",
                self.alternatives
            ));
        }
        if !self.mixing.is_finite() || !(0.0..=1.0).contains(&self.mixing) {
            return bad(format!("mixing {} must lie in [0, 1]", self.mixing));
        }
        Ok(())
    }

    /// Colour combinations per layer, `colours²`.
    pub fn combinations(&self) -> usize {
        self.colours * self.colours
    }

    /// Values of one tile, `tile²`.
    pub fn tile_len(&self) -> usize {
        self.tile * self.tile
    }

    /// Values of a whole set: 2 axes × combinations × alternatives × tile², or `None` on
    /// overflow.
    pub fn value_count(&self) -> Option<usize> {
        2usize
            .checked_mul(self.combinations())?
            .checked_mul(self.alternatives)?
            .checked_mul(self.tile_len())
    }
}

/// The gradient component a tile carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// x-gradients, colours on the left and right edges.
    X = 0,
    /// y-gradients, colours on the top and bottom edges.
    Y = 1,
}

/// A built gradient tile set.
#[derive(Clone, Debug, PartialEq)]
pub struct GradientTileSet {
    /// The parameters it was built with.
    pub params: GradientParams,
    /// `[axis][combination][alternative][tile²]`, normalised detail gradients.
    pub tiles: Vec<f32>,
    /// `[axis][combination]`: candidate patches the exemplars offered (0: the combination's
    /// tiles were copied from the nearest combination that had some).
    pub found: Vec<u32>,
}

impl GradientTileSet {
    /// Tile `alt` of colour combination `combo` (`first·C + second`) of `axis`.
    pub fn tile(&self, axis: Axis, combo: usize, alt: usize) -> &[f32] {
        let p = &self.params;
        let n = p.tile_len();
        let i = ((axis as usize * p.combinations() + combo) * p.alternatives + alt) * n;
        &self.tiles[i..i + n]
    }

    /// Checks the parameters, the array lengths and that every value is finite.
    pub fn check_consistency(&self) -> Result<(), String> {
        self.params.validate().map_err(|e| e.to_string())?;
        let want = self
            .params
            .value_count()
            .ok_or_else(|| "tile count overflows".to_string())?;
        if self.tiles.len() != want {
            return Err(format!("{} tile values, expected {want}", self.tiles.len()));
        }
        if self.found.len() != 2 * self.params.combinations() {
            return Err(format!(
                "{} combination counts, expected {}",
                self.found.len(),
                2 * self.params.combinations()
            ));
        }
        if self.tiles.iter().any(|v| !v.is_finite()) {
            return Err("non-finite tile value".into());
        }
        Ok(())
    }
}

/// The error function, Abramowitz & Stegun 7.1.26 (absolute error < 1.5·10⁻⁷), evaluated in
/// `f64` in a fixed order.
fn erf(x: f64) -> f64 {
    let sign = if x < 0.0 { -1.0 } else { 1.0 };
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    sign * (1.0 - poly * math::exp(-x * x))
}

/// The standard normal CDF `Φ`.
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
}

/// The Gaussian-CDF lookup of edge colours: the `C − 1` thresholds `Φ⁻¹(c/C)`.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourTable {
    thresholds: Vec<f32>,
}

impl ColourTable {
    /// The table for `colours` colours (thresholds found by bisection of [`normal_cdf`]).
    pub fn new(colours: usize) -> Self {
        let thresholds = (1..colours)
            .map(|c| {
                let target = c as f64 / colours as f64;
                let (mut lo, mut hi) = (-10.0f64, 10.0f64);
                for _ in 0..80 {
                    let mid = 0.5 * (lo + hi);
                    if normal_cdf(mid) < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                (0.5 * (lo + hi)) as f32
            })
            .collect();
        ColourTable { thresholds }
    }

    /// The colour of normalised gradient `z`: the number of thresholds at or below it (NaN → 0).
    pub fn colour(&self, z: f32) -> usize {
        self.thresholds.iter().take_while(|&&t| t <= z).count()
    }
}

/// A read-only window of a parent plane (row-major), addressed by global coordinates.
#[derive(Clone, Copy, Debug)]
pub struct ParentPlane<'a> {
    /// Values, `rows × cols`, row-major.
    pub data: &'a [f32],
    /// Global row of the first row.
    pub row0: i64,
    /// Global column of the first column.
    pub col0: i64,
    /// Number of columns.
    pub cols: usize,
}

impl ParentPlane<'_> {
    /// The value at global `(row, col)`, which the caller keeps inside the window.
    #[inline]
    pub fn at(&self, row: i64, col: i64) -> f32 {
        self.data[(row - self.row0) as usize * self.cols + (col - self.col0) as usize]
    }
}

/// `⌊a / b⌋` for `b > 0`.
#[inline]
fn floor_div(a: i64, b: i64) -> i64 {
    a.div_euclid(b)
}

/// A tile's colours and scale: `(first edge colour, second edge colour, σ)` for the tile of
/// `axis` with child origin `(x0, y0)` (even) and side `t`. Reads parent rows and columns
/// `[y0/2 − 1, y0/2 + t/2]` and `[x0/2 − 1, x0/2 + t/2]`.
pub fn tile_stats(
    p: &ParentPlane<'_>,
    table: &ColourTable,
    axis: Axis,
    x0: i64,
    y0: i64,
    t: usize,
) -> (usize, usize, f32) {
    let sigma = tile_sigma(p, x0, y0, t);
    let (a, b) = tile_colours(p, table, axis, x0, y0, t, sigma);
    (a, b, sigma)
}

/// The local scale `σ` of the tile with child origin `(x0, y0)` (even) and side `t`: the RMS
/// parent gradient over its `(t/2)²` parent cells, at least `MIN_SIGMA`. The same for both
/// axes' tiles at that origin.
pub fn tile_sigma(p: &ParentPlane<'_>, x0: i64, y0: i64, t: usize) -> f32 {
    let (pc, pr, h) = (x0 / 2, y0 / 2, (t / 2) as i64);
    let mut ss = 0.0f32;
    for r in pr..pr + h {
        for c in pc..pc + h {
            let v = p.at(r, c);
            let dx = p.at(r, c + 1) - v;
            let dy = p.at(r + 1, c) - v;
            ss += dx * dx + dy * dy;
        }
    }
    (ss / (2 * h * h) as f32).sqrt().max(MIN_SIGMA)
}

/// The edge colours `(first, second)` of the tile of `axis` with child origin `(x0, y0)` and
/// side `t`, whose scale is `sigma` ([`tile_sigma`]).
pub fn tile_colours(
    p: &ParentPlane<'_>,
    table: &ColourTable,
    axis: Axis,
    x0: i64,
    y0: i64,
    t: usize,
    sigma: f32,
) -> (usize, usize) {
    let (pc, pr, h) = (x0 / 2, y0 / 2, (t / 2) as i64);
    let inv = 1.0 / (sigma * h as f32);
    let edge = |e: i64| -> usize {
        let mut sum = 0.0f32;
        for k in 0..h {
            sum += match axis {
                Axis::X => p.at(pr + k, e) - p.at(pr + k, e - 1),
                Axis::Y => p.at(e, pc + k) - p.at(e - 1, pc + k),
            };
        }
        table.colour(sum * inv)
    };
    let first = match axis {
        Axis::X => pc,
        Axis::Y => pr,
    };
    (edge(first), edge(first + h))
}

/// Derivative of the cubic Hermite interpolant (central-difference tangents) of `v[0..4]`
/// (samples at −1, 0, 1, 2) at `0` (`half = false`) or `0.5` (`half = true`).
#[inline]
fn hermite_slope(v: [f32; 4], half: bool) -> f32 {
    let m0 = 0.5 * (v[2] - v[0]);
    if half {
        let m1 = 0.5 * (v[3] - v[1]);
        1.5 * (v[2] - v[1]) - 0.25 * (m0 + m1)
    } else {
        m0
    }
}

/// The coarse x-gradient (metres per child pixel) across the child edge `x → x+1` on child row
/// `y`: the Hermite interpolant's derivative along x on the two parent rows around the row,
/// interpolated linearly between them. Reads parent columns `⌊x/2⌋ − 1 ..= ⌊x/2⌋ + 2` and rows
/// `⌊(y−1)/2⌋ ..= ⌊(y−1)/2⌋ + 1`.
#[inline]
pub fn coarse_gx(p: &ParentPlane<'_>, x: i64, y: i64) -> f32 {
    let k = floor_div(x, 2);
    let half = x.rem_euclid(2) == 1;
    let ky = floor_div(y - 1, 2);
    let fy = if y.rem_euclid(2) == 0 { 0.75 } else { 0.25 };
    let row = |r: i64| {
        hermite_slope(
            [p.at(r, k - 1), p.at(r, k), p.at(r, k + 1), p.at(r, k + 2)],
            half,
        )
    };
    0.5 * (row(ky) * (1.0 - fy) + row(ky + 1) * fy)
}

/// The coarse y-gradient across the child edge `y → y+1` on child column `x`
/// ([`coarse_gx`] transposed).
#[inline]
pub fn coarse_gy(p: &ParentPlane<'_>, x: i64, y: i64) -> f32 {
    let k = floor_div(y, 2);
    let half = y.rem_euclid(2) == 1;
    let kx = floor_div(x - 1, 2);
    let fx = if x.rem_euclid(2) == 0 { 0.75 } else { 0.25 };
    let col = |c: i64| {
        hermite_slope(
            [p.at(k - 1, c), p.at(k, c), p.at(k + 1, c), p.at(k + 2, c)],
            half,
        )
    };
    0.5 * (col(kx) * (1.0 - fx) + col(kx + 1) * fx)
}

/// [`coarse_gx`] and [`coarse_gy`] added into `gx` and `gy` at every child pixel of the rows
/// of `cols` pixels starting at `(x0, y0)` (row-major; `gx.len() == gy.len()`), by the same
/// arithmetic, hence the same bits. The Hermite slopes along each parent row are computed once
/// for the four child rows that interpolate them, and those across each parent column once per
/// child row, instead of twice per pixel.
pub fn add_coarse_gradients(
    p: &ParentPlane<'_>,
    (x0, y0): (i64, i64),
    cols: usize,
    gx: &mut [f32],
    gy: &mut [f32],
) {
    let rows = gx.len().checked_div(cols).unwrap_or(0);
    if rows == 0 {
        return;
    }
    // x-slopes along the parent rows the band's child rows interpolate between.
    let r_lo = floor_div(y0 - 1, 2);
    let r_hi = floor_div(y0 + rows as i64 - 2, 2) + 1;
    let mut xs = vec![0.0f32; (r_hi - r_lo + 1) as usize * cols];
    for (ri, srow) in xs.chunks_mut(cols).enumerate() {
        let r = r_lo + ri as i64;
        for (i, s) in srow.iter_mut().enumerate() {
            let x = x0 + i as i64;
            let k = floor_div(x, 2);
            *s = hermite_slope(
                [p.at(r, k - 1), p.at(r, k), p.at(r, k + 1), p.at(r, k + 2)],
                x.rem_euclid(2) == 1,
            );
        }
    }
    // y-slopes across the parent columns the row's child columns interpolate between.
    let c_lo = floor_div(x0 - 1, 2);
    let c_hi = floor_div(x0 + cols as i64 - 2, 2) + 1;
    let mut cs = vec![0.0f32; (c_hi - c_lo + 1) as usize];
    for (ry, (rx, rgy)) in gx.chunks_mut(cols).zip(gy.chunks_mut(cols)).enumerate() {
        let y = y0 + ry as i64;
        let ky = floor_div(y - 1, 2);
        let fy = if y.rem_euclid(2) == 0 { 0.75 } else { 0.25 };
        let a = &xs[(ky - r_lo) as usize * cols..][..cols];
        let b = &xs[(ky + 1 - r_lo) as usize * cols..][..cols];
        for ((v, &sa), &sb) in rx.iter_mut().zip(a).zip(b) {
            *v += 0.5 * (sa * (1.0 - fy) + sb * fy);
        }
        let k = floor_div(y, 2);
        let half = y.rem_euclid(2) == 1;
        for (ci, s) in cs.iter_mut().enumerate() {
            let c = c_lo + ci as i64;
            *s = hermite_slope(
                [p.at(k - 1, c), p.at(k, c), p.at(k + 1, c), p.at(k + 2, c)],
                half,
            );
        }
        for (i, v) in rgy.iter_mut().enumerate() {
            let x = x0 + i as i64;
            let j = (floor_div(x - 1, 2) - c_lo) as usize;
            let fx = if x.rem_euclid(2) == 0 { 0.75 } else { 0.25 };
            *v += 0.5 * (cs[j] * (1.0 - fx) + cs[j + 1] * fx);
        }
    }
}

/// The elevation plane [`build_gradient_tiles`] reads from an exemplar: its values, NaN where
/// the grid is invalid or inside one of the `exclude` windows (held-out evaluation), so that no
/// tile touches them. The one way the command line and the admin API's builds prepare exemplars.
pub fn exemplar_plane(grid: &Grid, exclude: &[PixelWindow]) -> Array2<f32> {
    let excluded = |r: usize, c: usize| {
        exclude.iter().any(|w| {
            r.checked_sub(w.row).is_some_and(|d| d < w.height)
                && c.checked_sub(w.col).is_some_and(|d| d < w.width)
        })
    };
    Array2::from_shape_fn(grid.data.dim(), |(r, c)| {
        if grid.is_valid(r, c) && !excluded(r, c) {
            grid.data[[r, c]]
        } else {
            f32::NAN
        }
    })
}

/// A candidate patch: exemplar, child origin row and column.
type Candidate = (usize, i64, i64);

/// Builds a gradient tile set from exemplar elevation grids (NaN: invalid, windows touching one
/// are skipped). Every tile origin on the `T/2` lattice whose parent footprint lies inside an
/// exemplar with a margin of 2 parent pixels is a candidate; alternative `a` of a combination
/// with `n` candidates is candidate `⌊a·n / A⌋`, mixed with candidate `⌊a·n/A⌋ + n/2` (mod `n`).
/// Combinations without candidates take the tiles of the nearest combination (L1 distance of
/// the colours, ties to the lowest index).
pub fn build_gradient_tiles(
    exemplars: &[Array2<f32>],
    params: &GradientParams,
) -> Result<GradientTileSet, DictionaryError> {
    params.validate()?;
    if exemplars.is_empty() {
        return Err(DictionaryError::InvalidParams("no exemplar given".into()));
    }
    let t = params.tile;
    let ti = t as i64;
    let combos = params.combinations();
    let table = ColourTable::new(params.colours);
    let parents: Vec<Array2<f32>> = exemplars.iter().map(box_down).collect();
    // Candidates per axis and combination, in scan order.
    let mut cands: Vec<Vec<Candidate>> = vec![Vec::new(); 2 * combos];
    for (e, (hi, lo)) in exemplars.iter().zip(&parents).enumerate() {
        let (prow, pcol) = lo.dim();
        let Some(plane) = lo.as_slice() else {
            continue;
        };
        let plane = ParentPlane {
            data: plane,
            row0: 0,
            col0: 0,
            cols: pcol,
        };
        let half = ti / 2;
        let (pr, pc) = (prow as i64, pcol as i64);
        let mut y0 = 4;
        while (y0 + ti) / 2 + 2 <= pr {
            let mut x0 = 4;
            while (x0 + ti) / 2 + 2 <= pc {
                let ok = (y0 / 2 - 2..(y0 + ti) / 2 + 2).all(|r| {
                    (x0 / 2 - 2..(x0 + ti) / 2 + 2)
                        .all(|c| lo[[r as usize, c as usize]].is_finite())
                }) && (y0..=y0 + ti).all(|r| {
                    (x0..=x0 + ti).all(|c| {
                        hi.get((r as usize, c as usize))
                            .is_some_and(|v| v.is_finite())
                    })
                });
                if ok {
                    for axis in [Axis::X, Axis::Y] {
                        let (a, b, _) = tile_stats(&plane, &table, axis, x0, y0, t);
                        cands[axis as usize * combos + a * params.colours + b].push((e, y0, x0));
                    }
                }
                x0 += half;
            }
            y0 += half;
        }
    }
    if (0..2).any(|axis| {
        cands[axis * combos..(axis + 1) * combos]
            .iter()
            .all(Vec::is_empty)
    }) {
        return Err(DictionaryError::NoPatches);
    }
    let found: Vec<u32> = cands
        .iter()
        .map(|c| u32::try_from(c.len()).unwrap_or(u32::MAX))
        .collect();
    let n_tile = params.tile_len();
    let m = params.mixing;
    let renorm = 1.0 / ((1.0 - m) * (1.0 - m) + m * m).sqrt();
    let mut tiles = Vec::with_capacity(params.value_count().unwrap_or(0));
    let mut a_buf = vec![0.0f32; n_tile];
    let mut b_buf = vec![0.0f32; n_tile];
    for axis in [Axis::X, Axis::Y] {
        for combo in 0..combos {
            let src = nearest_filled(&cands[axis as usize * combos..][..combos], combo, params);
            let list = &cands[axis as usize * combos + src];
            let n = list.len();
            for alt in 0..params.alternatives {
                let ia = alt * n / params.alternatives;
                let ib = (ia + n / 2) % n;
                let (ea, ya, xa) = list[ia];
                let (eb, yb, xb) = list[ib];
                detail_tile(
                    &exemplars[ea],
                    &parents[ea],
                    &table,
                    axis,
                    xa,
                    ya,
                    t,
                    &mut a_buf,
                );
                detail_tile(
                    &exemplars[eb],
                    &parents[eb],
                    &table,
                    axis,
                    xb,
                    yb,
                    t,
                    &mut b_buf,
                );
                tiles.extend(
                    a_buf
                        .iter()
                        .zip(&b_buf)
                        .map(|(&a, &b)| ((1.0 - m) * a + m * b) * renorm),
                );
            }
        }
    }
    let set = GradientTileSet {
        params: params.clone(),
        tiles,
        found,
    };
    set.check_consistency()
        .map_err(|e| DictionaryError::Malformed(format!("built set: {e}")))?;
    Ok(set)
}

/// The 2×2 box average of `hi` (an odd last row or column is dropped), with *the* box filter.
fn box_down(hi: &Array2<f32>) -> Array2<f32> {
    let (r, c) = hi.dim();
    let mut lo = Array2::zeros((r / 2, c / 2));
    reduce2x2(hi.view(), lo.view_mut(), box2);
    lo
}

/// The combination nearest to `combo` (L1 distance of the colours, ties to the lowest index)
/// that has candidates; `cands` holds one axis's lists and at least one is non-empty.
fn nearest_filled(cands: &[Vec<Candidate>], combo: usize, params: &GradientParams) -> usize {
    let c = params.colours;
    let (a, b) = (combo / c, combo % c);
    (0..cands.len())
        .filter(|&k| !cands[k].is_empty())
        .min_by_key(|&k| ((k / c).abs_diff(a) + (k % c).abs_diff(b), k))
        .unwrap_or(0)
}

/// The normalised detail gradients of the tile of `axis` at child origin `(x0, y0)` of
/// exemplar `hi` (parent `lo`), into `out` (`t²`).
#[allow(clippy::too_many_arguments)]
fn detail_tile(
    hi: &Array2<f32>,
    lo: &Array2<f32>,
    table: &ColourTable,
    axis: Axis,
    x0: i64,
    y0: i64,
    t: usize,
    out: &mut [f32],
) {
    let data = lo.as_slice().unwrap_or(&[]);
    let plane = ParentPlane {
        data,
        row0: 0,
        col0: 0,
        cols: lo.ncols(),
    };
    let (_, _, sigma) = tile_stats(&plane, table, axis, x0, y0, t);
    let inv = 2.0 / sigma;
    for r in 0..t {
        for c in 0..t {
            let (y, x) = (y0 + r as i64, x0 + c as i64);
            let h = |yy: i64, xx: i64| hi[[yy as usize, xx as usize]];
            let v = match axis {
                Axis::X => h(y, x + 1) - h(y, x) - coarse_gx(&plane, x, y),
                Axis::Y => h(y + 1, x) - h(y, x) - coarse_gy(&plane, x, y),
            };
            out[r * t + c] = v * inv;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_colour_table_splits_the_normal_distribution_evenly() {
        let t = ColourTable::new(4);
        // Φ⁻¹(0.25) = −0.6745, Φ⁻¹(0.5) = 0, Φ⁻¹(0.75) = 0.6745 (standard normal quartiles).
        assert!(
            (t.thresholds[0] + 0.674_49).abs() < 1e-4,
            "{:?}",
            t.thresholds
        );
        assert!(t.thresholds[1].abs() < 1e-6);
        assert_eq!(t.colour(-5.0), 0);
        assert_eq!(t.colour(-0.5), 1);
        assert_eq!(t.colour(0.1), 2);
        assert_eq!(t.colour(3.0), 3);
        assert_eq!(t.colour(f32::NAN), 0);
    }

    #[test]
    fn shared_coarse_gradients_equal_the_per_pixel_ones_bit_for_bit() {
        let (rows, cols) = (23usize, 29usize);
        let data: Vec<f32> = (0..rows * cols)
            .map(|i| ((i * 7919) % 113) as f32 * 1.37 - 40.0 + math::sinf(i as f32) * 3.0)
            .collect();
        let p = ParentPlane {
            data: &data,
            row0: -5,
            col0: 3,
            cols,
        };
        // Odd and even origins, several widths and heights, inside the plane's reach.
        for (x0, y0, w, h) in [
            (10i64, -1i64, 17usize, 8usize),
            (9, 2, 20, 5),
            (12, 0, 1, 1),
        ] {
            let mut gx = vec![0.5f32; w * h];
            let mut gy = vec![-0.25f32; w * h];
            add_coarse_gradients(&p, (x0, y0), w, &mut gx, &mut gy);
            for r in 0..h {
                for c in 0..w {
                    let (x, y) = (x0 + c as i64, y0 + r as i64);
                    assert_eq!(
                        gx[r * w + c].to_bits(),
                        (0.5 + coarse_gx(&p, x, y)).to_bits()
                    );
                    assert_eq!(
                        gy[r * w + c].to_bits(),
                        (-0.25 + coarse_gy(&p, x, y)).to_bits()
                    );
                }
            }
        }
    }

    #[test]
    fn hermite_slopes_of_a_cubic_by_hand() {
        // Samples of x² at −1, 0, 1, 2: tangents (1 − 1)/2 = 0 at 0, (4 − 0)/2 = 2 at 1; the
        // Hermite derivative at 0.5 is 1.5·1 − 0.25·2 = 1 (= d/dx x² at 0.5).
        assert_eq!(hermite_slope([1.0, 0.0, 1.0, 4.0], false), 0.0);
        assert_eq!(hermite_slope([1.0, 0.0, 1.0, 4.0], true), 1.0);
    }

    #[test]
    fn bad_parameters_are_named() {
        for (p, word) in [
            (
                GradientParams {
                    tile: 6,
                    ..Default::default()
                },
                "tile",
            ),
            (
                GradientParams {
                    colours: 1,
                    ..Default::default()
                },
                "colours",
            ),
            (
                GradientParams {
                    alternatives: 0,
                    ..Default::default()
                },
                "alternatives",
            ),
            (
                GradientParams {
                    mixing: f32::NAN,
                    ..Default::default()
                },
                "mixing",
            ),
        ] {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(word), "{e}");
        }
    }
}
