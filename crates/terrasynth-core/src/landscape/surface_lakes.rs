//! Lakes that a base records as flat water surfaces. Global DEMs (GEBCO, SRTM and those built
//! from them) hold a lake's surface, not its bed: a lake is a patch of cells of exactly one
//! elevation. Such a patch has no depression for the depression lakes of
//! [`water`](fn@super::water) to find, so a world would draw Issyk-Kul as bare flat ground, and
//! every amplified zoom would add relief to it.
//!
//! [`surface_lakes`] finds them: 8-connected valid cells of exactly one elevation whose area
//! reaches a minimum (a threshold well above the flats that integer elevations leave on gentle
//! plains), above the sea level if there is one. [`sink_surface_lake_beds`] then gives each lake
//! a bed below its surface: its depth grows with the distance to the shore
//! ([`shore_distance`], metres along 8-neighbour steps) at a fixed slope, since the base holds no
//! bathymetry of it. The world keeps the surface as the lake's water level.
//!
//! Pure functions of their inputs, with a fixed traversal order: deterministic. The search has
//! a twin that labels every flat of the grid ([`surface_lakes_naive`]) and the distance a
//! relaxation twin ([`shore_distance_naive`]), each for a property test.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use ndarray::Array2;

use crate::math;
use crate::raster::CellSizes;

use super::water::{neighbours, N8};

/// Half the side of the square a cell's neighbourhood must fill within its flat for the cell
/// to be in the flat's core: 2, a 5×5 square.
pub const CORE_RADIUS: usize = 2;

/// The smallest share of a flat's cells in its core for the flat to be a lake. A lake's surface
/// is a broad patch; the flats that integer elevations leave on gentle plains are contour bands
/// a few cells wide. On the default world's 15″ GEBCO base every flat of 100 km² or more is one
/// or the other: the lakes' core shares are 0.29–0.91, the bands' at most 0.013.
pub const MIN_CORE_SHARE: f64 = 0.2;

/// How many steps from its flat a lake reaches over cells below its surface: 2.
pub const SHORE_RINGS: usize = 2;

/// The surface of every lake of `heights` recorded as a flat: each cell of a flat of at least
/// `min_area_m2` whose core ([`CORE_RADIUS`]) holds at least [`MIN_CORE_SHARE`] of its cells,
/// and each valid cell below the flat's elevation within [`SHORE_RINGS`] steps of it through
/// such cells, holds the flat's elevation; every other cell NaN. A flat is a set of 8-connected
/// valid cells (`valid`, `None`: all) of exactly one finite elevation, strictly above
/// `sea_level` when given (a flat at or below it is sea). `cells` gives the metric cell sizes of
/// the rows.
///
/// Only a flat with a core cell can be a lake, so the flats are searched from the core cells
/// alone (a 5×5 square of usable cells of one elevation, found with row runs first); each lake's
/// area is summed in the order [`surface_lakes_naive`] sums it and the lakes take their shores
/// in the order of their first cells, so the result is its twin's, bit for bit.
pub fn surface_lakes(
    heights: &Array2<f32>,
    valid: Option<&Array2<bool>>,
    cells: &CellSizes,
    min_area_m2: f64,
    sea_level: Option<f32>,
) -> Array2<f32> {
    let (rows, cols) = heights.dim();
    let mut surface = Array2::from_elem((rows, cols), f32::NAN);
    let usable = |r: usize, c: usize| {
        let v = heights[[r, c]];
        v.is_finite() && valid.is_none_or(|m| m[[r, c]]) && sea_level.is_none_or(|s| v > s)
    };
    let core = core_cells(heights, &usable);
    // The flat each searched cell belongs to, numbered from 1 (0: not searched).
    let mut label = Array2::<u32>::zeros((rows, cols));
    let mut next = 0u32;
    let mut queue = VecDeque::new();
    let mut lakes: Vec<FoundLake> = Vec::new();
    for ((r0, c0), &is_core) in core.indexed_iter() {
        if !is_core || label[[r0, c0]] != 0 {
            continue;
        }
        next = next.saturating_add(1);
        let flat = flat_from(heights, &usable, (r0, c0), &mut label, next, &mut queue);
        // The flat's first cell in row-major order, where its twin's search starts.
        let Some(&first) = flat.iter().min() else {
            continue;
        };
        let cores = flat.iter().filter(|&&(r, c)| core[[r, c]]).count();
        if (cores as f64) < MIN_CORE_SHARE * flat.len() as f64 {
            continue;
        }
        // Summed in the order of a search from the first cell, as the twin sums it: the
        // flat's cells are searched again from there.
        let ordered = if first == (r0, c0) {
            flat
        } else {
            for &(r, c) in &flat {
                label[[r, c]] = 0;
            }
            flat_from(heights, &usable, first, &mut label, next, &mut queue)
        };
        let area: f64 = ordered.iter().map(|&(r, _)| cells.area(r)).sum();
        if area < min_area_m2 {
            continue;
        }
        let v = heights[first];
        for &(r, c) in &ordered {
            surface[[r, c]] = v;
        }
        lakes.push(FoundLake {
            first,
            level: v,
            cells: ordered,
        });
    }
    lakes.sort_by_key(|lake| lake.first);
    take_shores(heights, valid, &mut surface, &lakes);
    surface
}

/// Whether each cell is in the core of its flat: its 5×5 square ([`CORE_RADIUS`]) lies in the
/// grid and holds usable cells of its elevation only.
fn core_cells(heights: &Array2<f32>, usable: &impl Fn(usize, usize) -> bool) -> Array2<bool> {
    let (rows, cols) = heights.dim();
    let k = CORE_RADIUS;
    let mut core = Array2::from_elem((rows, cols), false);
    if rows <= 2 * k || cols <= 2 * k {
        return core;
    }
    // Whether the cells k either side of (r, c) in its row are usable and of its elevation.
    let mut across = Array2::from_elem((rows, cols), false);
    for r in 0..rows {
        for c in k..cols - k {
            let v = heights[[r, c]];
            across[[r, c]] = (c - k..=c + k).all(|cc| heights[[r, cc]] == v && usable(r, cc));
        }
    }
    for r in k..rows - k {
        for c in k..cols - k {
            let v = heights[[r, c]];
            core[[r, c]] = (r - k..=r + k).all(|rr| across[[rr, c]] && heights[[rr, c]] == v);
        }
    }
    core
}

/// The flat of `start` (8-connected usable cells of its elevation not yet labelled), labelled
/// `id` in `label`, in the order of a breadth-first search from `start`.
fn flat_from(
    heights: &Array2<f32>,
    usable: &impl Fn(usize, usize) -> bool,
    start: (usize, usize),
    label: &mut Array2<u32>,
    id: u32,
    queue: &mut VecDeque<(usize, usize)>,
) -> Vec<(usize, usize)> {
    let (rows, cols) = heights.dim();
    let v = heights[start];
    let mut flat = Vec::new();
    label[start] = id;
    queue.push_back(start);
    while let Some((r, c)) = queue.pop_front() {
        flat.push((r, c));
        for (nr, nc) in neighbours(r, c, rows, cols) {
            if label[[nr, nc]] == 0 && heights[[nr, nc]] == v && usable(nr, nc) {
                label[[nr, nc]] = id;
                queue.push_back((nr, nc));
            }
        }
    }
    flat
}

/// [`surface_lakes`] by labelling every flat of the grid, one breadth-first search each, and
/// testing each flat's core cell by cell against the labels: the twin of the property test.
pub fn surface_lakes_naive(
    heights: &Array2<f32>,
    valid: Option<&Array2<bool>>,
    cells: &CellSizes,
    min_area_m2: f64,
    sea_level: Option<f32>,
) -> Array2<f32> {
    let (rows, cols) = heights.dim();
    let mut surface = Array2::from_elem((rows, cols), f32::NAN);
    let usable = |r: usize, c: usize| {
        let v = heights[[r, c]];
        v.is_finite() && valid.is_none_or(|m| m[[r, c]]) && sea_level.is_none_or(|s| v > s)
    };
    // Each cell's flat, numbered from 1 in row-major order of the flats' first cells (0: none).
    let mut label = Array2::<u32>::zeros((rows, cols));
    let mut next = 0u32;
    let mut flat = Vec::new();
    let mut queue = VecDeque::new();
    let mut lakes: Vec<FoundLake> = Vec::new();
    for r0 in 0..rows {
        for c0 in 0..cols {
            if label[[r0, c0]] != 0 || !usable(r0, c0) {
                continue;
            }
            let v = heights[[r0, c0]];
            next = next.saturating_add(1);
            label[[r0, c0]] = next;
            flat.clear();
            queue.push_back((r0, c0));
            let mut area = 0.0f64;
            while let Some((r, c)) = queue.pop_front() {
                flat.push((r, c));
                area += cells.area(r);
                for (nr, nc) in neighbours(r, c, rows, cols) {
                    if label[[nr, nc]] == 0 && heights[[nr, nc]] == v && usable(nr, nc) {
                        label[[nr, nc]] = next;
                        queue.push_back((nr, nc));
                    }
                }
            }
            if area < min_area_m2 {
                continue;
            }
            let k = CORE_RADIUS;
            let in_core = |&&(r, c): &&(usize, usize)| {
                r >= k
                    && c >= k
                    && r + k < rows
                    && c + k < cols
                    && label
                        .slice(ndarray::s![r - k..=r + k, c - k..=c + k])
                        .iter()
                        .all(|&l| l == next)
            };
            let core = flat.iter().filter(in_core).count();
            if core as f64 >= MIN_CORE_SHARE * flat.len() as f64 {
                for &(r, c) in &flat {
                    surface[[r, c]] = v;
                }
                lakes.push(FoundLake {
                    first: (r0, c0),
                    level: v,
                    cells: std::mem::take(&mut flat),
                });
            }
        }
    }
    take_shores(heights, valid, &mut surface, &lakes);
    surface
}

/// A lake [`surface_lakes`] found.
struct FoundLake {
    /// Its flat's first cell in row-major order.
    first: (usize, usize),
    /// Its surface, metres: the flat's elevation.
    level: f32,
    /// Its flat's cells.
    cells: Vec<(usize, usize)>,
}

/// Each lake of `lakes` (in order) takes the valid cells below its
/// surface within [`SHORE_RINGS`] steps of it through such cells, in `surface`, unless an
/// earlier lake took them (the gridding leaves such cells along many shores).
fn take_shores(
    heights: &Array2<f32>,
    valid: Option<&Array2<bool>>,
    surface: &mut Array2<f32>,
    lakes: &[FoundLake],
) {
    let (rows, cols) = heights.dim();
    let mut ring = Array2::from_elem((rows, cols), u8::MAX);
    for lake in lakes {
        let level = lake.level;
        let mut queue: VecDeque<(usize, usize)> = lake.cells.iter().copied().collect();
        for &(r, c) in &lake.cells {
            ring[[r, c]] = 0;
        }
        while let Some((r, c)) = queue.pop_front() {
            let step = ring[[r, c]];
            if usize::from(step) >= SHORE_RINGS {
                continue;
            }
            for (nr, nc) in neighbours(r, c, rows, cols) {
                let below = valid.is_none_or(|m| m[[nr, nc]]) && heights[[nr, nc]] < level;
                if surface[[nr, nc]].is_nan() && below {
                    surface[[nr, nc]] = level;
                    ring[[nr, nc]] = step + 1;
                    queue.push_back((nr, nc));
                }
            }
        }
    }
}

/// Lowers the cells of the lakes of `surface` (finite cells; [`surface_lakes`]) in `heights`
/// to their surface minus `bed_slope` × (their [`shore_distance`] less one cell, the smaller
/// side of their row's cells; at least 0), where that is lower: a bed whose depth grows from
/// the shore. The lake's outer ring keeps the surface's elevation, so amplified zooms draw its
/// shoreline where their detail crosses the surface instead of along the base's cell edges.
/// Cells off the lakes keep their value.
pub fn sink_surface_lake_beds(
    heights: &mut Array2<f32>,
    surface: &Array2<f32>,
    cells: &CellSizes,
    bed_slope: f32,
) {
    let inside = surface.mapv(|v| !v.is_nan());
    let (rows, cols) = inside.dim();
    // Each 8-connected patch of lake cells on its own: the distances of its cells run through
    // its cells only, so the window of the patch grown by one cell (its shore) gives the
    // distances of the whole grid, bit for bit, without a whole grid of them.
    for patch in patches(&inside) {
        let (mut r0, mut r1, mut c0, mut c1) = (rows, 0, cols, 0);
        for &(r, c) in &patch {
            (r0, r1, c0, c1) = (r0.min(r), r1.max(r + 1), c0.min(c), c1.max(c + 1));
        }
        let (r0, c0) = (r0.saturating_sub(1), c0.saturating_sub(1));
        let (r1, c1) = ((r1 + 1).min(rows), (c1 + 1).min(cols));
        let window = inside.slice(ndarray::s![r0..r1, c0..c1]).to_owned();
        let window_cells = CellSizes {
            dx: cells.dx[r0..r1].to_vec(),
            dy: cells.dy[r0..r1].to_vec(),
        };
        let distance = shore_distance(&window, &window_cells);
        for (r, c) in patch {
            let inland = (distance[[r - r0, c - c0]] - cells.dx[r].min(cells.dy[r])).max(0.0);
            let bed = (f64::from(surface[[r, c]]) - f64::from(bed_slope) * inland) as f32;
            heights[[r, c]] = heights[[r, c]].min(bed);
        }
    }
}

/// The 8-connected patches of `inside`'s cells, each in the order of a breadth-first search
/// from its first cell in row-major order.
fn patches(inside: &Array2<bool>) -> Vec<Vec<(usize, usize)>> {
    let (rows, cols) = inside.dim();
    let mut seen = Array2::from_elem((rows, cols), false);
    let mut out = Vec::new();
    let mut queue = VecDeque::new();
    for ((r0, c0), &is_in) in inside.indexed_iter() {
        if !is_in || seen[[r0, c0]] {
            continue;
        }
        seen[[r0, c0]] = true;
        queue.push_back((r0, c0));
        let mut patch = Vec::new();
        while let Some((r, c)) = queue.pop_front() {
            patch.push((r, c));
            for (nr, nc) in neighbours(r, c, rows, cols) {
                if inside[[nr, nc]] && !seen[[nr, nc]] {
                    seen[[nr, nc]] = true;
                    queue.push_back((nr, nc));
                }
            }
        }
        out.push(patch);
    }
    out
}

/// The length of the step from `(r, c)` by `(dr, dc)`: the mean of the two rows' cell sizes
/// along each axis moved (symmetric, so a path's length does not depend on its direction).
fn step(cells: &CellSizes, r: usize, dr: isize, dc: isize) -> f64 {
    let other = r
        .saturating_add_signed(dr)
        .min(cells.dx.len().saturating_sub(1));
    let dx = 0.5 * (cells.dx[r] + cells.dx[other]);
    let dy = 0.5 * (cells.dy[r] + cells.dy[other]);
    match (dr != 0, dc != 0) {
        (true, true) => math::hypot(dx, dy),
        (true, false) => dy,
        _ => dx,
    }
}

/// For each cell of `inside`, the length (m) of the shortest 8-neighbour path to a cell outside
/// it or off the grid (a step's length is the mean of its two rows' cell sizes along each axis
/// moved, a step off the grid its own row's); 0 for cells outside. Dijkstra from the shore.
pub fn shore_distance(inside: &Array2<bool>, cells: &CellSizes) -> Array2<f64> {
    let (rows, cols) = inside.dim();
    let mut dist = Array2::from_elem((rows, cols), f64::INFINITY);
    // Entries (distance bits, row-major index): distances are ≥ 0, so their bits order them.
    let mut heap = BinaryHeap::new();
    for ((r, c), &is_in) in inside.indexed_iter() {
        if !is_in {
            dist[[r, c]] = 0.0;
            continue;
        }
        let mut d = f64::INFINITY;
        for &(dr, dc) in &N8 {
            let off = match (r.checked_add_signed(dr), c.checked_add_signed(dc)) {
                (Some(nr), Some(nc)) if nr < rows && nc < cols => !inside[[nr, nc]],
                _ => true,
            };
            if off {
                d = d.min(step(cells, r, dr, dc));
            }
        }
        if d.is_finite() {
            dist[[r, c]] = d;
            heap.push(Reverse((d.to_bits(), r * cols + c)));
        }
    }
    while let Some(Reverse((bits, i))) = heap.pop() {
        let (r, c) = (i / cols, i % cols);
        let d = f64::from_bits(bits);
        if d > dist[[r, c]] {
            continue;
        }
        for &(dr, dc) in &N8 {
            let (Some(nr), Some(nc)) = (r.checked_add_signed(dr), c.checked_add_signed(dc)) else {
                continue;
            };
            if nr >= rows || nc >= cols || !inside[[nr, nc]] {
                continue;
            }
            let nd = d + step(cells, r, dr, dc);
            if nd < dist[[nr, nc]] {
                dist[[nr, nc]] = nd;
                heap.push(Reverse((nd.to_bits(), nr * cols + nc)));
            }
        }
    }
    dist
}

/// [`shore_distance`] by relaxation: every cell of `inside` starts at infinity and takes the
/// least of its neighbours' distances plus the step (a neighbour outside or off the grid counts
/// 0) until nothing changes. The reference of the property test.
pub fn shore_distance_naive(inside: &Array2<bool>, cells: &CellSizes) -> Array2<f64> {
    let (rows, cols) = inside.dim();
    let mut dist = inside.mapv(|i| if i { f64::INFINITY } else { 0.0 });
    let mut changed = true;
    while changed {
        changed = false;
        for r in 0..rows {
            for c in 0..cols {
                if !inside[[r, c]] {
                    continue;
                }
                for &(dr, dc) in &N8 {
                    let from = match (r.checked_add_signed(dr), c.checked_add_signed(dc)) {
                        (Some(nr), Some(nc)) if nr < rows && nc < cols => dist[[nr, nc]],
                        _ => 0.0,
                    };
                    let d = from + step(cells, r, dr, dc);
                    if d < dist[[r, c]] {
                        dist[[r, c]] = d;
                        changed = true;
                    }
                }
            }
        }
    }
    dist
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A 13×16 plain rising west to east by 1 m a column from 600 m, holding a flat of 7×8
    /// cells at 500 m (12 of its cells in its core), a chain of three cells below 500 m leading
    /// west from the flat's middle row (499, 498, 497 m) and a band of 16 cells at 700 m along
    /// its first row; cells of 100 m.
    fn plain() -> Array2<f32> {
        let mut h = Array2::from_shape_fn((13, 16), |(r, c)| 600.0 + c as f32 + 0.01 * r as f32);
        for r in 3..10 {
            for c in 4..12 {
                h[[r, c]] = 500.0;
            }
        }
        h[[6, 3]] = 499.0;
        h[[6, 2]] = 498.0;
        h[[6, 1]] = 497.0;
        for c in 0..16 {
            h[[0, c]] = 700.0;
        }
        h
    }

    /// The flat's cells.
    fn on_flat(r: usize, c: usize) -> bool {
        (3..10).contains(&r) && (4..12).contains(&c)
    }

    /// The lake's cells: the flat's and the two of the chain within two steps of it.
    fn on_lake(r: usize, c: usize) -> bool {
        on_flat(r, c) || (r == 6 && (2..4).contains(&c))
    }

    #[test]
    fn a_broad_flat_is_a_lake_when_its_area_reaches_the_minimum() {
        let h = plain();
        let cells = CellSizes::uniform(13, 100.0);
        // The flat's 56 cells of 1 ha: a lake at 56 ha, none at 57 ha. The band (16 ha, no
        // core) never. The lake reaches the chain's first two cells, not its third.
        let s = surface_lakes(&h, None, &cells, 56e4, None);
        for ((r, c), &v) in s.indexed_iter() {
            assert_eq!(!v.is_nan(), on_lake(r, c), "{r},{c}");
            if on_lake(r, c) {
                assert_eq!(v, 500.0);
            }
        }
        assert!(surface_lakes(&h, None, &cells, 57e4, None)
            .iter()
            .all(|v| v.is_nan()));
        assert_eq!(
            surface_lakes(&h, None, &cells, 1.0, None)
                .iter()
                .filter(|v| !v.is_nan())
                .count(),
            58
        );
        // At or below the sea level a flat is sea.
        assert!(surface_lakes(&h, None, &cells, 1.0, Some(500.0))
            .iter()
            .all(|v| v.is_nan()));
        // An invalid cell in the middle leaves the flat's other 55 cells but no core (every core
        // cell's square holds it).
        let mut valid = Array2::from_elem(h.dim(), true);
        valid[[6, 8]] = false;
        assert!(surface_lakes(&h, Some(&valid), &cells, 1.0, None)
            .iter()
            .all(|v| v.is_nan()));
        // A hole in the flat's corner takes one core cell: 11 of 55, exactly the share, still a
        // lake.
        valid[[6, 8]] = true;
        valid[[3, 4]] = false;
        let holed = surface_lakes(&h, Some(&valid), &cells, 1.0, None);
        assert!(holed[[3, 4]].is_nan());
        assert_eq!(holed.iter().filter(|v| !v.is_nan()).count(), 57);
    }

    #[test]
    fn of_two_lakes_reaching_one_shore_cell_the_first_in_row_major_order_takes_it() {
        // Lake X at 500 m: an 8 × 8 body in rows 6–13, columns 0–7, and a tail up column 8 from
        // row 0, so its first cell (0, 8) comes before lake Y's although its core starts later.
        // Lake Y at 400 m: rows 1–8, columns 11–19. Cells (3, 9) and (3, 10) lie at 300 m,
        // below both, one and two steps from each lake.
        let mut h = Array2::from_elem((14, 20), 600.0f32);
        for r in 6..14 {
            for c in 0..8 {
                h[[r, c]] = 500.0;
            }
        }
        for r in 0..7 {
            h[[r, 8]] = 500.0;
        }
        for r in 1..9 {
            for c in 11..20 {
                h[[r, c]] = 400.0;
            }
        }
        h[[3, 9]] = 300.0;
        h[[3, 10]] = 300.0;
        let cells = CellSizes::uniform(14, 100.0);
        for s in [
            surface_lakes(&h, None, &cells, 1e5, None),
            surface_lakes_naive(&h, None, &cells, 1e5, None),
        ] {
            assert_eq!(s[[0, 8]], 500.0);
            assert_eq!(s[[4, 15]], 400.0);
            assert_eq!((s[[3, 9]], s[[3, 10]]), (500.0, 500.0));
        }
    }

    #[test]
    fn a_lake_bed_deepens_with_the_distance_to_its_shore() {
        let mut h = plain();
        let before = h.clone();
        let cells = CellSizes::uniform(13, 100.0);
        let s = surface_lakes(&h, None, &cells, 1.0, None);
        sink_surface_lake_beds(&mut h, &s, &cells, 0.05);
        for ((r, c), &v) in h.indexed_iter() {
            if !on_flat(r, c) {
                // Off the lake, and on the chain's cells below the lake's outer ring: unchanged.
                assert_eq!(v, before[[r, c]], "{r},{c}");
            }
        }
        // The lake's outer ring is one step (100 m, one cell) from its shore and keeps the
        // surface; the next ring lies 5 m deep, the next 10 m, and the middle row's middle
        // cells 15 m.
        assert_eq!(h[[3, 4]], 500.0);
        assert_eq!(h[[9, 11]], 500.0);
        assert_eq!(h[[4, 5]], 495.0);
        assert_eq!(h[[5, 6]], 490.0);
        assert_eq!(h[[6, 7]], 485.0);
        assert_eq!(h[[6, 8]], 485.0);
    }

    #[test]
    fn shore_distance_counts_steps_off_the_grid_and_diagonals() {
        let inside = Array2::from_elem((3, 5), true);
        let cells = CellSizes::uniform(3, 10.0);
        let d = shore_distance(&inside, &cells);
        assert_eq!(d[[0, 0]], 10.0);
        assert_eq!(d[[1, 2]], 20.0);
        let mut ring = Array2::from_elem((5, 5), false);
        ring[[2, 2]] = true;
        ring[[2, 3]] = true;
        let d = shore_distance(&ring, &CellSizes::uniform(5, 10.0));
        assert_eq!((d[[2, 2]], d[[2, 3]], d[[0, 0]]), (10.0, 10.0, 0.0));
    }

    proptest! {
        /// The search from core cells equals labelling every flat, bit for bit, on grids of a
        /// few elevations (broad flats, bands, ±0, NaN holes, masked cells), with or without a
        /// sea level, for minima from none to the whole grid.
        #[test]
        fn surface_lakes_equal_their_twin(
            rows in 1usize..26,
            cols in 1usize..26,
            picks in proptest::collection::vec(0u8..=255, 625),
            masked in proptest::collection::vec(0u8..200, 625),
            sea in proptest::option::of(-1.0f32..600.0),
            min_cells in 0.0f64..120.0,
            dx0 in 50.0f64..150.0,
        ) {
            // Checkerboard squares of 10 × 11 cells: broad flats (touching at their corners; some
            // of zeros of either sign) with a few holes and other elevations in them, between
            // squares of small flats and single cells.
            let value = |r: usize, c: usize| match (picks[r * 25 + c], (r / 10 + c / 11) % 4) {
                (0, _) => f32::NAN,
                (1, _) => 499.0,
                (2, _) => 501.0,
                (k, 0) if r < 10 => if k % 2 == 0 { 0.0 } else { -0.0 },
                (_, 0 | 2) => 500.0,
                (k, _) => 600.0 + f32::from(k / 16),
            };
            let h = Array2::from_shape_fn((rows, cols), |(r, c)| value(r, c));
            let valid = Array2::from_shape_fn((rows, cols), |(r, c)| masked[r * 25 + c] != 0);
            let dx: Vec<f64> = (0..rows).map(|r| dx0 * (1.0 - 0.01 * r as f64)).collect();
            let cells = CellSizes { dx, dy: vec![dx0; rows] };
            let min_area = min_cells * dx0 * dx0;
            for valid in [None, Some(&valid)] {
                let fast = surface_lakes(&h, valid, &cells, min_area, sea);
                let naive = surface_lakes_naive(&h, valid, &cells, min_area, sea);
                for ((r, c), f) in fast.indexed_iter() {
                    let n = naive[[r, c]];
                    prop_assert_eq!(f.to_bits(), n.to_bits(), "{},{}: {} vs {}", r, c, f, n);
                }
            }
        }

        /// Sinking each patch of lake cells in its own window equals sinking over the whole
        /// grid's shore distances, bit for bit.
        #[test]
        fn sinking_patch_by_patch_equals_the_whole_grid(
            rows in 1usize..20,
            cols in 1usize..20,
            bits in proptest::collection::vec(0u8..3, 400),
            dx0 in 20.0f64..200.0,
            slope in 0.001f32..1.0,
        ) {
            let surface = Array2::from_shape_fn((rows, cols), |(r, c)| match bits[r * 20 + c] {
                0 => f32::NAN,
                k => 400.0 + 100.0 * f32::from(k),
            });
            let h = Array2::from_shape_fn((rows, cols), |(r, c)| 450.0 + (r * 7 + c * 3) as f32);
            let dx: Vec<f64> = (0..rows).map(|r| dx0 * (1.0 - 0.02 * r as f64)).collect();
            let dy: Vec<f64> = (0..rows).map(|r| 1.2 * dx0 * (1.0 + 0.03 * r as f64)).collect();
            let cells = CellSizes { dx, dy };
            let mut sunk = h.clone();
            sink_surface_lake_beds(&mut sunk, &surface, &cells, slope);
            let whole = shore_distance(&surface.mapv(|v| !v.is_nan()), &cells);
            for ((r, c), &v) in sunk.indexed_iter() {
                let s = surface[[r, c]];
                let expected = if s.is_nan() {
                    h[[r, c]]
                } else {
                    let inland = (whole[[r, c]] - cells.dx[r].min(cells.dy[r])).max(0.0);
                    h[[r, c]].min((f64::from(s) - f64::from(slope) * inland) as f32)
                };
                prop_assert_eq!(v.to_bits(), expected.to_bits(), "{},{}", r, c);
            }
        }

        /// Dijkstra from the shore equals relaxation on random shapes with rows of different
        /// cell sizes (to rounding: the two may sum a path's steps in another order).
        #[test]
        fn shore_distance_equals_its_relaxation_twin(
            rows in 1usize..14,
            cols in 1usize..14,
            bits in proptest::collection::vec(0u8..4, 196),
            dx0 in 20.0f64..200.0,
            shrink in 0.9f64..1.0,
        ) {
            let inside = Array2::from_shape_fn((rows, cols), |(r, c)| bits[r * 14 + c] != 0);
            let dx: Vec<f64> = (0..rows).map(|r| dx0 * shrink.powi(r as i32)).collect();
            let cells = CellSizes { dx, dy: vec![1.3 * dx0; rows] };
            let fast = shore_distance(&inside, &cells);
            let naive = shore_distance_naive(&inside, &cells);
            for ((r, c), &f) in fast.indexed_iter() {
                let n = naive[[r, c]];
                prop_assert!((f - n).abs() <= 1e-9 * n.max(1.0), "{r},{c}: {f} vs {n}");
                prop_assert_eq!(f == 0.0, !inside[[r, c]]);
            }
        }
    }
}
