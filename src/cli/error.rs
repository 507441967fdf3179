//! The command line's error: every module error rolled up, with a message fit for a terminal.

use thiserror::Error;

use crate::dictionary::DictionaryError;
use crate::raster::RasterError;
use crate::synth::SynthError;

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
    Store(#[from] crate::store::StoreError),
    /// The configuration could not be loaded.
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// The server failed.
    #[error(transparent)]
    Server(#[from] crate::server::ServerError),
    /// Amplification failed.
    #[error(transparent)]
    Synth(#[from] SynthError),
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
