//! The landscape configuration of a world (`[landscape]` in its TOML file): vegetation species
//! with their niches, the seeding simulation, the materials of the splat and colour maps, and the
//! drainage overlay style. A world without a `[landscape]` section gets the default world's
//! (parsed from the embedded `config/worlds/tienshan.toml`, so the defaults are configuration,
//! not code constants).
//!
//! Parameters and their units: `elevation` metres, `slope` degrees, `northness` cos(aspect) in
//! [−1, 1], `curvature` 1/m (negative Laplacian: > 0 on ridges), `wetness` log10 of the upstream
//! area in m², vegetation densities 0–1 by species name.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::scatter::{ScatterRule, DEFAULT_INSTANCES_MIN_ZOOM};
use super::LandscapeError;
use crate::math;

/// A smooth trapezoid weight curve: 0 outside `[min, max]`, 1 on `[min + falloff, max − falloff]`,
/// and a smoothstep `t²(3 − 2t)` on the two falloff bands (the falloff is capped at half the
/// range, so a zero-width plateau is a smooth bump).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trapezoid {
    /// Lower end of the range (weight 0 at and below).
    pub min: f32,
    /// Upper end of the range (weight 0 at and above).
    pub max: f32,
    /// Width of each smooth band inside the range (0: a box).
    #[serde(default)]
    pub falloff: f32,
}

impl Trapezoid {
    /// The weight of `x` (0 for NaN).
    pub fn weight(&self, x: f32) -> f32 {
        if !(x > self.min && x < self.max) {
            // Outside, on the ends, or NaN. A box (no falloff) includes its ends.
            if self.falloff <= 0.0 && x >= self.min && x <= self.max {
                return 1.0;
            }
            return 0.0;
        }
        let f = self.falloff.min(0.5 * (self.max - self.min));
        if f <= 0.0 {
            return 1.0;
        }
        let t = ((x - self.min) / f).min((self.max - x) / f).min(1.0);
        t * t * (3.0 - 2.0 * t)
    }

    fn check(&self, what: &str) -> Result<(), LandscapeError> {
        let ok = self.min.is_finite()
            && self.max.is_finite()
            && self.falloff.is_finite()
            && self.min <= self.max
            && self.falloff >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(LandscapeError::Invalid(format!(
                "{what}: range [{}, {}] with falloff {} must be finite with min ≤ max, falloff ≥ 0",
                self.min, self.max, self.falloff
            )))
        }
    }
}

/// One vegetation species (or cover type) and its niche: the product of the weight curves of
/// the parameters it names (an absent parameter does not constrain).
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Species {
    /// Layer name (letters, digits, `_`, `-`); also the EXR channel name.
    pub name: String,
    /// Overlay colour `[r, g, b]`.
    #[serde(default = "default_species_colour")]
    pub colour: [u8; 3],
    /// Altitude, metres.
    #[serde(default)]
    pub elevation: Option<Trapezoid>,
    /// Slope, degrees.
    #[serde(default)]
    pub slope: Option<Trapezoid>,
    /// Northness, −1..1.
    #[serde(default)]
    pub northness: Option<Trapezoid>,
    /// Wetness, log10 of the upstream area in m².
    #[serde(default)]
    pub wetness: Option<Trapezoid>,
    /// Land-cover class weights by class name (`class.<name>`), as for materials; they apply
    /// where a world gives class weights (dictionary builds, which have none, ignore them).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub class: BTreeMap<String, Trapezoid>,
    /// Painted biome weights by biome name (`biome.<name>`: the biome's normalised weight,
    /// 0–1), as for materials; the world must have those biomes.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub biome: BTreeMap<String, Trapezoid>,
}

// `Debug` by hand: as derived, with `class` only when it is not empty, so the text of a species
// or material without class terms is what it was before classes — world fingerprints (ETags) and
// configured worlds' dictionary aliases hash it.
impl std::fmt::Debug for Species {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("Species");
        d.field("name", &self.name)
            .field("colour", &self.colour)
            .field("elevation", &self.elevation)
            .field("slope", &self.slope)
            .field("northness", &self.northness)
            .field("wetness", &self.wetness);
        if !self.class.is_empty() {
            d.field("class", &self.class);
        }
        if !self.biome.is_empty() {
            d.field("biome", &self.biome);
        }
        d.finish()
    }
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("Material");
        d.field("name", &self.name)
            .field("colour", &self.colour)
            .field("elevation", &self.elevation)
            .field("slope", &self.slope)
            .field("northness", &self.northness)
            .field("curvature", &self.curvature)
            .field("wetness", &self.wetness)
            .field("vegetation", &self.vegetation);
        if !self.class.is_empty() {
            d.field("class", &self.class);
        }
        if !self.biome.is_empty() {
            d.field("biome", &self.biome);
        }
        d.field("spread", &self.spread)
            .field("spread_scale_m", &self.spread_scale_m)
            .finish()
    }
}

fn default_species_colour() -> [u8; 3] {
    [40, 140, 60]
}

/// The seeding/survival simulation (method 4) that turns niche suitability into patchy
/// densities: `density = suitability · (floor + (1 − floor) · cluster)`, where `cluster` is the
/// local fraction of occupied cells after `iterations` rounds of seeding near occupied cells and
/// survival, all drawn from hashes of global cell coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Clustering {
    /// Seed of every draw.
    pub seed: u64,
    /// Seeding rounds.
    pub iterations: u32,
    /// Seed dispersal (and final smoothing) radius, cells.
    pub radius: u32,
    /// Share of the suitability kept whatever the clusters (0: fully patchy, 1: no patches).
    pub floor: f32,
}

impl Default for Clustering {
    fn default() -> Self {
        Clustering {
            seed: 1,
            iterations: 4,
            radius: 2,
            floor: 0.5,
        }
    }
}

/// One material of the splat and colour maps: its weight is the product of the weight curves of
/// the parameters it names, times `1 + spread · n` with `n` a deterministic value noise in
/// [−1, 1] of wavelength `spread_scale_m` (so a weight is 0 wherever any of its ranges excludes
/// the pixel).
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Name.
    pub name: String,
    /// Colour `[r, g, b]` of the colour map.
    pub colour: [u8; 3],
    /// Altitude, metres.
    #[serde(default)]
    pub elevation: Option<Trapezoid>,
    /// Slope, degrees.
    #[serde(default)]
    pub slope: Option<Trapezoid>,
    /// Northness, −1..1.
    #[serde(default)]
    pub northness: Option<Trapezoid>,
    /// Curvature, 1/m.
    #[serde(default)]
    pub curvature: Option<Trapezoid>,
    /// Wetness, log10 m².
    #[serde(default)]
    pub wetness: Option<Trapezoid>,
    /// Vegetation densities by species name.
    #[serde(default)]
    pub vegetation: BTreeMap<String, Trapezoid>,
    /// Land-cover class weights by class name (`class.<name>`: 1 inside the class, 0 outside,
    /// smoothed over the world's `classes.smoothing_m`); the world must define those classes.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub class: BTreeMap<String, Trapezoid>,
    /// Painted biome weights by biome name (`biome.<name>`: the biome's weight normalised over
    /// the world's biomes, 0–1); the world must have those biomes.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub biome: BTreeMap<String, Trapezoid>,
    /// Amplitude of the noise modulation, 0..1 (0: none).
    #[serde(default)]
    pub spread: f32,
    /// Wavelength of the noise, metres (Web Mercator metres).
    #[serde(default = "default_spread_scale")]
    pub spread_scale_m: f32,
}

fn default_spread_scale() -> f32 {
    2000.0
}

/// How the drainage PNG overlay is drawn, in `colour`: transparent below `png_min_m2`; from
/// there the opacity rises linearly in log10 area from `png_min_opacity` to opaque at
/// `png_max_m2` ([`DrainageStyle::alpha_ramp`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DrainageStyle {
    /// Upstream area (m²) below which the overlay is transparent: the smallest channel drawn.
    pub png_min_m2: f64,
    /// Upstream area (m²) at and above which it is opaque.
    pub png_max_m2: f64,
    /// Opacity (0–1) of the smallest channel drawn (`png_min_m2`), so that the headwater
    /// streams a deep zoom shows are visible, not only the rivers that drain large basins.
    /// 0 makes it fade in from transparent.
    pub png_min_opacity: f64,
    /// River colour `[r, g, b]`.
    pub colour: [u8; 3],
}

impl Default for DrainageStyle {
    fn default() -> Self {
        DrainageStyle {
            png_min_m2: 1e6,
            png_max_m2: 1e10,
            png_min_opacity: 0.4,
            colour: [30, 100, 230],
        }
    }
}

impl DrainageStyle {
    /// The overlay's alpha (0–255) as a function of a pixel's upstream area in m² (0, negative
    /// or NaN: transparent), its constants worked out once for a whole tile.
    pub fn alpha_ramp(&self) -> impl Fn(f32) -> u8 {
        let (min, floor) = (self.png_min_m2, self.png_min_opacity);
        let (lo, hi) = (math::log10(min), math::log10(self.png_max_m2));
        move |area_m2| {
            let area = f64::from(area_m2);
            if area.is_nan() || area < min {
                return 0;
            }
            let t = ((math::log10(area) - lo) / (hi - lo)).clamp(0.0, 1.0);
            ((floor + (1.0 - floor) * t) * 255.0).round() as u8
        }
    }
}

/// The `[landscape]` section of a world file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LandscapeConfig {
    /// Vegetation species (at most 64).
    pub species: Vec<Species>,
    /// Seeding simulation.
    pub clustering: Clustering,
    /// Suitability at and above which synthesized densities are kept whole; below it they fade
    /// smoothly to 0 at suitability 0 (the viability step on the served terrain, applied after
    /// the niche has moved density among each parent pixel's children).
    pub viability: f32,
    /// Materials of the splat and colour maps (at least 1, at most 64), in splat order.
    pub materials: Vec<Material>,
    /// Material that takes a pixel no material's ranges admit (default: the first).
    pub fallback_material: Option<String>,
    /// Drainage overlay style.
    pub drainage: DrainageStyle,
    /// Scattering rules of the instance tiles (`[[landscape.scatter]]`).
    pub scatter: Vec<ScatterRule>,
    /// Shallowest zoom with instance tiles (default 14; they go up to `max_zoom`).
    pub instances_min_zoom: u8,
}

impl Default for LandscapeConfig {
    fn default() -> Self {
        LandscapeConfig {
            species: Vec::new(),
            clustering: Clustering::default(),
            viability: 0.2,
            materials: vec![Material {
                name: "ground".into(),
                colour: [150, 140, 120],
                elevation: None,
                slope: None,
                northness: None,
                curvature: None,
                wetness: None,
                vegetation: BTreeMap::new(),
                class: BTreeMap::new(),
                biome: BTreeMap::new(),
                spread: 0.0,
                spread_scale_m: default_spread_scale(),
            }],
            fallback_material: None,
            drainage: DrainageStyle::default(),
            scatter: Vec::new(),
            instances_min_zoom: DEFAULT_INSTANCES_MIN_ZOOM,
        }
    }
}

/// Only the `[landscape]` section of a world file.
#[derive(Deserialize)]
struct Section {
    #[serde(default)]
    landscape: Option<LandscapeConfig>,
}

/// The checks a species and a material share: `(kind, name)` is a valid name not among
/// `earlier` (the names of the items of its kind before it), and its named terms `fixed` and its
/// keyed terms `keyed` (`class.<name>`, `biome.<name>`) are valid ranges.
fn check_niche_item<'a>(
    (kind, name): (&str, &str),
    mut earlier: impl Iterator<Item = &'a String>,
    fixed: &[(&str, Option<Trapezoid>)],
    keyed: [(&str, &BTreeMap<String, Trapezoid>); 2],
) -> Result<(), LandscapeError> {
    if !crate::names::is_valid_name(name) || earlier.any(|o| o == name) {
        return Err(LandscapeError::Invalid(format!(
            "{kind} name `{name}` is invalid or repeated"
        )));
    }
    for (term, t) in fixed {
        if let Some(t) = t {
            t.check(&format!("{kind} {name} {term}"))?;
        }
    }
    for (prefix, terms) in keyed {
        for (key, t) in terms {
            t.check(&format!("{kind} {name} {prefix}.{key}"))?;
        }
    }
    Ok(())
}

impl LandscapeConfig {
    /// The default world's landscape (the `[landscape]` section of the embedded
    /// `config/worlds/tienshan.toml`); [`LandscapeConfig::default`] if it cannot be read.
    pub fn tienshan() -> Self {
        toml::from_str::<Section>(crate::assets::TIENSHAN_WORLD_TOML)
            .ok()
            .and_then(|s| s.landscape)
            .unwrap_or_default()
    }

    /// Checks names, ranges and counts.
    pub fn validate(&self) -> Result<(), LandscapeError> {
        let bad = |m: String| Err(LandscapeError::Invalid(m));
        if self.species.len() > 64 {
            return bad(format!("{} species (at most 64)", self.species.len()));
        }
        if self.materials.is_empty() || self.materials.len() > 64 {
            return bad(format!(
                "{} materials (1 to 64 wanted)",
                self.materials.len()
            ));
        }
        if !(self.viability.is_finite() && (0.0..=1.0).contains(&self.viability)) {
            return bad(format!("viability {} must lie in [0, 1]", self.viability));
        }
        let c = &self.clustering;
        if !(c.floor.is_finite() && (0.0..=1.0).contains(&c.floor)) {
            return bad(format!("clustering.floor {} must lie in [0, 1]", c.floor));
        }
        if c.iterations > 64 || c.radius > 32 {
            return bad("clustering: at most 64 iterations and radius 32".into());
        }
        for (i, s) in self.species.iter().enumerate() {
            check_niche_item(
                ("species", &s.name),
                self.species[..i].iter().map(|o| &o.name),
                &[
                    ("elevation", s.elevation),
                    ("slope", s.slope),
                    ("northness", s.northness),
                    ("wetness", s.wetness),
                ],
                [("class", &s.class), ("biome", &s.biome)],
            )?;
        }
        for (i, m) in self.materials.iter().enumerate() {
            check_niche_item(
                ("material", &m.name),
                self.materials[..i].iter().map(|o| &o.name),
                &[
                    ("elevation", m.elevation),
                    ("slope", m.slope),
                    ("northness", m.northness),
                    ("curvature", m.curvature),
                    ("wetness", m.wetness),
                ],
                [("class", &m.class), ("biome", &m.biome)],
            )?;
            for (sp, t) in &m.vegetation {
                if !self.species.iter().any(|s| &s.name == sp) {
                    return bad(format!("material {} names unknown species `{sp}`", m.name));
                }
                t.check(&format!("material {} vegetation {sp}", m.name))?;
            }
            if !(m.spread.is_finite() && (0.0..=1.0).contains(&m.spread)) {
                return bad(format!("material {}: spread must lie in [0, 1]", m.name));
            }
            if !(m.spread_scale_m.is_finite() && m.spread_scale_m > 0.0) {
                return bad(format!("material {}: spread_scale_m must be > 0", m.name));
            }
        }
        if let Some(f) = &self.fallback_material {
            if !self.materials.iter().any(|m| &m.name == f) {
                return bad(format!("fallback_material `{f}` is not a material"));
            }
        }
        if !(10..=24).contains(&self.instances_min_zoom) {
            return bad(format!(
                "instances_min_zoom {} must lie in 10..=24",
                self.instances_min_zoom
            ));
        }
        super::scatter::check_rules(self)?;
        let d = &self.drainage;
        if !(d.png_min_m2 > 0.0 && d.png_max_m2 > d.png_min_m2 && d.png_max_m2.is_finite()) {
            return bad("drainage: need 0 < png_min_m2 < png_max_m2".into());
        }
        if !(0.0..=1.0).contains(&d.png_min_opacity) {
            return bad(format!(
                "drainage: png_min_opacity {} must lie in 0..=1",
                d.png_min_opacity
            ));
        }
        Ok(())
    }

    /// Checks that every `class.<name>` term of the materials and species names one of the world's classes
    /// `names`; the error names the material and the class.
    pub fn check_classes(&self, names: &[String]) -> Result<(), LandscapeError> {
        self.check_term_names(("class", "classes"), names, |m| &m.class, |s| &s.class)
    }

    /// Checks that every `biome.<name>` term of the materials and species names one of the
    /// world's biomes `names`; the error names the material (or species) and the biome.
    pub fn check_biomes(&self, names: &[String]) -> Result<(), LandscapeError> {
        self.check_term_names(("biome", "biomes"), names, |m| &m.biome, |s| &s.biome)
    }

    /// The check behind [`check_classes`](Self::check_classes) and
    /// [`check_biomes`](Self::check_biomes): every key of the terms `of_material` and
    /// `of_species` pick must be one of `names`; `(noun, plural)` words the error.
    fn check_term_names(
        &self,
        (noun, plural): (&str, &str),
        names: &[String],
        of_material: impl Fn(&Material) -> &BTreeMap<String, Trapezoid>,
        of_species: impl Fn(&Species) -> &BTreeMap<String, Trapezoid>,
    ) -> Result<(), LandscapeError> {
        let terms = self
            .materials
            .iter()
            .map(|m| ("material", &m.name, of_material(m)))
            .chain(
                self.species
                    .iter()
                    .map(|s| ("species", &s.name, of_species(s))),
            );
        for (what, name, terms) in terms {
            if let Some(key) = terms.keys().find(|k| !names.contains(k)) {
                let known = if names.is_empty() {
                    format!("the world has no {plural}")
                } else {
                    format!("its {plural} are {}", names.join(", "))
                };
                return Err(LandscapeError::Invalid(format!(
                    "{what} {name} names unknown {noun} `{key}` ({known})"
                )));
            }
        }
        Ok(())
    }

    /// Index of the fallback material.
    pub fn fallback_index(&self) -> usize {
        self.fallback_material
            .as_ref()
            .and_then(|f| self.materials.iter().position(|m| &m.name == f))
            .unwrap_or(0)
    }

    /// Number of RGBA splat sets (`ceil(materials / 4)`).
    pub fn splat_sets(&self) -> usize {
        self.materials.len().div_ceil(4)
    }

    /// Species names in layer order.
    pub fn species_names(&self) -> Vec<String> {
        self.species.iter().map(|s| s.name.clone()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_is_zero_outside_one_inside_and_smooth() {
        let t = Trapezoid {
            min: 0.0,
            max: 10.0,
            falloff: 2.0,
        };
        assert_eq!(t.weight(-1.0), 0.0);
        assert_eq!(t.weight(0.0), 0.0);
        assert_eq!(t.weight(10.0), 0.0);
        assert_eq!(t.weight(11.0), 0.0);
        assert_eq!(t.weight(f32::NAN), 0.0);
        assert_eq!(t.weight(5.0), 1.0);
        assert_eq!(t.weight(2.0), 1.0);
        // Smoothstep at t = 1/2.
        assert!((t.weight(1.0) - 0.5).abs() < 1e-6);
        assert!((t.weight(9.0) - 0.5).abs() < 1e-6);
        let b = Trapezoid {
            min: 1.0,
            max: 2.0,
            falloff: 0.0,
        };
        assert_eq!(b.weight(1.0), 1.0);
        assert_eq!(b.weight(0.99), 0.0);
    }

    /// The drainage overlay's alpha: transparent below the smallest drawn channel and for no
    /// area or NaN, the floor opacity at it, opaque from the largest on, linear in log10 area
    /// between (values worked out by hand).
    #[test]
    fn drainage_alpha_has_its_floor_at_the_smallest_channel_and_rises_in_log_area() {
        let st = DrainageStyle {
            png_min_m2: 1e6,
            png_max_m2: 1e10,
            png_min_opacity: 0.4,
            colour: [0, 0, 0],
        };
        let alpha = st.alpha_ramp();
        assert_eq!(alpha(0.0), 0);
        assert_eq!(alpha(-5.0), 0);
        assert_eq!(alpha(f32::NAN), 0);
        assert_eq!(alpha(999_000.0), 0);
        assert_eq!(alpha(1e6), 102); // 0.4 · 255
        assert_eq!(alpha(1e8), 179); // (0.4 + 0.6 · 0.5) · 255 = 178.5
        assert_eq!(alpha(1e10), 255);
        assert_eq!(alpha(1e12), 255);
        assert_eq!(alpha(f32::INFINITY), 255);
        let fade = DrainageStyle {
            png_min_opacity: 0.0,
            ..st
        };
        assert_eq!(fade.alpha_ramp()(1e6), 0);
        assert_eq!(fade.alpha_ramp()(1e8), 128); // 127.5
        let mut cfg = LandscapeConfig::default();
        cfg.drainage.png_min_opacity = 1.5;
        assert!(cfg.validate().is_err());
    }

    #[test]
    fn debug_text_without_class_terms_is_the_text_before_classes() {
        // The derived text of the fields before classes, written out by hand.
        let t = Trapezoid {
            min: 1.0,
            max: 2.0,
            falloff: 0.0,
        };
        let mut s = Species {
            name: "a".into(),
            colour: [1, 2, 3],
            elevation: Some(t),
            slope: None,
            northness: None,
            wetness: None,
            class: BTreeMap::new(),
            biome: BTreeMap::new(),
        };
        assert_eq!(
            format!("{s:?}"),
            "Species { name: \"a\", colour: [1, 2, 3], elevation: Some(Trapezoid { min: 1.0, \
             max: 2.0, falloff: 0.0 }), slope: None, northness: None, wetness: None }"
        );
        s.class.insert("forest".into(), t);
        assert!(format!("{s:?}").contains("class: {\"forest\""));
        let mut m = LandscapeConfig::default().materials.remove(0);
        assert_eq!(
            format!("{m:?}"),
            "Material { name: \"ground\", colour: [150, 140, 120], elevation: None, slope: None, \
             northness: None, curvature: None, wetness: None, vegetation: {}, spread: 0.0, \
             spread_scale_m: 2000.0 }"
        );
        m.class.insert("forest".into(), t);
        assert!(format!("{m:?}").contains("vegetation: {}, class: {\"forest\""));
    }

    #[test]
    fn the_default_world_has_a_valid_landscape() {
        let l = LandscapeConfig::tienshan();
        l.validate().unwrap();
        assert!(l.species.len() >= 3, "{:?}", l.species_names());
        assert!(l.materials.len() >= 8);
        LandscapeConfig::default().validate().unwrap();
    }

    /// Species and materials are checked alike: a repeated or invalid name, and a bad range of
    /// a named or a keyed term, each named in the error.
    #[test]
    fn species_and_materials_name_what_is_wrong() {
        let bad_range = Trapezoid {
            min: 2.0,
            max: 1.0,
            falloff: 0.0,
        };
        let error = |l: &LandscapeConfig| match l.validate() {
            Err(LandscapeError::Invalid(m)) => m,
            other => panic!("expected an invalid landscape, got {other:?}"),
        };
        let base = LandscapeConfig::tienshan();

        let mut l = base.clone();
        let first = l.species[0].name.clone();
        l.species[1].name = first.clone();
        assert_eq!(
            error(&l),
            format!("species name `{first}` is invalid or repeated")
        );

        let mut l = base.clone();
        l.materials[0].name = "no spaces".into();
        assert_eq!(
            error(&l),
            "material name `no spaces` is invalid or repeated"
        );

        let mut l = base.clone();
        l.species[0].slope = Some(bad_range);
        let name = l.species[0].name.clone();
        assert!(error(&l).starts_with(&format!("species {name} slope: range [2, 1]")));

        let mut l = base.clone();
        l.materials[1].curvature = Some(bad_range);
        let name = l.materials[1].name.clone();
        assert!(error(&l).starts_with(&format!("material {name} curvature: range")));

        let mut l = base.clone();
        l.materials[2].class.insert("rock".into(), bad_range);
        let name = l.materials[2].name.clone();
        assert!(error(&l).starts_with(&format!("material {name} class.rock: range")));

        let mut l = base;
        l.species[2].biome.insert("steppe".into(), bad_range);
        let name = l.species[2].name.clone();
        assert!(error(&l).starts_with(&format!("species {name} biome.steppe: range")));
    }
}
