//! Giving back part of the volume that breaching carves out of each parent cell.
//!
//! A level's output is consistent with its parent when every 2 × 2 block of children (one parent
//! cell) averages to the parent's value. The correction passes make it so; breaching then
//! lowers the cells of its channels and pulls their blocks' means down. [`restore_block_means`]
//! raises the cells of each block that breaching left alone by `share` of the block's carved
//! volume, shared equally among them. Channels keep their depth and grade, so the drainage they
//! open stays open; a share below 1 keeps the raise small next to them.
//!
//! Blocks are the 2 × 2 cells whose global row and column start even. Only blocks wholly inside
//! the arrays are touched; the cells of partial blocks along the edge keep their values, so the
//! caller computes one cell more on every side and drops it: the result of every complete block
//! depends on its four cells only, whatever the window.

use ndarray::{Array2, ArrayView1, ArrayView2};
use rayon::prelude::*;

/// Raises the cells of `carved` (the breached surface; `raw` before breaching, same shape, cell
/// `(0, 0)` at global `origin`) that are not below `raw`, block by block (module docs), by
/// `share · Σ(raw − carved) / n`, the sum over the block's lowered cells and `n` its cells left
/// alone. Blocks with no carved cell, or with every cell carved, are unchanged.
pub fn restore_block_means(
    raw: ArrayView2<'_, f32>,
    carved: &mut Array2<f32>,
    origin: (i64, i64),
    share: f32,
) {
    let (rows, cols) = carved.dim();
    if raw.dim() != (rows, cols) || share == 0.0 || cols == 0 {
        return;
    }
    if carved.as_slice_mut().is_none() {
        *carved = carved.as_standard_layout().to_owned();
    }
    let Some(flat) = carved.as_slice_mut() else {
        return;
    };
    let r_first = origin.0.rem_euclid(2) as usize;
    let c_first = origin.1.rem_euclid(2) as usize;
    // Each pair of rows holds whole blocks and nothing else reads them: the pairs run in
    // parallel, every block as it would alone.
    let skip = (r_first * cols).min(flat.len());
    flat[skip..]
        .par_chunks_mut(2 * cols)
        .enumerate()
        .for_each(|(b, pair)| {
            if pair.len() < 2 * cols {
                return;
            }
            let r = r_first + 2 * b;
            let (top, bottom) = pair.split_at_mut(cols);
            restore_row_pair((raw.row(r), raw.row(r + 1)), (top, bottom), c_first, share);
        });
}

/// [`restore_block_means`] over the blocks of one pair of rows whose first block starts at
/// column `c_first`: `raw`'s rows and `carved`'s.
fn restore_row_pair(
    (raw_top, raw_bottom): (ArrayView1<'_, f32>, ArrayView1<'_, f32>),
    (top, bottom): (&mut [f32], &mut [f32]),
    c_first: usize,
    share: f32,
) {
    let cols = top.len().min(bottom.len());
    for c in (c_first..cols.saturating_sub(1)).step_by(2) {
        let ([top_left, top_right], [bottom_left, bottom_right]) =
            (&mut top[c..c + 2], &mut bottom[c..c + 2])
        else {
            continue;
        };
        // The block's cells in row-major order, each with its value before breaching.
        let block = [
            (top_left, raw_top[c]),
            (top_right, raw_top[c + 1]),
            (bottom_left, raw_bottom[c]),
            (bottom_right, raw_bottom[c + 1]),
        ];
        let lowered = block.each_ref().map(|(cell, raw)| raw - **cell);
        let channel = lowered.map(|d| d > 0.0);
        let (mut carved_volume, mut kept) = (0.0f32, 0u32);
        for (&d, &is_channel) in lowered.iter().zip(&channel) {
            if is_channel {
                carved_volume += d;
            } else {
                kept += 1;
            }
        }
        if carved_volume > 0.0 && kept > 0 {
            let raise = share * carved_volume / kept as f32;
            for ((cell, _), is_channel) in block.into_iter().zip(channel) {
                if !is_channel {
                    *cell += raise;
                }
            }
        }
    }
}

/// Reference implementation of [`restore_block_means`] for tests: each cell finds its block from
/// its global coordinates and sums the block's four cells itself.
pub fn restore_block_means_naive(
    raw: &Array2<f32>,
    carved: &Array2<f32>,
    origin: (i64, i64),
    share: f32,
) -> Array2<f32> {
    let (rows, cols) = carved.dim();
    let global = |r: usize, c: usize| (origin.0 + r as i64, origin.1 + c as i64);
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let v = carved[[r, c]];
        let (gr, gc) = global(r, c);
        // The block's first cell, local.
        let (br, bc) = (
            gr.div_euclid(2) * 2 - origin.0,
            gc.div_euclid(2) * 2 - origin.1,
        );
        if share == 0.0 || br < 0 || bc < 0 || br + 1 >= rows as i64 || bc + 1 >= cols as i64 {
            return v;
        }
        let (br, bc) = (br as usize, bc as usize);
        let lowered_by: Vec<f32> = [(br, bc), (br, bc + 1), (br + 1, bc), (br + 1, bc + 1)]
            .iter()
            .map(|&p| raw[p] - carved[p])
            .collect();
        let carved_volume = lowered_by
            .iter()
            .filter(|&&d| d > 0.0)
            .fold(0.0f32, |a, &d| a + d);
        let channels = lowered_by.iter().filter(|&&d| d > 0.0).count();
        let kept = lowered_by.len() - channels;
        let mine_is_channel = raw[[r, c]] - v > 0.0;
        if carved_volume > 0.0 && kept > 0 && !mine_is_channel {
            v + share * carved_volume / kept as f32
        } else {
            v
        }
    })
}
