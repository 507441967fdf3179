//! Tile encoders (and the decoders tests and clients' checks need): terrarium and mapbox
//! Terrain-RGB elevation PNGs and lossless WebPs, 8-bit grey PNGs, RGBA PNGs and lossless WebPs,
//! and float32 OpenEXR. A WebP tile holds exactly the pixels of the PNG of the same request
//! (lossless, `image-webp`'s encoder at its fixed settings), so it decodes to the same heights.
//!
//! Output bytes are deterministic: the PNG encoder always runs with the same settings
//! (8-bit, the Paeth row filter and zlib-rs deflate at level 3 — fast, with the dynamic Huffman codes
//! that let quantised data shrink), and EXR files are written single-threaded
//! with ZIP (16 scan lines, increasing line order, `miniz_oxide` at a fixed level). No metadata that
//! varies (times, software versions) is written.
//!
//! Vector (MVT) and GeoJSON tiles are not compressed by their format; [`gzip`] compresses them for
//! transfer (HTTP `Content-Encoding: gzip`) and for archives, with fixed settings as well.
//!
//! Decode formulas for clients: terrarium `h = R·256 + G + B/256 − 32768`; mapbox
//! `h = −10000 + (R·65536 + G·256 + B)·0.1`.

use std::io::{Cursor, Read, Write};

use ndarray::Array2;

use super::error::TileError;
use terrasynth_core::raster::{read_exr, write_exr, Georef, LayeredRaster, ReadLimits};

/// The height in metres that non-finite (NaN) heights are encoded as by
/// [`encode_terrarium_png`] and [`encode_mapbox_png`]: sea level. Infinite heights are clamped to
/// the encodable range like any other out-of-range height.
pub const NAN_FILL_HEIGHT_M: f64 = 0.0;

/// Largest mapbox code, `2^24 − 1`.
const MAPBOX_MAX: f64 = 16_777_215.0;

/// Deflate level of every PNG (zlib-rs, enabled through flate2's `zlib-rs` feature). Measured on
/// 60 real zoom-12..14 elevation tiles with the Paeth filter (`examples` throw-away trial): the
/// fixed-code `fdeflate` path 134.5 KB in 0.8 ms; level 1 (static codes) 127.8 KB in 1.7 ms;
/// level 3 82.8 KB in 3.1 ms; level 4 81.6 KB in 5.0 ms. Level 3 is where size stops paying for
/// time; its dynamic Huffman codes are what profit from [`TERRARIUM_STEPS_PER_M`].
const PNG_DEFLATE_LEVEL: u8 = 3;

/// Deflate level of [`gzip`] (zlib-rs). Measured with zlib on the default world's zoom-14 instance
/// tile 11482/6048: the `.mvt` (201,270 bytes) becomes 76.8 KB at level 1 in 1.8 ms, 73.6 KB at
/// level 3 in 2.9 ms, 69.0 KB at level 6 in 5.5 ms and 67.8 KB at level 9 in 37 ms; the `.json`
/// (1,562,671 bytes) 258, 240, 205 and 202 KB in 6.7, 10, 21 and 29 ms. A tile is compressed once
/// and cached compressed, against 100 ms and more of computing it cold: level 6, zlib's default.
const GZIP_LEVEL: u32 = 6;

/// Largest output [`gunzip`] accepts: far above any tile (the largest GeoJSON instance tile is a
/// few MB), so that a hostile archive cannot expand without bound.
pub const GUNZIP_MAX_BYTES: u64 = 256 << 20;

/// `bytes` as one gzip member (RFC 1952) with fixed settings — no file name, no comment,
/// modification time 0, operating system 255 (unknown), zlib-rs deflate at level 6
/// (`GZIP_LEVEL`) — so the same bytes always give the same output on every machine.
pub fn gzip(bytes: &[u8]) -> Result<Vec<u8>, TileError> {
    let out = Vec::with_capacity(bytes.len() / 3 + 64);
    let mut enc = flate2::GzBuilder::new()
        .mtime(0)
        .operating_system(255)
        .write(out, flate2::Compression::new(GZIP_LEVEL));
    enc.write_all(bytes)
        .and_then(|()| enc.finish())
        .map_err(|e| TileError::Encode(format!("gzip: {e}")))
}

/// The bytes of a gzip stream (what [`gzip`] wrote, or any RFC 1952 member), refusing output
/// longer than [`GUNZIP_MAX_BYTES`].
pub fn gunzip(bytes: &[u8]) -> Result<Vec<u8>, TileError> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes)
        .take(GUNZIP_MAX_BYTES + 1)
        .read_to_end(&mut out)
        .map_err(|e| TileError::Decode(format!("gzip: {e}")))?;
    if out.len() as u64 > GUNZIP_MAX_BYTES {
        return Err(TileError::Decode(format!(
            "gzip: more than {GUNZIP_MAX_BYTES} bytes"
        )));
    }
    Ok(out)
}

/// Terrarium PNGs carry heights rounded to `1 / TERRARIUM_STEPS_PER_M` metres (6.25 cm): finer
/// than the mapbox encoding's 0.1 m and far below what a DEM resolves, but it leaves the blue
/// channel 16 values instead of 256 of noise, which makes tiles ~40 % smaller (and faster to
/// serve). Full float32 precision is what the `.exr` tiles are for.
pub const TERRARIUM_STEPS_PER_M: f64 = 16.0;
const _: () = assert!(
    TERRARIUM_STEPS_PER_M as u32 <= 256 && (TERRARIUM_STEPS_PER_M as u32).is_power_of_two()
);

/// Image dimensions `(width, height)` as PNG needs them, checking they are non-zero and fit `u32`.
fn png_dims(rows: usize, cols: usize) -> Result<(u32, u32), TileError> {
    let w =
        u32::try_from(cols).map_err(|_| TileError::Encode(format!("width {cols} too large")))?;
    let h =
        u32::try_from(rows).map_err(|_| TileError::Encode(format!("height {rows} too large")))?;
    if w == 0 || h == 0 {
        return Err(TileError::Encode(format!("empty image {cols}×{rows}")));
    }
    Ok((w, h))
}

/// Writes an 8-bit PNG of `color` type from packed row-major samples, with fixed settings.
fn write_png(
    rows: usize,
    cols: usize,
    color: png::ColorType,
    samples: &[u8],
) -> Result<Vec<u8>, TileError> {
    let (w, h) = png_dims(rows, cols)?;
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, w, h);
        encoder.set_color(color);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_deflate_compression(png::DeflateCompression::Level(PNG_DEFLATE_LEVEL));
        encoder.set_filter(png::Filter::Paeth);
        let mut writer = encoder
            .write_header()
            .map_err(|e| TileError::Encode(e.to_string()))?;
        writer
            .write_image_data(samples)
            .map_err(|e| TileError::Encode(e.to_string()))?;
        writer
            .finish()
            .map_err(|e| TileError::Encode(e.to_string()))?;
    }
    Ok(out)
}

/// Encodes heights in metres as a terrarium RGB PNG: with `v = h + 32768` rounded to the nearest
/// multiple of `1 / TERRARIUM_STEPS_PER_M` (1/16 m) and clamped to `[0, 65535 + 15/16]`,
/// `R = floor(v / 256)`, `G = floor(v) mod 256`, `B = frac(v) · 256`, so
/// `R·256 + G + B/256 − 32768` is `h` to the nearest 1/16 m.
/// NaN heights are encoded as [`NAN_FILL_HEIGHT_M`]. Errors only for an empty or oversized array.
pub fn encode_terrarium_png(heights: &Array2<f32>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = heights.dim();
    write_png(rows, cols, png::ColorType::Rgb, &terrarium_rgb(heights))
}

/// The packed RGB samples of [`encode_terrarium_png`].
fn terrarium_rgb(heights: &Array2<f32>) -> Vec<u8> {
    let (rows, cols) = heights.dim();
    let steps = TERRARIUM_STEPS_PER_M;
    // The largest code: (65535 + 15/16) m above −32768, in steps.
    let max_code = 65_536.0 * steps - 1.0;
    let frac_shift = 8 - (steps as u32).trailing_zeros();
    let mut rgb = Vec::with_capacity(rows * cols * 3);
    for &h in heights.iter() {
        let h = if h.is_nan() {
            NAN_FILL_HEIGHT_M
        } else {
            f64::from(h)
        };
        // Integer arithmetic from here: `code` is v in steps, within 0..=max_code.
        let code = ((h + 32_768.0) * steps).round().clamp(0.0, max_code) as u32;
        let whole = code / steps as u32;
        let frac = code % steps as u32;
        rgb.extend_from_slice(&[
            (whole >> 8) as u8,
            (whole & 255) as u8,
            (frac << frac_shift) as u8,
        ]);
    }
    rgb
}

/// Encodes heights in metres as a mapbox Terrain-RGB PNG: `v = round((h + 10000) · 10)` clamped to
/// `0..=2^24 − 1`, `R = v >> 16`, `G = (v >> 8) & 255`, `B = v & 255`, so
/// `−10000 + (R·65536 + G·256 + B)·0.1` is `h` to the nearest 0.1 m (within −10000..=1667721.5 m).
/// NaN heights are encoded as [`NAN_FILL_HEIGHT_M`]. Errors only for an empty or oversized array.
pub fn encode_mapbox_png(heights: &Array2<f32>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = heights.dim();
    write_png(rows, cols, png::ColorType::Rgb, &mapbox_rgb(heights))
}

/// The packed RGB samples of [`encode_mapbox_png`].
fn mapbox_rgb(heights: &Array2<f32>) -> Vec<u8> {
    let (rows, cols) = heights.dim();
    let mut rgb = Vec::with_capacity(rows * cols * 3);
    for &h in heights.iter() {
        let h = if h.is_nan() {
            NAN_FILL_HEIGHT_M
        } else {
            f64::from(h)
        };
        let v = ((h + 10_000.0) * 10.0).round().clamp(0.0, MAPBOX_MAX) as u32;
        rgb.extend_from_slice(&[(v >> 16) as u8, ((v >> 8) & 255) as u8, (v & 255) as u8]);
    }
    rgb
}

/// Writes a lossless WebP from packed row-major RGB (`alpha` false) or RGBA samples.
fn write_webp(rows: usize, cols: usize, alpha: bool, samples: &[u8]) -> Result<Vec<u8>, TileError> {
    let (w, h) = png_dims(rows, cols)?;
    let color = if alpha {
        image_webp::ColorType::Rgba8
    } else {
        image_webp::ColorType::Rgb8
    };
    let mut out = Vec::new();
    image_webp::WebPEncoder::new(&mut out)
        .encode(samples, w, h, color)
        .map_err(|e| TileError::Encode(e.to_string()))?;
    Ok(out)
}

/// [`encode_terrarium_png`]'s pixels as a lossless WebP.
pub fn encode_terrarium_webp(heights: &Array2<f32>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = heights.dim();
    write_webp(rows, cols, false, &terrarium_rgb(heights))
}

/// [`encode_mapbox_png`]'s pixels as a lossless WebP.
pub fn encode_mapbox_webp(heights: &Array2<f32>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = heights.dim();
    write_webp(rows, cols, false, &mapbox_rgb(heights))
}

/// [`encode_rgba_png`]'s pixels as a lossless WebP.
pub fn encode_rgba_webp(rgba: &Array2<[u8; 4]>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = rgba.dim();
    let samples: Vec<u8> = rgba.iter().flatten().copied().collect();
    write_webp(rows, cols, true, &samples)
}

/// Whether `bytes` are a WebP file (`RIFF....WEBP`).
fn is_webp(bytes: &[u8]) -> bool {
    bytes.len() >= 12 && &bytes[..4] == b"RIFF" && &bytes[8..12] == b"WEBP"
}

/// Decodes a WebP (RGB or RGBA) into `(R, G, B)` triples, shape `(height, width)`.
fn decode_rgb_webp(bytes: &[u8]) -> Result<Array2<[u8; 3]>, TileError> {
    let err = |e: image_webp::DecodingError| TileError::Decode(e.to_string());
    let mut d = image_webp::WebPDecoder::new(Cursor::new(bytes)).map_err(err)?;
    let (w, h) = d.dimensions();
    let (w, h) = (w as usize, h as usize);
    if w.saturating_mul(h) > 4096 * 4096 {
        return Err(TileError::Decode(format!("WebP of {w}×{h} is too large")));
    }
    let channels = if d.has_alpha() { 4 } else { 3 };
    let size = d
        .output_buffer_size()
        .ok_or_else(|| TileError::Decode("image too large".to_string()))?;
    if size != w * h * channels {
        return Err(TileError::Decode("unexpected WebP buffer size".to_string()));
    }
    let mut buf = vec![0u8; size];
    d.read_image(&mut buf).map_err(err)?;
    Ok(Array2::from_shape_fn((h, w), |(r, c)| {
        let o = (r * w + c) * channels;
        [buf[o], buf[o + 1], buf[o + 2]]
    }))
}

/// Encodes 8-bit values as a greyscale PNG (hillshade, log-scaled drainage...).
pub fn encode_gray_png(values: &Array2<u8>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = values.dim();
    let samples: Vec<u8> = values.iter().copied().collect();
    write_png(rows, cols, png::ColorType::Grayscale, &samples)
}

/// Encodes RGBA pixels as an RGBA PNG (splat maps, vegetation, colour maps).
pub fn encode_rgba_png(rgba: &Array2<[u8; 4]>) -> Result<Vec<u8>, TileError> {
    let (rows, cols) = rgba.dim();
    let samples: Vec<u8> = rgba.iter().flatten().copied().collect();
    write_png(rows, cols, png::ColorType::Rgba, &samples)
}

/// Decodes an 8-bit RGB or RGBA PNG into `(R, G, B)` triples, shape `(height, width)`.
fn decode_rgb_png(bytes: &[u8]) -> Result<Array2<[u8; 3]>, TileError> {
    let err = |e: png::DecodingError| TileError::Decode(e.to_string());
    let mut decoder = png::Decoder::new(Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(err)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| TileError::Decode("image too large".to_string()))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(err)?;
    if info.bit_depth != png::BitDepth::Eight {
        return Err(TileError::Decode(format!(
            "expected 8-bit samples, got {:?}",
            info.bit_depth
        )));
    }
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => {
            return Err(TileError::Decode(format!(
                "expected an RGB or RGBA PNG, got {other:?}"
            )))
        }
    };
    let (w, h) = (info.width as usize, info.height as usize);
    let line = info.line_size;
    if line < w * channels || buf.len() < line * h {
        return Err(TileError::Decode("short image data".to_string()));
    }
    Ok(Array2::from_shape_fn((h, w), |(r, c)| {
        let o = r * line + c * channels;
        [buf[o], buf[o + 1], buf[o + 2]]
    }))
}

/// The RGB triples of a PNG or a WebP (told by its first bytes).
fn decode_rgb(bytes: &[u8]) -> Result<Array2<[u8; 3]>, TileError> {
    if is_webp(bytes) {
        decode_rgb_webp(bytes)
    } else {
        decode_rgb_png(bytes)
    }
}

/// Decodes a terrarium PNG or WebP (8-bit RGB or RGBA) into heights
/// `R·256 + G + B/256 − 32768`, shape `(height, width)`.
pub fn decode_terrarium_png(bytes: &[u8]) -> Result<Array2<f32>, TileError> {
    let rgb = decode_rgb(bytes)?;
    Ok(rgb.mapv(|[r, g, b]| {
        (f64::from(r) * 256.0 + f64::from(g) + f64::from(b) / 256.0 - 32_768.0) as f32
    }))
}

/// Decodes a mapbox Terrain-RGB PNG or WebP (8-bit RGB or RGBA) into heights
/// `−10000 + (R·65536 + G·256 + B)·0.1`, shape `(height, width)`.
pub fn decode_mapbox_png(bytes: &[u8]) -> Result<Array2<f32>, TileError> {
    let rgb = decode_rgb(bytes)?;
    Ok(rgb.mapv(|[r, g, b]| {
        let v = (u32::from(r) << 16) | (u32::from(g) << 8) | u32::from(b);
        (-10_000.0 + f64::from(v) * 0.1) as f32
    }))
}

/// Encodes float32 channels as a single-part OpenEXR image (a tile has no georeference of its
/// own): one channel per entry, named as given, stored exactly (NaN included). This is
/// [`terrasynth_core::raster::write_exr`], the project's one EXR writer (ZIP blocks of 16 lines, written
/// sequentially so the bytes are deterministic). Errors when the list is empty, a name is empty,
/// repeated or not printable ASCII, or the shapes differ or are empty.
pub fn encode_float_exr(channels: &[(&str, &Array2<f32>)]) -> Result<Vec<u8>, TileError> {
    let raster = LayeredRaster {
        georef: Georef::local_metric(1.0),
        layers: channels
            .iter()
            .map(|(n, a)| (n.to_string(), (*a).clone()))
            .collect(),
        valid: None,
    };
    write_exr(&raster).map_err(|e| TileError::Encode(e.to_string()))
}

/// Decodes an OpenEXR image into `(name, values)` channels sorted by name (the order EXR stores
/// them in), each of shape `(height, width)`, through [`terrasynth_core::raster::read_exr`].
pub fn decode_float_exr(bytes: &[u8]) -> Result<Vec<(String, Array2<f32>)>, TileError> {
    let raster = read_exr(bytes, Georef::local_metric(1.0), &ReadLimits::default())
        .map_err(|e| TileError::Decode(e.to_string()))?;
    let mut layers = raster.layers;
    layers.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(layers)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use terrasynth_core::math;

    /// Raw RGB triples of a PNG, decoded by the test (through the shared helper, which only
    /// unpacks bytes and does not apply any height formula).
    fn pixels(bytes: &[u8]) -> Vec<[u8; 3]> {
        decode_rgb_png(bytes)
            .expect("decodes")
            .iter()
            .copied()
            .collect()
    }

    fn known_heights() -> Array2<f32> {
        Array2::from_shape_vec((1, 4), vec![-32768.0, 0.0, 1234.5, 7633.0]).expect("shape")
    }

    #[test]
    fn webp_tiles_decode_to_the_png_heights_and_pixels() {
        let heights = Array2::from_shape_fn((256, 256), |(r, c)| {
            let (r, c) = (r as f32, c as f32);
            1500.0 + 700.0 * math::sinf(r * 0.031) * math::cosf(c * 0.017) + 0.37 * r - 0.11 * c
                + if (r as usize * 7 + c as usize) % 13 == 0 {
                    f32::NAN
                } else {
                    0.0
                }
        });
        let (tp, tw) = (
            encode_terrarium_png(&heights).unwrap(),
            encode_terrarium_webp(&heights).unwrap(),
        );
        assert!(is_webp(&tw) && !is_webp(&tp));
        assert_eq!(
            decode_terrarium_png(&tp).unwrap(),
            decode_terrarium_png(&tw).unwrap()
        );
        assert_eq!(decode_rgb(&tp).unwrap(), decode_rgb(&tw).unwrap());
        let (mp, mw) = (
            encode_mapbox_png(&heights).unwrap(),
            encode_mapbox_webp(&heights).unwrap(),
        );
        assert_eq!(
            decode_mapbox_png(&mp).unwrap(),
            decode_mapbox_png(&mw).unwrap()
        );
        let rgba = Array2::from_shape_fn((256, 256), |(r, c)| {
            [
                r as u8,
                c as u8,
                (r * c % 251) as u8,
                if r == c { 0 } else { 255 },
            ]
        });
        let w = encode_rgba_webp(&rgba).unwrap();
        let mut d = image_webp::WebPDecoder::new(Cursor::new(&w[..])).unwrap();
        assert!(d.has_alpha());
        let mut buf = vec![0u8; d.output_buffer_size().unwrap()];
        d.read_image(&mut buf).unwrap();
        assert_eq!(buf, rgba.iter().flatten().copied().collect::<Vec<u8>>());
        // Deterministic bytes.
        assert_eq!(encode_rgba_webp(&rgba).unwrap(), w);
        assert!(decode_terrarium_png(b"RIFF\0\0\0\0WEBPjunk").is_err());
    }

    #[test]
    fn terrarium_encodes_known_heights() {
        let bytes = encode_terrarium_png(&known_heights()).expect("encodes");
        // By hand: v = h + 32768; 0 → (0,0,0); 32768 = 128·256 → (128,0,0);
        // 34002.5 = 132·256 + 210 + 0.5 → (132,210,128); 40401 = 157·256 + 209 → (157,209,0).
        assert_eq!(
            pixels(&bytes),
            vec![[0, 0, 0], [128, 0, 0], [132, 210, 128], [157, 209, 0]]
        );
        let back = decode_terrarium_png(&bytes).expect("decodes");
        for (a, b) in known_heights().iter().zip(back.iter()) {
            assert!((a - b).abs() <= 1.0 / 32.0, "{a} vs {b}");
        }
    }

    #[test]
    fn terrarium_rounds_to_the_nearest_sixteenth() {
        let heights =
            Array2::from_shape_vec((1, 6), vec![1234.47, 7633.03, -0.02, 10.96, 40_000.0, -4e4])
                .expect("shape");
        // By hand, in 1/16 m: 1234.47 → 1234.5; 7633.03 → 7633; −0.02 → 0; 10.96 → 10.9375
        // (v = 32778.9375 = 128·256 + 10 + 240/256); 40000 clamps to the largest multiple of
        // 1/16 a pixel holds, 65535 + 15/16; −40000 clamps to 0.
        assert_eq!(
            pixels(&encode_terrarium_png(&heights).expect("encodes")),
            vec![
                [132, 210, 128],
                [157, 209, 0],
                [128, 0, 0],
                [128, 10, 240],
                [255, 255, 240],
                [0, 0, 0]
            ]
        );
    }

    #[test]
    fn mapbox_encodes_known_heights() {
        let bytes = encode_mapbox_png(&known_heights()).expect("encodes");
        // By hand: v = round((h + 10000)·10); −32768 clamps to 0; 100000 = 1·65536 + 134·256
        // + 160; 112345 = 1·65536 + 182·256 + 217; 176330 = 2·65536 + 176·256 + 202.
        assert_eq!(
            pixels(&bytes),
            vec![[0, 0, 0], [1, 134, 160], [1, 182, 217], [2, 176, 202]]
        );
        let back = decode_mapbox_png(&bytes).expect("decodes");
        assert_eq!(back[[0, 0]], -10_000.0);
        for (a, b) in known_heights().iter().zip(back.iter()).skip(1) {
            assert!((a - b).abs() <= 0.1, "{a} vs {b}");
        }
    }

    #[test]
    fn nan_and_out_of_range_heights_never_panic() {
        let h = Array2::from_shape_vec(
            (1, 5),
            vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e9, -1e9],
        )
        .expect("shape");
        let t = decode_terrarium_png(&encode_terrarium_png(&h).expect("encodes")).expect("decodes");
        assert_eq!(t[[0, 0]], NAN_FILL_HEIGHT_M as f32);
        assert_eq!(t[[0, 2]], -32768.0);
        assert!((t[[0, 1]] - (32767.0 + 15.0 / 16.0)).abs() < 1e-3);
        let m = decode_mapbox_png(&encode_mapbox_png(&h).expect("encodes")).expect("decodes");
        assert_eq!(m[[0, 0]], NAN_FILL_HEIGHT_M as f32);
        assert_eq!(m[[0, 2]], -10_000.0);
        assert!((m[[0, 3]] - 1_667_721.5).abs() < 0.2);
        // Empty arrays are an error, not a panic.
        assert!(encode_terrarium_png(&Array2::zeros((0, 3))).is_err());
        assert!(encode_gray_png(&Array2::zeros((3, 0))).is_err());
        assert!(decode_terrarium_png(b"not a png").is_err());
    }

    #[test]
    fn encodings_are_deterministic() {
        let h = Array2::from_shape_fn((256, 256), |(r, c)| {
            math::sinf(r as f32 * 7.25 - c as f32 * 3.5) * 1500.0 + 2000.0
        });
        assert_eq!(
            encode_terrarium_png(&h).expect("a"),
            encode_terrarium_png(&h).expect("b")
        );
        assert_eq!(
            encode_mapbox_png(&h).expect("a"),
            encode_mapbox_png(&h).expect("b")
        );
        let g = h.mapv(|v| (v / 16.0) as u8);
        assert_eq!(
            encode_gray_png(&g).expect("a"),
            encode_gray_png(&g).expect("b")
        );
        let rgba = h.mapv(|v| [(v / 16.0) as u8, 1, 2, 255]);
        assert_eq!(
            encode_rgba_png(&rgba).expect("a"),
            encode_rgba_png(&rgba).expect("b")
        );
        let exr_a = encode_float_exr(&[("height", &h), ("aux", &g.mapv(f32::from))]).expect("a");
        let exr_b = encode_float_exr(&[("height", &h), ("aux", &g.mapv(f32::from))]).expect("b");
        assert_eq!(exr_a, exr_b);
    }

    #[test]
    fn gray_and_rgba_png_round_trip() {
        let g = Array2::from_shape_fn((3, 5), |(r, c)| (r * 50 + c) as u8);
        let bytes = encode_gray_png(&g).expect("encodes");
        let mut d = png::Decoder::new(Cursor::new(&bytes[..]))
            .read_info()
            .expect("info");
        let mut buf = vec![0; d.output_buffer_size().expect("size")];
        let info = d.next_frame(&mut buf).expect("frame");
        assert_eq!(info.color_type, png::ColorType::Grayscale);
        assert_eq!((info.width, info.height), (5, 3));
        assert_eq!(&buf[..15], g.as_slice().expect("standard layout"));

        let rgba = Array2::from_shape_fn((2, 3), |(r, c)| [r as u8, c as u8, 9, 200]);
        let bytes = encode_rgba_png(&rgba).expect("encodes");
        let mut d = png::Decoder::new(Cursor::new(&bytes[..]))
            .read_info()
            .expect("info");
        let mut buf = vec![0; d.output_buffer_size().expect("size")];
        let info = d.next_frame(&mut buf).expect("frame");
        assert_eq!(info.color_type, png::ColorType::Rgba);
        let expected: Vec<u8> = rgba.iter().flatten().copied().collect();
        assert_eq!(&buf[..expected.len()], &expected[..]);
    }

    #[test]
    fn exr_round_trips_float_channels_exactly() {
        let a = Array2::from_shape_fn((17, 33), |(r, c)| r as f32 * 0.1 - c as f32 * 1e3);
        let mut b = Array2::from_elem((17, 33), 1.5f32);
        b[[3, 4]] = f32::NAN;
        let bytes = encode_float_exr(&[("elevation", &a), ("drainage", &b)]).expect("encodes");
        let back = decode_float_exr(&bytes).expect("decodes");
        let names: Vec<&str> = back.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, vec!["drainage", "elevation"]);
        assert_eq!(back[1].1, a);
        assert!(back[0].1[[3, 4]].is_nan());
        assert_eq!(back[0].1[[0, 0]], 1.5);

        assert!(encode_float_exr(&[]).is_err());
        assert!(encode_float_exr(&[("a", &a), ("a", &a)]).is_err());
        assert!(encode_float_exr(&[("", &a)]).is_err());
        assert!(encode_float_exr(&[("é", &a)]).is_err());
        assert!(encode_float_exr(&[("a", &a), ("b", &Array2::zeros((2, 2)))]).is_err());
        assert!(decode_float_exr(b"nope").is_err());
    }

    proptest! {
        #[test]
        fn terrarium_round_trip_within_half_a_step(h in -11_000.0f32..9_000.0) {
            let arr = Array2::from_elem((1, 1), h);
            let back = decode_terrarium_png(&encode_terrarium_png(&arr).unwrap()).unwrap();
            let err = (f64::from(back[[0, 0]]) - f64::from(h)).abs();
            // Rounding to 1/16 m, plus the f32 representation of the decoded height.
            prop_assert!(err <= 1.0 / 32.0 + 1e-3, "h {} back {} err {}", h, back[[0, 0]], err);
            // The blue channel only takes multiples of 256/16.
            let b = pixels(&encode_terrarium_png(&arr).unwrap())[0][2];
            prop_assert_eq!(b % 16, 0);
        }

        #[test]
        fn mapbox_round_trip_within_5cm(h in -10_000.0f32..9_000.0) {
            let arr = Array2::from_elem((1, 1), h);
            let back = decode_mapbox_png(&encode_mapbox_png(&arr).unwrap()).unwrap();
            let err = (f64::from(back[[0, 0]]) - f64::from(h)).abs();
            // Rounding to 0.1 m, plus the f32 representation of the decoded height.
            prop_assert!(err <= 0.05 + 1e-3, "h {} back {} err {}", h, back[[0, 0]], err);
        }
    }

    /// The gzip member's fixed header (RFC 1952 §2.3: magic, deflate, no flags, modification
    /// time 0, OS 255) and its trailer (CRC-32 and length of the input, little-endian), read byte
    /// by byte.
    #[test]
    fn gzip_writes_a_fixed_header_and_the_inputs_crc_and_length() {
        let input = b"layer trees, layer grass, layer rocks; ".repeat(40);
        let z = gzip(&input).expect("gzip");
        assert_eq!(&z[..10], &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 255][..]);
        let n = z.len();
        let crc = u32::from_le_bytes(z[n - 8..n - 4].try_into().expect("4 bytes"));
        let len = u32::from_le_bytes(z[n - 4..].try_into().expect("4 bytes"));
        assert_eq!(crc, crc32fast::hash(&input));
        assert_eq!(len as usize, input.len());
        assert!(n < input.len() / 4, "{n} bytes from {}", input.len());
    }

    #[test]
    fn gunzip_refuses_what_is_not_a_whole_gzip_stream() {
        let z = gzip(b"some tile bytes, some tile bytes").expect("gzip");
        assert!(gunzip(&z[..z.len() - 3]).is_err(), "truncated");
        assert!(gunzip(b"\x89PNG\r\n\x1a\n").is_err(), "not gzip");
        let mut flipped = z.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 1;
        assert!(gunzip(&flipped).is_err(), "wrong length in the trailer");
    }

    proptest! {
        #[test]
        fn gzip_round_trips_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..5000)) {
            prop_assert_eq!(gunzip(&gzip(&bytes).expect("gzip")).expect("gunzip"), bytes);
        }
    }
}
