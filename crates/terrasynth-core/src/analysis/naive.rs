//! Straightforward reference implementations used to test the optimised ones: Planchon–Darboux
//! depression filling, D8 accumulation by following receiver chains, MFD accumulation by
//! repeated relaxation passes, a per-cell Horn gradient and a 2D DFT. They are slow (quadratic
//! or worse) and meant for small grids only; they share conventions, not code, with the fast
//! versions (except the 1D [`dft_naive`]).

use ndarray::Array2;

use super::fft::{dft_naive, Complex};
use crate::math;
use crate::raster::CellSizes;

/// Size of row `r` from `v`, with the same fallbacks as the fast code (last row reused, 1 m
/// when missing or invalid).
fn size_at(v: &[f64], r: usize) -> f64 {
    let s = if r < v.len() {
        v[r]
    } else if let Some(&l) = v.last() {
        l
    } else {
        1.0
    };
    if s.is_finite() && s > 0.0 {
        s
    } else {
        1.0
    }
}

/// Value at `(r, c)` with coordinates clamped into the grid (replicated borders).
fn clamped(z: &Array2<f32>, r: isize, c: isize) -> f64 {
    let (rows, cols) = z.dim();
    let rr = r.clamp(0, rows as isize - 1) as usize;
    let cc = c.clamp(0, cols as isize - 1) as usize;
    z[[rr, cc]] as f64
}

/// Horn gradient `(dz/dx east, dz/dy north)` computed cell by cell from the textbook formula
/// (with per-row widths, see [`gradient`](super::gradient)).
pub fn gradient(z: &Array2<f32>, cs: &CellSizes) -> (Array2<f32>, Array2<f32>) {
    let (rows, cols) = z.dim();
    let mut gx = Array2::zeros((rows, cols));
    let mut gy = Array2::zeros((rows, cols));
    for r in 0..rows as isize {
        for c in 0..cols as isize {
            let rn = (r - 1).max(0) as usize;
            let rs = (r + 1).min(rows as isize - 1) as usize;
            let ru = r as usize;
            let (dxn, dxm, dxs) = (
                size_at(&cs.dx, rn),
                size_at(&cs.dx, ru),
                size_at(&cs.dx, rs),
            );
            let (dyn_, dym, dys) = (
                size_at(&cs.dy, rn),
                size_at(&cs.dy, ru),
                size_at(&cs.dy, rs),
            );
            let z_ = |dr: isize, dc: isize| clamped(z, r + dr, c + dc);
            let east = (z_(-1, 1) - z_(-1, -1)) / (2.0 * dxn) * 1.0
                + (z_(0, 1) - z_(0, -1)) / (2.0 * dxm) * 2.0
                + (z_(1, 1) - z_(1, -1)) / (2.0 * dxs) * 1.0;
            let north_sum = z_(-1, -1) + 2.0 * z_(-1, 0) + z_(-1, 1);
            let south_sum = z_(1, -1) + 2.0 * z_(1, 0) + z_(1, 1);
            gx[[ru, c as usize]] = (east / 4.0) as f32;
            gy[[ru, c as usize]] =
                ((north_sum - south_sum) / (2.0 * (dyn_ + 2.0 * dym + dys))) as f32;
        }
    }
    (gx, gy)
}

/// Priority-Flood+ε ([`priority_flood_fill`](super::priority_flood_fill)'s algorithm) on the
/// standard library's binary heap instead of its ranked bitset queue: the same sequence of
/// cells, hence the same bits, if the bitset queue pops in order.
pub fn priority_flood_fill_binary_heap(z: &Array2<f32>) -> Array2<f32> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    super::flood::flood_in(
        z,
        super::next_up,
        |_| BinaryHeap::<Reverse<u64>>::new(),
        BinaryHeap::<Reverse<(u32, usize)>>::new,
    )
}

/// Planchon & Darboux (2001) style relaxation without ε: start from the border (and NaN cells)
/// at their own height and every other cell at +∞, then repeatedly set
/// `W = max(z, min over 8 neighbours of W)` (NaN neighbours count as −∞, i.e. outlets) until
/// nothing changes. The fixed point is the minimal drained surface.
pub fn fill_flat(z: &Array2<f32>) -> Array2<f32> {
    let (rows, cols) = z.dim();
    let mut w = z.clone();
    if rows < 3 || cols < 3 {
        return w;
    }
    for r in 1..rows - 1 {
        for c in 1..cols - 1 {
            if !z[[r, c]].is_nan() {
                w[[r, c]] = f32::INFINITY;
            }
        }
    }
    loop {
        let mut changed = false;
        for r in 1..rows - 1 {
            for c in 1..cols - 1 {
                if z[[r, c]].is_nan() {
                    continue;
                }
                let mut m = f32::INFINITY;
                for dr in 0..3 {
                    for dc in 0..3 {
                        if dr == 1 && dc == 1 {
                            continue;
                        }
                        let v = w[[r + dr - 1, c + dc - 1]];
                        let v = if v.is_nan() { f32::NEG_INFINITY } else { v };
                        if v < m {
                            m = v;
                        }
                    }
                }
                let new = if z[[r, c]] > m { z[[r, c]] } else { m };
                if new < w[[r, c]] {
                    w[[r, c]] = new;
                    changed = true;
                }
            }
        }
        if !changed {
            return w;
        }
    }
}

/// Neighbour list of a cell in the D8 order E, NE, N, NW, W, SW, S, SE with the metric
/// centre distance and contour length of each direction (`None` outside the grid).
fn neighbours(
    rows: usize,
    cols: usize,
    cs: &CellSizes,
    r: usize,
    c: usize,
) -> [Option<(usize, usize, f64, f64)>; 8] {
    const DIRS: [(i64, i64); 8] = [
        (0, 1),
        (-1, 1),
        (-1, 0),
        (-1, -1),
        (0, -1),
        (1, -1),
        (1, 0),
        (1, 1),
    ];
    let mut out = [None; 8];
    for (k, &(dr, dc)) in DIRS.iter().enumerate() {
        let (nr, nc) = (r as i64 + dr, c as i64 + dc);
        if nr < 0 || nc < 0 || nr >= rows as i64 || nc >= cols as i64 {
            continue;
        }
        let (nr, nc) = (nr as usize, nc as usize);
        let (dx, dy) = (size_at(&cs.dx, r), size_at(&cs.dy, r));
        let dxm = 0.5 * (dx + size_at(&cs.dx, nr));
        let dym = 0.5 * (dy + size_at(&cs.dy, nr));
        let (dist, contour) = if dr == 0 {
            (dx, 0.5 * dy)
        } else if dc == 0 {
            (dym, 0.5 * dx)
        } else {
            (
                (dxm * dxm + dym * dym).sqrt(),
                0.25 * (dx * dx + dy * dy).sqrt(),
            )
        };
        out[k] = Some((nr, nc, dist, contour));
    }
    out
}

/// D8 receivers by a per-cell scan: each cell weighs its neighbours in direction order and
/// keeps the first strictly steepest positive drop/distance ([`D8_NONE`](super::D8_NONE) when
/// none drops).
pub fn d8_receivers(filled: &Array2<f32>, cs: &CellSizes) -> Array2<u8> {
    let (rows, cols) = filled.dim();
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let mut best = super::D8_NONE;
        let mut best_s = 0.0;
        for (k, n) in neighbours(rows, cols, cs, r, c).into_iter().enumerate() {
            let Some((nr, nc, dist, _)) = n else { continue };
            let drop = filled[[r, c]] as f64 - filled[[nr, nc]] as f64;
            if drop > 0.0 && drop / dist > best_s {
                best_s = drop / dist;
                best = k as u8;
            }
        }
        best
    })
}

/// [`super::resolve_flats`] by repeated relaxation: the flat cells, the two distances (towards
/// the low edges, away from the high edges) as fixed points of `d = min(d, d_neighbour + 1)` over
/// equal-valued flat neighbours, each flat's largest away distance by propagating the maximum,
/// each flat's bounding box the same way (open flats: touching the border ring or spanning more
/// than `max_span` cells, with the distance from their `guide` cells instead of the away term),
/// then the steepest fall of the mask per flat cell.
pub fn resolve_flats(
    filled: &Array2<f32>,
    cs: &CellSizes,
    max_span: usize,
    guide: Option<&dyn Fn(usize, usize) -> bool>,
    receivers: &mut Array2<u8>,
) {
    let (rows, cols) = filled.dim();
    if rows < 3 || cols < 3 || receivers.dim() != (rows, cols) {
        return;
    }
    let none = super::D8_NONE;
    let nbrs = |r: usize, c: usize| neighbours(rows, cols, cs, r, c);
    let flat = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let interior = r > 0 && c > 0 && r + 1 < rows && c + 1 < cols;
        interior
            && receivers[[r, c]] == none
            && filled[[r, c]].is_finite()
            && nbrs(r, c)
                .iter()
                .flatten()
                .all(|&(nr, nc, _, _)| !filled[[nr, nc]].is_nan())
    });
    let same_flat = |r: usize, c: usize, nr: usize, nc: usize| {
        flat[[nr, nc]] && filled[[nr, nc]] == filled[[r, c]]
    };
    // A distance from the flat cells where `seed` holds, through equal-valued flat cells (0:
    // unreached).
    let distance = |seed: &dyn Fn(usize, usize) -> bool| {
        let mut d = Array2::<u32>::zeros((rows, cols));
        for ((r, c), v) in d.indexed_iter_mut() {
            if flat[[r, c]] && seed(r, c) {
                *v = 1;
            }
        }
        loop {
            let mut changed = false;
            for r in 0..rows {
                for c in 0..cols {
                    if !flat[[r, c]] {
                        continue;
                    }
                    for &(nr, nc, _, _) in nbrs(r, c).iter().flatten() {
                        let dn = d[[nr, nc]];
                        if same_flat(r, c, nr, nc)
                            && dn > 0
                            && (d[[r, c]] == 0 || dn + 1 < d[[r, c]])
                        {
                            d[[r, c]] = dn + 1;
                            changed = true;
                        }
                    }
                }
            }
            if !changed {
                return d;
            }
        }
    };
    // Next to a neighbour for which `edge(r, c, nr, nc)` holds.
    let next_to = |edge: &dyn Fn(usize, usize, usize, usize) -> bool, r: usize, c: usize| {
        nbrs(r, c)
            .iter()
            .flatten()
            .any(|&(nr, nc, _, _)| edge(r, c, nr, nc))
    };
    let towards = distance(&|r, c| {
        next_to(
            &|r, c, nr, nc| !flat[[nr, nc]] && filled[[nr, nc]] == filled[[r, c]],
            r,
            c,
        )
    });
    let away = distance(&|r, c| next_to(&|r, c, nr, nc| filled[[nr, nc]] > filled[[r, c]], r, c));
    let guided = distance(&|r, c| guide.is_some_and(|g| g(r, c)));
    // Each flat's largest away distance and bounding box (smallest and largest row and column,
    // the smallest as a negated maximum), spread over the flat.
    let mut most = away.clone();
    let mut extent = Array2::from_shape_fn((rows, cols), |(r, c)| {
        [-(r as i64), r as i64, -(c as i64), c as i64]
    });
    loop {
        let mut changed = false;
        for r in 0..rows {
            for c in 0..cols {
                for &(nr, nc, _, _) in nbrs(r, c).iter().flatten() {
                    if !flat[[r, c]] || !same_flat(r, c, nr, nc) {
                        continue;
                    }
                    if most[[nr, nc]] > most[[r, c]] {
                        most[[r, c]] = most[[nr, nc]];
                        changed = true;
                    }
                    for k in 0..4 {
                        if extent[[nr, nc]][k] > extent[[r, c]][k] {
                            extent[[r, c]][k] = extent[[nr, nc]][k];
                            changed = true;
                        }
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
    let span = i64::try_from(max_span).unwrap_or(i64::MAX);
    let open = |r: usize, c: usize| {
        let [r_lo, r_hi, c_lo, c_hi] = extent[[r, c]];
        let (r_lo, c_lo) = (-r_lo, -c_lo);
        let touches = r_lo <= 1 || c_lo <= 1 || r_hi + 2 >= rows as i64 || c_hi + 2 >= cols as i64;
        touches || r_hi - r_lo + 1 > span || c_hi - c_lo + 1 > span
    };
    let mask = Array2::from_shape_fn((rows, cols), |(r, c)| {
        if !flat[[r, c]] || towards[[r, c]] == 0 {
            0
        } else if open(r, c) {
            2 * towards[[r, c]] + guided[[r, c]]
        } else if away[[r, c]] > 0 {
            2 * towards[[r, c]] + most[[r, c]] - away[[r, c]]
        } else {
            2 * towards[[r, c]]
        }
    });
    for r in 0..rows {
        for c in 0..cols {
            if !flat[[r, c]] || mask[[r, c]] == 0 {
                continue;
            }
            let mut best = 0.0;
            let mut code = none;
            for (k, n) in nbrs(r, c).iter().enumerate() {
                let Some((nr, nc, dist, _)) = *n else {
                    continue;
                };
                if filled[[nr, nc]] != filled[[r, c]] {
                    continue;
                }
                let m = if flat[[nr, nc]] { mask[[nr, nc]] } else { 0 };
                if m < mask[[r, c]] {
                    let slope = f64::from(mask[[r, c]] - m) / dist;
                    if slope > best {
                        best = slope;
                        code = k as u8;
                    }
                }
            }
            receivers[[r, c]] = code;
        }
    }
}

/// D8 upstream area by brute force: every cell walks down its steepest-descent chain
/// ([`d8_receivers`] of this module) to a sink, adding its own area to every
/// cell on the way.
pub fn flow_accumulation_d8(filled: &Array2<f32>, cs: &CellSizes) -> Array2<f64> {
    let (rows, cols) = filled.dim();
    let codes = d8_receivers(filled, cs);
    let receiver = |r: usize, c: usize| -> Option<(usize, usize)> {
        let k = usize::from(codes[[r, c]]);
        neighbours(rows, cols, cs, r, c)
            .get(k)
            .copied()
            .flatten()
            .map(|(nr, nc, _, _)| (nr, nc))
    };
    let mut acc = Array2::zeros((rows, cols));
    for r in 0..rows {
        for c in 0..cols {
            let a = size_at(&cs.dx, r) * size_at(&cs.dy, r);
            let mut cur = (r, c);
            acc[cur] += a;
            for _ in 0..rows * cols {
                match receiver(cur.0, cur.1) {
                    Some(next) => {
                        acc[next] += a;
                        cur = next;
                    }
                    None => break,
                }
            }
        }
    }
    acc
}

/// Fractions of a cell's flow sent to each neighbour direction under the Freeman/Quinn MFD
/// rule (see [`flow_accumulation_mfd`](super::flow_accumulation_mfd)).
fn mfd_fractions(
    filled: &Array2<f32>,
    cs: &CellSizes,
    r: usize,
    c: usize,
    p: f64,
) -> [Option<(usize, usize, f64)>; 8] {
    let (rows, cols) = filled.dim();
    let mut w = [None; 8];
    let mut total = 0.0;
    let mut count = 0;
    for (k, nb) in neighbours(rows, cols, cs, r, c).into_iter().enumerate() {
        if let Some((nr, nc, dist, contour)) = nb {
            let drop = filled[[r, c]] as f64 - filled[[nr, nc]] as f64;
            if drop > 0.0 {
                let x = math::pow(drop / dist * contour, p);
                total += x;
                count += 1;
                w[k] = Some((nr, nc, x));
            }
        }
    }
    let ok = total > 0.0 && total.is_finite();
    for (nr, nc, x) in w.iter_mut().flatten() {
        let _ = (nr, nc);
        *x = if ok { *x / total } else { 1.0 / count as f64 };
    }
    w
}

/// MFD upstream area by relaxation: `A(c) = area(c) + Σ_h A(h)·share(h → c)` over the higher
/// neighbours `h`, recomputed for the whole grid until no value changes (at most one pass per
/// cell on the longest flow path, plus one).
pub fn flow_accumulation_mfd(filled: &Array2<f32>, cs: &CellSizes, exponent: f64) -> Array2<f64> {
    let (rows, cols) = filled.dim();
    let area = Array2::from_shape_fn((rows, cols), |(r, _)| {
        size_at(&cs.dx, r) * size_at(&cs.dy, r)
    });
    let mut acc = area.clone();
    for _ in 0..=rows * cols {
        let mut next = area.clone();
        for r in 0..rows {
            for c in 0..cols {
                for (nr, nc, share) in mfd_fractions(filled, cs, r, c, exponent)
                    .into_iter()
                    .flatten()
                {
                    next[[nr, nc]] += acc[[r, c]] * share;
                }
            }
        }
        if next == acc {
            break;
        }
        acc = next;
    }
    acc
}

/// 2D DFT by applying the naive 1D DFT to every row and then every column.
pub fn dft2(x: &Array2<Complex>, inverse: bool) -> Array2<Complex> {
    let (rows, cols) = x.dim();
    let mut out = x.clone();
    for r in 0..rows {
        let row: Vec<Complex> = (0..cols).map(|c| out[[r, c]]).collect();
        for (c, v) in dft_naive(&row, inverse).into_iter().enumerate() {
            out[[r, c]] = v;
        }
    }
    for c in 0..cols {
        let col: Vec<Complex> = (0..rows).map(|r| out[[r, c]]).collect();
        for (r, v) in dft_naive(&col, inverse).into_iter().enumerate() {
            out[[r, c]] = v;
        }
    }
    out
}

/// Source accumulation by brute force: every cell walks its receiver chain (codes as in
/// [`D8_OFFSETS`](super::D8_OFFSETS), other codes are sinks) adding its source to every cell on
/// the way. Reference for [`accumulate_sources`](super::flow::accumulate_sources).
pub fn accumulate_sources(receivers: &Array2<u8>, sources: &Array2<f64>) -> Array2<f64> {
    let (rows, cols) = receivers.dim();
    let mut acc = Array2::zeros((rows, cols));
    for r in 0..rows {
        for c in 0..cols {
            let s = sources[[r, c]];
            let mut cur = (r, c);
            acc[cur] += s;
            for _ in 0..rows * cols {
                let code = receivers[cur] as usize;
                let Some(&(dr, dc)) = super::D8_OFFSETS.get(code) else {
                    break;
                };
                let (nr, nc) = (cur.0 as isize + dr, cur.1 as isize + dc);
                if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
                    break;
                }
                cur = (nr as usize, nc as usize);
                acc[cur] += s;
            }
        }
    }
    acc
}

/// Pixel-axis anisotropy computed the slow way, as a reference for
/// [`axis_anisotropy`](super::axis_anisotropy): the least-squares plane from the 3×3 normal
/// equations (Cramer's rule), a Hann window, the naive 2D DFT, and wedges classified by the
/// angle of each bin in degrees.
pub fn axis_anisotropy(z: &Array2<f32>) -> f64 {
    let (rows, cols) = z.dim();
    if rows < 4 || cols < 4 {
        return f64::NAN;
    }
    // Normal equations of v ≈ a + b·r + c·col.
    let mut m = [[0.0f64; 3]; 3];
    let mut y = [0.0f64; 3];
    for r in 0..rows {
        for c in 0..cols {
            let x = [1.0, r as f64, c as f64];
            let v = z[[r, c]] as f64;
            for i in 0..3 {
                y[i] += x[i] * v;
                for j in 0..3 {
                    m[i][j] += x[i] * x[j];
                }
            }
        }
    }
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    let mut coef = [0.0f64; 3];
    for (k, ck) in coef.iter_mut().enumerate() {
        let mut mk = m;
        for i in 0..3 {
            mk[i][k] = y[i];
        }
        *ck = det(&mk) / d;
    }
    let hann = |i: usize, n: usize| {
        0.5 - 0.5 * math::cos(2.0 * std::f64::consts::PI * i as f64 / n as f64)
    };
    let x = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let plane = coef[0] + coef[1] * r as f64 + coef[2] * c as f64;
        Complex::new(
            (z[[r, c]] as f64 - plane) * hann(r, rows) * hann(c, cols),
            0.0,
        )
    });
    let f = dft2(&x, false);
    let half = super::realism::ANISOTROPY_WEDGE_DEG;
    let (mut axis, mut na, mut diag, mut nd) = (0.0, 0usize, 0.0, 0usize);
    for r in 0..rows {
        for c in 0..cols {
            let fy = if 2 * r <= rows {
                r as f64
            } else {
                r as f64 - rows as f64
            } / rows as f64;
            let fx = if 2 * c <= cols {
                c as f64
            } else {
                c as f64 - cols as f64
            } / cols as f64;
            let radius = (fx * fx + fy * fy).sqrt();
            if !(0.25..0.5).contains(&radius) {
                continue;
            }
            let deg = math::atan2(fy, fx).to_degrees(); // (−180, 180]
            let off_axis = (deg - 90.0 * (deg / 90.0).round()).abs();
            let off_diag = (deg - 45.0 - 90.0 * ((deg - 45.0) / 90.0).round()).abs();
            let p = f[[r, c]].norm_sqr();
            if off_axis <= half {
                axis += p;
                na += 1;
            } else if off_diag <= half {
                diag += p;
                nd += 1;
            }
        }
    }
    if na == 0 || nd == 0 || diag <= 0.0 {
        return f64::NAN;
    }
    (axis / na as f64) / (diag / nd as f64)
}

/// Marching squares by the classic 16-case table, level by level over every cell: the
/// reference for [`super::contour::contour_segments`] (same conventions: `>=` is above, the
/// crossing measured from the edge's first end, saddles resolved by the mean of the corners).
pub fn contour_segments_naive(z: &Array2<f32>, levels: &[f64]) -> Vec<super::contour::Segment> {
    use super::contour::{Edge, Segment};
    let (rows, cols) = z.dim();
    let mut out = Vec::new();
    // Edge pairs per case (bit 3: top-left above, 2: top-right, 1: bottom-right, 0:
    // bottom-left); edges 0 top, 1 right, 2 bottom, 3 left; saddles (5, 10) below.
    const TABLE: [&[(usize, usize)]; 16] = [
        &[],
        &[(3, 2)],
        &[(2, 1)],
        &[(3, 1)],
        &[(0, 1)],
        &[],
        &[(0, 2)],
        &[(0, 3)],
        &[(0, 3)],
        &[(0, 2)],
        &[],
        &[(0, 1)],
        &[(3, 1)],
        &[(2, 1)],
        &[(3, 2)],
        &[],
    ];
    for (k, &l) in levels.iter().enumerate() {
        for r in 0..rows.saturating_sub(1) {
            for c in 0..cols.saturating_sub(1) {
                let tl = f64::from(z[[r, c]]);
                let tr = f64::from(z[[r, c + 1]]);
                let br = f64::from(z[[r + 1, c + 1]]);
                let bl = f64::from(z[[r + 1, c]]);
                if [tl, tr, br, bl].iter().any(|v| !v.is_finite()) {
                    continue;
                }
                let bit = |v: f64, b: usize| usize::from(v >= l) << b;
                let case = bit(tl, 3) | bit(tr, 2) | bit(br, 1) | bit(bl, 0);
                let (ru, cu) = (r as u32, c as u32);
                let edge = |i: usize| -> (Edge, (f64, f64)) {
                    let (vertical, er, ec, a, b) = match i {
                        0 => (false, ru, cu, tl, tr),
                        1 => (true, ru, cu + 1, tr, br),
                        2 => (false, ru + 1, cu, bl, br),
                        _ => (true, ru, cu, tl, bl),
                    };
                    let t = (l - a) / (b - a);
                    let p = if vertical {
                        (f64::from(ec), f64::from(er) + t)
                    } else {
                        (f64::from(ec) + t, f64::from(er))
                    };
                    (
                        Edge {
                            vertical,
                            r: er,
                            c: ec,
                        },
                        p,
                    )
                };
                let centre_above = ((tl + tr) + (br + bl)) / 4.0 >= l;
                let pairs: &[(usize, usize)] = match (case, centre_above) {
                    (10, true) | (5, false) => &[(0, 1), (2, 3)],
                    (10, false) | (5, true) => &[(0, 3), (1, 2)],
                    _ => TABLE[case],
                };
                for &(i, j) in pairs {
                    let ((a, pa), (b, pb)) = (edge(i), edge(j));
                    out.push(Segment {
                        level: k,
                        a,
                        b,
                        pa,
                        pb,
                    });
                }
            }
        }
    }
    out
}
