//! One ×2 amplification level (DESIGN.md, methods 1 and 2; issue #12).
//!
//! Level `L` is a pixel plane twice as fine as level `L−1`: pixel `x` of level `L` lies at parent
//! coordinate `(x + 0.5)/2 − 0.5`, so the 2×2 block `{2k, 2k+1}²` sits on parent pixel `k`.
//! Primitives stand on a *global* lattice of step `s = patch/2` (centre `c = s·i`, a pixel corner);
//! primitive `i` reads the parent patch `P = [c/2 − patch/4, c/2 + patch/4)²`, matches it against
//! the dictionary and reconstructs it over `[c − s, c + s)²` as a smooth part
//! `(P_h·D_h,k) P_s U_k + P_a` (`U_k`: the Catmull-Rom up-sampling of the low atom) plus a detail
//! part `a·(D~_h,k − U_k)`, weighted by `α = (1 − r²)³`, `r = |p − c| / s`. The detail amplitude
//! `a` follows the parent's own finest octave ([`Levers::roughness`]): `a` makes the detail's RMS
//! `roughness · RMS(P − CR(box P))`, so each level adds the fraction of the octave above that real
//! terrain carries, whatever the scale the atoms were cut at; the fraction is larger where that
//! octave is gentle ([`Levers::gentle_roughness`]: steep ranges keep less of it than low ranges
//! and plains). Every pixel is covered by exactly 4
//! primitives and their contributions are added in lattice order, whatever window is requested,
//! so a pixel's value does not depend on the window it is computed in (bit for bit).
//!
//! A residual correction then makes 2×2 box averages reproduce the parent:
//! [`Levers::passes`] passes of `F_L += Up(F_{L−1} − Down(F_L))` with a Kaiser-windowed sinc `Up`
//! ([`kernel`](super::kernel)), whose images of the parent's spectrum are far weaker than a
//! cubic's (those images were the ribbing along pixel rows and columns). Last, every pit of the
//! level gets a channel to a lower cell within [`Levers::breach`] cells
//! ([`breach_pits`](crate::analysis::breach::breach_pits)), an operation that reads a bounded
//! neighbourhood only, so the level stays window-invariant. Extra dictionary layers are blended
//! with `α` and corrected with the Catmull-Rom kernel in four passes.

use std::sync::Arc;

use ndarray::{s, Array2};
use rayon::prelude::*;

use super::error::SynthError;
use super::field::{Field, Window};
pub use super::kernel::KernelKind;
use super::kernel::{
    consistent_upsample_patch, finest_octave_rms, finest_octave_rms_n, floor_div, upsample_patch,
    OctaveScratch, UpKernel, CATMULL_ROM,
};
pub use super::levers::{Levers, DEFAULT_AMPLIFY_SPARSITY, MAX_AMPLIFY_SPARSITY};
use crate::analysis::banks::widen_channels;
use crate::analysis::block_means::restore_block_means;
use crate::analysis::breach::{breach_margin, breach_pits_with, BreachRule, RISE_REACH};
use crate::dictionary::features::{centre_normalise_n, patch_mean_slope_n};
use crate::dictionary::matching::{
    unit_centred, MatchScratch, MatchWeights, Matcher, Query, Ranked, DOT_BATCH,
};
use crate::dictionary::omp::{Omp, OmpScratch};
use crate::dictionary::{Dictionary, LayerKind};
use crate::math;
use crate::raster::boxfilter::box2;
use crate::simd::Isa;

/// The matched atom of one primitive.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Primitive {
    atom: usize,
    /// `(P_h · D_h,k) · P_s`: the amplitude of the atom's smooth part.
    coef: f32,
    /// `P_a`: the mean altitude added back.
    mean: f32,
    /// The amplitude of the atom's detail part: `P_s` in the baseline (detail scaled with the
    /// parent's local relief, not with how well the coarse shapes matched), or the
    /// [`Levers::roughness`] target over the atom's own detail RMS.
    detail_coef: f32,
    /// `1 / mean slope` of the parent patch (0 when flat), for [`Levers::slope_mod`].
    inv_slope: f32,
    /// Further atoms of the sparse code ([`Levers::sparsity`] > 1): `(atom, smooth amplitude,
    /// detail amplitude)`, the first `n_extra` entries.
    extra: [(u32, f32, f32); MAX_AMPLIFY_SPARSITY - 1],
    /// Number of entries of `extra` in use.
    n_extra: u8,
}

impl Primitive {
    /// A placeholder, overwritten before it is read.
    const EMPTY: Primitive = Primitive {
        atom: 0,
        coef: 0.0,
        mean: 0.0,
        detail_coef: 0.0,
        inv_slope: 0.0,
        extra: [(0, 0.0, 0.0); MAX_AMPLIFY_SPARSITY - 1],
        n_extra: 0,
    };
}

/// What [`Amplifier::blend`] reconstructs.
#[derive(Clone, Copy, Debug)]
enum Blended {
    /// Elevation: smooth and detail components.
    Elevation,
    /// Extra dictionary layer `l`.
    Layer(usize),
}

/// The atoms one level matched for the primitives that the extra layers of an output window read
/// ([`Amplifier::amplify_keeping_atoms`]): all [`Amplifier::amplify_layers_with`] needs to
/// reconstruct those layers without matching again.
#[derive(Clone, Debug)]
pub struct LayerAtoms {
    /// The dictionary they index.
    dict: Arc<Dictionary>,
    /// The output window they were matched for.
    out: Window,
    /// Their lattice range.
    lr: LatticeRange,
    /// One atom per lattice point, row-major by `j`, then `i`.
    atoms: Vec<u32>,
}

impl LayerAtoms {
    /// The output window they were matched for.
    pub fn window(&self) -> Window {
        self.out
    }

    /// Bytes they hold.
    pub fn bytes(&self) -> u64 {
        (self.atoms.len() * 4 + std::mem::size_of::<Self>()) as u64
    }
}

/// The lattice rows and columns of the primitives that cover a hi-res window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LatticeRange {
    i0: i64,
    i1: i64,
    j0: i64,
    j1: i64,
}

/// The columns of a blend row one primitive covers.
#[derive(Clone, Copy)]
struct Span<'a> {
    prim: &'a Primitive,
    /// First column inside the primitive's patch.
    ox0: usize,
    /// Number of columns.
    len: usize,
    /// First column inside the blend window.
    c0: usize,
}

/// What every strip of one [`Amplifier::blend`] reads.
#[derive(Clone, Copy)]
struct StripJob<'a> {
    bw: Window,
    lr: LatticeRange,
    prims: &'a [Primitive],
    what: Blended,
    slope: Option<&'a Array2<f32>>,
}

/// A thread's value and detail sums of [`Amplifier::blend`], reused from strip to strip.
type StripBuffers<'a> = (&'a mut [f32], &'a mut [f32]);

/// Correction passes of the extra dictionary layers and of [`Amplifier::upsample_layer`]
/// (Catmull-Rom, as before issue #12: layers are smooth and carry no grid artefacts).
const LAYER_PASSES: i64 = 4;

/// Largest factor [`Levers::slope_mod`] multiplies an atom's detail by.
const SLOPE_MOD_MAX: f32 = 3.0;

/// The roughness of a primitive whose parent's finest octave has slope `octave_slope` (its RMS
/// per cell): `gentle.0` ([`Levers::gentle_roughness`]) up to `gentle.1`
/// ([`Levers::gentle_slope`]), `roughness` from twice that, linear in between; `roughness`
/// alone when `gentle.0` is 0.
fn gentle_blend(roughness: f32, gentle: (f32, f32), octave_slope: f32) -> f32 {
    ramp_below(roughness, gentle, octave_slope)
}

/// `low.0` up to the slope `low.1`, `above` from twice that, linear in between; `above` when
/// `low.0` or `low.1` is 0 or the slope is NaN (it fails `<`).
fn ramp_below(above: f32, low: (f32, f32), octave_slope: f32) -> f32 {
    let (low_rough, low_slope) = low;
    let on_ramp = octave_slope < 2.0 * low_slope;
    if low_rough <= 0.0 || low_slope <= 0.0 || !on_ramp {
        return above;
    }
    let t = ((octave_slope - low_slope) / low_slope).clamp(0.0, 1.0);
    low_rough + (above - low_rough) * t
}

/// [`gentle_blend`], then [`Levers::plains_roughness`] (`plains`: roughness and slope) below
/// it by the same ramp.
fn roughness_at(roughness: f32, gentle: (f32, f32), plains: (f32, f32), octave_slope: f32) -> f32 {
    ramp_below(
        gentle_blend(roughness, gentle, octave_slope),
        plains,
        octave_slope,
    )
}

/// Largest detail amplitude relative to the patch's relief `P_s` under [`Levers::roughness`].
const MAX_DETAIL_PER_RELIEF: f32 = 4.0;

/// One amplification level bound to a dictionary and matching weights.
#[derive(Debug)]
pub struct Amplifier {
    matcher: Matcher,
    dict: Arc<Dictionary>,
    patch: usize,
    step: usize,
    /// `patch × patch` blending weights `α`.
    alpha: Vec<f32>,
    /// `patch × patch` detail blending weights `w = α^p` ([`Levers::blend_power`]).
    walpha: Vec<f32>,
    /// `step × step`: `1 / Σ α` at each pixel offset inside a lattice cell.
    inv_norm: Vec<f32>,
    /// `step × step`: `1 / √(Σ w²)` at each pixel offset: the variance-preserving normaliser of
    /// the detail component.
    inv_rms: Vec<f32>,
    /// The levers this level runs with.
    levers: Levers,
    /// The residual correction's up-sampling kernel.
    kernel: UpKernel,
    /// `n × patch²`: the smooth part of each high atom, the Catmull-Rom up-sampling of its low atom
    /// (consistent with it under [`Levers::consistent_split`]).
    smooth: Vec<f32>,
    /// `n × patch²`: the detail part of each high atom, `hi − smooth`.
    detail: Vec<f32>,
    /// Per atom: the RMS of its detail part.
    detail_rms: Vec<f32>,
    /// Per atom: the RMS of its detail part over the RMS of its low atom's finest octave
    /// ([`Levers::octave_match`]; 0 where that octave is flat).
    detail_per_octave: Vec<f32>,
    /// Whether extra dictionary layers are reconstructed too.
    with_layers: bool,
    /// Per dictionary layer: whether it is reconstructed (when `with_layers`).
    layer_mask: Vec<bool>,
    /// Atoms per primitive, resolved from [`Levers::sparsity`] and the dictionary.
    sparsity: usize,
    /// The pursuit over the low atoms, when `sparsity > 1`.
    omp: Option<Arc<Omp>>,
}

/// [`Levers::detail_smooth`]: each value of the `side × side` patch `x` moves a fraction `k` of
/// the way to its 3×3 binomial average (edges clamped), and the patch is rescaled to its RMS
/// before, so the detail keeps its energy but holds less of it at the pixel scale.
fn smooth_detail(x: &mut [f32], side: usize, k: f32) {
    let norm = |v: &[f32]| {
        v.iter()
            .map(|&a| f64::from(a) * f64::from(a))
            .sum::<f64>()
            .sqrt()
    };
    let before = norm(x);
    let at = |r: isize, c: isize| {
        let r = r.clamp(0, side as isize - 1) as usize;
        let c = c.clamp(0, side as isize - 1) as usize;
        x[r * side + c]
    };
    let mut out = vec![0.0f32; x.len()];
    for r in 0..side as isize {
        for c in 0..side as isize {
            let mut sum = 0.0f32;
            for (dr, wr) in [(-1isize, 1.0f32), (0, 2.0), (1, 1.0)] {
                for (dc, wc) in [(-1isize, 1.0f32), (0, 2.0), (1, 1.0)] {
                    sum += wr * wc * at(r + dr, c + dc);
                }
            }
            let v = at(r, c);
            out[r as usize * side + c as usize] = v + k * (sum / 16.0 - v);
        }
    }
    let after = norm(&out);
    let scale = if after > 0.0 {
        (before / after) as f32
    } else {
        1.0
    };
    for (d, o) in x.iter_mut().zip(&out) {
        *d = o * scale;
    }
}

/// Caps the stripes of a `side × side` detail patch: the energy of its row means about the
/// patch mean (and separately of its column means) is scaled down to at most `cap / side` of the
/// patch's energy about its mean before the cap (isotropic detail holds about `1/side` there);
/// `cap = 0` removes them. The patch mean is kept.
fn cap_stripes(x: &mut [f32], side: usize, cap: f32) {
    let n = side as f64;
    let mut rows = vec![0.0f64; side];
    let mut cols = vec![0.0f64; side];
    let mut all = 0.0f64;
    for r in 0..side {
        for c in 0..side {
            let v = f64::from(x[r * side + c]);
            rows[r] += v / n;
            cols[c] += v / n;
            all += v / (n * n);
        }
    }
    let total: f64 = x.iter().map(|&v| (f64::from(v) - all).powi(2)).sum();
    let share = f64::from(cap) / n;
    // Scale of the row (column) component so that its energy is at most `share · total`.
    let scale = |means: &[f64]| -> f64 {
        let e: f64 = n * means.iter().map(|m| (m - all).powi(2)).sum::<f64>();
        if e <= share * total || e <= 0.0 {
            1.0
        } else {
            (share * total / e).sqrt()
        }
    };
    let (kr, kc) = (scale(&rows), scale(&cols));
    for r in 0..side {
        for c in 0..side {
            let v = f64::from(x[r * side + c]);
            let d = (1.0 - kr) * (rows[r] - all) + (1.0 - kc) * (cols[c] - all);
            x[r * side + c] = (v - d) as f32;
        }
    }
}

/// The blending weights `α = (1 − r²)³`, `r = |p − c| / step`, of a primitive over its
/// `patch × patch` square (`c` its centre, `step = patch/2`); 0 outside the disc. Compact
/// terrains ([`super::compact`]) blend with the same weights.
pub fn blend_alpha(patch: usize) -> Vec<f32> {
    let radius = (patch / 2) as f32;
    let mut alpha = vec![0.0f32; patch * patch];
    for r in 0..patch {
        for c in 0..patch {
            let dy = (r as f32 + 0.5 - radius) / radius;
            let dx = (c as f32 + 0.5 - radius) / radius;
            let r2 = dx * dx + dy * dy;
            if r2 < 1.0 {
                let t = 1.0 - r2;
                alpha[r * patch + c] = t * t * t;
            }
        }
    }
    alpha
}

impl Amplifier {
    /// Prepares an amplifier. The dictionary's patch must be a multiple of 4 and at least 8.
    pub fn new(dict: Arc<Dictionary>, weights: &MatchWeights) -> Result<Self, SynthError> {
        let patch = dict.patch();
        if patch < 8 || patch % 4 != 0 {
            return Err(SynthError::PatchSize(patch));
        }
        let mut amp = Amplifier {
            inv_rms: Vec::new(),
            with_layers: true,
            layer_mask: vec![true; dict.layers.len()],
            smooth: Vec::new(),
            detail: Vec::new(),
            detail_rms: Vec::new(),
            detail_per_octave: Vec::new(),
            matcher: Matcher::new(dict.clone(), weights)?,
            dict,
            patch,
            step: patch / 2,
            alpha: Vec::new(),
            walpha: Vec::new(),
            inv_norm: Vec::new(),
            levers: Levers::default(),
            kernel: CATMULL_ROM,
            sparsity: 1,
            omp: None,
        };
        amp.configure();
        Ok(amp)
    }

    /// This amplifier with other [`Levers`] (the tables that depend on them are rebuilt).
    pub fn with_levers(mut self, levers: Levers) -> Self {
        self.levers = levers;
        self.configure();
        self
    }

    /// The levers this amplifier runs with.
    pub fn levers(&self) -> Levers {
        self.levers
    }

    /// Builds the blending tables and the atoms' smooth/detail split for the current levers.
    fn configure(&mut self) {
        let patch = self.patch;
        let step = self.step;
        let dict = self.dict.clone();
        let power = self.levers.blend_power.max(1) as i32;
        self.kernel = UpKernel::new(self.levers.kernel);
        let alpha = blend_alpha(patch);
        let walpha: Vec<f32> = alpha.iter().map(|a| a.powi(power)).collect();
        // A pixel at offset (oy, ox) of a lattice cell is covered by the four primitives that see
        // it at patch offsets {oy, oy+step} × {ox, ox+step}; sum them in lattice order.
        let mut inv_norm = vec![0.0f32; step * step];
        let mut inv_rms = vec![0.0f32; step * step];
        for oy in 0..step {
            for ox in 0..step {
                let (mut sum, mut sum2) = (0.0f32, 0.0f32);
                for py in [oy + step, oy] {
                    for px in [ox + step, ox] {
                        sum += alpha[py * patch + px];
                        let w = walpha[py * patch + px];
                        sum2 += w * w;
                    }
                }
                inv_norm[oy * step + ox] = 1.0 / sum;
                inv_rms[oy * step + ox] = 1.0 / sum2.sqrt();
            }
        }
        let p2 = patch * patch;
        let mut smooth = vec![0.0f32; dict.n_atoms * p2];
        let mut detail = vec![0.0f32; dict.n_atoms * p2];
        for i in 0..dict.n_atoms {
            let sm = &mut smooth[i * p2..(i + 1) * p2];
            if self.levers.consistent_split {
                consistent_upsample_patch(dict.lo_atom(i), patch / 2, sm);
            } else {
                upsample_patch(&CATMULL_ROM, dict.lo_atom(i), patch / 2, sm);
            }
            for ((d, &h), &m) in detail[i * p2..(i + 1) * p2]
                .iter_mut()
                .zip(dict.hi_atom(i))
                .zip(sm.iter())
            {
                *d = h - m;
            }
            if self.levers.stripe_cap.is_finite() {
                cap_stripes(
                    &mut detail[i * p2..(i + 1) * p2],
                    patch,
                    self.levers.stripe_cap,
                );
            }
            if self.levers.detail_smooth > 0.0 {
                smooth_detail(
                    &mut detail[i * p2..(i + 1) * p2],
                    patch,
                    self.levers.detail_smooth,
                );
            }
        }
        self.detail_rms = detail
            .chunks(p2.max(1))
            .map(|d| {
                let ss: f64 = d.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
                (ss / p2.max(1) as f64).sqrt() as f32
            })
            .collect();
        let mut octave = OctaveScratch::default();
        self.detail_per_octave = (0..dict.n_atoms)
            .map(|i| {
                let oct = finest_octave_rms(dict.lo_atom(i), patch / 2, &mut octave);
                if oct > 0.0 {
                    self.detail_rms[i] / oct
                } else {
                    0.0
                }
            })
            .collect();
        self.sparsity = match self.levers.sparsity {
            0 => dict.params.sparsity.max(DEFAULT_AMPLIFY_SPARSITY),
            s => s as usize,
        }
        .clamp(1, MAX_AMPLIFY_SPARSITY);
        self.omp = match (self.sparsity > 1, &self.omp) {
            (false, _) => None,
            (true, Some(omp)) => Some(omp.clone()),
            (true, None) => {
                let lo2 = (patch / 2) * (patch / 2);
                Some(Arc::new(Omp::new(&dict.lo_elev[..dict.n_atoms * lo2], lo2)))
            }
        };
        self.alpha = alpha;
        self.walpha = walpha;
        self.inv_norm = inv_norm;
        self.inv_rms = inv_rms;
        self.smooth = smooth;
        self.detail = detail;
    }

    /// This amplifier, reconstructing elevation only (extra dictionary layers are skipped, which
    /// roughly halves the work with two extra layers). Elevation values are unchanged.
    pub fn without_layers(mut self) -> Self {
        self.with_layers = false;
        self
    }

    /// This amplifier, reconstructing only the extra dictionary layers named in `names` (others
    /// are left out of [`Amplifier::amplify`]'s result). Elevation values are unchanged.
    pub fn with_only_layers(mut self, names: &[String]) -> Self {
        self.layer_mask = self
            .dict
            .layers
            .iter()
            .map(|l| names.contains(&l.name))
            .collect();
        self
    }

    /// A layer the dictionary does not carry, carried to this level from the parent's values
    /// alone: the residual correction of a zero blend, i.e. the smooth C¹ up-sampling of the
    /// parent whose 2×2 box averages reproduce it. `parent` (held over `parent_window`) must cover
    /// [`Amplifier::layers_parent_window_for`]`(out)`. Window-invariant like
    /// [`Amplifier::amplify`].
    pub fn upsample_layer(
        &self,
        parent: &Array2<f32>,
        parent_window: Window,
        out: Window,
    ) -> Result<Array2<f32>, SynthError> {
        let needed = self.layers_parent_window_for(out);
        if !parent_window.contains(&needed)
            || parent.dim() != (parent_window.rows, parent_window.cols)
        {
            return Err(SynthError::ParentTooSmall {
                given: parent_window.to_string(),
                needed: needed.to_string(),
            });
        }
        let bw = Self::margin_window(out, Self::layer_margin());
        let zero = Array2::<f32>::zeros((bw.rows, bw.cols));
        Ok(correct(
            &CATMULL_ROM,
            zero,
            bw,
            parent,
            parent_window,
            out,
            LAYER_PASSES,
        ))
    }

    /// The dictionary this level uses.
    pub fn dictionary(&self) -> &Dictionary {
        &self.dict
    }

    /// The parent pixels `[k0, k1)` under the hi-res span `[x0, x1)`.
    fn parent_span(x0: i64, x1: i64) -> (i64, i64) {
        (floor_div(x0, 2), floor_div(x1 + 1, 2))
    }

    /// Parent pixels of margin the corrections consume on each side: the elevation's passes times
    /// its kernel's reach, or the layers' Catmull-Rom passes, whichever is wider.
    fn correction_margin(&self) -> i64 {
        (i64::from(self.levers.passes) * self.kernel.reach()).max(Self::layer_margin())
    }

    /// The hi-res window on which the raw blend is needed for output window `out`: the children
    /// of the parent pixels under `out`, widened by one parent pixel per smooth correction pass.
    fn blend_window(&self, out: Window) -> Window {
        Self::margin_window(out, self.correction_margin())
    }

    /// The children of the parent pixels under `out`, widened by `n` parent pixels.
    fn margin_window(out: Window, n: i64) -> Window {
        let (k0, k1) = Self::parent_span(out.col0, out.col1());
        let (l0, l1) = Self::parent_span(out.row0, out.row1());
        Window::from_bounds(2 * (k0 - n), 2 * (l0 - n), 2 * (k1 + n), 2 * (l1 + n))
    }

    /// Lattice indices of the primitives whose support `[c − step, c + step)` meets window `w`.
    fn lattice_range(&self, w: Window) -> LatticeRange {
        let s = self.step as i64;
        // c + s > x0  ⇔  i > (x0 − s)/s ;  c − s ≤ x1 − 1  ⇔  i ≤ (x1 − 1 + s)/s.
        LatticeRange {
            i0: floor_div(w.col0 - s, s) + 1,
            i1: floor_div(w.col1() - 1 + s, s) + 1,
            j0: floor_div(w.row0 - s, s) + 1,
            j1: floor_div(w.row1() - 1 + s, s) + 1,
        }
    }

    /// The window whose raw elevation the breaching of `out` reads: `out` widened by
    /// [`breach_margin`] (the reach of a channel, and of the search that finds it), plus one
    /// cell per ring of [`Levers::banks`].
    fn conditioned_window(&self, out: Window) -> Window {
        let m = if self.levers.breach > 0 {
            (breach_margin(self.levers.breach as usize)
                + self.levers.banks as usize
                + self.restore_margin()) as i64
        } else {
            0
        };
        out.grown(m)
    }

    /// The cells computed around the output for [`restore_block_means`]: one would make every
    /// parent cell touching the output whole; two keep the conditioned window's parity, so that
    /// its parent cells stay aligned (with one, a level ran 15 % slower: criterion's
    /// `amplify_level/default`).
    fn restore_margin(&self) -> usize {
        2 * usize::from(self.levers.restore > 0.0)
    }

    /// The parent window that [`Amplifier::amplify`] needs to compute output window `out`.
    pub fn parent_window_for(&self, out: Window) -> Window {
        self.parent_window_over(self.conditioned_window(out), self.correction_margin())
    }

    /// The parent window that [`Amplifier::amplify_layers`] needs to compute output window
    /// `out`: the matches and corrections of the extra layers alone, without the elevation's
    /// breaching margin and correction (so at most [`Amplifier::parent_window_for`]`(out)`).
    pub fn layers_parent_window_for(&self, out: Window) -> Window {
        self.parent_window_over(out, Self::layer_margin())
    }

    /// Parent pixels of margin the extra layers' corrections consume on each side.
    fn layer_margin() -> i64 {
        LAYER_PASSES * CATMULL_ROM.reach()
    }

    /// The parent window under `out` widened by `n` parent pixels, and under the low patches
    /// of every primitive whose support meets the children of that widening.
    fn parent_window_over(&self, out: Window, n: i64) -> Window {
        let bw = Self::margin_window(out, n);
        let lr = self.lattice_range(bw);
        let s = self.step as i64;
        let q = (self.patch / 4) as i64;
        let (k0, k1) = Self::parent_span(out.col0, out.col1());
        let (l0, l1) = Self::parent_span(out.row0, out.row1());
        let c0 = (lr.i0 * s / 2 - q).min(k0 - n);
        let c1 = ((lr.i1 - 1) * s / 2 + q).max(k1 + n);
        let r0 = (lr.j0 * s / 2 - q).min(l0 - n);
        let r1 = ((lr.j1 - 1) * s / 2 + q).max(l1 + n);
        Window::from_bounds(c0, r0, c1, r1)
    }

    /// Matches every primitive of `lr` against the dictionary, reading low patches from `parent`.
    /// Results are in lattice order (row-major by `j`, then `i`).
    fn match_primitives(
        &self,
        parent: &Field,
        lr: LatticeRange,
        parent_cell_m: f32,
    ) -> Vec<Primitive> {
        let lo = self.patch / 2;
        let q = (self.patch / 4) as i64;
        let s = self.step as i64;
        let ni = (lr.i1 - lr.i0) as usize;
        let nj = (lr.j1 - lr.j0) as usize;
        let parent_layers: Vec<Option<(&Array2<f32>, bool)>> = self
            .dict
            .layers
            .iter()
            .map(|info| {
                parent
                    .layer(&info.name)
                    .map(|a| (a, info.kind == LayerKind::Continuous))
            })
            .collect();
        let pw = parent.window;
        let roughness = self.levers.roughness;
        let gentle = (self.levers.gentle_roughness, self.levers.gentle_slope);
        let plains = (self.levers.plains_roughness, self.levers.plains_slope);
        let octave_match = self.levers.octave_match;
        let diversity = self.levers.diversity.max(1) as usize;
        let diversity_tol = self.levers.diversity_tol;
        let floor = self.levers.floor_m * math::powf((parent_cell_m / 2000.0).max(0.0), 0.7);
        // The primitives go in groups of `DOT_BATCH`, whose queries' dot products are computed
        // in one pass over the atoms (`Matcher::prepare_batch`); each primitive is then matched
        // on its own, as it would be alone.
        let mut prims = vec![Primitive::EMPTY; nj * ni];
        prims.par_chunks_mut(DOT_BATCH).enumerate().for_each_init(
            || {
                (
                    std::array::from_fn::<_, DOT_BATCH, _>(|_| MatchScratch::default()),
                    OmpScratch::default(),
                    std::array::from_fn::<_, DOT_BATCH, _>(|_| vec![0.0f32; lo * lo]),
                    std::array::from_fn::<_, DOT_BATCH, _>(|_| Query::default()),
                    OctaveScratch::default(),
                    Vec::<Ranked>::new(),
                    Vec::<f32>::new(),
                )
            },
            |(scratches, omp_scratch, raws, queries, octave, ranked, mean_detail), (g, group)| {
                let point = |m: usize| {
                    let n = g * DOT_BATCH + m;
                    (lr.i0 + (n % ni) as i64, lr.j0 + (n / ni) as i64)
                };
                // A short last group repeats its last point: a full batch, whose extra results
                // are dropped.
                for (m, (raw, query)) in raws.iter_mut().zip(queries.iter_mut()).enumerate() {
                    let (i, j) = point(m.min(group.len() - 1));
                    let pc0 = (i * s / 2 - q - pw.col0) as usize;
                    let pr0 = (j * s / 2 - q - pw.row0) as usize;
                    let read = |a: &Array2<f32>, out: &mut [f32]| {
                        for r in 0..lo {
                            let row = a.row(pr0 + r);
                            for c in 0..lo {
                                out[r * lo + c] = row[pc0 + c];
                            }
                        }
                    };
                    read(&parent.elevation, raw);
                    query.elevation.resize(lo * lo, 0.0);
                    query.layers.clear();
                    for pl in &parent_layers {
                        match pl {
                            Some((a, continuous)) => {
                                let mut v = vec![0.0f32; lo * lo];
                                read(a, &mut v);
                                query
                                    .layers
                                    .push(if *continuous { unit_centred(&v) } else { v });
                            }
                            None => query.layers.push(Vec::new()),
                        }
                    }
                }
                let patches = raws.each_ref().map(Vec::as_slice);
                let PatchMeasures {
                    stats,
                    slopes,
                    finest,
                } = measure_patches(
                    patches,
                    queries.each_mut().map(|q| q.elevation.as_mut_slice()),
                    (lo, parent_cell_m),
                    (roughness > 0.0).then_some(octave),
                );
                for ((query, &(mean, _)), &slope) in queries.iter_mut().zip(&stats).zip(&slopes) {
                    query.mean_alt = mean;
                    query.mean_slope = slope;
                }
                self.matcher.prepare_batch(queries.each_ref(), scratches);
                for (m, prim) in group.iter_mut().enumerate() {
                    let (i, j) = point(m);
                    let (query, scratch) = (&queries[m], &mut scratches[m]);
                    let (mean, norm) = stats[m];
                    let (atom, dot) = if diversity > 1 {
                        self.matcher.diverse_match_prepared(
                            query,
                            (scratch, ranked),
                            (diversity, diversity_tol),
                            i,
                            j,
                        )
                    } else {
                        self.matcher.best_match_prepared(query, scratch)
                    };
                    let detail_coef = if roughness > 0.0 {
                        let finest = finest[m];
                        let rough = if octave_match > 0.0 {
                            octave_match * self.detail_per_octave[atom]
                        } else {
                            roughness_at(roughness, gentle, plains, finest / parent_cell_m)
                        };
                        let oct = rough * finest;
                        let target = (oct * oct + floor * floor).sqrt();
                        let own = self.detail_rms[atom];
                        if own > 0.0 {
                            (target / own).min(MAX_DETAIL_PER_RELIEF * norm)
                        } else {
                            0.0
                        }
                    } else {
                        norm
                    };
                    *prim = Primitive {
                        atom,
                        coef: dot * norm,
                        mean,
                        detail_coef,
                        inv_slope: if query.mean_slope > 0.0 {
                            1.0 / query.mean_slope
                        } else {
                            0.0
                        },
                        extra: [(0, 0.0, 0.0); MAX_AMPLIFY_SPARSITY - 1],
                        n_extra: 0,
                    };
                    if self.levers.mean_k > 1 {
                        self.mean_of_best_details(prim, atom, query, scratch, ranked, mean_detail);
                    } else if let Some(omp) = &self.omp {
                        // The matcher's atom first, then the pursuit (on the matcher's dot
                        // products); least-squares coefficients of the low patch for all of
                        // them. Each further atom's detail comes in the proportion of its
                        // coefficient.
                        let code = omp.code_from_dots(
                            &query.elevation,
                            scratch.dots(),
                            Some(atom),
                            self.sparsity,
                            omp_scratch,
                        );
                        if let Some(&(_, x0)) = code.first() {
                            prim.coef = x0 as f32 * norm;
                        }
                        for (slot, &(a, x)) in prim.extra.iter_mut().zip(code.iter().skip(1)) {
                            *slot = (a as u32, x as f32 * norm, x as f32 * detail_coef);
                            prim.n_extra += 1;
                        }
                    }
                }
            },
        );
        prims
    }

    /// [`Levers::mean_k`]: sets `prim`'s detail to the mean of the unit-RMS details of its own
    /// `atom` and the next best matches of `query` (as further atoms with no smooth part),
    /// rescaled to the RMS its own atom's detail had. Leaves `prim` as it is when it has no
    /// detail or the mean is flat. `sum` is scratch.
    fn mean_of_best_details(
        &self,
        prim: &mut Primitive,
        atom: usize,
        query: &Query,
        scratch: &mut MatchScratch,
        ranked: &mut Vec<Ranked>,
        sum: &mut Vec<f32>,
    ) {
        let own_rms = self.detail_rms[atom];
        if prim.detail_coef <= 0.0 || own_rms <= 0.0 {
            return;
        }
        let k = (self.levers.mean_k as usize).min(MAX_AMPLIFY_SPARSITY);
        self.matcher.best_k_prepared(query, scratch, k, ranked);
        let mut members = [(0usize, 0.0f32); MAX_AMPLIFY_SPARSITY];
        members[0] = (atom, 1.0 / own_rms);
        let mut n = 1;
        for r in ranked.iter().filter(|r| r.atom != atom) {
            let rms = self.detail_rms[r.atom];
            if n < k && rms > 0.0 {
                members[n] = (r.atom, 1.0 / rms);
                n += 1;
            }
        }
        let p2 = self.patch * self.patch;
        sum.clear();
        sum.resize(p2, 0.0);
        for &(a, w) in &members[..n] {
            for (s, &d) in sum.iter_mut().zip(&self.detail[a * p2..(a + 1) * p2]) {
                *s += w * d;
            }
        }
        let ss: f64 = sum.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
        let rms = (ss / p2.max(1) as f64).sqrt() as f32;
        if rms <= 0.0 {
            return;
        }
        let scale = prim.detail_coef * own_rms / rms;
        prim.detail_coef = scale * members[0].1;
        prim.n_extra = 0;
        for (slot, &(a, w)) in prim.extra.iter_mut().zip(&members[1..n]) {
            *slot = (a as u32, 0.0, scale * w);
            prim.n_extra += 1;
        }
    }

    /// Blends the primitives over window `bw`, adding contributions in lattice order. For
    /// [`Blended::Elevation`] the value is `Σ α·smooth / Σ α + Σ α·detail / √(Σ α²)` with
    /// `smooth = (P_h·D_h,k)·P_s·U_k + P_a` and `detail = P_s·(D~_k − U_k)`: the detail uses the
    /// variance-preserving normaliser, so that four overlapping patches do not average it away. For
    /// [`Blended::Layer`] it is `Σ α·D~_k^l / Σ α`.
    ///
    /// The window is cut into strips of rows between two lattice rows (`step` rows, the first and
    /// last possibly shorter); every row of a strip is covered by the same two primitive rows, so
    /// each primitive is looked up once per strip and added to all its rows. A pixel still
    /// receives its contributions in lattice order (row `j − 1` before `j`, `i` increasing), so
    /// the result is bit-identical to [`Amplifier::blend_rows`], the row-by-row reference.
    fn blend(
        &self,
        bw: Window,
        lr: LatticeRange,
        prims: &[Primitive],
        what: Blended,
        slope: Option<&Array2<f32>>,
    ) -> Array2<f32> {
        let s = self.step as i64;
        let cols = bw.cols.max(1);
        let mut flat = vec![0.0f32; bw.rows * bw.cols];
        // Strips: rows [y, next multiple of s) of the window.
        let mut strips: Vec<(i64, &mut [f32])> = Vec::new();
        let mut rest: &mut [f32] = &mut flat;
        let mut y = bw.row0;
        while y < bw.row1() {
            let end = ((floor_div(y, s) + 1) * s).min(bw.row1());
            let (strip, tail) = rest.split_at_mut((end - y) as usize * bw.cols);
            strips.push((y, strip));
            rest = tail;
            y = end;
        }
        // Each strip is summed in its thread's own buffers (reused from strip to strip) and
        // copied out at the end: the output's fresh pages are only ever written, never read
        // first (a read maps the shared zero page, and the write after it costs a copy-on-write
        // fault and a TLB flush on every core).
        strips.into_par_iter().for_each_init(
            || {
                (
                    vec![0.0f32; cols * self.step],
                    vec![0.0f32; cols * self.step],
                )
            },
            |(acc_value, acc_detail), (y0, out_strip)| {
                let job = StripJob {
                    bw,
                    lr,
                    prims,
                    what,
                    slope,
                };
                self.blend_strip(&job, y0, out_strip, (acc_value, acc_detail));
            },
        );
        Array2::from_shape_vec((bw.rows, bw.cols), flat).unwrap_or_default()
    }

    /// One strip of [`Amplifier::blend`] (rows `y0..` of `job.bw`, as many as `out_strip`
    /// holds), summed in `acc` (the thread's value and detail buffers): the widest build
    /// [`Isa::current`] allows of [`Amplifier::blend_strip_with`], the same bits in every build
    /// (the same multiplications and additions, never fused).
    fn blend_strip(
        &self,
        job: &StripJob<'_>,
        y0: i64,
        out_strip: &mut [f32],
        acc: StripBuffers<'_>,
    ) {
        Isa::current().run(
            #[inline(always)]
            |_| self.blend_strip_with(job, y0, out_strip, acc),
        );
    }

    /// The body of [`Amplifier::blend_strip`], inlined into each build.
    #[inline(always)]
    fn blend_strip_with(
        &self,
        job: &StripJob<'_>,
        y0: i64,
        out_strip: &mut [f32],
        (acc_value, acc_detail): StripBuffers<'_>,
    ) {
        let StripJob {
            bw,
            lr,
            prims,
            what,
            slope,
        } = *job;
        let s = self.step as i64;
        let cols = bw.cols.max(1);
        let rows = out_strip.len() / cols;
        let strip = &mut acc_value[..rows * cols];
        strip.iter_mut().for_each(|v| *v = 0.0);
        let det_all = &mut acc_detail[..rows * cols];
        det_all.iter_mut().for_each(|v| *v = 0.0);
        // The two primitive rows covering the strip: c_j ∈ (y − s, y + s].
        let j_hi = floor_div(y0 + s, s);
        for j in [j_hi - 1, j_hi] {
            if j < lr.j0 || j >= lr.j1 {
                continue;
            }
            let oy0 = (y0 - (j * s - s)) as usize;
            for i in lr.i0..lr.i1 {
                let Some(span) = self.span(bw, lr, i, j, prims) else {
                    continue;
                };
                for (r, (row, det)) in strip
                    .chunks_exact_mut(cols)
                    .zip(det_all.chunks_exact_mut(cols))
                    .enumerate()
                {
                    let srow = slope.map(|sl| sl.row(r + (y0 - bw.row0) as usize));
                    let srow = srow.as_ref().and_then(|v| v.as_slice());
                    self.add_span(&span, what, oy0 + r, row, det, srow);
                }
            }
        }
        for (r, (row, det)) in strip
            .chunks_exact_mut(cols)
            .zip(det_all.chunks_exact(cols))
            .enumerate()
        {
            self.normalise_row(bw, y0 + r as i64, row, det);
        }
        out_strip.copy_from_slice(strip);
    }

    /// Reference implementation of [`Amplifier::blend`]: one row at a time, every primitive
    /// looked up again for every row.
    #[cfg(test)]
    fn blend_rows(
        &self,
        bw: Window,
        lr: LatticeRange,
        prims: &[Primitive],
        what: Blended,
        slope: Option<&Array2<f32>>,
    ) -> Array2<f32> {
        let s = self.step as i64;
        let cols = bw.cols.max(1);
        let mut flat = vec![0.0f32; bw.rows * bw.cols];
        for (r, row) in flat.chunks_mut(cols).enumerate() {
            let mut acc_detail = vec![0.0f32; cols];
            let y = bw.row0 + r as i64;
            let j_hi = floor_div(y + s, s);
            for j in [j_hi - 1, j_hi] {
                if j < lr.j0 || j >= lr.j1 {
                    continue;
                }
                let oy = (y - (j * s - s)) as usize;
                for i in lr.i0..lr.i1 {
                    if let Some(span) = self.span(bw, lr, i, j, prims) {
                        let srow = slope.map(|sl| sl.row(r).to_vec());
                        self.add_span(&span, what, oy, row, &mut acc_detail, srow.as_deref());
                    }
                }
            }
            self.normalise_row(bw, y, row, &acc_detail);
        }
        Array2::from_shape_vec((bw.rows, bw.cols), flat).unwrap_or_default()
    }

    /// The columns of window `bw` that primitive `(i, j)` covers, or `None` when it covers none.
    #[inline]
    fn span<'a>(
        &self,
        bw: Window,
        lr: LatticeRange,
        i: i64,
        j: i64,
        prims: &'a [Primitive],
    ) -> Option<Span<'a>> {
        let s = self.step as i64;
        let ni = (lr.i1 - lr.i0) as usize;
        let x_start = (i * s - s).max(bw.col0);
        let x_end = (i * s + s).min(bw.col1());
        if x_start >= x_end {
            return None;
        }
        Some(Span {
            prim: &prims[(j - lr.j0) as usize * ni + (i - lr.i0) as usize],
            ox0: (x_start - (i * s - s)) as usize,
            len: (x_end - x_start) as usize,
            c0: (x_start - bw.col0) as usize,
        })
    }

    /// Adds the contribution of one primitive to one row of the blend: its patch row `oy`, over
    /// the columns of `span`; `row` accumulates `α`-weighted values, `det` the elevation's detail;
    /// `slope_row` is the row of [`child_slope`] under [`Levers::slope_mod`].
    #[inline(always)]
    fn add_span(
        &self,
        span: &Span<'_>,
        what: Blended,
        oy: usize,
        row: &mut [f32],
        det: &mut [f32],
        slope_row: Option<&[f32]>,
    ) {
        let p = self.patch;
        let p2 = p * p;
        let Span { prim, ox0, len, c0 } = *span;
        let a = &self.alpha[oy * p + ox0..oy * p + ox0 + len];
        let out = &mut row[c0..c0 + len];
        match what {
            Blended::Elevation => {
                let base = prim.atom * p2 + oy * p + ox0;
                let sm = &self.smooth[base..base + len];
                let dt = &self.detail[base..base + len];
                let det = &mut det[c0..c0 + len];
                let wa = &self.walpha[oy * p + ox0..oy * p + ox0 + len];
                if !self.levers.parent_smooth {
                    for k in 0..len {
                        out[k] += a[k] * (prim.coef * sm[k] + prim.mean);
                    }
                }
                let srow = slope_row.map(|sl| &sl[c0..c0 + len]);
                match srow {
                    Some(srow) => {
                        for k in 0..len {
                            let m = (srow[k] * prim.inv_slope).min(SLOPE_MOD_MAX);
                            det[k] += wa[k] * (prim.detail_coef * dt[k]) * m;
                        }
                    }
                    None => {
                        for k in 0..len {
                            det[k] += wa[k] * (prim.detail_coef * dt[k]);
                        }
                    }
                }
                // The sparse code's further atoms (none at sparsity 1).
                for &(ea, ec, ed) in &prim.extra[..usize::from(prim.n_extra)] {
                    let eb = ea as usize * p2 + oy * p + ox0;
                    let sm = &self.smooth[eb..eb + len];
                    let dt = &self.detail[eb..eb + len];
                    if !self.levers.parent_smooth {
                        for k in 0..len {
                            out[k] += a[k] * (ec * sm[k]);
                        }
                    }
                    match srow {
                        Some(srow) => {
                            for k in 0..len {
                                let m = (srow[k] * prim.inv_slope).min(SLOPE_MOD_MAX);
                                det[k] += wa[k] * (ed * dt[k]) * m;
                            }
                        }
                        None => {
                            for k in 0..len {
                                det[k] += wa[k] * (ed * dt[k]);
                            }
                        }
                    }
                }
            }
            Blended::Layer(l) => {
                let nl = self.dict.layers.len();
                let base = (prim.atom * nl + l) * p2 + oy * p + ox0;
                let v = &self.dict.hi_layers[base..base + len];
                for k in 0..len {
                    out[k] += a[k] * v[k];
                }
            }
        }
    }

    /// Normalises row `y` of the blend: `value · (1 / Σ α) + detail · (1 / √(Σ w²))` with the
    /// tables of the pixel's offset in its lattice cell, cell by cell (no division per pixel).
    #[inline(always)]
    fn normalise_row(&self, bw: Window, y: i64, row: &mut [f32], det: &[f32]) {
        let s = self.step as i64;
        let step = self.step;
        let oy = y.rem_euclid(s) as usize;
        let norm_row = &self.inv_norm[oy * step..(oy + 1) * step];
        let rms_row = &self.inv_rms[oy * step..(oy + 1) * step];
        let first = bw.col0.rem_euclid(s) as usize;
        let mut c = 0;
        for run in std::iter::once(first..step).chain(std::iter::repeat(0..step)) {
            if c >= row.len() {
                break;
            }
            let len = (run.end - run.start).min(row.len() - c);
            let (n, m) = (
                &norm_row[run.start..run.start + len],
                &rms_row[run.start..run.start + len],
            );
            for (((v, d), n), m) in row[c..c + len]
                .iter_mut()
                .zip(&det[c..c + len])
                .zip(n)
                .zip(m)
            {
                *v = *v * n + d * m;
            }
            c += len;
        }
    }

    /// Amplifies window `out` of this level from `parent`, which must cover
    /// [`Amplifier::parent_window_for`]`(out)`. `parent_cell_m` is the parent level's metric cell
    /// size (used by the slope term). The result does not depend on anything but the parent's
    /// values, the dictionary and `out`'s pixels: any window containing a pixel gives it the same
    /// value, bit for bit.
    pub fn amplify(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Field, SynthError> {
        Ok(self.amplify_matched(parent, out, parent_cell_m)?.0)
    }

    /// [`Amplifier::amplify`], keeping the atoms matched for the primitives the extra layers of
    /// `out` read, so that [`Amplifier::amplify_layers_with`] can reconstruct those layers later
    /// without matching again.
    pub fn amplify_keeping_atoms(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<(Field, LayerAtoms), SynthError> {
        let (field, lr, prims) = self.amplify_matched(parent, out, parent_cell_m)?;
        let llr = self.lattice_range(Self::margin_window(out, Self::layer_margin()));
        let ni = (lr.i1 - lr.i0) as usize;
        let mut atoms = Vec::with_capacity(((llr.i1 - llr.i0) * (llr.j1 - llr.j0)).max(0) as usize);
        for j in llr.j0..llr.j1 {
            for i in llr.i0..llr.i1 {
                let k = (j - lr.j0) as usize * ni + (i - lr.i0) as usize;
                atoms.push(prims[k].atom as u32);
            }
        }
        Ok((
            field,
            LayerAtoms {
                dict: self.dict.clone(),
                out,
                lr: llr,
                atoms,
            },
        ))
    }

    /// [`Amplifier::amplify`] and the lattice range and primitives it matched.
    fn amplify_matched(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<(Field, LatticeRange, Vec<Primitive>), SynthError> {
        let parent = Self::checked_parent(parent, out, self.parent_window_for(out))?;
        let ext = self.conditioned_window(out);
        let bw = self.blend_window(ext);
        let lr = self.lattice_range(bw);
        let prims = self.match_primitives(&parent, lr, parent_cell_m);
        let slope = self
            .levers
            .slope_mod
            .then(|| child_slope(&parent.elevation, parent.window, bw, parent_cell_m));
        let blended = self.blend(bw, lr, &prims, Blended::Elevation, slope.as_ref());
        let raw = correct(
            &self.kernel,
            blended,
            bw,
            &parent.elevation,
            parent.window,
            ext,
            i64::from(self.levers.passes),
        );
        let elevation = if self.levers.breach > 0 {
            let rule = BreachRule {
                radius: self.levers.breach as usize,
                flat_radius: (self.levers.breach_flat.min(self.levers.breach)) as usize,
                steep_rise: self.levers.steep_slope * RISE_REACH as f32 * parent_cell_m / 2.0,
                volume: self.levers.breach_volume,
                corner_depth: self.levers.corner_depth,
                corner_rise: self.levers.corner_slope * RISE_REACH as f32 * parent_cell_m / 2.0,
            };
            let carved = breach_pits_with(&raw, (ext.row0, ext.col0), rule);
            let m = breach_margin(rule.radius);
            let (rr, rc) = raw.dim();
            let banked = if self.levers.banks > 0 {
                // The raw values of the breaching's result, for the banks.
                let raw_inner = raw.slice(s![m..rr - m, m..rc - m]).to_owned();
                widen_channels(
                    &raw_inner,
                    &carved,
                    self.levers.banks as usize,
                    self.levers.bank_share,
                )
            } else {
                carved
            };
            let rm = self.restore_margin();
            if rm > 0 {
                // Over the output and one more cell, so that its parent cells are whole.
                let k = m + self.levers.banks as usize;
                let mut restored = banked;
                restore_block_means(
                    raw.slice(s![k..rr - k, k..rc - k]),
                    &mut restored,
                    (ext.row0 + k as i64, ext.col0 + k as i64),
                    self.levers.restore,
                );
                let (h, w) = restored.dim();
                restored.slice(s![rm..h - rm, rm..w - rm]).to_owned()
            } else {
                banked
            }
        } else {
            raw
        };
        let layers = self.reconstruct_layers(&parent, out, lr, &prims);
        let field = Field {
            window: out,
            elevation,
            layers,
        };
        Ok((field, lr, prims))
    }

    /// The extra dictionary layers of window `out` of this level from `parent`, which must cover
    /// [`Amplifier::layers_parent_window_for`]`(out)`: bit for bit the layers of
    /// [`Amplifier::amplify`]`(parent, out, parent_cell_m)`, without reconstructing (and
    /// breaching) the elevation, and matching only the primitives the layers read — for callers
    /// that already have the level's elevation (the vegetation of a tile whose elevation tile
    /// is computed).
    pub fn amplify_layers(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Vec<(String, Array2<f32>)>, SynthError> {
        let parent = Self::checked_parent(parent, out, self.layers_parent_window_for(out))?;
        let lr = self.lattice_range(Self::margin_window(out, Self::layer_margin()));
        let prims = self.match_primitives(&parent, lr, parent_cell_m);
        Ok(self.reconstruct_layers(&parent, out, lr, &prims))
    }

    /// [`Amplifier::amplify_layers`] from the atoms an amplifier with the same dictionary (the same
    /// `Arc`) and matching matched for `out` ([`Amplifier::amplify_keeping_atoms`]): the same layers, bit
    /// for bit, when `parent` holds the same elevation and matched layers, without matching.
    /// `parent` must cover [`Amplifier::layers_parent_window_for`]`(out)`.
    pub fn amplify_layers_with(
        &self,
        parent: &Field,
        out: Window,
        atoms: &LayerAtoms,
    ) -> Result<Vec<(String, Array2<f32>)>, SynthError> {
        let parent = Self::checked_parent(parent, out, self.layers_parent_window_for(out))?;
        if atoms.out != out || !Arc::ptr_eq(&atoms.dict, &self.dict) {
            return Err(SynthError::BadWindow(format!(
                "atoms matched for {} with another dictionary or window than {out}",
                atoms.out
            )));
        }
        let prims: Vec<Primitive> = atoms
            .atoms
            .iter()
            .map(|&a| Primitive {
                atom: a as usize,
                ..Primitive::EMPTY
            })
            .collect();
        Ok(self.reconstruct_layers(&parent, out, atoms.lr, &prims))
    }

    /// `parent` cropped to `needed` (the parent window of output window `out`), refusing an empty
    /// or oversized `out`, a parent that does not cover `needed` and non-finite elevation.
    fn checked_parent(parent: &Field, out: Window, needed: Window) -> Result<Field, SynthError> {
        if out.is_empty() || out.len() > (1usize << 30) {
            return Err(SynthError::BadWindow(format!(
                "{out} has {} pixels",
                out.len()
            )));
        }
        let too_small = || SynthError::ParentTooSmall {
            given: parent.window.to_string(),
            needed: needed.to_string(),
        };
        if !parent.window.contains(&needed) {
            return Err(too_small());
        }
        let parent = parent.crop(needed).ok_or_else(too_small)?;
        if parent.elevation.iter().any(|v| !v.is_finite()) {
            return Err(SynthError::NonFinite);
        }
        Ok(parent)
    }

    /// The extra dictionary layers this amplifier reconstructs, over `out`, from the primitives
    /// `prims` of lattice range `lr` (which must cover the layers' blend windows) and the parent's
    /// own values of each layer (corrected against them; blended alone where it has none).
    fn reconstruct_layers(
        &self,
        parent: &Field,
        out: Window,
        lr: LatticeRange,
        prims: &[Primitive],
    ) -> Vec<(String, Array2<f32>)> {
        let dict = &*self.dict;
        let nl = if self.with_layers {
            dict.layers.len()
        } else {
            0
        };
        let mut layers = Vec::with_capacity(nl);
        for (l, info) in dict.layers.iter().enumerate().take(nl) {
            if !self.layer_mask.get(l).copied().unwrap_or(false) {
                continue;
            }
            // A layer is blended only where its result needs it: over `out` and the margin of
            // its correction, or over `out` alone when the parent does not carry it (every
            // blended value is a function of its global pixel, so the window does not matter).
            let field = match parent.layer(&info.name) {
                Some(pl) => {
                    let lw = Self::margin_window(out, Self::layer_margin());
                    let raw = self.blend(lw, lr, prims, Blended::Layer(l), None);
                    correct(&CATMULL_ROM, raw, lw, pl, parent.window, out, LAYER_PASSES)
                }
                None => self.blend(out, lr, prims, Blended::Layer(l), None),
            };
            layers.push((info.name.clone(), field));
        }
        layers
    }
}

/// What [`Amplifier::match_primitives`] measures of a group's low patches before matching.
struct PatchMeasures {
    /// Mean and norm of each patch ([`centre_normalise_n`]).
    stats: [(f32, f32); DOT_BATCH],
    /// Mean slope of each patch ([`patch_mean_slope_n`]).
    slopes: [f32; DOT_BATCH],
    /// RMS of each patch's finest octave ([`finest_octave_rms_n`]; 0 without `octave`).
    finest: [f32; DOT_BATCH],
}

/// The measures of a group of `side²` low `patches` (of cells `cell_m` metres), the centred,
/// unit-norm patches written to `centred`; the finest octave only with `octave` scratch. The
/// widest build [`Isa::current`] allows of [`measure_patches_with`]: the same bits in every build.
fn measure_patches(
    patches: [&[f32]; DOT_BATCH],
    centred: [&mut [f32]; DOT_BATCH],
    side_cell: (usize, f32),
    octave: Option<&mut OctaveScratch>,
) -> PatchMeasures {
    Isa::current().run(
        #[inline(always)]
        |_| measure_patches_with(patches, centred, side_cell, octave),
    )
}

/// The body of [`measure_patches`], inlined into each build.
#[inline(always)]
fn measure_patches_with(
    patches: [&[f32]; DOT_BATCH],
    centred: [&mut [f32]; DOT_BATCH],
    (side, cell_m): (usize, f32),
    octave: Option<&mut OctaveScratch>,
) -> PatchMeasures {
    PatchMeasures {
        stats: centre_normalise_n(patches, centred),
        slopes: patch_mean_slope_n(patches, side, cell_m),
        finest: match octave {
            Some(o) => finest_octave_rms_n(patches, side, o),
            None => [0.0; DOT_BATCH],
        },
    }
}

/// The parent's slope magnitude (m/m, central differences on cells of `cell_m`), interpolated
/// bilinearly at the children of window `w` (the parent must cover `w`'s parents and 2 more).
fn child_slope(p: &Array2<f32>, pw: Window, w: Window, cell_m: f32) -> Array2<f32> {
    let inv = 1.0 / (2.0 * cell_m.max(1e-6));
    let at = |r: i64, c: i64| p[[(r - pw.row0) as usize, (c - pw.col0) as usize]];
    let slope_at = |r: i64, c: i64| {
        let gx = (at(r, c + 1) - at(r, c - 1)) * inv;
        let gy = (at(r + 1, c) - at(r - 1, c)) * inv;
        (gx * gx + gy * gy).sqrt()
    };
    Array2::from_shape_fn((w.rows, w.cols), |(rr, cc)| {
        let (y, x) = (w.row0 + rr as i64, w.col0 + cc as i64);
        // Child x lies at parent coordinate (x + 0.5)/2 − 0.5: between k = floor((x − 1)/2) and
        // k + 1 with weight 0.25 or 0.75.
        let (kx, fx) = (
            floor_div(x - 1, 2),
            if x.rem_euclid(2) == 0 { 0.75 } else { 0.25 },
        );
        let (ky, fy) = (
            floor_div(y - 1, 2),
            if y.rem_euclid(2) == 0 { 0.75 } else { 0.25 },
        );
        let top = slope_at(ky, kx) * (1.0 - fx) + slope_at(ky, kx + 1) * fx;
        let bottom = slope_at(ky + 1, kx) * (1.0 - fx) + slope_at(ky + 1, kx + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    })
}

/// A row-major plane of values over a window of a level.
struct Plane {
    data: Vec<f32>,
    w: Window,
}

impl Plane {
    fn from_array(a: &Array2<f32>, w: Window) -> Plane {
        let data = match a.as_slice() {
            Some(v) => v.to_vec(),
            None => a.iter().copied().collect(),
        };
        Plane { data, w }
    }

    /// The plane of an owned array, without a copy when it is in standard layout.
    fn from_owned(a: Array2<f32>, w: Window) -> Plane {
        if !a.is_standard_layout() {
            return Plane::from_array(&a, w);
        }
        let n = a.len();
        let (mut data, offset) = a.into_raw_vec_and_offset();
        let o = offset.unwrap_or(0);
        if o > 0 {
            data.drain(..o);
        }
        data.truncate(n);
        Plane { data, w }
    }

    /// Row `y` (global), starting at column `w.col0`.
    fn row(&self, y: i64) -> &[f32] {
        let r = (y - self.w.row0) as usize;
        &self.data[r * self.w.cols..(r + 1) * self.w.cols]
    }
}

/// `F − Down(G)` over the parent pixels of window `rw` (whose children `g` covers), computed with
/// the one 2×2 box average ([`box2`]);
/// `data` is a reused buffer.
fn residual(f: &Plane, g: &Plane, rw: Window, mut data: Vec<f32>) -> Plane {
    data.clear();
    data.resize(rw.len(), 0.0);
    data.par_chunks_mut(rw.cols.max(1))
        .enumerate()
        .for_each(|(rr, out)| {
            let row = rw.row0 + rr as i64;
            let (g0, g1) = (g.row(2 * row), g.row(2 * row + 1));
            let fr = f.row(row);
            for (cc, o) in out.iter_mut().enumerate() {
                let col = rw.col0 + cc as i64;
                let x = (2 * col - g.w.col0) as usize;
                let down = box2([g0[x], g0[x + 1], g1[x], g1[x + 1]]);
                *o = fr[(col - f.w.col0) as usize] - down;
            }
        });
    Plane { data, w: rw }
}

/// Residual correction of a raw blend `b` (held over the blend window `bw`) against the parent
/// field `f` (held over `fw`), returning the corrected values over `out`: `passes` passes of
/// `G += Up(F − Down(G))` with `kernel`, each on a window `kernel.reach()` parent pixels narrower.
/// Every value is a function of global coordinates only, so the result is window-invariant; rows
/// are processed in parallel.
fn correct(
    kernel: &UpKernel,
    b: Array2<f32>,
    bw: Window,
    f: &Array2<f32>,
    fw: Window,
    out: Window,
    passes: i64,
) -> Array2<f32> {
    match kernel.taps_per_phase() {
        4 => correct_n::<4>(kernel, b, bw, f, fw, out, passes),
        8 => correct_n::<8>(kernel, b, bw, f, fw, out, passes),
        _ => correct_n::<12>(kernel, b, bw, f, fw, out, passes),
    }
}

/// The weights of child `x` as an array of `N` (the kernel's taps per phase).
#[inline]
fn taps_n<const N: usize>(kernel: &UpKernel, x: i64) -> (i64, [f32; N]) {
    let (k, w) = kernel.taps(x);
    let mut a = [0.0f32; N];
    for (d, s) in a.iter_mut().zip(w) {
        *d = *s;
    }
    (k, a)
}

/// One row of the horizontal up-sampling: `out[c]` is child column `col0 + c` of the parent row
/// `src` (whose first pixel is parent column `src_col0`). The columns of one phase (even or odd)
/// read consecutive windows of `src` with the same weights, so each phase is a filter run along
/// the row (vectorised across columns; every output still sums its taps in tap order from 0,
/// which [`upsample_row_naive`] does column by column). `acc` holds at least `⌈len/2⌉` values.
fn upsample_row<const N: usize>(
    kernel: &UpKernel,
    src: &[f32],
    src_col0: i64,
    col0: i64,
    out: &mut [f32],
    acc: &mut [f32],
) {
    for first in 0..2usize.min(out.len()) {
        let (k, w) = taps_n::<N>(kernel, col0 + first as i64);
        let n = (out.len() - first).div_ceil(2);
        let acc = &mut acc[..n];
        fir_phase::<N>(src, (k - src_col0) as usize, &w, acc);
        for (v, a) in out[first..].iter_mut().step_by(2).zip(acc.iter()) {
            *v = *a;
        }
    }
}

/// Reference implementation of [`upsample_row`]: every column's taps summed in a plain loop.
#[cfg(test)]
fn upsample_row_naive(kernel: &UpKernel, src: &[f32], src_col0: i64, col0: i64, out: &mut [f32]) {
    for (c, v) in out.iter_mut().enumerate() {
        let (k, w) = kernel.taps(col0 + c as i64);
        let mut acc = 0.0f32;
        for (t, wt) in w.iter().enumerate() {
            acc += wt * src[(k + t as i64 - src_col0) as usize];
        }
        *v = acc;
    }
}

/// `out[m] = Σ_t w[t]·src[start + m + t]`, summed in tap order from 0 for every `m` (the loop
/// over `m` is innermost, so it vectorises without reassociating any sum).
#[inline]
fn fir_phase<const N: usize>(src: &[f32], start: usize, w: &[f32; N], out: &mut [f32]) {
    out.fill(0.0);
    let n = out.len();
    for (t, &wt) in w.iter().enumerate() {
        crate::simd::add_scaled(out, wt, &src[start + t..start + t + n]);
    }
}

/// [`correct`] for a kernel of `N` taps per phase (the sums run in tap order, like a plain loop).
fn correct_n<const N: usize>(
    kernel: &UpKernel,
    b: Array2<f32>,
    bw: Window,
    f: &Array2<f32>,
    fw: Window,
    out: Window,
    passes: i64,
) -> Array2<f32> {
    let (k0, k1) = Amplifier::parent_span(out.col0, out.col1());
    let (l0, l1) = Amplifier::parent_span(out.row0, out.row1());
    let f = Plane::from_array(f, fw);
    let mut g = Plane::from_owned(b, bw);
    // Buffers reused from pass to pass (fresh pages cost a fault each): the residual, the
    // horizontal pass, and the plane the next pass writes (the previous G once replaced).
    let (mut rbuf, mut horiz, mut spare) = (Vec::new(), Vec::new(), Vec::new());
    for pass in 1..=passes {
        let rw = Window::from_bounds(g.w.col0 / 2, g.w.row0 / 2, g.w.col1() / 2, g.w.row1() / 2);
        let r = residual(&f, &g, rw, std::mem::take(&mut rbuf));
        let n = (passes - pass) * kernel.reach();
        let nw = Window::from_bounds(2 * (k0 - n), 2 * (l0 - n), 2 * (k1 + n), 2 * (l1 + n));
        // Horizontal pass of the up-sampling over the residual's rows, then vertical.
        horiz.clear();
        horiz.resize(rw.rows * nw.cols, 0.0);
        horiz
            .par_chunks_mut(nw.cols.max(1))
            .enumerate()
            .for_each_init(
                || vec![0.0f32; nw.cols.div_ceil(2)],
                |acc, (rr, o)| {
                    let rrow = r.row(rw.row0 + rr as i64);
                    upsample_row::<N>(kernel, rrow, rw.col0, nw.col0, o, acc);
                },
            );
        let mut data = std::mem::take(&mut spare);
        data.clear();
        data.resize(nw.len(), 0.0);
        data.par_chunks_mut(nw.cols.max(1))
            .enumerate()
            .for_each_init(
                || vec![0.0f32; nw.cols],
                |up, (rr, o)| {
                    let y = nw.row0 + rr as i64;
                    let (ky, w) = taps_n::<N>(kernel, y);
                    up.iter_mut().for_each(|u| *u = 0.0);
                    for (t, wt) in w.iter().enumerate() {
                        let i = (ky + t as i64 - rw.row0) as usize * nw.cols;
                        crate::simd::add_scaled(up, *wt, &horiz[i..i + nw.cols]);
                    }
                    let grow = &g.row(y)[(nw.col0 - g.w.col0) as usize..];
                    for ((v, gv), u) in o.iter_mut().zip(grow).zip(up.iter()) {
                        *v = gv + u;
                    }
                },
            );
        rbuf = r.data;
        spare = std::mem::replace(&mut g, Plane { data, w: nw }).data;
    }
    if g.w == out {
        return Array2::from_shape_vec((out.rows, out.cols), g.data).unwrap_or_default();
    }
    // The result over `out`, cut from G (which covers the children of [k0, k1) × [l0, l1)).
    let mut data = vec![0.0f32; out.len()];
    data.par_chunks_mut(out.cols.max(1))
        .enumerate()
        .for_each(|(rr, o)| {
            let y = out.row0 + rr as i64;
            let grow = &g.row(y)[(out.col0 - g.w.col0) as usize..];
            o.copy_from_slice(&grow[..o.len()]);
        });
    Array2::from_shape_vec((out.rows, out.cols), data).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gentle_octaves_take_the_gentle_roughness_steep_ones_the_plain_one() {
        let g = (0.8, 0.04);
        // Up to the gentle slope: the gentle roughness; from twice it: the plain one.
        for s in [0.0, 0.01, 0.04] {
            assert_eq!(gentle_blend(0.58, g, s), 0.8, "{s}");
        }
        for s in [0.08, 0.2, f32::INFINITY] {
            assert_eq!(gentle_blend(0.58, g, s), 0.58, "{s}");
        }
        // Halfway along the ramp: halfway between them.
        assert!((gentle_blend(0.58, g, 0.06) - 0.69).abs() < 1e-6);
        // Monotone on the ramp.
        assert!(gentle_blend(0.58, g, 0.05) > gentle_blend(0.58, g, 0.07));
        // Off (0), a zero slope threshold or a NaN slope: the plain roughness.
        assert_eq!(gentle_blend(0.58, (0.0, 0.04), 0.01), 0.58);
        assert_eq!(gentle_blend(0.58, (0.8, 0.0), 0.01), 0.58);
        assert_eq!(gentle_blend(0.58, g, f32::NAN), 0.58);
    }

    #[test]
    fn the_flattest_octaves_take_the_plains_roughness() {
        let (g, p) = ((0.8, 0.04), (0.3, 0.016));
        // Up to the plains slope: the plains roughness; from twice it, the gentle one (still
        // within the gentle slope); from twice the gentle slope, the plain one.
        for s in [0.0, 0.01, 0.016] {
            assert_eq!(roughness_at(0.58, g, p, s), 0.3, "{s}");
        }
        for s in [0.032, 0.04] {
            assert_eq!(roughness_at(0.58, g, p, s), 0.8, "{s}");
        }
        assert_eq!(roughness_at(0.58, g, p, 0.2), 0.58);
        // Halfway along the plains ramp: halfway between the plains and the gentle roughness.
        assert!((roughness_at(0.58, g, p, 0.024) - 0.55).abs() < 1e-6);
        // Off (0): the gentle blend alone, at every slope.
        for s in [0.0, 0.01, 0.024, 0.06, 0.2, f32::NAN] {
            let off = roughness_at(0.58, g, (0.0, 0.016), s);
            assert_eq!(off.to_bits(), gentle_blend(0.58, g, s).to_bits(), "{s}");
        }
        // A NaN slope takes the plain roughness.
        assert_eq!(roughness_at(0.58, g, p, f32::NAN), 0.58);
    }

    #[test]
    fn the_detail_smoothing_keeps_the_rms_and_moves_energy_off_the_pixel_scale() {
        let side = 8;
        // A checkerboard (all its energy at the pixel scale) over a slow ramp.
        let patch: Vec<f32> = (0..side * side)
            .map(|k| {
                let (r, c) = (k / side, k % side);
                let board = if (r + c) % 2 == 0 { 1.0f32 } else { -1.0 };
                board + 0.5 * (r as f32 - 3.5)
            })
            .collect();
        let rms = |v: &[f32]| (v.iter().map(|a| a * a).sum::<f32>() / v.len() as f32).sqrt();
        // Energy of the differences between horizontal neighbours: the checkerboard's 4 per
        // pair before, far less once it is smoothed.
        let rough = |v: &[f32]| -> f32 {
            (0..side * side)
                .filter(|k| k % side + 1 < side)
                .map(|k| (v[k + 1] - v[k]).powi(2))
                .sum()
        };
        for k in [0.25f32, 0.5, 1.0] {
            let mut x = patch.clone();
            smooth_detail(&mut x, side, k);
            assert!((rms(&x) - rms(&patch)).abs() < 1e-4, "{k}: rms");
            assert!(
                rough(&x) < 0.8 * rough(&patch),
                "{k}: {} vs {}",
                rough(&x),
                rough(&patch)
            );
        }
        // Smoother with more smoothing.
        let (mut half, mut whole) = (patch.clone(), patch.clone());
        smooth_detail(&mut half, side, 0.5);
        smooth_detail(&mut whole, side, 1.0);
        assert!(rough(&whole) < rough(&half));
        // A flat patch stays flat (no division by zero).
        let mut zero = vec![0.0f32; side * side];
        smooth_detail(&mut zero, side, 1.0);
        assert!(zero.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn the_stripe_cap_removes_and_caps_row_and_column_means() {
        let side = 8;
        // Horizontal stripes (each row constant) over a checkerboard (every row and column mean 0).
        let stripe = |r: usize| [3.0f32, -1.0, 2.0, -4.0, 1.0, 0.0, -2.0, 1.0][r];
        let board = |r: usize, c: usize| if (r + c) % 2 == 0 { 1.0f32 } else { -1.0 };
        let patch: Vec<f32> = (0..side * side)
            .map(|k| 5.0 + stripe(k / side) + board(k / side, k % side))
            .collect();
        // Cap 0: the stripes go, the checkerboard and the mean stay.
        let mut x = patch.clone();
        cap_stripes(&mut x, side, 0.0);
        for (k, v) in x.iter().enumerate() {
            assert!(
                (v - (5.0 + board(k / side, k % side))).abs() < 1e-5,
                "{k}: {v}"
            );
        }
        // Cap 1: the stripes' energy becomes 1/8 of the patch's energy about its mean before the
        // cap. Stripes hold 8·Σ stripe² = 8·36 = 288, the checkerboard 64; scaled by k,
        // k²·288 = (288 + 64)/8 = 44.
        let mut x = patch.clone();
        cap_stripes(&mut x, side, 1.0);
        let k = (44.0f32 / 288.0).sqrt();
        for (i, v) in x.iter().enumerate() {
            let want = 5.0 + k * stripe(i / side) + board(i / side, i % side);
            assert!((v - want).abs() < 1e-4, "{i}: {v} vs {want}");
        }
        // A cap above the stripes' share leaves the patch alone; so does a patch without stripes.
        let mut x = patch.clone();
        cap_stripes(&mut x, side, 8.0);
        assert_eq!(x, patch);
        let plain: Vec<f32> = (0..side * side)
            .map(|k| board(k / side, k % side))
            .collect();
        let mut x = plain.clone();
        cap_stripes(&mut x, side, 0.0);
        assert!(x.iter().zip(&plain).all(|(a, b)| (a - b).abs() < 1e-6));
    }
    use crate::dictionary::build::{build, BuildOptions, Exemplar};
    use crate::dictionary::derive::derived_layers;
    use crate::dictionary::features::{centre_normalise, patch_mean_slope};
    use crate::raster::CellSizes;
    use proptest::prelude::*;

    /// A ridged test terrain (sums of rotated sinusoids), metres.
    fn terrain(rows: usize, cols: usize, seed: f64) -> Array2<f32> {
        Array2::from_shape_fn((rows, cols), |(r, c)| {
            let (x, y) = (c as f64, r as f64);
            let mut h = 900.0 + 2.0 * x - 3.0 * y;
            for (k, (fx, fy, amp)) in [
                (0.031, 0.017, 300.0),
                (-0.052, 0.047, 140.0),
                (0.11, -0.093, 60.0),
                (0.23, 0.19, 25.0),
                (-0.41, 0.37, 9.0),
            ]
            .iter()
            .enumerate()
            {
                let v = math::sin(fx * x + fy * y + seed * (k as f64 + 1.0));
                h += amp * (1.0 - 2.0 * v.abs());
            }
            h as f32
        })
    }

    /// A small dictionary with the derived layers, built once.
    fn dictionary() -> Arc<Dictionary> {
        static DICT: std::sync::OnceLock<Arc<Dictionary>> = std::sync::OnceLock::new();
        DICT.get_or_init(|| {
            let z = terrain(128, 128, 0.3);
            let layers = derived_layers(&z, &CellSizes::uniform(128, 100.0));
            let ex = Exemplar {
                elevation: z,
                valid: None,
                cell_m: 100.0,
                layers,
            };
            let opts = BuildOptions {
                atoms: 48,
                ..BuildOptions::default()
            };
            Arc::new(build(&[ex], &opts, &mut |_, _| {}).unwrap())
        })
        .clone()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// The strip blend gives the row-by-row reference's bits, for the elevation (with and
        /// without the slope term, one or several atoms per primitive, atom or parent smooth
        /// parts) and for the extra layers, on windows that start anywhere in a lattice cell.
        #[test]
        fn strip_blend_equals_the_row_reference(
            c0 in -40i64..40,
            r0 in -40i64..40,
            cols in 1usize..90,
            rows in 1usize..90,
            which in 0usize..4,
        ) {
            let levers = match which {
                0 => Levers::default(),
                1 => Levers { slope_mod: true, ..Levers::default() },
                2 => Levers { sparsity: 3, parent_smooth: true, ..Levers::default() },
                _ => Levers::baseline(),
            };
            let amp = Amplifier::new(dictionary(), &MatchWeights::default())
                .unwrap()
                .with_levers(levers);
            let out = Window::new(c0, r0, cols, rows);
            let bw = amp.blend_window(out);
            let lr = amp.lattice_range(bw);
            let need = amp.parent_window_for(out);
            let base = terrain(need.rows, need.cols, 1.7);
            let parent = Field::elevation_only(need, base);
            let prims = amp.match_primitives(&parent, lr, 200.0);
            let slope = child_slope(&parent.elevation, parent.window, bw, 200.0);
            let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            for (what, sl) in [
                (Blended::Elevation, None),
                (Blended::Elevation, Some(&slope)),
                (Blended::Layer(0), None),
                (Blended::Layer(1), None),
            ] {
                let fast = amp.blend(bw, lr, &prims, what, sl);
                let naive = amp.blend_rows(bw, lr, &prims, what, sl);
                prop_assert_eq!(bits(&fast), bits(&naive), "{:?}", what);
            }
        }

        /// The patch measures of a group, in the widest build, are each patch's measures taken
        /// alone by the plain functions, bit for bit.
        #[test]
        fn group_measures_equal_each_patch_measured_alone(
            seed in 0u32..1000, side_half in 1usize..9, cell_m in 1.0f32..500.0,
        ) {
            let side = 2 * side_half;
            let z = terrain(side * DOT_BATCH, side, f64::from(seed) * 0.37);
            let flat = z.as_slice().unwrap();
            let patches: [&[f32]; DOT_BATCH] =
                std::array::from_fn(|m| &flat[m * side * side..(m + 1) * side * side]);
            let mut centred: [Vec<f32>; DOT_BATCH] = std::array::from_fn(|_| vec![0.0; side * side]);
            let mut octave = OctaveScratch::default();
            let got = measure_patches(
                patches,
                centred.each_mut().map(Vec::as_mut_slice),
                (side, cell_m),
                Some(&mut octave),
            );
            for (m, patch) in patches.iter().enumerate() {
                let mut alone = vec![0.0f32; side * side];
                let (mean, norm) = centre_normalise(patch, &mut alone);
                prop_assert_eq!(got.stats[m].0.to_bits(), mean.to_bits());
                prop_assert_eq!(got.stats[m].1.to_bits(), norm.to_bits());
                prop_assert_eq!(
                    centred[m].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    alone.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
                let slope = patch_mean_slope(patch, side, cell_m);
                prop_assert_eq!(got.slopes[m].to_bits(), slope.to_bits());
                let finest = finest_octave_rms(patch, side, &mut OctaveScratch::default());
                prop_assert_eq!(got.finest[m].to_bits(), finest.to_bits());
            }
            let none = measure_patches(
                patches,
                centred.each_mut().map(Vec::as_mut_slice),
                (side, cell_m),
                None,
            );
            prop_assert!(none.finest.iter().all(|&f| f == 0.0));
        }

        /// The phase-split horizontal up-sampling gives the per-column loop's bits.
        #[test]
        fn upsample_row_equals_the_column_loop(
            kind in 0usize..3,
            col0 in -30i64..30,
            len in 0usize..70,
            values in proptest::collection::vec(-500.0f32..500.0, 60),
        ) {
            let kernel = UpKernel::new(
                [KernelKind::CatmullRom, KernelKind::Kaiser4, KernelKind::Kaiser6][kind],
            );
            // The parent row covers every tap of the children [col0, col0 + len).
            let (k0, _) = kernel.taps(col0);
            let src_col0 = k0 - 1;
            let need = (floor_div(col0 + len as i64, 2) + kernel.reach() + 1 - src_col0) as usize;
            let src: Vec<f32> = values.iter().cycle().take(need.max(1)).copied().collect();
            let (mut fast, mut naive) = (vec![0.0f32; len], vec![1.0f32; len]);
            let mut acc = vec![0.0f32; len.div_ceil(2)];
            match kernel.taps_per_phase() {
                4 => upsample_row::<4>(&kernel, &src, src_col0, col0, &mut fast, &mut acc),
                8 => upsample_row::<8>(&kernel, &src, src_col0, col0, &mut fast, &mut acc),
                _ => upsample_row::<12>(&kernel, &src, src_col0, col0, &mut fast, &mut acc),
            }
            upsample_row_naive(&kernel, &src, src_col0, col0, &mut naive);
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(&fast), bits(&naive));
        }
    }
}
