//! Splat weights and the colour map's inputs for a tile (with the `water` material of submerged
//! pixels, see [`crate::water`]): per-pixel functions of the tile's
//! elevation (slope, northness and curvature from a one-pixel border), wetness (log10 of the
//! drainage), vegetation and land-cover class weights ([`crate::classes`]), so they are seamless and deterministic whenever those are.

use ndarray::Array2;

use terrasynth_core::landscape::{self, LandscapeConfig, LayerInputs};
use terrasynth_core::synth::Window;

use crate::cancel::join;
use crate::classes::ClassWeights;
use crate::coverage::mask_in_place;
use crate::error::TileError;
use crate::mercator::pixel_size_m;
use crate::pyramid::{tile_window, LevelTile};
use crate::terrain::Terrain;
use crate::vegetation::{wetness, Inputs, VegetationLevels};
use crate::water::zero_under_water;

/// Name of the material of submerged pixels: a landscape material of that name, else one
/// appended after the landscape's materials.
pub const WATER_MATERIAL: &str = "water";

/// Index of the `water` material among the splat weights: the landscape's material of that name,
/// else `materials.len()` (appended).
pub fn water_index(landscape: &LandscapeConfig) -> usize {
    landscape
        .materials
        .iter()
        .position(|m| m.name == WATER_MATERIAL)
        .unwrap_or(landscape.materials.len())
}

/// The names of the splat weights in order: the landscape's materials, then `water` unless the
/// landscape has a material of that name.
pub fn splat_names(landscape: &LandscapeConfig) -> Vec<&str> {
    let mut v: Vec<&str> = landscape
        .materials
        .iter()
        .map(|m| m.name.as_str())
        .collect();
    if water_index(landscape) == v.len() {
        v.push(WATER_MATERIAL);
    }
    v
}

/// Normalised material weights of tile `(z, tx, ty)` (one grid per name of [`splat_names`]:
/// submerged pixels are all `water`; summing to the pixel's coverage: 1 inside the base, 0 outside it, see [`crate::coverage`]), and the tile's
/// hillshade (0–1): [`material_window`] over the tile.
pub fn material_tile(
    landscape: &LandscapeConfig,
    vegetation: &VegetationLevels,
    classes: &ClassWeights,
    inputs: Inputs<'_>,
    z: u8,
    tx: i64,
    ty: i64,
) -> Result<MaterialTile, TileError> {
    material_window(
        landscape,
        vegetation,
        classes,
        inputs,
        z,
        tile_window(tx, ty),
    )
    .map(|m| MaterialTile {
        weights: m.weights,
        shade: m.shade,
    })
}

/// A tile's material weights and hillshade: what its splat sets and its colour map read, kept
/// in a level cache as one tile (the weights' planes, then the shade) so that they share one
/// computation.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialTile {
    /// Normalised weights, one grid per name of [`splat_names`].
    pub weights: Vec<Array2<f32>>,
    /// Hillshade, 0–1.
    pub shade: Array2<f32>,
}

impl LevelTile for MaterialTile {
    fn planes(&self) -> usize {
        self.weights.len() + 1
    }
    fn plane(&self, k: usize) -> &Array2<f32> {
        self.weights.get(k).unwrap_or(&self.shade)
    }
    fn from_planes(mut planes: Vec<Array2<f32>>) -> Self {
        let shade = planes.pop().unwrap_or_else(|| Array2::zeros((0, 0)));
        MaterialTile {
            weights: planes,
            shade,
        }
    }
}

/// A window's material weights, its hillshade and the species densities the weights read.
#[derive(Debug)]
pub struct MaterialWindow {
    /// Normalised weights, one grid per name of [`splat_names`].
    pub weights: Vec<Array2<f32>>,
    /// Hillshade, 0–1.
    pub shade: Array2<f32>,
    /// The window's vegetation, one grid per species (what [`VegetationLevels::window`] gives).
    pub vegetation: Vec<Array2<f32>>,
}

/// Normalised material weights over an arbitrary window `w` of zoom `z`, its hillshade and its
/// vegetation (the instance tiles' rules read both weights and densities). Every
/// input is per pixel (the derivatives read a one-pixel border), so the weights of a window are
/// those of the tiles it covers, bit for bit, without computing those whole tiles (the instance
/// tiles' halos need only a strip of each neighbour).
pub fn material_window(
    landscape: &LandscapeConfig,
    vegetation: &VegetationLevels,
    classes: &ClassWeights,
    inputs: Inputs<'_>,
    z: u8,
    w: Window,
) -> Result<MaterialWindow, TileError> {
    // The three inputs side by side: a cold window's drainage chain routes its parent levels
    // while the window's own elevation tiles are amplified, and the vegetation waits only for
    // what it shares with them (the same tiles, computed once).
    let (terrain, (area, veg)) = join(
        || Terrain::of(inputs.elevation, z, w),
        || {
            join(
                || {
                    inputs
                        .drainage
                        .window(inputs.elevation, inputs.whole, inputs.water, z, w)
                },
                || vegetation.window(inputs, z, w),
            )
        },
    );
    let (terrain, area, veg) = (terrain?, area?, veg?);
    let wet = wetness(&area);
    // Only the classes (and biomes) a material names are sampled.
    let class_weights: Vec<(String, Array2<f32>)> = if landscape
        .materials
        .iter()
        .any(|m| !m.class.is_empty() || !m.biome.is_empty())
    {
        classes.window(z, w)
    } else {
        Vec::new()
    };
    let layer_inputs = LayerInputs {
        elevation: &terrain.elevation,
        slope: &terrain.slope,
        northness: &terrain.northness,
        curvature: &terrain.curvature,
        wetness: &wet,
        vegetation: &veg,
        classes: &class_weights,
        origin: (w.row0, w.col0),
        pixel_m: pixel_size_m(z),
    };
    let mut weights = landscape::material_weights(landscape, &layer_inputs);
    // Submerged pixels are all `water`.
    let depth = inputs.water.depth_window(inputs.elevation, z, w)?;
    let k = water_index(landscape);
    if k == weights.len() {
        weights.push(Array2::zeros((w.rows, w.cols)));
    }
    for (i, m) in weights.iter_mut().enumerate() {
        if i != k {
            zero_under_water(m, &depth);
        }
    }
    ndarray::Zip::from(&mut weights[k])
        .and(&depth)
        .for_each(|v, &d| {
            if d > 0.0 {
                *v = 1.0;
            }
        });
    let coverage = inputs.elevation.coverage_window(z, w)?;
    for m in &mut weights {
        mask_in_place(m, &coverage);
    }
    Ok(MaterialWindow {
        weights,
        shade: terrain.shade,
        vegetation: veg,
    })
}
