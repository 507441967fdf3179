//! A world ready to serve: its [`Extent`] on the tile planes and the pyramids of its layers —
//! elevation (with the base's coverage), drainage, vegetation and water, plus splat weights and
//! colour inputs computed per tile — built from its [`WorldParts`]. The world's cache budget is
//! shared by its whole-world layers (first) and its level caches: half for elevation, a
//! sixty-fourth for the coverage overviews, a quarter each for vegetation and drainage (less an
//! eighth of the budget between them for water, in worlds that may have water, and drainage
//! less the coverage's share).
//! The ridges and valleys of the base (PPA) are computed once, on first use, outside that
//! budget.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

use ndarray::Array2;

use terrasynth_core::analysis::ppa::{self, Features, PpaParams};
use terrasynth_core::dictionary::AnyDictionary;
use terrasynth_core::dictionary::MatchWeights;
use terrasynth_core::landscape::water::default_sea_level;
use terrasynth_core::landscape::{LandscapeConfig, WaterConfig};
use terrasynth_core::raster::reproject::to_geographic;
use terrasynth_core::raster::{CellSizes, Crs, Georef, Grid};
use terrasynth_core::synth::{
    check_bands, Amplifier, AnyAmplifier, GradientAmplifier, Levers, SynthError, Window, ZoomBand,
};

use crate::base_layers::{base_layer_bytes, LayerStore, WholeWorld};
use crate::biomes::{BiomeWeights, Biomes, WorldBiome};
use crate::chain::{Chain, DictionaryBand};
use crate::classes::{ClassWeights, WorldClasses};
use crate::controls::{SpeciesControl, SpeciesControls};
use crate::drainage::DrainageLevels;
use crate::elevation::ElevationLevels;
use crate::error::TileError;
use crate::extent::{relief_center, Extent};
use crate::materials::{self, MaterialTile};
use crate::pyramid::LevelCache;
use crate::vegetation::{Inputs, VegetationLevels};
use crate::water::{WaterLevels, DEPTH, LEVEL};

/// Everything a world is made of, resolved: its base, dictionary and settings.
#[derive(Clone, Debug)]
pub struct WorldParts {
    /// URL name of the world.
    pub name: String,
    /// Human title.
    pub title: String,
    /// Attribution shown by map clients.
    pub attribution: String,
    /// The georeferenced base raster (EPSG:4326, EPSG:3857 or projected: reprojected).
    pub base: Grid,
    /// Native zoom of the base; `None` derives it from the base's cell size.
    pub z_base: Option<u8>,
    /// Deepest zoom served.
    pub max_zoom: u8,
    /// Elevation (m) of pixels outside the base coverage.
    pub fill_m: f32,
    /// The amplification dictionaries, one per zoom band ([`DictionaryBand::every_zoom`] for a
    /// world with one dictionary); checked against the native and deepest zooms by
    /// [`World::new`].
    pub dictionaries: Vec<DictionaryBand>,
    /// Matching weights.
    pub weights: MatchWeights,
    /// The world's memory budget, bytes: its whole-world landscape layers first, the rest (at
    /// least a quarter) for its level-tile caches.
    pub cache_bytes: u64,
    /// Landscape layers: species niches, materials, drainage style.
    pub landscape: LandscapeConfig,
    /// Where map clients open, `[lon, lat]`; `None`: over the base's highest-relief region
    /// ([`relief_center`]).
    pub center: Option<[f64; 2]>,
    /// Atoms per primitive of the amplifier ([`Levers::sparsity`]); `None`: the dictionary's.
    pub sparsity: Option<u32>,
    /// Sea level and lake settings ([`crate::water`]); a `sea_level_m` of `None` takes the
    /// default rule ([`default_sea_level`]: 0 m for a base with cells below 0, else no sea).
    pub water: WaterConfig,
    /// Land-cover classes on the base's grid ([`crate::classes`]); `None`: no classes (a
    /// material's `class.<name>` term then names an unknown class).
    pub classes: Option<WorldClasses>,
    /// Painted biomes ([`crate::biomes`]): several dictionaries, each with a weight raster on
    /// the base's grid; empty: none. A biome world's `dictionaries` must be empty (the biomes
    /// amplify every zoom).
    pub biomes: Vec<WorldBiome>,
    /// Painted controls replacing or scaling species densities ([`crate::controls`]); empty:
    /// none.
    pub controls: Vec<SpeciesControl>,
}

/// The material tiles' part of the level caches' budget (1/32, out of the elevation tiles'
/// half): a tile's splat sets and colour map are asked for one after the other, so a few tiles
/// (2–3 MB each) suffice. Taken out of the vegetation tiles' quarter instead, it slowed the
/// instance tiles, which read the vegetation of nine tiles around theirs.
const MATERIALS_SHARE: u64 = 32;

/// A snapshot of a world's counters, for `/metrics`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorldStats {
    /// Elevation level tiles served from the cache.
    pub cache_hits: u64,
    /// Elevation level tiles that had to be computed.
    pub cache_misses: u64,
    /// Level tiles synthesized by amplification (zooms above `z_b`).
    pub tiles_synthesized: u64,
    /// Parent windows amplified directly on cold chains (not cached; their tiles are computed in
    /// the background).
    pub windows_synthesized: u64,
    /// Whether the background thread is still computing parent tiles of cold chains.
    pub prefilling: bool,
    /// Seconds spent computing elevation level tiles.
    pub synthesis_seconds: f64,
    /// Level-tile computations (every layer) abandoned because nobody waited for them any more.
    pub cancelled: u64,
}

/// How a world's memory share is spent: its whole-world landscape layers first, then its
/// level-tile caches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryPlan {
    /// The world's share of the cache budget, bytes.
    pub share: u64,
    /// Bytes of the whole-world landscape layers (drainage and vegetation of the native zoom).
    pub whole_world: u64,
    /// Bytes left to the level-tile caches (at least a quarter of the share).
    pub level_caches: u64,
}

impl MemoryPlan {
    /// Whether the share holds the whole-world layers and leaves the level caches what remains
    /// (`false`: the world will use more memory than its share).
    pub fn fits(&self) -> bool {
        self.whole_world.saturating_add(self.level_caches) <= self.share
    }
}

/// A world ready to serve tiles.
pub struct World {
    memory: MemoryPlan,
    name: String,
    title: String,
    attribution: String,
    /// Where map clients open, `[lon, lat]`.
    center: [f64; 2],
    /// The chain's bands: zooms (`None`: every amplified zoom) and dictionary id.
    bands: Vec<(Option<ZoomBand>, String)>,
    /// The biomes' names, in the order given (empty: not a biome world).
    biome_names: Vec<String>,
    fingerprint: String,
    /// [`World::etag_seed`]: the hash states of tile ETags after the world's own part.
    etag_seeds: [sha2::Sha256; 2],
    landscape: Arc<LandscapeConfig>,
    elevation: Arc<ElevationLevels>,
    whole: WholeWorld,
    drainage: DrainageLevels,
    vegetation: VegetationLevels,
    /// Material tiles (weights and hillshade), read by a tile's splat sets and colour map.
    materials: LevelCache<MaterialTile>,
    water: WaterLevels,
    water_config: WaterConfig,
    /// Land-cover class weights on the base's grid (empty without classes).
    classes: Arc<ClassWeights>,
    /// The base's ridges and valleys, once computed (the lock coalesces concurrent first uses).
    features: Mutex<Option<Arc<Features>>>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("name", &self.name)
            .field("extent", self.elevation.extent())
            .finish_non_exhaustive()
    }
}

fn scatter_fingerprint(landscape: &LandscapeConfig) -> String {
    format!("{:?}|{}", landscape.scatter, landscape.instances_min_zoom)
}

fn etag_seeds(fingerprint: &str, scatter: &str) -> [sha2::Sha256; 2] {
    use sha2::{Digest, Sha256};
    let mut tiles = Sha256::new();
    tiles.update(fingerprint.as_bytes());
    let mut instances = tiles.clone();
    instances.update(scatter.as_bytes());
    [tiles, instances]
}

/// The dictionaries' part of a fingerprint: the id of a world's single dictionary (as before
/// zoom bands, so such worlds keep their fingerprint), else `id@zooms` per band.
fn dictionary_key(bands: &[DictionaryBand]) -> String {
    match bands {
        [DictionaryBand {
            zooms: None, id, ..
        }] => id.clone(),
        _ => bands
            .iter()
            .map(|b| match b.zooms {
                Some(z) => format!("{}@{z}", b.id),
                None => b.id.clone(),
            })
            .collect::<Vec<_>>()
            .join(","),
    }
}

/// The amplifier of band `b`: dictionary matching (with `weights` and `levers`) or gradient
/// tiles, by the band's file. `species`: `None` reconstructs elevation only, else elevation and
/// those layers (the vegetation pyramid's amplifiers).
fn band_amplifier(
    b: &DictionaryBand,
    weights: &MatchWeights,
    levers: Levers,
    species: Option<&[String]>,
) -> Result<AnyAmplifier, SynthError> {
    Ok(match &b.dictionary {
        AnyDictionary::Dictionary(d) => {
            let a = Amplifier::new(d.clone(), weights)?.with_levers(levers);
            AnyAmplifier::Dictionary(Box::new(match species {
                None => a.without_layers(),
                Some(s) => a.with_only_layers(s),
            }))
        }
        AnyDictionary::Gradient(g) => {
            let a = GradientAmplifier::new(g.clone())?;
            AnyAmplifier::Gradient(match species {
                None => a.without_layers(),
                Some(_) => a,
            })
        }
    })
}

/// The revision of what tiles hold, for a given world and request: hashed into every world's
/// fingerprint and so into every tile's ETag, so that a client or cache holding a tile of an
/// earlier revision never has it confirmed by a 304. Raised with every change of the code that
/// alters the bytes of a tile (the amplifier, a layer, an encoder). The committed tile-hash list
/// is pinned to it (`tests/it/tile_hashes.rs`): a change that rewrites the list fails that test
/// until this is raised.
///
/// Revision 1 is the first with a revision: tiles computed with the same transcendental
/// functions on every machine (`terrasynth_core::math`).
pub const TILE_BYTES_REVISION: u32 = 1;

/// Hex SHA-256 of everything that determines a world's tiles.
fn fingerprint(
    parts: &WorldParts,
    z_base: u8,
    classes: &ClassWeights,
    biomes: &BiomeWeights,
    controls: &SpeciesControls,
) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(format!("|tiles r{TILE_BYTES_REVISION}").as_bytes());
    h.update(format!(
        "|{:?}|{}|{}|{}|{}|{:?}|",
        parts.base.georef,
        dictionary_key(&parts.dictionaries),
        z_base,
        parts.max_zoom,
        parts.fill_m.to_bits(),
        parts.weights
    ));
    // The scattering rules determine only the instance tiles, whose ETag adds them
    // ([`World::scatter_fingerprint`]): the other tiles keep their ETags.
    let without_scatter = LandscapeConfig {
        scatter: Vec::new(),
        instances_min_zoom: terrasynth_core::landscape::scatter::DEFAULT_INSTANCES_MIN_ZOOM,
        ..parts.landscape.clone()
    };
    h.update(format!("{without_scatter:?}|"));
    if let Some(s) = parts.sparsity {
        // Absent before sparse codes: worlds without the setting keep their fingerprint.
        h.update(format!("sparsity={s}|"));
    }
    if parts.water != WaterConfig::default() {
        // Absent before water: worlds with the default settings keep their fingerprint.
        h.update(format!("water={:?}|", parts.water));
    }
    if !classes.is_empty() {
        // Absent before classes: worlds without classes keep their fingerprint.
        h.update(b"classes=");
        h.update(classes.fingerprint_bytes());
        h.update(b"|");
    }
    if !biomes.is_empty() {
        // Absent before biomes: worlds without biomes keep their fingerprint.
        h.update(b"biomes=");
        for b in &parts.biomes {
            h.update(format!("{}@{}|", b.name, b.id).as_bytes());
        }
        h.update(biomes.fingerprint_bytes());
        h.update(b"|");
    }
    if !controls.is_empty() {
        // Absent before controls: worlds without controls keep their fingerprint.
        h.update(b"controls=");
        h.update(controls.fingerprint_bytes());
        h.update(b"|");
    }
    for v in parts.base.data.iter() {
        h.update(v.to_bits().to_le_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

impl World {
    /// Builds a world from its parts (resolving `z_base` from the base's cell size when absent).
    /// A base in a projected CRS (UTM…) is first reprojected onto EPSG:4326
    /// ([`terrasynth_core::raster::reproject::to_geographic`]).
    pub fn new(mut parts: WorldParts) -> Result<World, TileError> {
        // Classes lie on the base's grid as given: weighed before the base is reprojected.
        let classes = match &parts.classes {
            Some(c) => ClassWeights::of(
                c,
                &parts.base,
                parts
                    .weights
                    .layers
                    .iter()
                    .any(|(n, w)| n == crate::classes::CLASS_GROUP && *w > 0.0),
            )?,
            None => ClassWeights::default(),
        };
        parts.landscape.check_classes(&classes.names())?;
        // Biomes, like classes, lie on the base's grid as given.
        let biome_weights = if parts.biomes.is_empty() {
            BiomeWeights::default()
        } else {
            if !parts.dictionaries.is_empty() {
                return Err(TileError::Biomes(
                    "a world takes `biomes` or `dictionary`/`dictionaries`, not both".into(),
                ));
            }
            let w = BiomeWeights::of(&parts.biomes, &parts.base)?;
            // The chain (unused while biomes amplify) and the bands listed: the biomes'
            // dictionaries, the dominant one first.
            let d = &parts.biomes[w.dominant()];
            parts.dictionaries = vec![DictionaryBand::every_zoom(
                d.dictionary.clone(),
                d.id.clone(),
            )];
            w
        };
        // Controls, like classes, lie on the base's grid as given.
        let controls = SpeciesControls::of(&parts.controls, &parts.landscape, &parts.base)?;
        if matches!(parts.base.georef.crs, Crs::Projected(_)) {
            parts.base =
                to_geographic(&parts.base).map_err(|e| TileError::Raster(e.to_string()))?;
        }
        let extent = Extent::of_base(&parts.base, parts.z_base, parts.max_zoom)?;
        parts.landscape.validate()?;
        if parts.water.sea_level_m.is_none() {
            parts.water.sea_level_m = default_sea_level(parts.base.min_max().map(|m| m.0));
        }
        parts.water.validate()?;
        // Lakes the base records as flat surfaces get a bed below their surface, before
        // anything reads the base's heights.
        let surface_lakes = crate::water::take_surface_lakes(&mut parts.base, &parts.water);
        let levers = Levers {
            sparsity: parts.sparsity.unwrap_or(0),
            ..Levers::default()
        };
        let zooms: Vec<_> = parts.dictionaries.iter().map(|b| b.zooms).collect();
        check_bands(&zooms, extent.z_base, extent.max_zoom)?;
        let amplifiers = Chain::new(&parts.dictionaries, |b| {
            band_amplifier(b, &parts.weights, levers, None)
        })?;
        let species = parts.landscape.species_names();
        let layer_amplifiers = Chain::new(&parts.dictionaries, |b| {
            band_amplifier(b, &parts.weights, levers, Some(&species))
        })?;
        // One copy of the weights, shared by the pyramids and the landscape's terms.
        let shared_biomes = Arc::new(biome_weights.clone());
        let biomes = |species: Option<&[String]>| -> Result<_, TileError> {
            if biome_weights.is_empty() {
                return Ok(None);
            }
            let weights = shared_biomes.clone();
            let amplifiers = parts
                .biomes
                .iter()
                .map(|b| {
                    band_amplifier(
                        &DictionaryBand::every_zoom(b.dictionary.clone(), b.id.clone()),
                        &parts.weights,
                        levers,
                        species,
                    )
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Some(Biomes {
                amplifiers,
                weights,
            }))
        };
        let matched_layers: Vec<String> = parts
            .weights
            .layers
            .iter()
            .map(|(n, _)| n.clone())
            .collect();
        let elevation_biomes = biomes(None)?;
        let vegetation_biomes = biomes(Some(&species))?;
        parts.landscape.check_biomes(biome_weights.names())?;
        let fingerprint = fingerprint(&parts, extent.z_base, &classes, &biome_weights, &controls);
        // The whole-world landscape layers come out of the same budget; the level caches keep
        // at least a quarter of it.
        let wet = parts.water.may_have_water();
        let base_bytes = base_layer_bytes(
            extent.world_window(extent.z_base),
            parts.landscape.species.len(),
            wet,
        )
        .saturating_add(classes.bytes())
        .saturating_add(biome_weights.bytes())
        .saturating_add(controls.bytes());
        let budget = parts
            .cache_bytes
            .saturating_sub(base_bytes)
            .max(parts.cache_bytes / 4);
        // Water tiles hold three planes: an eighth of the budget for worlds with a sea or
        // depression lakes, a sixty-fourth for worlds whose only water is the base's surface
        // lakes (tiles far from water are the shared dry tile, never cached: a few lakes need
        // few tiles, and the drainage and vegetation caches keep the rest).
        let water_bytes = if parts.water.sea_level_m.is_some() || parts.water.lakes {
            budget / 8
        } else if wet {
            budget / 64
        } else {
            0
        };
        let center = parts
            .center
            .or_else(|| relief_center(&parts.base))
            .unwrap_or_else(|| extent.middle());
        let etag_seeds = etag_seeds(&fingerprint, &scatter_fingerprint(&parts.landscape));
        let landscape = Arc::new(parts.landscape);
        // Materials and species read the biome weights with the class weights.
        let classes = Arc::new(if biome_weights.is_empty() {
            classes
        } else {
            classes.with_biomes(shared_biomes)
        });
        Ok(World {
            memory: MemoryPlan {
                share: parts.cache_bytes,
                whole_world: base_bytes,
                level_caches: budget,
            },
            name: parts.name,
            title: parts.title,
            attribution: parts.attribution,
            center,
            bands: if parts.biomes.is_empty() {
                parts
                    .dictionaries
                    .iter()
                    .map(|b| (b.zooms, b.id.clone()))
                    .collect()
            } else {
                parts.biomes.iter().map(|b| (None, b.id.clone())).collect()
            },
            biome_names: biome_weights.names().to_vec(),
            fingerprint,
            etag_seeds,
            elevation: ElevationLevels::new(
                parts.base,
                parts.fill_m,
                extent,
                amplifiers,
                elevation_biomes,
                budget / 2 - budget / MATERIALS_SHARE,
                budget / 64,
                parts.water.clone(),
                surface_lakes,
                classes.clone(),
            ),
            whole: WholeWorld::new(landscape.clone(), classes.clone(), controls),
            drainage: DrainageLevels::new(budget / 4 - budget / 64 - water_bytes / 2),
            vegetation: VegetationLevels::new(
                landscape.clone(),
                classes.clone(),
                layer_amplifiers,
                vegetation_biomes,
                budget / 4 - water_bytes / 2,
                &matched_layers,
            ),
            materials: LevelCache::new("materials", budget / MATERIALS_SHARE),
            water: WaterLevels::new(water_bytes),
            water_config: parts.water,
            classes,
            landscape,
            features: Mutex::new(None),
        })
    }

    fn inputs(&self) -> Inputs<'_> {
        Inputs {
            elevation: &self.elevation,
            drainage: &self.drainage,
            whole: &self.whole,
            water: &self.water,
        }
    }

    /// What the instance tiles depend on beyond [`World::fingerprint`]: the scattering rules and
    /// the zoom instance tiles start at.
    pub fn scatter_fingerprint(&self) -> String {
        scatter_fingerprint(&self.landscape)
    }

    /// The state of a tile ETag's hash after the world's part: the [`World::fingerprint`], and
    /// for instance tiles (`instances`) the [`World::scatter_fingerprint`] after it. Hashed once
    /// when the world is made, so that a request hashes only its own few bytes.
    pub fn etag_seed(&self, instances: bool) -> &sha2::Sha256 {
        &self.etag_seeds[usize::from(instances)]
    }

    /// A hash of everything that determines this world's tiles (base values and georeference,
    /// dictionary id, weights, zooms, fill, landscape, crate version): tile ETags derive from it.
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }

    /// URL name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Human title.
    pub fn title(&self) -> &str {
        &self.title
    }

    /// Attribution for map clients.
    pub fn attribution(&self) -> &str {
        &self.attribution
    }

    /// The world's place on the tile planes.
    pub fn extent(&self) -> &Extent {
        self.elevation.extent()
    }

    /// Native zoom of the base.
    pub fn z_base(&self) -> u8 {
        self.extent().z_base
    }

    /// Deepest zoom served.
    pub fn max_zoom(&self) -> u8 {
        self.extent().max_zoom
    }

    /// Shallowest zoom served (always 0: overviews reach the whole globe).
    pub fn min_zoom(&self) -> u8 {
        0
    }

    /// Fill elevation outside the base coverage, metres.
    pub fn fill_m(&self) -> f32 {
        self.elevation.fill_m()
    }

    /// The georeference of the base raster.
    pub fn base_georef(&self) -> Georef {
        self.elevation.base().georef
    }

    /// The ridges and valleys of the base raster (PPA with default parameters, on the base with
    /// its invalid cells filled), computed on the first call and kept (CPU-bound: call it off
    /// any async runtime). Concurrent first calls wait for one computation.
    pub fn features(&self) -> Result<Arc<Features>, TileError> {
        let mut slot = self
            .features
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(f) = slot.as_ref() {
            return Ok(f.clone());
        }
        let z = self
            .elevation
            .base()
            .filled()
            .map_err(|e| TileError::Raster(e.to_string()))?;
        let f = Arc::new(ppa::features(&z, &PpaParams::default()));
        *slot = Some(f.clone());
        Ok(f)
    }

    /// Bounds `[w, s, e, n]` in degrees.
    pub fn bounds(&self) -> [f64; 4] {
        self.extent().bounds
    }

    /// Where map clients open, `[lon, lat, zoom]`: the configured centre or the centre of the
    /// base's highest-relief region, two zooms above the native zoom.
    pub fn center(&self) -> [f64; 3] {
        [
            self.center[0],
            self.center[1],
            f64::from(self.extent().opening_zoom()),
        ]
    }

    /// Content ids of the dictionaries of the synthesis chain, in band order.
    pub fn dictionary_ids(&self) -> Vec<String> {
        self.bands.iter().map(|(_, id)| id.clone()).collect()
    }

    /// The chain's bands: zooms (`None`: every amplified zoom) and dictionary id, in the order
    /// they were given.
    pub fn dictionary_bands(&self) -> &[(Option<ZoomBand>, String)] {
        &self.bands
    }

    /// The names of a biome world's biomes, in the order given (empty: not a biome world); their
    /// dictionaries are [`World::dictionary_ids`], in the same order.
    pub fn biome_names(&self) -> &[String] {
        &self.biome_names
    }

    /// The landscape configuration.
    pub fn landscape(&self) -> &LandscapeConfig {
        &self.landscape
    }

    /// A snapshot of the world's counters.
    pub fn stats(&self) -> WorldStats {
        let e = &self.elevation;
        WorldStats {
            cache_hits: e.cache().stats().hits.load(Ordering::Relaxed),
            cache_misses: e.cache().stats().misses.load(Ordering::Relaxed),
            tiles_synthesized: e.tiles_synthesized.load(Ordering::Relaxed),
            windows_synthesized: e.windows_synthesized.load(Ordering::Relaxed),
            prefilling: e.prefilling(),
            synthesis_seconds: e.synthesis_micros.load(Ordering::Relaxed) as f64 / 1e6,
            cancelled: [
                &e.cache().stats().cancelled,
                &self.drainage.cache().stats().cancelled,
                &self.vegetation.cache().stats().cancelled,
                &self.water.cache().stats().cancelled,
                &self.materials.stats().cancelled,
            ]
            .iter()
            .map(|c| c.load(Ordering::Relaxed))
            .sum(),
        }
    }

    /// How the world's memory share is spent (see [`MemoryPlan::fits`]).
    pub fn memory(&self) -> MemoryPlan {
        self.memory
    }

    /// Bytes currently held by the level-tile caches (elevation, coverage, vegetation, drainage, water,
    /// materials).
    pub fn cache_bytes(&self) -> u64 {
        self.elevation.cache().weighted_size()
            + self.elevation.coverage_cache().weighted_size()
            + self.vegetation.cache().weighted_size()
            + self.drainage.cache().weighted_size()
            + self.water.cache().weighted_size()
            + self.materials.weighted_size()
    }

    /// Checks that tile `(z, x, y)` exists and intersects the world: `OutOfRange`, `ZoomTooDeep`
    /// or `OutsideWorld` otherwise.
    pub fn check_tile(&self, z: u8, x: u32, y: u32) -> Result<(), TileError> {
        self.extent().check_tile(z, x, y)
    }

    /// Metric ground cell size of zoom `z`'s pixels at the world's reference latitude.
    pub fn level_cell_m(&self, z: u8) -> f64 {
        self.extent().level_cell_m(z)
    }

    /// Per-row metric cell sizes of the rows `[row0, row0 + rows)` of zoom `z`'s pixel plane
    /// (true Mercator scale at each row's latitude), for slopes and hillshades.
    pub fn cell_sizes(&self, z: u8, row0: i64, rows: usize) -> CellSizes {
        self.extent().cell_sizes(z, row0, rows)
    }

    /// The elevation tile `(z, x, y)`, 256×256 metres, after [`World::check_tile`]. CPU-bound:
    /// call it off the async runtime.
    pub fn elevation_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<Array2<f32>>, TileError> {
        self.check_tile(z, x, y)?;
        self.elevation.tile(z, i64::from(x), i64::from(y))
    }

    /// The coverage tile `(z, x, y)`: the fraction (0–1) of each pixel that the base's valid data
    /// covers ([`crate::coverage`]); overlays are transparent where it is 0.
    pub fn coverage_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<Array2<f32>>, TileError> {
        self.elevation.coverage_tile(z, i64::from(x), i64::from(y))
    }

    /// Coverage over an arbitrary window of zoom `z`.
    pub fn coverage_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        self.elevation.coverage_window(z, w)
    }

    /// Whether the world has computed (or read back from the store) its native zoom's sea and
    /// lakes, which take the whole world at the native zoom. A world whose only water is the
    /// base's surface lakes serves tiles away from them without it.
    pub fn base_water_known(&self) -> bool {
        self.elevation.base_water_known()
    }

    /// An arbitrary window of zoom `z`'s pixel plane, assembled from level tiles. `z` may exceed
    /// `max_zoom` by one (for 512-px tiles at the deepest zoom).
    pub fn elevation_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        self.elevation.window(z, w)
    }

    /// Computes the whole-world layers of the native zoom now (drainage of the whole base and
    /// the base vegetation), which are otherwise computed by the first landscape request that
    /// needs them; a request arriving meanwhile waits for the same computation. Returns the bytes
    /// they hold.
    pub fn prepare_landscape(&self) -> Result<u64, TileError> {
        self.whole.get(&self.elevation).map(|b| {
            base_layer_bytes(
                b.window,
                b.vegetation.len(),
                self.water_config.may_have_water(),
            )
        })
    }

    /// Keeps this world's whole-world layers in `store` between runs: whoever computes them
    /// first reads them from it when stored there for the same inputs by the same build, and
    /// stores them after computing them otherwise (the same layers either way, bit for bit).
    /// Set it before the first landscape tile; the first store given stays.
    pub fn keep_landscape_in(&self, store: Arc<dyn LayerStore>) {
        self.whole.keep_in(store);
    }

    /// The drainage tile `(z, x, y)`: upstream area in m² (after [`World::check_tile`]).
    pub fn drainage_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<Array2<f32>>, TileError> {
        self.check_tile(z, x, y)?;
        self.drainage.tile(
            &self.elevation,
            &self.whole,
            &self.water,
            z,
            i64::from(x),
            i64::from(y),
        )
    }

    /// Drainage over an arbitrary window of zoom `z`, assembled from drainage tiles.
    pub fn drainage_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        self.drainage
            .window(&self.elevation, &self.whole, &self.water, z, w)
    }

    /// The world's water settings.
    pub fn water_config(&self) -> &WaterConfig {
        &self.water_config
    }

    /// The water tile `(z, x, y)`: depth (m, 0 where dry) and surface level (m, NaN where dry).
    pub fn water_tile(
        &self,
        z: u8,
        x: u32,
        y: u32,
    ) -> Result<(Array2<f32>, Array2<f32>), TileError> {
        self.check_tile(z, x, y)?;
        let t = self
            .water
            .tile(&self.elevation, z, i64::from(x), i64::from(y))?;
        Ok((t[DEPTH].clone(), t[LEVEL].clone()))
    }

    /// Water depth over an arbitrary window of zoom `z` (m, 0 where dry).
    pub fn water_depth_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        self.water.depth_window(&self.elevation, z, w)
    }

    /// The vegetation tile `(z, x, y)`: one density grid (0–1) per species.
    pub fn vegetation_tile(
        &self,
        z: u8,
        x: u32,
        y: u32,
    ) -> Result<Arc<Vec<Array2<f32>>>, TileError> {
        self.check_tile(z, x, y)?;
        self.vegetation
            .tile(self.inputs(), z, i64::from(x), i64::from(y))
    }

    /// Vegetation over an arbitrary window of zoom `z`, one grid per species.
    pub fn vegetation_window(&self, z: u8, w: Window) -> Result<Vec<Array2<f32>>, TileError> {
        self.vegetation.window(self.inputs(), z, w)
    }

    /// Material weights of tile `(z, tx, ty)` of the plane (no check that it meets the world)
    /// and its hillshade, computed: [`World::material_tile`] without the check and the cache.
    pub fn material_weights_at(&self, z: u8, tx: i64, ty: i64) -> Result<MaterialTile, TileError> {
        materials::material_tile(
            &self.landscape,
            &self.vegetation,
            &self.classes,
            self.inputs(),
            z,
            tx,
            ty,
        )
    }

    /// Normalised material weights over window `w` of zoom `z` (no check that it meets the
    /// world), equal bit for bit to the same window of the tiles' weights.
    pub fn material_window(&self, z: u8, w: Window) -> Result<Vec<Array2<f32>>, TileError> {
        self.materials_and_vegetation(z, w).map(|m| m.weights)
    }

    /// The material weights, hillshade and vegetation of window `w` of zoom `z` at once (no
    /// check that it meets the world): [`World::material_window`] and
    /// [`World::vegetation_window`] with the vegetation assembled once.
    pub fn materials_and_vegetation(
        &self,
        z: u8,
        w: Window,
    ) -> Result<materials::MaterialWindow, TileError> {
        materials::material_window(
            &self.landscape,
            &self.vegetation,
            &self.classes,
            self.inputs(),
            z,
            w,
        )
    }

    /// Normalised material weights of tile `(z, x, y)` (one grid per material, summing to 1),
    /// and the tile's hillshade (0–1), from the material cache: a tile's two splat sets and its
    /// colour map compute them once.
    pub fn material_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<MaterialTile>, TileError> {
        self.check_tile(z, x, y)?;
        let (tx, ty) = (i64::from(x), i64::from(y));
        self.materials
            .get_or_compute((z, tx, ty), || self.material_weights_at(z, tx, ty))
    }
}
