//! Matching a low-resolution input patch `P` against the atoms of a dictionary:
//! `g(P, D_i) = Σ_j ω_j g_j(P_j, D_i^j)` with `Σ ω_j = 1` (DESIGN.md, method 1).
//!
//! Terms:
//! - elevation, orientation-preserving: `(1 + P_h · D_h,i) / 2` on centred unit-norm patches;
//! - altitude and slope: `exp(−x² / σ²)` of the difference of mean altitude (mean slope), with
//!   `σ = max_i |P − D_i| / (2 √ln 2)` computed per query;
//! - continuous extra layers (drainage, irradiance...): `(1 + P · D) / 2` on centred unit-norm
//!   patches;
//! - class layers: the mean over pixels of the dot product of unit-norm class-probability vectors.
//!
//! [`best_match_naive`] is the reference: a full scan scoring every atom with [`Matcher::score`].
//! [`Matcher::best_match`] returns exactly the same atom (ties → lowest index): it computes every
//! elevation dot product with the atoms stored dimension-major, so the inner loop runs across atoms
//! and vectorises without changing the per-atom summation order, then prunes atoms whose upper
//! bound cannot beat the best full score, and scores the rest with the same formula.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::atoms::{Dictionary, LayerKind};
use super::rng::hash2;
use crate::math;
use crate::simd::Isa;

/// Slack added to the pruning bound so that float rounding of the full score can never make a
/// pruned atom the true argmax.
const PRUNE_SLACK: f32 = 1e-4;

/// Matching weights `ω_j`. They are normalised to sum 1 before use; a weight of 0 disables a
/// term. Layer weights refer to extra dictionary layers by name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatchWeights {
    /// Weight of the orientation-preserving elevation term.
    pub elevation: f32,
    /// Weight of the mean-altitude kernel.
    pub altitude: f32,
    /// Weight of the mean-slope kernel.
    pub slope: f32,
    /// Weights of extra layers by name (continuous layers, or class groups by group name).
    pub layers: Vec<(String, f32)>,
}

impl Default for MatchWeights {
    fn default() -> Self {
        MatchWeights {
            elevation: 0.8,
            altitude: 0.1,
            slope: 0.1,
            layers: Vec::new(),
        }
    }
}

/// Errors of matching set-up.
#[derive(Debug, Clone, thiserror::Error, PartialEq, Eq)]
pub enum MatchError {
    /// A weight is negative or not finite, or all weights are zero.
    #[error("invalid matching weights: {0}")]
    InvalidWeights(String),
    /// A weight names a layer the dictionary does not have.
    #[error("matching weight names unknown layer `{0}`")]
    UnknownLayer(String),
    /// A query does not have the length the dictionary expects.
    #[error("query patch has {got} values, the dictionary expects {want}")]
    QueryShape {
        /// Values given.
        got: usize,
        /// Values expected.
        want: usize,
    },
}

/// A matching term on extra layers, resolved against a dictionary.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerTerm {
    /// A continuous layer at dictionary index `layer`.
    Continuous {
        /// Index into `Dictionary::layers`.
        layer: usize,
        /// Normalised weight.
        weight: f32,
    },
    /// A class group made of the dictionary layers `layers`.
    Class {
        /// Indices into `Dictionary::layers`, in dictionary order.
        layers: Vec<usize>,
        /// Normalised weight.
        weight: f32,
    },
}

/// Weights resolved against one dictionary and normalised to sum 1.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedWeights {
    /// Elevation term weight.
    pub elevation: f32,
    /// Altitude kernel weight.
    pub altitude: f32,
    /// Slope kernel weight.
    pub slope: f32,
    /// Extra-layer terms.
    pub layers: Vec<LayerTerm>,
}

impl ResolvedWeights {
    /// Resolves `w` against `dict`: checks values, looks up layer names (a name may be a
    /// continuous layer or a class group), normalises the sum to 1.
    pub fn resolve(w: &MatchWeights, dict: &Dictionary) -> Result<Self, MatchError> {
        let all = [w.elevation, w.altitude, w.slope]
            .into_iter()
            .chain(w.layers.iter().map(|(_, v)| *v));
        let mut total = 0.0f32;
        for v in all {
            if !v.is_finite() || v < 0.0 {
                return Err(MatchError::InvalidWeights(format!(
                    "weight {v} is negative or not finite"
                )));
            }
            total += v;
        }
        if total <= 0.0 {
            return Err(MatchError::InvalidWeights("all weights are zero".into()));
        }
        let mut layers = Vec::new();
        for (name, v) in &w.layers {
            if *v == 0.0 {
                continue;
            }
            let weight = v / total;
            if let Some(i) = dict.layer_index(name) {
                if dict.layers[i].kind == LayerKind::Continuous {
                    layers.push(LayerTerm::Continuous { layer: i, weight });
                    continue;
                }
            }
            let members: Vec<usize> = dict
                .layers
                .iter()
                .enumerate()
                .filter(|(_, l)| matches!(&l.kind, LayerKind::Class { group } if group == name))
                .map(|(i, _)| i)
                .collect();
            if members.is_empty() {
                return Err(MatchError::UnknownLayer(name.clone()));
            }
            layers.push(LayerTerm::Class {
                layers: members,
                weight,
            });
        }
        Ok(ResolvedWeights {
            elevation: w.elevation / total,
            altitude: w.altitude / total,
            slope: w.slope / total,
            layers,
        })
    }

    /// Sum of the weights of the layer terms: the most they can add to a score.
    fn layers_weight(&self) -> f32 {
        self.layers
            .iter()
            .map(|t| match t {
                LayerTerm::Continuous { weight, .. } | LayerTerm::Class { weight, .. } => *weight,
            })
            .sum::<f32>()
    }

    /// Sum of the weights of every term other than elevation: the most they can add to a score.
    fn rest(&self) -> f32 {
        self.altitude + self.slope + self.layers_weight()
    }
}

/// A low-resolution input patch prepared for matching.
#[derive(Clone, Debug, Default)]
pub struct Query {
    /// Centred, unit-norm elevation `P_h` (`lo²` values; all zero for a flat patch).
    pub elevation: Vec<f32>,
    /// Mean altitude `P_a`, metres.
    pub mean_alt: f32,
    /// Mean slope, m/m.
    pub mean_slope: f32,
    /// Per dictionary layer: the input's patch of that layer, prepared for its term (centred unit
    /// norm for continuous layers, raw probabilities for class layers), or empty when the input
    /// does not have the layer (the term then scores 0.5 for continuous, 0 for class).
    pub layers: Vec<Vec<f32>>,
}

/// The per-query kernel widths shared by every atom.
#[derive(Clone, Copy, Debug)]
struct Sigmas {
    inv_alt2: f32,
    inv_slope2: f32,
}

/// `σ = max_i |P − D_i| / (2 √ln 2)`, returned as `1/σ²` (0 when σ = 0: the kernel is then 1).
fn inv_sigma2(p: f32, min: f32, max: f32) -> f32 {
    let m = (p - min).abs().max((p - max).abs());
    let sigma = m / (2.0 * std::f32::consts::LN_2.sqrt());
    if sigma > 0.0 {
        1.0 / (sigma * sigma)
    } else {
        0.0
    }
}

fn min_max(v: &[f32]) -> (f32, f32) {
    v.iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for (x, y) in a.iter().zip(b) {
        s += x * y;
    }
    s
}

/// Centres `x` and scales it to unit norm (all zeros when constant). Used on continuous layers of
/// both queries and atoms.
pub fn unit_centred(x: &[f32]) -> Vec<f32> {
    let mut out = vec![0.0; x.len()];
    super::features::centre_normalise(x, &mut out);
    out
}

/// Mean over pixels of the dot product of unit-norm class vectors: `p(c, px)` and `d(c, px)` are
/// the query's and the atom's value of the group's `c`-th layer (of `k`) at pixel `px` (of `n`).
/// Read in place, so that scoring an atom allocates nothing.
fn class_similarity(
    k: usize,
    n: usize,
    p: impl Fn(usize, usize) -> f32,
    d: impl Fn(usize, usize) -> f32,
) -> f32 {
    if n == 0 || k == 0 {
        return 0.0;
    }
    let mut total = 0.0f32;
    for px in 0..n {
        let (mut pp, mut dd, mut pd) = (0.0f32, 0.0f32, 0.0f32);
        for c in 0..k {
            let a = p(c, px);
            let b = d(c, px);
            pp += a * a;
            dd += b * b;
            pd += a * b;
        }
        let den = (pp * dd).sqrt();
        if den > 0.0 {
            total += pd / den;
        }
    }
    total / n as f32
}

/// Atom data prepared once per dictionary for the layer terms.
#[derive(Clone, Debug)]
struct PreparedLayers {
    /// Per dictionary layer, per atom: centred unit-norm low patch (continuous layers) or raw
    /// (class layers), `n × lo²` each.
    atoms: Vec<Vec<f32>>,
}

impl PreparedLayers {
    fn new(dict: &Dictionary) -> Self {
        let lo2 = dict.lo_patch() * dict.lo_patch();
        let atoms = (0..dict.layers.len())
            .map(|l| {
                let mut all = Vec::with_capacity(dict.n_atoms * lo2);
                for i in 0..dict.n_atoms {
                    let raw = dict.lo_layer(i, l);
                    match dict.layers[l].kind {
                        LayerKind::Continuous => all.extend(unit_centred(raw)),
                        LayerKind::Class { .. } => all.extend_from_slice(raw),
                    }
                }
                all
            })
            .collect();
        PreparedLayers { atoms }
    }

    fn atom(&self, layer: usize, i: usize, lo2: usize) -> &[f32] {
        &self.atoms[layer][i * lo2..(i + 1) * lo2]
    }
}

/// Everything of the score of atom `i` except the elevation dot product, which the caller passes
/// in `elev_dot`. Both the naive scan and the fast matcher call this, so their scores agree to
/// the bit.
#[allow(clippy::too_many_arguments)]
fn combine(
    w: &ResolvedWeights,
    dict: &Dictionary,
    prepared: &PreparedLayers,
    q: &Query,
    s: Sigmas,
    i: usize,
    elev_dot: f32,
) -> f32 {
    let lo2 = dict.lo_patch() * dict.lo_patch();
    let mut score = w.elevation * (0.5 * (1.0 + elev_dot));
    if w.altitude > 0.0 {
        let d = q.mean_alt - dict.mean_alt[i];
        score += w.altitude * math::expf(-(d * d) * s.inv_alt2);
    }
    if w.slope > 0.0 {
        let d = q.mean_slope - dict.mean_slope[i];
        score += w.slope * math::expf(-(d * d) * s.inv_slope2);
    }
    for term in &w.layers {
        match term {
            LayerTerm::Continuous { layer, weight } => {
                let p = q.layers.get(*layer).map_or(&[][..], |v| v.as_slice());
                let g = if p.len() == lo2 {
                    0.5 * (1.0 + dot(p, prepared.atom(*layer, i, lo2)))
                } else {
                    0.5
                };
                score += weight * g;
            }
            LayerTerm::Class { layers, weight } => {
                let k = layers.len();
                let have_all = layers
                    .iter()
                    .all(|l| q.layers.get(*l).is_some_and(|v| v.len() == lo2));
                if !have_all {
                    continue;
                }
                score += weight
                    * class_similarity(
                        k,
                        lo2,
                        |c, px| q.layers[layers[c]][px],
                        |c, px| prepared.atom(layers[c], i, lo2)[px],
                    );
            }
        }
    }
    score
}

/// An upper bound of `e^{−x}` for `x ≥ 0` without an exponential: `1 / (1 + x + x²/2 + x³/6)`
/// (the first terms of `e^x`'s series, all positive, sum to at most `e^x`).
#[inline]
fn exp_neg_upper(x: f32) -> f32 {
    1.0 / (1.0 + x * (1.0 + x * (0.5 + x * (1.0 / 6.0))))
}

/// Upper bounds of the full scores ([`combine`]) of the atoms `start..start + dots.len()` given
/// their elevation dot products `dots`, written to `out`; cheaper than the scores and free of
/// branches, so that it runs vectorised over a chunk of atoms: the altitude and slope kernels are
/// bounded by [`exp_neg_upper`] of the same argument, the layer terms by their weights, and
/// [`PRUNE_SLACK`] (in `layers_slack`) covers the rounding of both sums. Used only for chunks that
/// the plain bound (elevation plus every other weight) did not prune, before paying for scores.
#[allow(clippy::too_many_arguments)]
#[inline]
fn score_upper_bounds(
    w: &ResolvedWeights,
    dict: &Dictionary,
    q: &Query,
    s: Sigmas,
    start: usize,
    dots: &[f32],
    layers_slack: f32,
    out: &mut [f32],
) {
    let end = start + dots.len();
    let (alts, slopes) = (&dict.mean_alt[start..end], &dict.mean_slope[start..end]);
    // A disabled term (weight 0) adds nothing to the score, and 0 × a bound in [0, 1] here.
    let (wa, ws) = (w.altitude, w.slope);
    for (((o, &d), &alt), &slope) in out.iter_mut().zip(dots).zip(alts).zip(slopes) {
        let da = q.mean_alt - alt;
        let ds = q.mean_slope - slope;
        *o = w.elevation * (0.5 * (1.0 + d))
            + layers_slack
            + wa * exp_neg_upper((da * da) * s.inv_alt2)
            + ws * exp_neg_upper((ds * ds) * s.inv_slope2);
    }
}

/// Prepared dictionary for fast exact matching.
#[derive(Clone, Debug)]
pub struct Matcher {
    dict: Arc<Dictionary>,
    weights: ResolvedWeights,
    prepared: PreparedLayers,
    /// Low elevation atoms transposed: `lo² × n_pad`, dimension-major, atoms padded with zeros to
    /// a multiple of [`ATOM_BLOCK`].
    lo_t: Vec<f32>,
    /// `n` rounded up to a multiple of [`ATOM_BLOCK`].
    n_pad: usize,
    /// The widest build of the dot-product kernel this CPU runs.
    isa: Isa,
    alt_range: (f32, f32),
    slope_range: (f32, f32),
}

/// Atoms per chunk of the scans of [`Matcher::best_match`] (a chunk with nothing to do is skipped
/// after one vectorised test).
const SCAN_CHUNK: usize = 16;

/// The largest value of a chunk of dot products, by a tree of pairwise maxima over a full chunk
/// (vectorised; a plain fold over a shorter one). It only chooses [`Matcher::best_k`]'s seeds,
/// which do not change its result: a NaN may come out, and then the chunk gives no seed.
#[inline(always)]
fn chunk_max(chunk: &[f32]) -> f32 {
    let pick = |a: f32, b: f32| if b > a { b } else { a };
    let Ok(c) = <&[f32; SCAN_CHUNK]>::try_from(chunk) else {
        return chunk.iter().fold(f32::NEG_INFINITY, |m, &d| pick(m, d));
    };
    let mut m = [0.0f32; SCAN_CHUNK / 2];
    for (i, v) in m.iter_mut().enumerate() {
        *v = pick(c[i], c[i + SCAN_CHUNK / 2]);
    }
    let mut width = SCAN_CHUNK / 2;
    while width > 1 {
        width /= 2;
        for i in 0..width {
            m[i] = pick(m[i], m[i + width]);
        }
    }
    m[0]
}

/// The index of the first value of `chunk` equal to `v` (at most [`SCAN_CHUNK`] values).
#[inline(always)]
fn first_equal(chunk: &[f32], v: f32) -> Option<usize> {
    let mask = chunk
        .iter()
        .enumerate()
        .fold(0u32, |m, (k, &x)| m | (u32::from(x == v) << k));
    (mask != 0).then(|| mask.trailing_zeros() as usize)
}

/// Atoms per block of the dot-product kernel: the block's accumulators stay in registers.
pub const ATOM_BLOCK: usize = 64;

/// Queries whose dot products [`Matcher::prepare_batch`] computes in one pass over the atoms.
pub const DOT_BATCH: usize = 4;

/// `dots[m][i] = Σ_d qs[m][d]·lo_t[d·n_pad + i]` for every atom and each of the `N` queries,
/// summed in increasing `d` — exactly the order of the naive per-atom loop, so the results are
/// bit-identical to it. Blocks of `W` atoms (`W` divides [`ATOM_BLOCK`]) keep their `N × W`
/// accumulators in registers while `d` runs, and each block is read once for all `N` queries
/// (a batch streams the atoms from the cache `N` times less often); the compiler vectorises
/// across atoms without reassociating any sum.
#[inline(always)]
fn dots_blocked<const N: usize, const W: usize>(
    qs: [&[f32]; N],
    lo_t: &[f32],
    n_pad: usize,
    mut dots: [&mut [f32]; N],
) {
    let dim = qs.first().map_or(0, |q| q.len());
    for start in (0..n_pad).step_by(W) {
        let mut acc = [[0.0f32; W]; N];
        for d in 0..dim {
            let row = &lo_t[d * n_pad + start..d * n_pad + start + W];
            for (acc, q) in acc.iter_mut().zip(&qs) {
                let p = q[d];
                for k in 0..W {
                    acc[k] += p * row[k];
                }
            }
        }
        for (out, acc) in dots.iter_mut().zip(&acc) {
            out[start..start + W].copy_from_slice(acc);
        }
    }
}

/// The dot products of `N` queries of `lo_t`'s dimension, each into its own `n_pad`-long slice,
/// by [`dots_blocked`] in the widest build `isa` allows. One query goes in blocks of
/// [`ATOM_BLOCK`] atoms; a batch in blocks of what the build's registers hold: 8 atoms in the
/// baseline build, 16 with AVX2 (16 registers), [`ATOM_BLOCK`] with AVX-512 (32 registers).
/// Every build does the same IEEE multiplications and additions in the same order, hence the same
/// bits.
fn all_dots<const N: usize>(
    qs: [&[f32]; N],
    lo_t: &[f32],
    n_pad: usize,
    dots: [&mut [f32]; N],
    isa: Isa,
) {
    isa.run(
        #[inline(always)]
        |build| match (N, build) {
            (1, _) => dots_blocked::<N, ATOM_BLOCK>(qs, lo_t, n_pad, dots),
            (_, Isa::Avx512) => dots_blocked::<N, ATOM_BLOCK>(qs, lo_t, n_pad, dots),
            (_, Isa::Avx2) => dots_blocked::<N, 16>(qs, lo_t, n_pad, dots),
            (_, Isa::Baseline) => dots_blocked::<N, 8>(qs, lo_t, n_pad, dots),
        },
    );
}

/// Scratch buffers reused across queries so that matching does not allocate.
#[derive(Clone, Debug, Default)]
pub struct MatchScratch {
    dots: Vec<f32>,
    /// The seeds of [`Matcher::best_k`].
    seeds: Vec<usize>,
}

impl MatchScratch {
    /// The elevation dot products of the last query [`Matcher::prepare`]d here, one per atom
    /// (`Dᵀq` over the low atoms, in `f32`).
    pub fn dots(&self) -> &[f32] {
        &self.dots
    }
}

impl Matcher {
    /// Prepares `dict` for matching with `weights`.
    pub fn new(dict: Arc<Dictionary>, weights: &MatchWeights) -> Result<Self, MatchError> {
        let weights = ResolvedWeights::resolve(weights, &dict)?;
        let lo2 = dict.lo_patch() * dict.lo_patch();
        let n = dict.n_atoms;
        let n_pad = n.div_ceil(ATOM_BLOCK) * ATOM_BLOCK;
        let mut lo_t = vec![0.0f32; lo2 * n_pad];
        for i in 0..n {
            for (d, &v) in dict.lo_atom(i).iter().enumerate() {
                lo_t[d * n_pad + i] = v;
            }
        }
        Ok(Matcher {
            prepared: PreparedLayers::new(&dict),
            alt_range: min_max(&dict.mean_alt),
            slope_range: min_max(&dict.mean_slope),
            dict,
            weights,
            lo_t,
            n_pad,
            isa: Isa::detect(),
        })
    }

    /// The dictionary being matched against.
    pub fn dictionary(&self) -> &Dictionary {
        &self.dict
    }

    /// The resolved, normalised weights.
    pub fn weights(&self) -> &ResolvedWeights {
        &self.weights
    }

    fn sigmas(&self, q: &Query) -> Sigmas {
        Sigmas {
            inv_alt2: inv_sigma2(q.mean_alt, self.alt_range.0, self.alt_range.1),
            inv_slope2: inv_sigma2(q.mean_slope, self.slope_range.0, self.slope_range.1),
        }
    }

    /// Checks the shape of a query.
    pub fn check_query(&self, q: &Query) -> Result<(), MatchError> {
        let want = self.dict.lo_patch() * self.dict.lo_patch();
        if q.elevation.len() != want {
            return Err(MatchError::QueryShape {
                got: q.elevation.len(),
                want,
            });
        }
        Ok(())
    }

    /// The cheaper score bounds ([`score_upper_bounds`]) of the atoms `start..` whose dot
    /// products are `chunk`, or `None` when the chunk can be skipped whole: every atom's plain
    /// bound (elevation plus every other weight), or else every atom's cheaper bound, lies below
    /// `floor`. `!(b < floor)`, not `b >= floor`: a NaN bound is never skipped.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn chunk_bounds<'t>(
        &self,
        q: &Query,
        s: Sigmas,
        start: usize,
        chunk: &[f32],
        floor: f32,
        tight: &'t mut [f32; SCAN_CHUNK],
    ) -> Option<&'t [f32]> {
        let w = &self.weights;
        let rest = w.rest() + PRUNE_SLACK;
        let reaches = |b: f32| !(b < floor);
        if !chunk.iter().fold(false, |any, &d| {
            any | reaches(w.elevation * (0.5 * (1.0 + d)) + rest)
        }) {
            return None;
        }
        let tight = &mut tight[..chunk.len()];
        let layers_slack = w.layers_weight() + PRUNE_SLACK;
        score_upper_bounds(w, &self.dict, q, s, start, chunk, layers_slack, tight);
        tight
            .iter()
            .fold(false, |any, &t| any | reaches(t))
            .then_some(&*tight)
    }

    /// Index of the best atom for `q` and its elevation dot product `P_h · D_h,k`.
    /// Identical to [`best_match_naive`]. The query must have the right shape
    /// ([`Matcher::check_query`]); a wrong-length elevation is treated as zero-padded/truncated.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn best_match(&self, q: &Query, scratch: &mut MatchScratch) -> (usize, f32) {
        self.prepare(q, scratch);
        self.best_match_prepared(q, scratch)
    }

    /// Computes `q`'s elevation dot products with every atom into `scratch`: the first step of
    /// every search, which the `_prepared` searches then take from `scratch`.
    pub fn prepare(&self, q: &Query, scratch: &mut MatchScratch) {
        let dots = &mut scratch.dots;
        dots.clear();
        dots.resize(self.n_pad, 0.0);
        if q.elevation.len() * self.n_pad == self.lo_t.len() {
            all_dots([&q.elevation], &self.lo_t, self.n_pad, [dots], self.isa);
        }
        dots.truncate(self.dict.n_atoms);
    }

    /// [`Matcher::prepare`] for [`DOT_BATCH`] queries in one pass over the atoms (the same
    /// values, bit for bit: each query's sums run in the same order).
    pub fn prepare_batch(
        &self,
        qs: [&Query; DOT_BATCH],
        scratches: &mut [MatchScratch; DOT_BATCH],
    ) {
        if !qs
            .iter()
            .all(|q| q.elevation.len() * self.n_pad == self.lo_t.len())
        {
            for (q, scratch) in qs.iter().zip(scratches) {
                self.prepare(q, scratch);
            }
            return;
        }
        let [s0, s1, s2, s3] = scratches;
        let mut bufs = [&mut s0.dots, &mut s1.dots, &mut s2.dots, &mut s3.dots];
        for dots in bufs.iter_mut() {
            dots.clear();
            dots.resize(self.n_pad, 0.0);
        }
        let [d0, d1, d2, d3] = &mut bufs;
        all_dots(
            qs.map(|q| q.elevation.as_slice()),
            &self.lo_t,
            self.n_pad,
            [d0.as_mut_slice(), d1, d2, d3],
            self.isa,
        );
        for dots in bufs {
            dots.truncate(self.dict.n_atoms);
        }
    }

    /// [`Matcher::best_match`] on the dot products [`Matcher::prepare`] left in `scratch` for
    /// this same `q`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn best_match_prepared(&self, q: &Query, scratch: &MatchScratch) -> (usize, f32) {
        let dots = &scratch.dots;
        let s = self.sigmas(q);
        let w = &self.weights;
        // The first index of the largest dot product. Chunks in which no value beats the best
        // at the chunk's start are skipped whole: the best only grows, so the plain loop would
        // not have moved in them either.
        let mut best = 0usize;
        for (c, chunk) in dots.chunks(SCAN_CHUNK).enumerate() {
            let top = dots[best];
            if !chunk.iter().fold(false, |any, &v| any | (v > top)) {
                continue;
            }
            for (k, &v) in chunk.iter().enumerate() {
                if v > dots[best] {
                    best = c * SCAN_CHUNK + k;
                }
            }
        }
        // The best elevation term alone gives a first full score; an atom can only beat it if its
        // elevation term plus every other weight (each term ≤ 1) reaches it.
        let mut best_score = combine(w, &self.dict, &self.prepared, q, s, best, dots[best]);
        let rest = w.rest() + PRUNE_SLACK;
        let mut tight = [0.0f32; SCAN_CHUNK];
        let first = best;
        let bound = |d: f32| w.elevation * (0.5 * (1.0 + d)) + rest;
        for (c, chunk) in dots.chunks(SCAN_CHUNK).enumerate() {
            // A chunk whose bounds all lie below the best score so far is skipped whole (the
            // best score only grows, so the per-atom test below would skip each of them).
            let start = c * SCAN_CHUNK;
            let Some(tight) = self.chunk_bounds(q, s, start, chunk, best_score, &mut tight) else {
                continue;
            };
            for (k, (&dot_i, &tight_i)) in chunk.iter().zip(tight.iter()).enumerate() {
                let i = start + k;
                if i == first || bound(dot_i) < best_score || tight_i < best_score {
                    continue;
                }
                let sc = combine(w, &self.dict, &self.prepared, q, s, i, dot_i);
                if sc > best_score || (sc == best_score && i < best) {
                    best_score = sc;
                    best = i;
                }
            }
        }
        (best, dots[best])
    }

    /// The `k` best atoms for `q`, best first: full score descending, ties by lower index (the
    /// order [`best_match`](Matcher::best_match) uses, so `out[0]` is its atom). Atoms whose
    /// score is NaN are never ranked. Identical to [`best_k_naive`]; pruned like
    /// [`Matcher::best_match`], against the `k`-th best score so far.
    pub fn best_k(&self, q: &Query, scratch: &mut MatchScratch, k: usize, out: &mut Vec<Ranked>) {
        self.prepare(q, scratch);
        self.best_k_prepared(q, scratch, k, out);
    }

    /// [`Matcher::best_k`] on the dot products [`Matcher::prepare`] left in `scratch` for this
    /// same `q`.
    pub fn best_k_prepared(
        &self,
        q: &Query,
        scratch: &mut MatchScratch,
        k: usize,
        out: &mut Vec<Ranked>,
    ) {
        self.isa.run(
            #[inline(always)]
            |_| self.best_k_scan(q, scratch, k, out),
        );
    }

    /// The search of [`Matcher::best_k`], inlined into each build.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn best_k_scan(&self, q: &Query, scratch: &mut MatchScratch, k: usize, out: &mut Vec<Ranked>) {
        out.clear();
        if k == 0 {
            return;
        }
        let dots = &scratch.dots;
        let s = self.sigmas(q);
        let w = &self.weights;
        let rest = w.rest() + PRUNE_SLACK;
        let mut tight = [0.0f32; SCAN_CHUNK];
        let bound = |d: f32| w.elevation * (0.5 * (1.0 + d)) + rest;
        // Seeds: the largest dot product of each chunk (its first index on ties), the `k` largest
        // of those (ties: lower index), scored first so that the `k`-th best score, the pruning
        // floor, starts high. Any `k` atoms would give the same ranking (they are ranked first
        // and skipped by the scan); these are nearly the `k` largest dot products, for one
        // vectorised maximum per chunk.
        let seeds = &mut scratch.seeds;
        seeds.clear();
        for (c, chunk) in dots.chunks(SCAN_CHUNK).enumerate() {
            let top = chunk_max(chunk);
            if seeds.len() == k && !(top > dots[seeds[k - 1]]) {
                continue;
            }
            let Some(j) = first_equal(chunk, top) else {
                continue;
            };
            let at = seeds
                .iter()
                .position(|&o| top > dots[o])
                .unwrap_or(seeds.len());
            seeds.insert(at, c * SCAN_CHUNK + j);
            seeds.truncate(k);
        }
        for &i in seeds.iter() {
            let score = combine(w, &self.dict, &self.prepared, q, s, i, dots[i]);
            insert_ranked(
                out,
                k,
                Ranked {
                    atom: i,
                    dot: dots[i],
                    score,
                },
            );
        }
        for (c, chunk) in dots.chunks(SCAN_CHUNK).enumerate() {
            let floor = if out.len() == k {
                out[k - 1].score
            } else {
                f32::NEG_INFINITY
            };
            let start = c * SCAN_CHUNK;
            let Some(tight) = self.chunk_bounds(q, s, start, chunk, floor, &mut tight) else {
                continue;
            };
            for (j, (&dot_i, &tight_i)) in chunk.iter().zip(tight.iter()).enumerate() {
                let i = start + j;
                if (out.len() == k
                    && (bound(dot_i) < out[k - 1].score || tight_i < out[k - 1].score))
                    || seeds.contains(&i)
                {
                    continue;
                }
                let score = combine(w, &self.dict, &self.prepared, q, s, i, dot_i);
                insert_ranked(
                    out,
                    k,
                    Ranked {
                        atom: i,
                        dot: dot_i,
                        score,
                    },
                );
            }
        }
    }

    /// The atom and elevation dot product lattice point `(i, j)` takes among its `k` best matches
    /// within score tolerance `tol` (`Levers::diversity`): [`choose_diverse`] over
    /// [`Matcher::best_k`]. With no tolerance and at least `k` atoms, the pick is the `r`-th best for
    /// `r = hash(i, j) mod k` (NaN scores aside), so only the best `r + 1` are ranked (the best alone: the plain
    /// [`Matcher::best_match`]) — the same atom, for less work.
    pub fn diverse_match(
        &self,
        q: &Query,
        (scratch, ranked): (&mut MatchScratch, &mut Vec<Ranked>),
        (k, tol): (usize, f32),
        i: i64,
        j: i64,
    ) -> (usize, f32) {
        self.prepare(q, scratch);
        self.diverse_match_prepared(q, (scratch, ranked), (k, tol), i, j)
    }

    /// [`Matcher::diverse_match`] on the dot products [`Matcher::prepare`] left in `scratch`
    /// for this same `q`.
    pub fn diverse_match_prepared(
        &self,
        q: &Query,
        (scratch, ranked): (&mut MatchScratch, &mut Vec<Ranked>),
        (k, tol): (usize, f32),
        i: i64,
        j: i64,
    ) -> (usize, f32) {
        if tol == f32::INFINITY && self.dictionary().n_atoms >= k {
            let r = (hash2(DIVERSITY_SEED, i, j) % k as u64) as usize;
            if r == 0 {
                return self.best_match_prepared(q, scratch);
            }
            self.best_k_prepared(q, scratch, r + 1, ranked);
            if ranked.len() == r + 1 {
                return (ranked[r].atom, ranked[r].dot);
            }
        }
        self.best_k_prepared(q, scratch, k, ranked);
        choose_diverse(ranked, tol, i, j).unwrap_or_else(|| self.best_match_prepared(q, scratch))
    }

    /// The full score of atom `i` for `q` (the reference formula).
    pub fn score(&self, q: &Query, i: usize) -> f32 {
        let elev_dot = dot(&q.elevation, self.dict.lo_atom(i));
        combine(
            &self.weights,
            &self.dict,
            &self.prepared,
            q,
            self.sigmas(q),
            i,
            elev_dot,
        )
    }
}

/// One ranked atom of [`Matcher::best_k`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ranked {
    /// Atom index.
    pub atom: usize,
    /// Its elevation dot product `P_h · D_h,k`.
    pub dot: f32,
    /// Its full score.
    pub score: f32,
}

/// Seed of the hash that picks a primitive's atom among its candidates (`Levers::diversity`).
const DIVERSITY_SEED: u64 = 0x6469_7665_7273_6531;

/// The atom and elevation dot product that lattice point `(i, j)` takes among the ranked
/// candidates `ranked` (best first): those scoring within `tol` of the best, picked by a hash of
/// the point. `None` when nothing is ranked.
pub fn choose_diverse(ranked: &[Ranked], tol: f32, i: i64, j: i64) -> Option<(usize, f32)> {
    let best = ranked.first()?;
    let m = ranked
        .iter()
        .take_while(|r| r.score >= best.score - tol)
        .count()
        .max(1);
    let pick = &ranked[(hash2(DIVERSITY_SEED, i, j) % m as u64) as usize];
    Some((pick.atom, pick.dot))
}

/// Whether `a` ranks before `b`: higher score, then lower index.
fn ranks_before(a: &Ranked, b: &Ranked) -> bool {
    a.score > b.score || (a.score == b.score && a.atom < b.atom)
}

/// Inserts `r` into the ranked list `out` (best first), keeping at most `k` entries; a NaN score
/// is not ranked.
fn insert_ranked(out: &mut Vec<Ranked>, k: usize, r: Ranked) {
    if r.score.is_nan() {
        return;
    }
    let at = out
        .iter()
        .position(|o| ranks_before(&r, o))
        .unwrap_or(out.len());
    if at < k {
        out.insert(at, r);
        out.truncate(k);
    }
}

/// Reference for [`Matcher::best_k`]: scores every atom with the plain formula, sorts by score
/// (descending, ties by index) and keeps the first `k`.
pub fn best_k_naive(matcher: &Matcher, q: &Query, k: usize) -> Vec<Ranked> {
    let dict = matcher.dictionary();
    let mut all: Vec<Ranked> = (0..dict.n_atoms)
        .map(|i| Ranked {
            atom: i,
            dot: dot(&q.elevation, dict.lo_atom(i)),
            score: matcher.score(q, i),
        })
        .filter(|r| !r.score.is_nan())
        .collect();
    all.sort_by(|a, b| {
        b.score
            .partial_cmp(&a.score)
            .unwrap_or(std::cmp::Ordering::Equal)
            .then_with(|| a.atom.cmp(&b.atom))
    });
    all.truncate(k);
    all
}

/// Reference implementation: scores every atom with the plain formula and returns the first
/// index of the maximum score, with its elevation dot product.
pub fn best_match_naive(matcher: &Matcher, q: &Query) -> (usize, f32) {
    let dict = matcher.dictionary();
    let mut best = 0usize;
    let mut best_score = f32::NEG_INFINITY;
    for i in 0..dict.n_atoms {
        let sc = matcher.score(q, i);
        if sc > best_score {
            best_score = sc;
            best = i;
        }
    }
    (best, dot(&q.elevation, dict.lo_atom(best)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batched dot products of every build this CPU runs equal the single-query kernel's
    /// baseline build, bit for bit, on several blocks of atoms.
    #[test]
    fn batched_dots_equal_single_dots_in_every_build() {
        let (dim, n_pad) = (16, 3 * ATOM_BLOCK);
        let mut x = 0.37f32;
        let mut next = || {
            x = (x * 3.7 + 0.11).fract();
            x * 2.0 - 1.0
        };
        let lo_t: Vec<f32> = (0..dim * n_pad).map(|_| next() * 10.0).collect();
        let qs: Vec<Vec<f32>> = (0..DOT_BATCH)
            .map(|_| (0..dim).map(|_| next()).collect())
            .collect();
        let want: Vec<Vec<u32>> = qs
            .iter()
            .map(|q| {
                let mut d = vec![0.0f32; n_pad];
                dots_blocked::<1, ATOM_BLOCK>([q], &lo_t, n_pad, [&mut d]);
                d.iter().map(|v| v.to_bits()).collect()
            })
            .collect();
        for isa in Isa::builds() {
            let mut out = vec![vec![0.0f32; n_pad]; DOT_BATCH];
            let [o0, o1, o2, o3] = out.as_mut_slice() else {
                unreachable!()
            };
            let q = [0, 1, 2, 3].map(|m| qs[m].as_slice());
            all_dots(
                q,
                &lo_t,
                n_pad,
                [o0, o1, o2, o3].map(|o| o.as_mut_slice()),
                isa,
            );
            for (m, w) in want.iter().enumerate() {
                let got: Vec<u32> = out[m].iter().map(|v| v.to_bits()).collect();
                assert_eq!(&got, w, "{isa:?}, query {m}");
            }
        }
    }
}
