//! The one ×2 down-sampling filter of terrasynth: the 2×2 box average, always summed in the same
//! order (`top-left + top-right + bottom-left + bottom-right`, then `× 0.25`) so that every user —
//! low-resolution dictionary atoms, the amplifier's residual correction, the overviews of every
//! tile pyramid — gets bit-identical values on every machine.

use ndarray::{ArrayView2, ArrayViewMut2};

/// The 2×2 box average of `[top-left, top-right, bottom-left, bottom-right]`, summed in that order.
#[inline]
pub fn box2(v: [f32; 4]) -> f32 {
    (v[0] + v[1] + v[2] + v[3]) * 0.25
}

/// Reduces every 2×2 block of `src` (`2h × 2w`) with `reduce` into `out` (`h × w`): `out[r][c] =
/// reduce([src[2r][2c], src[2r][2c+1], src[2r+1][2c], src[2r+1][2c+1]])`. With [`box2`] this is
/// the box down-sampling; pyramids also reduce with the maximum (drainage).
///
/// Only the overlapping part is written when the shapes disagree (`min` of both extents), so a
/// caller's slicing mistake cannot index out of bounds.
pub fn reduce2x2(
    src: ArrayView2<'_, f32>,
    mut out: ArrayViewMut2<'_, f32>,
    reduce: fn([f32; 4]) -> f32,
) {
    let rows = out.nrows().min(src.nrows() / 2);
    let cols = out.ncols().min(src.ncols() / 2);
    for r in 0..rows {
        for c in 0..cols {
            out[[r, c]] = reduce([
                src[[2 * r, 2 * c]],
                src[[2 * r, 2 * c + 1]],
                src[[2 * r + 1, 2 * c]],
                src[[2 * r + 1, 2 * c + 1]],
            ]);
        }
    }
}

/// Box-averages the row pair `top`/`bottom` (length `2n`) into `out` (length `n`).
pub fn box_down2_rows(top: &[f32], bottom: &[f32], out: &mut [f32]) {
    for (c, o) in out.iter_mut().enumerate() {
        *o = box2([top[2 * c], top[2 * c + 1], bottom[2 * c], bottom[2 * c + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{array, Array2};

    #[test]
    fn box_average_and_maximum_by_hand() {
        let src = array![[1.0f32, 2.0, 10.0, 30.0], [3.0, 6.0, 20.0, 40.0]];
        let mut out = Array2::zeros((1, 2));
        reduce2x2(src.view(), out.view_mut(), box2);
        assert_eq!(out, array![[3.0f32, 25.0]]);
        reduce2x2(src.view(), out.view_mut(), |v| {
            v[0].max(v[1]).max(v[2]).max(v[3])
        });
        assert_eq!(out, array![[6.0f32, 40.0]]);
        let mut row = [0.0f32; 2];
        box_down2_rows(&[1.0, 2.0, 10.0, 30.0], &[3.0, 6.0, 20.0, 40.0], &mut row);
        assert_eq!(row, [3.0, 25.0]);
    }

    #[test]
    fn summation_order_is_fixed() {
        // (a + b) + c + d rounds differently from a + (b + c + d) for these values: the filter
        // must give the left-to-right sum.
        let v = [1.0e8f32, 1.0, -1.0e8, 1.0];
        assert_eq!(box2(v), (((v[0] + v[1]) + v[2]) + v[3]) * 0.25);
        assert_ne!(box2(v), (v[0] + (v[1] + (v[2] + v[3]))) * 0.25);
    }

    #[test]
    fn mismatched_shapes_write_only_the_overlap() {
        let src = Array2::from_elem((4, 4), 2.0f32);
        let mut out = Array2::from_elem((3, 1), -1.0f32);
        reduce2x2(src.view(), out.view_mut(), box2);
        assert_eq!(out, array![[2.0f32], [2.0], [-1.0]]);
    }
}
