//! The command line's error: every module error rolled up, with a message fit for a terminal.

use thiserror::Error;

use terrasynth_core::dictionary::DictionaryError;
use terrasynth_core::raster::RasterError;
use terrasynth_core::synth::SynthError;

/// An error of a command-line command.
#[derive(Debug, Error)]
pub enum CliError {
    /// Reading or writing a raster failed.
    #[error(transparent)]
    Raster(#[from] RasterError),
    /// Building, reading or writing a dictionary failed.
    #[error(transparent)]
    Dictionary(#[from] DictionaryError),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] terrasynth_store::StoreError),
    /// Amplification failed.
    #[error(transparent)]
    Synth(#[from] SynthError),
    /// An archive could not be written or read.
    #[error(transparent)]
    Archive(#[from] crate::archive::ArchiveError),
    /// A tile could not be computed or encoded.
    #[error(transparent)]
    Tile(#[from] terrasynth_tiles::TileError),
    /// Sketch synthesis failed (or the sketch is invalid).
    #[error(transparent)]
    Sketch(#[from] terrasynth_core::synth::sketch::SketchError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// An argument is malformed or inconsistent.
    #[error("invalid argument: {0}")]
    Usage(String),
}
