//! The canonical bytes of a stored exemplar: a named multi-layer raster.
//!
//! Payload (inside the object envelope): JSON header length `u32` LE, the JSON header
//! ([`ExemplarHeader`]: name, width, height, georeference, layer names, statistics), then every
//! layer as row-major `f32` LE in header order. Invalid cells hold NaN in every layer, so the
//! validity mask needs no extra bytes. Decoding checks every length before allocating.

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use super::StoreError;
use terrasynth_core::raster::{Georef, LayeredRaster, ELEVATION};

/// Largest accepted JSON header, bytes.
const MAX_HEADER: usize = 1 << 20;

/// Bytes at the start of a payload that always hold its header (its length and JSON).
pub const MAX_HEAD: usize = 4 + MAX_HEADER;

/// Statistics of an exemplar's elevation over its valid cells.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExemplarStats {
    /// Lowest elevation, metres.
    pub min: f32,
    /// Highest elevation, metres.
    pub max: f32,
    /// Mean elevation, metres.
    pub mean: f32,
    /// Number of valid cells.
    pub valid_cells: u64,
}

/// The JSON header of a stored exemplar.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExemplarHeader {
    /// Human name given at upload.
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Georeference.
    pub georef: Georef,
    /// Layer names, elevation first.
    pub layers: Vec<String>,
    /// Elevation statistics.
    pub stats: ExemplarStats,
}

fn bad(reason: impl Into<String>) -> StoreError {
    StoreError::BadObject {
        id: "-".into(),
        reason: reason.into(),
    }
}

/// Elevation statistics of `r` over valid cells (finite, and not masked out); `None` when no
/// cell is valid.
pub fn stats(r: &LayeredRaster) -> Option<ExemplarStats> {
    let elev = r.layer(ELEVATION)?;
    let (mut lo, mut hi, mut sum, mut n) = (f32::INFINITY, f32::NEG_INFINITY, 0f64, 0u64);
    for ((row, col), &v) in elev.indexed_iter() {
        let masked = r.valid.as_ref().is_some_and(|m| !m[[row, col]]);
        if v.is_finite() && !masked {
            lo = lo.min(v);
            hi = hi.max(v);
            sum += f64::from(v);
            n += 1;
        }
    }
    (n > 0).then(|| ExemplarStats {
        min: lo,
        max: hi,
        mean: (sum / n as f64) as f32,
        valid_cells: n,
    })
}

/// The canonical payload of exemplar `name`, ready to be written: its header, the header's
/// JSON, and the payload's length.
pub struct Encoder<'a> {
    raster: &'a LayeredRaster,
    /// The header.
    pub header: ExemplarHeader,
    json: Vec<u8>,
}

impl<'a> Encoder<'a> {
    /// The encoder of exemplar `name` (elevation must be the first layer and some cell valid).
    pub fn new(name: &str, r: &'a LayeredRaster) -> Result<Self, StoreError> {
        let (height, width) = r.dim();
        if r.layers.first().map(|(n, _)| n.as_str()) != Some(ELEVATION) {
            return Err(bad("the first layer must be elevation"));
        }
        let stats = stats(r).ok_or_else(|| bad("no valid elevation"))?;
        let header = ExemplarHeader {
            name: name.to_string(),
            width,
            height,
            georef: r.georef,
            layers: r.layers.iter().map(|(n, _)| n.clone()).collect(),
            stats,
        };
        let json = serde_json::to_vec(&header).map_err(|e| bad(e.to_string()))?;
        if json.len() > MAX_HEADER {
            return Err(bad("exemplar header too large"));
        }
        Ok(Encoder {
            raster: r,
            header,
            json,
        })
    }

    /// Bytes of the payload.
    pub fn len(&self) -> u64 {
        let (h, w) = self.raster.dim();
        4 + self.json.len() as u64 + (self.raster.layers.len() as u64) * (h as u64) * (w as u64) * 4
    }

    /// Whether the payload is empty (never: it holds at least its header).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Writes the payload to `out`, a row at a time.
    pub fn write(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let r = self.raster;
        out.write_all(&(self.json.len() as u32).to_le_bytes())?;
        out.write_all(&self.json)?;
        // A cell is valid when its elevation is finite and not masked out; invalid cells are NaN
        // in every layer.
        let elevation = &r.layers[0].1;
        let cell_valid = |row: usize, col: usize| {
            elevation[[row, col]].is_finite() && r.valid.as_ref().is_none_or(|m| m[[row, col]])
        };
        let mut line = Vec::with_capacity(r.dim().1 * 4);
        for (_, a) in &r.layers {
            for (row, values) in a.outer_iter().enumerate() {
                line.clear();
                for (col, &v) in values.iter().enumerate() {
                    let v = if cell_valid(row, col) { v } else { f32::NAN };
                    // One canonical NaN, so equal rasters give equal bytes.
                    let v = if v.is_nan() { f32::NAN } else { v };
                    line.extend_from_slice(&v.to_le_bytes());
                }
                out.write_all(&line)?;
            }
        }
        Ok(())
    }
}

/// The canonical payload of exemplar `name` in memory (elevation must be the first layer and
/// some cell valid); the store streams it with [`Encoder::write`] instead.
pub fn encode(name: &str, r: &LayeredRaster) -> Result<(ExemplarHeader, Vec<u8>), StoreError> {
    let e = Encoder::new(name, r)?;
    let mut out = Vec::with_capacity(usize::try_from(e.len()).unwrap_or(0));
    e.write(&mut out).map_err(|e| bad(e.to_string()))?;
    Ok((e.header, out))
}

/// The header of a payload (without decoding the layers).
pub fn decode_header(payload: &[u8]) -> Result<ExemplarHeader, StoreError> {
    let len = payload
        .get(..4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .ok_or_else(|| bad("truncated exemplar"))?;
    if len > MAX_HEADER {
        return Err(bad("exemplar header too large"));
    }
    let json = payload
        .get(4..4 + len)
        .ok_or_else(|| bad("truncated exemplar header"))?;
    serde_json::from_slice(json).map_err(|e| bad(format!("exemplar header: {e}")))
}

/// Decodes a payload into its header and raster.
pub fn decode(payload: &[u8]) -> Result<(ExemplarHeader, LayeredRaster), StoreError> {
    let header = decode_header(payload)?;
    // decode_header checked that the 4-byte length and the JSON are present.
    let json_len = u32::from_le_bytes([payload[0], payload[1], payload[2], payload[3]]) as usize;
    let start = 4 + json_len;
    let cells = header
        .width
        .checked_mul(header.height)
        .filter(|&c| c > 0)
        .ok_or_else(|| bad("empty or overflowing exemplar size"))?;
    let need = cells
        .checked_mul(4)
        .and_then(|b| b.checked_mul(header.layers.len()))
        .ok_or_else(|| bad("exemplar size overflows"))?;
    if payload.len() - start != need {
        return Err(bad("exemplar data length disagrees with its header"));
    }
    if header.layers.first().map(String::as_str) != Some(ELEVATION) {
        return Err(bad("exemplar without an elevation layer"));
    }
    let mut layers = Vec::with_capacity(header.layers.len());
    let mut valid = Array2::from_elem((header.height, header.width), true);
    for (i, name) in header.layers.iter().enumerate() {
        let bytes = &payload[start + i * cells * 4..start + (i + 1) * cells * 4];
        let values: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let a = Array2::from_shape_vec((header.height, header.width), values)
            .map_err(|e| bad(e.to_string()))?;
        if i == 0 {
            valid = a.mapv(|v| !v.is_nan());
        }
        layers.push((name.clone(), a));
    }
    let all_valid = valid.iter().all(|&v| v);
    Ok((
        header.clone(),
        LayeredRaster {
            georef: header.georef,
            layers,
            valid: (!all_valid).then_some(valid),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasynth_core::raster::{Georef, Grid};

    #[test]
    fn round_trip_keeps_values_mask_and_layers() {
        let mut data = Array2::from_shape_fn((3, 4), |(r, c)| (r * 10 + c) as f32);
        data[[1, 1]] = f32::NAN;
        let mut r = LayeredRaster::from_elevation(Grid::new(data, Georef::local_metric(30.0)));
        r.push_layer("forest", Array2::from_elem((3, 4), 0.5))
            .unwrap();
        let (h, bytes) = encode("crop", &r).unwrap();
        assert_eq!((h.width, h.height), (4, 3));
        assert_eq!(h.stats.valid_cells, 11);
        assert_eq!(h.stats.max, 23.0);
        let (h2, r2) = decode(&bytes).unwrap();
        assert_eq!(h, h2);
        assert_eq!(r2.layers.len(), 2);
        assert!(r2.valid.as_ref().is_some_and(|m| !m[[1, 1]] && m[[0, 0]]));
        assert_eq!(r2.layer("forest").unwrap()[[2, 3]], 0.5);
        assert_eq!(encode("crop", &r2).unwrap().1, bytes);
        for n in 0..bytes.len() {
            assert!(decode(&bytes[..n]).is_err() || n == bytes.len());
        }
    }
}
