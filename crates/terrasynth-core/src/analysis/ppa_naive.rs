//! Straightforward references for the optimised steps of the PPA ([`super::ppa`]): profile
//! recognition by scanning every side of every profile cell by cell; polygon breaking by finding
//! one closed polygon at a time (a depth-first search) and removing its lowest segment; branch
//! reduction and path tracing on a vector of neighbours per cell, the forest rebuilt as a set at
//! every pass. Slow (quadratic or worse) or memory-hungry; meant for property tests on small
//! grids.

use std::collections::BTreeSet;

use super::ppa::{
    segment_order, sorted_paths, FeaturePath, PpaParams, Segment, PROFILE_DIRECTIONS,
};

/// Profile recognition cell by cell: for each cell and direction, the minimum of each side's
/// `window` cells (NaN never lower) is compared with the cell.
pub fn candidates(z: &[f32], rows: usize, cols: usize, params: &PpaParams) -> Vec<bool> {
    let mut out = vec![false; rows * cols];
    if z.len() != rows * cols || params.window == 0 {
        return out;
    }
    let drop = params.min_drop.max(0.0);
    let at = |r: isize, c: isize| -> Option<f32> {
        if r < 0 || c < 0 || r >= rows as isize || c >= cols as isize {
            None
        } else {
            Some(z[r as usize * cols + c as usize])
        }
    };
    for r in 0..rows as isize {
        for c in 0..cols as isize {
            let Some(h) = at(r, c) else { continue };
            for &(dr, dc) in &PROFILE_DIRECTIONS {
                let side = |sign: isize| {
                    (1..=params.window as isize).any(|k| {
                        at(r + sign * k * dr, c + sign * k * dc)
                            .is_some_and(|v| !v.is_nan() && h - v > drop)
                    })
                };
                if side(1) && side(-1) {
                    out[r as usize * cols + c as usize] = true;
                }
            }
        }
    }
    out
}

/// One closed polygon of the graph `edges` (indices into `edges`), if any.
fn find_cycle(n: usize, edges: &[(usize, usize)]) -> Option<Vec<usize>> {
    let mut adj: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (k, &(a, b)) in edges.iter().enumerate() {
        adj[a].push((b, k));
        adj[b].push((a, k));
    }
    let mut depth = vec![usize::MAX; n];
    let mut parent_edge = vec![usize::MAX; n];
    let mut parent = vec![usize::MAX; n];
    for root in 0..n {
        if depth[root] != usize::MAX {
            continue;
        }
        depth[root] = 0;
        let mut stack = vec![root];
        while let Some(u) = stack.pop() {
            for &(v, k) in &adj[u] {
                if k == parent_edge[u] {
                    continue;
                }
                if depth[v] == usize::MAX {
                    depth[v] = depth[u] + 1;
                    parent[v] = u;
                    parent_edge[v] = k;
                    stack.push(v);
                } else {
                    // A non-tree edge closes a polygon: climb both ends to their meeting point.
                    let mut cycle = vec![k];
                    let (mut x, mut y) = (u, v);
                    while x != y {
                        if depth[x] >= depth[y] {
                            cycle.push(parent_edge[x]);
                            x = parent[x];
                        } else {
                            cycle.push(parent_edge[y]);
                            y = parent[y];
                        }
                    }
                    return Some(cycle);
                }
            }
        }
    }
    None
}

/// Polygon breaking one polygon at a time: while the graph has a closed polygon, its lowest
/// segment (the last under [`segment_order`]) is removed. Returns the sorted `(a, b)` pairs left.
pub fn break_polygons(n: usize, segments: &[Segment]) -> Vec<(usize, usize)> {
    let inside = |c: u32| (c as usize) < n;
    let mut segs: Vec<Segment> = segments
        .iter()
        .filter(|s| inside(s.1) && inside(s.2) && s.1 != s.2)
        .map(|s| (s.0, s.1.min(s.2), s.1.max(s.2)))
        .collect();
    let pair = |s: &Segment| (s.1 as usize, s.2 as usize);
    loop {
        let edges: Vec<(usize, usize)> = segs.iter().map(pair).collect();
        let Some(cycle) = find_cycle(n, &edges) else {
            break;
        };
        // The lowest segment is the last one under the order (heavier segments come first).
        let lowest = cycle
            .iter()
            .copied()
            .max_by(|&a, &b| segment_order(&segs[a], &segs[b]));
        match lowest {
            Some(k) => {
                segs.remove(k);
            }
            None => break,
        }
    }
    let mut out: Vec<(usize, usize)> = segs.iter().map(pair).collect();
    out.sort_unstable();
    out
}

/// Adjacency lists of a forest on `n` cells, each sorted.
fn adjacency(n: usize, edges: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut adj = vec![Vec::new(); n];
    for &(a, b) in edges {
        adj[a].push(b);
        adj[b].push(a);
    }
    for l in &mut adj {
        l.sort_unstable();
    }
    adj
}

/// Branch reduction: passes that remove every end branch shorter than `min_branch` cells (the
/// cells from an end point up to, not including, the first branch point) and every tree with
/// fewer than `min_branch` cells, until a pass removes nothing. Each pass decides from the
/// forest as it was at the start of the pass, so the result does not depend on visiting order.
pub fn reduce_branches(
    n: usize,
    edges: &[(usize, usize)],
    min_branch: usize,
) -> Vec<(usize, usize)> {
    let mut kept: BTreeSet<(usize, usize)> = edges.iter().copied().collect();
    if min_branch == 0 {
        return kept.into_iter().collect();
    }
    loop {
        let current: Vec<(usize, usize)> = kept.iter().copied().collect();
        let adj = adjacency(n, &current);
        let mut remove: BTreeSet<(usize, usize)> = BTreeSet::new();
        let mut visited_path = vec![false; n];
        for start in 0..n {
            if adj[start].len() != 1 || visited_path[start] {
                continue;
            }
            // Walk from the end point through degree-2 cells.
            let mut walk = vec![start];
            let mut prev = start;
            let mut cur = adj[start][0];
            let mut walked: Vec<(usize, usize)> = vec![(start.min(cur), start.max(cur))];
            while adj[cur].len() == 2 {
                walk.push(cur);
                let next = if adj[cur][0] == prev {
                    adj[cur][1]
                } else {
                    adj[cur][0]
                };
                prev = cur;
                cur = next;
                walked.push((prev.min(cur), prev.max(cur)));
            }
            if adj[cur].len() == 1 {
                // A bare path: both ends are end points; remove it when short.
                visited_path[cur] = true;
                walk.push(cur);
                if walk.len() < min_branch {
                    remove.extend(walked);
                }
            } else if walk.len() < min_branch {
                // An end branch hanging from the branch point `cur`.
                remove.extend(walked);
            }
        }
        if remove.is_empty() {
            break;
        }
        for e in &remove {
            kept.remove(e);
        }
    }
    kept.into_iter().collect()
}

/// The paths of a forest: from every key node (degree ≠ 2) along each of its edges to the next
/// key node. Each path is listed once, from its smaller end to its larger (by cell index), and
/// the list is sorted by (first cell, second cell).
pub fn paths(n: usize, edges: &[(usize, usize)], z: &[f32]) -> Vec<FeaturePath> {
    let adj = adjacency(n, edges);
    let mut out: Vec<Vec<usize>> = Vec::new();
    for start in 0..n {
        let d = adj[start].len();
        if d == 0 || d == 2 {
            continue;
        }
        for &first in &adj[start] {
            let mut cells = vec![start];
            let mut prev = start;
            let mut cur = first;
            while adj[cur].len() == 2 {
                cells.push(cur);
                let next = if adj[cur][0] == prev {
                    adj[cur][1]
                } else {
                    adj[cur][0]
                };
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
