//! The `.sct` file format of compact terrains (versioned, checksummed):
//!
//! ```text
//! magic    8 bytes   "TSSCT\0\0\x01" (the last byte is the format version)
//! header   u32 LE length, then JSON: rows, cols, patch, sparsity, coef_quantum, atoms,
//!                   georef, dictionary (the content id of the dictionary the atoms came from,
//!                   or a description of the analytic atoms)
//! payload  u64 LE length, then deflate of:
//!            atom scales  atoms × f32 LE
//!            atoms        atoms × patch² × i16 LE
//!            heights      primitives × i32 LE, each the difference to the previous one
//!            codes        per primitive: u8 count, then count × (u16 LE atom, i32 LE coefficient)
//! checksum 32 bytes  SHA-256 of everything before
//! ```
//!
//! The reader checks the magic, the version, every length and the checksum before it parses
//! anything, bounds the grid by [`ReadLimits`] before allocating, inflates at most the size the
//! header implies, and checks every atom index and code length: any truncation or changed byte
//! is an error, never a panic.

use std::io::{Read, Write};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use thiserror::Error;

use super::compact::{lattice_size, CompactTerrain};
use crate::raster::{Georef, ReadLimits};

/// The magic bytes, version included.
pub const MAGIC: &[u8; 8] = b"TSSCT\0\0\x01";

/// An unreadable `.sct` file.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum CompactFormatError {
    /// Not a compact terrain, or another version.
    #[error("not a terrasynth compact terrain (version 1)")]
    Magic,
    /// Shorter than its lengths say, or longer.
    #[error("truncated or padded compact terrain: {0}")]
    Length(String),
    /// The checksum does not match.
    #[error("compact terrain checksum mismatch: the file is corrupted")]
    Checksum,
    /// The content is inconsistent.
    #[error("malformed compact terrain: {0}")]
    Malformed(String),
    /// The grid exceeds the read limits.
    #[error("compact terrain of {rows}×{cols} exceeds the limit of {max} pixels")]
    TooLarge {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
        /// Pixel limit.
        max: u64,
    },
}

/// The JSON header.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// Rows of the decoded grid.
    pub rows: usize,
    /// Columns of the decoded grid.
    pub cols: usize,
    /// Atom side.
    pub patch: usize,
    /// Largest atoms per primitive.
    pub sparsity: usize,
    /// Coefficient quantum.
    pub coef_quantum: f32,
    /// Atoms stored.
    pub atoms: usize,
    /// Georeference of the decoded grid.
    pub georef: Georef,
    /// Where the atoms came from.
    pub dictionary: String,
}

/// Sizes of a written file, bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sizes {
    /// The whole file.
    pub total: usize,
    /// The stored atoms, deflated on their own (what the file would not need with a shared
    /// dictionary).
    pub atoms: usize,
}

fn deflate(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    // Writing into a Vec cannot fail.
    let _ = enc.write_all(bytes);
    enc.finish().unwrap_or_default()
}

fn atom_bytes(t: &CompactTerrain) -> Vec<u8> {
    let mut out = Vec::with_capacity(t.atom_scales.len() * 4 + t.atoms.len() * 2);
    for s in &t.atom_scales {
        out.extend_from_slice(&s.to_le_bytes());
    }
    for a in &t.atoms {
        out.extend_from_slice(&a.to_le_bytes());
    }
    out
}

/// Serialises `t` (with `georef` and the atoms' origin `dictionary`); the bytes and their sizes.
pub fn to_bytes(
    t: &CompactTerrain,
    georef: Georef,
    dictionary: &str,
) -> Result<(Vec<u8>, Sizes), CompactFormatError> {
    let header = Header {
        rows: t.rows,
        cols: t.cols,
        patch: t.patch,
        sparsity: t.sparsity,
        coef_quantum: t.coef_quantum,
        atoms: t.atom_scales.len(),
        georef,
        dictionary: dictionary.to_string(),
    };
    let json =
        serde_json::to_vec(&header).map_err(|e| CompactFormatError::Malformed(e.to_string()))?;
    let mut payload = atom_bytes(t);
    let mut prev = 0i32;
    for &z in &t.heights {
        payload.extend_from_slice(&z.wrapping_sub(prev).to_le_bytes());
        prev = z;
    }
    for code in &t.codes {
        let n = u8::try_from(code.len())
            .map_err(|_| CompactFormatError::Malformed("more than 255 atoms".into()))?;
        payload.push(n);
        for &(a, q) in code {
            payload.extend_from_slice(&a.to_le_bytes());
            payload.extend_from_slice(&q.to_le_bytes());
        }
    }
    let packed = deflate(&payload);
    let mut out = Vec::with_capacity(packed.len() + json.len() + 64);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(packed.len() as u64).to_le_bytes());
    out.extend_from_slice(&packed);
    let sum = Sha256::digest(&out);
    out.extend_from_slice(&sum);
    let sizes = Sizes {
        total: out.len(),
        atoms: deflate(&atom_bytes(t)).len(),
    };
    Ok((out, sizes))
}

/// A little-endian reader over a byte slice that reports running out as malformed.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CompactFormatError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| CompactFormatError::Malformed("payload too short".into()))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], CompactFormatError> {
        let s = self.take(N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
}

/// Parses a `.sct` file; the terrain, its header.
pub fn from_bytes(
    bytes: &[u8],
    limits: &ReadLimits,
) -> Result<(CompactTerrain, Header), CompactFormatError> {
    let len_err = |m: &str| CompactFormatError::Length(m.to_string());
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(CompactFormatError::Magic);
    }
    if bytes.len() < MAGIC.len() + 4 + 8 + 32 {
        return Err(len_err("shorter than the fixed fields"));
    }
    let body_len = bytes.len() - 32;
    let mut c = Cursor {
        bytes: &bytes[..body_len],
        at: MAGIC.len(),
    };
    let hlen = u32::from_le_bytes(c.array().map_err(|_| len_err("header length"))?) as usize;
    let json = c.take(hlen).map_err(|_| len_err("header"))?;
    let plen = u64::from_le_bytes(c.array().map_err(|_| len_err("payload length"))?);
    let plen = usize::try_from(plen).map_err(|_| len_err("payload length"))?;
    if c.at.checked_add(plen) != Some(body_len) {
        return Err(len_err("payload length disagrees with the file size"));
    }
    if Sha256::digest(&bytes[..body_len]).as_slice() != &bytes[body_len..] {
        return Err(CompactFormatError::Checksum);
    }
    let header: Header = serde_json::from_slice(json)
        .map_err(|e| CompactFormatError::Malformed(format!("header: {e}")))?;
    let malformed = |m: String| CompactFormatError::Malformed(m);
    let pixels = (header.rows as u64).saturating_mul(header.cols as u64);
    if header.rows == 0 || header.cols == 0 || pixels > limits.max_pixels {
        return Err(CompactFormatError::TooLarge {
            rows: header.rows,
            cols: header.cols,
            max: limits.max_pixels,
        });
    }
    if header.patch < 4 || header.patch > 256 || header.patch % 2 != 0 {
        return Err(malformed(format!("patch {}", header.patch)));
    }
    if header.sparsity == 0 || header.sparsity > 255 || header.atoms > usize::from(u16::MAX) + 1 {
        return Err(malformed("sparsity or atom count out of range".into()));
    }
    if !(header.coef_quantum.is_finite() && header.coef_quantum > 0.0) {
        return Err(malformed("coefficient quantum".into()));
    }
    let p2 = header.patch * header.patch;
    let (ni, nj) = lattice_size(header.rows, header.cols, header.patch / 2);
    let prims = ni * nj;
    // The largest payload the header allows.
    let max_payload = header.atoms * (4 + 2 * p2) + prims * (4 + 1 + header.sparsity * 6);
    let packed = c.take(plen).map_err(|_| len_err("payload"))?;
    let mut payload = Vec::new();
    flate2::read::DeflateDecoder::new(packed)
        .take(max_payload as u64 + 1)
        .read_to_end(&mut payload)
        .map_err(|e| malformed(format!("payload: {e}")))?;
    if payload.len() > max_payload {
        return Err(malformed("payload larger than the header allows".into()));
    }
    // The fixed-size parts must be there before anything is allocated for them.
    let fixed = header.atoms * (4 + 2 * p2) + prims * 5;
    if payload.len() < fixed {
        return Err(malformed("payload shorter than the header implies".into()));
    }
    let mut p = Cursor {
        bytes: &payload,
        at: 0,
    };
    let mut atom_scales = Vec::with_capacity(header.atoms);
    for _ in 0..header.atoms {
        let s = f32::from_le_bytes(p.array()?);
        if !(s.is_finite() && s > 0.0) {
            return Err(malformed("atom scale".into()));
        }
        atom_scales.push(s);
    }
    let mut atoms = Vec::with_capacity(header.atoms * p2);
    for _ in 0..header.atoms * p2 {
        atoms.push(i16::from_le_bytes(p.array()?));
    }
    let mut heights = Vec::with_capacity(prims);
    let mut prev = 0i32;
    for _ in 0..prims {
        prev = prev.wrapping_add(i32::from_le_bytes(p.array()?));
        heights.push(prev);
    }
    let mut codes = Vec::with_capacity(prims);
    for _ in 0..prims {
        let n = usize::from(p.array::<1>()?[0]);
        if n > header.sparsity {
            return Err(malformed(format!(
                "a code of {n} atoms (sparsity {})",
                header.sparsity
            )));
        }
        let mut code = Vec::with_capacity(n);
        for _ in 0..n {
            let a = u16::from_le_bytes(p.array()?);
            if usize::from(a) >= header.atoms {
                return Err(malformed(format!("atom {a} of {}", header.atoms)));
            }
            code.push((a, i32::from_le_bytes(p.array()?)));
        }
        codes.push(code);
    }
    if p.at != payload.len() {
        return Err(malformed("trailing payload bytes".into()));
    }
    let t = CompactTerrain {
        rows: header.rows,
        cols: header.cols,
        patch: header.patch,
        sparsity: header.sparsity,
        coef_quantum: header.coef_quantum,
        heights,
        codes,
        atoms,
        atom_scales,
    };
    Ok((t, header))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::analytic::{analytic_atoms, AnalyticKind};
    use crate::math;
    use crate::synth::compact::compress;
    use ndarray::Array2;

    fn sample() -> (CompactTerrain, Vec<u8>) {
        let grid = Array2::from_shape_fn((30, 26), |(r, c)| {
            200.0 + 40.0 * math::sinf((r as f32) * 0.3) + 25.0 * math::cosf((c as f32) * 0.23)
        });
        let atoms = analytic_atoms(AnalyticKind::Ridged, 8, 20, 2);
        let t = compress(&grid, &atoms, 8, 2, 0.05, 1);
        let (bytes, sizes) = to_bytes(&t, Georef::local_metric(30.0), "analytic:ridged").unwrap();
        assert_eq!(sizes.total, bytes.len());
        (t, bytes)
    }

    #[test]
    fn round_trips_exactly() {
        let (t, bytes) = sample();
        let (back, header) = from_bytes(&bytes, &ReadLimits::default()).unwrap();
        assert_eq!(back, t);
        assert_eq!(header.dictionary, "analytic:ridged");
        assert_eq!(header.georef, Georef::local_metric(30.0));
        assert_eq!(back.decode(), t.decode());
    }

    #[test]
    fn every_truncation_and_byte_flip_is_refused() {
        let (_, bytes) = sample();
        let limits = ReadLimits::default();
        for len in 0..bytes.len() {
            assert!(
                from_bytes(&bytes[..len], &limits).is_err(),
                "truncated to {len}"
            );
        }
        for i in 0..bytes.len() {
            for bit in [0x01u8, 0x80] {
                let mut b = bytes.clone();
                b[i] ^= bit;
                assert!(from_bytes(&b, &limits).is_err(), "flip at {i}");
            }
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(from_bytes(&longer, &limits).is_err());
    }

    #[test]
    fn limits_are_checked_before_allocating() {
        let (_, bytes) = sample();
        let tiny = ReadLimits {
            max_pixels: 100,
            max_layers: 1,
        };
        assert!(matches!(
            from_bytes(&bytes, &tiny),
            Err(CompactFormatError::TooLarge { .. })
        ));
    }
}
