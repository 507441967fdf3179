//! Format detection and dispatch: recognises GeoTIFF, PNG and OpenEXR by their magic bytes, reads
//! any of them into a [`LayeredRaster`], and writes a [`Grid`] in the format named by a file's
//! extension.

// Sizes and offsets come from the file: every sum and product on them is checked.
#![warn(clippy::arithmetic_side_effects)]

use std::path::Path;

use super::error::RasterError;
use super::georef::Georef;
use super::geotiff::{read_geotiff, write_geotiff_file};
use super::grid::{Grid, LayeredRaster};
use super::limits::ReadLimits;
use super::openexr::{read_exr, write_exr, EXR_MAGIC};
use super::png16::read_png16;

/// A raster file format recognised by [`sniff`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RasterFormat {
    /// TIFF / GeoTIFF (classic or BigTIFF, either byte order).
    GeoTiff,
    /// PNG.
    Png,
    /// OpenEXR.
    Exr,
}

/// The format of `bytes` judged by its leading magic bytes, or `None` when unrecognised.
pub fn sniff(bytes: &[u8]) -> Option<RasterFormat> {
    let head = bytes.get(0..4)?;
    match head {
        b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+" => Some(RasterFormat::GeoTiff),
        b"\x89PNG" => Some(RasterFormat::Png),
        h if h == EXR_MAGIC => Some(RasterFormat::Exr),
        _ => None,
    }
}

/// Reads the raster file at `path`, detecting its format from its content. GeoTIFFs carry their
/// own georeference and give a single [`ELEVATION`](super::ELEVATION) layer; PNG and EXR files
/// need `georef_hint`.
///
/// # Errors
/// [`RasterError::Io`] when the file cannot be read, [`RasterError::UnknownFormat`] for an
/// unrecognised format, [`RasterError::BadGeoreference`] for a PNG or EXR without a hint, and
/// otherwise the errors of the format's reader.
pub fn read_raster_file(
    path: &Path,
    georef_hint: Option<Georef>,
    limits: &ReadLimits,
) -> Result<LayeredRaster, RasterError> {
    let bytes = std::fs::read(path)?;
    let format = sniff(&bytes).ok_or_else(|| {
        RasterError::UnknownFormat(format!(
            "{} is not a GeoTIFF, PNG or OpenEXR file",
            path.display()
        ))
    })?;
    let need_hint = |what: &str| {
        georef_hint.ok_or_else(|| {
            RasterError::BadGeoreference(format!(
                "{what} file {} carries no georeference and none was given",
                path.display()
            ))
        })
    };
    match format {
        RasterFormat::GeoTiff => Ok(LayeredRaster::from_elevation(read_geotiff(&bytes, limits)?)),
        RasterFormat::Png => Ok(LayeredRaster::from_elevation(read_png16(
            &bytes,
            need_hint("PNG")?,
            limits,
        )?)),
        RasterFormat::Exr => read_exr(&bytes, need_hint("OpenEXR")?, limits),
    }
}

/// Writes `grid` to `path` in the format named by the extension (case-insensitive): `.tif` /
/// `.tiff` for GeoTIFF, `.exr` for OpenEXR (one [`ELEVATION`](super::ELEVATION) channel, no
/// georeference).
///
/// # Errors
/// [`RasterError::Unsupported`] for another or a missing extension, otherwise the writer's errors.
pub fn write_raster_file(grid: &Grid, path: &Path) -> Result<(), RasterError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("tif" | "tiff") => write_geotiff_file(grid, path),
        Some("exr") => {
            let bytes = write_exr(&LayeredRaster::from_elevation(grid.clone()))?;
            std::fs::write(path, bytes)?;
            Ok(())
        }
        other => Err(RasterError::Unsupported {
            format: "raster file",
            detail: format!(
                "extension {:?} of {} (expected .tif, .tiff or .exr)",
                other.unwrap_or(""),
                path.display()
            ),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniff_recognises_magics() {
        assert_eq!(sniff(b"II*\0rest"), Some(RasterFormat::GeoTiff));
        assert_eq!(sniff(b"MM\0*rest"), Some(RasterFormat::GeoTiff));
        assert_eq!(sniff(b"II+\0rest"), Some(RasterFormat::GeoTiff));
        assert_eq!(sniff(b"\x89PNG\r\n\x1a\n"), Some(RasterFormat::Png));
        assert_eq!(sniff(&[0x76, 0x2f, 0x31, 0x01, 2]), Some(RasterFormat::Exr));
        assert_eq!(sniff(b"GIF89a"), None);
        assert_eq!(sniff(b"II*"), None);
        assert_eq!(sniff(b""), None);
    }
}
