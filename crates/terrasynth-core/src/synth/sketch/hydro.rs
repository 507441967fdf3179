//! Hydrological conditioning of composition depressions. Two real patches rarely agree on the
//! height of a valley floor where a seam crosses it, and a patch's valley may end against
//! another's hillside; what the Poisson solve leaves of such disagreements are dams, and behind
//! them lakes no real terrain has. A depression most of whose cells held no water in the
//! exemplars they came from is such a lake: it is drained by a hybrid of breaching and filling (Lindsay 2016, "Efficient hybrid breaching-
//! filling sink removal methods for flow path enforcement in digital elevation models"): the
//! D8 flow path from its lowest cell through the spill point is lowered to at most
//! [`MAX_CUT_M`] below the lake level (and made to fall by [`CARVE_STEP_M`] a cell), and what is
//! left of the depression below that level is filled (a depression on a sketched valley may be cut
//! to [`MAX_CHANNEL_CUT_M`]: the valley should drain). Paths never cut through protected cells
//! (the sketch's ridges); such lakes are filled. Depressions that were depressions in the
//! exemplars (natural lakes and closed basins) are kept, so the result keeps about the exemplars'
//! share of them.

use ndarray::Array2;

use crate::analysis::{d8_receivers, priority_flood_fill, priority_flood_fill_flat, D8_OFFSETS};
use crate::raster::CellSizes;

/// A depression is kept when at least this share of its cells held water in their exemplars.
pub const NATURAL_SHARE: f64 = 0.5;
/// Deepest cut through a dam, metres (deeper trenches show on flat ground).
pub const MAX_CUT_M: f32 = 10.0;
/// Deepest cut through a dam across a sketched valley, metres.
pub const MAX_CHANNEL_CUT_M: f32 = 40.0;
/// Fall of a carved path per cell, metres.
pub const CARVE_STEP_M: f32 = 0.01;
/// Conditioning passes (nested depressions surface one level per pass).
pub const PASSES: usize = 6;

/// What conditioning did.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Conditioned {
    /// Composition depressions drained.
    pub drained: usize,
    /// Natural depressions kept.
    pub kept: usize,
    /// Cells lowered along carved paths.
    pub carved: usize,
    /// Cells raised by filling.
    pub filled: usize,
}

/// Drains the composition depressions of `z` (see the module). `natural[i]`: cell `i` held water
/// in its exemplar; `protected[i]`: never carve through cell `i`; `channel[i]`: cell `i` is on a
/// sketched valley, which should drain: depressions holding one are cut deeper and always drained.
pub fn condition(
    z: &mut Array2<f32>,
    cells: &CellSizes,
    natural: &[bool],
    protected: &[bool],
    channel: &[bool],
) -> Conditioned {
    let (rows, cols) = z.dim();
    let n = rows * cols;
    let mut out = Conditioned::default();
    if natural.len() != n || protected.len() != n || channel.len() != n || rows < 3 || cols < 3 {
        return out;
    }
    for _ in 0..PASSES {
        let flat = priority_flood_fill_flat(z);
        let eps = priority_flood_fill(z);
        let rcv = d8_receivers(&eps, cells);
        let h: Vec<f32> = z.iter().copied().collect();
        let f: Vec<f32> = flat.iter().copied().collect();
        let wet: Vec<bool> = (0..n).map(|i| f[i] > h[i]).collect();
        // Depressions: 8-connected wet components.
        let mut comp = vec![usize::MAX; n];
        let mut members: Vec<Vec<usize>> = Vec::new();
        for s in 0..n {
            if !wet[s] || comp[s] != usize::MAX {
                continue;
            }
            let id = members.len();
            let mut list = vec![s];
            comp[s] = id;
            let mut k = 0;
            while k < list.len() {
                let u = list[k];
                let (r, c) = (u / cols, u % cols);
                for &(dr, dc) in &D8_OFFSETS {
                    let (Some(nr), Some(nc)) = (r.checked_add_signed(dr), c.checked_add_signed(dc))
                    else {
                        continue;
                    };
                    if nr < rows && nc < cols {
                        let v = nr * cols + nc;
                        if wet[v] && comp[v] == usize::MAX {
                            comp[v] = id;
                            list.push(v);
                        }
                    }
                }
                k += 1;
            }
            members.push(list);
        }
        if members.is_empty() {
            break;
        }
        let receiver = |i: usize| -> Option<usize> {
            let d = rcv[[i / cols, i % cols]];
            if d as usize >= 8 {
                return None;
            }
            let (dr, dc) = D8_OFFSETS[d as usize];
            let nr = (i / cols).checked_add_signed(dr)?;
            let nc = (i % cols).checked_add_signed(dc)?;
            (nr < rows && nc < cols).then_some(nr * cols + nc)
        };
        let mut changed = false;
        let mut kept = 0usize;
        for list in &members {
            // The lowest cell (first on ties) and the lake level.
            let pit = list
                .iter()
                .copied()
                .min_by(|&a, &b| h[a].total_cmp(&h[b]).then(a.cmp(&b)))
                .unwrap_or(list[0]);
            let level = f[pit];
            // The flow path out of the lake: through the wet cells, over the spill point, down
            // to ground lower than the cut's level.
            let on_channel = list.iter().any(|&i| channel[i]);
            let natural_cells = list.iter().filter(|&&i| natural[i]).count();
            if !on_channel && natural_cells as f64 >= NATURAL_SHARE * list.len() as f64 {
                kept += 1;
                continue;
            }
            let max_cut = if on_channel {
                MAX_CHANNEL_CUT_M
            } else {
                MAX_CUT_M
            };
            let cut_level = (level - max_cut).max(h[pit]);
            let mut path = Vec::new();
            let mut spill = None;
            let mut cur = pit;
            let mut steps = 0usize;
            while let Some(next) = receiver(cur) {
                steps += 1;
                if steps > n {
                    break;
                }
                if spill.is_none() && !wet[next] {
                    spill = Some(next);
                }
                let target = cut_level - CARVE_STEP_M * steps as f32;
                if spill.is_some() && h[next] <= target {
                    break;
                }
                path.push(next);
                cur = next;
            }
            if spill.is_none() {
                kept += 1;
                continue;
            }
            let blocked = path.iter().any(|&i| protected[i]);
            let floor = if blocked { level } else { cut_level };
            if !blocked {
                for (k, &i) in path.iter().enumerate() {
                    let target = floor - CARVE_STEP_M * (k + 1) as f32;
                    let (r, c) = (i / cols, i % cols);
                    if z[[r, c]] > target {
                        z[[r, c]] = target;
                        out.carved += 1;
                        changed = true;
                    }
                }
            }
            for &i in list {
                let (r, c) = (i / cols, i % cols);
                if z[[r, c]] < floor {
                    z[[r, c]] = floor;
                    out.filled += 1;
                    changed = true;
                }
            }
            out.drained += 1;
        }
        out.kept = kept;
        if !changed {
            break;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dam_of_composition_is_cut_and_a_natural_one_is_kept() {
        // A valley falling east, dammed at column 20 by a 10 m step.
        let (rows, cols) = (9, 40);
        let valley = |r: usize, c: usize| {
            let floor = 100.0 - c as f32;
            let dam = if (19..=20).contains(&c) { 12.0 } else { 0.0 };
            floor + dam + 20.0 * (r as f32 - 4.0).abs()
        };
        let cells = CellSizes::uniform(rows, 100.0);
        let base = Array2::from_shape_fn((rows, cols), |(r, c)| valley(r, c));
        assert!(crate::analysis::flood_extent(&base) > 0.0);
        let free = vec![false; rows * cols];
        let mut z = base.clone();
        let done = condition(&mut z, &cells, &free, &free, &free);
        assert_eq!(done.drained, 1, "{done:?}");
        assert_eq!(crate::analysis::flood_extent(&z), 0.0);
        // The cut goes no deeper than needed and leaves the slopes alone.
        assert!(z[[0, 5]] == base[[0, 5]]);
        let mut kept = base.clone();
        let wet: Vec<bool> = crate::analysis::priority_flood_fill_flat(&base)
            .iter()
            .zip(base.iter())
            .map(|(f, h)| f > h)
            .collect();
        let done = condition(&mut kept, &cells, &wet, &free, &free);
        assert_eq!((done.drained, done.kept), (0, 1));
        assert_eq!(kept, base);
    }
}
