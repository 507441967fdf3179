//! Depression filling by Priority-Flood (Barnes, Lehman & Mulla 2014, "Priority-Flood: An
//! optimal depression-filling and watershed-labeling algorithm for digital elevation models"),
//! in its improved form: a priority queue for cells that keep their own elevation plus a plain
//! FIFO for cells raised inside a depression, which never need re-sorting. The priority queue is
//! a bitset over the cells ranked in advance (`rank_queue`) for grids of fewer than 2³¹ cells
//! (with their frame), a 4-ary heap for larger ones. The flood works on a copy of the grid framed
//! by closed cells, each cell's value beside its rank, so that it needs no bounds checks and a
//! cell's neighbourhood costs three cache lines.
//!
//! All border cells are outlets, and so are NaN cells (nodata): they seed the flood and keep
//! their value, and their neighbours drain into them. Output is always `≥` the input.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use ndarray::Array2;

use super::common::{next_up, order_key, values, D8_OFFSETS};
use super::rank_queue::RankQueue;

/// A heap entry ordering cells by (elevation key, row-major index).
trait Entry: Ord + Copy {
    fn make(key: u32, idx: usize) -> Self;
    fn key(self) -> u32;
    fn idx(self) -> usize;
}

/// Packed entry for grids of fewer than 2³² cells (the normal case): one `u64` compare.
impl Entry for u64 {
    #[inline]
    fn make(key: u32, idx: usize) -> Self {
        ((key as u64) << 32) | idx as u64
    }
    #[inline]
    fn key(self) -> u32 {
        (self >> 32) as u32
    }
    #[inline]
    fn idx(self) -> usize {
        (self & 0xFFFF_FFFF) as usize
    }
}

/// Entry for grids of 2³² cells or more.
impl Entry for (u32, usize) {
    #[inline]
    fn make(key: u32, idx: usize) -> Self {
        (key, idx)
    }
    #[inline]
    fn key(self) -> u32 {
        self.0
    }
    #[inline]
    fn idx(self) -> usize {
        self.1
    }
}

/// The priority queue of a flood: pops its entries in increasing order. Every entry of a flood
/// is distinct (a cell enters once; ties are broken by the index), so every correct queue pops
/// the same sequence and the flood's result does not depend on which one runs.
pub(crate) trait MinQueue<E> {
    /// Queues entry `e` of the cell whose tag (before the flood closed it) is `tag`: the tag
    /// [`MinQueue::tag_cells`] gave it, or 0.
    fn push(&mut self, e: E, tag: u32);
    fn peek(&self) -> Option<E>;
    fn pop(&mut self) -> Option<E>;
    /// Gives cells tags before the flood starts (`tag(index, value)`, values below 2³¹), for a
    /// queue that finds a cell's place from a tag kept beside its value faster than from its
    /// entry. None by default.
    fn tag_cells(&self, _tag: impl FnMut(usize, u32)) {}
}

/// The standard library's binary heap (the reference queue of [`super::naive`]).
impl<E: Ord + Copy> MinQueue<E> for BinaryHeap<Reverse<E>> {
    fn push(&mut self, e: E, _tag: u32) {
        BinaryHeap::push(self, Reverse(e));
    }
    fn peek(&self) -> Option<E> {
        BinaryHeap::peek(self).map(|r| r.0)
    }
    fn pop(&mut self) -> Option<E> {
        BinaryHeap::pop(self).map(|r| r.0)
    }
}

/// A 4-ary min-heap: half the depth of a binary heap and a node's children in one cache line,
/// so a pop compares more but waits for memory less. The least-cost search's queue of
/// [`super::breach`], and the floods' on grids of 2³² cells or more.
#[derive(Debug, Default)]
pub(crate) struct QuadHeap<E> {
    v: Vec<E>,
}

impl<E: Ord + Copy> QuadHeap<E> {
    /// Queues `e`.
    pub(crate) fn push(&mut self, e: E) {
        let hole = self.v.len();
        self.v.push(e);
        self.sift_up(hole, e);
    }

    /// The smallest entry.
    pub(crate) fn peek(&self) -> Option<E> {
        self.v.first().copied()
    }

    /// Removes and returns the smallest entry.
    pub(crate) fn pop(&mut self) -> Option<E> {
        let last = self.v.pop()?;
        let Some(&top) = self.v.first() else {
            return Some(last);
        };
        // Move the smallest child up along the path to a leaf (no comparison with `last` on
        // the way down), then sift `last` up from that hole: most holes end near the bottom.
        let n = self.v.len();
        let mut i = 0;
        loop {
            let first = 4 * i + 1;
            if first >= n {
                break;
            }
            let mut m = first;
            let mut mv = self.v[first];
            for k in first + 1..(first + 4).min(n) {
                let x = self.v[k];
                let less = x < mv;
                m = if less { k } else { m };
                mv = if less { x } else { mv };
            }
            self.v[i] = mv;
            i = m;
        }
        self.sift_up(i, last);
        Some(top)
    }

    /// Removes every entry, keeping the allocation.
    pub(crate) fn clear(&mut self) {
        self.v.clear();
    }

    /// Puts `e` into the hole at `i`, moving larger parents down into the hole on the way up.
    fn sift_up(&mut self, mut i: usize, e: E) {
        while i > 0 {
            let parent = (i - 1) / 4;
            if self.v[parent] <= e {
                break;
            }
            self.v[i] = self.v[parent];
            i = parent;
        }
        self.v[i] = e;
    }
}

impl<E: Ord + Copy> MinQueue<E> for QuadHeap<E> {
    fn push(&mut self, e: E, _tag: u32) {
        QuadHeap::push(self, e);
    }
    fn peek(&self) -> Option<E> {
        QuadHeap::peek(self)
    }
    fn pop(&mut self) -> Option<E> {
        QuadHeap::pop(self)
    }
}

/// Shared Priority-Flood. `raise(c)` is the value a cell at or below the level of the cell `c`
/// it is reached from is raised to: `c` itself (flat fill) or the next float above (ε fill).
///
/// Cells are processed in non-decreasing order of (filled) elevation: the next cell is the
/// lower of the FIFO front and the heap top (the FIFO front wins ties). The FIFO is monotone
/// because every pushed value is `≥` the value being processed, so this is an exact, globally
/// ordered flood; ties in the heap are broken by the row-major index, so results are fully
/// deterministic.
fn flood(z: &Array2<f32>, raise: impl Fn(f32) -> f32) -> Array2<f32> {
    flood_in(z, raise, RankQueue::new, QuadHeap::default)
}

/// One cell of the grid a flood works on, framed by a ring of closed cells so that every cell
/// has eight neighbours: its value (filled in place) and its tag (the queue's, see
/// [`MinQueue::tag_cells`]) with [`CLOSED`] set once it has entered a queue. Value and tag side
/// by side, a cell's neighbourhood is three cache lines however the flood jumps across the grid.
#[derive(Clone, Copy)]
struct Cell {
    v: f32,
    tag: u32,
}

/// The bit of a [`Cell`]'s tag set once the cell has entered a queue (or is the frame).
const CLOSED: u32 = 1 << 31;

/// [`flood`] with the queue `small` makes for grids whose framed cells number fewer than 2³¹
/// (given every cell's entry, `(order key of its value << 32) | framed index`, in increasing
/// index order) and the one `large` makes for larger grids.
pub(crate) fn flood_in<Q, Q2>(
    z: &Array2<f32>,
    raise: impl Fn(f32) -> f32,
    small: impl FnOnce(Vec<u64>) -> Q,
    large: impl FnOnce() -> Q2,
) -> Array2<f32>
where
    Q: MinQueue<u64>,
    Q2: MinQueue<(u32, usize)>,
{
    let (rows, cols) = z.dim();
    let w = values(z);
    if rows < 3 || cols < 3 {
        return z.to_owned();
    }
    let fc = cols + 2;
    let mut g = vec![
        Cell {
            v: f32::NAN,
            tag: CLOSED
        };
        (rows + 2) * fc
    ];
    // The cells into the frame and, for the ranked queue, their entries, in one pass.
    let ranked = g.len() < (1usize << 31);
    let mut entries = Vec::with_capacity(if ranked { rows * cols } else { 0 });
    for (r, row) in w.chunks_exact(cols).enumerate() {
        let first = (r + 1) * fc + 1;
        for ((i, cell), &v) in (first..).zip(&mut g[first..first + cols]).zip(row) {
            *cell = Cell { v, tag: 0 };
            if ranked {
                entries.push((u64::from(order_key(v)) << 32) | i as u64);
            }
        }
    }
    if ranked {
        let open = small(entries);
        open.tag_cells(|i, tag| g[i].tag = tag);
        flood_with::<u64, Q>(&mut g, rows, cols, raise, open);
    } else {
        flood_with::<(u32, usize), Q2>(&mut g, rows, cols, raise, large());
    }
    let mut filled = Vec::with_capacity(rows * cols);
    for row in g.chunks_exact(fc).skip(1).take(rows) {
        filled.extend(row[1..=cols].iter().map(|cell| cell.v));
    }
    Array2::from_shape_vec((rows, cols), filled).unwrap_or_else(|_| z.clone())
}

/// The flood of the framed `rows × cols` grid `g` with the empty queue `open`, whose entries
/// are `(order key of the cell's value, framed index)`.
fn flood_with<E: Entry, Q: MinQueue<E>>(
    g: &mut [Cell],
    rows: usize,
    cols: usize,
    raise: impl Fn(f32) -> f32,
    mut open: Q,
) {
    let fc = cols + 2;
    // Outlets: the border cells and the NaN cells.
    for r in 0..rows {
        let on_edge = r == 0 || r == rows - 1;
        for c in 0..cols {
            let i = (r + 1) * fc + c + 1;
            let cell = &mut g[i];
            if on_edge || c == 0 || c == cols - 1 || cell.v.is_nan() {
                let tag = cell.tag;
                cell.tag = tag | CLOSED;
                open.push(E::make(order_key(cell.v), i), tag);
            }
        }
    }
    let offsets: [isize; 8] = D8_OFFSETS.map(|(dr, dc)| dr * fc as isize + dc);
    let mut pit: VecDeque<usize> = VecDeque::new();
    loop {
        let from_pit = match (pit.front(), open.peek()) {
            (Some(&p), Some(e)) => order_key(g[p].v) <= e.key(),
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        let i = if from_pit {
            match pit.pop_front() {
                Some(i) => i,
                None => break,
            }
        } else {
            match open.pop() {
                Some(e) => e.idx(),
                None => break,
            }
        };
        let spill = raise(g[i].v);
        for o in offsets {
            let j = i.wrapping_add_signed(o);
            let cell = &mut g[j];
            if cell.tag & CLOSED != 0 {
                continue;
            }
            let tag = cell.tag;
            cell.tag = tag | CLOSED;
            // A NaN `spill` (from an outlet) compares false: the neighbour keeps its value.
            if cell.v <= spill {
                cell.v = spill;
                pit.push_back(j);
            } else {
                open.push(E::make(order_key(cell.v), j), tag);
            }
        }
    }
}

/// Priority-Flood+ε: fills every depression and imposes a tiny gradient on the filled flats
/// (and on flats in general), so that every non-border, non-NaN cell has a strictly lower
/// 8-neighbour (or a NaN neighbour) and every cell drains to an outlet.
///
/// Instead of a fixed ε each raised cell gets the next representable `f32` above the cell it
/// was reached from (`next_up`), which works at any elevation (a fixed 1e-5 vanishes at
/// 7000 m). Raised values are within a few ulps per cell of the flat fill.
/// Grids smaller than 3×3 are all border and are returned unchanged.
pub fn priority_flood_fill(z: &Array2<f32>) -> Array2<f32> {
    flood(z, next_up)
}

/// Priority-Flood without ε: depressions are filled to exactly their spill level, leaving flat
/// areas. Equal to the fixed point of Planchon–Darboux relaxation.
pub fn priority_flood_fill_flat(z: &Array2<f32>) -> Array2<f32> {
    flood(z, |v| v)
}

/// Percentage (0–100) of cells holding water at steady state when all border cells are
/// outlets: cells where [`priority_flood_fill_flat`] is strictly above the input. NaN cells
/// count in the denominator but never hold water. 0 for an empty grid.
pub fn flood_extent(z: &Array2<f32>) -> f64 {
    let n = z.len();
    if n == 0 {
        return 0.0;
    }
    let filled = priority_flood_fill_flat(z);
    let wet = ndarray::Zip::from(&filled)
        .and(z)
        .fold(0usize, |acc, &f, &v| acc + usize::from(f > v));
    100.0 * wet as f64 / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 4-ary heap pops any set of distinct entries in increasing order, pushes and pops
    /// interleaved.
    #[test]
    fn quad_heap_pops_in_order() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let mut heap = QuadHeap::default();
        let mut reference = std::collections::BTreeSet::new();
        for round in 0..20_000 {
            if round % 3 == 2 {
                assert_eq!(heap.pop(), reference.pop_first());
            } else {
                let e = next() % 5000 * 100_000 + round; // distinct, with many equal keys
                heap.push(e);
                reference.insert(e);
            }
            assert_eq!(heap.peek(), reference.first().copied());
        }
        while let Some(e) = reference.pop_first() {
            assert_eq!(heap.pop(), Some(e));
        }
        assert_eq!(heap.pop(), None);
    }

    /// The flood on the 4-ary heap (the queue of grids of 2³¹ cells or more, which ignores the
    /// cells' tags) equals the flood on the ranked queue bit for bit, both fills, on a grid with
    /// ties, pits and NaN cells.
    #[test]
    fn the_heap_flood_equals_the_ranked_flood() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let z = Array2::from_shape_fn((37, 53), |_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            match x % 50 {
                0 => f32::NAN,
                k if k < 20 => (k / 5) as f32 * 3.0,
                _ => (x >> 40) as f32 / 1e3,
            }
        });
        for raise in [std::convert::identity as fn(f32) -> f32, next_up] {
            let ranked = flood(&z, raise);
            let heap = flood_in(&z, raise, |_| QuadHeap::<u64>::default(), QuadHeap::default);
            let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&heap), bits(&ranked));
            assert!(
                ranked.iter().zip(&z).any(|(f, v)| f > v),
                "the grid has pits"
            );
        }
    }

    #[test]
    fn single_pit_and_heap_entry_packing() {
        let mut z = Array2::from_elem((4, 5), 3.0f32);
        z[[1, 2]] = 1.0;
        z[[2, 2]] = 2.0;
        let flat = priority_flood_fill_flat(&z);
        assert_eq!(flat, Array2::from_elem((4, 5), 3.0f32));
        assert!((flood_extent(&z) - 10.0).abs() < 1e-12);
        let eps = priority_flood_fill(&z);
        assert!(eps[[1, 2]] > 3.0 && eps[[2, 2]] > 3.0);
        assert!(eps[[1, 1]] > 3.0); // the flat interior also gets a drainage gradient
        let e = <u64 as Entry>::make(0xDEAD_BEEF, 12345);
        assert_eq!((e.key(), e.idx()), (0xDEAD_BEEF, 12345));
    }
}
