//! The switches of one amplification level (issue #12's levers), so that each can be measured
//! alone and in combination on the held-out suite (`scripts/realism.sh`, README "Realism").
//! [`Levers::default`] is the amplifier the server and the command line run;
//! [`Levers::baseline`] is the amplifier before issue #12.

use super::kernel::KernelKind;

/// Largest number of atoms per primitive the amplifier takes ([`Levers::sparsity`]).
pub const MAX_AMPLIFY_SPARSITY: usize = 8;

/// Fewest atoms per primitive when [`Levers::sparsity`] is 0 (the dictionary's own): the served
/// amplifier's roughness levers are set for two atoms (README, *Two atoms and a plains
/// roughness*).
pub const DEFAULT_AMPLIFY_SPARSITY: usize = 2;

/// The switches of one amplification level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Levers {
    /// Split each atom into a smooth part that is the *consistent* up-sampling of its low atom
    /// (its 2×2 box averages reproduce the low atom) and a detail part whose 2×2 box averages are
    /// zero, instead of a plain Catmull-Rom smooth part.
    pub consistent_split: bool,
    /// Take the smooth part from the parent alone (the residual correction of a detail-only blend
    /// reconstructs it) instead of from the matched atoms' scaled low shapes.
    pub parent_smooth: bool,
    /// Exponent `p` of the detail blending weights `α^p` (1: the plain radial falloff); above 1
    /// one atom dominates near its centre and fewer overlapping atoms are averaged into texture.
    pub blend_power: u32,
    /// When above 0, the detail's amplitude follows the parent's own finest octave instead of its
    /// relief: a primitive's detail RMS is `roughness` times the RMS of `P − CR(box(P))` over its
    /// low patch `P` (self-similarity: each octave carries a fixed fraction of the one above),
    /// whatever the matched atom's own detail-to-relief ratio, which belongs to the exemplar's
    /// scale and not to the level's. 0: the detail is scaled by the patch's relief `P_s`.
    pub roughness: f32,
    /// With [`Levers::roughness`] above 0, a floor under the detail RMS, metres at 1 km cells:
    /// the detail RMS is `√((roughness·octave)² + (floor·(cell/1 km)^0.7)²)` (`cell`: this level's
    /// cell size). Plains carry micro-relief that their smooth coarse octaves do not announce.
    pub floor_m: f32,
    /// With [`Levers::roughness`] above 0 and this above 0: the roughness of primitives whose
    /// parent's finest octave is gentle — its RMS per cell (`octave / cell`, a slope) at most
    /// [`Levers::gentle_slope`] — ramping linearly to [`Levers::roughness`] at twice that slope.
    /// Where the octave above is already steep, hillslopes near their threshold angle cannot
    /// steepen in proportion at the next octave, so the steep ranges keep less of it (the
    /// plain `roughness`); gentle ranges, low hills and plains keep more. One ratio for both
    /// left the detail of low ranges and plains too weak (band energy 0.54 and 0.74 of the
    /// truth's on the held-out Karatau and steppe crops). 0: off.
    pub gentle_roughness: f32,
    /// The finest-octave slope (RMS per cell, m/m) up to which [`Levers::gentle_roughness`]
    /// applies fully.
    pub gentle_slope: f32,
    /// When above 0: the roughness of primitives whose parent's finest octave is flatter still —
    /// its slope at most [`Levers::plains_slope`] — ramping linearly to the roughness
    /// [`Levers::gentle_roughness`] and [`Levers::roughness`] give at twice that slope. Plains
    /// and low hills take the gentle roughness alike, and their parents do not tell them apart
    /// (README, *Why Karatau and the steppe move together*); the flattest octaves are the
    /// plains'. 0: off. The served amplifier takes 0.38 up to 0.016.
    pub plains_roughness: f32,
    /// The finest-octave slope (RMS per cell, m/m) up to which [`Levers::plains_roughness`]
    /// applies fully.
    pub plains_slope: f32,
    /// When above 0 (and [`Levers::roughness`] above 0), the roughness of a primitive is this
    /// factor times its matched atom's own ratio of detail RMS to finest-octave RMS (the
    /// exemplar's octave-to-detail decay where that atom was cut), instead of one ratio for every
    /// terrain: the atom is scaled so that its finest octave matches the parent's.
    pub octave_match: f32,
    /// Up-sampling kernel of the elevation's residual correction.
    pub kernel: KernelKind,
    /// Number of residual-correction passes of the elevation.
    pub passes: u32,
    /// When above 0, the reach (cells) of the channels that
    /// [`breach_pits`](crate::analysis::breach::breach_pits) gives every pit of the level's
    /// output; 0: no breaching.
    pub breach: u32,
    /// The reach of the channels of pits in flat terrain (below [`Levers::steep_slope`]), at most
    /// [`Levers::breach`]; 0 leaves them (basins of plains are real more often than not).
    pub breach_flat: u32,
    /// Breaching channels cost the volume they carve (depth times step length), so a diagonal
    /// step costs √2 times a straight one ([`BreachRule::volume`](crate::analysis::breach::BreachRule::volume));
    /// off: the depth per cell alone, which favours diagonal channels.
    pub breach_volume: bool,
    /// Rings of V-shaped banks beside every breached channel
    /// ([`widen_channels`](crate::analysis::banks::widen_channels)): ring `k` is lowered by
    /// [`Levers::bank_share`]`^k` of the trench's depth. 0: none (the one-cell trench).
    pub banks: u32,
    /// The share of a neighbour's carve depth a bank is lowered by.
    pub bank_share: f32,
    /// Share of the way down to the channel that the two corner cells of each diagonal step of a
    /// breached channel go ([`BreachRule::corner_depth`](crate::analysis::breach::BreachRule::corner_depth)),
    /// for pits steeper than [`Levers::corner_slope`]: diagonal channels widen instead of
    /// putting their power in the spectrum's diagonal wedges. 0: off (the served amplifier: on,
    /// the held-out crops' anisotropy reaches their truths' but the served mosaics' rises above
    /// 1.5; README, *Corners and block means*).
    pub corner_depth: f32,
    /// Slope (m/m, measured as [`Levers::steep_slope`]) of the pits whose channels get corners.
    pub corner_slope: f32,
    /// Share of the volume breaching carves out of each parent cell given back to the cells of
    /// that parent cell it left alone
    /// ([`restore_block_means`](crate::analysis::block_means::restore_block_means)): channels
    /// pull their blocks' means below the parent's. 0: off. The served amplifier gives back
    /// 0.15 of it, against the consistency its second atom and plains roughness cost (README,
    /// *Corners and block means*, *Where the open issues stand*).
    pub restore: f32,
    /// Slope (m/m) from a pit to the highest cell within
    /// [`RISE_REACH`](crate::analysis::breach::RISE_REACH) cells that makes the pit steep.
    pub steep_slope: f32,
    /// Multiply each atom's detail by the parent's local slope over its patch's mean slope
    /// (interpolated to the pixel, at most 3): flat valley floors get little detail, steep slopes
    /// more.
    pub slope_mod: bool,
    /// Cap on the stripes of each atom's detail: the energy of its row means (and, separately,
    /// of its column means — the parts constant along a pixel axis, where the exemplar grid's
    /// stripes live) is scaled down to at most this multiple of the share isotropic detail
    /// holds there (`1/patch` of the detail's energy before the cap). 0 removes them; infinity
    /// leaves the atoms as they are.
    pub stripe_cap: f32,
    /// Low-pass of each atom's detail toward its 3×3 binomial smoothing (0: none, 1: the whole
    /// smoothing), rescaled to its RMS before: moves the detail's energy from the pixel scale to
    /// the octave below it.
    pub detail_smooth: f32,
    /// Atoms per primitive (the sparse construction tree of Guérin et al.): the matcher's atom
    /// plus up to `sparsity − 1` more, chosen by Orthogonal Matching Pursuit on what the first
    /// leaves of the parent patch, with least-squares coefficients for all of them. 0 (the
    /// default, and what a world or `amplify` without a sparsity of its own takes): the
    /// dictionary's own `sparsity`, at least [`DEFAULT_AMPLIFY_SPARSITY`] — 2 for a constrained
    /// dictionary, whose own is 1; the second atom lifts the low ranges' band energy more than
    /// the plains' (README, *Two atoms and a plains roughness*). 1: one atom (the amplifier
    /// before sparse codes, bit for bit).
    pub sparsity: u32,
    /// Atoms a primitive chooses among (1: the best match alone): the matcher ranks the best
    /// `diversity` atoms and each primitive takes one of those scoring within
    /// [`Levers::diversity_tol`] of the best, picked by a hash of its global lattice point, so
    /// that neighbouring primitives on a uniform slope do not repeat one atom along the
    /// lattice's rows and columns. A pure function of the lattice point: windows stay invariant.
    pub diversity: u32,
    /// Score tolerance of [`Levers::diversity`]: only atoms whose full score is at least the
    /// best's minus this are candidates.
    pub diversity_tol: f32,
    /// When above 1, each primitive's detail is the mean of the details of its `mean_k` best
    /// matches (its own atom first, each at unit RMS; at most [`MAX_AMPLIFY_SPARSITY`]), rescaled
    /// to the RMS its own atom's detail would have had: the candidates' shared shape stays, what
    /// only one of them has averages out. The smooth part stays its own atom's. Replaces the
    /// sparse code's further atoms. 0 or 1: off.
    pub mean_k: u32,
}

impl Default for Levers {
    /// The served amplifier: two atoms per primitive with a constrained dictionary (the
    /// matcher's and one by OMP: [`Levers::sparsity`] 0, the dictionary's own but at least 2); detail
    /// amplitude from the parent's finest octave (0.46 of it where that octave is steep, 0.56
    /// where it is gentle, 0.38 where it is as flat as plains; no floor: with the gentle
    /// roughness the floor only cost drainage figures); Kaiser-6 correction in two passes; pits breached
    /// within 14 cells where the terrain rises at 5 % or more around them, within 2 cells on
    /// flats (longer reaches cost the upstream-area distribution: deep, narrow channels cut far
    /// through the detail steal the flow of the cells around them; on flats most closed
    /// depressions are real), each channel costed by the volume it carves (so that channels do
    /// not run along the diagonals), 0.15 of the volume they carve given back to the rest of
    /// each parent cell; each primitive's atom picked among the 8 best matches by a hash
    /// of its lattice point. The held-out suite's figures of this set and of the one before it
    /// (one atom, 0.58 and 0.8, no plains roughness, nothing given back) are in the README,
    /// *Where the open issues stand*.
    fn default() -> Self {
        Levers {
            consistent_split: false,
            parent_smooth: false,
            blend_power: 1,
            roughness: 0.46,
            floor_m: 0.0,
            gentle_roughness: 0.56,
            gentle_slope: 0.04,
            plains_roughness: 0.38,
            plains_slope: 0.016,
            octave_match: 0.0,
            kernel: KernelKind::Kaiser6,
            passes: 2,
            breach: 14,
            breach_flat: 2,
            breach_volume: true,
            banks: 0,
            bank_share: 0.5,
            corner_depth: 0.0,
            corner_slope: 0.2,
            restore: 0.15,
            steep_slope: 0.05,
            slope_mod: false,
            stripe_cap: f32::INFINITY,
            detail_smooth: 0.0,
            sparsity: 0,
            diversity: 8,
            diversity_tol: f32::INFINITY,
            mean_k: 0,
        }
    }
}

impl Levers {
    /// The amplifier served until 2026-12-07 (`--levers single`): one atom per primitive, 0.58
    /// of the finest octave where it is steep and 0.8 where it is gentle, no plains roughness,
    /// nothing of the carved volume given back; the rest as [`Levers::default`]. The README's
    /// figures measured before then with `--levers default,...` read `--levers single,...` now.
    pub fn single_atom() -> Self {
        Levers {
            roughness: 0.58,
            gentle_roughness: 0.8,
            plains_roughness: 0.0,
            restore: 0.0,
            sparsity: 1,
            ..Levers::default()
        }
    }

    /// No lever pulled: the amplifier before issue #12 (Catmull-Rom split and correction in four
    /// passes, atom smooth parts, detail scaled by the patch's relief, `α` weights, no
    /// breaching).
    pub fn baseline() -> Self {
        Levers {
            consistent_split: false,
            parent_smooth: false,
            blend_power: 1,
            roughness: 0.0,
            floor_m: 0.0,
            gentle_roughness: 0.0,
            gentle_slope: 0.04,
            plains_roughness: 0.0,
            plains_slope: 0.016,
            octave_match: 0.0,
            kernel: KernelKind::CatmullRom,
            passes: 4,
            breach: 0,
            breach_flat: 0,
            breach_volume: false,
            banks: 0,
            bank_share: 0.5,
            corner_depth: 0.0,
            corner_slope: 0.2,
            restore: 0.0,
            steep_slope: 0.0,
            slope_mod: false,
            stripe_cap: f32::INFINITY,
            detail_smooth: 0.0,
            sparsity: 1,
            diversity: 1,
            diversity_tol: f32::INFINITY,
            mean_k: 0,
        }
    }

    /// Parses a comma-separated list of changes applied in order to [`Levers::default`]:
    /// `base` (start from [`Levers::baseline`]), `default`, `single` (start from
    /// [`Levers::single_atom`]), `split`, `parent`, `slopemod`
    /// `volume` (breaching costs by volume; a leading `no-` turns a switch off), `power=P`, `rough=R`, `kernel=cr|k4|k6`,
    /// `passes=N`, `breach=N`, `flat=N` (reach of flat pits), `steep=S` (slope of steep
    /// pits), `floor=M`, `gentle=R` (roughness where the finest octave is gentle),
    /// `gentleslope=S` (its slope), `plains=R` (roughness where the finest octave is flatter
    /// still), `plainsslope=S` (its slope), `octave=G`, `stripes=F|off` (stripe cap), `dsmooth=K` (detail
    /// low-pass), `sparsity=S` (0: the dictionary's, at least 2), `diverse=K` (atoms a primitive chooses
    /// among), `within=T` (their score tolerance), `banks=N` (rings of banks beside breached
    /// channels), `share=F` (their share of the depth), `meank=K` (detail as the mean of the `K`
    /// best matches'), `corner=D` (corner depth of diagonal channel steps), `cornerslope=S`
    /// (slope of the pits whose channels get them), `restore=F` (share of the carved volume
    /// given back to each parent cell).
    pub fn parse(s: &str) -> Result<Levers, String> {
        let mut l = Levers::default();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (key, value) = match part.split_once('=') {
                Some((k, v)) => (k.trim(), Some(v.trim())),
                None => (part, None),
            };
            let (key, on) = match key.strip_prefix("no-") {
                Some(k) => (k, false),
                None => (key, true),
            };
            let num = |lo: f64, hi: f64| -> Result<f64, String> {
                let v: f64 = value
                    .ok_or_else(|| format!("`{part}`: expected {key}=VALUE"))?
                    .parse()
                    .map_err(|e| format!("`{part}`: {e}"))?;
                if (lo..=hi).contains(&v) {
                    Ok(v)
                } else {
                    Err(format!("`{part}`: {key} must lie in {lo}..={hi}"))
                }
            };
            match key {
                "base" | "baseline" => l = Levers::baseline(),
                "default" => l = Levers::default(),
                "single" => l = Levers::single_atom(),
                "split" => l.consistent_split = on,
                "parent" => l.parent_smooth = on,
                "slopemod" => l.slope_mod = on,
                "volume" => l.breach_volume = on,
                "stripes" => {
                    l.stripe_cap = match value {
                        Some("off") => f32::INFINITY,
                        _ => num(0.0, 1e6)? as f32,
                    }
                }
                "dsmooth" => l.detail_smooth = num(0.0, 1.0)? as f32,
                "floor" => l.floor_m = num(0.0, 100.0)? as f32,
                "gentle" => l.gentle_roughness = num(0.0, 4.0)? as f32,
                "gentleslope" => l.gentle_slope = num(0.0, 10.0)? as f32,
                "plains" => l.plains_roughness = num(0.0, 4.0)? as f32,
                "plainsslope" => l.plains_slope = num(0.0, 10.0)? as f32,
                "octave" => l.octave_match = num(0.0, 4.0)? as f32,
                "power" => l.blend_power = num(1.0, 8.0)? as u32,
                "rough" => l.roughness = num(0.0, 4.0)? as f32,
                "passes" => l.passes = num(0.0, 12.0)? as u32,
                "breach" => {
                    l.breach = num(0.0, 32.0)? as u32;
                    l.breach_flat = l.breach_flat.min(l.breach);
                }
                "meank" => l.mean_k = num(0.0, MAX_AMPLIFY_SPARSITY as f64)? as u32,
                "banks" => l.banks = num(0.0, 8.0)? as u32,
                "share" => l.bank_share = num(0.0, 1.0)? as f32,
                "corner" => l.corner_depth = num(0.0, 1.0)? as f32,
                "cornerslope" => l.corner_slope = num(0.0, 10.0)? as f32,
                "restore" => l.restore = num(0.0, 1.0)? as f32,
                "flat" => l.breach_flat = num(0.0, 32.0)? as u32,
                "steep" => l.steep_slope = num(0.0, 10.0)? as f32,
                "diverse" => l.diversity = num(1.0, 64.0)? as u32,
                "within" => l.diversity_tol = num(0.0, 1.0)? as f32,
                "sparsity" => l.sparsity = num(0.0, MAX_AMPLIFY_SPARSITY as f64)? as u32,
                "kernel" => {
                    l.kernel = match value {
                        Some("cr") => KernelKind::CatmullRom,
                        Some("k4") => KernelKind::Kaiser4,
                        Some("k6") => KernelKind::Kaiser6,
                        _ => return Err(format!("`{part}`: expected kernel=cr, k4 or k6")),
                    }
                }
                _ => return Err(format!("`{part}`: unknown lever")),
            }
        }
        Ok(l)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_applies_changes_in_order() {
        assert_eq!(Levers::parse("").unwrap(), Levers::default());
        assert_eq!(Levers::parse("base").unwrap(), Levers::baseline());
        // `single` is the one-atom amplifier served before the second atom: what it changes
        // back, written out here and not taken from the code under test.
        let single = Levers::parse("single").unwrap();
        assert_eq!(
            single,
            Levers::parse("sparsity=1,rough=0.58,gentle=0.8,plains=0,restore=0").unwrap()
        );
        assert_ne!(single, Levers::default());
        assert_eq!(Levers::parse("single,sparsity=2").unwrap().sparsity, 2);
        let l = Levers::parse("base, rough=0.5, kernel=k6, breach=4, split, no-split, power=3")
            .unwrap();
        assert_eq!(l.roughness, 0.5);
        assert_eq!(l.kernel, KernelKind::Kaiser6);
        assert_eq!((l.breach, l.blend_power, l.consistent_split), (4, 3, false));
        assert_eq!(l.passes, 4);
        assert_eq!(Levers::parse("octave=1.5").unwrap().octave_match, 1.5);
        assert!(Levers::default().breach_volume);
        assert!(!Levers::parse("no-volume").unwrap().breach_volume);
        assert!(Levers::parse("base,volume").unwrap().breach_volume);
        assert!(Levers::parse("octave=5").is_err());
        let c = Levers::parse("corner=0.3,cornerslope=0.1,restore=0.4").unwrap();
        assert_eq!((c.corner_depth, c.corner_slope, c.restore), (0.3, 0.1, 0.4));
        assert_eq!(Levers::parse("base").unwrap().corner_depth, 0.0);
        assert!(Levers::parse("corner=1.5").is_err());
        assert_eq!(Levers::parse("stripes=0").unwrap().stripe_cap, 0.0);
        assert!(Levers::parse("stripes=off")
            .unwrap()
            .stripe_cap
            .is_infinite());
        assert!(Levers::parse("stripes=-1").is_err());
        assert_eq!(Levers::parse("dsmooth=0.3").unwrap().detail_smooth, 0.3);
        assert_eq!(Levers::default().detail_smooth, 0.0);
        assert!(Levers::parse("dsmooth=1.5").is_err());
        assert!(Levers::parse("rough").is_err());
        assert!(Levers::parse("breach=1000").is_err());
        assert!(Levers::parse("kernel=lanczos").is_err());
        assert!(Levers::parse("warp").is_err());
        assert_eq!(Levers::parse("sparsity=3").unwrap().sparsity, 3);
        let banked = Levers::parse("banks=2,share=0.25,meank=4").unwrap();
        assert_eq!(
            (banked.banks, banked.bank_share, banked.mean_k),
            (2, 0.25, 4)
        );
        assert!(Levers::parse("banks=9").is_err());
        assert!(Levers::parse("share=1.5").is_err());
        assert!(Levers::parse("meank=9").is_err());
        assert_eq!(Levers::default().banks, 0);
        assert_eq!(Levers::default().mean_k, 0);
        assert!(Levers::parse("sparsity=9").is_err());
        let l = Levers::parse("gentle=0.7,gentleslope=0.03").unwrap();
        assert_eq!((l.gentle_roughness, l.gentle_slope), (0.7, 0.03));
        assert_eq!(Levers::parse("base").unwrap().gentle_roughness, 0.0);
        assert!(Levers::parse("gentle=5").is_err());
    }
}
