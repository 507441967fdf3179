//! Terrain analysis: slope, aspect, curvature, hillshade, priority-flood depression filling, D8
//! and MFD flow accumulation, flood extent, spectra and realism metrics. Pure functions, no IO.
//!
//! Grids are `Array2<f32>` of shape `(rows, cols)`, row 0 north, column 0 west, with metric
//! cell sizes per row from [`CellSizes`](crate::raster::CellSizes). Everything is
//! deterministic: single-threaded, fixed summation orders, no global state. Empty, tiny (< 3×3)
//! and NaN-containing grids never panic.
//!
//! - [`banks`]: V-shaped banks beside breached channels (an ablation lever; window-invariant).
//! - [`block_means`]: part of the volume breaching carved given back to each parent cell.
//! - [`breach`]: bounded, order-independent pit breaching (window-invariant).
//! - [`contour`]: contour lines by marching squares (window-invariant crossings), joined.
//! - [`derivatives`]: Horn gradient, slope, aspect, northness, curvature.
//! - [`hillshade`](mod@hillshade): ESRI/GDAL hillshade.
//! - [`flood`]: Priority-Flood (+ε) depression filling and flood extent; `rank_queue`: its
//!   queue.
//! - [`flow`]: D8 receivers, D8 and MFD flow accumulation.
//! - [`metrics`]: RMSE, relief, 1-Wasserstein, box down-sampling.
//! - [`fft`](mod@fft): the radix-2 / Bluestein FFT (1D, 2D) and its naive DFT.
//! - [`spectrum`]: radial band energy, and the correlation of two grids by band.
//! - [`realism`]: pixel-axis anisotropy of the spectrum, drainage density, curvature values.
//! - [`ppa`]: ridges and valleys (Profile-recognition and Polygon-breaking Algorithm), and their
//!   agreement with D8 drainage; [`ppa_naive`]: its references.
//! - [`naive`]: slow reference implementations for tests.

pub mod banks;
pub mod block_means;
pub mod breach;
mod common;
pub mod contour;
pub mod derivatives;
pub mod fft;
pub mod flats;
pub mod flood;
pub mod flow;
pub mod hillshade;
pub mod metrics;
pub mod naive;
pub mod ppa;
pub mod ppa_naive;
mod rank_queue;
pub mod realism;
pub mod spectrum;

use thiserror::Error;

pub use breach::breach_pits;
pub use common::{next_down, next_up};
pub use contour::{contour_lines, contour_segments, join_segments, ContourLine};
pub use derivatives::{
    aspect, curvature, gradient, northness, slope, slope_degrees, slope_northness_shade,
};
pub use fft::{dft_naive, fft, fft2, Complex, Radix2};
pub use flats::{d8_receivers_over_flats, resolve_flats};
pub use flood::{flood_extent, priority_flood_fill, priority_flood_fill_flat};
pub use flow::{
    accumulate_sources, d8_receivers, flow_accumulation_d8, flow_accumulation_from_receivers,
    flow_accumulation_mfd, log_upstream_area, D8_NONE, D8_OFFSETS, MFD_EXPONENT,
};
pub use hillshade::{hillshade, hillshade_u8, DEFAULT_ALTITUDE_DEG, DEFAULT_AZIMUTH_DEG};
pub use metrics::{box_down, relief, rmse, wasserstein1};
pub use realism::{
    axis_anisotropy, curvature_values, drainage_density, ANISOTROPY_WEDGE_DEG, CHANNEL_AREA_M2,
};
pub use spectrum::{band_correlations, band_energies, band_energy};

/// An error of an analysis function with preconditions on its arguments.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum AnalysisError {
    /// The grid's dimensions are not multiples of the down-sampling factor (or it is 0).
    #[error("a {rows}×{cols} grid cannot be box-averaged by a factor of {factor}")]
    NotDivisible {
        /// Grid rows.
        rows: usize,
        /// Grid columns.
        cols: usize,
        /// Requested factor.
        factor: usize,
    },
}
