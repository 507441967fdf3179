//! The envelope of stored objects other than dictionaries (exemplars, world definitions).
//!
//! Layout (integers little-endian): magic `TSOBJ\0\0\x01` (8 bytes), kind (1 byte: 1 exemplar,
//! 2 world), envelope version `u32` (= [`OBJECT_VERSION`]), payload length `u64`, the payload,
//! then the SHA-256 of every preceding byte (32 bytes). An object's id is the lowercase hex of
//! that checksum, so a file can be verified against its name without any index.

use std::io::Write;

use sha2::{Digest, Sha256};

use super::{ObjectKind, StoreError};

/// Magic bytes of an object envelope.
pub const OBJECT_MAGIC: [u8; 8] = *b"TSOBJ\0\0\x01";
/// Version of the envelope written and read by this build.
pub const OBJECT_VERSION: u32 = 1;
/// Bytes of the envelope before the payload.
pub const PREFIX: usize = 8 + 1 + 4 + 8;

/// Lowercase hexadecimal of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Writes an envelope of `kind` around a payload of a known length as the payload is written
/// through it, hashing as it goes, so that an object of any size is sealed without holding it
/// in memory.
pub struct SealWriter<W: Write> {
    out: W,
    hasher: Sha256,
    remaining: u64,
}

impl<W: Write> SealWriter<W> {
    /// Writes the envelope's prefix for a payload of `len` bytes of `kind` to `out`.
    pub fn new(kind: ObjectKind, len: u64, mut out: W) -> std::io::Result<Self> {
        let mut prefix = [0u8; PREFIX];
        prefix[..8].copy_from_slice(&OBJECT_MAGIC);
        prefix[8] = kind.code();
        prefix[9..13].copy_from_slice(&OBJECT_VERSION.to_le_bytes());
        prefix[13..21].copy_from_slice(&len.to_le_bytes());
        out.write_all(&prefix)?;
        let mut hasher = Sha256::new();
        hasher.update(prefix);
        Ok(SealWriter {
            out,
            hasher,
            remaining: len,
        })
    }

    /// Writes the checksum after the payload (which must have been written whole); returns the
    /// writer and the object's id.
    pub fn finish(mut self) -> std::io::Result<(W, String)> {
        if self.remaining != 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{} payload bytes missing", self.remaining),
            ));
        }
        let digest = self.hasher.finalize();
        self.out.write_all(digest.as_slice())?;
        Ok((self.out, hex(digest.as_slice())))
    }
}

impl<W: Write> Write for SealWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let room = usize::try_from(self.remaining).unwrap_or(usize::MAX);
        if buf.len() > room {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "more payload than the envelope announced",
            ));
        }
        let n = self.out.write(buf)?;
        self.hasher.update(&buf[..n]);
        self.remaining -= n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// Wraps `payload` in an envelope of `kind`; returns the bytes and the object's id.
pub fn seal(kind: ObjectKind, payload: &[u8]) -> (Vec<u8>, String) {
    let sealed = SealWriter::new(
        kind,
        payload.len() as u64,
        Vec::with_capacity(PREFIX + payload.len() + 32),
    )
    .and_then(|mut w| {
        w.write_all(payload)?;
        w.finish()
    });
    // Writing to a Vec of the announced length cannot fail.
    sealed.unwrap_or_default()
}

/// The payload of envelope `bytes`, verified: magic, kind, version, length, checksum, and that
/// the checksum is `id`.
pub fn open(kind: ObjectKind, bytes: &[u8], id: &str) -> Result<Vec<u8>, StoreError> {
    let bad = |reason: &str| StoreError::BadObject {
        id: id.to_string(),
        reason: reason.to_string(),
    };
    if bytes.len() < PREFIX + 32 || bytes[..8] != OBJECT_MAGIC {
        return Err(bad("not an object envelope (bad magic or too short)"));
    }
    if bytes[8] != kind.code() {
        return Err(bad("object of another kind"));
    }
    let version = u32::from_le_bytes([bytes[9], bytes[10], bytes[11], bytes[12]]);
    if version != OBJECT_VERSION {
        return Err(bad(&format!("unsupported object version {version}")));
    }
    let mut len8 = [0u8; 8];
    len8.copy_from_slice(&bytes[13..21]);
    let len = u64::from_le_bytes(len8);
    if len != (bytes.len() - PREFIX - 32) as u64 {
        return Err(bad(
            "payload length disagrees with the file size (truncated?)",
        ));
    }
    let body = &bytes[..bytes.len() - 32];
    let digest = Sha256::digest(body);
    if digest.as_slice() != &bytes[bytes.len() - 32..] {
        return Err(bad("checksum mismatch (corrupted)"));
    }
    if hex(digest.as_slice()) != id {
        return Err(bad("content does not match its id"));
    }
    Ok(bytes[PREFIX..bytes.len() - 32].to_vec())
}

/// The payload bytes present in `head` (the first bytes of an envelope of `len` bytes in all),
/// after checking magic, kind, version and that the length field agrees with `len` — not the
/// checksum, which needs every byte.
pub fn open_head(kind: ObjectKind, head: &[u8], len: u64, id: &str) -> Result<Vec<u8>, StoreError> {
    let bad = |reason: &str| StoreError::BadObject {
        id: id.to_string(),
        reason: reason.to_string(),
    };
    if len < (PREFIX + 32) as u64 || head.len() < PREFIX || head[..8] != OBJECT_MAGIC {
        return Err(bad("not an object envelope (bad magic or too short)"));
    }
    if head[8] != kind.code() {
        return Err(bad("object of another kind"));
    }
    let version = u32::from_le_bytes([head[9], head[10], head[11], head[12]]);
    if version != OBJECT_VERSION {
        return Err(bad(&format!("unsupported object version {version}")));
    }
    let mut len8 = [0u8; 8];
    len8.copy_from_slice(&head[13..21]);
    let payload = u64::from_le_bytes(len8);
    if payload != len - (PREFIX + 32) as u64 {
        return Err(bad(
            "payload length disagrees with the file size (truncated?)",
        ));
    }
    let end = PREFIX
        + usize::try_from(payload)
            .unwrap_or(usize::MAX)
            .min(head.len() - PREFIX);
    Ok(head[PREFIX..end].to_vec())
}

/// Verifies the envelope of `len` bytes that `r` yields (magic, kind, version, length,
/// checksum, and that the checksum is `id`) without holding it in memory.
pub fn verify_stream(
    kind: ObjectKind,
    mut r: impl std::io::Read,
    len: u64,
    id: &str,
) -> Result<(), StoreError> {
    let bad = |reason: &str| StoreError::BadObject {
        id: id.to_string(),
        reason: reason.to_string(),
    };
    let fixed = (PREFIX + 32) as u64;
    if len < fixed {
        return Err(bad("not an object envelope (bad magic or too short)"));
    }
    let mut prefix = [0u8; PREFIX];
    r.read_exact(&mut prefix)
        .map_err(|_| bad("not an object envelope (bad magic or too short)"))?;
    if prefix[..8] != OBJECT_MAGIC {
        return Err(bad("not an object envelope (bad magic or too short)"));
    }
    if prefix[8] != kind.code() {
        return Err(bad("object of another kind"));
    }
    let version = u32::from_le_bytes([prefix[9], prefix[10], prefix[11], prefix[12]]);
    if version != OBJECT_VERSION {
        return Err(bad(&format!("unsupported object version {version}")));
    }
    let mut len8 = [0u8; 8];
    len8.copy_from_slice(&prefix[13..21]);
    let mut remaining = u64::from_le_bytes(len8);
    if remaining != len - fixed {
        return Err(bad(
            "payload length disagrees with the file size (truncated?)",
        ));
    }
    let mut hasher = Sha256::new();
    hasher.update(prefix);
    let mut buf = vec![0u8; 1 << 16];
    while remaining > 0 {
        let want = usize::try_from(remaining)
            .unwrap_or(usize::MAX)
            .min(buf.len());
        let n = r
            .read(&mut buf[..want])
            .map_err(|e| bad(&format!("unreadable: {e}")))?;
        if n == 0 {
            return Err(bad(
                "payload length disagrees with the file size (truncated?)",
            ));
        }
        hasher.update(&buf[..n]);
        remaining -= n as u64;
    }
    let mut trailer = [0u8; 32];
    r.read_exact(&mut trailer)
        .map_err(|_| bad("payload length disagrees with the file size (truncated?)"))?;
    let digest = hasher.finalize();
    if digest.as_slice() != trailer {
        return Err(bad("checksum mismatch (corrupted)"));
    }
    if hex(digest.as_slice()) != id {
        return Err(bad("content does not match its id"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_truncation_and_flip_is_rejected() {
        let (bytes, id) = seal(ObjectKind::Exemplar, b"payload bytes");
        assert_eq!(
            open(ObjectKind::Exemplar, &bytes, &id).unwrap(),
            b"payload bytes"
        );
        assert!(open(ObjectKind::World, &bytes, &id).is_err());
        let streamed = |b: &[u8]| verify_stream(ObjectKind::Exemplar, b, b.len() as u64, &id);
        assert!(streamed(&bytes).is_ok());
        for n in 0..bytes.len() {
            assert!(open(ObjectKind::Exemplar, &bytes[..n], &id).is_err());
            assert!(streamed(&bytes[..n]).is_err(), "truncated at {n}");
            let mut b = bytes.clone();
            b[n] ^= 0x10;
            assert!(open(ObjectKind::Exemplar, &b, &id).is_err(), "flip at {n}");
            assert!(streamed(&b).is_err(), "flip at {n}");
        }
    }
}
