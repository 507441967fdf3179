//! Bounded, order-independent depression breaching: every pit gets a monotone channel to the
//! cheapest lower cell within a fixed radius, found by a least-cost search on the *unmodified*
//! surface, and all channels are applied together with a minimum. A cell's result therefore
//! depends only on the surface within twice the radius of it, never on where a window starts or
//! ends nor on the order pits are processed in: breaching commutes with cutting windows out of an
//! infinite plane, which is what a window-invariant amplifier needs (no global priority queue, no
//! block seams).
//!
//! Definitions (all deterministic):
//! - cells are ordered by `(value, global row, global column)`; a *pit* is a cell below every
//!   8-neighbour in that order (so a flat has few pits, at its first cells);
//! - from pit `q` (value `z_q`), a Dijkstra search over the cells within Chebyshev distance
//!   `radius` of `q`, with entry cost `max(0, z − z_q) · L + STEP_COST · L` (`L`: the step's
//!   length, √2 for diagonal steps; the volume of trench to carve per unit width, plus a small
//!   length term) — or, with [`BreachRule::volume`] off, `max(0, z − z_q) + STEP_COST · L` (the
//!   depth alone, which makes a diagonal step carve √2 of channel for the price of one and draws
//!   channels along the diagonals) — heap ordered by
//!   `(cost, global index)`, ends at the first popped cell strictly lower than `z_q`; such goal
//!   cells are not expanded. No goal within the radius: the pit is left as it is;
//! - along the path `q = c_0, c_1, …, c_n` (every `c_i`, `0 < i < n`, is at least `z_q`, or it
//!   would have been the goal) the channel is the straight grade
//!   `t_i = z_q − (z_q − z(c_n))·i/n` for `0 < i < n`; the goal keeps its value. When `f32` has no
//!   room for a strictly descending grade (a goal a few ulps below the pit), the pit is left;
//! - with [`BreachRule::corner_depth`] `d > 0`, the channel of a pit whose neighbourhood rises
//!   [`BreachRule::corner_rise`] or more also lowers, at each diagonal step from `c_{i−1}` to
//!   `c_i`, each of the two cells the step passes between that lies above `c_{i−1}`'s channel
//!   value `t` (`z_q` for the first step): to `z − (z − t)·d`. A one-cell trench along a
//!   diagonal is `1/√2` of a cell wide across its axis, sharper than along a pixel axis, and
//!   puts its high-frequency power in the spectrum's diagonal wedges; the corners widen it
//!   symmetrically (an ablation lever: README, *Corners and block means*);
//! - the result is `min(z, every channel through the cell)`.
//!
//! Every lowered cell then has a strictly lower neighbour (the next cell of the channel that
//! gives it its value, or the goal; a corner cell's is `c_i`, below `t`), and cells not lowered
//! keep theirs, so no pit is created and every pit whose search succeeds drains.

use std::cmp::Ordering;

use ndarray::{s, Array2};
use rayon::prelude::*;

use super::common::D8_OFFSETS;
use super::flood::QuadHeap;

/// Cost of one (cardinal) step of a channel, metres: prefers short channels among equally deep
/// ones.
pub const STEP_COST: f64 = 0.01;

/// How far each pit's channel may reach: pits in steep terrain (a rise of at least `steep_rise`
/// within [`RISE_REACH`] cells) search `radius` cells, pits in flat terrain `flat_radius` (0:
/// left alone). Closed depressions are rare on steep fluvial slopes, where a pit is an artefact
/// of a blocked valley, and common on plains (playas, basins), where a pit is often real.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BreachRule {
    /// Reach of the channels of steep pits (the largest reach; sets the margin).
    pub radius: usize,
    /// Reach of the channels of flat pits, at most `radius`.
    pub flat_radius: usize,
    /// Rise (same unit as the surface) within [`RISE_REACH`] cells of a pit that makes it steep.
    pub steep_rise: f32,
    /// Weigh each step's carve depth by its length (the trench's volume): channels cost the same
    /// per metre in every direction. Off: the depth alone, per cell, whatever the step's length.
    pub volume: bool,
    /// Share (0–1) of the way down to the channel that the two corner cells of each diagonal
    /// step go (module docs); 0: channels are one D8 path wide.
    pub corner_depth: f32,
    /// Rise (same unit as the surface) within [`RISE_REACH`] cells of a pit from which its
    /// channel gets corners.
    pub corner_rise: f32,
}

impl BreachRule {
    /// Every pit searches `radius` cells; costs by volume.
    pub fn uniform(radius: usize) -> Self {
        BreachRule {
            radius,
            flat_radius: radius,
            steep_rise: 0.0,
            volume: true,
            corner_depth: 0.0,
            corner_rise: f32::INFINITY,
        }
    }

    /// The highest value within [`RISE_REACH`] of pit `(r, c)` of value `zq` (at least
    /// [`RISE_REACH`] cells from every edge; NaN cells ignored), and whether a cell there is
    /// strictly below `zq`.
    fn neighbourhood(z: &[f32], cols: usize, r: usize, c: usize, zq: f32) -> (f32, bool) {
        let k = RISE_REACH;
        let (mut top, mut lower) = (zq, false);
        for rr in r - k..=r + k {
            for &v in &z[rr * cols + c - k..=rr * cols + c + k] {
                top = top.max(v);
                lower |= v < zq;
            }
        }
        (top, lower)
    }

    /// The reach of pit `(r, c)` of value `zq` (at least [`RISE_REACH`] cells from every edge),
    /// whether its search can be skipped: a reach of at most [`RISE_REACH`] cells with no
    /// cell strictly below `zq` within [`RISE_REACH`] finds no goal (every cell of the box is
    /// reachable), so its search would leave the pit as it is; and the corner depth of its
    /// channel: [`BreachRule::corner_depth`] when its neighbourhood rises
    /// [`BreachRule::corner_rise`] above it, 0 otherwise.
    fn plan(&self, z: &[f32], cols: usize, r: usize, c: usize, zq: f32) -> (usize, bool, f32) {
        let by_rise = self.flat_radius < self.radius;
        let corners = self.corner_depth > 0.0;
        if !by_rise && !corners {
            return (self.radius, false, 0.0);
        }
        let (top, lower) = Self::neighbourhood(z, cols, r, c, zq);
        let rise = top - zq;
        let corner = if corners && rise >= self.corner_rise {
            self.corner_depth
        } else {
            0.0
        };
        if !by_rise {
            return (self.radius, false, corner);
        }
        let reach = if rise >= self.steep_rise {
            self.radius
        } else {
            self.flat_radius
        };
        (reach, reach <= RISE_REACH && !lower, corner)
    }
}

/// Chebyshev reach of the neighbourhood whose rise tells steep pits from flat ones.
pub const RISE_REACH: usize = 2;

/// Length of a diagonal step relative to a cardinal one.
const DIAGONAL_STEP: f64 = std::f64::consts::SQRT_2;

/// The entry cost of a step of `length` into a cell `depth` above the pit: `depth · w +
/// STEP_COST · length`, `w` the length when costs go by volume, 1 otherwise. The fast search and
/// its reference both call this, so their sums agree bit for bit.
#[inline]
fn step_weights(length: f64, volume: bool) -> (f64, f64) {
    (if volume { length } else { 1.0 }, STEP_COST * length)
}

/// Whether `(za, ia)` comes before `(zb, ib)` in the cell order (value by IEEE comparison, so
/// `−0 = +0` and NaN is below nothing, then global index).
#[inline]
fn below(za: f32, ia: (i64, i64), zb: f32, ib: (i64, i64)) -> bool {
    za < zb || (za == zb && ia < ib)
}

/// Whether cell `(r, c)` of the row-major `z` (`cols` wide; not on its border) is a pit.
#[inline]
fn is_pit(z: &[f32], cols: usize, origin: (i64, i64), r: usize, c: usize) -> bool {
    let i = r * cols + c;
    let v = z[i];
    let (up, down) = (
        &z[i - cols - 1..i - cols + 2],
        &z[i + cols - 1..i + cols + 2],
    );
    let (w, e) = (z[i - 1], z[i + 1]);
    // Fast path: a strictly lower neighbour settles it without indices.
    if up.iter().chain(down).any(|&n| n < v) || w < v || e < v {
        return false;
    }
    if !(up.iter().chain(down).any(|&n| n == v) || w == v || e == v) {
        return true;
    }
    let me = (origin.0 + r as i64, origin.1 + c as i64);
    D8_OFFSETS.iter().all(|&(dr, dc)| {
        let (nr, nc) = ((r as isize + dr) as usize, (c as isize + dc) as usize);
        let n = (origin.0 + nr as i64, origin.1 + nc as i64);
        !below(z[nr * cols + nc], n, v, me)
    })
}

/// `lowest[k]`: the lowest of the 8 neighbours of cell `(r, cols.start + k)` of the row-major
/// `z` (`cols` wide; `r` and the columns not on its border) — always one of their values, so
/// `lowest[k] < z` means that a neighbour lies strictly below the cell. Row-wise minima of
/// shifted rows, so the loop vectorises.
fn lowest_neighbours(
    z: &[f32],
    width: usize,
    r: usize,
    cols: std::ops::Range<usize>,
    lowest: &mut Vec<f32>,
) {
    let lower = |a: f32, b: f32| if b < a { b } else { a };
    let (c0, n) = (cols.start, cols.len());
    let row = |rr: usize, shift: usize| &z[rr * width + c0 - 1 + shift..][..n];
    lowest.clear();
    lowest.extend_from_slice(row(r - 1, 0));
    for (rr, shift) in [
        (r - 1, 1),
        (r - 1, 2),
        (r, 0),
        (r, 2),
        (r + 1, 0),
        (r + 1, 1),
        (r + 1, 2),
    ] {
        for (l, &x) in lowest.iter_mut().zip(row(rr, shift)) {
            *l = lower(*l, x);
        }
    }
}

/// A queue entry of the search: the bits of its cost (a non-negative `f64`, whose bits order
/// like its value) and its row-major index in the search box; popped smallest first (by cost,
/// then index; within one box the index order is the global order). Entries are distinct, so
/// any correct queue pops them in the same order.
type Item = (u64, u32);

/// Channels of pits, one after the other: cells of `z` with their channel values (the pits
/// themselves excluded).
type Channel = Vec<((usize, usize), f32)>;

/// Pits per task of [`breach_pits_with`]: each task appends its pits' channels, in pit order, to
/// one buffer.
const PITS_PER_TASK: usize = 64;

/// Reusable buffers of the search over a `(2·radius + 1)²` box, framed by one sentinel cell on
/// every side (so neighbours need no bounds test). Entries are valid for the current search only
/// when their stamp equals its generation, so nothing is cleared between pits.
struct Search {
    radius: usize,
    /// Costs by volume ([`BreachRule::volume`]).
    volume: bool,
    /// Side of the framed box, `2·radius + 3`.
    side: usize,
    dist: Vec<f64>,
    pred: Vec<u32>,
    /// Generation in which `dist`/`pred` were last written.
    seen: Vec<u32>,
    /// Generation in which the cell was popped (sentinels: `u32::MAX`).
    done: Vec<u32>,
    generation: u32,
    /// Neighbour offsets in the framed box and their [`step_weights`].
    steps: [(isize, (f64, f64)); 8],
    heap: QuadHeap<Item>,
    /// The path of the current channel, goal last.
    path: Vec<(usize, usize)>,
    /// Offset in `z` of every framed-box cell from the box's first cell, for rows `offs_cols`
    /// wide (rebuilt when the width changes).
    offs: Vec<usize>,
    /// The neighbour offsets of `steps` in `z`, for rows `offs_cols` wide.
    z_steps: [isize; 8],
    offs_cols: usize,
}

impl Search {
    fn new(radius: usize, volume: bool) -> Self {
        let side = 2 * radius + 3;
        let mut done = vec![0u32; side * side];
        for r in 0..side {
            for c in 0..side {
                if r == 0 || c == 0 || r == side - 1 || c == side - 1 {
                    done[r * side + c] = u32::MAX;
                }
            }
        }
        let steps = D8_OFFSETS.map(|(dr, dc)| {
            let step = if dr != 0 && dc != 0 {
                DIAGONAL_STEP
            } else {
                1.0
            };
            (dr * side as isize + dc, step_weights(step, volume))
        });
        Search {
            radius,
            volume,
            side,
            dist: vec![f64::INFINITY; side * side],
            pred: vec![u32::MAX; side * side],
            seen: vec![0u32; side * side],
            done,
            generation: 0,
            steps,
            heap: QuadHeap::default(),
            path: Vec::new(),
            offs: Vec::new(),
            z_steps: [0; 8],
            offs_cols: usize::MAX,
        }
    }

    /// The channel from pit `(r, c)` of the row-major `z` (`cols` wide; the pit at least
    /// `radius` cells from every edge), appended to `out` if a strictly lower cell lies within
    /// the radius (and `f32` holds a descending grade to it); `out` is left as it was otherwise.
    /// The box's frame of sentinels bounds the search, so its loop tests no coordinates.
    fn channel(
        &mut self,
        z: &[f32],
        cols: usize,
        (r, c): (usize, usize),
        corner_depth: f32,
        out: &mut Channel,
    ) {
        let (side, radius) = (self.side, self.radius);
        if self.generation >= u32::MAX - 1 {
            // Stamps would collide with the sentinels: start afresh.
            *self = Search::new(radius, self.volume);
        }
        self.generation += 1;
        let gen = self.generation;
        self.heap.clear();
        // Framed-box cell (br, bc) is cell (r − radius − 1 + br, c − radius − 1 + bc) of z (the
        // frame may lie one cell outside z; it is never read).
        if self.offs_cols != cols {
            self.offs = (0..side * side)
                .map(|cell| cell / side * cols + cell % side)
                .collect();
            self.z_steps = D8_OFFSETS.map(|(dr, dc)| dr * cols as isize + dc);
            self.offs_cols = cols;
        }
        let base = (r * cols + c).wrapping_sub((radius + 1) * cols + radius + 1);
        let offs = &self.offs;
        let zq = z[r * cols + c];
        let start = (radius + 1) * side + radius + 1;
        self.dist[start] = 0.0;
        self.seen[start] = gen;
        self.heap.push((0.0f64.to_bits(), start as u32));
        let mut goal = None;
        while let Some((cost, cell)) = self.heap.pop() {
            let (cost, cell) = (f64::from_bits(cost), cell as usize);
            if self.done[cell] == gen {
                continue;
            }
            self.done[cell] = gen;
            let zi = base.wrapping_add(offs[cell]);
            if z[zi] < zq {
                goal = Some(cell);
                break;
            }
            for (&(off, (per_m, length_cost)), &z_step) in self.steps.iter().zip(&self.z_steps) {
                let n = cell.wrapping_add_signed(off);
                let stamp = self.done[n];
                if stamp == gen || stamp == u32::MAX {
                    continue;
                }
                let zn = z[zi.wrapping_add_signed(z_step)];
                let depth = (f64::from(zn) - f64::from(zq)).max(0.0);
                let nd = cost + (depth * per_m + length_cost);
                if self.seen[n] != gen || nd < self.dist[n] {
                    self.seen[n] = gen;
                    self.dist[n] = nd;
                    self.pred[n] = cell as u32;
                    self.heap.push((nd.to_bits(), n as u32));
                }
            }
        }
        let Some(goal) = goal else {
            return;
        };
        let (r0, c0) = (r - radius, c - radius);
        let path = &mut self.path;
        path.clear();
        let mut cur = goal;
        while cur != start {
            // Never a frame cell: those are never pushed.
            path.push((r0 + cur / side - 1, c0 + cur % side - 1));
            cur = self.pred[cur] as usize;
        }
        path.reverse();
        profile(z, cols, zq, (r, c), path, corner_depth, out);
    }
}

/// The straight, strictly descending channel values of the cells of `path` before its end (the
/// path starts next to `pit`, of value `zq`, and ends at a strictly lower cell, which keeps its
/// value), and with `corner_depth > 0` the corner cells of its diagonal steps (module docs),
/// appended to `out`; nothing is appended when `f32` cannot hold a strictly descending grade
/// between them.
fn profile(
    z: &[f32],
    cols: usize,
    zq: f32,
    pit: (usize, usize),
    path: &[(usize, usize)],
    corner_depth: f32,
    out: &mut Channel,
) {
    let Some(&end) = path.last() else {
        return;
    };
    let zn = z[end.0 * cols + end.1];
    let n = path.len() as f64;
    let drop = f64::from(zq) - f64::from(zn);
    let (mut prev, mut from) = (zq, pit);
    let len = out.len();
    for (i, &p) in path.iter().enumerate() {
        let last = i + 1 == path.len();
        let t = if last {
            zn
        } else {
            (f64::from(zq) - drop * (i + 1) as f64 / n) as f32
        };
        let descends = t < prev && t > zn;
        if !last && !descends {
            out.truncate(len);
            return;
        }
        if corner_depth > 0.0 && p.0 != from.0 && p.1 != from.1 {
            // The two cells the diagonal step passes between.
            for k in [(from.0, p.1), (p.0, from.1)] {
                let zk = z[k.0 * cols + k.1];
                if zk > prev {
                    let lowered = (f64::from(zk)
                        - (f64::from(zk) - f64::from(prev)) * f64::from(corner_depth))
                        as f32;
                    if lowered < zk {
                        out.push((k, lowered));
                    }
                }
            }
        }
        if !last {
            out.push((p, t));
        }
        prev = t;
        from = p;
    }
}

/// The frame [`breach_pits`] consumes on each side: twice the channel reach (a pit up to
/// `radius` outside the window can carve into it, and its search reads `radius` further).
pub fn breach_margin(radius: usize) -> usize {
    2 * radius.max(RISE_REACH)
}

/// Breaches the pits of `z`, whose cell `(0, 0)` lies at global `origin = (row, col)`, with
/// channels of Chebyshev reach `radius` (at least 1), and returns the breached values of the
/// inner window (`z` without a frame of [`breach_margin`] cells; empty when `z` is too small).
/// The inner values are the same whatever frame surrounds them.
pub fn breach_pits(z: &Array2<f32>, origin: (i64, i64), radius: usize) -> Array2<f32> {
    breach_pits_with(z, origin, BreachRule::uniform(radius))
}

/// [`breach_pits`] with a reach per pit by [`BreachRule`]; the frame is
/// [`breach_margin`]`(rule.radius)`.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(low < z)`: a NaN cell is tested, not skipped.
pub fn breach_pits_with(z: &Array2<f32>, origin: (i64, i64), rule: BreachRule) -> Array2<f32> {
    let radius = rule.radius.max(RISE_REACH);
    let rule = BreachRule { radius, ..rule };
    let (rows, cols) = z.dim();
    let m = breach_margin(radius);
    if rows <= 2 * m || cols <= 2 * m {
        return Array2::zeros((rows.saturating_sub(2 * m), cols.saturating_sub(2 * m)));
    }
    let flat = z.as_standard_layout();
    let Some(v) = flat.as_slice() else {
        return z.slice(s![m..rows - m, m..cols - m]).to_owned();
    };
    // Pits whose channels can reach the inner window lie within `radius` of it.
    let pits: Vec<(usize, usize)> = (radius..rows - radius)
        .into_par_iter()
        .map_init(Vec::new, |lowest, r| {
            lowest_neighbours(v, cols, r, radius..cols - radius, lowest);
            let here = &v[r * cols + radius..r * cols + cols - radius];
            let mut row_pits = Vec::new();
            for (k, (&z, &low)) in here.iter().zip(lowest.iter()).enumerate() {
                // A cell with a strictly lower neighbour is no pit; the others are tested.
                if !(low < z) && is_pit(v, cols, origin, r, radius + k) {
                    row_pits.push((r, radius + k));
                }
            }
            row_pits
        })
        .flatten_iter()
        .collect();
    // Channels in pit order (so that equal minima keep the same bits whatever the threads).
    // One search per reach, each boxed by its own frame; the flat one made on first use.
    let channels: Vec<Channel> = pits
        .par_chunks(PITS_PER_TASK)
        .map_init(
            || (Search::new(radius, rule.volume), None::<Search>),
            |(steep, flat), task| {
                let mut out = Channel::new();
                for &(r, c) in task {
                    let (reach, skip, corner) = rule.plan(v, cols, r, c, v[r * cols + c]);
                    if reach == 0 || skip {
                        continue;
                    }
                    let search = if reach >= radius {
                        &mut *steep
                    } else {
                        flat.get_or_insert_with(|| Search::new(reach, rule.volume))
                    };
                    search.channel(v, cols, (r, c), corner, &mut out);
                }
                out
            },
        )
        .collect();
    let (ir, ic) = (rows - 2 * m, cols - 2 * m);
    // The inner window, copied row by row (one `memcpy` each, not element by element).
    let mut inner = Vec::with_capacity(ir * ic);
    for r in m..m + ir {
        inner.extend_from_slice(&v[r * cols + m..r * cols + m + ic]);
    }
    let Ok(mut out) = Array2::from_shape_vec((ir, ic), inner) else {
        return z.slice(s![m..m + ir, m..m + ic]).to_owned();
    };
    for &((r, c), t) in channels.iter().flatten() {
        if r >= m && c >= m && r < m + ir && c < m + ic {
            let o = &mut out[[r - m, c - m]];
            if t < *o {
                *o = t;
            }
        }
    }
    out
}

/// Reference implementation of [`breach_pits`] for tests: pits found by comparing `(value,
/// index)` with every neighbour, least costs by relaxation to a fixed point (Bellman-Ford) over
/// each pit's box, the goal as the lowest `(cost, global index)` among strictly lower cells, the
/// path by walking back through the neighbour of lowest `(cost, global index)` among those
/// expanded before the cell whose cost plus the cell's entry cost gives the cell's cost.
pub fn breach_pits_naive(z: &Array2<f32>, origin: (i64, i64), radius: usize) -> Array2<f32> {
    breach_pits_naive_with(z, origin, BreachRule::uniform(radius))
}

/// Reference implementation of [`breach_pits_with`]: as [`breach_pits_naive`], a pit's box
/// being `flat_radius` wide when no cell within [`RISE_REACH`] of it rises `steep_rise` above it,
/// its channel with corners when one rises `corner_rise` above it.
pub fn breach_pits_naive_with(
    z: &Array2<f32>,
    origin: (i64, i64),
    rule: BreachRule,
) -> Array2<f32> {
    let radius = rule.radius.max(RISE_REACH);
    let (rows, cols) = z.dim();
    let m = 2 * radius;
    if rows <= 2 * m || cols <= 2 * m {
        return Array2::zeros((rows.saturating_sub(2 * m), cols.saturating_sub(2 * m)));
    }
    let key = |a: (usize, usize)| (origin.0 + a.0 as i64, origin.1 + a.1 as i64);
    let lower = |a: (usize, usize), b: (usize, usize)| {
        let (za, zb) = (z[a], z[b]);
        za < zb || (za == zb && key(a) < key(b))
    };
    let neighbours = |a: (usize, usize)| {
        let mut v = Vec::new();
        for dr in -1isize..=1 {
            for dc in -1isize..=1 {
                if (dr, dc) != (0, 0) {
                    let step = if dr != 0 && dc != 0 {
                        DIAGONAL_STEP
                    } else {
                        1.0
                    };
                    v.push((
                        ((a.0 as isize + dr) as usize, (a.1 as isize + dc) as usize),
                        step,
                    ));
                }
            }
        }
        v
    };
    let mut out = z.clone();
    for r in radius..rows - radius {
        for c in radius..cols - radius {
            let q = (r, c);
            if neighbours(q).iter().any(|&(n, _)| lower(n, q)) {
                continue;
            }
            let zq = z[q];
            let k = RISE_REACH as isize;
            let steep = (-k..=k).any(|dr| {
                (-k..=k).any(|dc| {
                    let a = ((r as isize + dr) as usize, (c as isize + dc) as usize);
                    z[a] - zq >= rule.steep_rise
                })
            });
            let corners = (-k..=k).any(|dr| {
                (-k..=k).any(|dc| {
                    let a = ((r as isize + dr) as usize, (c as isize + dc) as usize);
                    z[a] - zq >= rule.corner_rise
                })
            });
            let corner_depth = if corners { rule.corner_depth } else { 0.0 };
            let reach = if steep || rule.flat_radius >= radius {
                radius
            } else {
                rule.flat_radius
            };
            if reach == 0 {
                continue;
            }
            let inside = |a: (usize, usize)| {
                // Neighbours of the frame wrap to huge indices: saturate, then the upper bound
                // excludes them.
                a.0.saturating_add(reach) >= r
                    && a.0 <= r + reach
                    && a.1.saturating_add(reach) >= c
                    && a.1 <= c + reach
            };
            let is_goal = |a: (usize, usize)| z[a] < zq;
            let entry = |a: (usize, usize), step: f64| {
                let (per_m, length_cost) = step_weights(step, rule.volume);
                (f64::from(z[a]) - f64::from(zq)).max(0.0) * per_m + length_cost
            };
            let mut dist = std::collections::BTreeMap::new();
            dist.insert(q, 0.0f64);
            loop {
                let mut changed = false;
                let snapshot: Vec<((usize, usize), f64)> =
                    dist.iter().map(|(k, v)| (*k, *v)).collect();
                for (a, da) in snapshot {
                    if is_goal(a) {
                        continue;
                    }
                    for (b, step) in neighbours(a) {
                        if !inside(b) {
                            continue;
                        }
                        let nd = da + entry(b, step);
                        if nd < dist.get(&b).copied().unwrap_or(f64::INFINITY) {
                            dist.insert(b, nd);
                            changed = true;
                        }
                    }
                }
                if !changed {
                    break;
                }
            }
            let rank = |a: &(usize, usize), d: f64| (d, key(*a));
            let goal = dist
                .iter()
                .filter(|(a, _)| is_goal(**a))
                .min_by(|(a, da), (b, db)| {
                    rank(a, **da)
                        .partial_cmp(&rank(b, **db))
                        .unwrap_or(Ordering::Equal)
                })
                .map(|(a, _)| *a);
            let Some(goal) = goal else { continue };
            let mut path = vec![goal];
            let mut cur = goal;
            while cur != q {
                let dc = dist[&cur];
                // The cell's predecessor: among the neighbours expanded before it (lower rank,
                // not goals) whose cost leads exactly to its cost, the first expanded.
                let best = neighbours(cur)
                    .into_iter()
                    .filter(|&(p, step)| {
                        inside(p)
                            && !is_goal(p)
                            && dist.get(&p).is_some_and(|&dp| {
                                dp + entry(cur, step) == dc && rank(&p, dp) < rank(&cur, dc)
                            })
                    })
                    .min_by(|(a, _), (b, _)| {
                        rank(a, dist[a])
                            .partial_cmp(&rank(b, dist[b]))
                            .unwrap_or(Ordering::Equal)
                    });
                let Some((p, _)) = best else { break };
                cur = p;
                if cur != q {
                    path.push(cur);
                }
            }
            path.reverse();
            let flat = z.as_standard_layout();
            let v = flat.as_slice().unwrap_or(&[]);
            let mut channel = Channel::new();
            profile(v, cols, zq, q, &path, corner_depth, &mut channel);
            for (p, t) in channel {
                if t < out[p] {
                    out[p] = t;
                }
            }
        }
    }
    out.slice(s![m..rows - m, m..cols - m]).to_owned()
}
