//! Decoding an uploaded exemplar: a GeoTIFF, 16-bit PNG or OpenEXR file, or an `elevation`
//! raster and named layer rasters on the same grid; a part named `rgb` is an 8-bit RGB(A) PNG (a
//! satellite image for land-cover classes) stored as the layer `rgb` of packed `0xRRGGBB` values. Everything goes through the core readers,
//! which check the header against the limits before allocating; this module adds the
//! width/height limit, the layer checks and the "some elevation is valid" rule.
//!
//! Uploads arrive spooled to files ([`Spooled`], written by the server as the body arrives).
//! Before any of them is read into memory, [`decode_spooled`] estimates from the file headers
//! how much memory reading and decoding them will take ([`decoded_bytes`]) and reserves it, with
//! the bodies, from the uploads' [`MemoryBudget`]; only then are the files read and decoded.
//! Nothing here writes to the store.

use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use terrasynth_core::names::{is_valid_name, NAME_RULE};
use terrasynth_core::raster::{
    read_exr, read_geotiff, read_png16, read_png_rgb, sniff, Georef, LayeredRaster, RasterError,
    RasterFormat, ReadLimits, ELEVATION,
};

use crate::budget::{MemoryBudget, Reservation};
use crate::error::ServiceError;

/// Memory a decoder needs beyond its sample buffers (row buffers, decompression state), bytes.
const DECODER_OVERHEAD: u64 = 4 << 20;

/// One part of an upload, spooled to a file that is removed when this is dropped.
#[derive(Debug)]
pub struct Spooled {
    /// The part's name (`elevation` or a layer name; the body of a raw upload is `elevation`).
    pub name: String,
    /// What its `Content-Type` claims.
    pub format: UploadFormat,
    /// The file.
    pub path: PathBuf,
    /// Its length, bytes.
    pub len: u64,
}

impl Drop for Spooled {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Limits of uploads.
#[derive(Clone, Copy, Debug)]
pub struct UploadLimits {
    /// Largest body, bytes.
    pub max_body: usize,
    /// Pixels per layer and layers, checked by the readers before they allocate.
    pub read: ReadLimits,
    /// Largest width or height.
    pub max_dimension: u64,
}

/// What an upload claims to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UploadFormat {
    /// A GeoTIFF.
    Tiff,
    /// A 16-bit grayscale PNG.
    Png,
    /// An OpenEXR file.
    Exr,
    /// Unknown: the format is sniffed from the bytes.
    Sniff,
}

/// The service error for a reader's error.
pub fn raster_error(what: &str, e: RasterError) -> ServiceError {
    match e {
        RasterError::TooLarge { .. } => ServiceError::TooLarge(format!("{what}: {e}")),
        RasterError::NoValidData
        | RasterError::BadGeoreference(_)
        | RasterError::LayerMismatch(_) => ServiceError::Invalid(format!("{what}: {e}")),
        RasterError::Unsupported { .. } => ServiceError::Invalid(format!("{what}: {e}")),
        _ => ServiceError::Undecodable(format!("{what} is undecodable: {e}")),
    }
}

/// Decodes one raster file of an upload. `georef` is required for PNG and OpenEXR (GeoTIFFs
/// carry theirs and ignore it).
pub fn decode_raster(
    what: &str,
    bytes: &[u8],
    claimed: UploadFormat,
    georef: Option<Georef>,
    limits: &UploadLimits,
) -> Result<LayeredRaster, ServiceError> {
    let format = sniff(bytes).ok_or_else(|| {
        ServiceError::Undecodable(format!(
            "{what} is undecodable: not a GeoTIFF, PNG or OpenEXR file"
        ))
    })?;
    let agrees = match claimed {
        UploadFormat::Sniff => true,
        UploadFormat::Tiff => format == RasterFormat::GeoTiff,
        UploadFormat::Png => format == RasterFormat::Png,
        UploadFormat::Exr => format == RasterFormat::Exr,
    };
    if !agrees {
        return Err(ServiceError::Undecodable(format!(
            "{what} is a {format:?} file, not what its Content-Type declares"
        )));
    }
    let need_georef = |kind: &str| {
        georef.ok_or_else(|| {
            ServiceError::Invalid(format!(
                "{what}: a {kind} file carries no georeference: give cell_size, west and north"
            ))
        })
    };
    let raster = match format {
        RasterFormat::GeoTiff => LayeredRaster::from_elevation(
            read_geotiff(bytes, &limits.read).map_err(|e| raster_error(what, e))?,
        ),
        RasterFormat::Png => LayeredRaster::from_elevation(
            read_png16(bytes, need_georef("PNG")?, &limits.read)
                .map_err(|e| raster_error(what, e))?,
        ),
        RasterFormat::Exr => read_exr(bytes, need_georef("OpenEXR")?, &limits.read)
            .map_err(|e| raster_error(what, e))?,
    };
    check_raster(what, &raster, limits)?;
    Ok(raster)
}

/// The memory, bytes, that reading the raster file at `path` (of `len` bytes) into memory and
/// decoding it will take at its peak — the file's bytes plus the decoder's sample buffers, the
/// `f32` layers and the validity mask — estimated from the file's header alone. A header that
/// cannot be read, or that exceeds `limits`, is estimated as the file alone: the decoder then
/// refuses it before allocating anything.
pub fn decoded_bytes(path: &Path, len: u64, limits: &ReadLimits) -> Result<u64, ServiceError> {
    let f = std::fs::File::open(path)
        .map_err(|e| ServiceError::Internal(format!("reading a spooled upload: {e}")))?;
    let mut r = BufReader::new(f);
    let mut magic = [0u8; 4];
    if r.read_exact(&mut magic).is_err() || r.seek(SeekFrom::Start(0)).is_err() {
        return Ok(len);
    }
    let per_pixel_and_pixels = match sniff(&magic) {
        Some(RasterFormat::GeoTiff) => tiff_estimate(r),
        Some(RasterFormat::Png) => png_estimate(r),
        Some(RasterFormat::Exr) => exr_estimate(r),
        None => None,
    };
    Ok(match per_pixel_and_pixels {
        Some((per_pixel, pixels)) if pixels <= limits.max_pixels => len
            .saturating_add(per_pixel.saturating_mul(pixels))
            .saturating_add(DECODER_OVERHEAD),
        _ => len,
    })
}

/// `(bytes per pixel at the peak, pixels)` of a TIFF: the decoded samples, their `f32` copy and
/// the mask.
fn tiff_estimate(r: impl Read + Seek) -> Option<(u64, u64)> {
    let mut dec = tiff::decoder::Decoder::new(r).ok()?;
    let (w, h) = dec.dimensions().ok()?;
    let bits = match dec.colortype().ok()? {
        tiff::ColorType::Gray(b) => u64::from(b),
        // Refused by the reader before it decodes pixels.
        _ => 8,
    };
    Some((bits.div_ceil(8) + 4 + 1, u64::from(w) * u64::from(h)))
}

/// `(bytes per pixel at the peak, pixels)` of a PNG (read from its IHDR chunk): the samples
/// (16-bit grey, or 8-bit RGB(A) of an `rgb` part), their `f32` copy and the mask.
fn png_estimate(mut r: impl Read) -> Option<(u64, u64)> {
    let mut head = [0u8; 26];
    r.read_exact(&mut head).ok()?;
    if &head[12..16] != b"IHDR" {
        return None;
    }
    let w = u32::from_be_bytes([head[16], head[17], head[18], head[19]]);
    let h = u32::from_be_bytes([head[20], head[21], head[22], head[23]]);
    // Colour type 2 (RGB) and 6 (RGBA) at 8 bits: 3 or 4 bytes; anything else is read as (or
    // refused before) 16-bit grey.
    let samples = match (head[24], head[25]) {
        (8, 2) => 3,
        (8, 6) => 4,
        _ => 2,
    };
    Some((samples + 4 + 1, u64::from(w) * u64::from(h)))
}

/// `(bytes per pixel at the peak, pixels)` of an OpenEXR file: every channel's samples and their
/// `f32` copies, and the mask.
fn exr_estimate(r: impl Read + Seek) -> Option<(u64, u64)> {
    let meta = exr::meta::MetaData::read_from_buffered(r, false).ok()?;
    let header = meta.headers.first()?;
    let size = header.layer_size;
    let per_pixel: u64 = header
        .channels
        .list
        .iter()
        .map(|c| c.sample_type.bytes_per_sample() as u64 + 4)
        .sum();
    Some((per_pixel + 1, size.width() as u64 * size.height() as u64))
}

/// Decodes a spooled upload: estimates its peak memory from the file headers, reserves it from
/// `budget` (413 when it exceeds the whole budget, 503 when other uploads hold it), then reads
/// and decodes each part (`elevation` first; the others are layers on its grid) and assembles
/// the exemplar. The reservation is returned with the raster: hold it until the raster is
/// stored.
pub fn decode_spooled(
    parts: &[Spooled],
    georef: Option<Georef>,
    limits: &UploadLimits,
    budget: &std::sync::Arc<MemoryBudget>,
) -> Result<(LayeredRaster, Reservation), ServiceError> {
    let elevation_at = parts
        .iter()
        .position(|p| p.name == ELEVATION)
        .ok_or_else(|| ServiceError::Invalid("the upload has no `elevation` part".into()))?;
    let mut need = 0u64;
    for p in parts {
        need = need.saturating_add(decoded_bytes(&p.path, p.len, &limits.read)?);
    }
    let reservation = budget.reserve(need, "this upload")?;
    let read = |p: &Spooled| {
        std::fs::read(&p.path)
            .map_err(|e| ServiceError::Internal(format!("reading a spooled upload: {e}")))
    };
    let what = |p: &Spooled| {
        if parts.len() == 1 {
            "the body".to_string()
        } else {
            format!("part `{}`", p.name)
        }
    };
    let first = &parts[elevation_at];
    let elevation = decode_raster(&what(first), &read(first)?, first.format, georef, limits)?;
    let mut layers = Vec::new();
    for (i, p) in parts.iter().enumerate() {
        if i == elevation_at {
            continue;
        }
        check_layer_name(&p.name)?;
        let r = if p.name == RGB_LAYER {
            decode_rgb(&what(p), &read(p)?, p.format, elevation.georef, limits)?
        } else {
            decode_raster(
                &what(p),
                &read(p)?,
                p.format,
                Some(elevation.georef),
                limits,
            )?
        };
        layers.push((p.name.clone(), r));
    }
    Ok((assemble(elevation, layers, limits)?, reservation))
}

/// The name of the part (and layer) of an RGB image: packed `0xRRGGBB` colours.
pub const RGB_LAYER: &str = "rgb";

/// Decodes an `rgb` part: an 8-bit RGB or RGBA PNG on the elevation's grid, as packed colours.
fn decode_rgb(
    what: &str,
    bytes: &[u8],
    claimed: UploadFormat,
    georef: Georef,
    limits: &UploadLimits,
) -> Result<LayeredRaster, ServiceError> {
    if !matches!(claimed, UploadFormat::Png | UploadFormat::Sniff)
        || sniff(bytes) != Some(RasterFormat::Png)
    {
        return Err(ServiceError::Undecodable(format!(
            "{what} is undecodable: an `rgb` part is an 8-bit RGB or RGBA PNG"
        )));
    }
    let mut grid = read_png_rgb(bytes, georef, &limits.read).map_err(|e| raster_error(what, e))?;
    // A layer keeps no mask of its own: transparent pixels become NaN (no class).
    let valid = grid.valid.take();
    terrasynth_core::raster::nan_where_invalid(&mut grid.data, valid.as_ref());
    let raster = LayeredRaster::from_elevation(grid);
    check_raster(what, &raster, limits)?;
    Ok(raster)
}

/// Checks dimensions, layer count, georeference and that some elevation is valid.
pub fn check_raster(
    what: &str,
    r: &LayeredRaster,
    limits: &UploadLimits,
) -> Result<(), ServiceError> {
    let (rows, cols) = r.dim();
    if rows as u64 > limits.max_dimension || cols as u64 > limits.max_dimension {
        return Err(ServiceError::TooLarge(format!(
            "{what} is {cols}×{rows}; the largest accepted side is {}",
            limits.max_dimension
        )));
    }
    if r.layers.len() > limits.read.max_layers {
        return Err(ServiceError::TooLarge(format!(
            "{what} has {} layers; at most {} are accepted",
            r.layers.len(),
            limits.read.max_layers
        )));
    }
    if rows == 0 || cols == 0 {
        return Err(ServiceError::Undecodable(format!("{what} is empty")));
    }
    if !r.georef.is_sane(cols, rows) {
        return Err(ServiceError::Invalid(format!(
            "{what}: absurd georeference {:?} for a {cols}×{rows} grid",
            r.georef
        )));
    }
    Ok(())
}

/// Checks a layer name given by a multipart part.
pub fn check_layer_name(name: &str) -> Result<(), ServiceError> {
    if is_valid_name(name) {
        Ok(())
    } else {
        Err(ServiceError::Invalid(format!(
            "layer name `{name}` must be {NAME_RULE}"
        )))
    }
}

/// Assembles an exemplar from an elevation raster and named single-layer rasters, all on one
/// grid.
pub fn assemble(
    elevation: LayeredRaster,
    layers: Vec<(String, LayeredRaster)>,
    limits: &UploadLimits,
) -> Result<LayeredRaster, ServiceError> {
    let mut out = elevation;
    if out.layer(ELEVATION).is_none() {
        return Err(ServiceError::Invalid(
            "the exemplar has no `elevation` layer (an EXR needs an `elevation` channel)".into(),
        ));
    }
    // Keep elevation first.
    out.layers.sort_by_key(|(n, _)| n != ELEVATION);
    for (name, r) in layers {
        check_layer_name(&name)?;
        let data = r
            .layers
            .into_iter()
            .next()
            .map(|(_, a)| a)
            .ok_or_else(|| ServiceError::Invalid(format!("layer `{name}` has no data")))?;
        out.push_layer(&name, data)
            .map_err(|e| raster_error(&format!("layer `{name}`"), e))?;
    }
    if out.layers.len() > limits.read.max_layers {
        return Err(ServiceError::TooLarge(format!(
            "{} layers; at most {} are accepted",
            out.layers.len(),
            limits.read.max_layers
        )));
    }
    if crate::exemplar::stats(&out).is_none() {
        return Err(ServiceError::Invalid(
            "the elevation holds no valid value (NaN or nodata only)".into(),
        ));
    }
    Ok(out)
}
