//! Instances (plants and rocks) scattered over a zoom's pixel plane: the scattering rules of a
//! world (`[[landscape.scatter]]`) and the three placement methods of the procedural texturing
//! and scattering paper — `jittered_grid` (one candidate per lattice cell, jittered, roulette
//! choice of type by density), `collision` (Poisson candidates, rejected within the minimum
//! distance of an accepted one) and `survival` (founders, then generations of seedlings within the
//! seeding radius that survive by viability and collision: natural clusters, age classes).
//!
//! **Window invariance.** Every candidate is drawn from hashes of *global* lattice coordinates
//! (positions are `(cell + u) · spacing` in global pixels, the same bits whatever the window), and
//! collisions are resolved in one global canonical order ([`resolve`]): candidates are binned in
//! cells of the minimum distance `d`; cells take four phases by the parity of their coordinates;
//! a candidate is tested, in the order (phase, cell row, cell column, hash priority), against the
//! candidates already accepted within `d`. Cells of one phase are two cells apart, so they never
//! interact: a candidate's fate depends only on the cells at most three cells away. Seedlings
//! depend on parents within the seeding radius. [`halo_px`] bounds that dependency, so
//! [`scatter`] over any window that holds the output rectangle plus the halo returns the same
//! instances, bit for bit. [`resolve_naive`] is the straightforward twin of [`resolve`] (full
//! scans instead of cell lookups), compared by property tests.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use super::{LandscapeConfig, LandscapeError};
use crate::dictionary::rng::{hash2, mix64, to_unit_f64};
use crate::math;

/// How candidates are placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// One candidate per lattice cell of `spacing_m`, jittered by `jitter` of a cell.
    JitteredGrid,
    /// Poisson candidates (one per `spacing_m²` on average) with collision rejection.
    Collision,
    /// Founders, then `generations` rounds of seeding within `seeding_radius_m` and survival.
    Survival,
}

/// A size range, metres: an instance of age class `a` of `n` takes
/// `min + (max − min) · (a + u) / n` with `u` uniform in `[0, 1)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SizeRange {
    /// Size of the youngest.
    pub min: f32,
    /// Size of the oldest.
    pub max: f32,
}

/// One scattering rule (`[[landscape.scatter]]`): what is placed, where, and how.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScatterRule {
    /// The kind (the MVT layer name): `trees`, `grass`, `rocks`…
    pub kind: String,
    /// The placement method.
    pub method: Method,
    /// Species whose density layers make the viability (summed, capped at 1); an instance's
    /// `species` is one of them, chosen by roulette in proportion to their densities.
    #[serde(default)]
    pub species: Vec<String>,
    /// Materials whose weights make the viability as well (rocks on scree); an instance on them
    /// is named after the material, or after `name` when given.
    #[serde(default)]
    pub materials: Vec<String>,
    /// The `species` of every instance of this rule instead of the chosen layer's name.
    #[serde(default)]
    pub name: Option<String>,
    /// Lattice spacing (jittered grid), mean candidate spacing (collision) or founder lattice
    /// (survival), metres.
    pub spacing_m: f32,
    /// No two instances of the rule closer than this, metres (0: no collision test).
    #[serde(default)]
    pub min_distance_m: f32,
    /// Jitter of the grid, share of a cell (0: a regular grid, 1: anywhere in the cell).
    #[serde(default = "default_jitter")]
    pub jitter: f32,
    /// Height distribution, metres.
    pub height_m: SizeRange,
    /// Crown (or rock) radius distribution, metres.
    pub radius_m: SizeRange,
    /// Age classes of `jittered_grid` and `collision` (survival: `generations + 1`).
    #[serde(default = "default_age_classes")]
    pub age_classes: u32,
    /// Survival: seed dispersal radius, metres.
    #[serde(default)]
    pub seeding_radius_m: f32,
    /// Survival: seeding rounds.
    #[serde(default = "default_generations")]
    pub generations: u32,
    /// Survival: seedlings per plant and round.
    #[serde(default = "default_seeds")]
    pub seeds: u32,
    /// Survival: share of founder lattice cells holding a founder candidate.
    #[serde(default = "default_founders")]
    pub founders: f32,
    /// Materials on which no instance stands (where their weight reaches `exclude_weight`).
    #[serde(default)]
    pub exclude_materials: Vec<String>,
    /// Weight at and above which an excluding material refuses an instance.
    #[serde(default = "default_exclude_weight")]
    pub exclude_weight: f32,
    /// Seed of every draw.
    #[serde(default)]
    pub seed: u64,
}

fn default_jitter() -> f32 {
    1.0
}
fn default_age_classes() -> u32 {
    3
}
fn default_generations() -> u32 {
    3
}
fn default_seeds() -> u32 {
    4
}
fn default_founders() -> f32 {
    0.1
}
fn default_exclude_weight() -> f32 {
    0.5
}

/// The zoom below which no instance tiles are served, unless a world says otherwise.
pub const DEFAULT_INSTANCES_MIN_ZOOM: u8 = 14;

impl ScatterRule {
    /// The age classes of this rule's instances.
    pub fn classes(&self) -> u32 {
        match self.method {
            Method::Survival => self.generations + 1,
            _ => self.age_classes,
        }
    }

    /// The names of this rule's viability layers in source order (species, then materials).
    pub fn source_names(&self) -> Vec<&str> {
        self.species
            .iter()
            .chain(&self.materials)
            .map(String::as_str)
            .collect()
    }

    /// Checks the rule against the landscape: names exist, sizes are finite and non-negative,
    /// spacing is positive, counts are bounded. Errors name the rule and the setting.
    pub fn check(&self, l: &LandscapeConfig) -> Result<(), LandscapeError> {
        let who = format!("scatter `{}`", self.kind);
        let bad = |m: String| Err(LandscapeError::Invalid(format!("{who}: {m}")));
        if !crate::names::is_valid_name(&self.kind) {
            return bad("kind must be 1–64 letters, digits, `-` or `_`".into());
        }
        if let Some(n) = &self.name {
            if !crate::names::is_valid_name(n) {
                return bad(format!(
                    "name `{n}` must be 1–64 letters, digits, `-` or `_`"
                ));
            }
        }
        if self.species.is_empty() && self.materials.is_empty() {
            return bad("names no species and no material (nothing makes its viability)".into());
        }
        for s in &self.species {
            if !l.species.iter().any(|o| &o.name == s) {
                return bad(format!("unknown species `{s}`"));
            }
        }
        for m in self.materials.iter().chain(&self.exclude_materials) {
            if !l.materials.iter().any(|o| &o.name == m) {
                return bad(format!("unknown material `{m}`"));
            }
        }
        if !(self.spacing_m.is_finite() && (1.0..=100.0).contains(&self.spacing_m)) {
            return bad(format!(
                "spacing_m {} must lie in [1, 100] metres (0 or negative spacing is refused)",
                self.spacing_m
            ));
        }
        if !(self.min_distance_m.is_finite() && (0.0..=20.0).contains(&self.min_distance_m)) {
            return bad(format!(
                "min_distance_m {} must lie in [0, 20] metres",
                self.min_distance_m
            ));
        }
        for (what, r) in [("height_m", self.height_m), ("radius_m", self.radius_m)] {
            if !(r.min.is_finite() && r.max.is_finite() && r.min >= 0.0 && r.min <= r.max) {
                return bad(format!(
                    "{what} [{}, {}] must be finite with 0 ≤ min ≤ max (a negative {what} is refused)",
                    r.min, r.max
                ));
            }
        }
        if !(self.jitter.is_finite() && (0.0..=1.0).contains(&self.jitter)) {
            return bad(format!("jitter {} must lie in [0, 1]", self.jitter));
        }
        if self.age_classes == 0 || self.age_classes > 16 {
            return bad(format!(
                "age_classes {} must lie in 1..=16",
                self.age_classes
            ));
        }
        if !(self.exclude_weight.is_finite() && (0.0..=1.0).contains(&self.exclude_weight)) {
            return bad(format!(
                "exclude_weight {} must lie in [0, 1]",
                self.exclude_weight
            ));
        }
        if self.method == Method::Survival {
            if !(self.seeding_radius_m.is_finite()
                && self.seeding_radius_m > 0.0
                && self.seeding_radius_m <= 50.0)
            {
                return bad(format!(
                    "seeding_radius_m {} must lie in (0, 50] metres (a negative radius is refused)",
                    self.seeding_radius_m
                ));
            }
            if self.min_distance_m <= 0.0 {
                return bad("survival needs min_distance_m > 0 (it bounds the clusters)".into());
            }
            if self.generations == 0 || self.generations > 6 {
                return bad(format!(
                    "generations {} must lie in 1..=6",
                    self.generations
                ));
            }
            if self.seeds == 0 || self.seeds > 16 {
                return bad(format!("seeds {} must lie in 1..=16", self.seeds));
            }
            if !(self.founders.is_finite() && self.founders > 0.0 && self.founders <= 1.0) {
                return bad(format!("founders {} must lie in (0, 1]", self.founders));
            }
        } else if !(self.seeding_radius_m.is_finite() && self.seeding_radius_m >= 0.0) {
            return bad(format!(
                "seeding_radius_m {} must be ≥ 0",
                self.seeding_radius_m
            ));
        }
        Ok(())
    }
}

/// Checks the scattering rules of a landscape (names resolve, settings in range) and the zoom
/// instance tiles start at.
pub fn check_rules(l: &LandscapeConfig) -> Result<(), LandscapeError> {
    if l.scatter.len() > 32 {
        return Err(LandscapeError::Invalid(format!(
            "{} scatter rules (at most 32)",
            l.scatter.len()
        )));
    }
    for r in &l.scatter {
        r.check(l)?;
    }
    Ok(())
}

/// One placed instance, in global pixels of its zoom.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Column, global pixels (fractional).
    pub x: f64,
    /// Row, global pixels (fractional).
    pub y: f64,
    /// Index of the viability layer it was chosen from (into [`ScatterRule::source_names`]).
    pub source: usize,
    /// Height, metres.
    pub height_m: f32,
    /// Crown or rock radius, metres.
    pub radius_m: f32,
    /// Rotation about the vertical, degrees clockwise from north, `[0, 360)`.
    pub rotation_deg: f32,
    /// Age class (0 the youngest).
    pub age: u32,
}

/// The per-pixel inputs of one rule over a window of the zoom's plane: its viability layers
/// (in [`ScatterRule::source_names`] order) and its excluding materials' weights.
#[derive(Clone, Copy, Debug)]
pub struct RuleField<'a> {
    /// Global row of the window's first row.
    pub row0: i64,
    /// Global column of the window's first column.
    pub col0: i64,
    /// Viability layers, 0–1 each.
    pub sources: &'a [&'a Array2<f32>],
    /// Weights of the excluding materials.
    pub exclude: &'a [&'a Array2<f32>],
    /// Weight at and above which an excluding material refuses an instance.
    pub exclude_weight: f32,
}

impl RuleField<'_> {
    /// The pixel holding global point `(x, y)`, if it lies in the window.
    fn pixel(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let (c, r) = (x.floor() as i64 - self.col0, y.floor() as i64 - self.row0);
        let (rows, cols) = self.sources.first()?.dim();
        (r >= 0 && c >= 0 && (r as usize) < rows && (c as usize) < cols)
            .then_some((r as usize, c as usize))
    }

    /// Viability at `(x, y)` and the source a roulette draw `u` in `[0, 1)` picks (0 outside
    /// the window or on excluded ground).
    pub fn viability(&self, x: f64, y: f64, u: f64) -> (f32, usize) {
        let Some(p) = self.pixel(x, y) else {
            return (0.0, 0);
        };
        if self.exclude.iter().any(|m| m[p] >= self.exclude_weight) {
            return (0.0, 0);
        }
        let total: f32 = self.sources.iter().map(|s| s[p].max(0.0)).sum();
        if total <= 0.0 || !total.is_finite() {
            return (0.0, 0);
        }
        let target = u * f64::from(total);
        let mut acc = 0.0f64;
        let mut pick = self.sources.len() - 1;
        for (k, s) in self.sources.iter().enumerate() {
            acc += f64::from(s[p].max(0.0));
            if target < acc {
                pick = k;
                break;
            }
        }
        (total.min(1.0), pick)
    }
}

/// A candidate of the collision test: position, canonical priority and whether it is viable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Global column, pixels.
    pub x: f64,
    /// Global row, pixels.
    pub y: f64,
    /// Identity hash: the priority inside a cell (then the position bits break ties).
    pub id: u64,
}

/// The canonical order key of a candidate for resolution cells of size `d` pixels: phase (the
/// parity of the cell coordinates), cell row, cell column, id, position bits.
fn order_key(c: &Candidate, d: f64) -> (u8, i64, i64, u64, u64, u64) {
    let (ci, cj) = cell_of(c, d);
    let phase = (ci.rem_euclid(2) + 2 * cj.rem_euclid(2)) as u8;
    (phase, cj, ci, c.id, c.x.to_bits(), c.y.to_bits())
}

/// A multiply-rotate hasher (the Fx hash) for the maps of [`resolve`] and `place`, keyed by
/// lattice cells and candidate bits: their keys come from the world's own lattice, not from a
/// client, so SipHash's resistance to chosen keys buys nothing there, and it was a sixth of the
/// scattering's time. Only lookups read the maps, never their order, so the hasher cannot change
/// a result.
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, word: i64) {
        self.write_u64(word as u64);
    }
}

/// A hash map with [`CellHasher`].
type CellMap<K, V> = HashMap<K, V, BuildHasherDefault<CellHasher>>;

fn cell_of(c: &Candidate, d: f64) -> (i64, i64) {
    ((c.x / d).floor() as i64, (c.y / d).floor() as i64)
}

fn too_close(a: &Candidate, b: &Candidate, d: f64) -> bool {
    let (dx, dy) = (a.x - b.x, a.y - b.y);
    dx * dx + dy * dy < d * d
}

/// Collision resolution in the canonical order (see the module doc): `cands` (all viable) are
/// tested against `older` (accepted before, all kept) and the candidates accepted before them;
/// returns the accepted ones in canonical order. `d ≤ 0` accepts everything (in input order).
pub fn resolve(cands: &[Candidate], older: &[Candidate], d: f64) -> Vec<Candidate> {
    if d <= 0.0 {
        return cands.to_vec();
    }
    let mut order: Vec<&Candidate> = cands.iter().collect();
    // Each key once (two divisions and floors), not per comparison; stable, as `sort_by_key`.
    order.sort_by_cached_key(|c| order_key(c, d));
    let mut bins: CellMap<(i64, i64), Vec<Candidate>> = CellMap::default();
    for o in older {
        bins.entry(cell_of(o, d)).or_default().push(*o);
    }
    let mut out = Vec::new();
    for c in order {
        let (ci, cj) = cell_of(c, d);
        let blocked = (-1..=1).any(|dj| {
            (-1..=1).any(|di| {
                bins.get(&(ci + di, cj + dj))
                    .is_some_and(|v| v.iter().any(|o| too_close(o, c, d)))
            })
        });
        if !blocked {
            bins.entry((ci, cj)).or_default().push(*c);
            out.push(*c);
        }
    }
    out
}

/// The naive twin of [`resolve`]: the same canonical order, every test a full scan of the
/// accepted list.
pub fn resolve_naive(cands: &[Candidate], older: &[Candidate], d: f64) -> Vec<Candidate> {
    if d <= 0.0 {
        return cands.to_vec();
    }
    let mut order: Vec<Candidate> = cands.to_vec();
    order.sort_by_key(|c| order_key(c, d));
    let mut kept: Vec<Candidate> = older.to_vec();
    let mut out = Vec::new();
    for c in order {
        if !kept.iter().any(|o| too_close(o, &c, d)) {
            kept.push(c);
            out.push(c);
        }
    }
    out
}

/// How far (pixels) outside an output rectangle the inputs of [`scatter`] must reach for its
/// instances to be exact: the candidate lattice cell, five resolution cells per collision round
/// and, for survival, the seeding radius per generation.
pub fn halo_px(rule: &ScatterRule, cell_m: f64) -> f64 {
    let c = f64::from(rule.spacing_m) / cell_m;
    let d = f64::from(rule.min_distance_m) / cell_m;
    let round = 5.0 * d;
    let mut h = c + round + 2.0;
    if rule.method == Method::Survival {
        let r = f64::from(rule.seeding_radius_m) / cell_m;
        h += f64::from(rule.generations) * (r + round);
    }
    h.ceil()
}

/// A uniform draw in `[0, 1)` from a hash and a stream number.
fn unit(h: u64, stream: u64) -> f64 {
    to_unit_f64(mix64(h ^ mix64(stream.wrapping_add(0x5CA7_7E55))))
}

/// The number of Poisson(1) events a uniform draw `u` gives (inverse CDF, at most 8).
fn poisson1(u: f64) -> u32 {
    let mut p = math::exp(-1.0f64);
    let mut cdf = p;
    let mut k = 0;
    while u >= cdf && k < 8 {
        k += 1;
        p /= f64::from(k);
        cdf += p;
    }
    k
}

/// An accepted candidate with what it carries.
#[derive(Clone, Copy, Debug)]
struct Placed {
    c: Candidate,
    source: usize,
    age: u32,
}

/// The instances of `rule` whose position lies in the rectangle `[x0, x1) × [y0, y1)` of global
/// pixels, on a zoom whose pixels measure `cell_m` metres, with `seed` the rule's seed (the
/// world's rule index mixed in by the caller). `field` must cover the rectangle plus
/// [`halo_px`]; then the result does not depend on the field's window, bit for bit. Instances
/// come sorted by (row, column) bits.
pub fn scatter(
    rule: &ScatterRule,
    seed: u64,
    cell_m: f64,
    field: &RuleField<'_>,
    rect: [f64; 4],
) -> Vec<Instance> {
    let [x0, y0, x1, y1] = rect;
    let halo = halo_px(rule, cell_m);
    let (qx0, qy0, qx1, qy1) = (x0 - halo, y0 - halo, x1 + halo, y1 + halo);
    let c = f64::from(rule.spacing_m) / cell_m;
    let d = f64::from(rule.min_distance_m) / cell_m;
    let seed = hash2(rule.seed, seed as i64, 0x5CA7);
    let (i0, i1) = ((qx0 / c).floor() as i64, (qx1 / c).floor() as i64);
    let (j0, j1) = ((qy0 / c).floor() as i64, (qy1 / c).floor() as i64);
    let classes = rule.classes();
    // Lattice candidates (survival: the founders), viable ones only.
    let mut cands: Vec<(Candidate, usize)> = Vec::new();
    for j in j0..=j1 {
        for i in i0..=i1 {
            let h = hash2(seed, i, j);
            let n = match rule.method {
                Method::JitteredGrid => 1,
                Method::Collision => poisson1(unit(h, 0)),
                Method::Survival => u32::from(unit(h, 0) < f64::from(rule.founders)),
            };
            for k in 0..n {
                let hk = mix64(h ^ u64::from(k).wrapping_mul(0x9E37_79B9));
                let (x, y) = match rule.method {
                    Method::JitteredGrid => {
                        let jit = f64::from(rule.jitter);
                        (
                            (i as f64 + 0.5 + jit * (unit(hk, 1) - 0.5)) * c,
                            (j as f64 + 0.5 + jit * (unit(hk, 2) - 0.5)) * c,
                        )
                    }
                    _ => ((i as f64 + unit(hk, 1)) * c, (j as f64 + unit(hk, 2)) * c),
                };
                let (v, source) = field.viability(x, y, unit(hk, 3));
                if unit(hk, 4) < f64::from(v) {
                    cands.push((Candidate { x, y, id: hk }, source));
                }
            }
        }
    }
    let mut placed = place(&cands, &[], d, 0);
    if rule.method == Method::Survival {
        let g_max = rule.generations;
        for p in &mut placed {
            p.age = g_max;
        }
        let r = f64::from(rule.seeding_radius_m) / cell_m;
        for g in 1..=g_max {
            let mut seedlings = Vec::new();
            for p in &placed {
                for s in 0..rule.seeds {
                    let h = mix64(p.c.id ^ mix64(u64::from(g) << 32 | u64::from(s)));
                    let (rho, theta) = (r * unit(h, 5).sqrt(), std::f64::consts::TAU * unit(h, 6));
                    let (x, y) = (
                        p.c.x + rho * math::cos(theta),
                        p.c.y + rho * math::sin(theta),
                    );
                    if x < qx0 || x >= qx1 || y < qy0 || y >= qy1 {
                        continue;
                    }
                    let (v, source) = field.viability(x, y, unit(h, 3));
                    if unit(h, 4) < f64::from(v) {
                        seedlings.push((Candidate { x, y, id: h }, source));
                    }
                }
            }
            let older: Vec<Candidate> = placed.iter().map(|p| p.c).collect();
            let born = place(&seedlings, &older, d, g_max - g);
            placed.extend(born);
        }
    }
    let mut out: Vec<Instance> = placed
        .into_iter()
        .filter(|p| p.c.x >= x0 && p.c.x < x1 && p.c.y >= y0 && p.c.y < y1)
        .map(|p| {
            let h = p.c.id;
            let age = if rule.method == Method::Survival {
                p.age
            } else {
                ((unit(h, 7) * f64::from(classes)) as u32).min(classes - 1)
            };
            let f = ((f64::from(age) + unit(h, 8)) / f64::from(classes)) as f32;
            let size = |s: SizeRange| s.min + (s.max - s.min) * f;
            Instance {
                x: p.c.x,
                y: p.c.y,
                source: p.source,
                height_m: size(rule.height_m),
                radius_m: size(rule.radius_m),
                rotation_deg: (unit(h, 9) * 360.0) as f32,
                age,
            }
        })
        .collect();
    out.sort_by_key(|i| (i.y.to_bits(), i.x.to_bits()));
    out
}

/// Resolves `cands` against `older` and keeps each accepted candidate's source, with age `age`.
fn place(cands: &[(Candidate, usize)], older: &[Candidate], d: f64, age: u32) -> Vec<Placed> {
    let only: Vec<Candidate> = cands.iter().map(|(c, _)| *c).collect();
    let source: CellMap<(u64, u64, u64), usize> = cands
        .iter()
        .map(|(c, s)| ((c.id, c.x.to_bits(), c.y.to_bits()), *s))
        .collect();
    resolve(&only, older, d)
        .into_iter()
        .map(|c| Placed {
            source: source
                .get(&(c.id, c.x.to_bits(), c.y.to_bits()))
                .copied()
                .unwrap_or(0),
            age,
            c,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rule(method: Method) -> ScatterRule {
        ScatterRule {
            kind: "trees".into(),
            method,
            species: vec!["a".into()],
            materials: vec![],
            name: None,
            spacing_m: 10.0,
            min_distance_m: 3.0,
            jitter: 0.5,
            height_m: SizeRange {
                min: 2.0,
                max: 20.0,
            },
            radius_m: SizeRange { min: 0.5, max: 4.0 },
            age_classes: 3,
            seeding_radius_m: 12.0,
            generations: 3,
            seeds: 4,
            founders: 0.05,
            exclude_materials: vec![],
            exclude_weight: 0.5,
            seed: 3,
        }
    }

    /// Scatter over `rect` with a density field `dens(col, row)` on the window `rect` + `extra`
    /// pixels.
    fn run(
        r: &ScatterRule,
        cell_m: f64,
        rect: [f64; 4],
        extra: i64,
        dens: impl Fn(i64, i64) -> f32,
    ) -> Vec<Instance> {
        let h = halo_px(r, cell_m) as i64 + extra;
        let (c0, r0) = (rect[0].floor() as i64 - h, rect[1].floor() as i64 - h);
        let (c1, r1) = (rect[2].ceil() as i64 + h, rect[3].ceil() as i64 + h);
        let a = Array2::from_shape_fn(((r1 - r0) as usize, (c1 - c0) as usize), |(y, x)| {
            dens(c0 + x as i64, r0 + y as i64)
        });
        let sources = [&a];
        let f = RuleField {
            row0: r0,
            col0: c0,
            sources: &sources,
            exclude: &[],
            exclude_weight: 0.5,
        };
        scatter(r, 0, cell_m, &f, rect)
    }

    fn min_pair_distance(p: &[Instance]) -> f64 {
        let mut m = f64::INFINITY;
        for (k, a) in p.iter().enumerate() {
            for b in &p[k + 1..] {
                m = m.min(((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt());
            }
        }
        m
    }

    /// The Clark–Evans ratio: the mean nearest-neighbour distance over its expectation for a
    /// Poisson process of the same intensity, `0.5 / sqrt(n / area)`, from points inside the
    /// inner square `[m, s − m]²` (neighbours searched among all points: no edge bias).
    fn clark_evans(p: &[Instance], s: f64, m: f64) -> f64 {
        let inner: Vec<&Instance> = p
            .iter()
            .filter(|a| a.x >= m && a.x < s - m && a.y >= m && a.y < s - m)
            .collect();
        let mut sum = 0.0;
        for a in &inner {
            let nn = p
                .iter()
                .filter(|b| !std::ptr::eq(*a, *b))
                .map(|b| ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            sum += nn;
        }
        let n = inner.len() as f64;
        let area = (s - 2.0 * m).powi(2);
        (sum / n) / (0.5 / (n / area).sqrt())
    }

    #[test]
    fn clark_evans_orders_the_methods_on_flat_ground() {
        let s = 1200.0;
        let flat = |_, _| 0.6f32;
        let cell_m = 1.0;
        let grid = run(
            &rule(Method::JitteredGrid),
            cell_m,
            [0.0, 0.0, s, s],
            0,
            flat,
        );
        let mut col = rule(Method::Collision);
        col.spacing_m = 12.0;
        col.min_distance_m = 1.0;
        let coll = run(&col, cell_m, [0.0, 0.0, s, s], 0, flat);
        let surv = run(&rule(Method::Survival), cell_m, [0.0, 0.0, s, s], 0, flat);
        let (rg, rc, rs) = (
            clark_evans(&grid, s, 60.0),
            clark_evans(&coll, s, 60.0),
            clark_evans(&surv, s, 60.0),
        );
        assert!(grid.len() > 3000 && coll.len() > 3000 && surv.len() > 2000);
        assert!(rg > 1.1, "jittered grid R = {rg}");
        assert!((rc - 1.0).abs() < 0.1, "collision R = {rc}");
        assert!(rs < 0.9, "survival R = {rs}");
    }

    #[test]
    fn a_rectangle_alone_is_the_same_window_of_a_larger_one() {
        let dens =
            |c: i64, r: i64| (math::sinf(c as f32 * 0.013) * math::cosf(r as f32 * 0.011)).max(0.0);
        for m in [Method::JitteredGrid, Method::Collision, Method::Survival] {
            let r = rule(m);
            let big = run(&r, 1.5, [-300.0, 200.0, 468.0, 968.0], 7, dens);
            let alone = run(&r, 1.5, [-44.0, 456.0, 212.0, 712.0], 0, dens);
            let window: Vec<Instance> = big
                .iter()
                .filter(|i| i.x >= -44.0 && i.x < 212.0 && i.y >= 456.0 && i.y < 712.0)
                .copied()
                .collect();
            assert!(!alone.is_empty(), "{m:?}");
            assert_eq!(alone, window, "{m:?}");
            assert!(min_pair_distance(&big) >= 3.0 / 1.5, "{m:?}");
        }
    }

    #[test]
    fn instances_only_where_the_density_is_positive() {
        let dens = |c: i64, _r: i64| if c.rem_euclid(64) < 20 { 0.0 } else { 0.9 };
        for m in [Method::JitteredGrid, Method::Collision, Method::Survival] {
            let p = run(&rule(m), 1.0, [0.0, 0.0, 400.0, 400.0], 0, dens);
            assert!(!p.is_empty());
            assert!(
                p.iter().all(|i| (i.x.floor() as i64).rem_euclid(64) >= 20),
                "{m:?}"
            );
            for i in &p {
                assert!(i.height_m >= 2.0 && i.height_m <= 20.0 && i.rotation_deg < 360.0);
                assert!(i.age < rule(m).classes());
            }
        }
    }

    #[test]
    fn bad_rules_are_refused_by_name() {
        let mut l = LandscapeConfig::tienshan();
        let mut r = rule(Method::Survival);
        r.species = vec!["spruce".into()];
        l.scatter = vec![r.clone()];
        check_rules(&l).unwrap();
        let cases: Vec<(ScatterRule, &str)> = vec![
            (
                ScatterRule {
                    seeding_radius_m: -1.0,
                    ..r.clone()
                },
                "seeding_radius_m",
            ),
            (
                ScatterRule {
                    radius_m: SizeRange {
                        min: -1.0,
                        max: 2.0,
                    },
                    ..r.clone()
                },
                "radius_m",
            ),
            (
                ScatterRule {
                    species: vec!["oak".into()],
                    ..r.clone()
                },
                "unknown species `oak`",
            ),
            (
                ScatterRule {
                    spacing_m: 0.0,
                    ..r.clone()
                },
                "spacing_m",
            ),
            (
                ScatterRule {
                    exclude_materials: vec!["lava".into()],
                    ..r.clone()
                },
                "unknown material `lava`",
            ),
        ];
        for (bad, want) in cases {
            l.scatter = vec![bad];
            let e = check_rules(&l).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("scatter `trees`"), "{e}");
        }
    }

    proptest! {
        #[test]
        fn resolve_equals_its_naive_twin(
            pts in prop::collection::vec((-50.0f64..50.0, -50.0f64..50.0, any::<u64>()), 0..120),
            old in prop::collection::vec((-50.0f64..50.0, -50.0f64..50.0, any::<u64>()), 0..20),
            d in 0.5f64..12.0,
        ) {
            let c = |v: &Vec<(f64, f64, u64)>| -> Vec<Candidate> {
                v.iter().map(|&(x, y, id)| Candidate { x, y, id }).collect()
            };
            let (cands, older) = (c(&pts), c(&old));
            let fast = resolve(&cands, &older, d);
            prop_assert_eq!(&fast, &resolve_naive(&cands, &older, d));
            // No accepted pair, nor accepted and older, closer than d; every rejected
            // candidate has an accepted or older one within d (maximal).
            let all: Vec<&Candidate> = fast.iter().chain(&older).collect();
            for (k, a) in fast.iter().enumerate() {
                for b in all.iter().skip(k + 1) {
                    prop_assert!(!too_close(a, b, d));
                }
            }
            for c in &cands {
                if !fast.contains(c) {
                    prop_assert!(all.iter().any(|o| too_close(o, c, d)));
                }
            }
        }
    }
}
