//! Building dictionaries from exemplars: cutting patches, normalising them into multi-resolution
//! atoms, and selecting atoms (every patch, or constrained k-medoids learning).
//!
//! Patches of `patch × patch` cells are cut every `stride` cells. For a high-resolution patch `X~`
//! its low-resolution patch is `X = box_down2(X~)`; with `a = mean(X)` and `s = ‖X − a‖` the atom
//! stores `lo = (X − a)/s`, `hi = (X~ − a)/s`, `mean_alt = a`, `relief = s`. Patches touching
//! invalid or non-finite cells, or flatter than [`MIN_RELIEF_M`], are skipped.
//!
//! Learning ([`Learning::Medoids`]) is sparsity-1 constrained dictionary learning whose atoms are
//! real patches: a seeded k-means++-style initialisation, then alternating assignment of each patch
//! to the atom of largest orientation-preserving dot product `lo_p · lo_d` and replacement of each
//! atom by the member closest to the normalised cluster mean. Everything is deterministic: fixed
//! summation orders, per-item parallel work collected in order, a seeded [`Rng`].

use std::sync::atomic::{AtomicBool, Ordering};

use ndarray::Array2;
use rayon::prelude::*;

use super::atoms::{AtomSource, Dictionary, DictionaryParams, LayerInfo, LayerKind, Learning};
use super::error::DictionaryError;
use super::features::{box_down2, centre_normalise, patch_mean_slope, MIN_RELIEF_M};
use super::ksvd::ksvd;
use super::rng::Rng;

/// One exemplar terrain: elevation plus extra layers on the same grid.
#[derive(Clone, Debug)]
pub struct Exemplar {
    /// Elevation, metres (rows × cols).
    pub elevation: Array2<f32>,
    /// Optional validity mask of the same shape (`false` cells are never part of a patch).
    pub valid: Option<Array2<bool>>,
    /// Metric cell size, metres.
    pub cell_m: f64,
    /// Extra layers `(name, values, kind)` on the elevation grid; derived layers (`log_area`,
    /// `northness`...) are computed by the caller beforehand.
    pub layers: Vec<(String, Array2<f32>, LayerKind)>,
}

/// Options of [`build`].
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// Side of a high-resolution patch in cells (even, at least 4). Default 16.
    pub patch: usize,
    /// Step between patches in cells (at least 1). Default 8.
    pub stride: usize,
    /// Number of atoms wanted; 0 keeps every patch. Default 256.
    pub atoms: usize,
    /// Atom selection. Default `Medoids { iterations: 6 }`.
    pub learning: Learning,
    /// Seed of every random choice. Default 1.
    pub seed: u64,
    /// Atoms per code while learning with [`Learning::Ksvd`] (the other learnings code with one
    /// atom). Default 1.
    pub sparsity: usize,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            patch: 16,
            stride: 8,
            atoms: 256,
            learning: Learning::Medoids { iterations: 6 },
            seed: 1,
            sparsity: 1,
        }
    }
}

/// Largest sparsity of a build or a code.
pub const MAX_SPARSITY: usize = 64;

/// Builds a dictionary from `exemplars`. `progress(stage, fraction)` is called with the stages
/// `"patches"`, `"learning"` and `"done"` and a fraction in `0..=1` of that stage.
pub fn build(
    exemplars: &[Exemplar],
    opts: &BuildOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Dictionary, DictionaryError> {
    build_cancellable(exemplars, opts, &AtomicBool::new(false), progress)
}

/// [`build`], returning [`DictionaryError::Cancelled`] soon after `cancel` becomes `true` (it is
/// checked between stages and between chunks of work).
pub fn build_cancellable(
    exemplars: &[Exemplar],
    opts: &BuildOptions,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Dictionary, DictionaryError> {
    let layers = validate(exemplars, opts)?;
    check_cancel(cancel)?;
    let patches = cut_patches(exemplars, opts, cancel, progress)?;
    let n = patches.sources.len();
    if n == 0 {
        return Err(DictionaryError::NoPatches);
    }
    progress("learning", 0.0);
    let want = if opts.atoms == 0 || opts.atoms >= n {
        n
    } else {
        opts.atoms
    };
    let cell_m = exemplars.iter().map(|e| e.cell_m).sum::<f64>() / exemplars.len() as f64;
    let params = DictionaryParams {
        patch: opts.patch,
        stride: opts.stride,
        atoms: opts.atoms,
        learning: opts.learning,
        seed: opts.seed,
        cell_m,
        sparsity: opts.sparsity,
    };
    let dict = match opts.learning {
        Learning::Ksvd { iterations } if want < n => {
            let mut seeds = init_plus_plus(
                &patches,
                want,
                &mut Rng::new(opts.seed),
                cancel,
                progress,
                0.2,
            )?;
            seeds.sort_unstable();
            let training = hi_vectors(exemplars, &patches, opts.patch);
            let p2 = opts.patch * opts.patch;
            let mut init = Vec::with_capacity(seeds.len() * p2);
            for &p in &seeds {
                let h = &training[p * p2..(p + 1) * p2];
                let norm = h.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>().sqrt();
                init.extend(h.iter().map(|&v| (f64::from(v) / norm.max(1e-12)) as f32));
            }
            let learned = ksvd(
                &training,
                p2,
                &init,
                opts.sparsity,
                iterations,
                cancel,
                &mut |f| progress("learning", 0.2 + 0.8 * f),
            )?;
            drop(training);
            check_cancel(cancel)?;
            progress("learning", 1.0);
            assemble_learned(exemplars, params, layers, &patches, &seeds, &learned.atoms)
        }
        _ => {
            let mut selected: Vec<usize> = if want == n {
                (0..n).collect()
            } else {
                match opts.learning {
                    Learning::Complete => evenly_spaced(n, want),
                    Learning::Medoids { iterations } | Learning::Ksvd { iterations } => {
                        learn_medoids(&patches, want, iterations, opts.seed, cancel, progress)?
                    }
                }
            };
            selected.sort_unstable();
            check_cancel(cancel)?;
            progress("learning", 1.0);
            assemble(exemplars, params, layers, &patches, &selected)
        }
    };
    dict.check_consistency().map_err(|e| {
        DictionaryError::Malformed(format!("built dictionary is inconsistent: {e}"))
    })?;
    progress("done", 1.0);
    Ok(dict)
}

fn check_cancel(cancel: &AtomicBool) -> Result<(), DictionaryError> {
    if cancel.load(Ordering::Relaxed) {
        Err(DictionaryError::Cancelled)
    } else {
        Ok(())
    }
}

/// Checks options and exemplars; returns the common layer list.
fn validate(
    exemplars: &[Exemplar],
    opts: &BuildOptions,
) -> Result<Vec<LayerInfo>, DictionaryError> {
    let bad = |m: String| Err(DictionaryError::InvalidParams(m));
    if opts.patch < 4 || opts.patch % 2 != 0 {
        return bad(format!(
            "patch size {} must be even and at least 4",
            opts.patch
        ));
    }
    if opts.patch > 1024 {
        return bad(format!("patch size {} exceeds 1024", opts.patch));
    }
    if opts.stride == 0 {
        return bad("stride must be at least 1".into());
    }
    if let Learning::Medoids { iterations } | Learning::Ksvd { iterations } = opts.learning {
        if iterations > 1000 {
            return bad(format!("{iterations} learning iterations exceeds 1000"));
        }
    }
    if opts.sparsity == 0 || opts.sparsity > MAX_SPARSITY {
        return bad(format!(
            "sparsity {} must lie between 1 and {MAX_SPARSITY}",
            opts.sparsity
        ));
    }
    let Some(first) = exemplars.first() else {
        return bad("no exemplar given".into());
    };
    let layers: Vec<LayerInfo> = first
        .layers
        .iter()
        .map(|(name, _, kind)| LayerInfo {
            name: name.clone(),
            kind: kind.clone(),
        })
        .collect();
    for (i, l) in layers.iter().enumerate() {
        if layers[..i].iter().any(|m| m.name == l.name) {
            return bad(format!("layer name {:?} appears twice", l.name));
        }
    }
    if exemplars.len() > u32::MAX as usize {
        return bad("too many exemplars".into());
    }
    for (e, ex) in exemplars.iter().enumerate() {
        let (rows, cols) = ex.elevation.dim();
        if rows > u32::MAX as usize || cols > u32::MAX as usize {
            return bad(format!("exemplar {e} is too large ({rows}×{cols})"));
        }
        if !(ex.cell_m.is_finite() && ex.cell_m > 0.0) {
            return bad(format!(
                "exemplar {e}: cell size {} must be positive",
                ex.cell_m
            ));
        }
        let shape = ex.elevation.dim();
        if let Some(v) = &ex.valid {
            if v.dim() != shape {
                return bad(format!(
                    "exemplar {e}: validity mask shape {:?} differs from elevation {shape:?}",
                    v.dim()
                ));
            }
        }
        if ex.layers.len() != layers.len() {
            return bad(format!(
                "exemplar {e} has {} layers, exemplar 0 has {}",
                ex.layers.len(),
                layers.len()
            ));
        }
        for ((name, data, kind), info) in ex.layers.iter().zip(&layers) {
            if *name != info.name || *kind != info.kind {
                return bad(format!(
                    "exemplar {e}: layer {name:?} ({kind:?}) differs from exemplar 0's {:?} ({:?})",
                    info.name, info.kind
                ));
            }
            if data.dim() != shape {
                return bad(format!(
                    "exemplar {e}: layer {name:?} shape {:?} differs from elevation {shape:?}",
                    data.dim()
                ));
            }
        }
    }
    Ok(layers)
}

/// Every usable patch: its low-resolution normalised elevation and statistics.
struct Patches {
    /// Side of a low patch.
    lo: usize,
    /// `N × lo²` normalised low-resolution elevation vectors.
    vectors: Vec<f32>,
    mean: Vec<f32>,
    relief: Vec<f32>,
    sources: Vec<AtomSource>,
}

impl Patches {
    fn dim(&self) -> usize {
        self.lo * self.lo
    }
    fn vector(&self, p: usize) -> &[f32] {
        let d = self.dim();
        &self.vectors[p * d..(p + 1) * d]
    }
}

/// Copies the `patch × patch` window at `(row, col)` of `a` into `out`; `false` if a value is not
/// finite.
fn copy_window(a: &Array2<f32>, row: usize, col: usize, patch: usize, out: &mut [f32]) -> bool {
    let mut ok = true;
    for r in 0..patch {
        for c in 0..patch {
            let v = a[[row + r, col + c]];
            ok &= v.is_finite();
            out[r * patch + c] = v;
        }
    }
    ok
}

/// A usable patch: its normalised low vector and `(a, s)`.
struct Cut {
    lo_norm: Vec<f32>,
    mean: f32,
    relief: f32,
}

/// Cuts the patch at `(row, col)`, or `None` if it touches invalid or non-finite cells or is flat.
fn cut(ex: &Exemplar, row: usize, col: usize, patch: usize) -> Option<Cut> {
    if let Some(valid) = &ex.valid {
        for r in 0..patch {
            for c in 0..patch {
                if !valid[[row + r, col + c]] {
                    return None;
                }
            }
        }
    }
    let lo = patch / 2;
    let mut hi_raw = vec![0.0f32; patch * patch];
    if !copy_window(&ex.elevation, row, col, patch, &mut hi_raw) {
        return None;
    }
    let mut lo_raw = vec![0.0f32; lo * lo];
    box_down2(&hi_raw, patch, &mut lo_raw);
    let mut lo_norm = vec![0.0f32; lo * lo];
    let (mean, relief) = centre_normalise(&lo_raw, &mut lo_norm);
    if !(relief >= MIN_RELIEF_M && relief.is_finite() && mean.is_finite()) {
        return None;
    }
    if lo_norm.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut buf = vec![0.0f32; patch * patch];
    for (_, data, _) in &ex.layers {
        if !copy_window(data, row, col, patch, &mut buf) {
            return None;
        }
    }
    Some(Cut {
        lo_norm,
        mean,
        relief,
    })
}

fn positions(len: usize, patch: usize, stride: usize) -> Vec<usize> {
    if len < patch {
        Vec::new()
    } else {
        (0..=len - patch).step_by(stride).collect()
    }
}

fn cut_patches(
    exemplars: &[Exemplar],
    opts: &BuildOptions,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Patches, DictionaryError> {
    let patch = opts.patch;
    let lo = patch / 2;
    let mut out = Patches {
        lo,
        vectors: Vec::new(),
        mean: Vec::new(),
        relief: Vec::new(),
        sources: Vec::new(),
    };
    let grids: Vec<(Vec<usize>, Vec<usize>)> = exemplars
        .iter()
        .map(|ex| {
            let (rows, cols) = ex.elevation.dim();
            (
                positions(rows, patch, opts.stride),
                positions(cols, patch, opts.stride),
            )
        })
        .collect();
    let total_rows: usize = grids.iter().map(|(r, _)| r.len()).sum::<usize>().max(1);
    let mut done_rows = 0usize;
    progress("patches", 0.0);
    const ROWS_PER_CHUNK: usize = 16;
    for (e, (ex, (rows, cols))) in exemplars.iter().zip(&grids).enumerate() {
        for chunk in rows.chunks(ROWS_PER_CHUNK) {
            check_cancel(cancel)?;
            // Collected in (row, col) order whatever the thread count.
            let cuts: Vec<Option<(Cut, AtomSource)>> = chunk
                .par_iter()
                .flat_map_iter(|&r| cols.iter().map(move |&c| (r, c)))
                .map(|(r, c)| {
                    cut(ex, r, c, patch).map(|k| {
                        let src = AtomSource {
                            exemplar: e as u32,
                            row: r as u32,
                            col: c as u32,
                        };
                        (k, src)
                    })
                })
                .collect();
            for (k, src) in cuts.into_iter().flatten() {
                out.vectors.extend_from_slice(&k.lo_norm);
                out.mean.push(k.mean);
                out.relief.push(k.relief);
                out.sources.push(src);
            }
            done_rows += chunk.len();
            progress("patches", done_rows as f64 / total_rows as f64);
        }
    }
    progress("patches", 1.0);
    Ok(out)
}

/// `k` indices evenly spread over `0..n` (`⌊i·n/k⌋`), for `k ≤ n`.
fn evenly_spaced(n: usize, k: usize) -> Vec<usize> {
    (0..k)
        .map(|i| ((i as u128 * n as u128) / k as u128) as usize)
        .collect()
}

/// Dot product summed in index order (the same order as the transposed assignment kernel).
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for (x, y) in a.iter().zip(b) {
        s += x * y;
    }
    s
}

const CHUNK: usize = 512;

/// For every patch, the index of the atom of largest dot product (ties → lowest index) and that
/// dot product. `at` is the `D × k` dimension-major atom matrix. Each patch is computed
/// independently, so the result does not depend on the thread count.
fn assign(patches: &Patches, at: &[f32], k: usize, assignment: &mut [u32], best: &mut [f32]) {
    let d = patches.dim();
    assignment
        .par_chunks_mut(CHUNK)
        .zip(best.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each_init(
            || vec![0.0f32; k],
            |acc, (ci, (asg, bst))| {
                for (j, (a_out, b_out)) in asg.iter_mut().zip(bst.iter_mut()).enumerate() {
                    let v = patches.vector(ci * CHUNK + j);
                    acc.fill(0.0);
                    for (dd, &x) in v.iter().enumerate().take(d) {
                        let row = &at[dd * k..(dd + 1) * k];
                        for (s, &w) in acc.iter_mut().zip(row) {
                            *s += x * w;
                        }
                    }
                    let mut arg = 0usize;
                    let mut val = f32::NEG_INFINITY;
                    for (i, &s) in acc.iter().enumerate() {
                        if s > val {
                            val = s;
                            arg = i;
                        }
                    }
                    *a_out = arg as u32;
                    *b_out = val;
                }
            },
        );
}

/// Dimension-major copy of the chosen atoms' vectors: `at[d·k + i] = v_{atoms[i]}[d]`.
fn transpose_atoms(patches: &Patches, atoms: &[usize], at: &mut Vec<f32>) {
    let d = patches.dim();
    let k = atoms.len();
    at.clear();
    at.resize(d * k, 0.0);
    for (i, &p) in atoms.iter().enumerate() {
        for (dd, &x) in patches.vector(p).iter().enumerate() {
            at[dd * k + i] = x;
        }
    }
}

/// Seeded k-means++-style initialisation: the first atom uniformly, each next one with
/// probability proportional to `(1 − max_dot)²` over the not yet chosen patches.
fn init_plus_plus(
    patches: &Patches,
    k: usize,
    rng: &mut Rng,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(&str, f64),
    share: f64,
) -> Result<Vec<usize>, DictionaryError> {
    let n = patches.sources.len();
    let mut chosen = vec![false; n];
    let mut atoms = Vec::with_capacity(k);
    let first = rng.below(n as u64) as usize;
    atoms.push(first);
    chosen[first] = true;
    let mut best = vec![f32::NEG_INFINITY; n];
    let mut last = first;
    while atoms.len() < k {
        if atoms.len() % 16 == 0 {
            check_cancel(cancel)?;
            progress("learning", share * atoms.len() as f64 / k as f64);
        }
        let atom = patches.vector(last);
        best.par_iter_mut().enumerate().for_each(|(p, b)| {
            let s = dot(patches.vector(p), atom);
            if s > *b {
                *b = s;
            }
        });
        let weight = |p: usize| -> f64 {
            if chosen[p] {
                0.0
            } else {
                let d = (1.0 - f64::from(best[p])).max(0.0);
                d * d
            }
        };
        let mut total = 0.0f64;
        for p in 0..n {
            total += weight(p);
        }
        let mut pick = None;
        if total > 0.0 {
            let target = rng.next_f64() * total;
            let mut cum = 0.0f64;
            for p in 0..n {
                let w = weight(p);
                if w > 0.0 {
                    cum += w;
                    pick = Some(p);
                    if cum > target {
                        break;
                    }
                }
            }
        }
        // Every remaining patch duplicates an atom: take the first unchosen one.
        let pick = match pick {
            Some(p) => p,
            None => match chosen.iter().position(|&c| !c) {
                Some(p) => p,
                None => break,
            },
        };
        chosen[pick] = true;
        atoms.push(pick);
        last = pick;
    }
    Ok(atoms)
}

fn learn_medoids(
    patches: &Patches,
    k: usize,
    iterations: u32,
    seed: u64,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Vec<usize>, DictionaryError> {
    let n = patches.sources.len();
    let d = patches.dim();
    let mut rng = Rng::new(seed);
    let init_share = if iterations == 0 { 1.0 } else { 0.3 };
    let mut atoms = init_plus_plus(patches, k, &mut rng, cancel, progress, init_share)?;
    let mut at = Vec::new();
    let mut assignment = vec![0u32; n];
    let mut best = vec![0.0f32; n];
    let mut sums = vec![0.0f64; k * d];
    let mut counts = vec![0usize; k];
    let mut centre = vec![0.0f32; k * d];
    for it in 0..iterations {
        check_cancel(cancel)?;
        progress(
            "learning",
            init_share + (1.0 - init_share) * f64::from(it) / f64::from(iterations),
        );
        transpose_atoms(patches, &atoms, &mut at);
        assign(patches, &at, k, &mut assignment, &mut best);
        check_cancel(cancel)?;

        // Cluster means, accumulated sequentially in patch order.
        sums.fill(0.0);
        counts.fill(0);
        for (p, &a) in assignment.iter().enumerate() {
            let a = a as usize;
            counts[a] += 1;
            for (s, &x) in sums[a * d..(a + 1) * d].iter_mut().zip(patches.vector(p)) {
                *s += f64::from(x);
            }
        }
        // Normalised means (a zero mean keeps the current atom as the centre).
        for a in 0..k {
            let sum = &sums[a * d..(a + 1) * d];
            let norm = sum.iter().map(|x| x * x).sum::<f64>().sqrt();
            let c = &mut centre[a * d..(a + 1) * d];
            if norm > 0.0 {
                for (o, &s) in c.iter_mut().zip(sum) {
                    *o = (s / norm) as f32;
                }
            } else {
                c.copy_from_slice(patches.vector(atoms[a]));
            }
        }
        // The member closest to its normalised mean (largest dot; ties → lowest patch index).
        let mut medoid: Vec<Option<(usize, f32)>> = vec![None; k];
        for (p, &a) in assignment.iter().enumerate() {
            let a = a as usize;
            let s = dot(patches.vector(p), &centre[a * d..(a + 1) * d]);
            match medoid[a] {
                Some((_, b)) if b >= s => {}
                _ => medoid[a] = Some((p, s)),
            }
        }
        let mut is_atom = vec![false; n];
        let mut new_atoms = vec![usize::MAX; k];
        for (a, m) in medoid.iter().enumerate() {
            if let Some((p, _)) = m {
                new_atoms[a] = *p;
                is_atom[*p] = true;
            }
        }
        // Empty clusters: re-seed from the worst-represented patches, worst first.
        let empty: Vec<usize> = (0..k).filter(|&a| medoid[a].is_none()).collect();
        if !empty.is_empty() {
            let mut order: Vec<usize> = (0..n).filter(|&p| !is_atom[p]).collect();
            order.sort_by(|&x, &y| best[x].total_cmp(&best[y]).then(x.cmp(&y)));
            for (a, p) in empty.into_iter().zip(order) {
                new_atoms[a] = p;
            }
        }
        if new_atoms == atoms {
            break;
        }
        atoms = new_atoms;
    }
    Ok(atoms)
}

/// Builds the dictionary arrays for the selected patches (in the given order).
fn assemble(
    exemplars: &[Exemplar],
    params: DictionaryParams,
    layers: Vec<LayerInfo>,
    patches: &Patches,
    selected: &[usize],
) -> Dictionary {
    let patch = params.patch;
    let lo = patch / 2;
    let nl = layers.len();
    struct Atom {
        lo_elev: Vec<f32>,
        hi_elev: Vec<f32>,
        slope: f32,
        lo_layers: Vec<f32>,
        hi_layers: Vec<f32>,
    }
    let built: Vec<Atom> = selected
        .par_iter()
        .map(|&p| {
            let src = patches.sources[p];
            let ex = &exemplars[src.exemplar as usize];
            let (row, col) = (src.row as usize, src.col as usize);
            let mut hi_raw = vec![0.0f32; patch * patch];
            copy_window(&ex.elevation, row, col, patch, &mut hi_raw);
            let mut lo_raw = vec![0.0f32; lo * lo];
            box_down2(&hi_raw, patch, &mut lo_raw);
            let a = f64::from(patches.mean[p]);
            let s = f64::from(patches.relief[p]);
            let hi_elev = hi_raw
                .iter()
                .map(|&x| ((f64::from(x) - a) / s) as f32)
                .collect();
            let slope = patch_mean_slope(&lo_raw, lo, (2.0 * ex.cell_m) as f32);
            let mut hi_layers = vec![0.0f32; nl * patch * patch];
            let mut lo_layers = vec![0.0f32; nl * lo * lo];
            for (l, (_, data, _)) in ex.layers.iter().enumerate() {
                let h = &mut hi_layers[l * patch * patch..(l + 1) * patch * patch];
                copy_window(data, row, col, patch, h);
                box_down2(h, patch, &mut lo_layers[l * lo * lo..(l + 1) * lo * lo]);
            }
            Atom {
                lo_elev: patches.vector(p).to_vec(),
                hi_elev,
                slope,
                lo_layers,
                hi_layers,
            }
        })
        .collect();
    let n = selected.len();
    let mut d = Dictionary {
        params,
        layers,
        n_atoms: n,
        lo_elev: Vec::with_capacity(n * lo * lo),
        hi_elev: Vec::with_capacity(n * patch * patch),
        mean_alt: Vec::with_capacity(n),
        mean_slope: Vec::with_capacity(n),
        relief: Vec::with_capacity(n),
        lo_layers: Vec::with_capacity(n * nl * lo * lo),
        hi_layers: Vec::with_capacity(n * nl * patch * patch),
        sources: Vec::with_capacity(n),
    };
    for (atom, &p) in built.into_iter().zip(selected) {
        d.lo_elev.extend_from_slice(&atom.lo_elev);
        d.hi_elev.extend_from_slice(&atom.hi_elev);
        d.mean_alt.push(patches.mean[p]);
        d.mean_slope.push(atom.slope);
        d.relief.push(patches.relief[p]);
        d.lo_layers.extend_from_slice(&atom.lo_layers);
        d.hi_layers.extend_from_slice(&atom.hi_layers);
        d.sources.push(patches.sources[p]);
    }
    d
}

/// The high-resolution elevation of every patch, centred and scaled by its low statistics like
/// an atom (`(X~ − a)/s`): `N × patch²`, patch-major — K-SVD's training vectors.
fn hi_vectors(exemplars: &[Exemplar], patches: &Patches, patch: usize) -> Vec<f32> {
    let p2 = patch * patch;
    let mut out = vec![0.0f32; patches.sources.len() * p2];
    out.par_chunks_mut(p2).enumerate().for_each(|(p, h)| {
        let src = patches.sources[p];
        let ex = &exemplars[src.exemplar as usize];
        copy_window(&ex.elevation, src.row as usize, src.col as usize, patch, h);
        let (a, s) = (f64::from(patches.mean[p]), f64::from(patches.relief[p]));
        h.iter_mut()
            .for_each(|v| *v = ((f64::from(*v) - a) / s) as f32);
    });
    out
}

/// A dictionary of learned high-resolution atoms (`learned`: unit-norm rows, one per seed
/// patch): each atom's low-resolution version is its box down-sampling, and both are centred and
/// scaled so that the low atom has unit norm (the invariant of every dictionary); its mean
/// altitude, slope, relief, extra layers and provenance are those of the real patch it was
/// initialised from. An atom without low-frequency content (which cannot be matched) is replaced
/// by its seed patch.
fn assemble_learned(
    exemplars: &[Exemplar],
    params: DictionaryParams,
    layers: Vec<LayerInfo>,
    patches: &Patches,
    seeds: &[usize],
    learned: &[f32],
) -> Dictionary {
    let patch = params.patch;
    let lo = patch / 2;
    let p2 = patch * patch;
    let mut d = assemble(exemplars, params, layers, patches, seeds);
    for (a, h) in learned.chunks(p2).enumerate() {
        let mut lo_raw = vec![0.0f32; lo * lo];
        box_down2(h, patch, &mut lo_raw);
        let mut lo_norm = vec![0.0f32; lo * lo];
        let (mean, norm) = centre_normalise(&lo_raw, &mut lo_norm);
        if norm < 1e-6 {
            continue;
        }
        d.lo_elev[a * lo * lo..(a + 1) * lo * lo].copy_from_slice(&lo_norm);
        for (o, &v) in d.hi_elev[a * p2..(a + 1) * p2].iter_mut().zip(h) {
            *o = (f64::from(v - mean) / f64::from(norm)) as f32;
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    // The transposed assignment kernel against a naive per-pair argmax (ties → lowest index),
    // over more patches than one parallel chunk.
    #[test]
    fn assignment_kernel_matches_naive_argmax() {
        let lo = 2;
        let n = 1300;
        let mut rng = Rng::new(3);
        let mut vectors = Vec::new();
        for _ in 0..n {
            // Values on a coarse grid so exact ties happen.
            vectors.extend((0..4).map(|_| rng.below(3) as f32 - 1.0));
        }
        let patches = Patches {
            lo,
            vectors,
            mean: vec![0.0; n],
            relief: vec![1.0; n],
            sources: vec![
                AtomSource {
                    exemplar: 0,
                    row: 0,
                    col: 0
                };
                n
            ],
        };
        let atoms = [5usize, 17, 5, 900, 42, 1299, 3];
        let mut at = Vec::new();
        transpose_atoms(&patches, &atoms, &mut at);
        let (mut asg, mut best) = (vec![0u32; n], vec![0.0f32; n]);
        assign(&patches, &at, atoms.len(), &mut asg, &mut best);
        for p in 0..n {
            let v = &patches.vectors[p * 4..p * 4 + 4];
            let dots: Vec<f32> = atoms
                .iter()
                .map(|&a| (0..4).map(|i| v[i] * patches.vectors[a * 4 + i]).sum())
                .collect();
            let max = dots.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
            let want = dots.iter().position(|&d| d == max).unwrap_or(0);
            assert_eq!(asg[p] as usize, want, "patch {p}: {dots:?}");
            assert_eq!(best[p], max);
        }
    }

    #[test]
    fn evenly_spaced_indices() {
        assert_eq!(evenly_spaced(10, 5), vec![0, 2, 4, 6, 8]);
        assert_eq!(evenly_spaced(7, 3), vec![0, 2, 4]);
        assert_eq!(evenly_spaced(4, 4), vec![0, 1, 2, 3]);
    }

    #[test]
    fn positions_cover_the_grid() {
        assert_eq!(positions(40, 16, 8), vec![0, 8, 16, 24]);
        assert_eq!(positions(15, 16, 8), Vec::<usize>::new());
        assert_eq!(positions(16, 16, 8), vec![0]);
    }

    #[test]
    fn invalid_params_rejected() {
        let ex = Exemplar {
            elevation: Array2::zeros((32, 32)),
            valid: None,
            cell_m: 10.0,
            layers: vec![],
        };
        for opts in [
            BuildOptions {
                patch: 6 + 1,
                ..Default::default()
            },
            BuildOptions {
                patch: 2,
                ..Default::default()
            },
            BuildOptions {
                stride: 0,
                ..Default::default()
            },
        ] {
            let r = build(std::slice::from_ref(&ex), &opts, &mut |_, _| {});
            assert!(
                matches!(r, Err(DictionaryError::InvalidParams(_))),
                "{opts:?}"
            );
        }
        let mut bad_layer = ex.clone();
        bad_layer
            .layers
            .push(("veg".into(), Array2::zeros((31, 32)), LayerKind::Continuous));
        let r = build(&[bad_layer], &BuildOptions::default(), &mut |_, _| {});
        assert!(matches!(r, Err(DictionaryError::InvalidParams(_))));
        let r = build(&[], &BuildOptions::default(), &mut |_, _| {});
        assert!(matches!(r, Err(DictionaryError::InvalidParams(_))));
    }
}
