//! Shared helpers of the analysis module: contiguous access to grids, per-row cell sizes that
//! tolerate short or empty [`CellSizes`], the fixed 8-neighbour order and its metric distances.

use std::borrow::Cow;

use ndarray::Array2;

use crate::raster::CellSizes;

/// Row-major values of `z` (borrowed when `z` is already in standard layout).
pub(crate) fn values<T: Copy>(z: &Array2<T>) -> Cow<'_, [T]> {
    match z.as_slice() {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(z.iter().copied().collect()),
    }
}

/// Per-row `(dx, dy)` for a grid of `rows` rows. Rows beyond the end of `cs` reuse its last row;
/// an empty `cs` (or a non-positive / non-finite size) falls back to 1 m.
pub(crate) fn row_sizes(cs: &CellSizes, rows: usize) -> (Vec<f64>, Vec<f64>) {
    let pick = |v: &[f64], r: usize| -> f64 {
        let s = v.get(r).or_else(|| v.last()).copied().unwrap_or(1.0);
        if s.is_finite() && s > 0.0 {
            s
        } else {
            1.0
        }
    };
    let dx = (0..rows).map(|r| pick(&cs.dx, r)).collect();
    let dy = (0..rows).map(|r| pick(&cs.dy, r)).collect();
    (dx, dy)
}

/// The 8 neighbour directions as `(row offset, column offset)`, counter-clockwise from east:
/// E, NE, N, NW, W, SW, S, SE (row 0 is north, so north is `-1` rows).
pub const D8_OFFSETS: [(isize, isize); 8] = [
    (0, 1),
    (-1, 1),
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// The neighbour of `(r, c)` in direction `d`, if inside a `rows × cols` grid.
#[inline]
pub(crate) fn neighbour(
    r: usize,
    c: usize,
    d: usize,
    rows: usize,
    cols: usize,
) -> Option<(usize, usize)> {
    let (dr, dc) = D8_OFFSETS[d];
    let nr = r.checked_add_signed(dr)?;
    let nc = c.checked_add_signed(dc)?;
    if nr < rows && nc < cols {
        Some((nr, nc))
    } else {
        None
    }
}

/// Metric geometry of the 8 directions for every row: centre-to-centre distance and the
/// contour length (Quinn et al. 1991) across which flow leaves the cell in that direction.
pub(crate) struct DirGeometry {
    /// `dist[r * 8 + d]`: distance in metres from a cell of row `r` to its neighbour `d`.
    pub dist: Vec<f64>,
    /// `contour[r * 8 + d]`: contour length in metres for direction `d` on row `r`.
    pub contour: Vec<f64>,
}

/// Distances between cell centres use the mean of the two rows' sizes: east/west `dx[r]`,
/// north/south `(dy[r] + dy[r']) / 2`, diagonals `sqrt(dxm² + dym²)` with `dxm = (dx[r] +
/// dx[r']) / 2`. Contour lengths are `dy/2` (E/W), `dx/2` (N/S) and `hypot(dx, dy)/4` (diagonals)
/// of the cell's own row, which for square cells gives Quinn's 0.5 and 0.354 cell widths.
pub(crate) fn dir_geometry(cs: &CellSizes, rows: usize) -> DirGeometry {
    let (dx, dy) = row_sizes(cs, rows);
    let mut dist = vec![0.0; rows * 8];
    let mut contour = vec![0.0; rows * 8];
    for r in 0..rows {
        for (d, &(dr, dc)) in D8_OFFSETS.iter().enumerate() {
            // Neighbour row clamped: for rows outside the grid the value is never used.
            let rn = r.saturating_add_signed(dr).min(rows - 1);
            let dxm = 0.5 * (dx[r] + dx[rn]);
            let dym = 0.5 * (dy[r] + dy[rn]);
            let (di, co) = match (dr, dc) {
                (0, _) => (dx[r], 0.5 * dy[r]),
                (_, 0) => (dym, 0.5 * dx[r]),
                _ => (
                    (dxm * dxm + dym * dym).sqrt(),
                    0.25 * (dx[r] * dx[r] + dy[r] * dy[r]).sqrt(),
                ),
            };
            dist[r * 8 + d] = di;
            contour[r * 8 + d] = co;
        }
    }
    DirGeometry { dist, contour }
}

/// Cell areas `dx[r] * dy[r]` for each row.
pub(crate) fn row_areas(cs: &CellSizes, rows: usize) -> Vec<f64> {
    let (dx, dy) = row_sizes(cs, rows);
    dx.iter().zip(&dy).map(|(a, b)| a * b).collect()
}

/// The next representable `f32` above `x` (like `f32::next_up`, stable only since Rust 1.86;
/// the crate's MSRV is 1.85). NaN and `+∞` map to themselves.
#[inline]
pub fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let b = x.to_bits();
    if x > 0.0 {
        f32::from_bits(b + 1)
    } else {
        f32::from_bits(b - 1)
    }
}

/// The next representable `f32` below `x` (the mirror of [`next_up`]). NaN and `−∞` map to
/// themselves.
#[inline]
pub fn next_down(x: f32) -> f32 {
    -next_up(-x)
}

/// A key whose unsigned order is the numeric order of `x`, with NaN below everything (NaN cells
/// are outlets and are processed first).
#[inline]
pub(crate) fn order_key(x: f32) -> u32 {
    if x.is_nan() {
        return 0;
    }
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_up_matches_bit_increment() {
        assert_eq!(next_up(1.0), f32::from_bits(1.0f32.to_bits() + 1));
        assert_eq!(next_up(0.0), f32::from_bits(1));
        assert_eq!(next_up(-0.0), f32::from_bits(1));
        assert!(next_up(-1.0) > -1.0);
        assert!(next_up(7000.0) > 7000.0 && next_up(7000.0) - 7000.0 < 1e-3);
        assert_eq!(next_up(f32::INFINITY), f32::INFINITY);
        assert!(next_up(f32::NAN).is_nan());
        assert_eq!(next_up(f32::NEG_INFINITY), f32::MIN);
    }

    #[test]
    fn order_key_is_monotone_with_nan_first() {
        let v = [
            f32::NEG_INFINITY,
            -5.0,
            -1e-30,
            0.0,
            1e-30,
            3.0,
            f32::INFINITY,
        ];
        for w in v.windows(2) {
            assert!(order_key(w[0]) < order_key(w[1]));
        }
        assert!(order_key(f32::NAN) < order_key(f32::NEG_INFINITY));
    }

    #[test]
    fn geometry_of_square_cells() {
        let g = dir_geometry(&CellSizes::uniform(3, 2.0), 3);
        let row = &g.dist[8..16];
        assert_eq!(row[0], 2.0);
        assert_eq!(row[2], 2.0);
        assert!((row[1] - 8f64.sqrt()).abs() < 1e-15);
        assert_eq!(g.contour[8], 1.0);
        assert!((g.contour[9] - 0.25 * 8f64.sqrt()).abs() < 1e-15);
        let (dx, dy) = row_sizes(
            &CellSizes {
                dx: vec![3.0],
                dy: vec![],
            },
            2,
        );
        assert_eq!((dx, dy), (vec![3.0, 3.0], vec![1.0, 1.0]));
    }
}
