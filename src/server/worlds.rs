//! Loading the configured worlds: resolve each base raster, find the world's dictionary in the
//! store (by an alias derived from its build settings) or build it there on first start, with a
//! log line per stage, then assemble the tile pyramid.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use sha2::{Digest, Sha256};

use super::error::ServerError;
use crate::config::{Config, DictionaryConfig, WorldConfig, EMBEDDED_TIENSHAN};
use crate::dictionary::build::{build, BuildOptions, Exemplar};
use crate::dictionary::derive::derived_layers;
use crate::dictionary::{Dictionary, Learning};
use crate::landscape::exemplar_vegetation;
use crate::raster::{embedded, read_geotiff_file, Grid, ReadLimits};
use crate::store::Store;
use crate::tiles::{World, WorldParts};

/// The worlds a server serves, by name.
pub type Worlds = BTreeMap<String, Arc<World>>;

fn load_raster(spec: &str, dir: &Path) -> Result<Grid, ServerError> {
    if spec == EMBEDDED_TIENSHAN {
        return embedded::tienshan()
            .map_err(|e| ServerError::Internal(format!("embedded raster: {e}")));
    }
    let path = dir.join(spec);
    read_geotiff_file(&path, &ReadLimits::default())
        .map_err(|e| ServerError::Internal(format!("{}: {e}", path.display())))
}

/// A stable name for the dictionary a world's settings produce.
fn dictionary_alias(world: &WorldConfig) -> String {
    let d = &world.dictionary;
    let mut h = Sha256::new();
    h.update(format!(
        "v2|{:?}|{}|{}|{}|{}|{}|{:?}|{:?}|{:?}",
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
    ));
    let digest = h.finalize();
    let hex: String = digest.iter().take(8).map(|b| format!("{b:02x}")).collect();
    format!("world-{}-{hex}", world.name)
}

fn build_dictionary(
    world: &WorldConfig,
    cfg: &DictionaryConfig,
) -> Result<Dictionary, ServerError> {
    for (species, rasters) in &cfg.vegetation_rasters {
        if !world.landscape.species.iter().any(|s| &s.name == species) {
            return Err(ServerError::Internal(format!(
                "vegetation raster for unknown species `{species}`"
            )));
        }
        if rasters.len() != cfg.exemplars.len() {
            return Err(ServerError::Internal(format!(
                "species `{species}`: {} vegetation rasters for {} exemplars",
                rasters.len(),
                cfg.exemplars.len()
            )));
        }
    }
    let mut exemplars = Vec::new();
    for (e, spec) in cfg.exemplars.iter().enumerate() {
        let t = Instant::now();
        let grid = load_raster(spec, &world.dir)?;
        let filled = grid
            .filled()
            .map_err(|e| ServerError::Internal(format!("exemplar {spec}: {e}")))?;
        let cells = grid.georef.cell_sizes(grid.rows());
        let mut layers = derived_layers(&filled, &cells);
        layers.extend(exemplar_vegetation(&world.landscape, &filled, &cells));
        // The exemplar's own vegetation rasters replace the derived layers.
        for (name, values, _) in layers.iter_mut() {
            let Some(path) = cfg.vegetation_rasters.get(name).and_then(|r| r.get(e)) else {
                continue;
            };
            if path.is_empty() {
                continue;
            }
            let v = load_raster(path, &world.dir)?;
            if v.data.dim() != filled.dim() {
                return Err(ServerError::Internal(format!(
                    "vegetation raster {path} is {:?}, exemplar {spec} is {:?}",
                    v.data.dim(),
                    filled.dim()
                )));
            }
            *values = v.data.mapv(|d| {
                if d.is_finite() {
                    d.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            });
        }
        tracing::info!(world = %world.name, exemplar = %spec, seconds = t.elapsed().as_secs_f64(), "dictionary: exemplar read and layers derived");
        let valid = grid.valid.clone();
        exemplars.push(Exemplar {
            elevation: filled,
            valid,
            cell_m: cells.mean_cell(),
            layers,
        });
    }
    let opts = BuildOptions {
        patch: cfg.patch,
        stride: cfg.stride,
        atoms: cfg.atoms,
        learning: Learning::Medoids { iterations: 6 },
        seed: cfg.seed,
    };
    let t = Instant::now();
    let mut last = String::new();
    let d = build(&exemplars, &opts, &mut |stage, _| {
        if stage != last {
            tracing::info!(world = %world.name, stage, "dictionary: stage");
            last = stage.to_string();
        }
    })
    .map_err(|e| ServerError::Internal(format!("building the dictionary: {e}")))?;
    tracing::info!(world = %world.name, atoms = d.n_atoms, seconds = t.elapsed().as_secs_f64(), "dictionary: built");
    Ok(d)
}

/// The world's dictionary from the store, building and storing it when absent (or unreadable).
fn world_dictionary(
    store: &Store,
    world: &WorldConfig,
) -> Result<(Arc<Dictionary>, String), ServerError> {
    let alias = dictionary_alias(world);
    if let Some(id) = store.alias(&alias)? {
        match store.get_dictionary(&id) {
            Ok(Some(d)) => {
                tracing::info!(world = %world.name, id = %id, "dictionary: loaded from the store");
                return Ok((Arc::new(d), id));
            }
            Ok(None) => {
                tracing::warn!(world = %world.name, id = %id, "dictionary: alias points at a missing object; rebuilding")
            }
            Err(e) => {
                tracing::warn!(world = %world.name, error = %e, "dictionary: stored object unusable; rebuilding")
            }
        }
    }
    tracing::info!(world = %world.name, "dictionary: not in the store; building it");
    let d = build_dictionary(world, &world.dictionary)?;
    let id = store.put_dictionary(&d)?;
    store.set_alias(&alias, &id)?;
    tracing::info!(world = %world.name, id = %id, "dictionary: stored");
    Ok((Arc::new(d), id))
}

/// Loads every configured world.
pub fn load_worlds(config: &Config) -> Result<Worlds, ServerError> {
    let store = Store::open(&config.server.store_dir)?;
    let mut worlds = Worlds::new();
    for wc in &config.worlds {
        let t = Instant::now();
        let base = load_raster(&wc.base, &wc.dir)?;
        tracing::info!(world = %wc.name, rows = base.rows(), cols = base.cols(), "world: base loaded");
        let (dictionary, dictionary_id) = world_dictionary(&store, wc)?;
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
            dictionary,
            dictionary_id,
            weights: wc.weights.clone(),
            cache_bytes: config.server.level_cache_bytes(config.worlds.len()),
            landscape: wc.landscape.clone(),
        })?;
        tracing::info!(world = %wc.name, z_base = world.z_base(), max_zoom = world.max_zoom(), seconds = t.elapsed().as_secs_f64(), "world: ready");
        worlds.insert(wc.name.clone(), Arc::new(world));
    }
    Ok(worlds)
}

/// Computes the whole-world landscape layers of `worlds` one after the other on a background
/// thread ([`World::prepare_landscape`]), so that the first landscape tile of a world does not
/// pay for them; a request that arrives first waits for the same computation.
pub fn prepare_landscapes(worlds: Vec<Arc<World>>) {
    let spawned = std::thread::Builder::new()
        .name("landscape-prepare".into())
        .spawn(move || {
            for world in worlds {
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
        });
    if let Err(e) = spawned {
        tracing::warn!("cannot start the landscape preparation thread: {e}");
    }
}
