//! Ridges and valleys by the Profile-recognition and Polygon-breaking Algorithm (PPA; Chang, Song
//! & Liu 1998, "Ridge and valley detection from DEMs"), as feature-guided synthesis (Zhou et al.
//! 2007) uses it to describe both an exemplar and a user's sketch:
//!
//! 1. **Profile recognition.** A cell is a ridge *candidate* when, along at least one of four
//!    profiles through it (east–west, north–south and the two diagonals), both sides hold a cell
//!    lower by more than `min_drop` within `window` cells. Valleys are ridges of the negated DEM.
//! 2. **Target connection.** Every pair of 8-adjacent candidates is joined by a segment whose
//!    elevation is the sum of its ends' (for valleys, of the negated ends'); of two crossing
//!    diagonals only the higher is kept.
//! 3. **Polygon breaking.** The lowest segment of every closed polygon is removed until none is
//!    left. With segments totally ordered (elevation, then cell indices) this leaves the unique
//!    maximum spanning forest of the segment graph, computed here by Kruskal's algorithm with a
//!    union–find; [`naive::break_polygons`](super::ppa_naive::break_polygons) removes cycles one
//!    by one instead, and property tests compare the two.
//! 4. **Branch reduction.** Passes remove every end branch (from an end point to the nearest
//!    branch point) shorter than `min_branch` cells, and every tree smaller than that, until a
//!    pass changes nothing.
//!
//! The result ([`FeatureTree`]) is a forest of cells: its branch points (degree ≥ 3), end
//! points (degree 1) and the paths between them. Everything is deterministic (fixed orders, total
//! tie-breaks, single-threaded) and pure; NaN cells are never candidates and never count as
//! lower or higher.
//!
//! [`drainage_agreement`] measures how well valleys follow D8 channels and ridges separate D8
//! basins (the acceptance figures).

use std::collections::BTreeSet;

use ndarray::Array2;

use super::common::values;
use super::flow::{d8_receivers, flow_accumulation_from_receivers};
use super::{priority_flood_fill, D8_NONE, D8_OFFSETS};
use crate::raster::CellSizes;

/// Which feature a tree describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FeatureKind {
    /// Crest lines: local maxima of cross-profiles.
    Ridge,
    /// Thalwegs: local minima of cross-profiles.
    Valley,
}

impl FeatureKind {
    /// `"ridge"` or `"valley"`.
    pub fn as_str(self) -> &'static str {
        match self {
            FeatureKind::Ridge => "ridge",
            FeatureKind::Valley => "valley",
        }
    }

    /// The kind named `s` (`ridge` or `valley`).
    pub fn parse(s: &str) -> Option<FeatureKind> {
        match s {
            "ridge" => Some(FeatureKind::Ridge),
            "valley" => Some(FeatureKind::Valley),
            _ => None,
        }
    }
}

/// Parameters of the PPA.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PpaParams {
    /// Cells on each side of a profile (≥ 1).
    pub window: usize,
    /// Drop (metres) a profile side must show below the cell (above it for valleys), ≥ 0.
    pub min_drop: f32,
    /// End branches and trees shorter than this many cells are removed (0 keeps everything).
    pub min_branch: usize,
}

impl Default for PpaParams {
    /// Profiles of 3 cells each side, any drop, branches of fewer than 6 cells pruned: on the
    /// Tien Shan at 15″ (≈ 460 m cells) valleys then cover more than 90 % of the D8 channel
    /// cells draining 10 km² or more (README, "Feature extraction").
    fn default() -> Self {
        PpaParams {
            window: 3,
            min_drop: 0.0,
            min_branch: 6,
        }
    }
}

/// Class of a node of a feature tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum NodeClass {
    /// Degree 1: where a line ends.
    End,
    /// Degree 2: on a path.
    Path,
    /// Degree ≥ 3: where lines meet.
    Branch,
}

impl NodeClass {
    /// The class of a node of `degree` (0 counts as an end).
    pub fn of_degree(degree: usize) -> NodeClass {
        match degree {
            0 | 1 => NodeClass::End,
            2 => NodeClass::Path,
            _ => NodeClass::Branch,
        }
    }
}

/// A path of a feature tree: cells from one key node (end or branch point) to the next, every
/// cell in between of degree 2.
#[derive(Clone, Debug, PartialEq)]
pub struct FeaturePath {
    /// Row-major cell indices, in order; consecutive cells are 8-adjacent.
    pub cells: Vec<usize>,
    /// Mean elevation of the cells, metres (NaN cells never occur).
    pub mean_elevation: f64,
}

/// The ridges or valleys of a grid: a forest of cells.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureTree {
    /// Ridge or valley.
    pub kind: FeatureKind,
    /// Grid rows.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    /// Segments `(a, b)` with `a < b` (row-major cell indices), sorted.
    pub edges: Vec<(usize, usize)>,
    /// Paths between key nodes, in the order of their first cell, then second.
    pub paths: Vec<FeaturePath>,
}

impl FeatureTree {
    /// Degree of every cell in the forest (0 outside it).
    pub fn degrees(&self) -> Vec<u8> {
        let mut d = vec![0u8; self.rows * self.cols];
        for &(a, b) in &self.edges {
            d[a] = d[a].saturating_add(1);
            d[b] = d[b].saturating_add(1);
        }
        d
    }

    /// Every cell of the forest, sorted.
    pub fn cells(&self) -> Vec<usize> {
        let set: BTreeSet<usize> = self.edges.iter().flat_map(|&(a, b)| [a, b]).collect();
        set.into_iter().collect()
    }

    /// The key nodes (end and branch points) with their class, sorted by cell.
    pub fn key_points(&self) -> Vec<(usize, NodeClass)> {
        let d = self.degrees();
        self.cells()
            .into_iter()
            .filter(|&i| d[i] != 2)
            .map(|i| (i, NodeClass::of_degree(d[i] as usize)))
            .collect()
    }

    /// A `rows × cols` mask of the forest's cells.
    pub fn mask(&self) -> Array2<bool> {
        let mut m = Array2::from_elem((self.rows, self.cols), false);
        if let Some(s) = m.as_slice_mut() {
            for &(a, b) in &self.edges {
                s[a] = true;
                s[b] = true;
            }
        }
        m
    }
}

/// Ridges and valleys of one grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    /// The ridge forest.
    pub ridges: FeatureTree,
    /// The valley forest.
    pub valleys: FeatureTree,
}

impl Features {
    /// The tree of `kind`.
    pub fn tree(&self, kind: FeatureKind) -> &FeatureTree {
        match kind {
            FeatureKind::Ridge => &self.ridges,
            FeatureKind::Valley => &self.valleys,
        }
    }
}

/// `z` oriented so that the features of `kind` are ridges: `z` itself for ridges, `−z` for
/// valleys (exact in floating point).
pub fn oriented(z: &Array2<f32>, kind: FeatureKind) -> Vec<f32> {
    let v = values(z);
    match kind {
        FeatureKind::Ridge => v.into_owned(),
        FeatureKind::Valley => v.iter().map(|&x| -x).collect(),
    }
}

/// The four profile directions `(row step, column step)`: east, south, south-east, south-west.
pub const PROFILE_DIRECTIONS: [(isize, isize); 4] = [(0, 1), (1, 0), (1, 1), (1, -1)];

/// The start cell of every line of direction `(dr, dc)` through a `rows × cols` grid, in order.
fn line_starts(rows: usize, cols: usize, dr: isize, dc: isize) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    let mut starts: Vec<(usize, usize)> = Vec::new();
    match (dr, dc) {
        (0, _) => starts.extend((0..rows).map(|r| (r, 0))),
        (_, 0) => starts.extend((0..cols).map(|c| (0, c))),
        (_, 1) => {
            // South-east: start on the top row and the left column.
            starts.extend((0..cols).map(|c| (0, c)));
            starts.extend((1..rows).map(|r| (r, 0)));
        }
        _ => {
            // South-west: start on the top row and the right column.
            starts.extend((0..cols).map(|c| (0, c)));
            starts.extend((1..rows).map(|r| (r, cols - 1)));
        }
    }
    starts
}

/// Writes into `out` the row-major cell indices of the line through a `rows × cols` grid that
/// starts at `(r, c)` and steps by `(dr, dc)` until it leaves the grid.
fn line_into(
    rows: usize,
    cols: usize,
    (mut r, mut c): (usize, usize),
    (dr, dc): (isize, isize),
    out: &mut Vec<usize>,
) {
    out.clear();
    loop {
        out.push(r * cols + c);
        match (r.checked_add_signed(dr), c.checked_add_signed(dc)) {
            (Some(nr), Some(nc)) if nr < rows && nc < cols => {
                r = nr;
                c = nc;
            }
            _ => return,
        }
    }
}

/// Minimum over each window of `w` values *after* position `i` (`v[i+1..=i+w]`, clipped to the
/// line), with NaN read as +∞ (never lower); `+∞` when the window is empty. Van Herk /
/// Gil-Werman: block prefix and suffix minima, O(1) per element whatever `w`.
fn forward_window_min(v: &[f32], w: usize) -> Vec<f32> {
    let n = v.len();
    let x: Vec<f32> = v
        .iter()
        .map(|&a| if a.is_nan() { f32::INFINITY } else { a })
        .collect();
    let mut out = vec![f32::INFINITY; n];
    if n == 0 || w == 0 {
        return out;
    }
    // prefix[i]: min of x from the start of i's block to i; suffix[i]: from i to its block's end.
    let mut prefix = x.clone();
    let mut suffix = x.clone();
    for i in 1..n {
        if i % w != 0 {
            prefix[i] = prefix[i - 1].min(x[i]);
        }
    }
    for i in (0..n.saturating_sub(1)).rev() {
        if (i + 1) % w != 0 {
            suffix[i] = suffix[i + 1].min(x[i]);
        }
    }
    for (i, o) in out.iter_mut().enumerate() {
        let lo = i + 1;
        if lo >= n {
            continue;
        }
        let hi = (i + w).min(n - 1);
        // [lo, hi] spans at most two blocks: the suffix of lo's block and the prefix of hi's.
        *o = if lo / w == hi / w {
            // Within one block: suffix minima run to the block's end, so scan (at most w).
            x[lo..=hi].iter().fold(f32::INFINITY, |m, &a| m.min(a))
        } else {
            suffix[lo].min(prefix[hi])
        };
    }
    out
}

/// Candidate cells of the PPA's profile recognition on `z` (already oriented: ridges are maxima):
/// `true` where along at least one of [`PROFILE_DIRECTIONS`] both sides hold, within `window`
/// cells, a value lower than the cell's by more than `min_drop`.
pub fn candidates(z: &[f32], rows: usize, cols: usize, params: &PpaParams) -> Vec<bool> {
    let n = rows * cols;
    let mut out = vec![false; n];
    if z.len() != n || params.window == 0 {
        return out;
    }
    let w = params.window;
    let drop = params.min_drop.max(0.0);
    // One line at a time, its buffers reused: a world's base has thousands of lines, and all
    // of one direction's cell indices at once would take 8 bytes a cell.
    let (mut cells, mut v, mut rev) = (Vec::new(), Vec::new(), Vec::new());
    for &(dr, dc) in &PROFILE_DIRECTIONS {
        for start in line_starts(rows, cols, dr, dc) {
            line_into(rows, cols, start, (dr, dc), &mut cells);
            v.clear();
            v.extend(cells.iter().map(|&i| z[i]));
            let ahead = forward_window_min(&v, w);
            rev.clear();
            rev.extend(v.iter().rev().copied());
            let mut behind = forward_window_min(&rev, w);
            behind.reverse();
            for (k, &i) in cells.iter().enumerate() {
                let h = v[k];
                // False for a NaN cell; +∞ minima (nothing or only NaN on a side) never pass.
                if h - ahead[k] > drop && h - behind[k] > drop {
                    out[i] = true;
                }
            }
        }
    }
    out
}

/// A segment of the target connection: its weight and its two cells. Cell indices are `u32`
/// (16 bytes a segment instead of 24, a world's base has millions): [`segments`] gives none on
/// a grid of more than `u32::MAX` cells (the raster readers' limit is 2^28).
pub type Segment = (f64, u32, u32);

/// The largest grid, in cells, that has [`Segment`]s.
pub const MAX_SEGMENT_CELLS: usize = u32::MAX as usize;

/// The segments of the target connection: `(weight, a, b)` with `a < b` for every pair of
/// 8-adjacent candidates, weight = `z[a] + z[b]` in `f64`; of two crossing diagonals of a 2×2
/// block only the heavier is kept (ties: the north-west–south-east one). None on a grid of more
/// than [`MAX_SEGMENT_CELLS`] cells.
pub fn segments(z: &[f32], rows: usize, cols: usize, cand: &[bool]) -> Vec<Segment> {
    let mut out = Vec::new();
    let n = rows * cols;
    if z.len() != n || cand.len() != n || n > MAX_SEGMENT_CELLS {
        return out;
    }
    let w = |a: usize, b: usize| f64::from(z[a]) + f64::from(z[b]);
    // Every index is below n ≤ u32::MAX, so the conversions are exact.
    let seg = |weight: f64, a: usize, b: usize| (weight, a as u32, b as u32);
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            if !cand[i] {
                continue;
            }
            if c + 1 < cols && cand[i + 1] {
                out.push(seg(w(i, i + 1), i, i + 1));
            }
            if r + 1 < rows {
                let s = i + cols;
                if cand[s] {
                    out.push(seg(w(i, s), i, s));
                }
                // The diagonals of the block whose top-left cell is i: i–(s+1) and (i+1)–s.
                if c + 1 < cols {
                    let se = cand[s + 1].then(|| w(i, s + 1));
                    let sw = (cand[i + 1] && cand[s]).then(|| w(i + 1, s));
                    match (se, sw) {
                        (Some(a), Some(b)) if b > a => out.push(seg(b, i + 1, s)),
                        (Some(a), _) => out.push(seg(a, i, s + 1)),
                        (None, Some(b)) => out.push(seg(b, i + 1, s)),
                        (None, None) => {}
                    }
                }
            }
        }
    }
    out
}

/// The total order of polygon breaking: heavier segments first, then by cell indices.
pub fn segment_order(a: &Segment, b: &Segment) -> std::cmp::Ordering {
    b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2))
}

/// A union–find over at most `u32::MAX` elements (path halving, union by size), 8 bytes an
/// element.
struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    /// `n` singletons; `n` ≤ [`MAX_SEGMENT_CELLS`].
    fn new(n: u32) -> Self {
        UnionFind {
            parent: (0..n).collect(),
            size: vec![1; n as usize],
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    /// Joins the sets of `a` and `b`; false when they already were one.
    fn union(&mut self, a: u32, b: u32) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        let (big, small) = if self.size[ra as usize] >= self.size[rb as usize] {
            (ra, rb)
        } else {
            (rb, ra)
        };
        self.parent[small as usize] = big;
        // Set sizes sum to at most n ≤ u32::MAX.
        self.size[big as usize] += self.size[small as usize];
        true
    }
}

/// Polygon breaking: the maximum spanning forest of `segments` under [`segment_order`] (Kruskal),
/// as sorted `(a, b)` pairs. `n` is the number of cells (segments with a cell at or beyond it are
/// ignored). Takes the segments by value and sorts them in place: a world's base has millions.
pub fn break_polygons(n: usize, mut segments: Vec<Segment>) -> Vec<(usize, usize)> {
    let cells = u32::try_from(n.min(MAX_SEGMENT_CELLS)).unwrap_or(u32::MAX);
    segments.retain(|s| s.1 < cells && s.2 < cells && s.1 != s.2);
    segments.sort_unstable_by(segment_order);
    let mut uf = UnionFind::new(cells);
    let mut kept: Vec<(usize, usize)> = segments
        .into_iter()
        .filter(|s| uf.union(s.1, s.2))
        .map(|s| (s.1.min(s.2) as usize, s.1.max(s.2) as usize))
        .collect();
    kept.sort_unstable();
    kept
}

/// The adjacency of a graph on `n` cells in compressed rows: the neighbours of cell `i` are
/// `neighbours[offsets[i]..offsets[i + 1]]`, sorted (ties, from repeated edges, by edge), each
/// with the index in the edge list of the edge that joins them. Three flat arrays instead of a
/// vector per cell: a world's base has millions of cells.
struct Adjacency {
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
    edge_of: Vec<u32>,
}

impl Adjacency {
    /// The adjacency of `edges` on `n` cells: empty (no cell has a neighbour) on a grid of more
    /// than [`MAX_SEGMENT_CELLS`] cells or with more than `u32::MAX` edges, which have no
    /// segments to begin with.
    fn new(n: usize, edges: &[(usize, usize)]) -> Adjacency {
        let mut offsets = vec![0usize; n + 1];
        if n > MAX_SEGMENT_CELLS || edges.len() > u32::MAX as usize {
            return Adjacency {
                offsets,
                neighbours: Vec::new(),
                edge_of: Vec::new(),
            };
        }
        // Each cell's count, then the end of its slots; placing an entry moves the end back,
        // so that it ends at the cell's first slot.
        for &(a, b) in edges {
            offsets[a] += 1;
            offsets[b] += 1;
        }
        let mut total = 0;
        for o in &mut offsets[..n] {
            total += *o;
            *o = total;
        }
        offsets[n] = total;
        let mut neighbours = vec![0u32; total];
        let mut edge_of = vec![0u32; total];
        // Cells are below n ≤ u32::MAX and edges below u32::MAX: the conversions are exact.
        for (k, &(a, b)) in edges.iter().enumerate() {
            for (from, to) in [(a, b), (b, a)] {
                offsets[from] -= 1;
                neighbours[offsets[from]] = to as u32;
                edge_of[offsets[from]] = k as u32;
            }
        }
        // Each cell's entries (at most 8 on a grid of 8-adjacent cells) sorted by (neighbour,
        // edge): an insertion sort of both arrays.
        for i in 0..n {
            for j in offsets[i] + 1..offsets[i + 1] {
                let mut k = j;
                while k > offsets[i]
                    && (neighbours[k - 1], edge_of[k - 1]) > (neighbours[k], edge_of[k])
                {
                    neighbours.swap(k - 1, k);
                    edge_of.swap(k - 1, k);
                    k -= 1;
                }
            }
        }
        Adjacency {
            offsets,
            neighbours,
            edge_of,
        }
    }

    /// The slots of cell `i`'s neighbours.
    fn slots(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i]..self.offsets[i + 1]
    }

    /// Cell `i`'s neighbours, sorted.
    fn of(&self, i: usize) -> &[u32] {
        &self.neighbours[self.slots(i)]
    }
}

/// Branch reduction: passes that remove every end branch shorter than `min_branch` cells (the
/// cells from an end point up to, not including, the first branch point) and every tree with
/// fewer than `min_branch` cells, until a pass removes nothing. Each pass decides from the
/// forest as it was at the start of the pass, so the result does not depend on visiting order.
/// Returns the edges left, sorted and without repeats. Takes the edges by value and sorts them
/// in place: a world's base has millions.
///
/// One adjacency for all passes, with a flag per edge for the ones removed;
/// [`naive::reduce_branches`](super::ppa_naive::reduce_branches) rebuilds the forest at every
/// pass instead, and property tests compare the two.
pub fn reduce_branches(
    n: usize,
    mut edges: Vec<(usize, usize)>,
    min_branch: usize,
) -> Vec<(usize, usize)> {
    edges.sort_unstable();
    edges.dedup();
    if min_branch == 0 {
        return edges;
    }
    let adj = Adjacency::new(n, &edges);
    let mut alive = vec![true; edges.len()];
    let mut remove = vec![false; edges.len()];
    let mut degree = vec![0u32; n];
    let mut visited_path = vec![false; n];
    // The first two neighbours of `i` still in the forest, with their edges, in sorted order.
    let first_two = |alive: &[bool], i: usize| {
        let mut it = adj
            .slots(i)
            .map(|s| (adj.neighbours[s] as usize, adj.edge_of[s] as usize))
            .filter(|&(_, e)| alive[e]);
        (it.next(), it.next())
    };
    loop {
        degree.fill(0);
        for (k, &(a, b)) in edges.iter().enumerate() {
            if alive[k] {
                degree[a] += 1;
                degree[b] += 1;
            }
        }
        visited_path.fill(false);
        let mut removing = false;
        for start in 0..n {
            if degree[start] != 1 || visited_path[start] {
                continue;
            }
            // Walk from the end point through degree-2 cells, noting the edges walked.
            let (Some((mut cur, first_edge)), _) = first_two(&alive, start) else {
                continue;
            };
            let mut walked = vec![first_edge];
            let mut prev = start;
            let mut cells = 1usize;
            while degree[cur] == 2 {
                cells += 1;
                let (Some((a, ea)), Some((b, eb))) = first_two(&alive, cur) else {
                    break;
                };
                let (next, e) = if a == prev { (b, eb) } else { (a, ea) };
                prev = cur;
                cur = next;
                walked.push(e);
            }
            let short = if degree[cur] == 1 {
                // A bare path: both ends are end points; remove it when short.
                visited_path[cur] = true;
                cells + 1 < min_branch
            } else {
                // An end branch hanging from the branch point `cur`.
                cells < min_branch
            };
            if short {
                for e in walked {
                    remove[e] = true;
                    removing = true;
                }
            }
        }
        if !removing {
            break;
        }
        for (a, r) in alive.iter_mut().zip(&mut remove) {
            *a &= !*r;
            *r = false;
        }
    }
    edges
        .into_iter()
        .zip(alive)
        .filter_map(|(e, a)| a.then_some(e))
        .collect()
}

/// The paths of a forest: from every key node (degree ≠ 2) along each of its edges to the next
/// key node. Each path is listed once, from its smaller end to its larger (by cell index), and
/// the list is sorted by (first cell, second cell).
pub fn paths(n: usize, edges: &[(usize, usize)], z: &[f32]) -> Vec<FeaturePath> {
    let adj = Adjacency::new(n, edges);
    let mut out: Vec<Vec<usize>> = Vec::new();
    for start in 0..n {
        let d = adj.of(start).len();
        if d == 0 || d == 2 {
            continue;
        }
        for &first in adj.of(start) {
            let mut cells = vec![start];
            let mut prev = start;
            let mut cur = first as usize;
            while let &[a, b] = adj.of(cur) {
                cells.push(cur);
                let (a, b) = (a as usize, b as usize);
                let next = if a == prev { b } else { a };
                prev = cur;
                cur = next;
            }
            cells.push(cur);
            // Listed from the smaller end (each path is found from both ends; a forest has no
            // path from a node back to itself).
            if start < cur {
                out.push(cells);
            }
        }
    }
    sorted_paths(out, z)
}

/// Traced paths sorted by (first cell, second cell), each with its mean elevation on `z`.
pub(crate) fn sorted_paths(mut traced: Vec<Vec<usize>>, z: &[f32]) -> Vec<FeaturePath> {
    traced.sort();
    traced
        .into_iter()
        .map(|cells| {
            let sum: f64 = cells
                .iter()
                .map(|&i| z.get(i).map_or(0.0, |&v| f64::from(v)))
                .sum();
            let mean_elevation = sum / cells.len().max(1) as f64;
            FeaturePath {
                cells,
                mean_elevation,
            }
        })
        .collect()
}

/// The PPA feature tree of `kind` on `z`.
pub fn feature_tree(z: &Array2<f32>, kind: FeatureKind, params: &PpaParams) -> FeatureTree {
    let (rows, cols) = z.dim();
    let n = rows * cols;
    let forest = {
        let o = oriented(z, kind);
        let cand = candidates(&o, rows, cols, params);
        break_polygons(n, segments(&o, rows, cols, &cand))
    };
    let edges = reduce_branches(n, forest, params.min_branch);
    let plain = values(z);
    let paths = paths(n, &edges, &plain);
    FeatureTree {
        kind,
        rows,
        cols,
        edges,
        paths,
    }
}

/// Ridges and valleys of `z`, the two trees computed side by side (rayon's pool; each tree is
/// what [`feature_tree`] alone gives).
pub fn features(z: &Array2<f32>, params: &PpaParams) -> Features {
    let (ridges, valleys) = rayon::join(
        || feature_tree(z, FeatureKind::Ridge, params),
        || feature_tree(z, FeatureKind::Valley, params),
    );
    Features { ridges, valleys }
}

/// How well extracted features agree with D8 drainage (see [`drainage_agreement`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DrainageAgreement {
    /// D8 channel cells (upstream area ≥ the threshold), border cells excluded.
    pub channel_cells: usize,
    /// Share (0–1) of those within `radius` cells (Chebyshev) of a valley cell.
    pub channels_near_valleys: f64,
    /// Ridge cells tested (those with a well-defined cross direction, border excluded).
    pub ridge_cells: usize,
    /// Share (0–1) of ridge cells whose two sides (the cells `radius` away across the ridge)
    /// drain to different D8 basins.
    pub ridges_separating_basins: f64,
    /// Share (0–1) of ridge cells that are D8 channel cells (flow crossing a ridge).
    pub ridges_on_channels: f64,
}

/// The D8 basin of every cell: the channel *link* (stretch of channel between a source or
/// confluence and the next confluence) its flow first enters, or, for flow leaving the grid
/// before reaching a channel, its outlet cell. Returned as a label per cell.
fn basin_labels(rcv: &[usize], channel: &[bool]) -> Vec<usize> {
    let n = rcv.len();
    // A channel cell starts a new link when it is a source or a confluence (≥ 2 channel inflows).
    let mut inflow = vec![0u8; n];
    for i in 0..n {
        if channel[i] && rcv[i] != usize::MAX && channel[rcv[i]] {
            inflow[rcv[i]] = inflow[rcv[i]].saturating_add(1);
        }
    }
    const UNSET: usize = usize::MAX;
    let mut label = vec![UNSET; n];
    // Channel cells: follow each link head down to the next confluence.
    for i in 0..n {
        if !channel[i] || inflow[i] == 1 {
            continue;
        }
        // i heads a link: a source (no channel inflow) or a confluence.
        let mut j = i;
        loop {
            label[j] = i;
            let k = rcv[j];
            if k == usize::MAX || !channel[k] || inflow[k] != 1 {
                break;
            }
            j = k;
        }
    }
    // Other cells: the label of the first labelled cell downstream, or the outlet.
    let mut stack = Vec::new();
    for i in 0..n {
        let mut j = i;
        while label[j] == UNSET {
            stack.push(j);
            if rcv[j] == usize::MAX {
                label[j] = j;
                stack.pop();
                break;
            }
            j = rcv[j];
        }
        let l = label[j];
        for s in stack.drain(..) {
            label[s] = l;
        }
    }
    label
}

/// Measures the acceptance figures on `z`: priority-flood fill, D8 receivers and upstream
/// area; channel cells are those draining at least `area_m2`; basins are the catchments of the
/// channel links. Valleys should cover the channels (`channels_near_valleys`), ridges should
/// separate basins (`ridges_separating_basins`) and not carry channels (`ridges_on_channels`).
/// `radius` is in cells (2 in the acceptance).
pub fn drainage_agreement(
    z: &Array2<f32>,
    cells: &CellSizes,
    features: &Features,
    area_m2: f64,
    radius: usize,
) -> DrainageAgreement {
    let (rows, cols) = z.dim();
    let n = rows * cols;
    let filled = priority_flood_fill(z);
    let codes = d8_receivers(&filled, cells);
    let area = flow_accumulation_from_receivers(&codes, cells);
    let code = values_u8(&codes);
    let rcv: Vec<usize> = (0..n)
        .map(|i| {
            let d = code[i];
            if d == D8_NONE || d >= 8 {
                return usize::MAX;
            }
            let (dr, dc) = D8_OFFSETS[d as usize];
            let (r, c) = (i / cols, i % cols);
            match (r.checked_add_signed(dr), c.checked_add_signed(dc)) {
                (Some(nr), Some(nc)) if nr < rows && nc < cols => nr * cols + nc,
                _ => usize::MAX,
            }
        })
        .collect();
    let area_v: Vec<f64> = area.iter().copied().collect();
    let channel: Vec<bool> = area_v.iter().map(|&a| a >= area_m2).collect();
    let inner = |i: usize| {
        let (r, c) = (i / cols, i % cols);
        r > 0 && c > 0 && r + 1 < rows && c + 1 < cols
    };
    // Channels near valleys: a dilation of the valley mask by `radius` (Chebyshev).
    let valley = features.valleys.mask();
    let near = dilate(&valley, radius);
    let (mut ch, mut ch_near) = (0usize, 0usize);
    for i in 0..n {
        if channel[i] && inner(i) {
            ch += 1;
            if near[i] {
                ch_near += 1;
            }
        }
    }
    // Ridges: cross direction from the ridge's own neighbours.
    let labels = basin_labels(&rcv, &channel);
    let adj = Adjacency::new(n, &features.ridges.edges);
    let (mut tested, mut separating, mut on_channel) = (0usize, 0usize, 0usize);
    let r_i = radius.max(1) as isize;
    for (i, &on_channel_cell) in channel.iter().enumerate() {
        let neighbours = adj.of(i);
        if neighbours.is_empty() || !inner(i) {
            continue;
        }
        // Local direction: from the first to the last neighbour (or to the one neighbour).
        let (r, c) = ((i / cols) as isize, (i % cols) as isize);
        let pos = |j: usize| ((j / cols) as isize, (j % cols) as isize);
        let (ar, ac) = pos(neighbours[0] as usize);
        let (br, bc) = match neighbours {
            [_, .., last] => pos(*last as usize),
            _ => (r, c),
        };
        let (tr, tc) = (ar - br, ac - bc);
        if tr == 0 && tc == 0 {
            continue;
        }
        // The normal, rounded to a grid step, scaled to the radius.
        let (nr, nc) = (tc.signum(), -tr.signum());
        let side = |s: isize| {
            let (rr, cc) = (r + s * nr * r_i, c + s * nc * r_i);
            (rr >= 0 && cc >= 0 && (rr as usize) < rows && (cc as usize) < cols)
                .then(|| rr as usize * cols + cc as usize)
        };
        let (Some(p), Some(q)) = (side(1), side(-1)) else {
            continue;
        };
        tested += 1;
        if labels[p] != labels[q] {
            separating += 1;
        }
        if on_channel_cell {
            on_channel += 1;
        }
    }
    let share = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    DrainageAgreement {
        channel_cells: ch,
        channels_near_valleys: share(ch_near, ch),
        ridge_cells: tested,
        ridges_separating_basins: share(separating, tested),
        ridges_on_channels: share(on_channel, tested),
    }
}

fn values_u8(a: &Array2<u8>) -> Vec<u8> {
    a.iter().copied().collect()
}

/// `mask` dilated by `radius` cells in the Chebyshev metric (a square structuring element),
/// separably: rows then columns.
pub fn dilate(mask: &Array2<bool>, radius: usize) -> Vec<bool> {
    let (rows, cols) = mask.dim();
    let m: Vec<bool> = mask.iter().copied().collect();
    if radius == 0 {
        return m;
    }
    let mut h = vec![false; rows * cols];
    for r in 0..rows {
        // Distance to the last set cell on the left and the next on the right.
        let row = &m[r * cols..(r + 1) * cols];
        let mut last: Option<usize> = None;
        for c in 0..cols {
            if row[c] {
                last = Some(c);
            }
            if last.is_some_and(|l| c - l <= radius) {
                h[r * cols + c] = true;
            }
        }
        let mut next: Option<usize> = None;
        for c in (0..cols).rev() {
            if row[c] {
                next = Some(c);
            }
            if next.is_some_and(|l| l - c <= radius) {
                h[r * cols + c] = true;
            }
        }
    }
    let mut out = vec![false; rows * cols];
    for c in 0..cols {
        let mut last: Option<usize> = None;
        for r in 0..rows {
            if h[r * cols + c] {
                last = Some(r);
            }
            if last.is_some_and(|l| r - l <= radius) {
                out[r * cols + c] = true;
            }
        }
        let mut next: Option<usize> = None;
        for r in (0..rows).rev() {
            if h[r * cols + c] {
                next = Some(r);
            }
            if next.is_some_and(|l| l - r <= radius) {
                out[r * cols + c] = true;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_window_min_matches_scan() {
        let v: Vec<f32> = (0..23).map(|i| ((i * 7) % 11) as f32).collect();
        for w in 1..9 {
            let fast = forward_window_min(&v, w);
            for i in 0..v.len() {
                let want = v[(i + 1).min(v.len())..(i + 1 + w).min(v.len())]
                    .iter()
                    .fold(f32::INFINITY, |m, &a| m.min(a));
                assert_eq!(fast[i], want, "w {w} i {i}");
            }
        }
    }

    #[test]
    fn a_tent_has_one_ridge_line() {
        // A roof whose crest runs along row 5.
        let z = Array2::from_shape_fn((11, 20), |(r, c)| {
            100.0 - 10.0 * (r as f32 - 5.0).abs() + 0.01 * c as f32
        });
        let t = feature_tree(&z, FeatureKind::Ridge, &PpaParams::default());
        assert_eq!(t.paths.len(), 1, "{:?}", t.paths);
        let rows: BTreeSet<usize> = t.paths[0].cells.iter().map(|&i| i / 20).collect();
        assert_eq!(rows, BTreeSet::from([5]));
        let v = feature_tree(&z, FeatureKind::Valley, &PpaParams::default());
        assert!(v.edges.is_empty(), "a roof has no valley: {:?}", v.paths);
    }
}
