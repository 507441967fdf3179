//! The embedded rasters ([`crate::assets`]), decoded: the default world's base and exemplar, the
//! real western Tien Shan (GEBCO 2023, 15″ cells, EPSG:4326).

use super::error::RasterError;
use super::geotiff::read_geotiff;
use super::grid::Grid;
use super::ReadLimits;
use crate::assets::TIENSHAN_TIF;

/// The embedded Tien Shan grid, decoded.
pub fn tienshan() -> Result<Grid, RasterError> {
    read_geotiff(TIENSHAN_TIF, &ReadLimits::default())
}

/// The default dictionary's exemplar (the embedded Tien Shan grid).
pub fn default_exemplar() -> Result<Grid, RasterError> {
    tienshan()
}
