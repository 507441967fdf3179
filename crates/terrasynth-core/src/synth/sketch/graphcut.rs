//! Minimum s–t cuts by maximum flow (Dinic's algorithm: breadth-first levels, then blocking flows
//! along level-increasing paths, with an explicit stack so that deep graphs cannot overflow the
//! thread's stack). Patches are joined along the cut of least total disagreement (Kwatra et al.
//! 2003, "Graphcut textures"). [`naive_min_cut`] enumerates every assignment of a small graph;
//! property tests compare the two. Deterministic: edges are visited in insertion order.

use std::collections::VecDeque;

/// Capacity standing for "never cut" (hard constraints).
pub const HARD: f64 = 1e18;

/// A flow network over `n` nodes plus a source and a sink.
#[derive(Clone, Debug)]
pub struct FlowGraph {
    n: usize,
    /// Per edge: head, residual capacity; edge `e ^ 1` is its reverse.
    head: Vec<usize>,
    cap: Vec<f64>,
    /// Adjacency: edge indices out of each node.
    adj: Vec<Vec<usize>>,
    /// Every edge as added (for the naive twin and cut costs): `(from, to, capacity)`.
    added: Vec<(usize, usize, f64)>,
}

impl FlowGraph {
    /// A network of `n` inner nodes; the source is node `n`, the sink `n + 1`.
    pub fn new(n: usize) -> Self {
        FlowGraph {
            n,
            head: Vec::new(),
            cap: Vec::new(),
            adj: vec![Vec::new(); n + 2],
            added: Vec::new(),
        }
    }

    /// The source node.
    pub fn source(&self) -> usize {
        self.n
    }

    /// The sink node.
    pub fn sink(&self) -> usize {
        self.n + 1
    }

    fn push_edge(&mut self, a: usize, b: usize, c_ab: f64, c_ba: f64) {
        let e = self.head.len();
        self.head.push(b);
        self.cap.push(c_ab);
        self.adj[a].push(e);
        self.head.push(a);
        self.cap.push(c_ba);
        self.adj[b].push(e + 1);
    }

    /// An undirected edge of capacity `c` between inner nodes `a` and `b`.
    pub fn add_edge(&mut self, a: usize, b: usize, c: f64) {
        if a == b || a >= self.n || b >= self.n || c.is_nan() || c <= 0.0 {
            return;
        }
        self.push_edge(a, b, c, c);
        self.added.push((a, b, c));
        self.added.push((b, a, c));
    }

    /// A terminal edge: source → `a` with capacity `to_source_side` (what cutting `a` away from
    /// the source costs) and `a` → sink with `to_sink_side`.
    pub fn add_terminal(&mut self, a: usize, to_source_side: f64, to_sink_side: f64) {
        if a >= self.n {
            return;
        }
        let (s, t) = (self.source(), self.sink());
        if to_source_side > 0.0 {
            self.push_edge(s, a, to_source_side, 0.0);
            self.added.push((s, a, to_source_side));
        }
        if to_sink_side > 0.0 {
            self.push_edge(a, t, to_sink_side, 0.0);
            self.added.push((a, t, to_sink_side));
        }
    }

    /// Levels from the source over edges with residual capacity; `None` when the sink is not
    /// reached.
    fn levels(&self) -> Option<Vec<usize>> {
        let mut level = vec![usize::MAX; self.n + 2];
        let s = self.source();
        level[s] = 0;
        let mut q = VecDeque::from([s]);
        while let Some(u) = q.pop_front() {
            for &e in &self.adj[u] {
                let v = self.head[e];
                if self.cap[e] > 0.0 && level[v] == usize::MAX {
                    level[v] = level[u] + 1;
                    q.push_back(v);
                }
            }
        }
        (level[self.sink()] != usize::MAX).then_some(level)
    }

    /// Runs Dinic's algorithm; the maximum flow value. Returns the source side of a minimum
    /// cut with [`FlowGraph::source_side`].
    pub fn max_flow(&mut self) -> f64 {
        let (s, t) = (self.source(), self.sink());
        let mut total = 0.0;
        while let Some(level) = self.levels() {
            let mut next = vec![0usize; self.n + 2];
            loop {
                // One augmenting path along increasing levels (iterative depth-first search).
                let mut path: Vec<usize> = Vec::new(); // edges
                let mut u = s;
                let found = loop {
                    if u == t {
                        break true;
                    }
                    let mut advanced = false;
                    while next[u] < self.adj[u].len() {
                        let e = self.adj[u][next[u]];
                        let v = self.head[e];
                        if self.cap[e] > 0.0 && level[v] == level[u] + 1 {
                            path.push(e);
                            u = v;
                            advanced = true;
                            break;
                        }
                        next[u] += 1;
                    }
                    if !advanced {
                        // Dead end: retreat and skip the edge that led here.
                        match path.pop() {
                            Some(e) => {
                                u = self.head[e ^ 1];
                                next[u] += 1;
                            }
                            None => break false,
                        }
                    }
                };
                if !found {
                    break;
                }
                let push = path.iter().fold(f64::INFINITY, |m, &e| m.min(self.cap[e]));
                for &e in &path {
                    self.cap[e] -= push;
                    self.cap[e ^ 1] += push;
                }
                total += push;
            }
        }
        total
    }

    /// After [`FlowGraph::max_flow`]: `true` for inner nodes on the source side of the minimum
    /// cut (reachable from the source in the residual network).
    pub fn source_side(&self) -> Vec<bool> {
        let mut seen = vec![false; self.n + 2];
        let s = self.source();
        seen[s] = true;
        let mut stack = vec![s];
        while let Some(u) = stack.pop() {
            for &e in &self.adj[u] {
                let v = self.head[e];
                if self.cap[e] > 0.0 && !seen[v] {
                    seen[v] = true;
                    stack.push(v);
                }
            }
        }
        seen.truncate(self.n);
        seen
    }

    /// The cost of the cut that puts `side[i] == true` nodes with the source.
    pub fn cut_cost(&self, side: &[bool]) -> f64 {
        let (s, t) = (self.source(), self.sink());
        let on_source = |v: usize| v == s || (v != t && side.get(v) == Some(&true));
        self.added
            .iter()
            .filter(|&&(a, b, _)| on_source(a) && !on_source(b))
            .map(|&(_, _, c)| c)
            .sum()
    }
}

/// Reference: the minimum cut of `g` by trying every assignment of its inner nodes (at most 20);
/// its cost and the first optimal assignment in binary-counting order.
pub fn naive_min_cut(g: &FlowGraph) -> Option<(f64, Vec<bool>)> {
    let n = g.n;
    if n > 20 {
        return None;
    }
    let mut best: Option<(f64, Vec<bool>)> = None;
    for bits in 0u32..(1u32 << n) {
        let side: Vec<bool> = (0..n).map(|i| bits & (1 << i) != 0).collect();
        let c = g.cut_cost(&side);
        if best.as_ref().is_none_or(|(b, _)| c < *b) {
            best = Some((c, side));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_is_cut_at_its_weakest_link() {
        let mut g = FlowGraph::new(4);
        g.add_terminal(0, HARD, 0.0);
        g.add_terminal(3, 0.0, HARD);
        g.add_edge(0, 1, 5.0);
        g.add_edge(1, 2, 1.5);
        g.add_edge(2, 3, 4.0);
        let f = g.max_flow();
        assert_eq!(f, 1.5);
        assert_eq!(g.source_side(), vec![true, true, false, false]);
        assert_eq!(naive_min_cut(&g).map(|b| b.0), Some(1.5));
    }
}
