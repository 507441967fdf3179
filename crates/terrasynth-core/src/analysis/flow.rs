//! Flow routing on a depression-filled DEM: D8 receivers (steepest descent), D8 flow
//! accumulation by topological order, and Freeman/Quinn multiple-flow-direction (MFD)
//! accumulation by decreasing elevation. Accumulations are upstream areas in m² including the
//! cell's own area `dx[r]·dy[r]`.
//!
//! Directions are indexed as in [`D8_OFFSETS`] (E, NE, N, NW, W, SW, S, SE). A cell only sends
//! flow to strictly lower neighbours; a cell without one (a border outlet, a pit of an unfilled
//! DEM, a NaN cell, or a cell whose only lower neighbours are NaN) is a sink with receiver
//! [`D8_NONE`] whose flow leaves the grid. NaN cells never receive flow but do count their own
//! area, so the sink accumulations always add up to the total area.

use ndarray::Array2;

pub use super::common::D8_OFFSETS;
use super::common::{dir_geometry, neighbour, row_areas, values};
use crate::math;
use crate::raster::CellSizes;
use crate::simd::Isa;

/// Receiver code of a sink (no strictly lower neighbour): its flow leaves the grid.
pub const D8_NONE: u8 = 255;

/// Default exponent of [`flow_accumulation_mfd`] (Freeman 1991).
pub const MFD_EXPONENT: f64 = 1.1;

/// D8 receivers: for every cell the index into [`D8_OFFSETS`] of the neighbour with the largest
/// drop/distance (metric distances from [`CellSizes`]: `dx`, the mean `dy` of the two rows, and
/// the diagonal of the two), or [`D8_NONE`]. Ties go to the lowest direction index. Drops are
/// computed in `f64` from the `f32` elevations, so next-float (ε) gradients are honoured.
///
/// Computed a row at a time and a direction at a time across the row (every cell still weighs
/// its directions in index order, so the result is the per-cell scan's, bit for bit: see
/// [`naive::d8_receivers`](super::naive::d8_receivers) and its property test); the inner loop
/// is branch-free and runs in the widest vectors [`Isa::current`] allows.
pub fn d8_receivers(filled: &Array2<f32>, cs: &CellSizes) -> Array2<u8> {
    let (rows, cols) = filled.dim();
    let z = values(filled);
    let geo = dir_geometry(cs, rows);
    let mut out = vec![D8_NONE; rows * cols];
    // The row's best slopes and their directions (as wide as the slopes, so that the update
    // vectorises).
    let mut best = vec![0.0f64; cols];
    let mut codes = vec![0u64; cols];
    let isa = Isa::current();
    for r in 0..rows {
        let dist = &geo.dist[r * 8..r * 8 + 8];
        best.fill(0.0);
        codes.fill(u64::from(D8_NONE));
        for (d, &(dr, dc)) in D8_OFFSETS.iter().enumerate() {
            let Some(nr) = r.checked_add_signed(dr).filter(|&nr| nr < rows) else {
                continue;
            };
            // The columns whose neighbour in direction d is inside the grid.
            let (c0, c1) = match dc {
                -1 => (1, cols),
                1 => (0, cols.saturating_sub(1)),
                _ => (0, cols),
            };
            if c0 >= c1 {
                continue;
            }
            let n0 = c0.wrapping_add_signed(dc);
            let n1 = c1.wrapping_add_signed(dc);
            let direction = Direction {
                here: &z[r * cols + c0..r * cols + c1],
                there: &z[nr * cols + n0..nr * cols + n1],
                dist: dist[d],
                code: d as u64,
            };
            d8_direction(isa, &direction, &mut best[c0..c1], &mut codes[c0..c1]);
        }
        for (o, &code) in out[r * cols..(r + 1) * cols].iter_mut().zip(&codes) {
            *o = code as u8;
        }
    }
    Array2::from_shape_vec((rows, cols), out)
        .unwrap_or_else(|_| Array2::from_elem((rows, cols), D8_NONE))
}

/// One direction of [`d8_receivers`] across part of a row: the cells' elevations, their
/// neighbours' in that direction, the distance to them and the direction's code.
struct Direction<'a> {
    here: &'a [f32],
    there: &'a [f32],
    dist: f64,
    code: u64,
}

/// Each cell whose drop to its neighbour in `dir` (`here − there`, in `f64`) is positive and
/// whose slope `drop / dist` beats its best so far takes the direction's code; in the build
/// `isa` allows (the same bits in every build).
#[inline]
fn d8_direction(isa: Isa, dir: &Direction<'_>, best: &mut [f64], codes: &mut [u64]) {
    isa.run(
        #[inline(always)]
        |_| {
            let n = dir
                .here
                .len()
                .min(dir.there.len())
                .min(best.len())
                .min(codes.len());
            let (here, there, best, codes) = (
                &dir.here[..n],
                &dir.there[..n],
                &mut best[..n],
                &mut codes[..n],
            );
            let (dist, code) = (dir.dist, dir.code);
            for i in 0..n {
                let drop = f64::from(here[i]) - f64::from(there[i]);
                let slope = drop / dist;
                // False for NaN on either side. Both tests are evaluated (no branch), so the
                // loop vectorises.
                let take = (drop > 0.0) & (slope > best[i]);
                best[i] = if take { slope } else { best[i] };
                codes[i] = if take { code } else { codes[i] };
            }
        },
    );
}

/// D8 upstream area (m²) from a receiver grid as produced by [`d8_receivers`] (codes ≥ 8 and
/// codes pointing outside the grid are sinks): [`accumulate_sources`] of the cell areas.
pub fn flow_accumulation_from_receivers(receivers: &Array2<u8>, cs: &CellSizes) -> Array2<f64> {
    let (rows, cols) = receivers.dim();
    let areas = row_areas(cs, rows);
    let sources = Array2::from_shape_fn((rows, cols), |(r, _)| areas[r]);
    accumulate_sources(receivers, &sources)
}

/// Accumulates `sources` down a D8 receiver grid: every cell gets its own source plus the sum of
/// the sources of every cell draining through it (the upstream area when sources are cell areas;
/// injected inflows are added as extra source). Cells are processed in a Kahn topological order
/// (in-degree stack seeded in row-major order), O(n). Cycles, which `d8_receivers` never
/// produces, would leave their cells with only their upstream sum so far. A `sources` grid of
/// another shape gives zeros.
pub fn accumulate_sources(receivers: &Array2<u8>, sources: &Array2<f64>) -> Array2<f64> {
    let (rows, cols) = receivers.dim();
    if sources.dim() != (rows, cols) {
        return Array2::zeros((rows, cols));
    }
    let n = rows * cols;
    // Receivers as `u32` cell indices (half the memory traffic of `usize`); a grid of 4 G cells
    // or more takes the naive walk (the same sums up to rounding, slowly).
    let no_receiver = u32::MAX;
    if n >= no_receiver as usize {
        return super::naive::accumulate_sources(receivers, sources);
    }
    let mut rcv = vec![no_receiver; n];
    let mut indeg = vec![0u8; n];
    let codes = values(receivers);
    // An interior cell's receiver is its index plus the direction's offset; only the border
    // cells need the bounds checks of `neighbour`.
    let offsets: [isize; 8] = D8_OFFSETS.map(|(dr, dc)| dr * cols as isize + dc);
    for r in 0..rows {
        let interior_row = r > 0 && r + 1 < rows;
        for c in 0..cols {
            let i = r * cols + c;
            let code = codes[i] as usize;
            if code >= 8 {
                continue;
            }
            let j = if interior_row && c > 0 && c + 1 < cols {
                i.wrapping_add_signed(offsets[code])
            } else {
                match neighbour(r, c, code, rows, cols) {
                    Some((nr, nc)) => nr * cols + nc,
                    None => continue,
                }
            };
            rcv[i] = j as u32;
            indeg[j] += 1;
        }
    }
    let mut acc: Vec<f64> = sources.iter().copied().collect();
    // Kahn's order without a queue: the cells nobody drains into, in row-major order, each
    // followed down its chain of receivers for as long as the next one has all its donors in
    // (what a stack seeded with them would pop, the same additions in the same order). A cell
    // reached so is marked, so that the scan does not take it again.
    const TAKEN: u8 = u8::MAX;
    for i in 0..n {
        if indeg[i] != 0 {
            continue;
        }
        let mut cur = i;
        loop {
            let j = rcv[cur];
            if j == no_receiver {
                break;
            }
            let j = j as usize;
            acc[j] += acc[cur];
            indeg[j] -= 1;
            if indeg[j] != 0 {
                break;
            }
            indeg[j] = TAKEN;
            cur = j;
        }
    }
    Array2::from_shape_vec((rows, cols), acc).unwrap_or_else(|_| Array2::zeros((rows, cols)))
}

/// D8 flow accumulation: upstream area in m² (including the cell itself) following
/// [`d8_receivers`] of `filled` (normally the output of
/// [`priority_flood_fill`](super::priority_flood_fill)). O(n).
pub fn flow_accumulation_d8(filled: &Array2<f32>, cs: &CellSizes) -> Array2<f64> {
    flow_accumulation_from_receivers(&d8_receivers(filled, cs), cs)
}

/// The fixed inputs of [`mfd_shares`].
struct Mfd<'a> {
    z: &'a [f32],
    rows: usize,
    cols: usize,
    dist: &'a [f64],
    contour: &'a [f64],
    exponent: f64,
}

/// MFD weights of cell `(r, c)` towards its 8 neighbours (0 for non-receivers), normalised to
/// sum to 1; returns false for a sink.
#[inline]
fn mfd_shares(m: &Mfd<'_>, r: usize, c: usize, w: &mut [f64; 8]) -> bool {
    let (rows, cols) = (m.rows, m.cols);
    let zi = m.z[r * cols + c] as f64;
    let (dist, contour) = (&m.dist[r * 8..r * 8 + 8], &m.contour[r * 8..r * 8 + 8]);
    let mut total = 0.0;
    let mut lower = 0usize;
    for d in 0..8 {
        w[d] = -1.0; // not a receiver unless strictly lower
        let Some((nr, nc)) = neighbour(r, c, d, rows, cols) else {
            continue;
        };
        let drop = zi - m.z[nr * cols + nc] as f64;
        if drop > 0.0 {
            let t = drop / dist[d] * contour[d];
            w[d] = math::pow(t, m.exponent);
            total += w[d];
            lower += 1;
        }
    }
    if lower == 0 {
        return false;
    }
    if total > 0.0 && total.is_finite() {
        for x in w.iter_mut() {
            *x = if *x > 0.0 { *x / total } else { 0.0 };
        }
    } else {
        // Degenerate weights (underflow or infinite drops): equal shares among lower cells.
        let share = 1.0 / lower as f64;
        for x in w.iter_mut() {
            *x = if *x >= 0.0 { share } else { 0.0 };
        }
    }
    true
}

/// Multiple-flow-direction accumulation (upstream area, m²), Freeman (1991) / Quinn et al.
/// (1991) variant: a cell splits its accumulated area among its strictly lower neighbours in
/// proportion to `(tanβ_d · L_d)^exponent`, where `tanβ_d` is drop/distance and `L_d` the contour
/// length (half the perpendicular cell size for cardinal directions, a quarter of the cell
/// diagonal for diagonals, i.e. Quinn's 0.5 and 0.354 for square cells). Cells are processed
/// in a topological order (a cell once all its strictly higher neighbours are done, Kahn's
/// algorithm seeded in row-major order), so each cell is complete before it is distributed;
/// O(n) and deterministic. Use [`MFD_EXPONENT`] (1.1) as the default exponent.
pub fn flow_accumulation_mfd(filled: &Array2<f32>, cs: &CellSizes, exponent: f64) -> Array2<f64> {
    let (rows, cols) = filled.dim();
    let n = rows * cols;
    let z = values(filled);
    let geo = dir_geometry(cs, rows);
    let areas = row_areas(cs, rows);
    let mut acc: Vec<f64> = (0..n).map(|i| areas[i / cols]).collect();
    // Kahn topological order: a cell is ready once all its strictly higher neighbours are done.
    let mut indeg = vec![0u8; n];
    for r in 0..rows {
        for c in 0..cols {
            let zi = z[r * cols + c];
            for d in 0..8 {
                if let Some((nr, nc)) = neighbour(r, c, d, rows, cols) {
                    if z[nr * cols + nc] > zi {
                        indeg[r * cols + c] += 1;
                    }
                }
            }
        }
    }
    let mut stack: Vec<usize> = (0..n).filter(|&i| indeg[i] == 0).rev().collect();
    let m = Mfd {
        z: &z,
        rows,
        cols,
        dist: &geo.dist,
        contour: &geo.contour,
        exponent,
    };
    let mut w = [0.0f64; 8];
    while let Some(i) = stack.pop() {
        let (r, c) = (i / cols, i % cols);
        let sends = mfd_shares(&m, r, c, &mut w);
        let a = acc[i];
        let zi = z[i];
        for (d, &share) in w.iter().enumerate() {
            let Some((nr, nc)) = neighbour(r, c, d, rows, cols) else {
                continue;
            };
            let j = nr * cols + nc;
            if z[j] < zi {
                if sends && share > 0.0 {
                    acc[j] += a * share;
                }
                indeg[j] -= 1;
                if indeg[j] == 0 {
                    stack.push(j);
                }
            }
        }
    }
    Array2::from_shape_vec((rows, cols), acc).unwrap_or_else(|_| Array2::zeros((rows, cols)))
}

/// `log10` of an upstream-area grid, as `f32` (for display and statistics).
pub fn log_upstream_area(area: &Array2<f64>) -> Array2<f32> {
    area.mapv(|a| math::log10(a) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every vector build of the D8 row update this CPU runs equals the baseline build bit for bit
    /// (slopes and codes), on rows with rises, falls, ties, NaN and single-ulp steps.
    #[test]
    fn d8_direction_builds_equal_the_plain_loop() {
        for n in [0usize, 1, 7, 8, 9, 31, 64, 1000] {
            let here: Vec<f32> = (0..n)
                .map(|i| match i % 11 {
                    3 => f32::NAN,
                    5 => 1000.0,
                    _ => 1000.0 + math::sinf((i as f32) * 0.731) * 40.0,
                })
                .collect();
            let there: Vec<f32> = (0..n)
                .map(|i| match i % 7 {
                    2 => f32::NAN,
                    4 => here[i].next_down(),
                    5 => here[i],
                    _ => 1000.0 + math::cosf((i as f32) * 1.37) * 40.0,
                })
                .collect();
            let start: Vec<f64> = (0..n).map(|i| [0.0, 0.1, 2.5][i % 3]).collect();
            let dir = Direction {
                here: &here,
                there: &there,
                dist: 30.0,
                code: 3,
            };
            let run = |f: &dyn Fn(&mut [f64], &mut [u64])| {
                let mut best = start.clone();
                let mut codes = vec![u64::from(D8_NONE); n];
                f(&mut best, &mut codes);
                (best.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), codes)
            };
            let plain = run(&|b, c| d8_direction(Isa::Baseline, &dir, b, c));
            if n >= 31 {
                // The rows exercise both outcomes.
                assert!(plain.1.contains(&3));
                assert!(plain.1.contains(&u64::from(D8_NONE)));
            }
            for isa in Isa::builds() {
                let v = run(&|b, c| d8_direction(isa, &dir, b, c));
                assert_eq!(v, plain, "{isa:?}");
            }
        }
    }
}
