//! Drainage directions across flats (Barnes, Lehman & Mulla 2014, "An efficient assignment of
//! drainage direction over flat surfaces in raster digital elevation models"), for a grid filled
//! to its spill levels ([`super::priority_flood_fill_flat`]).
//!
//! A flat cell has no lower neighbour, is not on the grid's border and has no NaN neighbour (the
//! border and nodata are outlets; their cells keep no receiver). Over each flat two breadth-first
//! distances are combined: towards the flat's *low edges* (its equal-valued neighbours that
//! drain: a cell with a receiver, or an outlet) and away from its *high edges* (its cells next to
//! higher ground). The mask `2 · towards + (most − away)` falls strictly along the way to a low
//! edge, so every flat drains without cycles, and its flow converges into the middle of a flat
//! valley floor instead of running down parallel lines as the ε-gradient of
//! [`super::priority_flood_fill`] makes it do. Each flat cell takes the steepest descent of the
//! mask over the metric distance to the neighbour (first direction in [`D8_OFFSETS`] order on
//! ties); a low edge counts as mask 0.
//!
//! **Open flats.** The away distance is a property of a whole flat: a grid that holds only part
//! of a flat would give its cells other directions than a grid that holds all of it. A flat that
//! touches the grid's border ring (a cell next to the border) or whose bounding box spans more
//! than `max_span` cells in rows or columns is *open* and drains towards its low edges only
//! (mask `2 · towards`, much as the ε-gradient does). The drainage layer routes each tile over the
//! tile plus a halo and passes the halo as `max_span`: a flat resolved in full that reaches a
//! tile's border lies wholly inside the regions of both tiles beside that border, so both give
//! its cells the same directions.
//!
//! **Guides.** An open flat holding *guide* cells (the drainage layer's: cells whose parent-level
//! pixel carries a river) drains towards its low edges and towards its guide cells: mask
//! `2 · towards + guided`, with `guided` the breadth-first distance from the flat's guide cells.
//! Like the away distance it changes by at most 1 from a cell to its neighbour, so every cell
//! still has a lower neighbour on the way to a low edge; unlike it, it needs no whole-flat
//! maximum. The flow converges on the parent level's channel across the flat and follows it.
//!
//! [`super::naive::resolve_flats`] computes the same by repeated relaxation; the property tests
//! compare the two.

use std::collections::VecDeque;

use ndarray::Array2;

use super::common::{dir_geometry, values, D8_OFFSETS};
use super::flow::{d8_receivers, D8_NONE};
use crate::raster::CellSizes;

/// D8 receivers of `filled` (a grid without depressions, flats left flat): the steepest descent
/// ([`d8_receivers`]) where a cell has a lower neighbour, and across flats the direction of the
/// combined gradient ([`resolve_flats`]; open flats, see the module's documentation, towards
/// their low edges and their `guide` cells only).
pub fn d8_receivers_over_flats(
    filled: &Array2<f32>,
    cs: &CellSizes,
    max_span: usize,
    guide: Option<&dyn Fn(usize, usize) -> bool>,
) -> Array2<u8> {
    let mut receivers = d8_receivers(filled, cs);
    resolve_flats(filled, cs, max_span, guide, &mut receivers);
    receivers
}

/// Gives every flat cell of `filled` (see the module's documentation) a receiver in `receivers`
/// (the D8 receivers of `filled`), pointing down the combined gradient. A flat cell that no low
/// edge can be reached from (none, after a fill) keeps [`D8_NONE`]. Flats that touch the border
/// ring or span more than `max_span` cells drain towards their low edges only, and towards the
/// `guide` cells they hold (`guide(row, col)`, asked of flat cells only).
pub fn resolve_flats(
    filled: &Array2<f32>,
    cs: &CellSizes,
    max_span: usize,
    guide: Option<&dyn Fn(usize, usize) -> bool>,
    receivers: &mut Array2<u8>,
) {
    let (rows, cols) = filled.dim();
    if rows < 3 || cols < 3 || receivers.dim() != (rows, cols) {
        return;
    }
    let z = values(filled);
    let grid = FlatGrid::new(&z, &values(receivers), rows, cols);
    if grid.cells.is_empty() {
        return;
    }
    let geo = dir_geometry(cs, rows);
    let mask = grid.mask(max_span, guide);
    if receivers.as_slice().is_none() {
        *receivers = receivers.as_standard_layout().into_owned();
    }
    if let Some(out) = receivers.as_slice_mut() {
        grid.assign_directions(&mask, &geo.dist, out);
    }
}

/// The flat cells of a grid: no receiver, finite, not on the border, no NaN neighbour. Every
/// flat cell is inside the grid, so its eight neighbours are at fixed index offsets.
struct FlatGrid<'a> {
    z: &'a [f32],
    rows: usize,
    cols: usize,
    /// Index offset of the neighbour in each direction of [`D8_OFFSETS`].
    offsets: [isize; 8],
    /// Whether each cell is flat.
    is_flat: Vec<bool>,
    /// The flat cells in index order.
    cells: Vec<usize>,
}

impl<'a> FlatGrid<'a> {
    fn new(z: &'a [f32], rcv: &[u8], rows: usize, cols: usize) -> Self {
        let offsets = D8_OFFSETS.map(|(dr, dc)| dr * cols as isize + dc);
        let mut is_flat = vec![false; rows * cols];
        let mut cells = Vec::new();
        for r in 1..rows - 1 {
            for i in r * cols + 1..(r + 1) * cols - 1 {
                if rcv[i] != D8_NONE || !z[i].is_finite() {
                    continue;
                }
                if offsets
                    .iter()
                    .all(|&o| !z[i.wrapping_add_signed(o)].is_nan())
                {
                    is_flat[i] = true;
                    cells.push(i);
                }
            }
        }
        FlatGrid {
            z,
            rows,
            cols,
            offsets,
            is_flat,
            cells,
        }
    }

    /// The neighbours of flat cell `i`, in direction order.
    fn neighbours(&self, i: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.offsets
            .iter()
            .enumerate()
            .map(move |(d, &o)| (d, i.wrapping_add_signed(o)))
    }

    /// Equal-valued flat neighbours of flat cell `i`, in direction order.
    fn flat_neighbours(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.neighbours(i)
            .map(|(_, n)| n)
            .filter(move |&n| self.is_flat[n] && self.z[n] == self.z[i])
    }

    /// The flat cells with a neighbour for which `is_edge(here, there, there_flat)` holds.
    fn seeds(&self, is_edge: impl Fn(f32, f32, bool) -> bool) -> Vec<usize> {
        self.cells
            .iter()
            .copied()
            .filter(|&i| {
                self.neighbours(i)
                    .any(|(_, n)| is_edge(self.z[i], self.z[n], self.is_flat[n]))
            })
            .collect()
    }

    /// Breadth-first distances through equal-valued flat cells (1 at the seeds, 0 where
    /// unreached).
    fn distances(&self, seeds: &[usize]) -> Vec<u32> {
        let mut dist = vec![0u32; self.z.len()];
        let mut queue = VecDeque::with_capacity(seeds.len());
        for &s in seeds {
            dist[s] = 1;
            queue.push_back(s);
        }
        while let Some(i) = queue.pop_front() {
            for m in self.flat_neighbours(i) {
                if dist[m] == 0 {
                    dist[m] = dist[i] + 1;
                    queue.push_back(m);
                }
            }
        }
        dist
    }

    /// The combined mask of every flat cell: `2 · towards + away` (`2 · towards + guided` on
    /// open flats), 0 elsewhere and on flat cells no low edge reaches.
    fn mask(&self, max_span: usize, guide: Option<&dyn Fn(usize, usize) -> bool>) -> Vec<u32> {
        let (rows, cols) = (self.rows, self.cols);
        // Towards lower: from the flat cells next to an equal-valued cell that drains.
        let towards = self.distances(&self.seeds(|here, there, flat| there == here && !flat));
        // Away from higher: from the flat cells next to higher ground.
        let away = self.distances(&self.seeds(|here, there, _| there > here));
        // Towards the guide cells (0 everywhere on a flat without one).
        let guided = match guide {
            Some(g) => {
                let seeds: Vec<usize> = self
                    .cells
                    .iter()
                    .copied()
                    .filter(|&i| g(i / cols, i % cols))
                    .collect();
                self.distances(&seeds)
            }
            None => vec![0; rows * cols],
        };
        // The largest away distance of each flat (a connected set of equal-valued flat cells),
        // or `None` for an open flat (touching the border ring or spanning more than
        // `max_span`).
        let mut label = vec![u32::MAX; rows * cols];
        let mut most: Vec<Option<u32>> = Vec::new();
        let mut queue = VecDeque::new();
        for &start in &self.cells {
            if label[start] != u32::MAX {
                continue;
            }
            let id = most.len() as u32;
            let mut m = 0;
            let (mut r_lo, mut r_hi, mut c_lo, mut c_hi) = (usize::MAX, 0, usize::MAX, 0);
            label[start] = id;
            queue.push_back(start);
            while let Some(i) = queue.pop_front() {
                m = m.max(away[i]);
                let (r, c) = (i / cols, i % cols);
                (r_lo, r_hi, c_lo, c_hi) = (r_lo.min(r), r_hi.max(r), c_lo.min(c), c_hi.max(c));
                for n in self.flat_neighbours(i) {
                    if label[n] == u32::MAX {
                        label[n] = id;
                        queue.push_back(n);
                    }
                }
            }
            let touches = r_lo <= 1 || c_lo <= 1 || r_hi + 2 >= rows || c_hi + 2 >= cols;
            let wide = r_hi - r_lo + 1 > max_span || c_hi - c_lo + 1 > max_span;
            most.push((!touches && !wide).then_some(m));
        }
        let mut mask = vec![0u32; rows * cols];
        for &i in &self.cells {
            if towards[i] == 0 {
                continue;
            }
            let a = match most[label[i] as usize] {
                Some(m) if away[i] > 0 => m - away[i],
                Some(_) => 0,
                None => guided[i],
            };
            mask[i] = 2 * towards[i] + a;
        }
        mask
    }

    /// Each flat cell with a mask takes the direction of the steepest fall of the mask over the
    /// distance (`dist[r * 8 + d]`) to an equal-valued neighbour: a flat cell of lower mask, or
    /// a cell that drains (mask 0).
    fn assign_directions(&self, mask: &[u32], dist: &[f64], out: &mut [u8]) {
        for &i in &self.cells {
            if mask[i] == 0 {
                continue;
            }
            let r = i / self.cols;
            let mut best = 0.0f64;
            let mut code = D8_NONE;
            for (d, n) in self.neighbours(i) {
                if self.z[n] != self.z[i] {
                    continue;
                }
                let m = if self.is_flat[n] { mask[n] } else { 0 };
                if m >= mask[i] {
                    continue;
                }
                let slope = f64::from(mask[i] - m) / dist[r * 8 + d];
                if slope > best {
                    best = slope;
                    code = d as u8;
                }
            }
            out[i] = code;
        }
    }
}
