//! Tiles: the pure, socket-free parts of serving Web Mercator XYZ tiles — the tile math
//! ([`mercator`]), sampling a georeferenced grid onto the Mercator pixel plane ([`resample`]),
//! encoding tile bytes ([`encode`]: terrarium and mapbox Terrain-RGB PNG, grey and RGBA PNG,
//! float32 OpenEXR), TileJSON documents ([`tilejson`]) and a world's tile pyramid ([`world`]).
//!
//! Everything here is deterministic: the bytes of a tile depend only on the inputs, never on the
//! clock, a global RNG, thread count or CPU features.

pub mod encode;
pub mod error;
pub mod layers;
pub mod mercator;
pub mod resample;
pub mod tilejson;
pub mod world;

pub use encode::{
    decode_float_exr, decode_mapbox_png, decode_terrarium_png, encode_float_exr, encode_gray_png,
    encode_mapbox_png, encode_rgba_png, encode_terrarium_png, NAN_FILL_HEIGHT_M,
};
pub use error::TileError;
pub use mercator::{
    ground_cell_m, lonlat_to_global_pixel, lonlat_to_mercator, mercator_to_lonlat, native_zoom,
    pixel_size_m, plane_cell_sizes, tile_bounds_lonlat, tile_range_for_bounds, validate_tile,
    MAX_LATITUDE, MAX_SUPPORTED_ZOOM, TILE_SIZE,
};
pub use resample::mercator_window_from_grid;
pub use tilejson::{TerrainEncoding, TileJson, DEFAULT_ATTRIBUTION, TILEJSON_VERSION};
pub use world::{World, WorldParts, WorldStats};
