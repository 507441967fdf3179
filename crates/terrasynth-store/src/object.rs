//! The envelope of stored objects other than dictionaries (exemplars, world definitions).
//!
//! Layout (integers little-endian): magic `TSOBJ\0\0\x01` (8 bytes), kind (1 byte: 1 exemplar,
//! 2 world), envelope version `u32` (= [`OBJECT_VERSION`]), payload length `u64`, the payload,
//! then the SHA-256 of every preceding byte (32 bytes). An object's id is the lowercase hex of
//! that checksum, so a file can be verified against its name without any index.

use sha2::{Digest, Sha256};

use super::{ObjectKind, StoreError};

/// Magic bytes of an object envelope.
pub const OBJECT_MAGIC: [u8; 8] = *b"TSOBJ\0\0\x01";
/// Version of the envelope written and read by this build.
pub const OBJECT_VERSION: u32 = 1;
const PREFIX: usize = 8 + 1 + 4 + 8;

/// Lowercase hexadecimal of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Wraps `payload` in an envelope of `kind`; returns the bytes and the object's id.
pub fn seal(kind: ObjectKind, payload: &[u8]) -> (Vec<u8>, String) {
    let mut out = Vec::with_capacity(PREFIX + payload.len() + 32);
    out.extend_from_slice(&OBJECT_MAGIC);
    out.push(kind.code());
    out.extend_from_slice(&OBJECT_VERSION.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(payload);
    let digest = Sha256::digest(&out);
    out.extend_from_slice(digest.as_slice());
    (out, hex(digest.as_slice()))
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
        for n in 0..bytes.len() {
            assert!(open(ObjectKind::Exemplar, &bytes[..n], &id).is_err());
            let mut b = bytes.clone();
            b[n] ^= 0x10;
            assert!(open(ObjectKind::Exemplar, &b, &id).is_err(), "flip at {n}");
        }
    }
}
