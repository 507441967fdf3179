//! Worlds: loading the configured worlds (resolve each base raster, find the world's dictionary
//! in the store by an alias derived from its build settings or build it there on first start,
//! with a log line per stage), assembling worlds the admin API created from their resolved
//! definitions, and computing their whole-world landscape layers in the background. A world
//! whose cache share cannot hold its whole-world layers is refused when created through the
//! admin API and loaded with a warning otherwise ([`share_shortfall`]).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, OnceLock};
use std::time::{Instant, UNIX_EPOCH};

use sha2::{Digest, Sha256};

use terrasynth_core::dictionary::build::{build, BuildOptions, Exemplar};
use terrasynth_core::dictionary::{
    build_gradient_tiles, exemplar_plane, AmplifierKind, AnyDictionary, Dictionary,
    ExemplarOptions, GradientTileSet, Learning,
};
use terrasynth_core::landscape::{exemplar_vegetation, WaterConfig};
use terrasynth_core::raster::{
    embedded, read_geotiff_file, read_png_rgb, Grid, ReadLimits, SquareCells,
};
use terrasynth_store::{ResolvedWorld, Store, Stored};
use terrasynth_tiles::{
    ControlMode, DictionaryBand, LayerStore, Obtained, SpeciesControl, TileError, World,
    WorldBiome, WorldClasses, WorldParts,
};

use super::error::StartupError;
use crate::config::{Config, DictionaryConfig, WorldConfig, EMBEDDED_CARRIZO, EMBEDDED_TIENSHAN};

/// The worlds a server serves, by name.
pub type Worlds = BTreeMap<String, Arc<World>>;

/// A world-loading error of world `world`.
fn world_error(world: &WorldConfig) -> impl Fn(String) -> StartupError + '_ {
    move |message| StartupError::World {
        world: world.name.clone(),
        message,
    }
}

fn load_raster(spec: &str, dir: &Path) -> Result<Grid, String> {
    if spec == EMBEDDED_TIENSHAN {
        return embedded::tienshan().map_err(|e| format!("embedded raster: {e}"));
    }
    if spec == EMBEDDED_CARRIZO {
        return embedded::carrizo().map_err(|e| format!("embedded raster: {e}"));
    }
    let path = dir.join(spec);
    read_geotiff_file(&path, &ReadLimits::default()).map_err(|e| format!("{}: {e}", path.display()))
}

/// The land-cover classes of world file `wc` on its base `base` (`None` without `[classes]`):
/// the `raster` GeoTIFF with a `legend`, or the `rgb` PNG (placed on the base's grid) with `hsv`.
fn load_classes(wc: &WorldConfig, base: &Grid) -> Result<Option<WorldClasses>, String> {
    let Some(c) = &wc.classes else {
        return Ok(None);
    };
    let raster = match (&c.raster, &c.rgb, c.hsv.is_empty()) {
        (Some(path), None, true) => {
            load_raster(path, &wc.dir).map_err(|e| format!("classes.raster: {e}"))?
        }
        (None, Some(path), false) => {
            let path = wc.dir.join(path);
            let bytes = std::fs::read(&path)
                .map_err(|e| format!("classes.rgb: {}: {e}", path.display()))?;
            read_png_rgb(&bytes, base.georef, &ReadLimits::default())
                .map_err(|e| format!("classes.rgb: {}: {e}", path.display()))?
        }
        _ => {
            return Err(
                "[classes] takes `raster` with a `legend`, or `rgb` with `hsv` ranges".into(),
            )
        }
    };
    Ok(Some(WorldClasses {
        config: c.config(),
        raster,
    }))
}

/// A stable name for the dictionary (or gradient tile set) a world's settings `d` produce (one of
/// its bands).
fn dictionary_alias(world: &WorldConfig, d: &DictionaryConfig) -> String {
    let mut h = Sha256::new();
    if d.amplifier == AmplifierKind::Gradient {
        h.update(format!(
            "gradient-v1|{:?}|{:?}|{}",
            d.exemplars,
            d.gradient_params(),
            world.dir.display()
        ));
    } else {
        h.update(dictionary_alias_text(world, d));
    }
    let digest = h.finalize();
    let hex: String = digest.iter().take(8).map(|b| format!("{b:02x}")).collect();
    format!("world-{}-{hex}", world.name)
}

/// What the alias of a dictionary band hashes. v3: exemplars on longitude/latitude grids are
/// resampled to square cells, so dictionaries stored under v2 are rebuilt. v4: that resampling
/// no longer overshoots (main-lobe clamp), so v3 dictionaries are rebuilt.
fn dictionary_alias_text(world: &WorldConfig, d: &DictionaryConfig) -> String {
    format!(
        "v4|{:?}|{}|{}|{}|{}|{}|{:?}|{:?}|{:?}",
        d.exemplars,
        d.atoms,
        d.patch,
        d.stride,
        d.seed,
        world.dir.display(),
        // The vegetation layers derived at build time depend on the niche model.
        world.landscape.species,
        world.landscape.clustering,
        d.vegetation_rasters,
    )
}

/// Builds the gradient tile set of a world's `amplifier = "gradient"` band from its exemplars.
fn build_gradient(world: &WorldConfig, cfg: &DictionaryConfig) -> Result<GradientTileSet, String> {
    let params = cfg.gradient_params()?;
    let t = Instant::now();
    let mut planes = Vec::with_capacity(cfg.exemplars.len());
    for spec in &cfg.exemplars {
        planes.push(exemplar_plane(&load_raster(spec, &world.dir)?, &[]));
    }
    let set = build_gradient_tiles(&planes, &params)
        .map_err(|e| format!("building the gradient tile set: {e}"))?;
    tracing::info!(world = %world.name, seconds = t.elapsed().as_secs_f64(), "gradient tile set: built");
    Ok(set)
}

fn build_dictionary(world: &WorldConfig, cfg: &DictionaryConfig) -> Result<Dictionary, String> {
    for (species, rasters) in &cfg.vegetation_rasters {
        if !world.landscape.species.iter().any(|s| &s.name == species) {
            return Err(format!("vegetation raster for unknown species `{species}`"));
        }
        if rasters.len() != cfg.exemplars.len() {
            return Err(format!(
                "species `{species}`: {} vegetation rasters for {} exemplars",
                rasters.len(),
                cfg.exemplars.len()
            ));
        }
    }
    let mut exemplars = Vec::new();
    for (e, spec) in cfg.exemplars.iter().enumerate() {
        let t = Instant::now();
        let grid = load_raster(spec, &world.dir)?;
        // The exemplar's own vegetation rasters replace the niche model's layers: read them
        // first, so that the species hook below cannot fail.
        let mut rasters = BTreeMap::new();
        let square = SquareCells::for_grid(&grid.georef, grid.rows(), grid.cols());
        for (name, paths) in &cfg.vegetation_rasters {
            let Some(path) = paths.get(e).filter(|p| !p.is_empty()) else {
                continue;
            };
            let v = load_raster(path, &world.dir)?;
            if v.data.dim() != grid.data.dim() {
                return Err(format!(
                    "vegetation raster {path} is {:?}, exemplar {spec} is {:?}",
                    v.data.dim(),
                    grid.data.dim()
                ));
            }
            let density = v.data.mapv(|d| {
                if d.is_finite() {
                    d.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            });
            // On the squared cells the exemplar's elevation takes (see `Exemplar::from_grid`).
            let density = square
                .resample(&density)
                .map_err(|e| format!("vegetation raster {path}: {e}"))?
                .mapv(|d| d.clamp(0.0, 1.0));
            rasters.insert(name.clone(), density);
        }
        let options = ExemplarOptions {
            derive: true,
            ..ExemplarOptions::default()
        };
        let ex = Exemplar::from_grid(&grid, options, |filled, cells| {
            let mut layers = exemplar_vegetation(&world.landscape, filled, cells);
            for (name, values, _) in layers.iter_mut() {
                if let Some(density) = rasters.remove(name) {
                    *values = density;
                }
            }
            layers
        })
        .map_err(|e| format!("exemplar {spec}: {e}"))?;
        tracing::info!(world = %world.name, exemplar = %spec, seconds = t.elapsed().as_secs_f64(), "dictionary: exemplar read and layers derived");
        exemplars.push(ex);
    }
    let opts = BuildOptions {
        patch: cfg.patch,
        stride: cfg.stride,
        atoms: cfg.atoms,
        learning: Learning::Medoids { iterations: 6 },
        seed: cfg.seed,
        sparsity: 1,
    };
    let t = Instant::now();
    let mut last = String::new();
    let d = build(&exemplars, &opts, &mut |stage, _| {
        if stage != last {
            tracing::info!(world = %world.name, stage, "dictionary: stage");
            last = stage.to_string();
        }
    })
    .map_err(|e| format!("building the dictionary: {e}"))?;
    tracing::info!(world = %world.name, atoms = d.n_atoms, seconds = t.elapsed().as_secs_f64(), "dictionary: built");
    Ok(d)
}

/// The dictionary (or gradient tile set, by the band's `amplifier`) of `world`'s settings `cfg`
/// from the store, building and storing it when absent (or unreadable, or of the other kind).
fn world_dictionary(
    store: &Store,
    world: &WorldConfig,
    cfg: &DictionaryConfig,
) -> Result<(AnyDictionary, String), StartupError> {
    let alias = dictionary_alias(world, cfg);
    let what = cfg.amplifier.file_noun();
    if let Some(id) = store.alias(&alias)? {
        match store.get_any_dictionary(&id) {
            Ok(Some(d)) if d.kind() == cfg.amplifier => {
                tracing::info!(world = %world.name, id = %id, "{what}: loaded from the store");
                return Ok((d, id));
            }
            Ok(Some(_)) => {
                tracing::warn!(world = %world.name, id = %id, "{what}: alias points at the other kind; rebuilding")
            }
            Ok(None) => {
                tracing::warn!(world = %world.name, id = %id, "{what}: alias points at a missing object; rebuilding")
            }
            Err(e) => {
                tracing::warn!(world = %world.name, error = %e, "{what}: stored object unusable; rebuilding");
                // Out of the way, so that the rebuilt dictionary can take its place.
                store.quarantine(Stored::Dictionary, &id, &e)?;
            }
        }
    }
    tracing::info!(world = %world.name, "{what}: not in the store; building it");
    let d: AnyDictionary = match cfg.amplifier {
        AmplifierKind::Dictionary => {
            Arc::new(build_dictionary(world, cfg).map_err(world_error(world))?).into()
        }
        AmplifierKind::Gradient => {
            Arc::new(build_gradient(world, cfg).map_err(world_error(world))?).into()
        }
    };
    let id = store.put_any_dictionary(&d)?;
    store.set_alias(&alias, &id)?;
    tracing::info!(world = %world.name, id = %id, "{what}: stored");
    Ok((d, id))
}

/// Why `world`'s cache share cannot hold its whole-world layers and leave its level caches their
/// part, worded for the operator; `None` when it can.
pub fn share_shortfall(world: &World) -> Option<String> {
    let m = world.memory();
    if m.fits() {
        return None;
    }
    let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
    Some(format!(
        "the whole-world landscape layers of world `{}` need {:.1} MiB but its share of cache_mb \
         is {:.1} MiB: it will hold about {:.1} MiB more than its share; raise cache_mb so that \
         each world's share is at least {:.1} MiB",
        world.name(),
        mib(m.whole_world),
        mib(m.share),
        mib(m.whole_world + m.level_caches - m.share),
        mib(m.whole_world.saturating_mul(4).div_ceil(3)),
    ))
}

/// Loads every configured world, building missing dictionaries into `store`.
pub fn load_worlds(config: &Config, store: &Store) -> Result<Worlds, StartupError> {
    let mut worlds = Worlds::new();
    for wc in &config.worlds {
        let t = Instant::now();
        let base = load_raster(&wc.base, &wc.dir).map_err(world_error(wc))?;
        let classes = load_classes(wc, &base).map_err(world_error(wc))?;
        tracing::info!(world = %wc.name, rows = base.rows(), cols = base.cols(), "world: base loaded");
        let mut dictionaries = Vec::new();
        let mut biomes = Vec::new();
        for (i, b) in wc.biomes.iter().enumerate() {
            let name = b.name(i);
            let weight = load_raster(&b.weight, &wc.dir)
                .map_err(|e| world_error(wc)(format!("biomes[{i}].weight: {e}")))?;
            let (dictionary, id) = world_dictionary(store, wc, &b.dictionary)?;
            tracing::info!(world = %wc.name, biome = %name, id = %id, "world: biome ready");
            biomes.push(WorldBiome {
                name,
                dictionary,
                id,
                weight,
            });
        }
        let mut controls = Vec::new();
        for (i, c) in wc.controls.iter().enumerate() {
            let raster = load_raster(&c.raster, &wc.dir)
                .map_err(|e| world_error(wc)(format!("controls[{i}].raster: {e}")))?;
            controls.push(SpeciesControl {
                species: c.species.clone(),
                mode: c.mode,
                raster,
            });
        }
        // A biome world's dictionaries are its biomes'.
        let bands = if wc.biomes.is_empty() {
            wc.dictionary_bands()
        } else {
            Vec::new()
        };
        for (zooms, cfg) in bands {
            let (dictionary, id) = world_dictionary(store, wc, cfg)?;
            dictionaries.push(DictionaryBand {
                zooms,
                dictionary,
                id,
            });
        }
        let world = World::new(WorldParts {
            name: wc.name.clone(),
            title: if wc.title.is_empty() {
                wc.name.clone()
            } else {
                wc.title.clone()
            },
            attribution: wc.attribution.clone(),
            base,
            z_base: wc.z_base,
            max_zoom: wc.max_zoom,
            fill_m: wc.fill_m,
            dictionaries,
            weights: wc.weights.clone(),
            cache_bytes: config.server.level_cache_bytes(config.worlds.len()),
            landscape: wc.landscape.clone(),
            center: wc.center,
            sparsity: wc.sparsity,
            water: WaterConfig {
                sea_level_m: wc.sea_level_m,
                ..wc.water.clone()
            },
            classes,
            biomes,
            controls: Vec::new(),
        })
        .map_err(|e| world_error(wc)(e.to_string()))?;
        if let Some(why) = share_shortfall(&world) {
            tracing::warn!(world = %wc.name, "{why}");
        }
        tracing::info!(world = %wc.name, z_base = world.z_base(), max_zoom = world.max_zoom(), seconds = t.elapsed().as_secs_f64(), "world: ready");
        worlds.insert(wc.name.clone(), Arc::new(world));
    }
    Ok(worlds)
}

/// The world a resolved admin-API definition describes, with a cache share of `cache_bytes`
/// (CPU-bound: call it off the runtime).
pub fn world_from(resolved: ResolvedWorld, cache_bytes: u64) -> Result<World, TileError> {
    let def = resolved.definition;
    World::new(WorldParts {
        title: def.title.clone().unwrap_or_else(|| def.name.clone()),
        attribution: def.attribution.clone().unwrap_or_default(),
        center: def.center,
        sparsity: None,
        base: resolved.base,
        z_base: None,
        max_zoom: def.max_zoom,
        fill_m: def.fill_m,
        dictionaries: resolved
            .dictionaries
            .into_iter()
            .map(|d| DictionaryBand {
                zooms: d.zooms,
                dictionary: d.dictionary,
                id: d.id,
            })
            .collect(),
        weights: def.match_weights(),
        cache_bytes,
        landscape: resolved.landscape,
        water: WaterConfig {
            sea_level_m: def.sea_level_m,
            ..def.water.clone().unwrap_or_default()
        },
        classes: resolved
            .classes
            .map(|(config, raster)| WorldClasses { config, raster }),
        biomes: resolved
            .biomes
            .into_iter()
            .map(|b| WorldBiome {
                name: b.name,
                dictionary: b.dictionary,
                id: b.id,
                weight: b.weight,
            })
            .collect(),
        controls: resolved
            .controls
            .into_iter()
            .map(|(species, mode, raster)| SpeciesControl {
                species,
                mode: if mode == "scale" {
                    ControlMode::Scale
                } else {
                    ControlMode::Replace
                },
                raster,
            })
            .collect(),
        name: def.name,
    })
}

/// Prepares the whole-world landscape layers of `worlds` one after the other on a background
/// thread, so that the first landscape tile of a world does not pay for them (a request that
/// arrives first waits for the same computation). With a `store`, each world keeps its layers
/// there (`StoredLayers`, set before this returns, so that a request that starts them first
/// uses it too): read at the next start instead of computed (1.5 s for the default world).
pub fn prepare_landscapes(worlds: Vec<Arc<World>>, store: Option<Store>) {
    for world in &worlds {
        keep_landscape(world, store.as_ref());
    }
    let spawned = std::thread::Builder::new()
        .name("landscape-prepare".into())
        .spawn(move || {
            for world in worlds {
                prepare_landscape(&world, None);
            }
        });
    if let Err(e) = spawned {
        tracing::warn!("cannot start the landscape preparation thread: {e}");
    }
}

/// Keeps `world`'s whole-world layers in `store` (`StoredLayers`); nothing without a store or
/// when the running executable cannot be examined (`build_identity`). A world keeps the first
/// store it is given.
pub fn keep_landscape(world: &World, store: Option<&Store>) {
    if let (Some(store), Some(build)) = (store, build_identity()) {
        world.keep_landscape_in(Arc::new(StoredLayers {
            store: store.clone(),
            world: world.name().to_string(),
            build,
        }));
    }
}

/// Prepares `world`'s whole-world landscape layers now, on this thread, as
/// [`prepare_landscapes`] does on its own (kept in `store`, when given). For tools that need
/// them before their first tile (`terrasynth export` of landscape layers: the shards of an
/// export share one computation).
pub fn prepare_landscape(world: &World, store: Option<&Store>) {
    keep_landscape(world, store);
    let t = Instant::now();
    match world.prepare_landscape() {
        Ok(bytes) => tracing::info!(
            world = %world.name(),
            mib = bytes as f64 / f64::from(1u32 << 20),
            seconds = t.elapsed().as_secs_f64(),
            "world: whole-world landscape layers ready"
        ),
        Err(e) => tracing::warn!(
            world = %world.name(),
            error = %e,
            "world: whole-world landscape layers failed; landscape tiles will answer errors"
        ),
    }
}

/// A world's whole-world layers in the store (`landscape/{world}.layers`).
#[derive(Debug)]
struct StoredLayers {
    store: Store,
    world: String,
    build: &'static [u8],
}

impl LayerStore for StoredLayers {
    fn load(&self) -> Option<Vec<u8>> {
        self.store.get_landscape(&self.world).unwrap_or_else(|e| {
            tracing::warn!(world = %self.world, error = %e, "world: cannot read the stored whole-world layers");
            None
        })
    }

    fn save(&self, file: &[u8]) {
        if let Err(e) = self.store.put_landscape(&self.world, file) {
            tracing::warn!(world = %self.world, error = %e, "world: cannot store the whole-world layers");
        }
    }

    fn build(&self) -> &[u8] {
        self.build
    }

    fn obtained(&self, how: Obtained) {
        match how {
            Obtained::Read => {
                tracing::info!(world = %self.world, "world: whole-world layers read from the store")
            }
            Obtained::Computed => {
                tracing::info!(world = %self.world, "world: whole-world layers computed and stored")
            }
            Obtained::Refused(why) => tracing::info!(
                world = %self.world,
                reason = %why,
                "world: stored whole-world layers not used; computed and stored again"
            ),
        }
    }
}

/// Stands for the code that computes the whole-world layers in the key of their stored copy:
/// the package version and the running executable's length and modification time, so that any
/// rebuild refuses the copies of the build before. `None` when the executable cannot be
/// examined: the layers are computed and not stored then.
fn build_identity() -> Option<&'static [u8]> {
    static BUILD: OnceLock<Option<Vec<u8>>> = OnceLock::new();
    BUILD
        .get_or_init(|| {
            let meta = std::fs::metadata(std::env::current_exe().ok()?).ok()?;
            let modified = meta.modified().ok()?.duration_since(UNIX_EPOCH).ok()?;
            let id = format!(
                "terrasynth {} {} {}",
                env!("CARGO_PKG_VERSION"),
                meta.len(),
                modified.as_nanos()
            );
            Some(id.into_bytes())
        })
        .as_deref()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;
    use terrasynth_core::math;
    use terrasynth_core::raster::{write_geotiff_file, Georef};

    /// A world whose one exemplar is a 96² hilly GeoTIFF in a temporary directory, with the
    /// given `[dictionary.vegetation_rasters]` lines.
    fn world_with(dir: &Path, rasters: &str) -> WorldConfig {
        let hills = Array2::from_shape_fn((96, 96), |(r, c)| {
            2200.0
                + 300.0 * math::sinf(c as f32 * 0.07) * math::cosf(r as f32 * 0.05)
                + 2.0 * r as f32
        });
        write_geotiff_file(
            &Grid::new(hills, Georef::local_metric(30.0)),
            &dir.join("hills.tif"),
        )
        .unwrap();
        let mut w: WorldConfig = toml::from_str(&format!(
            "name = \"t\"\nbase = \"hills.tif\"\n[dictionary]\nexemplars = [\"hills.tif\"]\n\
             atoms = 8\npatch = 16\nstride = 16\n[dictionary.vegetation_rasters]\n{rasters}\n"
        ))
        .unwrap();
        w.dir = dir.to_path_buf();
        w
    }

    fn write_density(dir: &Path, name: &str, rows: usize, values: impl Fn(usize, usize) -> f32) {
        let grid = Grid::new(
            Array2::from_shape_fn((rows, 96), |(r, c)| values(r, c)),
            Georef::local_metric(30.0),
        );
        write_geotiff_file(&grid, &dir.join(name)).unwrap();
    }

    #[test]
    fn exemplar_vegetation_rasters_replace_the_derived_layers() {
        let dir = tempfile::tempdir().unwrap();
        // Spruce from a raster: 0.7 everywhere but a NaN row (read as 0) and a row of 1.5
        // (clamped to 1).
        write_density(dir.path(), "spruce.tif", 96, |r, _| match r {
            10 => f32::NAN,
            20 => 1.5,
            _ => 0.7,
        });
        let w = world_with(dir.path(), "spruce = [\"spruce.tif\"]");
        let d = build_dictionary(&w, &w.dictionary).unwrap();
        let spruce = d.layer_index("spruce").unwrap();
        let juniper = d.layer_index("juniper").unwrap();
        let mut spruce_values = std::collections::BTreeSet::new();
        let mut juniper_values = std::collections::BTreeSet::new();
        for i in 0..d.n_atoms {
            spruce_values.extend(d.hi_layer(i, spruce).iter().map(|v| v.to_bits()));
            juniper_values.extend(d.hi_layer(i, juniper).iter().map(|v| v.to_bits()));
        }
        let allowed = [0.0f32, 0.7, 1.0].map(f32::to_bits);
        assert!(spruce_values.iter().all(|v| allowed.contains(v)));
        assert!(spruce_values.contains(&0.7f32.to_bits()));
        // Juniper keeps its niche-model layer: more than the raster's three values.
        assert!(juniper_values.len() > 3, "{juniper_values:?}");
    }

    #[test]
    fn world_files_take_a_class_raster_or_an_rgb_image_on_the_base_grid() {
        let dir = tempfile::tempdir().unwrap();
        let w = world_with(dir.path(), "");
        let base = load_raster(&w.base, &w.dir).unwrap();
        // A class raster: 1 on the west half, 2 on the east half.
        write_density(
            dir.path(),
            "lc.tif",
            96,
            |_, c| if c < 48 { 1.0 } else { 2.0 },
        );
        write_density(dir.path(), "lc_small.tif", 64, |_, _| 1.0);
        // An RGB image: green west, grey east.
        let mut png = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut png, 96, 96);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut wr = enc.write_header().unwrap();
            let data: Vec<u8> = (0..96 * 96)
                .flat_map(|i| {
                    if i % 96 < 48 {
                        [30, 100, 40]
                    } else {
                        [150, 150, 150]
                    }
                })
                .collect();
            wr.write_image_data(&data).unwrap();
        }
        std::fs::write(dir.path().join("sat.png"), png).unwrap();
        let with = |classes: &str| {
            let mut w = w.clone();
            w.classes = Some(toml::from_str(classes).unwrap());
            load_classes(&w, &base)
        };
        let hsv =
            "hsv = [{ name = \"forest\", hsv = { h = [70, 170], s = [0.2, 1], v = [0, 0.6] } }, \
                   { name = \"rock\", hsv = { h = [0, 360], s = [0, 0.1], v = [0.3, 1] } }]";
        for classes in [
            "raster = \"lc.tif\"\nlegend = { \"1\" = \"forest\", \"2\" = \"rock\" }".to_string(),
            format!("rgb = \"sat.png\"\n{hsv}"),
        ] {
            let c = with(&classes).unwrap().unwrap();
            let weights = terrasynth_tiles::ClassWeights::of(&c, &base, true).unwrap();
            assert_eq!(weights.names(), ["forest", "rock"], "{classes}");
        }
        // Refused by name: a raster without a legend, an RGB image without ranges, a missing
        // file; a raster off the base's grid or a legend missing a value when weighed.
        for (classes, needle) in [
            (format!("raster = \"lc.tif\"\n{hsv}"), "[classes] takes"),
            ("rgb = \"sat.png\"".to_string(), "[classes] takes"),
            (
                "raster = \"nope.tif\"\nlegend = { \"1\" = \"a\" }".into(),
                "nope.tif",
            ),
        ] {
            let e = with(&classes).unwrap_err();
            assert!(e.contains(needle), "{classes}: {e}");
        }
        for (classes, needle) in [
            (
                "raster = \"lc_small.tif\"\nlegend = { \"1\" = \"a\" }",
                "base's grid",
            ),
            (
                "raster = \"lc.tif\"\nlegend = { \"1\" = \"a\" }",
                "raster value 2",
            ),
        ] {
            let c = with(classes).unwrap().unwrap();
            let e = terrasynth_tiles::ClassWeights::of(&c, &base, true)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{classes}: {e}");
        }
        // A material naming a class the file does not define is a configuration error.
        let text = "name = \"t\"\nbase = \"hills.tif\"\n[classes]\nraster = \"lc.tif\"\n\
                    legend = { \"1\" = \"forest\" }\n[landscape]\n[[landscape.materials]]\n\
                    name = \"bog\"\ncolour = [0, 0, 0]\nclass.wetland = { min = 0.5, max = 1 }\n";
        let e = crate::config::parse_world(text, "t.toml", dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown class `wetland`"), "{e}");
    }

    #[test]
    fn bad_vegetation_rasters_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        write_density(dir.path(), "small.tif", 64, |_, _| 0.5);
        for (lines, needle) in [
            ("oak = [\"small.tif\"]", "unknown species `oak`"),
            (
                "spruce = [\"small.tif\", \"small.tif\"]",
                "2 vegetation rasters for 1",
            ),
            (
                "spruce = [\"small.tif\"]",
                "vegetation raster small.tif is (64, 96)",
            ),
            ("spruce = [\"missing.tif\"]", "missing.tif"),
        ] {
            let w = world_with(dir.path(), lines);
            let err = build_dictionary(&w, &w.dictionary).unwrap_err().to_string();
            assert!(err.contains(needle), "{lines}: {err}");
        }
    }
}
