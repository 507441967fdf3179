//! Decoding an uploaded exemplar: a GeoTIFF, 16-bit PNG or OpenEXR file, or an `elevation`
//! raster and named layer rasters on the same grid. Everything goes through the core readers,
//! which check the header against the limits before allocating; this module adds the
//! width/height limit, the layer checks and the "some elevation is valid" rule. Nothing here
//! touches the store.

use terrasynth_core::names::{is_valid_name, NAME_RULE};
use terrasynth_core::raster::{
    read_exr, read_geotiff, read_png16, sniff, Georef, LayeredRaster, RasterError, RasterFormat,
    ReadLimits, ELEVATION,
};

use crate::error::ServiceError;

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
