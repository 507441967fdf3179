//! Rasters: grids on `ndarray::Array2<f32>` with a georeference (EPSG:4326, EPSG:3857 or a
//! projected CRS in metres: [`projection`]) and a nodata mask, reprojection of projected grids
//! onto longitude/latitude ([`reproject`]), multi-layer rasters, resampling to square cells ([`square`]), and the file formats terrasynth reads and writes (GeoTIFF,
//! 16-bit PNG, OpenEXR). Nothing here does HTTP or async work.

pub mod boxfilter;
pub mod embedded;
pub mod error;
pub mod georef;
pub mod geotiff;
pub mod grid;
pub mod io;
pub mod limits;
pub mod openexr;
pub mod png16;
pub mod projection;
pub mod reproject;
pub mod square;

pub use boxfilter::{box2, box_down2_rows, reduce2x2};
pub use error::RasterError;
pub use georef::{CellSizes, Crs, Georef};
pub use geotiff::{read_geotiff, read_geotiff_file, write_geotiff, write_geotiff_file};
pub use grid::{nan_where_invalid, Grid, LayeredRaster, ELEVATION};
pub use io::{read_raster_file, sniff, write_raster_file, RasterFormat};
pub use limits::ReadLimits;
pub use openexr::{read_exr, write_exr};
pub use png16::{read_png16, read_png_rgb, write_png16};
pub use square::SquareCells;
