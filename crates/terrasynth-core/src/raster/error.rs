//! Errors of the raster module: every way a raster file can be unreadable or unwritable.

use thiserror::Error;

/// An error reading, writing or validating a raster.
#[derive(Debug, Error)]
pub enum RasterError {
    /// An operating-system IO error (file missing, disk full...).
    #[error("io error: {0}")]
    Io(#[from] std::io::Error),
    /// The bytes do not start with the magic of any supported format.
    #[error("not a supported raster: {0}")]
    UnknownFormat(String),
    /// The file is structurally broken or truncated.
    #[error("malformed {format}: {detail}")]
    Malformed {
        /// Which format was being decoded.
        format: &'static str,
        /// What was wrong.
        detail: String,
    },
    /// A feature of the format that terrasynth does not read (a compression, a sample type...).
    #[error("unsupported {format} feature: {detail}")]
    Unsupported {
        /// Which format was being decoded.
        format: &'static str,
        /// The feature.
        detail: String,
    },
    /// The raster is larger than the configured limits (checked before allocating).
    #[error("raster too large: {width}×{height} pixels exceeds the limit of {limit} pixels")]
    TooLarge {
        /// Claimed width.
        width: u64,
        /// Claimed height.
        height: u64,
        /// Maximum number of pixels allowed.
        limit: u64,
    },
    /// The raster has no valid (finite, non-nodata) value.
    #[error("raster holds no valid data (all values are nodata or NaN)")]
    NoValidData,
    /// The georeference is missing, inconsistent or out of the CRS's domain.
    #[error("bad georeference: {0}")]
    BadGeoreference(String),
    /// Layers of a multi-layer raster do not share a grid, or a name repeats.
    #[error("layer mismatch: {0}")]
    LayerMismatch(String),
}

impl RasterError {
    /// A [`RasterError::Malformed`] for `format`.
    pub fn malformed(format: &'static str, detail: impl Into<String>) -> Self {
        RasterError::Malformed {
            format,
            detail: detail.into(),
        }
    }

    /// A [`RasterError::Unsupported`] for `format`.
    pub fn unsupported(format: &'static str, detail: impl Into<String>) -> Self {
        RasterError::Unsupported {
            format,
            detail: detail.into(),
        }
    }
}
