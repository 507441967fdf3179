//! Terrain derivatives of a tile window — elevation, slope, northness, curvature and hillshade —
//! computed from the elevation over the window plus a one-pixel border read from the neighbouring
//! tiles, so that they are seamless across tile borders. Vegetation and materials use them.

use ndarray::{s, Array2};

use terrasynth_core::analysis;
use terrasynth_core::synth::Window;

use crate::elevation::ElevationLevels;
use crate::error::TileError;

/// Derivatives of the elevation over a window of one zoom.
#[derive(Debug)]
pub struct Terrain {
    /// Elevation, metres.
    pub elevation: Array2<f32>,
    /// Slope, degrees.
    pub slope: Array2<f32>,
    /// Northness (cosine of the aspect).
    pub northness: Array2<f32>,
    /// Curvature, 1/m (> 0 on ridges).
    pub curvature: Array2<f32>,
    /// Hillshade 0–1 under the default sun.
    pub shade: Array2<f32>,
}

impl Terrain {
    /// The derivatives over window `w` of zoom `z`.
    pub fn of(elevation: &ElevationLevels, z: u8, w: Window) -> Result<Terrain, TileError> {
        let b = Window::new(w.col0 - 1, w.row0 - 1, w.cols + 2, w.rows + 2);
        let e = elevation.window(z, b)?;
        let cells = elevation.extent().cell_sizes(z, b.row0, b.rows);
        let inner = |a: Array2<f32>| a.slice(s![1..=w.rows, 1..=w.cols]).to_owned();
        let [slope, northness, shade] = analysis::slope_northness_shade(
            &e,
            &cells,
            analysis::DEFAULT_AZIMUTH_DEG,
            analysis::DEFAULT_ALTITUDE_DEG,
        );
        Ok(Terrain {
            slope: inner(slope),
            northness: inner(northness),
            curvature: inner(analysis::curvature(&e, &cells)),
            shade: inner(shade),
            elevation: inner(e),
        })
    }
}
