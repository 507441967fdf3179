//! 16-bit grayscale PNG elevation rasters: each pixel holds the elevation in whole metres as an
//! unsigned 16-bit integer. PNG carries no georeference, so the caller supplies one. Also 8-bit
//! RGB(A) images (satellite images classified into land-cover classes), read as packed
//! `0xRRGGBB` values ([`read_png_rgb`]).

// Sizes and offsets come from the file: every sum and product on them is checked.
#![warn(clippy::arithmetic_side_effects)]

use std::io::Cursor;

use ndarray::Array2;

use super::error::RasterError;
use super::georef::Georef;
use super::grid::Grid;
use super::limits::ReadLimits;

const FORMAT: &str = "PNG";

fn malformed(detail: impl Into<String>) -> RasterError {
    RasterError::malformed(FORMAT, detail)
}

fn unsupported(detail: impl Into<String>) -> RasterError {
    RasterError::unsupported(FORMAT, detail)
}

fn map_png_error(err: png::DecodingError) -> RasterError {
    match err {
        png::DecodingError::IoError(e) => malformed(format!("truncated or unreadable data: {e}")),
        png::DecodingError::Format(e) => malformed(e.to_string()),
        png::DecodingError::LimitsExceeded => malformed("decoder memory limit exceeded"),
        other => malformed(other.to_string()),
    }
}

/// Reads a 16-bit grayscale PNG whose values are metres, placing it with `georef`. Every cell is
/// valid (the returned grid has no mask).
///
/// # Errors
/// [`RasterError::UnknownFormat`] without the PNG signature, [`RasterError::TooLarge`] when the
/// header exceeds `limits` (checked before pixel buffers are allocated),
/// [`RasterError::Unsupported`] for other bit depths or colour types,
/// [`RasterError::BadGeoreference`] when `georef` is not sane for the image and
/// [`RasterError::Malformed`] for broken or truncated files.
pub fn read_png16(bytes: &[u8], georef: Georef, limits: &ReadLimits) -> Result<Grid, RasterError> {
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Err(RasterError::UnknownFormat("no PNG signature".to_string()));
    }
    let png_limits = png::Limits {
        // Row buffers and the decoder's internal state; the output buffer is ours.
        bytes: limits.byte_budget(2).saturating_add(1 << 20),
    };
    let mut decoder = png::Decoder::new_with_limits(Cursor::new(bytes), png_limits);
    let (width, height) = {
        let info = decoder.read_header_info().map_err(map_png_error)?;
        limits.check_dimensions(u64::from(info.width), u64::from(info.height))?;
        if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen
        {
            return Err(unsupported(format!(
                "{:?} at {} bits per sample (only 16-bit grayscale is read)",
                info.color_type, info.bit_depth as u8
            )));
        }
        (info.width as usize, info.height as usize)
    };
    if !georef.is_sane(width, height) {
        return Err(RasterError::BadGeoreference(format!(
            "{georef:?} is not a sane georeference for a {width}×{height} grid"
        )));
    }
    let mut reader = decoder.read_info().map_err(map_png_error)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| malformed("image size overflows"))?;
    let expected = width.saturating_mul(height).saturating_mul(2);
    if size != expected {
        return Err(malformed(format!(
            "output buffer of {size} bytes for a {width}×{height} 16-bit image"
        )));
    }
    let mut buf = vec![0u8; size];
    reader.next_frame(&mut buf).map_err(map_png_error)?;
    let values: Vec<f32> = buf
        .chunks_exact(2)
        .map(|b| f32::from(u16::from_be_bytes([b[0], b[1]])))
        .collect();
    let data =
        Array2::from_shape_vec((height, width), values).map_err(|e| malformed(e.to_string()))?;
    Ok(Grid::new(data, georef))
}

/// An 8-bit RGB colour packed into one exactly representable `f32`: `r·65536 + g·256 + b`
/// (the `rgb` layer of an exemplar; read by
/// [`crate::landscape::classes`]).
pub fn pack_rgb(rgb: [u8; 3]) -> f32 {
    (u32::from(rgb[0]) << 16 | u32::from(rgb[1]) << 8 | u32::from(rgb[2])) as f32
}

/// The colour of a packed value ([`pack_rgb`]); `None` for values that are no packed colour.
pub fn unpack_rgb(x: f32) -> Option<[u8; 3]> {
    if !(x.is_finite() && x.fract() == 0.0 && (0.0..=16_777_215.0).contains(&x)) {
        return None;
    }
    let v = x as u32;
    Some([(v >> 16) as u8, (v >> 8) as u8, v as u8])
}

/// Reads an 8-bit RGB or RGBA PNG placed with `georef` as one grid of packed colours
/// `r·65536 + g·256 + b` ([`pack_rgb`]); fully transparent pixels
/// (alpha 0) are invalid.
///
/// # Errors
/// As [`read_png16`]; [`RasterError::Unsupported`] for anything but 8-bit RGB or RGBA.
pub fn read_png_rgb(
    bytes: &[u8],
    georef: Georef,
    limits: &ReadLimits,
) -> Result<Grid, RasterError> {
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Err(RasterError::UnknownFormat("no PNG signature".to_string()));
    }
    let png_limits = png::Limits {
        bytes: limits.byte_budget(4).saturating_add(1 << 20),
    };
    let mut decoder = png::Decoder::new_with_limits(Cursor::new(bytes), png_limits);
    let (width, height, channels) = {
        let info = decoder.read_header_info().map_err(map_png_error)?;
        limits.check_dimensions(u64::from(info.width), u64::from(info.height))?;
        let channels = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => 3usize,
            (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
            (t, d) => {
                return Err(unsupported(format!(
                    "{t:?} at {} bits per sample (an RGB image must be 8-bit RGB or RGBA)",
                    d as u8
                )))
            }
        };
        (info.width as usize, info.height as usize, channels)
    };
    if !georef.is_sane(width, height) {
        return Err(RasterError::BadGeoreference(format!(
            "{georef:?} is not a sane georeference for a {width}×{height} grid"
        )));
    }
    let mut reader = decoder.read_info().map_err(map_png_error)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| malformed("image size overflows"))?;
    let expected = width.saturating_mul(height).saturating_mul(channels);
    if size != expected {
        return Err(malformed(format!(
            "output buffer of {size} bytes for a {width}×{height} image of {channels} channels"
        )));
    }
    let mut buf = vec![0u8; size];
    reader.next_frame(&mut buf).map_err(map_png_error)?;
    let mut values = Vec::with_capacity(width.saturating_mul(height));
    let mut valid = Vec::with_capacity(width.saturating_mul(height));
    for p in buf.chunks_exact(channels) {
        values.push(pack_rgb([p[0], p[1], p[2]]));
        valid.push(channels == 3 || p[3] > 0);
    }
    let data =
        Array2::from_shape_vec((height, width), values).map_err(|e| malformed(e.to_string()))?;
    let mut grid = Grid::new(data, georef);
    if valid.iter().any(|v| !v) {
        grid.valid = Some(
            Array2::from_shape_vec((height, width), valid).map_err(|e| malformed(e.to_string()))?,
        );
    }
    Ok(grid)
}

/// Encodes `grid` as a 16-bit grayscale PNG: values are rounded to whole metres and clamped to
/// `0..=65535`; invalid cells are written as 0. The georeference is not stored.
///
/// # Errors
/// [`RasterError::Unsupported`] for an empty grid or one larger than `u32::MAX` on a side,
/// [`RasterError::Malformed`] when encoding fails.
pub fn write_png16(grid: &Grid) -> Result<Vec<u8>, RasterError> {
    let (rows, cols) = grid.data.dim();
    if rows == 0 || cols == 0 {
        return Err(unsupported("writing an empty grid"));
    }
    let width = u32::try_from(cols).map_err(|_| unsupported("grid wider than 2^32 - 1"))?;
    let height = u32::try_from(rows).map_err(|_| unsupported("grid taller than 2^32 - 1"))?;
    let mut bytes = Vec::with_capacity(grid.data.len().saturating_mul(2));
    for ((r, c), &v) in grid.data.indexed_iter() {
        let masked = grid
            .valid
            .as_ref()
            .is_some_and(|m| !m.get((r, c)).copied().unwrap_or(false));
        let q = if masked || !v.is_finite() {
            0
        } else {
            v.round().clamp(0.0, 65535.0) as u16
        };
        bytes.extend_from_slice(&q.to_be_bytes());
    }
    let mut out = Vec::new();
    let enc_err = |e: png::EncodingError| malformed(format!("encoding failed: {e}"));
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Sixteen);
        let mut writer = encoder.write_header().map_err(enc_err)?;
        writer.write_image_data(&bytes).map_err(enc_err)?;
        writer.finish().map_err(enc_err)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(color: png::ColorType, depth: png::BitDepth, w: u32, h: u32, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, w, h);
            enc.set_color(color);
            enc.set_depth(depth);
            let mut wr = enc.write_header().unwrap();
            wr.write_image_data(data).unwrap();
        }
        out
    }

    #[test]
    fn rgb_and_rgba_pngs_read_as_packed_colours_with_transparent_pixels_invalid() {
        let g = Georef::local_metric(10.0);
        let l = ReadLimits::default();
        // 2 × 1 RGB: (1, 2, 3) = 65536 + 512 + 3 = 66051; (255, 0, 0) = 16711680.
        let grid = read_png_rgb(
            &png(
                png::ColorType::Rgb,
                png::BitDepth::Eight,
                2,
                1,
                &[1, 2, 3, 255, 0, 0],
            ),
            g,
            &l,
        )
        .unwrap();
        assert_eq!(grid.data, ndarray::arr2(&[[66051.0f32, 16711680.0]]));
        assert!(grid.valid.is_none());
        // RGBA: the second pixel is transparent.
        let grid = read_png_rgb(
            &png(
                png::ColorType::Rgba,
                png::BitDepth::Eight,
                2,
                1,
                &[0, 0, 1, 255, 9, 9, 9, 0],
            ),
            g,
            &l,
        )
        .unwrap();
        assert_eq!(grid.data[[0, 0]], 1.0);
        assert_eq!(grid.valid, Some(ndarray::arr2(&[[true, false]])));
        // 16-bit grey is no RGB image.
        let e = read_png_rgb(
            &png(
                png::ColorType::Grayscale,
                png::BitDepth::Sixteen,
                1,
                1,
                &[0, 7],
            ),
            g,
            &l,
        )
        .unwrap_err();
        assert!(e.to_string().contains("8-bit RGB or RGBA"), "{e}");
    }
}
