//! Errors of the store and of the catalogue service. None of them carries an HTTP status: the
//! server maps each kind to one.

use thiserror::Error;

use terrasynth_core::dictionary::DictionaryError;

/// An error of the store.
#[derive(Debug, Error)]
pub enum StoreError {
    /// A file operation failed.
    #[error("store io error on {path}: {source}")]
    Io {
        /// The file or directory.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A stored dictionary is corrupted or unreadable.
    #[error("stored dictionary {id} is unusable: {source}")]
    Corrupt {
        /// Its id.
        id: String,
        /// Why.
        source: DictionaryError,
    },
    /// A dictionary could not be serialised.
    #[error(transparent)]
    Dictionary(#[from] DictionaryError),
    /// An alias or id is not a safe file name.
    #[error("invalid store name `{0}`")]
    BadName(String),
    /// A stored object (exemplar, world) is corrupted, or bytes are not a valid object.
    #[error("object {id} is unusable: {reason}")]
    BadObject {
        /// Its id (or `-` for bytes not yet stored).
        id: String,
        /// Why.
        reason: String,
    },
    /// The directory is not empty and has no `VERSION`: it is not a store (refused, so that a
    /// mistyped `store_dir` never adopts someone else's files).
    #[error("{0} is not empty and has no VERSION file: it is not a terrasynth store (give an empty or new directory)")]
    NotAStore(String),
    /// The store was written by a newer, incompatible terrasynth.
    #[error("store format `{found}` is not supported (this build reads version {supported})")]
    Version {
        /// What the store's `VERSION` file says.
        found: String,
        /// The layout version this build reads.
        supported: u32,
    },
}

/// An error of the catalogue service: a rule was broken, or the store failed. The kinds say what
/// went wrong, not how to answer it (the server maps them to HTTP statuses).
#[derive(Debug, Error)]
pub enum ServiceError {
    /// No such object.
    #[error("{0}")]
    NotFound(String),
    /// The object is in use, or the name is taken.
    #[error("{0}")]
    Conflict(String),
    /// The bytes cannot be decoded as what they claim to be.
    #[error("{0}")]
    Undecodable(String),
    /// The body or raster exceeds a limit.
    #[error("{0}")]
    TooLarge(String),
    /// Well-formed but unusable: NaN-only raster, mismatched layers, absurd georeference,
    /// invalid parameters, unknown ids.
    #[error("{0}")]
    Invalid(String),
    /// The build queue is full.
    #[error("the build queue is full; retry later")]
    QueueFull,
    /// A shared resource (the upload memory budget) is spent for now; retrying later may work.
    #[error("{0}")]
    Busy(String),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// Something else failed (a thread could not start, a record could not be serialised).
    #[error("internal error: {0}")]
    Internal(String),
}
