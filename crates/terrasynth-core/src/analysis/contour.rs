//! Contour lines of a grid by marching squares: the crossings of each level on the edges between
//! pixel centres ([`contour_segments`]), joined into polylines ([`join_segments`],
//! [`contour_lines`]).
//!
//! Conventions, shared with the naive twin
//! [`contour_segments_naive`](super::naive::contour_segments_naive): a value `v` is *above* level
//! `L` when `v >= L`; an edge crosses `L` when its two ends are on different sides; the
//! crossing lies at `t = (L − a) / (b − a)` from the edge's first end `a` (the one with the
//! smaller row, then column), so that the two cells sharing an edge compute the same point, bit
//! for bit. A saddle cell (opposite corners on the same side, four crossings) is resolved by the
//! mean of its four corners `((tl + tr) + (br + bl)) / 4`: when it is on the same side as the
//! top-left corner, the top-right and bottom-left corners are cut off, else the top-left and
//! bottom-right ones. Cells with a non-finite corner have no contour.
//!
//! Points are `(x, y)` in pixel units of the grid: pixel `(r, c)` is the point `(c, r)`. Since
//! every crossing depends only on the two values of its edge, the lines of a window of a larger
//! grid are exactly the larger grid's lines inside it: the tiles crate relies on this for
//! seamless contour tiles.

use std::collections::HashMap;

use ndarray::Array2;

/// An edge between two neighbouring pixels of a grid: horizontal from `(r, c)` to `(r, c + 1)`
/// or vertical from `(r, c)` to `(r + 1, c)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Edge {
    /// Whether the edge is vertical (else horizontal).
    pub vertical: bool,
    /// Row of its first end.
    pub r: u32,
    /// Column of its first end.
    pub c: u32,
}

/// One segment of a contour line inside one cell: from a crossing on edge `a` to one on edge `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Index of the level in the slice of levels.
    pub level: usize,
    /// The edge of the first point.
    pub a: Edge,
    /// The edge of the second point.
    pub b: Edge,
    /// The first point, `(x, y)` in pixels.
    pub pa: (f64, f64),
    /// The second point.
    pub pb: (f64, f64),
}

/// A contour line: points `(x, y)` in pixels, closed when its first and last points are equal.
#[derive(Clone, Debug, PartialEq)]
pub struct ContourLine {
    /// Index of the level in the slice of levels.
    pub level: usize,
    /// The points, in order.
    pub points: Vec<(f64, f64)>,
}

impl ContourLine {
    /// Whether the line is a ring (first point = last point).
    pub fn is_closed(&self) -> bool {
        self.points.len() > 2 && self.points.first() == self.points.last()
    }
}

/// The crossing of level `l` on `edge` of `z` (whose ends are on different sides of `l`).
pub fn crossing(z: &Array2<f32>, edge: Edge, l: f64) -> (f64, f64) {
    let (r, c) = (edge.r as usize, edge.c as usize);
    let a = f64::from(z[[r, c]]);
    let b = if edge.vertical {
        f64::from(z[[r + 1, c]])
    } else {
        f64::from(z[[r, c + 1]])
    };
    let t = (l - a) / (b - a);
    if edge.vertical {
        (c as f64, r as f64 + t)
    } else {
        (c as f64 + t, r as f64)
    }
}

/// The segments of every level of `levels` (sorted ascending) in `z`, cell by cell in row-major
/// order, each cell's levels ascending. Each cell looks only at the levels between its smallest
/// and largest corner.
pub fn contour_segments(z: &Array2<f32>, levels: &[f64]) -> Vec<Segment> {
    let (rows, cols) = z.dim();
    let mut out = Vec::new();
    if rows < 2 || cols < 2 || levels.is_empty() {
        return out;
    }
    for r in 0..rows - 1 {
        for c in 0..cols - 1 {
            let v = [
                f64::from(z[[r, c]]),
                f64::from(z[[r, c + 1]]),
                f64::from(z[[r + 1, c + 1]]),
                f64::from(z[[r + 1, c]]),
            ];
            if v.iter().any(|x| !x.is_finite()) {
                continue;
            }
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            // Levels in (lo, hi]: a level <= lo has every corner above it.
            let first = levels.partition_point(|&l| l <= lo);
            let last = levels.partition_point(|&l| l <= hi);
            let (ru, cu) = (r as u32, c as u32);
            let top = Edge {
                vertical: false,
                r: ru,
                c: cu,
            };
            let right = Edge {
                vertical: true,
                r: ru,
                c: cu + 1,
            };
            let bottom = Edge {
                vertical: false,
                r: ru + 1,
                c: cu,
            };
            let left = Edge {
                vertical: true,
                r: ru,
                c: cu,
            };
            for (k, &l) in levels.iter().enumerate().take(last).skip(first) {
                let up = v.map(|x| x >= l);
                let mut seg = |a: Edge, b: Edge| {
                    out.push(Segment {
                        level: k,
                        a,
                        b,
                        pa: crossing(z, a, l),
                        pb: crossing(z, b, l),
                    })
                };
                let crosses = [
                    up[0] != up[1],
                    up[1] != up[2],
                    up[3] != up[2],
                    up[0] != up[3],
                ];
                let edges = [top, right, bottom, left];
                let n = crosses.iter().filter(|&&x| x).count();
                if n == 2 {
                    let mut it = (0..4).filter(|&i| crosses[i]).map(|i| edges[i]);
                    if let (Some(a), Some(b)) = (it.next(), it.next()) {
                        seg(a, b);
                    }
                } else if n == 4 {
                    let centre = ((v[0] + v[1]) + (v[2] + v[3])) / 4.0;
                    if (centre >= l) == up[0] {
                        seg(top, right);
                        seg(bottom, left);
                    } else {
                        seg(top, left);
                        seg(right, bottom);
                    }
                }
            }
        }
    }
    out
}

/// Joins segments into lines, level by level in ascending order: open lines first, each started
/// at the first segment (in the given order) with a free end, then closed rings. Every segment
/// is used exactly once; the order depends only on the segments' order.
pub fn join_segments(segments: &[Segment]) -> Vec<ContourLine> {
    let mut order: Vec<usize> = (0..segments.len()).collect();
    order.sort_by_key(|&i| segments[i].level);
    let mut out = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let level = segments[order[start]].level;
        let mut end = start;
        while end < order.len() && segments[order[end]].level == level {
            end += 1;
        }
        join_level(segments, &order[start..end], level, &mut out);
        start = end;
    }
    out
}

/// Joins the segments `ids` (all of one level) into lines appended to `out`.
fn join_level(segments: &[Segment], ids: &[usize], level: usize, out: &mut Vec<ContourLine>) {
    // Every edge holds one crossing, shared by at most two segments.
    let mut at: HashMap<Edge, Vec<usize>> = HashMap::with_capacity(ids.len() * 2);
    for &i in ids {
        at.entry(segments[i].a).or_default().push(i);
        at.entry(segments[i].b).or_default().push(i);
    }
    let mut used = vec![false; segments.len()];
    let free_end = |e: &Edge| at.get(e).is_some_and(|v| v.len() == 1);
    // Open lines from a free end, then rings.
    for pass in 0..2 {
        for &i in ids {
            if used[i] {
                continue;
            }
            let s = segments[i];
            let (to, p0, p1) = if pass == 1 || free_end(&s.a) {
                (s.b, s.pa, s.pb)
            } else if free_end(&s.b) {
                (s.a, s.pb, s.pa)
            } else {
                continue;
            };
            used[i] = true;
            let mut points = vec![p0, p1];
            let mut edge = to;
            loop {
                let next = at
                    .get(&edge)
                    .and_then(|v| v.iter().copied().find(|&j| !used[j]));
                let Some(j) = next else { break };
                used[j] = true;
                let t = segments[j];
                let (e, p) = if t.a == edge {
                    (t.b, t.pb)
                } else {
                    (t.a, t.pa)
                };
                points.push(p);
                edge = e;
            }
            out.push(ContourLine { level, points });
        }
    }
}

/// The contour lines of `z` at `levels` (sorted ascending): [`contour_segments`] joined by
/// [`join_segments`].
pub fn contour_lines(z: &Array2<f32>, levels: &[f64]) -> Vec<ContourLine> {
    join_segments(&contour_segments(z, levels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::naive::contour_segments_naive;
    use proptest::prelude::*;

    /// Segments as comparable keys: level, edges in order, points' bits.
    fn keys(s: &[Segment]) -> Vec<(usize, Edge, Edge, [u64; 4])> {
        let mut v: Vec<_> = s
            .iter()
            .map(|s| {
                let (a, b, pa, pb) = if s.a <= s.b {
                    (s.a, s.b, s.pa, s.pb)
                } else {
                    (s.b, s.a, s.pb, s.pa)
                };
                (
                    s.level,
                    a,
                    b,
                    [
                        pa.0.to_bits(),
                        pa.1.to_bits(),
                        pb.0.to_bits(),
                        pb.1.to_bits(),
                    ],
                )
            })
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_ramp_gives_straight_lines_at_the_interpolated_columns() {
        // z = 10·c: level 25 crosses every row at x = 2.5; level 30 sits on column 3 (>= is
        // above), so its crossings are at x = 3.0 exactly on the edges from column 2.
        let z = Array2::from_shape_fn((4, 6), |(_, c)| 10.0 * c as f32);
        let lines = contour_lines(&z, &[25.0, 30.0]);
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].level, 0);
        let mut ys: Vec<f64> = lines[0].points.iter().map(|p| p.1).collect();
        assert!(lines[0].points.iter().all(|p| p.0 == 2.5), "{lines:?}");
        ys.sort_by(f64::total_cmp);
        assert_eq!(ys, [0.0, 1.0, 2.0, 3.0]);
        assert!(lines[1].points.iter().all(|p| p.0 == 3.0));
        assert!(!lines[0].is_closed());
    }

    #[test]
    fn a_peak_gives_one_ring_per_level() {
        // A cone: every level between the rim and the summit is one closed ring.
        let z = Array2::from_shape_fn((21, 21), |(r, c)| {
            let (dr, dc) = (r as f32 - 10.0, c as f32 - 10.0);
            100.0 - (dr * dr + dc * dc).sqrt() * 5.0
        });
        let lines = contour_lines(&z, &[60.0, 70.0, 80.0, 90.0]);
        assert_eq!(lines.len(), 4);
        for (k, l) in lines.iter().enumerate() {
            assert_eq!(l.level, k);
            assert!(l.is_closed(), "{l:?}");
            // Distance from the summit (100 − 5·d = level).
            let want = (100.0 - [60.0, 70.0, 80.0, 90.0][k]) / 5.0;
            for p in &l.points {
                let d = ((p.0 - 10.0).powi(2) + (p.1 - 10.0).powi(2)).sqrt();
                assert!((d - want).abs() < 0.3, "level {k}: {d} vs {want}");
            }
        }
    }

    #[test]
    fn saddles_follow_the_centre_and_nan_cells_are_skipped() {
        // 2×2 saddle: top-left and bottom-right high. Centre 5 is above level 4 (same side as
        // the top-left): the low corners are cut off.
        let z = ndarray::array![[10.0f32, 0.0], [0.0, 10.0]];
        let s = contour_segments(&z, &[4.0]);
        let e = |vertical, r, c| Edge { vertical, r, c };
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].a, s[0].b), (e(false, 0, 0), e(true, 0, 1)));
        assert_eq!((s[1].a, s[1].b), (e(false, 1, 0), e(true, 0, 0)));
        // Level 6: centre below, the high corners are cut off.
        let s = contour_segments(&z, &[6.0]);
        assert_eq!((s[0].a, s[0].b), (e(false, 0, 0), e(true, 0, 0)));
        assert_eq!((s[1].a, s[1].b), (e(true, 0, 1), e(false, 1, 0)));
        let mut n = Array2::from_elem((3, 3), 0.0f32);
        n[[2, 2]] = 10.0;
        n[[1, 1]] = f32::NAN;
        assert!(contour_segments(&n, &[5.0]).is_empty());
        assert!(contour_segments(&Array2::zeros((1, 5)), &[0.0]).is_empty());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn the_kernel_equals_the_naive_twin_and_joins_every_segment(
            rows in 2usize..14,
            cols in 2usize..14,
            seed in any::<u64>(),
            step in 1u32..6,
        ) {
            // Integer-ish values hit levels exactly (the `>=` convention) and make saddles.
            let mut s = seed | 1;
            let z = Array2::from_shape_fn((rows, cols), |_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s % 9) as f32 * 2.5
            });
            let levels: Vec<f64> = (0..8).map(|k| f64::from(k * step) * 1.25).collect();
            let fast = contour_segments(&z, &levels);
            let naive = contour_segments_naive(&z, &levels);
            prop_assert_eq!(keys(&fast), keys(&naive));
            let lines = join_segments(&fast);
            let used: usize = lines.iter().map(|l| l.points.len() - 1).sum();
            prop_assert_eq!(used, fast.len());
            for l in &lines {
                for w in l.points.windows(2) {
                    // Consecutive points are the two ends of one segment of the line's level.
                    let found = fast.iter().any(|s| s.level == l.level
                        && ((s.pa == w[0] && s.pb == w[1]) || (s.pa == w[1] && s.pb == w[0])));
                    prop_assert!(found);
                }
            }
        }
    }
}
