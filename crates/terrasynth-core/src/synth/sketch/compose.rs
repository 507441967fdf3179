//! The composite a sketch world is built in: heights, which patch each cell came from, the
//! guidance gradient of every edge between 4-adjacent cells (for the Poisson solve), and the
//! cells that protect an already placed sketch line. A new patch is joined to what is there
//! along a minimum graph cut over the overlap ([`super::graphcut`]): edge costs
//! `|A(p) − B(p)| + |A(q) − B(q)|` (Kwatra et al. 2003), overlap cells next to cells only the new
//! patch covers bound to the new patch, overlap cells next to old cells outside it bound to the
//! old content, and so are cells protecting another line. Across a seam the guidance is the mean
//! of the two patches' own differences.

use super::graphcut::{FlowGraph, HARD};

/// Steps (metres) below which ground counts as flat in the seam cost: keeps the cost finite and
/// makes disagreements on flats expensive.
pub const SEAM_STEP_FLOOR: f64 = 1.0;

/// A patch laid on the output grid.
#[derive(Clone, Debug)]
pub struct Patch {
    /// Top-left row of its window.
    pub row0: usize,
    /// Top-left column of its window.
    pub col0: usize,
    /// Window rows.
    pub rows: usize,
    /// Window columns.
    pub cols: usize,
    /// Heights, row-major; NaN where the patch has no value.
    pub values: Vec<f64>,
    /// Whether each cell holds water in its exemplar (a natural depression); empty: none does.
    pub wet: Vec<bool>,
}

impl Patch {
    fn at(&self, r: usize, c: usize) -> Option<f64> {
        if r < self.row0
            || c < self.col0
            || r >= self.row0 + self.rows
            || c >= self.col0 + self.cols
        {
            return None;
        }
        let v = self.values[(r - self.row0) * self.cols + (c - self.col0)];
        (!v.is_nan()).then_some(v)
    }
}

/// How a placement went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Placed {
    /// Cells the new patch took.
    pub taken: usize,
    /// Of those, cells that were covered before.
    pub replaced: usize,
    /// Cost of the cut.
    pub cut_cost: f64,
}

/// The composite.
#[derive(Clone, Debug)]
pub struct Composite {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Heights (meaningful where covered).
    pub h: Vec<f64>,
    /// Patch of each cell, 1-based; 0 = not covered yet.
    pub label: Vec<u32>,
    /// Guidance of horizontal edges, `(r, c) → (r, c+1)` at `r·(cols−1) + c`.
    pub gx: Vec<f64>,
    /// Guidance of vertical edges, `(r, c) → (r+1, c)` at `r·cols + c`.
    pub gy: Vec<f64>,
    /// The sketch path protecting each cell, 1-based; 0 = none.
    pub protect: Vec<u32>,
    /// Whether each cell held water in the exemplar it came from.
    pub wet: Vec<bool>,
    patches: u32,
}

/// Which cells a placement must leave alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protection<'a> {
    /// Cells protected by any path.
    All,
    /// Cells protected by paths other than these.
    Except(&'a [u32]),
}

impl Composite {
    /// An empty composite.
    pub fn new(rows: usize, cols: usize) -> Self {
        let n = rows * cols;
        Composite {
            rows,
            cols,
            h: vec![0.0; n],
            label: vec![0; n],
            gx: vec![0.0; rows * cols.saturating_sub(1)],
            gy: vec![0.0; rows.saturating_sub(1) * cols],
            protect: vec![0; n],
            wet: vec![false; n],
            patches: 0,
        }
    }

    /// Whether cell `i` is covered.
    pub fn covered(&self, i: usize) -> bool {
        self.label[i] != 0
    }

    /// Number of patches placed.
    pub fn patches(&self) -> u32 {
        self.patches
    }

    fn protected(&self, i: usize, p: Protection<'_>) -> bool {
        let v = self.protect[i];
        v != 0
            && match p {
                Protection::All => true,
                Protection::Except(own) => !own.contains(&(v - 1)),
            }
    }

    /// Lays `patch` over the composite: the cells it takes are decided by a minimum cut over the
    /// overlap; `force` lists cells (row-major) it must take unless protected. Returns what
    /// happened.
    pub fn place(&mut self, patch: &Patch, force: &[usize], protection: Protection<'_>) -> Placed {
        let (rows, cols) = (self.rows, self.cols);
        let r_end = (patch.row0 + patch.rows).min(rows);
        let c_end = (patch.col0 + patch.cols).min(cols);
        if patch.row0 >= r_end || patch.col0 >= c_end {
            return Placed::default();
        }
        let (wr, wc) = (r_end - patch.row0, c_end - patch.col0);
        let idx = |r: usize, c: usize| r * cols + c;
        // Overlap nodes.
        let mut node = vec![usize::MAX; wr * wc];
        let mut cells: Vec<(usize, usize)> = Vec::new();
        for r in patch.row0..r_end {
            for c in patch.col0..c_end {
                if patch.at(r, c).is_some() && self.covered(idx(r, c)) {
                    node[(r - patch.row0) * wc + (c - patch.col0)] = cells.len();
                    cells.push((r, c));
                }
            }
        }
        let node_of = |r: usize, c: usize| -> Option<usize> {
            if r < patch.row0 || c < patch.col0 || r >= r_end || c >= c_end {
                return None;
            }
            let k = node[(r - patch.row0) * wc + (c - patch.col0)];
            (k != usize::MAX).then_some(k)
        };
        let mut take = vec![false; cells.len()];
        let mut cut_cost = 0.0;
        if !cells.is_empty() {
            let mut g = FlowGraph::new(cells.len());
            let forced: std::collections::BTreeSet<usize> = force.iter().copied().collect();
            for (k, &(r, c)) in cells.iter().enumerate() {
                let i = idx(r, c);
                let (mut keep, mut new) = (false, false);
                if self.protected(i, protection) {
                    keep = true;
                }
                if forced.contains(&i) {
                    new = true;
                }
                let mut neighbours = [None; 4];
                if r > 0 {
                    neighbours[0] = Some((r - 1, c));
                }
                if r + 1 < rows {
                    neighbours[1] = Some((r + 1, c));
                }
                if c > 0 {
                    neighbours[2] = Some((r, c - 1));
                }
                if c + 1 < cols {
                    neighbours[3] = Some((r, c + 1));
                }
                for (nr, nc) in neighbours.into_iter().flatten() {
                    let j = idx(nr, nc);
                    let in_patch = patch.at(nr, nc).is_some();
                    if in_patch && !self.covered(j) {
                        new = true; // next to a cell only the new patch covers
                    } else if !in_patch && self.covered(j) {
                        keep = true; // next to old content the patch does not reach
                    }
                }
                if keep {
                    g.add_terminal(k, HARD, 0.0);
                } else if new {
                    g.add_terminal(k, 0.0, HARD);
                }
                // Edges to the right and down neighbours in the overlap: the disagreement of the
                // two patches, divided by their steps along the edge (Kwatra et al. 2003, eq. 2),
                // so that seams prefer rough ground, where a step shows least, to flats, where it
                // dams valleys.
                let diff = |r: usize, c: usize| -> f64 {
                    let b = patch.at(r, c).unwrap_or(0.0);
                    (self.h[idx(r, c)] - b).abs()
                };
                let here = diff(r, c);
                for (nr, nc) in [(r, c + 1), (r + 1, c)] {
                    if let Some(m) = node_of(nr, nc) {
                        let ga = (self.h[idx(nr, nc)] - self.h[idx(r, c)]).abs();
                        let gb = match (patch.at(r, c), patch.at(nr, nc)) {
                            (Some(a), Some(b)) => (b - a).abs(),
                            _ => 0.0,
                        };
                        let w = (here + diff(nr, nc)) / (ga + gb + SEAM_STEP_FLOOR);
                        g.add_edge(k, m, w + 1e-6);
                    }
                }
            }
            cut_cost = g.max_flow();
            let source = g.source_side();
            for k in 0..cells.len() {
                take[k] = !source[k];
            }
        }
        // Which window cells the new patch takes.
        let mut takes = vec![false; wr * wc];
        for r in patch.row0..r_end {
            for c in patch.col0..c_end {
                let w = (r - patch.row0) * wc + (c - patch.col0);
                takes[w] = match node_of(r, c) {
                    Some(k) => take[k],
                    None => patch.at(r, c).is_some(),
                };
            }
        }
        let takes_at = |r: usize, c: usize| -> bool {
            r >= patch.row0 && c >= patch.col0 && r < r_end && c < c_end && {
                takes[(r - patch.row0) * wc + (c - patch.col0)]
            }
        };
        // Guidance of the edges touching the window, decided before heights change.
        let r_lo = patch.row0.saturating_sub(1);
        let c_lo = patch.col0.saturating_sub(1);
        let mut new_gx: Vec<(usize, f64)> = Vec::new();
        let mut new_gy: Vec<(usize, f64)> = Vec::new();
        let new_h = |r: usize, c: usize| -> f64 {
            if takes_at(r, c) {
                patch.at(r, c).unwrap_or(0.0)
            } else {
                self.h[idx(r, c)]
            }
        };
        let edge = |p: (usize, usize), q: (usize, usize), old_g: f64| -> Option<f64> {
            let (np, nq) = (takes_at(p.0, p.1), takes_at(q.0, q.1));
            if !np && !nq {
                return None;
            }
            let gb = match (patch.at(p.0, p.1), patch.at(q.0, q.1)) {
                (Some(a), Some(b)) => Some(b - a),
                _ => None,
            };
            if np && nq {
                return gb;
            }
            let ga = (self.covered(idx(p.0, p.1)) && self.covered(idx(q.0, q.1))).then_some(old_g);
            Some(match (ga, gb) {
                (Some(a), Some(b)) => 0.5 * (a + b),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => new_h(q.0, q.1) - new_h(p.0, p.1),
            })
        };
        for r in r_lo..r_end.min(rows) {
            for c in c_lo..c_end.min(cols) {
                if c + 1 < cols {
                    let e = r * (cols - 1) + c;
                    if let Some(g) = edge((r, c), (r, c + 1), self.gx[e]) {
                        new_gx.push((e, g));
                    }
                }
                if r + 1 < rows {
                    let e = r * cols + c;
                    if let Some(g) = edge((r, c), (r + 1, c), self.gy[e]) {
                        new_gy.push((e, g));
                    }
                }
            }
        }
        for (e, g) in new_gx {
            self.gx[e] = g;
        }
        for (e, g) in new_gy {
            self.gy[e] = g;
        }
        self.patches += 1;
        let id = self.patches;
        let mut placed = Placed {
            cut_cost,
            ..Placed::default()
        };
        for r in patch.row0..r_end {
            for c in patch.col0..c_end {
                if takes_at(r, c) {
                    let i = idx(r, c);
                    if self.covered(i) {
                        placed.replaced += 1;
                    }
                    placed.taken += 1;
                    self.h[i] = patch.at(r, c).unwrap_or(0.0);
                    self.label[i] = id;
                    self.wet[i] = patch
                        .wet
                        .get((r - patch.row0) * patch.cols + (c - patch.col0))
                        .copied()
                        .unwrap_or(false);
                }
            }
        }
        placed
    }

    /// Marks cells as protecting sketch path `path` (those not protecting another already).
    pub fn protect_cells(&mut self, cells: &[usize], path: u32) {
        for &i in cells {
            if i < self.protect.len() && self.protect[i] == 0 {
                self.protect[i] = path + 1;
            }
        }
    }

    /// Seam edges (4-adjacent cells from different patches): `(horizontal, vertical)` masks in
    /// the layout of [`Composite::gx`] and [`Composite::gy`].
    pub fn seams(&self) -> (Vec<bool>, Vec<bool>) {
        let (rows, cols) = (self.rows, self.cols);
        let mut h = vec![false; rows * cols.saturating_sub(1)];
        let mut v = vec![false; rows.saturating_sub(1) * cols];
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                if c + 1 < cols {
                    h[r * (cols - 1) + c] = self.label[i] != self.label[i + 1];
                }
                if r + 1 < rows {
                    v[i] = self.label[i] != self.label[i + cols];
                }
            }
        }
        (h, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seam_runs_where_patches_agree() {
        // Old content: 0 everywhere on the left 12 columns. New patch over columns 4..16 equals
        // the old content only on column 9; elsewhere it differs by 10.
        let mut comp = Composite::new(6, 16);
        let left = Patch {
            row0: 0,
            col0: 0,
            rows: 6,
            cols: 12,
            values: vec![0.0; 72],
            wet: Vec::new(),
        };
        comp.place(&left, &[], Protection::All);
        let values: Vec<f64> = (0..6 * 12)
            .map(|k| if k % 12 == 5 { 0.0 } else { 10.0 })
            .collect();
        let right = Patch {
            row0: 0,
            col0: 4,
            rows: 6,
            cols: 12,
            values,
            wet: Vec::new(),
        };
        let placed = comp.place(&right, &[], Protection::All);
        // The cut runs beside column 9: columns ≤ 8 or ≤ 9 stay old.
        for r in 0..6 {
            assert_eq!(comp.label[r * 16 + 8], 1);
            assert_eq!(comp.label[r * 16 + 10], 2);
        }
        assert!(placed.cut_cost < 6.0 * 11.0 / SEAM_STEP_FLOOR, "{placed:?}");
        let (h, _) = comp.seams();
        assert_eq!(h.iter().filter(|&&s| s).count(), 6);
    }
}
