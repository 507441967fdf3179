//! Whole-world layers at the native zoom: priority-flood filling and D8 flow accumulation of the
//! whole base (upstream area in m², ending in the sea, nothing from outside the coverage), and the niche model with the seeding simulation for
//! vegetation (then the world's painted species controls, [`crate::controls`]). Drainage is global by nature, so it is computed once per world on a fixed window
//! of the native zoom's plane ([`crate::extent::Extent::world_window`]); the native-zoom tiles of
//! drainage and vegetation are cut out of it.

use std::sync::{Arc, OnceLock};

use ndarray::{s, Array2};
use sha2::{Digest, Sha256};
use terrasynth_core::raster::CellSizes;

use terrasynth_core::analysis;
use terrasynth_core::landscape::{vegetation, LandscapeConfig};

use crate::classes::ClassWeights;
use crate::controls::SpeciesControls;
use terrasynth_core::synth::Window;

use crate::cancel::uncancellable;
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

/// The whole-world layers of a world, computed once on first use (or ahead of time by
/// a background thread at start); concurrent users wait for the same computation.
#[derive(Debug)]
pub struct WholeWorld {
    landscape: Arc<LandscapeConfig>,
    classes: Arc<ClassWeights>,
    /// Painted controls of species densities ([`crate::controls`]).
    controls: SpeciesControls,
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
            layers: OnceLock::new(),
        }
    }

    /// The layers, computing them on first use. The computation is never cancelled (its result
    /// is kept for ever, so an abandoned request must not leave a cancellation in its place).
    pub fn get(&self, elevation: &ElevationLevels) -> Result<Arc<BaseLayers>, TileError> {
        self.layers
            .get_or_init(|| uncancellable(|| self.compute(elevation, None).map(|(l, _)| l)))
            .clone()
    }

    /// The layers as [`WholeWorld::get`] gives them, read from `stored` (a file of
    /// [`crate::layer_file`]) when that file was written by the build `build` for exactly these
    /// inputs, else computed; with the file to store when they were computed here. A file
    /// refused for any reason costs only the time to check it. The base water stored with the
    /// layers is installed into `elevation` too.
    pub fn restore(
        &self,
        elevation: &ElevationLevels,
        stored: Option<&[u8]>,
        build: &[u8],
    ) -> Result<Restored, TileError> {
        let mut outcome = Outcome::Computed(None);
        let layers = self
            .layers
            .get_or_init(|| {
                uncancellable(|| {
                    let (layers, how) = self.compute(elevation, Some((stored, build)))?;
                    outcome = how;
                    Ok(layers)
                })
            })
            .clone()?;
        let (loaded, to_store, refused) = match outcome {
            Outcome::Loaded => (true, None, None),
            Outcome::Computed(file) => (false, file, None),
            Outcome::Refused(why, file) => (false, file, Some(why)),
        };
        Ok(Restored {
            layers,
            loaded,
            to_store,
            refused,
        })
    }

    /// Computes the layers, or with `cache` (a stored file and the build) reads them from the
    /// file when its key is that of the inputs.
    fn compute(
        &self,
        elevation: &ElevationLevels,
        cache: Option<(Option<&[u8]>, &[u8])>,
    ) -> Result<(Arc<BaseLayers>, Outcome), TileError> {
        let inputs = gather(elevation, &self.landscape, &self.classes)?;
        let species = self.landscape.species.len();
        let key = cache.map(|(_, build)| inputs_key(&inputs, elevation, &self.landscape, build));
        let mut refused = None;
        if let (Some(key), Some((Some(bytes), _))) = (&key, cache) {
            match layer_file::decode(bytes, key, inputs.window, species) {
                Ok(file) => {
                    elevation.install_base_water(file.water.map(Arc::new));
                    let layers = BaseLayers {
                        window: file.window,
                        area: file.area,
                        vegetation: file.vegetation,
                    };
                    return Ok((self.finish(inputs.z, layers), Outcome::Loaded));
                }
                Err(why) => refused = Some(why),
            }
        }
        let water = elevation.base_water()?;
        let layers = derive(&inputs, water.as_deref(), &self.landscape);
        let file = key.map(|k| {
            let (w, area, veg) = (layers.window, &layers.area, &layers.vegetation);
            layer_file::encode(&k, w, area, veg, water.as_deref())
        });
        let how = match refused {
            Some(why) => Outcome::Refused(why, file),
            None => Outcome::Computed(file),
        };
        Ok((self.finish(inputs.z, layers), how))
    }

    /// The layers with the painted species controls applied.
    fn finish(&self, z: u8, mut layers: BaseLayers) -> Arc<BaseLayers> {
        self.controls
            .apply(z, layers.window, &mut layers.vegetation);
        Arc::new(layers)
    }
}

/// How [`WholeWorld::restore`] came by the layers.
enum Outcome {
    /// Read from the stored file.
    Loaded,
    /// Computed (no file given, or the layers were there already), with the file to store.
    Computed(Option<Vec<u8>>),
    /// Computed because the stored file was refused, with the file to store.
    Refused(Refused, Option<Vec<u8>>),
}

/// What [`WholeWorld::restore`] did.
#[derive(Debug)]
pub struct Restored {
    /// The layers.
    pub layers: Arc<BaseLayers>,
    /// Whether they were read from the stored file.
    pub loaded: bool,
    /// The file to store, when they were computed by this call.
    pub to_store: Option<Vec<u8>>,
    /// Why the stored file was not used, when one was given and refused.
    pub refused: Option<Refused>,
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
    let heights = elevation.window(z, window)?;
    let cells = extent.cell_sizes(z, window.row0, window.rows);
    let covered = elevation
        .coverage_window(z, window)?
        .mapv(|c| !crate::coverage::uncovered(c));
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
    let mut h = Sha256::new();
    let mut field = |name: &str, bytes: &[u8]| {
        h.update(name.as_bytes());
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    field("format", &layer_file::FORMAT_VERSION.to_le_bytes());
    field("build", build);
    let w = inputs.window;
    field(
        "window",
        format!("{} {} {} {} {}", inputs.z, w.col0, w.row0, w.cols, w.rows).as_bytes(),
    );
    field("heights", &f32_bytes(inputs.heights.iter()));
    let covered: Vec<u8> = inputs.covered.iter().map(|&c| u8::from(c)).collect();
    field("covered", &covered);
    let cells: Vec<u8> = (inputs.cells.dx.iter().chain(&inputs.cells.dy))
        .flat_map(|v| v.to_le_bytes())
        .collect();
    field("cells", &cells);
    field(
        "water",
        format!("{:?}", elevation.water_config()).as_bytes(),
    );
    field("landscape", format!("{landscape:?}").as_bytes());
    for (name, g) in &inputs.class_weights {
        field(&format!("class {name}"), &f32_bytes(g.iter()));
    }
    h.finalize().into()
}

fn f32_bytes<'a>(values: impl Iterator<Item = &'a f32>) -> Vec<u8> {
    values.flat_map(|v| v.to_le_bytes()).collect()
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
    // D8 on the filled surface: lakes pass their inflow on at their outlet; flow ends where it
    // enters the sea (sea cells are sinks) and nothing is routed from uncovered or sea cells.
    let mut receivers = analysis::d8_receivers(&analysis::priority_flood_fill(heights), cells);
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
