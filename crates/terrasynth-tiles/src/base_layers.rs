//! Whole-world layers at the native zoom: priority-flood filling and D8 flow accumulation of the
//! whole base (upstream area in m², ending in the sea, nothing from outside the coverage), and the niche model with the seeding simulation for
//! vegetation (then the world's painted species controls, [`crate::controls`]). Drainage is global by nature, so it is computed once per world on a fixed window
//! of the native zoom's plane ([`crate::extent::Extent::world_window`]); the native-zoom tiles of
//! drainage and vegetation are cut out of it.

use std::sync::{Arc, OnceLock};

use ndarray::{s, Array2};

use terrasynth_core::analysis;
use terrasynth_core::landscape::{vegetation, LandscapeConfig};

use crate::classes::ClassWeights;
use crate::controls::SpeciesControls;
use terrasynth_core::synth::Window;

use crate::cancel::uncancellable;
use crate::elevation::{ElevationLevels, MAX_WORLD_PIXELS};
use crate::error::TileError;

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
            .get_or_init(|| {
                uncancellable(|| {
                    compute(elevation, &self.landscape, &self.classes, &self.controls).map(Arc::new)
                })
            })
            .clone()
    }
}

fn compute(
    elevation: &ElevationLevels,
    landscape: &LandscapeConfig,
    classes: &ClassWeights,
    controls: &SpeciesControls,
) -> Result<BaseLayers, TileError> {
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
    let water = elevation.base_water()?;
    let is_sea = |r: usize, c: usize| {
        water
            .as_ref()
            .is_some_and(|w| cut_at(&w.sea, w.window, window, r, c) > 0.0)
    };
    // D8 on the filled surface: lakes pass their inflow on at their outlet; flow ends where it
    // enters the sea (sea cells are sinks) and nothing is routed from uncovered or sea cells.
    let mut receivers = analysis::d8_receivers(&analysis::priority_flood_fill(&heights), &cells);
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
    let class_weights = if landscape
        .species
        .iter()
        .any(|s| !s.class.is_empty() || !s.biome.is_empty())
    {
        classes.window(z, window)
    } else {
        Vec::new()
    };
    let mut vegetation = vegetation::densities(
        landscape,
        &heights,
        &cells,
        &wetness,
        (window.row0, window.col0),
        &class_weights,
    );
    controls.apply(z, window, &mut vegetation);
    Ok(BaseLayers {
        window,
        area,
        vegetation,
    })
}
