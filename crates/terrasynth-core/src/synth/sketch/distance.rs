//! Exact Euclidean distance transforms (Felzenszwalb & Huttenlocher 2012, "Distance transforms of
//! sampled functions"): for every cell, the distance to the nearest *site* of a mask and which
//! site that is, in two separable passes (columns, then rows, each a lower envelope of
//! parabolas), O(n). [`naive_transform`] scans every site for every cell; property tests compare
//! them. Ties between equally near sites go to the first found, so distances always agree and
//! sites agree up to ties.

/// Squared distance standing for "no site" (larger than any grid's).
const FAR: f64 = 1e30;

/// Distances to the nearest site and the site itself (row-major index), `None` sites when the
/// mask is empty.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceMap {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Euclidean distance (cells) to the nearest site, `f64::INFINITY` with no site.
    pub dist: Vec<f64>,
    /// Row-major index of the nearest site, `usize::MAX` with no site.
    pub site: Vec<usize>,
}

impl DistanceMap {
    /// Bilinearly interpolated distance at continuous cell coordinates `(x, y)` (clamped to the
    /// grid).
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        if self.rows == 0 || self.cols == 0 {
            return f64::INFINITY;
        }
        let xc = x.clamp(0.0, (self.cols - 1) as f64);
        let yc = y.clamp(0.0, (self.rows - 1) as f64);
        let (c0, r0) = (xc.floor() as usize, yc.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.cols - 1), (r0 + 1).min(self.rows - 1));
        let (fx, fy) = (xc - c0 as f64, yc - r0 as f64);
        let d = |r: usize, c: usize| self.dist[r * self.cols + c];
        let top = d(r0, c0) * (1.0 - fx) + d(r0, c1) * fx;
        let bottom = d(r1, c0) * (1.0 - fx) + d(r1, c1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// One 1-D pass: `f[i]` are squared distances along the line (with `arg[i]` the site each
/// stands for); returns the lower envelope `min_j f[j] + (i − j)²` and the winning `arg`.
fn pass(f: &[f64], arg: &[usize], out_d: &mut [f64], out_a: &mut [usize]) {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0f64; n + 1];
    let mut k = 0usize;
    let mut any = false;
    for q in 0..n {
        if f[q] >= FAR {
            continue;
        }
        if !any {
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            any = true;
            continue;
        }
        loop {
            let p = v[k];
            let s =
                ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0: q replaces the first parabola entirely.
                v[0] = q;
                z[0] = f64::NEG_INFINITY;
                z[1] = f64::INFINITY;
                break;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    if !any {
        for i in 0..n {
            out_d[i] = FAR;
            out_a[i] = usize::MAX;
        }
        return;
    }
    let mut j = 0usize;
    for q in 0..n {
        while z[j + 1] < q as f64 {
            j += 1;
        }
        let p = v[j];
        let d = q as f64 - p as f64;
        out_d[q] = d * d + f[p];
        out_a[q] = arg[p];
    }
}

/// The distance map of the sites `mask[i] == true` on a `rows × cols` grid.
pub fn distance_transform(mask: &[bool], rows: usize, cols: usize) -> DistanceMap {
    let n = rows * cols;
    if mask.len() != n || n == 0 {
        return DistanceMap {
            rows,
            cols,
            dist: vec![f64::INFINITY; n],
            site: vec![usize::MAX; n],
        };
    }
    // Columns: squared distance to the nearest site in the same column.
    let mut d1 = vec![FAR; n];
    let mut a1 = vec![usize::MAX; n];
    let mut f = vec![0f64; rows];
    let mut arg = vec![0usize; rows];
    let mut od = vec![0f64; rows];
    let mut oa = vec![0usize; rows];
    for c in 0..cols {
        for r in 0..rows {
            let i = r * cols + c;
            f[r] = if mask[i] { 0.0 } else { FAR };
            arg[r] = i;
        }
        pass(&f, &arg, &mut od, &mut oa);
        for r in 0..rows {
            d1[r * cols + c] = od[r];
            a1[r * cols + c] = oa[r];
        }
    }
    // Rows: combine the columns' distances.
    let mut dist = vec![0f64; n];
    let mut site = vec![0usize; n];
    for r in 0..rows {
        let s = r * cols..(r + 1) * cols;
        pass(
            &d1[s.clone()],
            &a1[s.clone()],
            &mut dist[s.clone()],
            &mut site[s],
        );
    }
    for (d, s) in dist.iter_mut().zip(site.iter_mut()) {
        if *d >= FAR || *s == usize::MAX {
            *d = f64::INFINITY;
            *s = usize::MAX;
        } else {
            *d = d.sqrt();
        }
    }
    DistanceMap {
        rows,
        cols,
        dist,
        site,
    }
}

/// Reference: every cell against every site (first nearest site in row-major order wins).
pub fn naive_transform(mask: &[bool], rows: usize, cols: usize) -> DistanceMap {
    let n = rows * cols;
    let sites: Vec<usize> = (0..n).filter(|&i| mask.get(i) == Some(&true)).collect();
    let mut dist = vec![f64::INFINITY; n];
    let mut site = vec![usize::MAX; n];
    for i in 0..n {
        let (r, c) = ((i / cols) as f64, (i % cols) as f64);
        for &s in &sites {
            let (sr, sc) = ((s / cols) as f64, (s % cols) as f64);
            let d2 = (r - sr) * (r - sr) + (c - sc) * (c - sc);
            if d2 < dist[i] {
                dist[i] = d2;
                site[i] = s;
            }
        }
        dist[i] = dist[i].sqrt();
    }
    DistanceMap {
        rows,
        cols,
        dist,
        site,
    }
}
