//! Resource limits for the raster readers, checked against a file's header before any buffer for
//! pixel data is allocated, so that a hostile or corrupt header cannot exhaust memory.

use super::error::RasterError;

/// Limits applied when decoding raster files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Largest accepted `width × height`, in pixels (per layer).
    pub max_pixels: u64,
    /// Largest accepted number of layers (channels) in a multi-layer file.
    pub max_layers: usize,
}

impl Default for ReadLimits {
    /// `max_pixels = 2^28` (a 16384 × 16384 grid), `max_layers = 16`.
    fn default() -> Self {
        ReadLimits {
            max_pixels: 1 << 28,
            max_layers: 16,
        }
    }
}

impl ReadLimits {
    /// Errors with [`RasterError::TooLarge`] when a `width × height` raster exceeds the limit.
    /// Zero-sized rasters pass this check (readers reject them separately).
    pub fn check_dimensions(&self, width: u64, height: u64) -> Result<(), RasterError> {
        let too_large = width
            .checked_mul(height)
            .is_none_or(|pixels| pixels > self.max_pixels);
        if too_large {
            return Err(RasterError::TooLarge {
                width,
                height,
                limit: self.max_pixels,
            });
        }
        Ok(())
    }

    /// The byte budget for a decoded buffer of `bytes_per_sample`-byte samples within the pixel
    /// limit, saturating at `usize::MAX`.
    pub(crate) fn byte_budget(&self, bytes_per_sample: u64) -> usize {
        let bytes = self.max_pixels.saturating_mul(bytes_per_sample);
        usize::try_from(bytes).unwrap_or(usize::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_match_documented_values() {
        let l = ReadLimits::default();
        assert_eq!(l.max_pixels, 268_435_456);
        assert_eq!(l.max_layers, 16);
    }

    #[test]
    fn dimension_check_is_inclusive_and_overflow_safe() {
        let l = ReadLimits {
            max_pixels: 100,
            max_layers: 1,
        };
        assert!(l.check_dimensions(10, 10).is_ok());
        assert!(matches!(
            l.check_dimensions(10, 11),
            Err(RasterError::TooLarge {
                width: 10,
                height: 11,
                limit: 100
            })
        ));
        assert!(l.check_dimensions(u64::MAX, 2).is_err());
    }
}
