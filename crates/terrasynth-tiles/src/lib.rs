//! terrasynth's tiles: everything between the numeric pipeline and the sockets. Web Mercator XYZ
//! math ([`mercator`]), a world's place on the planes ([`extent`]) and the base's data coverage
//! ([`coverage`]), resampling a georeferenced
//! grid onto a zoom's plane ([`resample`]), the one level pyramid every layer uses ([`pyramid`]:
//! get-or-compute with coalescing, window assembly, overviews, byte weighing), the layers' pyramids
//! ([`elevation`], [`drainage`], [`vegetation`], [`water`], the whole-world layers of the native zoom in
//! [`base_layers`], steered by painted species controls, [`controls`], per-tile [`terrain`] derivatives and [`materials`]), a world composed of them
//! ([`world`]) with a dictionary per zoom band ([`chain`]) or painted biomes ([`biomes`]), instances of plants and rocks as vector
//! tiles ([`instances`]), contour lines of the served elevation as vector tiles ([`contours`]),
//! tile requests ([`request`]), renderers ([`render`](mod@render)), encoders
//! ([`encode`]), TileJSON ([`tilejson`]), styles ([`style`]) and point queries of the served
//! elevation ([`point`]). Computations are coalesced and cancelled
//! cooperatively when nobody waits for them any more ([`cancel`]).
//!
//! Everything here is deterministic: the bytes of a tile depend only on the world and the
//! request, never on the clock, a global RNG, thread count, CPU features or cache state. No
//! sockets and no HTTP types: the server translates HTTP into these calls.

pub mod base_layers;
pub mod biomes;
pub mod cancel;
pub mod chain;
pub mod classes;
pub mod contours;
pub mod controls;
pub mod coverage;
pub mod drainage;
pub mod elevation;
pub mod encode;
pub mod error;
pub mod extent;
pub mod instances;
pub mod layer_file;
pub mod materials;
pub mod mercator;
pub mod point;
pub mod pyramid;
pub mod render;
pub mod request;
pub mod resample;
pub mod style;
pub mod terrain;
pub mod tilejson;
pub mod vegetation;
pub mod water;
pub mod wmts;
pub mod world;

pub use base_layers::{LayerStore, Obtained};
pub use biomes::{BiomeWeights, WorldBiome};
pub use cancel::{run_cancellable, uncancellable, CancelOnDrop, CancelToken, Flights};
pub use chain::{Chain, DictionaryBand};
pub use classes::{ClassWeights, WorldClasses};
pub use controls::{ControlMode, SpeciesControl, SpeciesControls};
pub use encode::{
    decode_float_exr, decode_mapbox_png, decode_terrarium_png, encode_float_exr, encode_gray_png,
    encode_mapbox_png, encode_mapbox_webp, encode_rgba_png, encode_rgba_webp, encode_terrarium_png,
    encode_terrarium_webp, gunzip, gzip, NAN_FILL_HEIGHT_M,
};
pub use error::TileError;
pub use extent::Extent;
pub use mercator::{
    ground_cell_m, lonlat_to_global_pixel, lonlat_to_mercator, mercator_to_lonlat, native_zoom,
    pixel_size_m, plane_cell_sizes, tile_bounds_lonlat, tile_range_for_bounds, validate_tile,
    MAX_LATITUDE, MAX_SUPPORTED_ZOOM, TILE_SIZE,
};
pub use render::render;
pub use request::{
    check_against_world, etag, parse_request, query_map, RequestError, TileKind, TileRequest,
};
pub use resample::mercator_window_from_grid;
pub use tilejson::{TerrainEncoding, TileJson, VectorLayer, DEFAULT_ATTRIBUTION, TILEJSON_VERSION};
pub use world::{MemoryPlan, World, WorldParts, WorldStats, TILE_BYTES_REVISION};
