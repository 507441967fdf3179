//! World definitions created through the admin API: what a world is made of (a base exemplar, a
//! dictionary, zooms, matching weights, its landscape's materials, species and scattering rules),
//! the rules a request must follow, and the defaults it inherits from the default world.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use terrasynth_core::dictionary::{AmplifierKind, MatchWeights};
use terrasynth_core::landscape::{
    ClassesConfig, HsvClass, LandscapeConfig, Material, ScatterRule, Species, WaterConfig,
};
use terrasynth_core::names::{is_content_id, is_valid_name, NAME_RULE};
use terrasynth_core::raster::georef::{is_map_point, MAX_MERCATOR_LAT};
use terrasynth_core::synth::{check_bands, ZoomBand};

use crate::error::ServiceError;

/// A world created through the API, as stored (JSON in a world object).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct WorldDefinition {
    /// URL name.
    pub name: String,
    /// Exemplar id of the base (the coarse DEM or sketch).
    pub base: String,
    /// Dictionaries of the synthesis chain: ids (every amplified zoom) or `{"id", "zooms",
    /// "amplifier"}` bands; empty in a biome world.
    #[serde(default)]
    pub dictionaries: Vec<WorldDictionary>,
    /// Painted biomes (instead of `dictionaries`): a dictionary and a weight layer each.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub biomes: Vec<WorldBiomeRef>,
    /// Painted controls of species densities: a layer and a mode each.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub controls: Vec<WorldControlRef>,
    /// Deepest zoom served.
    pub max_zoom: u8,
    /// Matching weights by term or layer name.
    pub weights: BTreeMap<String, f32>,
    /// Materials of the splat and colour maps, in splat order, each as a world file's
    /// `[[landscape.materials]]`; empty: the default world's.
    #[schema(value_type = Vec<Object>)]
    #[serde(deserialize_with = "lenient_materials")]
    pub materials: Vec<Material>,
    /// Vegetation species, each as a world file's `[[landscape.species]]`; absent: the default
    /// world's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Object>>)]
    pub species: Option<Vec<Species>>,
    /// Human title shown by `/worlds`, TileJSON and the web map; absent: the name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub title: Option<String>,
    /// Attribution (the data's source) shown by map clients.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attribution: Option<String>,
    /// Elevation of pixels outside the base coverage, metres.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub fill_m: f32,
    /// Where map clients open, `[lon, lat]`; absent: over the base's highest-relief region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 2]>,
    /// Sea level, metres; absent: 0 for a base with cells below 0, no sea otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sea_level_m: Option<f32>,
    /// Lakes and water colours, as a world file's `[water]`; absent: the defaults (no lakes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub water: Option<WaterConfig>,
    /// Scattering rules of the instance tiles, each as a world file's `[[landscape.scatter]]`;
    /// absent: the default world's (less the rules naming species or materials it lacks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Object>>)]
    pub scatter: Option<Vec<ScatterRule>>,
    /// Land-cover classes for the materials' `class.<name>` terms; absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub classes: Option<WorldClassesRef>,
}

/// A world's land-cover classes: a class raster with its legend, or an RGB image with HSV ranges,
/// taken from an exemplar's layer on the base's grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorldClassesRef {
    /// Exemplar holding the raster: its `classes` layer (with `legend`) or its `rgb` layer (with
    /// `hsv`), on the base's grid (same size and georeference); absent: the base exemplar.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exemplar: Option<String>,
    /// The class raster's legend, `{"value": "name"}` (values are integers 0–65535; every value
    /// of the raster must have an entry; several values may name one class).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    #[schema(value_type = Object, example = json!({"1": "forest", "2": "rock"}))]
    pub legend: BTreeMap<String, String>,
    /// The RGB image's classes, `[{"name", "hsv": {"h": [min, max], "s": [min, max], "v": [min,
    /// max]}}]`: hue in degrees 0–360 (`min > max` wraps through 0°), saturation and value 0–1;
    /// a pixel takes the first class whose ranges hold it, else none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schema(value_type = Vec<Object>)]
    pub hsv: Vec<HsvClass>,
    /// Distance, metres, over which a class weight falls from 1 to 0 across a class border
    /// (default 0: sharp; at most 64 base cells each way).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub smoothing_m: f32,
}

impl WorldClassesRef {
    /// The classes' settings (legend or HSV ranges, smoothing).
    pub fn config(&self) -> ClassesConfig {
        ClassesConfig {
            legend: self.legend.clone(),
            hsv: self.hsv.clone(),
            smoothing_m: self.smoothing_m,
        }
    }

    /// The exemplar layer holding the raster: `rgb` with HSV ranges, else `classes`.
    pub fn layer(&self) -> &'static str {
        if self.hsv.is_empty() {
            CLASSES_LAYER
        } else {
            crate::ingest::RGB_LAYER
        }
    }
}

/// One painted biome of a world (#15): a dictionary and the layer of weights that says where
/// its detail goes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorldBiomeRef {
    /// Dictionary (or gradient tile set) id amplifying this biome at every amplified zoom.
    pub dictionary: String,
    /// The weight raster: the name of a layer of `exemplar` (uploaded as a named multipart
    /// part, e.g. `-F alps=@alps.tif`); weights finite and ≥ 0 at every cell.
    #[schema(example = "alps")]
    pub weight: String,
    /// Exemplar holding the weight layer, on the base's grid; absent: the base exemplar.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exemplar: Option<String>,
    /// The biome's name (default: `weight`); unique in the world.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// `dictionary` (the default) or `gradient` (`dictionary` then names a gradient tile set).
    #[serde(default, skip_serializing_if = "AmplifierKind::is_default")]
    #[schema(value_type = String, example = "dictionary")]
    pub amplifier: AmplifierKind,
}

impl WorldBiomeRef {
    /// The biome's name: `name`, else the weight layer's.
    pub fn name(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.weight)
    }
}

/// A painted control of a species' density (#15): a layer of the base exemplar (or of another
/// exemplar on its grid) that replaces or scales the species' density.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorldControlRef {
    /// The species it steers (one of the world's).
    pub species: String,
    /// The layer holding the painted values (uploaded as a named part).
    pub layer: String,
    /// `replace` (the density is the layer's value, 0–1) or `scale` (multiplied by it, ≥ 0).
    #[schema(example = "replace")]
    pub mode: String,
    /// Exemplar holding the layer, on the base's grid; absent: the base exemplar.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exemplar: Option<String>,
}

/// The modes of [`WorldControlRef::mode`].
pub const CONTROL_MODES: [&str; 2] = ["replace", "scale"];

/// The exemplar layer of a class raster.
pub const CLASSES_LAYER: &str = "classes";

/// Whether a fill is the default (not written, so definitions stored before it read the same).
fn is_zero(v: &f32) -> bool {
    *v == 0.0
}

/// Materials of a stored definition: definitions written before materials were used held any
/// JSON value there (kept, never read); anything but a list of materials reads as "none" (the
/// default world's), so those worlds still load.
fn lenient_materials<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<Material>, D::Error> {
    let v = serde_json::Value::deserialize(d)?;
    Ok(serde_json::from_value(v).unwrap_or_default())
}

/// `POST /admin/worlds`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorldRequest {
    /// URL name: 1–64 letters, digits, `-` or `_`.
    #[schema(pattern = "^[A-Za-z0-9_-]{1,64}$")]
    pub name: String,
    /// Exemplar id of the base.
    pub base: String,
    /// The synthesis chain's dictionaries: one dictionary id (used at every amplified zoom), or
    /// one `{"id", "zooms", "amplifier"}` object per zoom band (`zooms`: `"FIRST-LAST"` or
    /// `"ZOOM"`, absent only for a single entry covering every zoom; bands lie above the native
    /// zoom and at most `max_zoom` and do not overlap; a zoom no band covers uses the nearest
    /// shallower band, zooms below the first band the first band; `amplifier`: `"dictionary"`
    /// (default) or `"gradient"`, whose `id` is then a gradient tile set). Absent in a biome
    /// world (`biomes`).
    #[serde(default)]
    pub dictionaries: Vec<WorldDictionary>,
    /// Painted biomes, instead of `dictionaries` (#15): `[{"dictionary": id, "weight": layer,
    /// "exemplar", "name", "amplifier"}]` — each biome's dictionary amplifies where its weight
    /// layer (a layer of the base exemplar, uploaded as a named part, or of `exemplar` on the
    /// base's grid) paints it; the outputs are blended by the weights normalised per pixel.
    /// Checked: 422 naming the problem (unknown dictionary or layer, weights off the base's
    /// grid, negative or NaN, all 0; both `biomes` and `dictionaries`).
    #[serde(default)]
    pub biomes: Vec<WorldBiomeRef>,
    /// Painted controls of species densities (default: none): `[{"species", "layer", "mode":
    /// "replace" | "scale", "exemplar"}]` — the layer (of the base exemplar, uploaded as a named
    /// part, or of `exemplar` on the base's grid) replaces the species' density (values 0–1) or
    /// scales it (values ≥ 0) at the native zoom, and every zoom follows. Checked: 422 naming
    /// the problem.
    #[serde(default)]
    pub controls: Vec<WorldControlRef>,
    /// Deepest zoom served (default: the default world's).
    #[serde(default)]
    pub max_zoom: Option<u8>,
    /// Matching weights (default: the default world's).
    #[serde(default)]
    pub weights: Option<BTreeMap<String, f32>>,
    /// Materials of the splat and colour maps, in splat order, each as a world file's
    /// `[[landscape.materials]]` (`{"name", "colour", "elevation", "slope", "northness",
    /// "curvature", "wetness", "vegetation", "spread", "spread_scale_m"}`; ranges `{"min", "max",
    /// "falloff"}`). Default: the default world's.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Object>>)]
    pub materials: Option<Vec<Material>>,
    /// Vegetation species, each as a world file's `[[landscape.species]]`. Default: the default
    /// world's.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Object>>)]
    pub species: Option<Vec<Species>>,
    /// Human title (default: the name); at most 200 characters.
    #[serde(default)]
    pub title: Option<String>,
    /// Attribution of the data shown by map clients; at most 1,000 characters.
    #[serde(default)]
    pub attribution: Option<String>,
    /// Elevation of pixels outside the base coverage, metres (default 0; finite, within
    /// ±12,000 m).
    #[serde(default)]
    pub fill_m: Option<f32>,
    /// Where map clients open, `[lon, lat]` in degrees (default: the centre of the base's
    /// highest-relief region).
    #[serde(default)]
    pub center: Option<[f64; 2]>,
    /// Sea level, metres (default: 0 for a base with cells below 0, no sea otherwise; finite,
    /// within ±12,000 m).
    #[serde(default)]
    pub sea_level_m: Option<f32>,
    /// Lakes and water colours, as a world file's `[water]`: `{"lakes": bool,
    /// "lake_min_area_m2", "lake_min_depth_m", "surface_lake_min_area_m2",
    /// "surface_lake_bed_slope", "shallow_colour": [r, g, b], "deep_colour", "deep_m"}`
    /// (default: no lakes; minima 1 km² and 20 m; no surface lakes, bed slope 0.01). Checked:
    /// 422 naming the field.
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub water: Option<WaterConfig>,
    /// Scattering rules of the instance tiles, each as a world file's `[[landscape.scatter]]`
    /// (`{"kind", "method": "jittered_grid" | "collision" | "survival", "species", "materials",
    /// "name", "spacing_m", "min_distance_m", "jitter", "height_m", "radius_m", "age_classes",
    /// "seeding_radius_m", "generations", "seeds", "founders", "exclude_materials",
    /// "exclude_weight", "seed"}`; sizes `{"min", "max"}`). Default: the default world's rules
    /// that name only the world's species and materials.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Object>>)]
    pub scatter: Option<Vec<ScatterRule>>,
    /// Land-cover classes (default: none): `{"exemplar", "legend", "hsv", "smoothing_m"}` — a
    /// class raster (the exemplar's `classes` layer, uploaded as a `classes` part) with a
    /// `legend` `{"value": "name"}`, or an RGB image (its `rgb` layer, uploaded as an `rgb`
    /// part: an 8-bit RGB(A) PNG) with `hsv` ranges per class; `exemplar` defaults to the base
    /// and must lie on its grid. Materials and species weigh classes with `"class": {"name":
    /// {"min", "max", "falloff"}}`. Checked: 422 naming the problem.
    #[serde(default)]
    pub classes: Option<WorldClassesRef>,
}

/// One entry of a world's `dictionaries`: a bare dictionary id (every amplified zoom; worlds
/// stored before zoom bands hold these) or a band.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged, try_from = "serde_json::Value")]
pub enum WorldDictionary {
    /// A dictionary id: the world's one dictionary, used at every amplified zoom.
    Id(String),
    /// A dictionary for a band of zooms.
    Band(DictionaryBandRef),
}

/// A dictionary (or gradient tile set) and the zooms it amplifies, with the amplifier that uses
/// it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DictionaryBandRef {
    /// Dictionary (or gradient tile set) id.
    pub id: String,
    /// Zooms, `"FIRST-LAST"` or `"ZOOM"`, e.g. `"9-12"`; may be absent only for a world's one
    /// entry (every amplified zoom).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(example = "9-12")]
    pub zooms: Option<String>,
    /// `dictionary` (the default: dictionary matching; `id` names a dictionary) or `gradient`
    /// (gradient tiles; `id` names a gradient tile set built with `"kind": "gradient"`).
    #[serde(default, skip_serializing_if = "AmplifierKind::is_default")]
    #[schema(value_type = String, example = "gradient")]
    pub amplifier: AmplifierKind,
}

impl TryFrom<serde_json::Value> for WorldDictionary {
    type Error = String;

    fn try_from(v: serde_json::Value) -> Result<Self, String> {
        match v {
            serde_json::Value::String(id) => Ok(WorldDictionary::Id(id)),
            v @ serde_json::Value::Object(_) => serde_json::from_value(v)
                .map(WorldDictionary::Band)
                .map_err(|e| {
                    format!(
                        "dictionaries: a band is {{\"id\", \"zooms\", \"amplifier\": \
                         \"dictionary\" | \"gradient\"}}: {e}"
                    )
                }),
            _ => Err(
                "dictionaries: each entry is a dictionary id or {\"id\", \"zooms\", \"amplifier\"}"
                    .into(),
            ),
        }
    }
}

impl WorldDictionary {
    /// The dictionary id.
    pub fn id(&self) -> &str {
        match self {
            WorldDictionary::Id(id) => id,
            WorldDictionary::Band(b) => &b.id,
        }
    }

    /// The amplifier of this entry (a bare id: `dictionary`).
    pub fn amplifier(&self) -> AmplifierKind {
        match self {
            WorldDictionary::Id(_) => AmplifierKind::Dictionary,
            WorldDictionary::Band(b) => b.amplifier,
        }
    }
}

/// Longest accepted title, characters.
pub const MAX_TITLE_CHARS: usize = 200;
/// Longest accepted attribution, characters.
pub const MAX_ATTRIBUTION_CHARS: usize = 1000;

/// What created worlds inherit: the default (first configured) world's settings.
#[derive(Clone, Debug)]
pub struct WorldDefaults {
    /// Deepest zoom.
    pub max_zoom: u8,
    /// Matching weights.
    pub weights: BTreeMap<String, f32>,
    /// Landscape (species, seeding simulation, materials, drainage style).
    pub landscape: LandscapeConfig,
}

/// World names the admin API's own routes take (`POST /admin/worlds/sketch`): a world of that
/// name could not be deleted through `DELETE /admin/worlds/{name}`.
pub const RESERVED_WORLD_NAMES: [&str; 1] = ["sketch"];

/// Checks a user-given world name: the name rule, and not a reserved name.
pub fn check_world_name(name: &str) -> Result<(), ServiceError> {
    check_name("world name", name)?;
    if RESERVED_WORLD_NAMES.contains(&name) {
        return Err(ServiceError::Invalid(format!(
            "world name `{name}` is reserved (it is an admin route)"
        )));
    }
    Ok(())
}

/// Checks a user-given name.
pub fn check_name(what: &str, name: &str) -> Result<(), ServiceError> {
    if is_valid_name(name) {
        Ok(())
    } else {
        Err(ServiceError::Invalid(format!(
            "{what} `{name}` must be {NAME_RULE}"
        )))
    }
}

/// A name → weight map of matching weights (`elevation`, `altitude`, `slope`, then layers).
pub fn weights_map(w: &MatchWeights) -> BTreeMap<String, f32> {
    let mut m = BTreeMap::new();
    m.insert("elevation".to_string(), w.elevation);
    m.insert("altitude".to_string(), w.altitude);
    m.insert("slope".to_string(), w.slope);
    for (k, v) in &w.layers {
        m.insert(k.clone(), *v);
    }
    m
}

/// Matching weights from a name → weight map (`elevation`, `altitude`, `slope`, else layers;
/// absent terms are 0).
pub fn match_weights(w: &BTreeMap<String, f32>) -> MatchWeights {
    let mut m = MatchWeights {
        elevation: 0.0,
        altitude: 0.0,
        slope: 0.0,
        layers: Vec::new(),
    };
    for (k, &v) in w {
        match k.as_str() {
            "elevation" => m.elevation = v,
            "altitude" => m.altitude = v,
            "slope" => m.slope = v,
            _ => m.layers.push((k.clone(), v)),
        }
    }
    m
}

impl WorldDefinition {
    /// The definition a request asks for, with defaults filled in and the rules that need no
    /// store checked: the name, finite non-negative weights, a valid landscape. The base and
    /// dictionary are checked when the definition is resolved against the store.
    pub fn from_request(r: WorldRequest, d: &WorldDefaults) -> Result<Self, ServiceError> {
        check_world_name(&r.name)?;
        let def = WorldDefinition {
            name: r.name,
            base: r.base,
            dictionaries: r.dictionaries,
            biomes: r.biomes,
            controls: r.controls,
            max_zoom: r.max_zoom.unwrap_or(d.max_zoom),
            weights: r.weights.unwrap_or_else(|| d.weights.clone()),
            materials: r.materials.unwrap_or_default(),
            species: r.species,
            title: r.title,
            attribution: r.attribution,
            fill_m: r.fill_m.unwrap_or(0.0),
            center: r.center,
            sea_level_m: r.sea_level_m,
            water: r.water,
            scatter: r.scatter,
            classes: r.classes,
        };
        if let Some(c) = &def.classes {
            c.config()
                .validate()
                .map_err(|e| ServiceError::Invalid(e.to_string()))?;
            if c.exemplar.as_ref().is_some_and(|e| !is_content_id(e)) {
                return Err(ServiceError::Invalid(format!(
                    "classes.exemplar: unknown exemplar `{}`",
                    c.exemplar.as_deref().unwrap_or_default()
                )));
            }
        }
        if let Some(w) = &def.water {
            w.validate()
                .map_err(|e| ServiceError::Invalid(e.to_string()))?;
        }
        if def
            .title
            .as_ref()
            .is_some_and(|t| t.trim().is_empty() || t.chars().count() > MAX_TITLE_CHARS)
        {
            return Err(ServiceError::Invalid(format!(
                "title must be 1–{MAX_TITLE_CHARS} characters"
            )));
        }
        if def
            .attribution
            .as_ref()
            .is_some_and(|a| a.chars().count() > MAX_ATTRIBUTION_CHARS)
        {
            return Err(ServiceError::Invalid(format!(
                "attribution must be at most {MAX_ATTRIBUTION_CHARS} characters"
            )));
        }
        if !def.fill_m.is_finite() || def.fill_m.abs() > 12_000.0 {
            return Err(ServiceError::Invalid(
                "fill_m must be a finite elevation within ±12,000 m".into(),
            ));
        }
        if def
            .sea_level_m
            .is_some_and(|s| !s.is_finite() || s.abs() > 12_000.0)
        {
            return Err(ServiceError::Invalid(
                "sea_level_m must be a finite elevation within ±12,000 m".into(),
            ));
        }
        if def.center.is_some_and(|c| !is_map_point(c)) {
            return Err(ServiceError::Invalid(format!(
                "center must be [lon, lat] with |lon| ≤ 180 and |lat| ≤ {MAX_MERCATOR_LAT}"
            )));
        }
        if def.weights.values().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(ServiceError::Invalid(
                "weights must be finite and non-negative".into(),
            ));
        }
        def.landscape(&d.landscape)?;
        def.check_biomes()?;
        for (i, c) in def.controls.iter().enumerate() {
            if !CONTROL_MODES.contains(&c.mode.as_str()) {
                return Err(ServiceError::Invalid(format!(
                    "controls[{i}].mode `{}` must be `replace` or `scale`",
                    c.mode
                )));
            }
            if !is_valid_name(&c.layer) {
                return Err(ServiceError::Invalid(format!(
                    "controls[{i}].layer: unknown layer `{}`",
                    c.layer
                )));
            }
            if c.exemplar.as_ref().is_some_and(|e| !is_content_id(e)) {
                return Err(ServiceError::Invalid(format!(
                    "controls[{i}].exemplar: unknown exemplar `{}`",
                    c.exemplar.as_deref().unwrap_or_default()
                )));
            }
        }
        def.band_zooms()?;
        Ok(def)
    }

    /// Checks the biomes as far as the definition tells: not with `dictionaries`, names valid
    /// and unique, ids well-formed.
    pub fn check_biomes(&self) -> Result<(), ServiceError> {
        if self.biomes.is_empty() {
            return Ok(());
        }
        if !self.dictionaries.is_empty() {
            return Err(ServiceError::Invalid(
                "give either `biomes` or `dictionaries`, not both (each biome names its own \
                 dictionary)"
                    .into(),
            ));
        }
        let mut names: Vec<&str> = Vec::new();
        for (i, b) in self.biomes.iter().enumerate() {
            if !is_content_id(&b.dictionary) {
                return Err(ServiceError::Invalid(format!(
                    "biomes[{i}]: unknown dictionary `{}`",
                    b.dictionary
                )));
            }
            if !is_valid_name(&b.weight) {
                return Err(ServiceError::Invalid(format!(
                    "biomes[{i}].weight: unknown layer `{}` (a layer name is {NAME_RULE})",
                    b.weight
                )));
            }
            if b.exemplar.as_ref().is_some_and(|e| !is_content_id(e)) {
                return Err(ServiceError::Invalid(format!(
                    "biomes[{i}].exemplar: unknown exemplar `{}`",
                    b.exemplar.as_deref().unwrap_or_default()
                )));
            }
            check_name(&format!("biomes[{i}].name"), b.name())?;
            if names.contains(&b.name()) {
                return Err(ServiceError::Invalid(format!(
                    "biomes[{i}].name `{}` is used twice",
                    b.name()
                )));
            }
            names.push(b.name());
        }
        Ok(())
    }

    /// The zooms of each of the chain's dictionaries (`None`: every amplified zoom), checked as
    /// far as the definition tells: at least one, well-formed `zooms`, bands at most `max_zoom`
    /// and not overlapping, a bare id only alone. (Whether bands lie above the native zoom is
    /// checked when the world is made, since the base decides it.)
    pub fn band_zooms(&self) -> Result<Vec<Option<ZoomBand>>, ServiceError> {
        if self.dictionaries.is_empty() && !self.biomes.is_empty() {
            // A biome world: its biomes amplify every zoom.
            return Ok(Vec::new());
        }
        let mut out = Vec::with_capacity(self.dictionaries.len());
        for (i, d) in self.dictionaries.iter().enumerate() {
            out.push(match d {
                WorldDictionary::Id(_) => None,
                WorldDictionary::Band(b) => match &b.zooms {
                    None => None,
                    Some(z) => Some(z.parse::<ZoomBand>().map_err(|e| {
                        ServiceError::Invalid(format!("dictionaries[{i}].zooms: {e}"))
                    })?),
                },
            });
        }
        check_bands(&out, 0, self.max_zoom)
            .map_err(|e| ServiceError::Invalid(format!("dictionaries: {e}")))?;
        Ok(out)
    }

    /// The chain's dictionaries with their zooms ([`WorldDefinition::band_zooms`]), their ids
    /// well-formed (each entry's amplifier is [`WorldDictionary::amplifier`]).
    pub fn dictionary_bands(&self) -> Result<Vec<(Option<ZoomBand>, &str)>, ServiceError> {
        let zooms = self.band_zooms()?;
        let mut out = Vec::with_capacity(zooms.len());
        for (i, (d, z)) in self.dictionaries.iter().zip(zooms).enumerate() {
            if !is_content_id(d.id()) {
                return Err(ServiceError::Invalid(format!(
                    "dictionaries[{i}]: unknown dictionary `{}`",
                    d.id()
                )));
            }
            out.push((z, d.id()));
        }
        Ok(out)
    }

    /// The world's landscape: `defaults` with this definition's materials (when any) and
    /// species (when given), validated.
    pub fn landscape(&self, defaults: &LandscapeConfig) -> Result<LandscapeConfig, ServiceError> {
        let mut l = defaults.clone();
        if !self.materials.is_empty() {
            l.materials = self.materials.clone();
            // A fallback named by the defaults may not exist among the new materials.
            if l.fallback_material
                .as_ref()
                .is_some_and(|f| !l.materials.iter().any(|m| &m.name == f))
            {
                l.fallback_material = None;
            }
        }
        if let Some(species) = &self.species {
            l.species = species.clone();
            if self.materials.is_empty() {
                // The default materials may weigh the default species: those terms go with
                // them (a material of one's own must name only the world's species).
                for m in &mut l.materials {
                    m.vegetation
                        .retain(|name, _| species.iter().any(|s| &s.name == name));
                }
            }
        }
        match &self.scatter {
            Some(rules) => l.scatter = rules.clone(),
            None => {
                // The default rules go with the species and materials they name.
                let (species, materials) = (l.species.clone(), l.materials.clone());
                l.scatter.retain(|r| {
                    r.species
                        .iter()
                        .all(|n| species.iter().any(|s| &s.name == n))
                        && r.materials
                            .iter()
                            .chain(&r.exclude_materials)
                            .all(|n| materials.iter().any(|m| &m.name == n))
                });
            }
        }
        l.validate()
            .map_err(|e| ServiceError::Invalid(e.to_string()))?;
        let class_names = self
            .classes
            .as_ref()
            .map(|c| c.config().names())
            .unwrap_or_default();
        l.check_classes(&class_names)
            .map_err(|e| ServiceError::Invalid(e.to_string()))?;
        let biome_names: Vec<String> = self.biomes.iter().map(|b| b.name().to_string()).collect();
        l.check_biomes(&biome_names)
            .map_err(|e| ServiceError::Invalid(e.to_string()))?;
        Ok(l)
    }

    /// The matching weights.
    pub fn match_weights(&self) -> MatchWeights {
        match_weights(&self.weights)
    }
}
