//! Errors of the tiles module: requests for tiles that do not exist, and failures to encode or
//! decode tile bytes. The server maps [`TileError::OutOfRange`] and [`TileError::ZoomTooDeep`] to
//! 404 and the others to 500 (encoding) or 400 (decoding of uploaded bytes).

use thiserror::Error;

/// An error addressing, encoding or decoding a tile.
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
    /// Amplification failed (an internal error).
    #[error("synthesis failed: {0}")]
    Synthesis(String),
    /// Tile bytes could not be produced.
    #[error("cannot encode tile: {0}")]
    Encode(String),
    /// Tile bytes could not be read back.
    #[error("cannot decode tile: {0}")]
    Decode(String),
}
