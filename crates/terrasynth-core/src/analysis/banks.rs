//! Banks for breached channels: turns the one-cell trenches that [`breach`](super::breach) carves
//! into V-shaped valleys by lowering the cells beside them, ring by ring, without creating a pit.
//! An ablation lever of the amplifier (`Levers::banks`, README "Realism"), not part of the served
//! amplifier.
//!
//! Definition: given the surface before breaching (`raw`) and after (`carved`), over the same
//! cells, each ring lowers every cell that the breaching left at its raw value toward `share` of
//! the deepest carve `raw − current` among its 8 neighbours — to `max(z − share·d, next_up(n))`
//! (`z` its raw value) for neighbour `n` of depth `d > 0`, the lowest such value and never above
//! its current one — so it stays strictly above the neighbour it follows, and a ring-`k` bank
//! sits `share^k` of the trench's depth below its raw value. A ring reads the ring before it over one more cell, so each ring consumes
//! one cell of frame on every side, and a cell's result depends on the `rings`-cell neighbourhood
//! alone: cutting windows out of a larger surface gives the same values.
//!
//! Every lowered cell keeps a strictly lower neighbour (the one it followed, which can only have
//! been lowered further), and no cell rises, so the rings create no pit.

use ndarray::{s, Array2, ArrayView2};

use super::common::{next_up, D8_OFFSETS};

/// The rings of banks around the channels that turned `raw` into `carved` (same shape): `carved`
/// without a frame of `rings` cells on every side, with `rings` rings of banks (see the module
/// docs). Empty when the grids are smaller than the frame; `carved` cropped when the shapes differ.
pub fn widen_channels(
    raw: &Array2<f32>,
    carved: &Array2<f32>,
    rings: usize,
    share: f32,
) -> Array2<f32> {
    let (rows, cols) = carved.dim();
    if rows <= 2 * rings || cols <= 2 * rings {
        return Array2::zeros((
            rows.saturating_sub(2 * rings),
            cols.saturating_sub(2 * rings),
        ));
    }
    if raw.dim() != carved.dim() {
        return carved
            .slice(s![rings..rows - rings, rings..cols - rings])
            .to_owned();
    }
    let mut current = carved.clone();
    for ring in 0..rings {
        // `current` covers cells `ring..rows − ring` of `raw` and `carved`.
        let inner = s![ring..rows - ring, ring..cols - ring];
        current = bank_ring(raw.slice(inner), carved.slice(inner), &current, share);
    }
    current
}

/// One ring of [`widen_channels`]: the inner cells of `current` (one-cell frame dropped), each
/// not carved by the breaching lowered beside its neighbours' carves.
fn bank_ring(
    raw: ArrayView2<'_, f32>,
    carved: ArrayView2<'_, f32>,
    current: &Array2<f32>,
    share: f32,
) -> Array2<f32> {
    let (rows, cols) = current.dim();
    Array2::from_shape_fn((rows - 2, cols - 2), |(r, c)| {
        let (r, c) = (r + 1, c + 1);
        let (v, own) = (current[[r, c]], raw[[r, c]]);
        if carved[[r, c]] < own {
            return v;
        }
        let mut lowest = v;
        for &(dr, dc) in &D8_OFFSETS {
            let (nr, nc) = ((r as isize + dr) as usize, (c as isize + dc) as usize);
            let n = current[[nr, nc]];
            let depth = raw[[nr, nc]] - n;
            if depth > 0.0 {
                let bank = (own - share * depth).max(next_up(n));
                if bank < lowest {
                    lowest = bank;
                }
            }
        }
        lowest
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_trench_across_a_plateau_gets_banks_at_the_share_of_its_depth() {
        // A plateau at 10 with a trench down column 4 carved to 6 (depth 4).
        let raw = Array2::from_elem((9, 9), 10.0f32);
        let mut carved = raw.clone();
        for r in 0..9 {
            carved[[r, 4]] = 6.0;
        }
        let one = widen_channels(&raw, &carved, 1, 0.5);
        assert_eq!(one.dim(), (7, 7));
        // Inner column 3 is global column 4: the trench keeps its value.
        for r in 0..7 {
            assert_eq!(one[[r, 3]], 6.0);
            assert_eq!(one[[r, 2]], 8.0);
            assert_eq!(one[[r, 4]], 8.0);
            assert_eq!(one[[r, 0]], 10.0);
        }
        // A second ring: half of the first ring's depth of 2.
        let two = widen_channels(&raw, &carved, 2, 0.5);
        assert_eq!(two.dim(), (5, 5));
        for r in 0..5 {
            assert_eq!(
                two.row(r).to_vec(),
                vec![10.0, 9.0, 8.0, 6.0, 8.0, 9.0, 10.0][1..6]
            );
        }
        // Never to the trench or below it, however large the share.
        let full = widen_channels(&raw, &carved, 1, 1.0);
        assert_eq!(full[[0, 2]], next_up(6.0));
    }

    #[test]
    fn small_or_mismatched_grids_do_not_panic() {
        let a = Array2::from_elem((4, 4), 1.0f32);
        assert_eq!(widen_channels(&a, &a, 2, 0.5).dim(), (0, 0));
        assert_eq!(widen_channels(&a, &a, 0, 0.5), a);
        let b = Array2::from_elem((5, 4), 1.0f32);
        assert_eq!(widen_channels(&b, &a, 1, 0.5).dim(), (2, 2));
    }
}
