//! The versioned, checksummed binary format of gradient tile sets, with the conventions of the
//! dictionary format ([`super::format`]: the same hashing writer and reader, prefix and trailing
//! SHA-256).
//!
//! Layout (all integers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `TSGRAD\0\x01` |
//! | 4 | format version, `u32` (= 1) |
//! | 8 | header length `h`, `u64` |
//! | `h` | JSON header: `params`, `lengths` (value count of `tiles` and `found`) |
//! | 4·n | `tiles` as `f32` |
//! | 4·m | `found` as `u32` |
//! | 32 | SHA-256 of every preceding byte |
//!
//! Reading validates the magic, the version, the parameters, that the claimed lengths agree with
//! them and fit in `max_bytes` (before allocating), the checksum and
//! [`GradientTileSet::check_consistency`]. The bytes are canonical: [`content_id`] is the hex of
//! the checksum. [`is_gradient`] tells a tile set's bytes from a dictionary's by the magic.

use std::io::{Read, Write};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::error::DictionaryError;
use super::format::{put_f32s, HashReader, HashWriter, Sink};
use super::gradient_tiles::{GradientParams, GradientTileSet};

/// The 8 magic bytes every gradient tile set file starts with.
pub const MAGIC: [u8; 8] = *b"TSGRAD\0\x01";
/// The format version written by this build (the only one it reads).
pub const VERSION: u32 = 1;
/// Largest JSON header accepted, bytes.
const MAX_HEADER: u64 = 1 << 16;
/// Bytes of the fixed prefix and of the trailing checksum.
const FRAME: u64 = 8 + 4 + 8 + 32;

/// Value counts of the arrays.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Lengths {
    tiles: u64,
    found: u64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    params: GradientParams,
    lengths: Lengths,
}

/// Whether `bytes` start with the gradient tile set magic.
pub fn is_gradient(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}

fn write_body<W: Write>(set: &GradientTileSet, w: W) -> Result<HashWriter<W>, DictionaryError> {
    set.check_consistency()
        .map_err(|e| DictionaryError::Malformed(format!("refusing to write: {e}")))?;
    let header = Header {
        params: set.params.clone(),
        lengths: Lengths {
            tiles: set.tiles.len() as u64,
            found: set.found.len() as u64,
        },
    };
    let json = serde_json::to_vec(&header)
        .map_err(|e| DictionaryError::Malformed(format!("header serialisation: {e}")))?;
    let mut hw = HashWriter {
        inner: w,
        hasher: Sha256::new(),
    };
    hw.put(&MAGIC)?;
    hw.put(&VERSION.to_le_bytes())?;
    hw.put(&(json.len() as u64).to_le_bytes())?;
    hw.put(&json)?;
    put_f32s(&mut hw, &set.tiles)?;
    let found: Vec<u8> = set.found.iter().flat_map(|v| v.to_le_bytes()).collect();
    hw.put(&found)?;
    Ok(hw)
}

/// Writes `set` in the binary format.
pub fn write_gradient_tiles<W: Write>(set: &GradientTileSet, w: W) -> Result<(), DictionaryError> {
    write_body(set, w)?.finish()?;
    Ok(())
}

/// The canonical bytes of `set`.
pub fn to_bytes(set: &GradientTileSet) -> Result<Vec<u8>, DictionaryError> {
    let mut out = Vec::new();
    write_gradient_tiles(set, &mut out)?;
    Ok(out)
}

/// Content identifier of `set`: the hex SHA-256 ending its file.
pub fn content_id(set: &GradientTileSet) -> Result<String, DictionaryError> {
    Ok(write_body(set, Sink)?.content_id())
}

/// Reads a gradient tile set, refusing files larger than `max_bytes` (checked against the
/// header's claims before reading the arrays).
pub fn read_gradient_tiles<R: Read>(
    r: R,
    max_bytes: u64,
) -> Result<GradientTileSet, DictionaryError> {
    let mut hr = HashReader {
        inner: r,
        hasher: Sha256::new(),
    };
    let mut magic = [0u8; 8];
    hr.take(&mut magic)?;
    if magic != MAGIC {
        return Err(DictionaryError::BadMagic);
    }
    let mut b4 = [0u8; 4];
    hr.take(&mut b4)?;
    let version = u32::from_le_bytes(b4);
    if version != VERSION {
        return Err(DictionaryError::UnsupportedVersion { found: version });
    }
    let mut b8 = [0u8; 8];
    hr.take(&mut b8)?;
    let header_len = u64::from_le_bytes(b8);
    if header_len > MAX_HEADER || FRAME + header_len > max_bytes {
        return Err(DictionaryError::Malformed(format!(
            "header length {header_len} exceeds the limits"
        )));
    }
    let mut json = vec![0u8; header_len as usize];
    hr.take(&mut json)?;
    let header: Header = serde_json::from_slice(&json)
        .map_err(|e| DictionaryError::Malformed(format!("bad header: {e}")))?;
    header
        .params
        .validate()
        .map_err(|e| DictionaryError::Malformed(e.to_string()))?;
    let want = Lengths {
        tiles: header.params.value_count().unwrap_or(usize::MAX) as u64,
        found: 2 * header.params.combinations() as u64,
    };
    if want != header.lengths {
        return Err(DictionaryError::Malformed(format!(
            "array lengths {:?} disagree with the parameters (expected {want:?})",
            header.lengths
        )));
    }
    let total = (want.tiles + want.found)
        .checked_mul(4)
        .and_then(|b| b.checked_add(FRAME + header_len))
        .ok_or_else(|| DictionaryError::Malformed("file size overflows".into()))?;
    if total > max_bytes {
        return Err(DictionaryError::Malformed(format!(
            "a tile set of {total} bytes exceeds the limit of {max_bytes} bytes"
        )));
    }
    let tiles = hr.f32s(want.tiles)?;
    let found = hr.f32s(want.found)?.into_iter().map(f32::to_bits).collect();
    let mut stored = [0u8; 32];
    hr.read_raw(&mut stored)?;
    if hr.hasher.finalize().as_slice() != stored {
        return Err(DictionaryError::ChecksumMismatch);
    }
    let set = GradientTileSet {
        params: header.params,
        tiles,
        found,
    };
    set.check_consistency()
        .map_err(DictionaryError::Malformed)?;
    Ok(set)
}

/// Reads a gradient tile set from a complete byte buffer; trailing bytes are an error.
pub fn from_bytes(bytes: &[u8]) -> Result<GradientTileSet, DictionaryError> {
    let mut cursor = bytes;
    let set = read_gradient_tiles(&mut cursor, bytes.len() as u64)?;
    if !cursor.is_empty() {
        return Err(DictionaryError::Malformed(format!(
            "{} trailing bytes after the checksum",
            cursor.len()
        )));
    }
    Ok(set)
}
