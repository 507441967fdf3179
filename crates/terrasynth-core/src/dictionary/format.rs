//! The versioned, checksummed binary dictionary format.
//!
//! Layout (all integers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `TSDICT\0\x01` |
//! | 4 | format version, `u32` (= 1) |
//! | 8 | header length `h`, `u64` |
//! | `h` | JSON header: `params`, `layers`, `n_atoms`, `lengths` (value count of every array) |
//! | … | `lo_elev`, `hi_elev`, `mean_alt`, `mean_slope`, `relief`, `lo_layers`, `hi_layers` as `f32` |
//! | 12·n | `sources` as `u32` triples `(exemplar, row, col)` |
//! | 32 | SHA-256 of every preceding byte |
//!
//! Reading validates the magic, the version, the header, that the claimed lengths agree with the
//! counts and fit in `max_bytes` (before allocating anything), the checksum, and
//! [`Dictionary::check_consistency`]. Any corruption or truncation is an error, never a panic.
//! The bytes of a dictionary are canonical: [`content_id`] is the hex SHA-256 of them.

use std::io::{self, Read, Write};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::atoms::{AtomSource, Dictionary, DictionaryParams, LayerInfo};
use super::error::DictionaryError;

/// The 8 magic bytes every dictionary file starts with.
pub const MAGIC: [u8; 8] = *b"TSDICT\0\x01";
/// The format version written by this build (the only one it reads).
pub const VERSION: u32 = 1;
/// Largest JSON header accepted, bytes.
const MAX_HEADER: u64 = 1 << 20;
/// Bytes of the fixed prefix (magic, version, header length).
const PREFIX: u64 = 8 + 4 + 8;
/// Bytes of the trailing checksum.
const CHECKSUM: u64 = 32;

/// Value counts of every array.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Lengths {
    lo_elev: u64,
    hi_elev: u64,
    mean_alt: u64,
    mean_slope: u64,
    relief: u64,
    lo_layers: u64,
    hi_layers: u64,
    sources: u64,
}

impl Lengths {
    fn of(d: &Dictionary) -> Self {
        Self {
            lo_elev: d.lo_elev.len() as u64,
            hi_elev: d.hi_elev.len() as u64,
            mean_alt: d.mean_alt.len() as u64,
            mean_slope: d.mean_slope.len() as u64,
            relief: d.relief.len() as u64,
            lo_layers: d.lo_layers.len() as u64,
            hi_layers: d.hi_layers.len() as u64,
            sources: d.sources.len() as u64,
        }
    }

    /// The lengths implied by the counts, or `None` on overflow.
    fn expected(params: &DictionaryParams, n_layers: u64, n: u64) -> Option<Self> {
        let p = params.patch as u64;
        let lo = p / 2;
        let p2 = p.checked_mul(p)?;
        let lo2 = lo.checked_mul(lo)?;
        Some(Self {
            lo_elev: n.checked_mul(lo2)?,
            hi_elev: n.checked_mul(p2)?,
            mean_alt: n,
            mean_slope: n,
            relief: n,
            lo_layers: n.checked_mul(n_layers)?.checked_mul(lo2)?,
            hi_layers: n.checked_mul(n_layers)?.checked_mul(p2)?,
            sources: n,
        })
    }

    /// Bytes of the array section, or `None` on overflow.
    fn data_bytes(&self) -> Option<u64> {
        let floats = [
            self.lo_elev,
            self.hi_elev,
            self.mean_alt,
            self.mean_slope,
            self.relief,
            self.lo_layers,
            self.hi_layers,
        ]
        .iter()
        .try_fold(0u64, |acc, &x| acc.checked_add(x))?;
        floats
            .checked_mul(4)?
            .checked_add(self.sources.checked_mul(12)?)
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    params: DictionaryParams,
    layers: Vec<LayerInfo>,
    n_atoms: u64,
    lengths: Lengths,
}

/// A writer that hashes everything written through it.
pub(super) struct HashWriter<W> {
    pub(super) inner: W,
    pub(super) hasher: Sha256,
}

impl<W: Write> HashWriter<W> {
    pub(super) fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.hasher.update(bytes);
        self.inner.write_all(bytes)
    }

    /// Ends the file: appends the SHA-256 of everything put so far and flushes.
    pub(super) fn finish(mut self) -> io::Result<()> {
        let digest = self.hasher.finalize();
        self.inner.write_all(digest.as_slice())?;
        self.inner.flush()
    }

    /// The content identifier of what was put: the hex of the digest [`finish`](Self::finish)
    /// would append.
    pub(super) fn content_id(self) -> String {
        hex(self.hasher.finalize().as_slice())
    }
}

/// A sink that discards bytes (used to hash without buffering).
pub(super) struct Sink;

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

const CHUNK_BYTES: usize = 1 << 16;

pub(super) fn put_f32s<W: Write>(w: &mut HashWriter<W>, values: &[f32]) -> io::Result<()> {
    let mut buf = Vec::with_capacity(CHUNK_BYTES);
    for chunk in values.chunks(CHUNK_BYTES / 4) {
        buf.clear();
        for v in chunk {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        w.put(&buf)?;
    }
    Ok(())
}

/// Writes everything but the checksum; returns the hasher state.
fn write_body<W: Write>(d: &Dictionary, w: W) -> Result<HashWriter<W>, DictionaryError> {
    d.check_consistency()
        .map_err(|e| DictionaryError::Malformed(format!("refusing to write: {e}")))?;
    let header = Header {
        params: d.params.clone(),
        layers: d.layers.clone(),
        n_atoms: d.n_atoms as u64,
        lengths: Lengths::of(d),
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
    for arr in [
        &d.lo_elev,
        &d.hi_elev,
        &d.mean_alt,
        &d.mean_slope,
        &d.relief,
        &d.lo_layers,
        &d.hi_layers,
    ] {
        put_f32s(&mut hw, arr)?;
    }
    let mut buf = Vec::with_capacity(CHUNK_BYTES);
    for chunk in d.sources.chunks(CHUNK_BYTES / 12) {
        buf.clear();
        for s in chunk {
            buf.extend_from_slice(&s.exemplar.to_le_bytes());
            buf.extend_from_slice(&s.row.to_le_bytes());
            buf.extend_from_slice(&s.col.to_le_bytes());
        }
        hw.put(&buf)?;
    }
    Ok(hw)
}

/// Writes `d` in the binary format (the dictionary must pass `check_consistency`).
pub fn write_dictionary<W: Write>(d: &Dictionary, w: W) -> Result<(), DictionaryError> {
    write_body(d, w)?.finish()?;
    Ok(())
}

/// The canonical bytes of `d`.
pub fn to_bytes(d: &Dictionary) -> Result<Vec<u8>, DictionaryError> {
    let mut out = Vec::new();
    write_dictionary(d, &mut out)?;
    Ok(out)
}

/// Content identifier of `d`: the lowercase hex SHA-256 of its canonical bytes up to the
/// checksum — i.e. the hex of the 32-byte checksum that ends its file, so the identifier of a stored
/// file can be read from its last 32 bytes. Computed without materialising the bytes.
pub fn content_id(d: &Dictionary) -> Result<String, DictionaryError> {
    Ok(write_body(d, Sink)?.content_id())
}

/// Lowercase hexadecimal of `bytes`.
pub(super) fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = String::with_capacity(bytes.len() * 2);
    for &b in bytes {
        out.push(char::from(DIGITS[usize::from(b >> 4)]));
        out.push(char::from(DIGITS[usize::from(b & 15)]));
    }
    out
}

/// A reader that hashes and counts what it reads, mapping EOF to [`DictionaryError::Truncated`].
pub(super) struct HashReader<R> {
    pub(super) inner: R,
    pub(super) hasher: Sha256,
}

impl<R: Read> HashReader<R> {
    pub(super) fn read_raw(&mut self, buf: &mut [u8]) -> Result<(), DictionaryError> {
        self.inner.read_exact(buf).map_err(|e| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                DictionaryError::Truncated
            } else {
                DictionaryError::Io(e)
            }
        })
    }

    pub(super) fn take(&mut self, buf: &mut [u8]) -> Result<(), DictionaryError> {
        self.read_raw(buf)?;
        self.hasher.update(&*buf);
        Ok(())
    }

    /// Reads `count` little-endian `f32`s, growing the vector only as data arrives.
    pub(super) fn f32s(&mut self, count: u64) -> Result<Vec<f32>, DictionaryError> {
        let mut out = Vec::new();
        let mut buf = vec![0u8; CHUNK_BYTES];
        let mut left = count;
        while left > 0 {
            let n = left.min((CHUNK_BYTES / 4) as u64) as usize;
            let bytes = &mut buf[..n * 4];
            self.take(bytes)?;
            out.extend(
                bytes
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])),
            );
            left -= n as u64;
        }
        Ok(out)
    }

    fn u32_at(c: &[u8], i: usize) -> u32 {
        u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]])
    }

    fn sources(&mut self, count: u64) -> Result<Vec<AtomSource>, DictionaryError> {
        let mut out = Vec::new();
        let mut buf = vec![0u8; CHUNK_BYTES / 12 * 12];
        let mut left = count;
        while left > 0 {
            let n = left.min((CHUNK_BYTES / 12) as u64) as usize;
            let bytes = &mut buf[..n * 12];
            self.take(bytes)?;
            out.extend(bytes.chunks_exact(12).map(|c| AtomSource {
                exemplar: Self::u32_at(c, 0),
                row: Self::u32_at(c, 4),
                col: Self::u32_at(c, 8),
            }));
            left -= n as u64;
        }
        Ok(out)
    }
}

/// Reads a dictionary, refusing files larger than `max_bytes` (checked against the header's
/// claims before reading the arrays).
pub fn read_dictionary<R: Read>(r: R, max_bytes: u64) -> Result<Dictionary, DictionaryError> {
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
    let too_big = |what: String| {
        DictionaryError::Malformed(format!("{what} exceeds the limit of {max_bytes} bytes"))
    };
    if header_len > MAX_HEADER {
        return Err(DictionaryError::Malformed(format!(
            "header length {header_len} exceeds {MAX_HEADER}"
        )));
    }
    if PREFIX + header_len + CHECKSUM > max_bytes {
        return Err(too_big(format!("header of {header_len} bytes")));
    }
    let mut json = vec![0u8; header_len as usize];
    hr.take(&mut json)?;
    let header: Header = serde_json::from_slice(&json)
        .map_err(|e| DictionaryError::Malformed(format!("bad header: {e}")))?;
    let p = header.params.patch;
    if !(4..=1024).contains(&p) || p % 2 != 0 {
        return Err(DictionaryError::Malformed(format!("patch size {p}")));
    }
    let expected = Lengths::expected(&header.params, header.layers.len() as u64, header.n_atoms)
        .ok_or_else(|| DictionaryError::Malformed("array lengths overflow".into()))?;
    if expected != header.lengths {
        return Err(DictionaryError::Malformed(format!(
            "array lengths {:?} disagree with the counts (expected {expected:?})",
            header.lengths
        )));
    }
    let total = expected
        .data_bytes()
        .and_then(|b| b.checked_add(PREFIX + header_len + CHECKSUM))
        .ok_or_else(|| DictionaryError::Malformed("file size overflows".into()))?;
    if total > max_bytes {
        return Err(too_big(format!("a dictionary of {total} bytes")));
    }
    let n_atoms = usize::try_from(header.n_atoms)
        .map_err(|_| DictionaryError::Malformed("too many atoms".into()))?;
    let l = &header.lengths;
    let lo_elev = hr.f32s(l.lo_elev)?;
    let hi_elev = hr.f32s(l.hi_elev)?;
    let mean_alt = hr.f32s(l.mean_alt)?;
    let mean_slope = hr.f32s(l.mean_slope)?;
    let relief = hr.f32s(l.relief)?;
    let lo_layers = hr.f32s(l.lo_layers)?;
    let hi_layers = hr.f32s(l.hi_layers)?;
    let sources = hr.sources(l.sources)?;
    let mut stored = [0u8; 32];
    hr.read_raw(&mut stored)?;
    let digest = hr.hasher.finalize();
    if digest.as_slice() != stored {
        return Err(DictionaryError::ChecksumMismatch);
    }
    let d = Dictionary {
        params: header.params,
        layers: header.layers,
        n_atoms,
        lo_elev,
        hi_elev,
        mean_alt,
        mean_slope,
        relief,
        lo_layers,
        hi_layers,
        sources,
    };
    d.check_consistency().map_err(DictionaryError::Malformed)?;
    Ok(d)
}

/// Reads a dictionary from a complete byte buffer; trailing bytes are an error.
pub fn from_bytes(bytes: &[u8]) -> Result<Dictionary, DictionaryError> {
    let mut cursor = bytes;
    let d = read_dictionary(&mut cursor, bytes.len() as u64)?;
    if !cursor.is_empty() {
        return Err(DictionaryError::Malformed(format!(
            "{} trailing bytes after the checksum",
            cursor.len()
        )));
    }
    Ok(d)
}
