//! Data embedded in the binary, so that a fresh clone (or an installed binary run from anywhere)
//! serves the default world without any file: the real western Tien Shan (GEBCO 2023, 15″ cells,
//! EPSG:4326), the Carrizo Plain lidar of its deep zooms (2 m, UTM 11N) and its world definition. A leaf module: constants only, decoded by their users
//! ([`crate::raster::embedded`], [`crate::landscape::LandscapeConfig::tienshan`] and the server's
//! configuration loader).

/// The GeoTIFF bytes of `config/data/tienshan_west_gebco15s.tif`.
pub const TIENSHAN_TIF: &[u8] = include_bytes!("../../../config/data/tienshan_west_gebco15s.tif");

/// The GeoTIFF bytes of `config/data/carrizo_lidar_2m.tif` (2 m lidar in EPSG:26911, the
/// default world's deep-zoom exemplar).
pub const CARRIZO_TIF: &[u8] = include_bytes!("../../../config/data/carrizo_lidar_2m.tif");

/// The default world's definition, `config/worlds/tienshan.toml`.
pub const TIENSHAN_WORLD_TOML: &str = include_str!("../../../config/worlds/tienshan.toml");
