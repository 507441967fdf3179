//! Layers derived from an exemplar's elevation at build time and carried by every atom:
//! `log_area` (log10 of the D8 upstream area in m², after priority-flood filling) and `northness`
//! (cosine of the aspect, 0 on flat cells). The same derivation runs on amplification inputs when
//! the matching weights use these layers.

use ndarray::Array2;

use super::atoms::LayerKind;
use crate::analysis;
use crate::raster::CellSizes;

/// Name of the derived log10 upstream-area layer.
pub const LOG_AREA: &str = "log_area";
/// Name of the derived northness layer.
pub const NORTHNESS: &str = "northness";

/// The derived layers of a filled (NaN-free) elevation grid with metric cell sizes `cells`.
pub fn derived_layers(
    elevation: &Array2<f32>,
    cells: &CellSizes,
) -> Vec<(String, Array2<f32>, LayerKind)> {
    let filled = analysis::priority_flood_fill(elevation);
    let area = analysis::flow_accumulation_d8(&filled, cells);
    vec![
        (
            LOG_AREA.to_string(),
            analysis::log_upstream_area(&area),
            LayerKind::Continuous,
        ),
        (
            NORTHNESS.to_string(),
            analysis::northness(elevation, cells),
            LayerKind::Continuous,
        ),
    ]
}
