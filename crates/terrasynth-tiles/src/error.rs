//! Errors of the tiles crate: tiles that do not exist, worlds that cannot be built, synthesis and
//! encoding failures. Every variant is typed; the server maps the "does not exist" ones to 404,
//! decoding failures of client bytes to 400, and the rest to 500 without showing their details.

use thiserror::Error;

use terrasynth_core::landscape::LandscapeError;
use terrasynth_core::synth::Window;
use terrasynth_core::synth::{BandError, SynthError};

/// An error addressing, computing, encoding or decoding a tile, or building a world.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TileError {
    /// `x` or `y` lies outside `[0, 2^z)` (a 404 for clients).
    #[error("tile {z}/{x}/{y} does not exist")]
    OutOfRange {
        /// Zoom level.
        z: u8,
        /// Tile column.
        x: u32,
        /// Tile row (from the north).
        y: u32,
    },
    /// The zoom is deeper than the world (or the tile math) supports (a 404 for clients).
    #[error("zoom {z} is deeper than the maximum zoom {max}")]
    ZoomTooDeep {
        /// Requested zoom.
        z: u8,
        /// Deepest zoom served.
        max: u8,
    },
    /// The tile lies wholly outside the world's bounds (a 404 for clients).
    #[error("tile {z}/{x}/{y} lies outside the world")]
    OutsideWorld {
        /// Zoom level.
        z: u8,
        /// Tile column.
        x: u32,
        /// Tile row (from the north).
        y: u32,
    },
    /// A world's deepest zoom is not between its native zoom and 24.
    #[error("max_zoom {max_zoom} must lie between the native zoom {z_base} and 24")]
    ZoomRange {
        /// The deepest zoom asked for.
        max_zoom: u8,
        /// The world's native zoom.
        z_base: u8,
    },
    /// The world covers too many native-zoom pixels for its whole-world layers.
    #[error("the native-zoom window {0} is too large for whole-world layers")]
    WorldTooLarge(Window),
    /// The world's dictionary bands are inconsistent with its zooms.
    #[error("dictionaries: {0}")]
    Bands(#[from] BandError),
    /// Amplification failed.
    #[error(transparent)]
    Synth(#[from] SynthError),
    /// The world's landscape settings are invalid.
    #[error(transparent)]
    Landscape(#[from] LandscapeError),
    /// A world's painted biomes are invalid ([`crate::biomes`]).
    #[error("biomes: {0}")]
    Biomes(String),
    /// A world's painted species controls are invalid ([`crate::controls`]).
    #[error("controls: {0}")]
    Controls(String),
    /// Tile bytes could not be produced.
    #[error("cannot encode tile: {0}")]
    Encode(String),
    /// The base raster cannot be analysed (no valid cell).
    #[error("base raster: {0}")]
    Raster(String),
    /// Tile bytes could not be read back.
    #[error("cannot decode tile: {0}")]
    Decode(String),
    /// Nobody waits for the computation any more (its requests were abandoned): it stopped.
    #[error("the computation was abandoned: nobody waits for it any more")]
    Cancelled,
}
