//! The sketch's feature trees and the order in which patches are placed along them. Each kind's
//! lines are drawn into the output grid (the cells whose centre lies within `√2/2` of a line) and
//! connected as the PPA connects candidates ([`crate::analysis::ppa`]: segments between adjacent
//! cells, weighted by closeness to the lines; polygon breaking; pruning of the one- or two-cell
//! spurs a drawn line leaves), so a sketch gets the same description as an exemplar: a forest of
//! end points, branch points (where lines meet or cross) and paths. Patch centres are every key
//! point and points every `spacing` cells along each path, in breadth-first order of each tree
//! from its root (its branch point of highest degree, else its first end point); larger trees
//! first.

use std::collections::VecDeque;

use crate::analysis::ppa::{break_polygons, paths, reduce_branches, FeatureKind, NodeClass};
use crate::math;

use super::geometry::{dist, Sketch};

/// Cells closer than this to a line (cell centre to line, cells) belong to it.
const LINE_HALF_WIDTH: f64 = std::f64::consts::FRAC_1_SQRT_2 + 1e-9;

/// A cell of a sketch tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SketchCell {
    /// Cell coordinates `(x, y)` of its centre.
    pub pos: [f64; 2],
    /// Ridge or valley.
    pub kind: FeatureKind,
    /// The path it lies on (ids are global over both kinds); a key point lies on several and
    /// keeps the first.
    pub path: u32,
    /// The height asked for by the nearest line, metres.
    pub height_m: Option<f64>,
    /// Its index along its path (from the path's first cell).
    pub along: u32,
}

/// Where a patch goes.
#[derive(Clone, Debug, PartialEq)]
pub struct Centre {
    /// Cell coordinates of the centre.
    pub pos: [f64; 2],
    /// The feature it sits on.
    pub kind: FeatureKind,
    /// End, path or branch point.
    pub class: NodeClass,
    /// Directions (radians, `atan2(dy, dx)` in cell coordinates) of the tree's arms leaving it.
    pub arms: Vec<f64>,
    /// Paths through it.
    pub paths: Vec<u32>,
    /// Its index along each of those paths.
    pub along: Vec<u32>,
    /// The height asked for there, metres.
    pub height_m: Option<f64>,
    /// For a valley centre: cells along its tree down to the tree's outlet.
    pub drain: Option<f64>,
}

/// A sketch's trees: every cell of them, and the patch centres in placement order.
#[derive(Clone, Debug, PartialEq)]
pub struct SketchTrees {
    /// Every tree cell.
    pub cells: Vec<SketchCell>,
    /// Patch centres in placement order.
    pub centres: Vec<Centre>,
    /// Number of paths (ids `0..paths`).
    pub paths: u32,
    /// For each path, which way water runs: `+1` when heights should fall with increasing
    /// [`SketchCell::along`], `−1` when they should rise; `0` for ridges. Every valley tree
    /// drains to its outlet, the end point nearest the grid's border.
    pub descent: Vec<f64>,
}

/// Distance from `p` to segment `ab`.
fn point_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (vx, vy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = vx * vx + vy * vy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * vx + (p[1] - a[1]) * vy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, [a[0] + t * vx, a[1] + t * vy])
}

/// One kind's tree: the drawn cells' distance to their line and the line's height.
struct Drawn {
    /// Distance of each cell to the nearest line of the kind (∞ when not drawn).
    d: Vec<f64>,
    height: Vec<Option<f64>>,
}

fn draw(sketch: &Sketch, kind: FeatureKind) -> Drawn {
    let (rows, cols) = (sketch.grid.rows, sketch.grid.cols);
    let mut d = vec![f64::INFINITY; rows * cols];
    let mut height = vec![None; rows * cols];
    for line in sketch.lines.iter().filter(|l| l.kind == kind) {
        for w in line.points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let lo_x = (a[0].min(b[0]) - 1.0).floor().max(0.0) as usize;
            let hi_x = ((a[0].max(b[0]) + 1.0).ceil().max(0.0) as usize).min(cols - 1);
            let lo_y = (a[1].min(b[1]) - 1.0).floor().max(0.0) as usize;
            let hi_y = ((a[1].max(b[1]) + 1.0).ceil().max(0.0) as usize).min(rows - 1);
            for r in lo_y..=hi_y {
                for c in lo_x..=hi_x {
                    let e = point_segment([c as f64, r as f64], a, b);
                    let i = r * cols + c;
                    if e <= LINE_HALF_WIDTH && e < d[i] {
                        d[i] = e;
                        height[i] = line.height_m;
                    }
                }
            }
        }
    }
    Drawn { d, height }
}

/// Cells `steps` along the tree from `from` through `first` (stopping at key nodes); the last.
fn walk(adj: &[Vec<usize>], from: usize, first: usize, steps: usize) -> usize {
    let (mut prev, mut cur) = (from, first);
    for _ in 1..steps {
        if adj[cur].len() != 2 {
            break;
        }
        let next = if adj[cur][0] == prev {
            adj[cur][1]
        } else {
            adj[cur][0]
        };
        prev = cur;
        cur = next;
    }
    cur
}

/// The trees of `sketch` and patch centres every `spacing` cells.
pub fn sketch_trees(sketch: &Sketch, spacing: usize) -> SketchTrees {
    let (rows, cols) = (sketch.grid.rows, sketch.grid.cols);
    let n = rows * cols;
    let spacing = spacing.max(1);
    let mut cells = Vec::new();
    // (component size, kind, root, centres in BFS order)
    let mut components: Vec<(usize, FeatureKind, usize, Vec<Centre>)> = Vec::new();
    let mut path_base = 0u32;
    let mut descent: Vec<f64> = Vec::new();
    for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
        let drawn = draw(sketch, kind);
        let mask: Vec<bool> = drawn.d.iter().map(|v| v.is_finite()).collect();
        // Segments weighted so that cells nearer the line are preferred.
        let weight: Vec<f32> = drawn.d.iter().map(|&v| (-v) as f32).collect();
        let segs = crate::analysis::ppa::segments(&weight, rows, cols, &mask);
        let forest = break_polygons(n, segs);
        let edges = reduce_branches(n, forest, 3);
        let tree_paths = paths(n, &edges, &weight);
        descent.resize(path_base as usize + tree_paths.len(), 0.0);
        let mut adj = vec![Vec::new(); n];
        for &(a, b) in &edges {
            adj[a].push(b);
            adj[b].push(a);
        }
        for l in &mut adj {
            l.sort_unstable();
        }
        // Path ids of every cell (a key point keeps the first path listing it).
        let mut path_of = vec![u32::MAX; n];
        let mut along = vec![0u32; n];
        let mut paths_at: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
        for (k, p) in tree_paths.iter().enumerate() {
            let id = path_base + k as u32;
            for (j, &i) in p.cells.iter().enumerate() {
                if path_of[i] == u32::MAX {
                    path_of[i] = id;
                    along[i] = j as u32;
                }
                if paths_at[i].last().map(|l| l.0) != Some(id) {
                    paths_at[i].push((id, j as u32));
                }
            }
        }
        let pos = |i: usize| [(i % cols) as f64, (i / cols) as f64];
        for i in 0..n {
            if path_of[i] != u32::MAX {
                cells.push(SketchCell {
                    pos: pos(i),
                    kind,
                    path: path_of[i],
                    height_m: drawn.height[i],
                    along: along[i],
                });
            }
        }
        // Components, each traversed breadth-first from its root.
        let mut seen = vec![false; n];
        for start in 0..n {
            if adj[start].is_empty() || seen[start] {
                continue;
            }
            // Collect the component.
            let mut comp = vec![start];
            seen[start] = true;
            let mut k = 0;
            while k < comp.len() {
                let u = comp[k];
                for &v in &adj[u] {
                    if !seen[v] {
                        seen[v] = true;
                        comp.push(v);
                    }
                }
                k += 1;
            }
            let root = comp
                .iter()
                .copied()
                .filter(|&i| adj[i].len() >= 3)
                .max_by(|&a, &b| adj[a].len().cmp(&adj[b].len()).then(b.cmp(&a)))
                .or_else(|| comp.iter().copied().filter(|&i| adj[i].len() == 1).min())
                .unwrap_or(start);
            // Breadth-first ranks and distances.
            let mut rank = vec![usize::MAX; n];
            let mut depth = vec![0usize; n];
            let mut order = Vec::with_capacity(comp.len());
            let mut q = VecDeque::from([root]);
            rank[root] = 0;
            while let Some(u) = q.pop_front() {
                order.push(u);
                for &v in &adj[u] {
                    if rank[v] == usize::MAX {
                        rank[v] = order.len() + q.len();
                        depth[v] = depth[u] + 1;
                        q.push_back(v);
                    }
                }
            }
            for (r, &u) in order.iter().enumerate() {
                rank[u] = r;
            }
            // Centres: key points, and every `spacing` cells along each path from the end the
            // traversal reaches first (none closer than spacing/2 to the far end).
            let mut chosen: Vec<usize> = comp
                .iter()
                .copied()
                .filter(|&i| adj[i].len() != 2)
                .collect();
            for p in tree_paths.iter().filter(|p| rank[p.cells[0]] != usize::MAX) {
                let mut seq = p.cells.clone();
                if rank[seq[0]] > rank[seq[seq.len() - 1]] {
                    seq.reverse();
                }
                let len = seq.len() - 1;
                let mut at = spacing;
                while at + spacing / 2 <= len {
                    chosen.push(seq[at]);
                    at += spacing;
                }
            }
            chosen.sort_by_key(|&i| rank[i]);
            chosen.dedup();
            let centres: Vec<Centre> = chosen
                .into_iter()
                .map(|i| {
                    let arms = adj[i]
                        .iter()
                        .map(|&first| {
                            let end = walk(&adj, i, first, 5);
                            let (a, b) = (pos(i), pos(end));
                            math::atan2(b[1] - a[1], b[0] - a[0])
                        })
                        .collect();
                    Centre {
                        pos: pos(i),
                        kind,
                        class: NodeClass::of_degree(adj[i].len()),
                        arms,
                        paths: paths_at[i].iter().map(|p| p.0).collect(),
                        along: paths_at[i].iter().map(|p| p.1).collect(),
                        height_m: drawn.height[i],
                        drain: None,
                    }
                })
                .collect();
            let mut centres = centres;
            if kind == FeatureKind::Valley {
                // Distances along the tree from the outlet: the end point nearest the border.
                let border = |i: usize| {
                    let (r, c) = (i / cols, i % cols);
                    r.min(c).min(rows - 1 - r).min(cols - 1 - c)
                };
                let outlet = comp
                    .iter()
                    .copied()
                    .filter(|&i| adj[i].len() == 1)
                    .min_by(|&a, &b| border(a).cmp(&border(b)).then(a.cmp(&b)))
                    .unwrap_or(root);
                let mut from_outlet = vec![usize::MAX; n];
                from_outlet[outlet] = 0;
                let mut q = VecDeque::from([outlet]);
                while let Some(u) = q.pop_front() {
                    for &v in &adj[u] {
                        if from_outlet[v] == usize::MAX {
                            from_outlet[v] = from_outlet[u] + 1;
                            q.push_back(v);
                        }
                    }
                }
                for (k, p) in tree_paths.iter().enumerate() {
                    let (a, b) = (p.cells[0], p.cells[p.cells.len() - 1]);
                    if from_outlet[a] == usize::MAX {
                        continue;
                    }
                    // Heights fall towards the outlet.
                    descent[path_base as usize + k] = if from_outlet[b] < from_outlet[a] {
                        1.0
                    } else {
                        -1.0
                    };
                }
                for c in &mut centres {
                    let i = c.pos[1] as usize * cols + c.pos[0] as usize;
                    if from_outlet[i] != usize::MAX {
                        c.drain = Some(from_outlet[i] as f64);
                    }
                }
            }
            components.push((comp.len(), kind, root, centres));
        }
        path_base += tree_paths.len() as u32;
    }
    components.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    SketchTrees {
        cells,
        centres: components.into_iter().flat_map(|c| c.3).collect(),
        paths: path_base,
        descent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Georef;
    use crate::synth::sketch::geometry::{OutputGrid, SketchLine};

    #[test]
    fn a_y_of_ridges_has_one_branch_and_three_ends() {
        let grid = OutputGrid {
            georef: Georef::local_metric(1.0),
            rows: 80,
            cols: 80,
        };
        let line = |pts: Vec<[f64; 2]>| SketchLine {
            kind: FeatureKind::Ridge,
            points: pts,
            height_m: None,
        };
        let sketch = Sketch {
            grid,
            lines: vec![
                line(vec![[10.0, 40.0], [40.0, 40.0]]),
                line(vec![[40.0, 40.0], [70.0, 10.0]]),
                line(vec![[40.0, 40.0], [70.0, 70.3]]),
            ],
        };
        let t = sketch_trees(&sketch, 12);
        let branches = t
            .centres
            .iter()
            .filter(|c| c.class == NodeClass::Branch)
            .count();
        let ends = t
            .centres
            .iter()
            .filter(|c| c.class == NodeClass::End)
            .count();
        assert_eq!((branches, ends), (1, 3), "{:?}", t.centres);
        // The branch point is the root: placed first.
        assert_eq!(t.centres[0].class, NodeClass::Branch);
        assert!(dist(t.centres[0].pos, [40.0, 40.0]) <= 1.5);
        assert_eq!(t.centres[0].arms.len(), 3);
        assert_eq!(t.paths, 3);
        assert!(t.centres.len() >= 4 + 3);
    }
}
