//! Rasters embedded in the binary: the default world's base and exemplar, the real western
//! Tien Shan (GEBCO 2023, 15″ cells, EPSG:4326), so that a fresh clone works without any file.

use super::error::RasterError;
use super::geotiff::read_geotiff;
use super::grid::Grid;
use super::ReadLimits;

/// The GeoTIFF bytes of `config/data/tienshan_west_gebco15s.tif`.
pub const TIENSHAN_TIF: &[u8] = include_bytes!("../../config/data/tienshan_west_gebco15s.tif");

/// The embedded Tien Shan grid, decoded.
pub fn tienshan() -> Result<Grid, RasterError> {
    read_geotiff(TIENSHAN_TIF, &ReadLimits::default())
}

/// The default dictionary's exemplar (the embedded Tien Shan grid).
pub fn default_exemplar() -> Result<Grid, RasterError> {
    tienshan()
}
