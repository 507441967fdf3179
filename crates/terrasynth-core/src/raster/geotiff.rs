//! GeoTIFF reading and writing on top of the `tiff` crate.
//!
//! Reading accepts single-band rasters of 8/16/32-bit integers or 32/64-bit floats (16-bit floats
//! and 8-bit signed integers too, since the decoder provides them), stored in strips or tiles,
//! uncompressed, Deflate (codes 8 and 32946), LZW or PackBits, with predictor 1, 2 or 3. The
//! georeference comes from ModelPixelScale + ModelTiepoint or a north-up ModelTransformation, and
//! the CRS from the GeoKeyDirectory (EPSG:4326, EPSG:3857 or a projected CRS in metres that
//! [`super::projection`] understands: UTM zones). `GDAL_NODATA` values and non-finite
//! values become invalid cells (stored as NaN in the returned grid's data).
//!
//! Writing produces a Deflate-compressed single-band float32 GeoTIFF that this reader (and GDAL)
//! reads back to the same values and georeference.

// Sizes and offsets come from the file: every sum and product on them is checked.
#![warn(clippy::arithmetic_side_effects)]

use std::fs::File;
use std::io::{BufWriter, Cursor, Seek, Write};
use std::path::Path;

use ndarray::Array2;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::encoder::{colortype, Compression, DeflateLevel, TiffEncoder};
use tiff::tags::Tag;
use tiff::{TiffError, TiffFormatError};

use super::error::RasterError;
use super::georef::{Crs, Georef};
use super::grid::Grid;
use super::limits::ReadLimits;

const FORMAT: &str = "GeoTIFF";

/// GeoKey: model type (1 projected, 2 geographic, 3 geocentric).
const GT_MODEL_TYPE: u16 = 1024;
/// GeoKey: raster type (1 PixelIsArea, 2 PixelIsPoint).
const GT_RASTER_TYPE: u16 = 1025;
/// GeoKey: EPSG code of a geographic CRS.
const GEOGRAPHIC_TYPE: u16 = 2048;
/// GeoKey: EPSG code of a projected CRS.
const PROJECTED_CS_TYPE: u16 = 3072;
/// `GTRasterTypeGeoKey` value: pixel values describe areas.
const PIXEL_IS_AREA: u16 = 1;
/// `GTRasterTypeGeoKey` value: pixel values describe points at pixel centres.
const PIXEL_IS_POINT: u16 = 2;

/// Compression codes this reader accepts: none, LZW, Deflate, PackBits, old-style Deflate.
const SUPPORTED_COMPRESSIONS: [u16; 5] = [1, 5, 8, 32773, 32946];

fn malformed(detail: impl Into<String>) -> RasterError {
    RasterError::malformed(FORMAT, detail)
}

fn unsupported(detail: impl Into<String>) -> RasterError {
    RasterError::unsupported(FORMAT, detail)
}

/// Maps a `tiff` crate error to a [`RasterError`]. `dims` are the image dimensions when known, so
/// that an exceeded decoding limit reports as [`RasterError::TooLarge`].
fn map_tiff_error(err: TiffError, dims: Option<(u32, u32)>, limits: &ReadLimits) -> RasterError {
    match err {
        TiffError::FormatError(TiffFormatError::TiffSignatureNotFound)
        | TiffError::FormatError(TiffFormatError::TiffSignatureInvalid) => {
            RasterError::UnknownFormat("no TIFF signature".to_string())
        }
        TiffError::FormatError(e) => malformed(e.to_string()),
        TiffError::UnsupportedError(e) => unsupported(e.to_string()),
        TiffError::IoError(e) => malformed(format!("truncated or unreadable data: {e}")),
        TiffError::LimitsExceeded => match dims {
            Some((w, h)) => RasterError::TooLarge {
                width: u64::from(w),
                height: u64::from(h),
                limit: limits.max_pixels,
            },
            None => malformed("a tag value exceeds the decoder's size limits"),
        },
        TiffError::IntSizeError => malformed("a size does not fit this platform"),
        TiffError::UsageError(e) => malformed(e.to_string()),
    }
}

/// Reads `(width, height)` from the first IFD of a classic (non-Big) TIFF without the decoder,
/// so the size limit can be applied before anything else is parsed. Returns `None` when the
/// header cannot be read this way; the real decoder then reports the problem.
fn prescan_dimensions(bytes: &[u8]) -> Option<(u64, u64)> {
    let little = match bytes.get(0..4)? {
        b"II*\0" => true,
        b"MM\0*" => false,
        _ => return None,
    };
    let u16_at = |off: usize| -> Option<u16> {
        let b: [u8; 2] = bytes.get(off..off.checked_add(2)?)?.try_into().ok()?;
        Some(if little {
            u16::from_le_bytes(b)
        } else {
            u16::from_be_bytes(b)
        })
    };
    let u32_at = |off: usize| -> Option<u32> {
        let b: [u8; 4] = bytes.get(off..off.checked_add(4)?)?.try_into().ok()?;
        Some(if little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    };
    let ifd = usize::try_from(u32_at(4)?).ok()?;
    let count = usize::from(u16_at(ifd)?);
    let (mut width, mut height) = (None, None);
    for i in 0..count {
        let entry = ifd.checked_add(2)?.checked_add(i.checked_mul(12)?)?;
        let tag = u16_at(entry)?;
        if tag != 256 && tag != 257 {
            continue;
        }
        let value = match u16_at(entry.checked_add(2)?)? {
            3 => u64::from(u16_at(entry.checked_add(8)?)?),
            4 => u64::from(u32_at(entry.checked_add(8)?)?),
            _ => return None,
        };
        if tag == 256 {
            width = Some(value);
        } else {
            height = Some(value);
        }
    }
    Some((width?, height?))
}

/// The GeoKeys this reader uses, all with values stored inline in the directory.
#[derive(Debug, Default)]
struct GeoKeys {
    model_type: Option<u16>,
    raster_type: Option<u16>,
    geographic: Option<u16>,
    projected: Option<u16>,
}

/// Parses a GeoKeyDirectoryTag: a 4-short header (version, revision, minor, key count) followed by
/// 4-short entries (key id, tag location, count, value or offset).
fn parse_geokeys(dir: &[u16]) -> Result<GeoKeys, RasterError> {
    let header = dir
        .get(0..4)
        .ok_or_else(|| malformed("GeoKeyDirectoryTag is shorter than its header"))?;
    if header.first() != Some(&1) {
        return Err(malformed(format!(
            "GeoKeyDirectoryTag version {} (expected 1)",
            header.first().copied().unwrap_or(0)
        )));
    }
    let n = usize::from(header.get(3).copied().unwrap_or(0));
    let mut keys = GeoKeys::default();
    for i in 0..n {
        // n < 2^16, so these cannot overflow; checked all the same, like every file offset.
        let start = i.saturating_mul(4).saturating_add(4);
        let entry = dir.get(start..start.saturating_add(4)).ok_or_else(|| {
            malformed(format!(
                "GeoKeyDirectoryTag announces {n} keys but holds {}",
                (dir.len().saturating_sub(4)) / 4
            ))
        })?;
        let (id, location, value) = (entry[0], entry[1], entry[3]);
        if location != 0 {
            // Values held in GeoDoubleParams / GeoAsciiParams: none of the keys we use.
            continue;
        }
        match id {
            GT_MODEL_TYPE => keys.model_type = Some(value),
            GT_RASTER_TYPE => keys.raster_type = Some(value),
            GEOGRAPHIC_TYPE => keys.geographic = Some(value),
            PROJECTED_CS_TYPE => keys.projected = Some(value),
            _ => {}
        }
    }
    Ok(keys)
}

/// The CRS named by the GeoKeys. Projected files are judged by ProjectedCSTypeGeoKey, geographic
/// ones by GeographicTypeGeoKey; without a model type, a projected code wins.
fn crs_from_keys(keys: &GeoKeys) -> Result<Crs, RasterError> {
    let code = match keys.model_type {
        Some(1) => keys.projected.map(|c| ("ProjectedCSTypeGeoKey", c)),
        Some(2) => keys.geographic.map(|c| ("GeographicTypeGeoKey", c)),
        Some(t) if t != 0 && t != 32767 => {
            return Err(unsupported(format!("GTModelTypeGeoKey {t} (geocentric?)")))
        }
        _ => keys
            .projected
            .map(|c| ("ProjectedCSTypeGeoKey", c))
            .or(keys.geographic.map(|c| ("GeographicTypeGeoKey", c))),
    };
    let (key, code) = code.ok_or_else(|| {
        RasterError::BadGeoreference(
            "the GeoKeyDirectory names no CRS (no GeographicTypeGeoKey or ProjectedCSTypeGeoKey)"
                .to_string(),
        )
    })?;
    Crs::from_epsg(u32::from(code)).ok_or_else(|| {
        unsupported(format!(
            "CRS {key} = {code} (EPSG:{code}); read are EPSG:4326, EPSG:3857 and the UTM zones \
             EPSG:326xx/327xx (WGS84), 269xx (NAD83) and 258xx (ETRS89)"
        ))
    })
}

/// The raw transform tags of a GeoTIFF.
#[derive(Debug, Default)]
struct TransformTags {
    pixel_scale: Option<Vec<f64>>,
    tiepoint: Option<Vec<f64>>,
    transformation: Option<Vec<f64>>,
}

/// Computes the north-up georeference from the transform tags and GeoKeys.
fn georef_from_tags(
    tags: &TransformTags,
    keys: &GeoKeys,
    width: u32,
    height: u32,
) -> Result<Georef, RasterError> {
    let crs = crs_from_keys(keys)?;
    let (mut west, mut north, pixel_width, pixel_height) =
        match (&tags.pixel_scale, &tags.tiepoint, &tags.transformation) {
            (Some(scale), Some(tie), _) => {
                let (sx, sy) = match scale.as_slice() {
                    [sx, sy, ..] => (*sx, *sy),
                    _ => return Err(malformed("ModelPixelScaleTag has fewer than 2 values")),
                };
                let (i, j, x, y) = match tie.as_slice() {
                    [i, j, _k, x, y, _z, ..] => (*i, *j, *x, *y),
                    _ => return Err(malformed("ModelTiepointTag has fewer than 6 values")),
                };
                (x - i * sx, y + j * sy, sx, sy)
            }
            (_, _, Some(t)) => {
                let m: &[f64; 16] = t
                    .as_slice()
                    .try_into()
                    .map_err(|_| malformed("ModelTransformationTag does not hold 16 values"))?;
                let (a, b, d, e, f, h) = (m[0], m[1], m[3], m[4], m[5], m[7]);
                if b != 0.0 || e != 0.0 {
                    return Err(unsupported(
                        "rotated or sheared ModelTransformation (only north-up grids are read)",
                    ));
                }
                (d, h, a, -f)
            }
            _ => {
                return Err(RasterError::BadGeoreference(
                    "no ModelPixelScale + ModelTiepoint and no ModelTransformation tag".to_string(),
                ))
            }
        };
    match keys.raster_type.unwrap_or(PIXEL_IS_AREA) {
        PIXEL_IS_AREA => {}
        PIXEL_IS_POINT => {
            // The transform maps pixel indices to pixel centres: move to the corner.
            west -= 0.5 * pixel_width;
            north += 0.5 * pixel_height;
        }
        other => {
            return Err(RasterError::BadGeoreference(format!(
                "GTRasterTypeGeoKey {other} is neither PixelIsArea (1) nor PixelIsPoint (2)"
            )))
        }
    }
    let georef = Georef {
        crs,
        west,
        north,
        pixel_width,
        pixel_height,
    };
    if !georef.is_sane(width as usize, height as usize) {
        return Err(RasterError::BadGeoreference(format!(
            "west {west}, north {north}, pixel {pixel_width} × {pixel_height} for a \
             {width}×{height} grid is not a finite north-up transform within the domain of EPSG:{}",
            crs.epsg()
        )));
    }
    Ok(georef)
}

/// Parses a GDAL_NODATA string (`"-32768"`, `"nan"`, `"-inf"`...).
fn parse_nodata(text: &str) -> Result<f64, RasterError> {
    let t = text.trim_matches(|c: char| c == '\0' || c.is_whitespace());
    t.parse::<f64>()
        .map_err(|_| malformed(format!("GDAL_NODATA value {t:?} is not a number")))
}

/// Converts decoded samples to `f32` and a validity vector: a cell is valid when it is finite and
/// differs from `nodata` (compared at the sample type's precision).
fn to_f32_with_validity(
    result: DecodingResult,
    nodata: Option<f64>,
) -> Result<(Vec<f32>, Vec<bool>), RasterError> {
    fn convert<T: Copy>(
        v: Vec<T>,
        to64: impl Fn(T) -> f64,
        nodata: Option<f64>,
        nodata_in_type: impl Fn(f64) -> f64,
    ) -> (Vec<f32>, Vec<bool>) {
        let nd = nodata.map(nodata_in_type);
        let mut data = Vec::with_capacity(v.len());
        let mut valid = Vec::with_capacity(v.len());
        for x in v {
            let x = to64(x);
            let ok = x.is_finite() && nd.is_none_or(|nd| x != nd);
            data.push(if ok { x as f32 } else { f32::NAN });
            valid.push(ok);
        }
        (data, valid)
    }
    let same = |nd: f64| nd;
    let via_f32 = |nd: f64| f64::from(nd as f32);
    Ok(match result {
        DecodingResult::U8(v) => convert(v, f64::from, nodata, same),
        DecodingResult::I8(v) => convert(v, f64::from, nodata, same),
        DecodingResult::U16(v) => convert(v, f64::from, nodata, same),
        DecodingResult::I16(v) => convert(v, f64::from, nodata, same),
        DecodingResult::U32(v) => convert(v, f64::from, nodata, same),
        DecodingResult::I32(v) => convert(v, f64::from, nodata, same),
        DecodingResult::F16(v) => convert(v, |x| f64::from(x.to_f32()), nodata, via_f32),
        DecodingResult::F32(v) => convert(v, f64::from, nodata, via_f32),
        DecodingResult::F64(v) => convert(v, |x| x, nodata, same),
        DecodingResult::U64(_) | DecodingResult::I64(_) => {
            return Err(unsupported("64-bit integer samples"))
        }
    })
}

/// Reads a single-band GeoTIFF held in memory. See the module documentation for what is
/// supported. Invalid cells (GDAL_NODATA or non-finite) are NaN in `data` and `false` in the mask;
/// the mask is `None` when every cell is valid.
///
/// # Errors
/// [`RasterError::UnknownFormat`] without a TIFF signature, [`RasterError::TooLarge`] when the
/// header exceeds `limits` (before pixel data is allocated), [`RasterError::Unsupported`] for
/// several bands, other compressions or CRSs and rotated transforms,
/// [`RasterError::BadGeoreference`] for a missing or insane georeference,
/// [`RasterError::Malformed`] for broken or truncated files and [`RasterError::NoValidData`] when
/// no cell is valid.
pub fn read_geotiff(bytes: &[u8], limits: &ReadLimits) -> Result<Grid, RasterError> {
    if let Some((w, h)) = prescan_dimensions(bytes) {
        limits.check_dimensions(w, h)?;
    }
    let tiff_limits = {
        let mut l = Limits::default();
        // Largest sample is 8 bytes.
        l.decoding_buffer_size = limits.byte_budget(8);
        l.intermediate_buffer_size = l.intermediate_buffer_size.min(l.decoding_buffer_size);
        l
    };
    let mut dec = Decoder::new(Cursor::new(bytes))
        .map_err(|e| map_tiff_error(e, None, limits))?
        .with_limits(tiff_limits);
    let (width, height) = dec
        .dimensions()
        .map_err(|e| map_tiff_error(e, None, limits))?;
    limits.check_dimensions(u64::from(width), u64::from(height))?;
    let dims = Some((width, height));
    let err = |e: TiffError| map_tiff_error(e, dims, limits);

    let samples = dec
        .find_tag_unsigned::<u16>(Tag::SamplesPerPixel)
        .map_err(err)?
        .unwrap_or(1);
    if samples != 1 {
        return Err(unsupported(format!(
            "{samples} samples per pixel (only single-band rasters are read)"
        )));
    }
    let compression = dec
        .find_tag_unsigned::<u16>(Tag::Compression)
        .map_err(err)?
        .unwrap_or(1);
    if !SUPPORTED_COMPRESSIONS.contains(&compression) {
        let name = match compression {
            6 | 7 => "JPEG",
            2..=4 => "CCITT fax",
            34712 => "JPEG 2000",
            34887 => "LERC",
            50000 => "ZSTD",
            50001 => "WebP",
            _ => "unknown",
        };
        return Err(unsupported(format!(
            "compression {compression} ({name}); only none, LZW, Deflate and PackBits are read"
        )));
    }

    let f64_vec = |dec: &mut Decoder<Cursor<&[u8]>>, tag: Tag| -> Result<_, RasterError> {
        dec.find_tag(tag)
            .map_err(err)?
            .map(|v| v.into_f64_vec())
            .transpose()
            .map_err(|e| malformed(format!("{tag:?}: {e}")))
    };
    let tags = TransformTags {
        pixel_scale: f64_vec(&mut dec, Tag::ModelPixelScaleTag)?,
        tiepoint: f64_vec(&mut dec, Tag::ModelTiepointTag)?,
        transformation: f64_vec(&mut dec, Tag::ModelTransformationTag)?,
    };
    let keys = match dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(err)? {
        Some(v) => parse_geokeys(
            &v.into_u16_vec()
                .map_err(|e| malformed(format!("GeoKeyDirectoryTag: {e}")))?,
        )?,
        None => {
            return Err(RasterError::BadGeoreference(
                "no GeoKeyDirectoryTag: the CRS is unknown".to_string(),
            ))
        }
    };
    let georef = georef_from_tags(&tags, &keys, width, height)?;
    let nodata = match dec.find_tag(Tag::GdalNodata).map_err(err)? {
        Some(v) => Some(parse_nodata(
            &v.into_string()
                .map_err(|e| malformed(format!("GDAL_NODATA: {e}")))?,
        )?),
        None => None,
    };

    let decoded = dec.read_image().map_err(err)?;
    let (data, valid) = to_f32_with_validity(decoded, nodata)?;
    let shape = (height as usize, width as usize);
    if data.len() != shape.0.saturating_mul(shape.1) {
        return Err(malformed(format!(
            "decoded {} samples for a {width}×{height} image",
            data.len()
        )));
    }
    let any_invalid = valid.iter().any(|v| !v);
    if !valid.iter().any(|&v| v) {
        return Err(RasterError::NoValidData);
    }
    let data = Array2::from_shape_vec(shape, data).map_err(|e| malformed(e.to_string()))?;
    let valid = if any_invalid {
        Some(Array2::from_shape_vec(shape, valid).map_err(|e| malformed(e.to_string()))?)
    } else {
        None
    };
    Ok(Grid {
        data,
        georef,
        valid,
    })
}

/// Reads a GeoTIFF file; see [`read_geotiff`].
///
/// # Errors
/// [`RasterError::Io`] when the file cannot be read, otherwise as [`read_geotiff`].
pub fn read_geotiff_file(path: &Path, limits: &ReadLimits) -> Result<Grid, RasterError> {
    let bytes = std::fs::read(path)?;
    read_geotiff(&bytes, limits)
}

/// The GeoKeyDirectory for a CRS: GTModelType, GTRasterType = PixelIsArea and the EPSG code.
fn geokey_directory(crs: Crs) -> [u16; 16] {
    let (model_type, crs_key) = match crs {
        Crs::Epsg4326 => (2, GEOGRAPHIC_TYPE),
        Crs::Epsg3857 | Crs::Projected(_) => (1, PROJECTED_CS_TYPE),
    };
    [
        1,
        1,
        0,
        3,
        GT_MODEL_TYPE,
        0,
        1,
        model_type,
        GT_RASTER_TYPE,
        0,
        1,
        PIXEL_IS_AREA,
        crs_key,
        0,
        1,
        crs.epsg(),
    ]
}

/// Errors when a grid's mask does not have the shape of its data.
pub(crate) fn check_mask_shape(grid: &Grid) -> Result<(), RasterError> {
    match &grid.valid {
        Some(m) if m.dim() != grid.data.dim() => Err(RasterError::LayerMismatch(format!(
            "mask is {}×{} but the data is {}×{}",
            m.nrows(),
            m.ncols(),
            grid.rows(),
            grid.cols()
        ))),
        _ => Ok(()),
    }
}

/// Writes `grid` as a Deflate-compressed single-band float32 GeoTIFF with ModelPixelScale,
/// ModelTiepoint and GeoKeyDirectory tags. When the grid has a mask, invalid cells are written as
/// NaN and `GDAL_NODATA` is set to `"nan"`.
///
/// # Errors
/// [`RasterError::BadGeoreference`] when the georeference is not sane for the grid,
/// [`RasterError::LayerMismatch`] when the mask's shape differs from the data's,
/// [`RasterError::Unsupported`] for an empty grid or one wider or taller than `u32::MAX`, and
/// [`RasterError::Io`] / [`RasterError::Malformed`] when encoding fails.
pub fn write_geotiff<W: Write + Seek>(grid: &Grid, out: W) -> Result<(), RasterError> {
    let (rows, cols) = grid.data.dim();
    if rows == 0 || cols == 0 {
        return Err(unsupported("writing an empty grid"));
    }
    let width = u32::try_from(cols).map_err(|_| unsupported("grid wider than 2^32 - 1"))?;
    let height = u32::try_from(rows).map_err(|_| unsupported("grid taller than 2^32 - 1"))?;
    let g = grid.georef;
    if !g.is_sane(cols, rows) {
        return Err(RasterError::BadGeoreference(format!(
            "cannot write an insane georeference {g:?} for a {cols}×{rows} grid"
        )));
    }
    check_mask_shape(grid)?;
    let mut data = Vec::with_capacity(grid.data.len());
    for ((r, c), &v) in grid.data.indexed_iter() {
        let masked = grid
            .valid
            .as_ref()
            .is_some_and(|m| !m.get((r, c)).copied().unwrap_or(false));
        data.push(if masked { f32::NAN } else { v });
    }
    let write_err = |e: TiffError| match e {
        TiffError::IoError(io) => RasterError::Io(io),
        other => malformed(format!("encoding failed: {other}")),
    };
    let mut enc = TiffEncoder::new(out)
        .map_err(write_err)?
        .with_compression(Compression::Deflate(DeflateLevel::Fast));
    let mut image = enc
        .new_image::<colortype::Gray32Float>(width, height)
        .map_err(write_err)?;
    {
        let dir = image.encoder();
        dir.write_tag(
            Tag::ModelPixelScaleTag,
            &[g.pixel_width, g.pixel_height, 0.0][..],
        )
        .map_err(write_err)?;
        dir.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, g.west, g.north, 0.0][..],
        )
        .map_err(write_err)?;
        dir.write_tag(Tag::GeoKeyDirectoryTag, &geokey_directory(g.crs)[..])
            .map_err(write_err)?;
        if grid.valid.is_some() {
            dir.write_tag(Tag::GdalNodata, "nan").map_err(write_err)?;
        }
    }
    image.write_data(&data).map_err(write_err)?;
    Ok(())
}

/// Writes `grid` to a GeoTIFF file at `path`; see [`write_geotiff`].
///
/// # Errors
/// As [`write_geotiff`], plus [`RasterError::Io`] when the file cannot be created.
pub fn write_geotiff_file(grid: &Grid, path: &Path) -> Result<(), RasterError> {
    let mut out = BufWriter::new(File::create(path)?);
    write_geotiff(grid, &mut out)?;
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geokeys_parse_inline_values_and_skip_param_references() {
        let dir = [
            1, 1, 0, 4, 1024, 0, 1, 1, 1025, 0, 1, 2, 3072, 0, 1, 3857, 3073, 34737, 10, 0,
        ];
        let k = parse_geokeys(&dir).unwrap();
        assert_eq!(k.model_type, Some(1));
        assert_eq!(k.raster_type, Some(2));
        assert_eq!(k.projected, Some(3857));
        assert_eq!(k.geographic, None);
    }

    #[test]
    fn geokeys_with_too_few_entries_are_malformed() {
        assert!(matches!(
            parse_geokeys(&[1, 1, 0, 2, 1024, 0, 1, 2]),
            Err(RasterError::Malformed { .. })
        ));
        assert!(parse_geokeys(&[1, 1]).is_err());
    }

    #[test]
    fn projected_model_type_selects_projected_code() {
        let keys = GeoKeys {
            model_type: Some(1),
            projected: Some(3785),
            geographic: Some(4326),
            raster_type: None,
        };
        assert_eq!(crs_from_keys(&keys).unwrap(), Crs::Epsg3857);
        let utm = GeoKeys {
            projected: Some(32633),
            ..keys
        };
        assert_eq!(crs_from_keys(&utm).unwrap(), Crs::Projected(32633));
        let lambert = GeoKeys {
            projected: Some(2154),
            ..utm
        };
        let e = crs_from_keys(&lambert).unwrap_err();
        assert!(matches!(e, RasterError::Unsupported { .. }));
        assert!(e.to_string().contains("EPSG:2154"), "{e}");
    }

    #[test]
    fn nodata_strings_parse() {
        assert_eq!(parse_nodata("-32768\0").unwrap(), -32768.0);
        assert!(parse_nodata(" nan ").unwrap().is_nan());
        assert!(parse_nodata("none").is_err());
    }

    #[test]
    fn nodata_compares_at_float32_precision() {
        // 0.1 as f64 differs from 0.1f32, but GDAL compares at the band's type.
        let (data, valid) =
            to_f32_with_validity(DecodingResult::F32(vec![0.1, 1.0]), Some(0.1)).unwrap();
        assert_eq!(valid, vec![false, true]);
        assert!(data[0].is_nan());
        assert_eq!(data[1], 1.0);
    }

    #[test]
    fn prescan_reads_dimensions_of_both_byte_orders() {
        let mut le = b"II*\0\x08\0\0\0".to_vec();
        le.extend_from_slice(&2u16.to_le_bytes());
        for (tag, val) in [(256u16, 300u32), (257, 70_000)] {
            le.extend_from_slice(&tag.to_le_bytes());
            le.extend_from_slice(&4u16.to_le_bytes());
            le.extend_from_slice(&1u32.to_le_bytes());
            le.extend_from_slice(&val.to_le_bytes());
        }
        assert_eq!(prescan_dimensions(&le), Some((300, 70_000)));
        let mut be = b"MM\0*\0\0\0\x08".to_vec();
        be.extend_from_slice(&2u16.to_be_bytes());
        for (tag, val) in [(256u16, 5u16), (257, 9)] {
            be.extend_from_slice(&tag.to_be_bytes());
            be.extend_from_slice(&3u16.to_be_bytes());
            be.extend_from_slice(&1u32.to_be_bytes());
            be.extend_from_slice(&val.to_be_bytes());
            be.extend_from_slice(&[0, 0]);
        }
        assert_eq!(prescan_dimensions(&be), Some((5, 9)));
        assert_eq!(prescan_dimensions(&le[..20]), None);
    }
}
