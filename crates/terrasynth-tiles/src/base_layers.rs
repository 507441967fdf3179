//! Whole-world layers at the native zoom: priority-flood filling and D8 flow accumulation of the
//! whole base (upstream area in m², ending in the sea, nothing from outside the coverage), and the niche model with the seeding simulation for
//! vegetation (then the world's painted species controls, [`crate::controls`]). Drainage is global by nature, so it is computed once per world on a fixed window
//! of the native zoom's plane ([`crate::extent::Extent::world_window`]); the native-zoom tiles of
//! drainage and vegetation are cut out of it. A world given a [`LayerStore`] reads them from it
//! instead when they were stored there for the same inputs by the same build, and stores them
//! after computing them ([`crate::layer_file`]).

use std::sync::{Arc, OnceLock};

use ndarray::{s, Array2};
use sha2::{Digest, Sha256};
use terrasynth_core::raster::CellSizes;

use terrasynth_core::analysis;
use terrasynth_core::landscape::{vegetation, LandscapeConfig};

use crate::classes::ClassWeights;
use crate::controls::SpeciesControls;
use terrasynth_core::synth::Window;

use crate::cancel::{join, uncancellable};
use crate::elevation::{BaseWater, ElevationLevels, MAX_WORLD_PIXELS};
use crate::error::TileError;
use crate::layer_file::{self, Refused};

/// Whole-world layers at the native zoom.
#[derive(Debug)]
pub struct BaseLayers {
    /// The window of the native zoom's plane they cover.
    pub window: Window,
    /// D8 upstream area, m².
    pub area: Array2<f32>,
    /// Vegetation densities, one grid per species.
    pub vegetation: Vec<Array2<f32>>,
}

/// Bytes the whole-world layers over `window` hold: the upstream area, one grid per species and,
/// for a world that may have water, the water's two grids ([`ElevationLevels::base_water`]; a
/// world without sea level or lakes never computes them), f32 each.
pub fn base_layer_bytes(window: Window, species: usize, water: bool) -> u64 {
    let grids = 1 + species as u64 + if water { 2 } else { 0 };
    (window.len() as u64).saturating_mul(4 * grids)
}

/// Copies the part of `a` (held over `aw`) that lies in `w` into a `w`-shaped grid, `fill`
/// elsewhere.
pub fn cut(a: &Array2<f32>, aw: Window, w: Window, fill: f32) -> Array2<f32> {
    let mut out = Array2::from_elem((w.rows, w.cols), fill);
    let c0 = w.col0.max(aw.col0);
    let c1 = w.col1().min(aw.col1());
    let r0 = w.row0.max(aw.row0);
    let r1 = w.row1().min(aw.row1());
    if c0 < c1 && r0 < r1 {
        out.slice_mut(s![
            (r0 - w.row0) as usize..(r1 - w.row0) as usize,
            (c0 - w.col0) as usize..(c1 - w.col0) as usize
        ])
        .assign(&a.slice(s![
            (r0 - aw.row0) as usize..(r1 - aw.row0) as usize,
            (c0 - aw.col0) as usize..(c1 - aw.col0) as usize
        ]));
    }
    out
}

/// The value of `a` (held over `aw`) at `(r, c)` of window `w`, 0 outside `aw`.
fn cut_at(a: &Array2<f32>, aw: Window, w: Window, r: usize, c: usize) -> f32 {
    let (gr, gc) = (w.row0 + r as i64 - aw.row0, w.col0 + c as i64 - aw.col0);
    if gr < 0 || gc < 0 {
        return 0.0;
    }
    a.get((gr as usize, gc as usize)).copied().unwrap_or(0.0)
}

/// Where one world's whole-world layers are kept between runs, as files of
/// [`crate::layer_file`] (the server's store). Whoever computes the layers first — the
/// background thread at start or a request — reads them from here when the stored file fits,
/// and stores them after computing them otherwise.
pub trait LayerStore: Send + Sync + std::fmt::Debug {
    /// The stored file, if any.
    fn load(&self) -> Option<Vec<u8>>;
    /// Stores `file` (failures are the store's to report: the layers are served either way).
    fn save(&self, file: &[u8]);
    /// Stands for the code that computes the layers: part of the file's key, so that another
    /// build never reads this one's file.
    fn build(&self) -> &[u8];
    /// Told how the layers were obtained: read from the stored file, or computed (with why the
    /// stored file was refused, when there was one).
    fn obtained(&self, how: Obtained);
}

/// How the whole-world layers were obtained, for [`LayerStore::obtained`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Obtained {
    /// Read from the stored file.
    Read,
    /// Computed: there was no stored file.
    Computed,
    /// Computed: the stored file was refused.
    Refused(Refused),
}

/// The whole-world layers of a world, computed once on first use (or ahead of time by
/// a background thread at start); concurrent users wait for the same computation. With a
/// [`LayerStore`] ([`WholeWorld::keep_in`]) they are read from it instead when stored there
/// for the same inputs by the same build.
#[derive(Debug)]
pub struct WholeWorld {
    landscape: Arc<LandscapeConfig>,
    classes: Arc<ClassWeights>,
    /// Painted controls of species densities ([`crate::controls`]).
    controls: SpeciesControls,
    store: OnceLock<Arc<dyn LayerStore>>,
    layers: OnceLock<Result<Arc<BaseLayers>, TileError>>,
}

impl WholeWorld {
    /// The whole-world layers of a world with this landscape, not computed yet; `controls`
    /// steer its species' densities.
    pub fn new(
        landscape: Arc<LandscapeConfig>,
        classes: Arc<ClassWeights>,
        controls: SpeciesControls,
    ) -> Self {
        WholeWorld {
            landscape,
            classes,
            controls,
            store: OnceLock::new(),
            layers: OnceLock::new(),
        }
    }

    /// Keeps the layers in `store` from now on (the first store given stays; no effect on
    /// layers already obtained).
    pub fn keep_in(&self, store: Arc<dyn LayerStore>) {
        let _ = self.store.set(store);
    }

    /// The layers, read from the store or computed on first use. The computation is never
    /// cancelled (its result is kept for ever, so an abandoned request must not leave a
    /// cancellation in its place).
    pub fn get(&self, elevation: &ElevationLevels) -> Result<Arc<BaseLayers>, TileError> {
        self.layers
            .get_or_init(|| uncancellable(|| self.obtain(elevation)))
            .clone()
    }

    /// Reads the layers from the store when its file's key is that of the inputs and this
    /// build, else computes them (and stores them).
    fn obtain(&self, elevation: &ElevationLevels) -> Result<Arc<BaseLayers>, TileError> {
        let store = self.store.get();
        // The stored file is read while the inputs are gathered and hashed.
        let (gathered, stored) = join(
            || -> Result<_, TileError> {
                let inputs = gather(elevation, &self.landscape, &self.classes)?;
                let key = store.map(|s| inputs_key(&inputs, elevation, &self.landscape, s.build()));
                Ok((inputs, key))
            },
            || store.and_then(|s| s.load()),
        );
        let (inputs, key) = gathered?;
        let mut how = Obtained::Computed;
        if let (Some(store), Some(key)) = (store, &key) {
            if let Some(bytes) = stored {
                let species = self.landscape.species.len();
                match layer_file::decode(&bytes, key, inputs.window, species) {
                    Ok(file) => {
                        drop(bytes);
                        elevation.install_base_water(file.water.map(Arc::new));
                        let layers = BaseLayers {
                            window: file.window,
                            area: file.area,
                            vegetation: file.vegetation,
                        };
                        store.obtained(Obtained::Read);
                        return Ok(self.finish(inputs.z, layers));
                    }
                    Err(why) => how = Obtained::Refused(why),
                }
            }
        }
        let water = elevation.base_water()?;
        let layers = derive(&inputs, water.as_deref(), &self.landscape);
        if let (Some(store), Some(key)) = (store, &key) {
            let (w, area, veg) = (layers.window, &layers.area, &layers.vegetation);
            store.save(&layer_file::encode(key, w, area, veg, water.as_deref()));
            store.obtained(how);
        }
        Ok(self.finish(inputs.z, layers))
    }

    /// The layers with the painted species controls applied.
    fn finish(&self, z: u8, mut layers: BaseLayers) -> Arc<BaseLayers> {
        self.controls
            .apply(z, layers.window, &mut layers.vegetation);
        Arc::new(layers)
    }
}

/// What the whole-world layers are computed from, besides the landscape and the classes'
/// settings.
struct Inputs {
    z: u8,
    window: Window,
    heights: Array2<f32>,
    cells: CellSizes,
    covered: Array2<bool>,
    /// Class (or biome) name and its weights.
    class_weights: Vec<(String, Array2<f32>)>,
}

fn gather(
    elevation: &ElevationLevels,
    landscape: &LandscapeConfig,
    classes: &ClassWeights,
) -> Result<Inputs, TileError> {
    let extent = elevation.extent();
    let z = extent.z_base;
    let window = extent.world_window(z);
    if window.len() > MAX_WORLD_PIXELS {
        return Err(TileError::WorldTooLarge(window));
    }
    let (heights, coverage) = join(
        || elevation.window(z, window),
        || elevation.coverage_window(z, window),
    );
    let heights = heights?;
    let covered = coverage?.mapv(|c| !crate::coverage::uncovered(c));
    let cells = extent.cell_sizes(z, window.row0, window.rows);
    let class_weights = if landscape
        .species
        .iter()
        .any(|s| !s.class.is_empty() || !s.biome.is_empty())
    {
        classes.window(z, window)
    } else {
        Vec::new()
    };
    Ok(Inputs {
        z,
        window,
        heights,
        cells,
        covered,
        class_weights,
    })
}

/// SHA-256 of everything the layers (and the base water stored with them) are computed from:
/// the native zoom's heights, coverage and cell sizes, the water and landscape settings, the
/// class weights, and `build`, which stands for the code that computes them.
fn inputs_key(
    inputs: &Inputs,
    elevation: &ElevationLevels,
    landscape: &LandscapeConfig,
    build: &[u8],
) -> [u8; 32] {
    let mut hasher = Sha256::new();
    let h = &mut hasher;
    field(h, "format", &layer_file::FORMAT_VERSION.to_le_bytes());
    field(h, "build", build);
    let w = inputs.window;
    let window = format!("{} {} {} {} {}", inputs.z, w.col0, w.row0, w.cols, w.rows);
    field(h, "window", window.as_bytes());
    f32_field(h, "heights", &inputs.heights);
    let covered: Vec<u8> = inputs.covered.iter().map(|&c| u8::from(c)).collect();
    field(h, "covered", &covered);
    let cells: Vec<u8> = (inputs.cells.dx.iter().chain(&inputs.cells.dy))
        .flat_map(|v| v.to_le_bytes())
        .collect();
    field(h, "cells", &cells);
    let water = format!("{:?}", elevation.water_config());
    field(h, "water", water.as_bytes());
    field(h, "landscape", format!("{landscape:?}").as_bytes());
    for (name, g) in &inputs.class_weights {
        f32_field(h, &format!("class {name}"), g);
    }
    hasher.finalize().into()
}

/// Hashes one named field of the key: its name, its length in bytes and its bytes.
fn field(h: &mut Sha256, name: &str, bytes: &[u8]) {
    h.update(name.as_bytes());
    h.update((bytes.len() as u64).to_le_bytes());
    h.update(bytes);
}

/// [`field`] of a grid's values as little-endian `f32` bytes in row-major order, without a copy
/// of the whole grid.
fn f32_field(h: &mut Sha256, name: &str, grid: &Array2<f32>) {
    h.update(name.as_bytes());
    h.update((4 * grid.len() as u64).to_le_bytes());
    let mut buffer = [0u8; 4 * 1024];
    let mut filled = 0;
    for v in grid.iter() {
        buffer[filled..filled + 4].copy_from_slice(&v.to_le_bytes());
        filled += 4;
        if filled == buffer.len() {
            h.update(buffer);
            filled = 0;
        }
    }
    h.update(&buffer[..filled]);
}

/// Drainage and vegetation (before the painted controls) from the gathered inputs and the base
/// water.
fn derive(inputs: &Inputs, water: Option<&BaseWater>, landscape: &LandscapeConfig) -> BaseLayers {
    let Inputs {
        window,
        heights,
        cells,
        covered,
        class_weights,
        ..
    } = inputs;
    let window = *window;
    let is_sea =
        |r: usize, c: usize| water.is_some_and(|w| cut_at(&w.sea, w.window, window, r, c) > 0.0);
    // D8 on the surface filled to its spill levels, flats drained towards their outlets and
    // away from higher ground (Barnes et al. 2014): lakes pass their inflow on at their outlet;
    // flow ends where it enters the sea (sea cells are sinks) and nothing is routed from
    // uncovered or sea cells.
    let mut receivers = analysis::d8_receivers_over_flats(
        &analysis::priority_flood_fill_flat(heights),
        cells,
        usize::MAX,
        None,
    );
    let sink = |r: usize, c: usize| is_sea(r, c) || !covered[[r, c]];
    for ((r, c), code) in receivers.indexed_iter_mut() {
        if is_sea(r, c) {
            *code = analysis::D8_NONE;
        }
    }
    let sources =
        Array2::from_shape_fn(
            heights.dim(),
            |(r, c)| if sink(r, c) { 0.0 } else { cells.area(r) },
        );
    let area64 = analysis::accumulate_sources(&receivers, &sources);
    drop(receivers);
    let wetness = analysis::log_upstream_area(&area64);
    let area = area64.mapv(|v| v as f32);
    drop(area64);
    let vegetation = vegetation::densities(
        landscape,
        heights,
        cells,
        &wetness,
        (window.row0, window.col0),
        class_weights,
    );
    BaseLayers {
        window,
        area,
        vegetation,
    }
}
