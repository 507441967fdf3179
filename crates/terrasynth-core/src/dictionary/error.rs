//! Errors of the dictionary module: building, reading and writing dictionaries.

use thiserror::Error;

/// An error building, reading or writing a dictionary.
#[derive(Debug, Error)]
pub enum DictionaryError {
    /// An operating-system IO error while reading or writing.
    #[error("io error: {0}")]
    Io(#[from] std::io::Error),
    /// The bytes do not start with the dictionary magic `TSDICT\0\x01`.
    #[error("not a terrasynth dictionary (bad magic)")]
    BadMagic,
    /// The file's format version is not one this build reads.
    #[error("unsupported dictionary format version {found}")]
    UnsupportedVersion {
        /// The version stored in the file.
        found: u32,
    },
    /// The stream ended before the dictionary did.
    #[error("dictionary file is truncated")]
    Truncated,
    /// The stored SHA-256 does not match the content.
    #[error("dictionary checksum mismatch (file corrupted)")]
    ChecksumMismatch,
    /// The file is structurally invalid (bad header, inconsistent lengths, non-finite values...).
    #[error("malformed dictionary: {0}")]
    Malformed(String),
    /// Build parameters or exemplars are invalid.
    #[error("invalid dictionary parameters: {0}")]
    InvalidParams(String),
    /// No usable patch: the exemplars are too small, too flat, or entirely invalid.
    #[error("no usable patch in the exemplars (too small, too flat or invalid)")]
    NoPatches,
    /// The build was cancelled by the caller.
    #[error("dictionary build cancelled")]
    Cancelled,
}
