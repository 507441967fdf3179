//! The embedded rasters ([`crate::assets`]), decoded: the default world's base and exemplar, the
//! real western Tien Shan (GEBCO 2023, 15″ cells, EPSG:4326), and the default world's deep-zoom
//! exemplar, 2 m lidar of the Carrizo Plain (EPSG:26911).

use super::error::RasterError;
use super::geotiff::read_geotiff;
use super::grid::Grid;
use super::ReadLimits;
use crate::assets::{CARRIZO_TIF, TIENSHAN_TIF};

/// The embedded Tien Shan grid, decoded.
pub fn tienshan() -> Result<Grid, RasterError> {
    read_geotiff(TIENSHAN_TIF, &ReadLimits::default())
}

/// The default dictionary's exemplar (the embedded Tien Shan grid).
pub fn default_exemplar() -> Result<Grid, RasterError> {
    tienshan()
}

/// The embedded Carrizo Plain lidar (2 m cells, EPSG:26911), decoded.
pub fn carrizo() -> Result<Grid, RasterError> {
    read_geotiff(CARRIZO_TIF, &ReadLimits::default())
}
