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
//! gradient ([`coarse_gx`], [`coarse_gy`]: the preconditioning) plus that detail.
//!
//! Heights are reconstructed per `T × T` block of the level's lattice (origins `(i·T, j·T)`) by
//! the precomputed Poisson operator ([`Reconstruction`]) against the parent's `(T/2)²` control
//! points under the block, so every 2×2 box average reproduces its parent pixel up to rounding.
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
    coarse_gx, coarse_gy, tile_stats, Axis, ColourTable, GradientTileSet, ParentPlane,
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
    with_layers: bool,
}

/// Scratch of one block: the reconstruction inputs, detail planes and the block's heights.
#[derive(Default)]
struct BlockScratch {
    inputs: Vec<f32>,
    dx: Vec<f32>,
    dy: Vec<f32>,
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
        Ok(GradientAmplifier {
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

    /// Block indices `[i0, i1) × [j0, j1)` covering `out`.
    fn blocks(&self, out: Window) -> (i64, i64, i64, i64) {
        let t = self.t();
        (
            out.col0.div_euclid(t),
            (out.col1() - 1).div_euclid(t) + 1,
            out.row0.div_euclid(t),
            (out.row1() - 1).div_euclid(t) + 1,
        )
    }

    /// The parent window that [`GradientAmplifier::amplify`] needs for output window `out`: the
    /// parent pixels under the blocks covering `out`, widened by `T/4 + 2` (the staggered tiles'
    /// reach and the Hermite tangents).
    pub fn parent_window_for(&self, out: Window) -> Window {
        let t = self.t();
        let m = t / 4 + 2;
        let (i0, i1, j0, j1) = self.blocks(out);
        Window::from_bounds(
            i0 * t / 2 - m,
            j0 * t / 2 - m,
            i1 * t / 2 + m,
            j1 * t / 2 + m,
        )
    }

    /// Adds the detail gradients of every tile of both layers overlapping block `(X0, Y0)` into
    /// `dx` / `dy` (`T²`, zeroed by the caller).
    fn add_detail(&self, p: &ParentPlane<'_>, bx: i64, by: i64, dx: &mut [f32], dy: &mut [f32]) {
        let params = &self.set.params;
        let t = self.t();
        let tu = params.tile;
        let alts = params.alternatives as u64;
        for layer in 0..2i64 {
            let o = layer * t / 2;
            let (i0, i1) = ((bx - o).div_euclid(t), (bx + t - 1 - o).div_euclid(t));
            let (j0, j1) = ((by - o).div_euclid(t), (by + t - 1 - o).div_euclid(t));
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (x0, y0) = (i * t + o, j * t + o);
                    // The overlap of tile and block, in block-local coordinates.
                    let (c0, c1) = ((x0 - bx).max(0), (x0 + t - bx).min(t));
                    let (r0, r1) = ((y0 - by).max(0), (y0 + t - by).min(t));
                    for axis in [Axis::X, Axis::Y] {
                        let (a, b, sigma) = tile_stats(p, &self.table, axis, x0, y0, tu);
                        let salt = (layer as u64) * 2 + axis as u64 + 1;
                        let h = hash2(
                            params.seed.wrapping_add(salt.wrapping_mul(0x9E37_79B9)),
                            i,
                            j,
                        );
                        let alt = (h % alts) as usize;
                        let tile = self.set.tile(axis, a * params.colours + b, alt);
                        let scale = 0.5 * sigma;
                        for r in r0..r1 {
                            let tr = (r + by - y0) as usize;
                            for c in c0..c1 {
                                let tc = (c + bx - x0) as usize;
                                let v = tile[tr * tu + tc] * scale;
                                let k = r as usize * tu + c as usize;
                                match axis {
                                    Axis::X => dx[k] += v * self.window[tc],
                                    Axis::Y => dy[k] += v * self.window[tr],
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The heights of block `(bx, by)` of plane `p` into `s.out` (with detail when `detail`).
    fn block(&self, p: &ParentPlane<'_>, bx: i64, by: i64, detail: bool, s: &mut BlockScratch) {
        let tu = self.set.params.tile;
        let t = tu as i64;
        let n = tu * tu;
        s.dx.clear();
        s.dx.resize(n, 0.0);
        s.dy.clear();
        s.dy.resize(n, 0.0);
        if detail {
            self.add_detail(p, bx, by, &mut s.dx, &mut s.dy);
        }
        s.inputs.clear();
        for r in 0..t {
            for c in 0..t - 1 {
                let k = (r * t + c) as usize;
                s.inputs.push(coarse_gx(p, bx + c, by + r) + s.dx[k]);
            }
        }
        for r in 0..t - 1 {
            for c in 0..t {
                let k = (r * t + c) as usize;
                s.inputs.push(coarse_gy(p, bx + c, by + r) + s.dy[k]);
            }
        }
        for r in 0..t / 2 {
            for c in 0..t / 2 {
                s.inputs.push(p.at(by / 2 + r, bx / 2 + c));
            }
        }
        debug_assert_eq!(s.inputs.len(), input_count(tu));
        s.out.resize(n, 0.0);
        self.recon.apply(&s.inputs, &mut s.out);
    }

    /// Reconstructs window `out` of plane `p` block row by block row (in parallel; each block
    /// is independent).
    fn reconstruct(&self, p: &ParentPlane<'_>, out: Window, detail: bool) -> Array2<f32> {
        let t = self.t();
        let tu = self.set.params.tile;
        let (i0, i1, j0, j1) = self.blocks(out);
        let cols = out.cols;
        let mut data = vec![0.0f32; out.len()];
        // Output rows grouped by block row: the first group may be shorter.
        let first_rows = ((j0 + 1) * t - out.row0).min(out.rows as i64) as usize;
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
                let by = j * t;
                for i in i0..i1 {
                    let bx = i * t;
                    self.block(p, bx, by, detail, s);
                    let c0 = bx.max(out.col0);
                    let c1 = (bx + t).min(out.col1());
                    for (rr, orow) in rows.chunks_mut(cols.max(1)).enumerate() {
                        let y = by.max(out.row0) + rr as i64;
                        let br = (y - by) as usize;
                        let src =
                            &s.out[br * tu + (c0 - bx) as usize..br * tu + (c1 - bx) as usize];
                        orow[(c0 - out.col0) as usize..(c1 - out.col0) as usize]
                            .copy_from_slice(src);
                    }
                }
            });
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
