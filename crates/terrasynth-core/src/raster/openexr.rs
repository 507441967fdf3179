//! OpenEXR multi-layer rasters: each channel of a single-part, flat (non-deep) EXR file is one
//! layer of a [`LayeredRaster`], named after the channel. EXR carries no georeference, so the
//! caller supplies one. Named `openexr` to avoid clashing with the `exr` crate.

// Sizes and offsets come from the file: every sum and product on them is checked.
#![warn(clippy::arithmetic_side_effects)]

use std::io::Cursor;

use exr::prelude::{
    f16, read, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};
use ndarray::Array2;

use super::error::RasterError;
use super::georef::Georef;
use super::grid::{LayeredRaster, ELEVATION};
use super::limits::ReadLimits;

const FORMAT: &str = "OpenEXR";

/// The magic number every OpenEXR file starts with.
pub const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

fn malformed(detail: impl Into<String>) -> RasterError {
    RasterError::malformed(FORMAT, detail)
}

fn unsupported(detail: impl Into<String>) -> RasterError {
    RasterError::unsupported(FORMAT, detail)
}

fn map_exr_error(err: exr::error::Error) -> RasterError {
    match err {
        exr::error::Error::NotSupported(m) => unsupported(m.to_string()),
        exr::error::Error::Invalid(m) => malformed(m.to_string()),
        exr::error::Error::Io(e) => malformed(format!("truncated or unreadable data: {e}")),
        exr::error::Error::Aborted => malformed("decoding aborted"),
    }
}

/// Reads a single-part flat OpenEXR file: every channel becomes a layer named after it
/// (converted to `f32`), except that a lone channel is named [`ELEVATION`]. The elevation layer,
/// when present, comes first; the others follow in file (alphabetical) order. Non-finite values
/// are invalid in the mask; the mask is `None` when every value is finite.
///
/// # Errors
/// [`RasterError::UnknownFormat`] without the EXR magic, [`RasterError::TooLarge`] when the header
/// exceeds `limits` (checked before pixel data is read), [`RasterError::Unsupported`] for
/// multi-part, deep or subsampled files and more channels than `limits.max_layers`,
/// [`RasterError::BadGeoreference`] when `georef` is not sane for the image,
/// [`RasterError::Malformed`] for broken files and [`RasterError::NoValidData`] when no value is
/// finite.
pub fn read_exr(
    bytes: &[u8],
    georef: Georef,
    limits: &ReadLimits,
) -> Result<LayeredRaster, RasterError> {
    if !bytes.starts_with(&EXR_MAGIC) {
        return Err(RasterError::UnknownFormat("no OpenEXR magic".to_string()));
    }
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(map_exr_error)?;
    let header = match meta.headers.as_slice() {
        [one] => one,
        [] => return Err(malformed("no header")),
        more => {
            return Err(unsupported(format!(
                "{} parts (only single-part files are read)",
                more.len()
            )))
        }
    };
    let (width, height) = (header.layer_size.width(), header.layer_size.height());
    limits.check_dimensions(width as u64, height as u64)?;
    if header.deep {
        return Err(unsupported("deep data"));
    }
    let channels = &header.channels.list;
    if channels.is_empty() {
        return Err(malformed("no channels"));
    }
    if channels.len() > limits.max_layers {
        return Err(unsupported(format!(
            "{} channels exceed the limit of {} layers",
            channels.len(),
            limits.max_layers
        )));
    }
    if let Some(c) = channels
        .iter()
        .find(|c| c.sampling.width() != 1 || c.sampling.height() != 1)
    {
        return Err(unsupported(format!("subsampled channel `{}`", c.name)));
    }
    if width == 0 || height == 0 {
        return Err(malformed("empty image"));
    }
    if !georef.is_sane(width, height) {
        return Err(RasterError::BadGeoreference(format!(
            "{georef:?} is not a sane georeference for a {width}×{height} grid"
        )));
    }

    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(map_exr_error)?;
    let layer = image.layer_data;
    if layer.size.width() != width || layer.size.height() != height {
        return Err(malformed("layer size differs from the header"));
    }
    let single = layer.channel_data.list.len() == 1;
    let n = width.saturating_mul(height);
    let mut valid = vec![true; n];
    let mut layers: Vec<(String, Array2<f32>)> = Vec::new();
    for channel in layer.channel_data.list {
        let name = if single {
            ELEVATION.to_string()
        } else {
            channel.name.to_string()
        };
        let values: Vec<f32> = match channel.sample_data {
            FlatSamples::F16(v) => v.into_iter().map(f16::to_f32).collect(),
            FlatSamples::F32(v) => v,
            FlatSamples::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        };
        if values.len() != n {
            return Err(malformed(format!(
                "channel `{name}` holds {} samples for a {width}×{height} image",
                values.len()
            )));
        }
        for (ok, v) in valid.iter_mut().zip(&values) {
            *ok &= v.is_finite();
        }
        let data = Array2::from_shape_vec((height, width), values)
            .map_err(|e| malformed(e.to_string()))?;
        if layers.iter().any(|(existing, _)| *existing == name) {
            return Err(RasterError::LayerMismatch(format!(
                "channel `{name}` given twice"
            )));
        }
        layers.push((name, data));
    }
    // Elevation first, by convention; a stable sort keeps the others in file order.
    layers.sort_by_key(|(name, _)| name != ELEVATION);
    if !valid.iter().any(|&v| v) {
        return Err(RasterError::NoValidData);
    }
    let valid = if valid.iter().all(|&v| v) {
        None
    } else {
        Some(Array2::from_shape_vec((height, width), valid).map_err(|e| malformed(e.to_string()))?)
    };
    Ok(LayeredRaster {
        georef,
        layers,
        valid,
    })
}

/// Encodes `raster` as an in-memory single-part OpenEXR file with one lossless-compressed
/// float32 channel per layer, named after the layer. Cells invalid in the mask are written as
/// NaN. The georeference is not stored.
///
/// # Errors
/// [`RasterError::LayerMismatch`] when there are no layers, shapes differ or a layer name is empty
/// or repeated, [`RasterError::Malformed`] when encoding fails.
pub fn write_exr(raster: &LayeredRaster) -> Result<Vec<u8>, RasterError> {
    let (rows, cols) = raster.dim();
    if raster.layers.is_empty() || rows == 0 || cols == 0 {
        return Err(RasterError::LayerMismatch(
            "cannot write a raster without layers or cells".to_string(),
        ));
    }
    if let Some(m) = &raster.valid {
        if m.dim() != (rows, cols) {
            return Err(RasterError::LayerMismatch(format!(
                "mask is {}×{} but the layers are {rows}×{cols}",
                m.nrows(),
                m.ncols()
            )));
        }
    }
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (i, (name, data)) in raster.layers.iter().enumerate() {
        if data.dim() != (rows, cols) {
            return Err(RasterError::LayerMismatch(format!(
                "layer `{name}` is {}×{} but the first is {rows}×{cols}",
                data.nrows(),
                data.ncols()
            )));
        }
        if name.is_empty() || raster.layers[..i].iter().any(|(n, _)| n == name) {
            return Err(RasterError::LayerMismatch(format!(
                "layer name `{name}` is empty or repeated"
            )));
        }
        let printable =
            name.len() <= 255 && name.bytes().all(|b| b.is_ascii_graphic() || b == b' ');
        let text = Text::new_or_none(name.as_str())
            .filter(|_| printable)
            .ok_or_else(|| {
                RasterError::LayerMismatch(format!(
                    "layer name `{name}` is not printable ASCII EXR text"
                ))
            })?;
        let values: Vec<f32> = data
            .indexed_iter()
            .map(|((r, c), &v)| {
                let masked = raster
                    .valid
                    .as_ref()
                    .is_some_and(|m| !m.get((r, c)).copied().unwrap_or(false));
                if masked {
                    f32::NAN
                } else {
                    v
                }
            })
            .collect();
        list.push(AnyChannel::new(text, FlatSamples::F32(values)));
    }
    let layer = Layer::new(
        (cols, rows),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| malformed(format!("encoding failed: {e}")))?;
    Ok(out.into_inner())
}
