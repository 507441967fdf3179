//! Decoding an uploaded exemplar: a raw GeoTIFF, 16-bit PNG or OpenEXR body, or a
//! `multipart/form-data` body with an `elevation` part and named layer parts on the same grid.
//! Everything goes through `raster`'s readers, which check the header against the limits before
//! allocating; this module adds the width/height limit, the georeference from query parameters
//! and the layer checks. Nothing here touches the store.

use std::collections::HashMap;

use super::AdminError;
use crate::raster::{
    read_exr, read_geotiff, read_png16, sniff, Crs, Georef, LayeredRaster, RasterError,
    RasterFormat, ReadLimits, ELEVATION,
};

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

/// How a body declares itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Declared {
    /// `image/tiff` (or `image/geotiff`).
    Tiff,
    /// `image/png`.
    Png,
    /// `image/x-exr` (or `image/aces`).
    Exr,
    /// `application/octet-stream`: the format is sniffed.
    Sniff,
}

/// The declared raster type of a `Content-Type` value, or 415.
pub fn declared(content_type: Option<&str>) -> Result<Declared, AdminError> {
    let ct = content_type
        .map(|c| {
            c.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
        .unwrap_or_default();
    match ct.as_str() {
        "image/tiff" | "image/geotiff" | "image/tiff; application=geotiff" => Ok(Declared::Tiff),
        "image/png" => Ok(Declared::Png),
        "image/x-exr" | "image/aces" | "image/exr" => Ok(Declared::Exr),
        "application/octet-stream" => Ok(Declared::Sniff),
        "" => Err(AdminError::UnsupportedMediaType(
            "missing Content-Type: send image/tiff, image/png, image/x-exr, application/octet-stream or multipart/form-data".into(),
        )),
        other => Err(AdminError::UnsupportedMediaType(format!(
            "Content-Type `{other}` is not accepted: send image/tiff, image/png, image/x-exr, application/octet-stream or multipart/form-data"
        ))),
    }
}

/// The georeference given by the query parameters `cell_size`, `west`, `north` and `crs`
/// (`EPSG:4326` by default, or `EPSG:3857`); `None` when none of the first three is given.
pub fn georef_from_query(q: &HashMap<String, String>) -> Result<Option<Georef>, AdminError> {
    let num = |k: &str| -> Result<Option<f64>, AdminError> {
        q.get(k)
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        AdminError::BadRequest(format!(
                            "query parameter {k}=`{v}` is not a finite number"
                        ))
                    })
            })
            .transpose()
    };
    let (cell, west, north) = (num("cell_size")?, num("west")?, num("north")?);
    let crs = match q.get("crs").map(|c| c.trim().to_ascii_uppercase()) {
        None => Crs::Epsg4326,
        Some(c) if c == "EPSG:4326" || c == "4326" => Crs::Epsg4326,
        Some(c) if c == "EPSG:3857" || c == "3857" => Crs::Epsg3857,
        Some(c) => {
            return Err(AdminError::Invalid(format!(
                "crs `{c}` is not supported (EPSG:4326 or EPSG:3857)"
            )))
        }
    };
    match (cell, west, north) {
        (None, None, None) => Ok(None),
        (Some(cell), Some(west), Some(north)) => {
            if cell <= 0.0 {
                return Err(AdminError::Invalid(format!(
                    "absurd georeference: cell_size {cell} must be positive"
                )));
            }
            Ok(Some(Georef {
                crs,
                west,
                north,
                pixel_width: cell,
                pixel_height: cell,
            }))
        }
        _ => Err(AdminError::Invalid(
            "give all of cell_size, west and north (and optionally crs)".into(),
        )),
    }
}

/// The admin error for a reader's error.
pub fn raster_error(what: &str, e: RasterError) -> AdminError {
    match e {
        RasterError::TooLarge { .. } => AdminError::TooLarge(format!("{what}: {e}")),
        RasterError::NoValidData
        | RasterError::BadGeoreference(_)
        | RasterError::LayerMismatch(_) => AdminError::Invalid(format!("{what}: {e}")),
        RasterError::Unsupported { .. } => AdminError::Invalid(format!("{what}: {e}")),
        _ => AdminError::BadRequest(format!("{what} is undecodable: {e}")),
    }
}

/// Decodes one raster file of an upload. `georef` is required for PNG and OpenEXR (GeoTIFFs
/// carry theirs and ignore it).
pub fn decode_raster(
    what: &str,
    bytes: &[u8],
    declared: Declared,
    georef: Option<Georef>,
    limits: &UploadLimits,
) -> Result<LayeredRaster, AdminError> {
    let format = sniff(bytes).ok_or_else(|| {
        AdminError::BadRequest(format!(
            "{what} is undecodable: not a GeoTIFF, PNG or OpenEXR file"
        ))
    })?;
    let agrees = match declared {
        Declared::Sniff => true,
        Declared::Tiff => format == RasterFormat::GeoTiff,
        Declared::Png => format == RasterFormat::Png,
        Declared::Exr => format == RasterFormat::Exr,
    };
    if !agrees {
        return Err(AdminError::BadRequest(format!(
            "{what} is a {format:?} file, not what its Content-Type declares"
        )));
    }
    let need_georef = |kind: &str| {
        georef.ok_or_else(|| {
            AdminError::Invalid(format!(
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
) -> Result<(), AdminError> {
    let (rows, cols) = r.dim();
    if rows as u64 > limits.max_dimension || cols as u64 > limits.max_dimension {
        return Err(AdminError::TooLarge(format!(
            "{what} is {cols}×{rows}; the largest accepted side is {}",
            limits.max_dimension
        )));
    }
    if r.layers.len() > limits.read.max_layers {
        return Err(AdminError::TooLarge(format!(
            "{what} has {} layers; at most {} are accepted",
            r.layers.len(),
            limits.read.max_layers
        )));
    }
    if rows == 0 || cols == 0 {
        return Err(AdminError::BadRequest(format!("{what} is empty")));
    }
    if !r.georef.is_sane(cols, rows) {
        return Err(AdminError::Invalid(format!(
            "{what}: absurd georeference {:?} for a {cols}×{rows} grid",
            r.georef
        )));
    }
    Ok(())
}

/// Checks a layer name given by a multipart part.
pub fn check_layer_name(name: &str) -> Result<(), AdminError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if ok {
        Ok(())
    } else {
        Err(AdminError::Invalid(format!(
            "layer name `{name}` must be 1–64 letters, digits, `-` or `_`"
        )))
    }
}

/// Assembles an exemplar from an elevation raster and named single-layer rasters, all on one
/// grid.
pub fn assemble(
    elevation: LayeredRaster,
    layers: Vec<(String, LayeredRaster)>,
    limits: &UploadLimits,
) -> Result<LayeredRaster, AdminError> {
    let mut out = elevation;
    if out.layer(ELEVATION).is_none() {
        return Err(AdminError::Invalid(
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
            .ok_or_else(|| AdminError::Invalid(format!("layer `{name}` has no data")))?;
        out.push_layer(&name, data)
            .map_err(|e| raster_error(&format!("layer `{name}`"), e))?;
    }
    if out.layers.len() > limits.read.max_layers {
        return Err(AdminError::TooLarge(format!(
            "{} layers; at most {} are accepted",
            out.layers.len(),
            limits.read.max_layers
        )));
    }
    if crate::store::exemplar::stats(&out).is_none() {
        return Err(AdminError::Invalid(
            "the elevation holds no valid value (NaN or nodata only)".into(),
        ));
    }
    Ok(out)
}
