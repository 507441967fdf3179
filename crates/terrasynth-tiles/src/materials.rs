//! Splat weights and the colour map's inputs for a tile: per-pixel functions of the tile's
//! elevation (slope, northness and curvature from a one-pixel border), wetness (log10 of the
//! drainage) and vegetation, so they are seamless and deterministic whenever those are.

use ndarray::Array2;

use terrasynth_core::landscape::{self, LandscapeConfig, LayerInputs};

use crate::error::TileError;
use crate::mercator::pixel_size_m;
use crate::pyramid::tile_window;
use crate::terrain::Terrain;
use crate::vegetation::{wetness, Inputs, VegetationLevels};

/// Normalised material weights of tile `(z, tx, ty)` (one grid per material, summing to 1), and
/// the tile's hillshade (0–1).
pub fn material_tile(
    landscape: &LandscapeConfig,
    vegetation: &VegetationLevels,
    inputs: Inputs<'_>,
    z: u8,
    tx: i64,
    ty: i64,
) -> Result<(Vec<Array2<f32>>, Array2<f32>), TileError> {
    let w = tile_window(tx, ty);
    let terrain = Terrain::of(inputs.elevation, z, w)?;
    let area = inputs
        .drainage
        .tile(inputs.elevation, inputs.whole, z, tx, ty)?;
    let wet = wetness(&area);
    let veg = vegetation.tile(inputs, z, tx, ty)?;
    let layer_inputs = LayerInputs {
        elevation: &terrain.elevation,
        slope: &terrain.slope,
        northness: &terrain.northness,
        curvature: &terrain.curvature,
        wetness: &wet,
        vegetation: &veg,
        origin: (w.row0, w.col0),
        pixel_m: pixel_size_m(z),
    };
    Ok((
        landscape::material_weights(landscape, &layer_inputs),
        terrain.shade,
    ))
}
