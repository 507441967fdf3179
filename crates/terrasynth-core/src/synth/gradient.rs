//! The gradient-domain amplifier (DESIGN.md method 3, issue #20): one ×2 level built from a
//! gradient tile set ([`crate::dictionary::gradient_tiles`]) instead of a dictionary.
//!
//! On the level's global pixel plane, two layers of `T × T` tiles stand on lattices staggered by
//! `T/2` in both directions (layer `k` has origins `(i·T + k·T/2, j·T + k·T/2)`). Each tile of
//! each layer carries an x-gradient tile and a y-gradient tile: the x-tile's colours are those of
//! the parent's x-gradient across its left and right edges, the y-tile's those across its top and
//! bottom edges ([`tile_stats`]: Gaussian-CDF lookup of the gradient over the local scale `σ`);
//! among the alternatives of that colour combination one is picked by hashing the world tile
//! coordinates `(i, j)` with the set's seed, the layer and the axis. Its values are scaled by
//! `σ/2` and weighted along the constrained axis by the Hermite window
//! `S(1 − |2u − 1|)`, `S(t) = 3t² − 2t³` (edge smoothing: zero on the constrained edges, and the
//! two staggered layers sum to 1). The target gradient field is the parent's Hermite-interpolant
//! gradient ([`coarse_gx`], [`coarse_gy`]: the preconditioning; computed row by row with shared
//! slopes by [`add_coarse_gradients`]) plus that detail.
//!
//! [`tile_stats`]: crate::dictionary::gradient_tiles::tile_stats
//! [`coarse_gx`]: crate::dictionary::gradient_tiles::coarse_gx
//! [`coarse_gy`]: crate::dictionary::gradient_tiles::coarse_gy
//!
//! Heights are reconstructed per `T × T` block by the precomputed Poisson operator
//! ([`Reconstruction`]) against the parent's `(T/2)²` control points under the block, so every
//! 2×2 box average reproduces its parent pixel up to rounding. A block knows nothing of the
//! gradients across its edges, so its border pixels are its least reliable: four block
//! lattices staggered by `T/2` (origins `(i·T + a, j·T + b)`, `a, b ∈ {0, T/2}`) are
//! reconstructed and blended with weights `w(x)·w(y)` constant on each parent cell
//! (`cell_weights`: a Hermite window, smallest on a block's border cells, the two lattices of an
//! axis summing to 1), which keeps the box averages and hides the blocks' edges (without it, the
//! steps across block edges were 1.6× the mean step at zoom 11 of the default base).
//! Every value is a function of global coordinates only: any window gives a pixel the same
//! value, bit for bit, whatever the thread count. Extra layers of the parent are reconstructed
//! with the same operator from their coarse gradients alone (no detail).

use std::sync::Arc;

use ndarray::Array2;
use rayon::prelude::*;

use super::error::SynthError;
use super::field::{Field, Window};
use super::gradient_solve::{input_count, Reconstruction};
use crate::dictionary::gradient_tiles::{
    add_coarse_gradients, tile_colours, tile_sigma, Axis, ColourTable, GradientTileSet, ParentPlane,
};
use crate::dictionary::rng::hash2;

/// A gradient-domain amplification level bound to a tile set.
#[derive(Debug, Clone)]
pub struct GradientAmplifier {
    set: Arc<GradientTileSet>,
    recon: Arc<Reconstruction>,
    table: ColourTable,
    /// `T` weights of the Hermite edge window by tile-local edge index.
    window: Vec<f32>,
    /// `T/2` blending weights of a reconstruction block by block-local parent cell
    /// ([`cell_weights`]).
    weights: Vec<f32>,
    /// [`GradientAmplifier::weights`] by block-local child pixel (`T` values, each cell's
    /// weight twice), so that blending reads them contiguously.
    pixel_weights: Vec<f32>,
    with_layers: bool,
}

/// Scratch of one block: the reconstruction inputs and the block's heights.
#[derive(Default)]
struct BlockScratch {
    inputs: Vec<f32>,
    out: Vec<f32>,
}

impl GradientAmplifier {
    /// Prepares an amplifier (precomputes the reconstruction operator of the set's tile size).
    pub fn new(set: Arc<GradientTileSet>) -> Result<Self, SynthError> {
        set.check_consistency().map_err(SynthError::BadWindow)?;
        let t = set.params.tile;
        let recon = Arc::new(Reconstruction::new(t)?);
        let window = (0..t)
            .map(|c| {
                let u = (c + 1) as f32 / t as f32;
                let s = 1.0 - (2.0 * u - 1.0).abs();
                s * s * (3.0 - 2.0 * s)
            })
            .collect();
        let weights = cell_weights(t);
        Ok(GradientAmplifier {
            pixel_weights: (0..t).map(|c| weights[c / 2]).collect(),
            weights,
            table: ColourTable::new(set.params.colours),
            set,
            recon,
            window,
            with_layers: true,
        })
    }

    /// This amplifier, reconstructing elevation only (the parent's extra layers are dropped).
    pub fn without_layers(mut self) -> Self {
        self.with_layers = false;
        self
    }

    /// The tile set this level uses.
    pub fn tile_set(&self) -> &GradientTileSet {
        &self.set
    }

    /// Tile side `T`.
    fn t(&self) -> i64 {
        self.set.params.tile as i64
    }

    /// The origins' offsets of the four reconstruction lattices: `(0, 0)`, `(T/2, 0)`,
    /// `(0, T/2)`, `(T/2, T/2)`, in the order their contributions are summed.
    fn lattices(&self) -> [(i64, i64); 4] {
        let h = self.t() / 2;
        [(0, 0), (h, 0), (0, h), (h, h)]
    }

    /// Block indices `[i0, i1) × [j0, j1)` of the lattice with origin offset `(ox, oy)` (block
    /// `(i, j)` has its origin at `(i·T + ox, j·T + oy)`) covering `out`.
    fn blocks(&self, out: Window, ox: i64, oy: i64) -> (i64, i64, i64, i64) {
        let t = self.t();
        (
            (out.col0 - ox).div_euclid(t),
            (out.col1() - 1 - ox).div_euclid(t) + 1,
            (out.row0 - oy).div_euclid(t),
            (out.row1() - 1 - oy).div_euclid(t) + 1,
        )
    }

    /// The parent window that [`GradientAmplifier::amplify`] needs for output window `out`: the
    /// parent pixels under the blocks of the four lattices covering `out`, widened by
    /// `T/4 + 2` (the staggered tiles' reach and the Hermite tangents).
    pub fn parent_window_for(&self, out: Window) -> Window {
        let m = self.t() / 4 + 2;
        let r = self.block_region(out);
        Window::from_bounds(
            r.col0.div_euclid(2) - m,
            r.row0.div_euclid(2) - m,
            r.col1().div_euclid(2) + m,
            r.row1().div_euclid(2) + m,
        )
    }

    /// Adds the detail gradients of every tile of both layers overlapping the rectangle of
    /// `cols` × `dx.len() / cols` child pixels at `(x0, y0)` into `dx` / `dy` (row-major, zeroed
    /// by the caller). A pixel gets its layer-0 tile's value, then its layer-1 tile's.
    fn add_detail(
        &self,
        p: &ParentPlane<'_>,
        (x0, y0): (i64, i64),
        cols: usize,
        dx: &mut [f32],
        dy: &mut [f32],
    ) {
        let params = &self.set.params;
        let t = self.t();
        let tu = params.tile;
        let alts = params.alternatives as u64;
        let (w, h) = (cols as i64, (dx.len() / cols.max(1)) as i64);
        if w == 0 || h == 0 {
            return;
        }
        for layer in 0..2i64 {
            let o = layer * t / 2;
            let (i0, i1) = ((x0 - o).div_euclid(t), (x0 + w - 1 - o).div_euclid(t));
            let (j0, j1) = ((y0 - o).div_euclid(t), (y0 + h - 1 - o).div_euclid(t));
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (tx, ty) = (i * t + o, j * t + o);
                    // The overlap of tile and rectangle, in rectangle coordinates.
                    let (c0, c1) = ((tx - x0).max(0), (tx + t - x0).min(w));
                    let (r0, r1) = ((ty - y0).max(0), (ty + t - y0).min(h));
                    let sigma = tile_sigma(p, tx, ty, tu);
                    for axis in [Axis::X, Axis::Y] {
                        let (a, b) = tile_colours(p, &self.table, axis, tx, ty, tu, sigma);
                        let salt = (layer as u64) * 2 + axis as u64 + 1;
                        let hsh = hash2(
                            params.seed.wrapping_add(salt.wrapping_mul(0x9E37_79B9)),
                            i,
                            j,
                        );
                        let alt = (hsh % alts) as usize;
                        let tile = self.set.tile(axis, a * params.colours + b, alt);
                        let scale = 0.5 * sigma;
                        for r in r0..r1 {
                            let tr = (r + y0 - ty) as usize;
                            let trow = &tile[tr * tu..(tr + 1) * tu];
                            let k0 = r as usize * cols;
                            let tc0 = (c0 + x0 - tx) as usize;
                            let n = (c1 - c0) as usize;
                            let src = &trow[tc0..tc0 + n];
                            match axis {
                                // Weighted along x: by column.
                                Axis::X => {
                                    let dst = &mut dx[k0 + c0 as usize..][..n];
                                    let wts = &self.window[tc0..tc0 + n];
                                    for ((d, &v), &w) in dst.iter_mut().zip(src).zip(wts) {
                                        *d += (v * scale) * w;
                                    }
                                }
                                // Weighted along y: one weight for the row.
                                Axis::Y => {
                                    let dst = &mut dy[k0 + c0 as usize..][..n];
                                    let w = self.window[tr];
                                    for (d, &v) in dst.iter_mut().zip(src) {
                                        *d += (v * scale) * w;
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The target gradients (coarse plus, with `detail`, the tiles' detail) at every child pixel
    /// of `region`: `gx` across the edge `x → x+1`, `gy` across `y → y+1`, row-major. Computed
    /// in bands of `T` rows in parallel (each pixel's value does not depend on the band).
    fn gradient_planes(
        &self,
        p: &ParentPlane<'_>,
        region: Window,
        detail: bool,
    ) -> (Vec<f32>, Vec<f32>) {
        let cols = region.cols;
        let band = self.set.params.tile * cols.max(1);
        let mut gx = vec![0.0f32; region.len()];
        let mut gy = vec![0.0f32; region.len()];
        gx.par_chunks_mut(band)
            .zip(gy.par_chunks_mut(band))
            .enumerate()
            .for_each(|(b, (gx, gy))| {
                let y0 = region.row0 + (b * self.set.params.tile) as i64;
                if detail {
                    self.add_detail(p, (region.col0, y0), cols, gx, gy);
                }
                add_coarse_gradients(p, (region.col0, y0), cols, gx, gy);
            });
        (gx, gy)
    }

    /// The heights of block `(bx, by)` into `s.out`, from the gradient planes over `region`.
    fn block(
        &self,
        p: &ParentPlane<'_>,
        planes: (&[f32], &[f32], Window),
        bx: i64,
        by: i64,
        s: &mut BlockScratch,
    ) {
        let (gx, gy, region) = planes;
        let tu = self.set.params.tile;
        let t = tu as i64;
        let at = |x: i64, y: i64| {
            ((y - region.row0) as usize) * region.cols + (x - region.col0) as usize
        };
        s.inputs.clear();
        for r in 0..t {
            let k = at(bx, by + r);
            s.inputs.extend_from_slice(&gx[k..k + tu - 1]);
        }
        for r in 0..t - 1 {
            let k = at(bx, by + r);
            s.inputs.extend_from_slice(&gy[k..k + tu]);
        }
        for r in 0..t / 2 {
            for c in 0..t / 2 {
                s.inputs.push(p.at(by / 2 + r, bx / 2 + c));
            }
        }
        debug_assert_eq!(s.inputs.len(), input_count(tu));
        s.out.resize(tu * tu, 0.0);
        self.recon.apply(&s.inputs, &mut s.out);
    }

    /// The region of the child plane the blocks of the four lattices covering `out` span.
    fn block_region(&self, out: Window) -> Window {
        let t = self.t();
        let (mut x0, mut y0, mut x1, mut y1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
        for (ox, oy) in self.lattices() {
            let (i0, i1, j0, j1) = self.blocks(out, ox, oy);
            x0 = x0.min(i0 * t + ox);
            x1 = x1.max(i1 * t + ox);
            y0 = y0.min(j0 * t + oy);
            y1 = y1.max(j1 * t + oy);
        }
        Window::from_bounds(x0, y0, x1, y1)
    }

    /// Reconstructs window `out` of plane `p`: the target gradients once over the blocks'
    /// region, then on each of the four staggered block lattices in turn, block row by block
    /// row (in parallel; each block is independent), adding each block's heights weighted by
    /// the lattices' blending weights ([`cell_weights`]). The contributions of a pixel are
    /// summed in lattice order, whatever the thread count.
    fn reconstruct(&self, p: &ParentPlane<'_>, out: Window, detail: bool) -> Array2<f32> {
        let t = self.t();
        let tu = self.set.params.tile;
        let cols = out.cols;
        let region = self.block_region(out);
        let (gx, gy) = self.gradient_planes(p, region, detail);
        let planes = (&gx[..], &gy[..], region);
        let mut data = vec![0.0f32; out.len()];
        for (ox, oy) in self.lattices() {
            let (i0, i1, j0, j1) = self.blocks(out, ox, oy);
            // Output rows grouped by block row: the first group may be shorter.
            let first_rows = ((j0 + 1) * t + oy - out.row0).min(out.rows as i64) as usize;
            let mut groups: Vec<(i64, &mut [f32])> = Vec::new();
            let (head, mut rest) = data.split_at_mut(first_rows * cols);
            groups.push((j0, head));
            for j in j0 + 1..j1 {
                let take = (tu * cols).min(rest.len());
                let (g, r) = rest.split_at_mut(take);
                groups.push((j, g));
                rest = r;
            }
            groups
                .into_par_iter()
                .for_each_init(BlockScratch::default, |s, (j, rows)| {
                    let by = j * t + oy;
                    for i in i0..i1 {
                        let bx = i * t + ox;
                        self.block(p, planes, bx, by, s);
                        let c0 = bx.max(out.col0);
                        let c1 = (bx + t).min(out.col1());
                        for (rr, orow) in rows.chunks_mut(cols.max(1)).enumerate() {
                            let y = by.max(out.row0) + rr as i64;
                            let br = (y - by) as usize;
                            let wy = self.weights[br / 2];
                            let src = &s.out[br * tu..(br + 1) * tu];
                            let dst = &mut orow[(c0 - out.col0) as usize..(c1 - out.col0) as usize];
                            let b0 = (c0 - bx) as usize;
                            let wx = &self.pixel_weights[b0..b0 + dst.len()];
                            for ((d, &w), &v) in dst.iter_mut().zip(wx).zip(&src[b0..]) {
                                *d += (wy * w) * v;
                            }
                        }
                    }
                });
        }
        Array2::from_shape_vec((out.rows, out.cols), data).unwrap_or_default()
    }

    /// Amplifies window `out` of this level from `parent`, which must cover
    /// [`GradientAmplifier::parent_window_for`]`(out)`. `_parent_cell_m` is accepted for the
    /// amplifiers' common shape (the tiles are scaled by the parent's own gradients). The result
    /// depends only on the parent's values, the tile set and `out`'s pixels.
    pub fn amplify(
        &self,
        parent: &Field,
        out: Window,
        _parent_cell_m: f32,
    ) -> Result<Field, SynthError> {
        if out.is_empty() || out.len() > (1usize << 30) {
            return Err(SynthError::BadWindow(format!(
                "{out} has {} pixels",
                out.len()
            )));
        }
        let needed = self.parent_window_for(out);
        let too_small = || SynthError::ParentTooSmall {
            given: parent.window.to_string(),
            needed: needed.to_string(),
        };
        let parent = parent.crop(needed).ok_or_else(too_small)?;
        if parent.elevation.iter().any(|v| !v.is_finite()) {
            return Err(SynthError::NonFinite);
        }
        let elev = plane_data(&parent.elevation);
        let elevation = self.reconstruct(&plane(&elev, needed), out, true);
        let mut layers = Vec::new();
        if self.with_layers {
            for (name, a) in &parent.layers {
                if a.iter().any(|v| !v.is_finite()) {
                    return Err(SynthError::NonFinite);
                }
                let d = plane_data(a);
                layers.push((
                    name.clone(),
                    self.reconstruct(&plane(&d, needed), out, false),
                ));
            }
        }
        Ok(Field {
            window: out,
            elevation,
            layers,
        })
    }
}

/// The blending weights of a reconstruction block of side `t` along one axis, by block-local
/// parent cell `k ∈ [0, t/2)`: the Hermite window `S(1 − |2u − 1|)` at the cell's centre
/// `u = (k + ½)/(t/2)`. A cell's weights in the two lattices staggered by `t/2` (`t/4` cells)
/// sum to 1 (`S(s) + S(1 − s) = 1`), so the four lattices' products `w(x)·w(y)` sum to 1; they
/// are constant over each 2×2 child block, so blending keeps every box average; and a block's
/// border cells weigh least, so a block's edge never shows as a seam.
fn cell_weights(t: usize) -> Vec<f32> {
    let h = t / 2;
    (0..h)
        .map(|k| {
            let u = (k as f32 + 0.5) / h as f32;
            let s = 1.0 - (2.0 * u - 1.0).abs();
            s * s * (3.0 - 2.0 * s)
        })
        .collect()
}

/// The values of `a` in row-major order.
fn plane_data(a: &Array2<f32>) -> Vec<f32> {
    a.iter().copied().collect()
}

/// `data` (row-major over window `w`) as a parent plane.
fn plane(data: &[f32], w: Window) -> ParentPlane<'_> {
    ParentPlane {
        data,
        row0: w.row0,
        col0: w.col0,
        cols: w.cols,
    }
}
