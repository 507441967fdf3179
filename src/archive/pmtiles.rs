//! PMTiles v3 archives: Hilbert tile ids ([`tile_id`], naive twin [`tile_id_naive`]), directories
//! (varint columns, run lengths, offsets written as 0 when contiguous, gzip-compressed), a writer
//! that spools tile data in tile-id order, deduplicates identical tiles by content hash and
//! merges identical consecutive tiles into one run-length entry ([`Writer`]), and a reader of the
//! same format ([`Reader`], used by `export merge` and the tests).
//!
//! Layout of a written archive (clustered): the 127-byte header, the root directory (with the
//! header within the first 16 KiB), the gzip-compressed JSON metadata, the leaf directories (only
//! when the root directory would not fit), then the tile data in tile-id order.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use sha2::{Digest, Sha256};

use super::{io_error, temporary_path, ArchiveError, TileFormat};

/// The header's length in bytes.
pub const HEADER_LEN: usize = 127;
/// The header and the root directory fit in these first bytes of the archive.
pub const ROOT_LIMIT: usize = 16_384;
/// Internal (directory and metadata) compression: gzip.
const COMPRESSION_GZIP: u8 = 2;
/// Tile compression of PNG and WebP: none (their formats compress them).
const COMPRESSION_NONE: u8 = 1;

/// The PMTiles `tile_type` of a tile format.
fn tile_type(format: TileFormat) -> u8 {
    match format {
        TileFormat::Mvt => 1,
        TileFormat::Png => 2,
        TileFormat::Webp => 4,
    }
}

/// The PMTiles `tile_compression` of a tile format.
fn tile_compression(format: TileFormat) -> u8 {
    if format.gzipped() {
        COMPRESSION_GZIP
    } else {
        COMPRESSION_NONE
    }
}

/// Tiles in zooms `0..z`: the first tile id of zoom `z`.
fn zoom_base(z: u8) -> u64 {
    ((1u64 << (2 * u32::from(z))) - 1) / 3
}

/// The PMTiles tile id of `z/x/y`: tiles of shallower zooms first, then the position of `(x, y)`
/// along the Hilbert curve of zoom `z`.
pub fn tile_id(z: u8, x: u32, y: u32) -> u64 {
    let (mut x, mut y) = (u64::from(x), u64::from(y));
    let mut d = 0u64;
    let mut s = if z == 0 { 0 } else { 1u64 << (z - 1) };
    while s > 0 {
        let rx = u64::from(x & s > 0);
        let ry = u64::from(y & s > 0);
        d += s * s * ((3 * rx) ^ ry);
        // Rotate the quadrant (only the bits below `s` matter from here on).
        if ry == 0 {
            if rx == 1 {
                x = s - 1 - (x & (s - 1));
                y = s - 1 - (y & (s - 1));
            }
            std::mem::swap(&mut x, &mut y);
        }
        s >>= 1;
    }
    zoom_base(z) + d
}

/// The tile id by walking the Hilbert curve of zoom `z` cell by cell (naive twin of [`tile_id`]:
/// the curve built recursively from its four rotated quarters).
pub fn tile_id_naive(z: u8, x: u32, y: u32) -> u64 {
    /// The cells of the order-`n` curve in visiting order.
    fn curve(n: u8) -> Vec<(u32, u32)> {
        if n == 0 {
            return vec![(0, 0)];
        }
        let prev = curve(n - 1);
        let h = 1u32 << (n - 1);
        let mut out = Vec::with_capacity(prev.len() * 4);
        // Lower-left quarter transposed, upper-left, upper-right, lower-right anti-transposed
        // (the textbook construction in a y-down frame: x right, y down).
        out.extend(prev.iter().map(|&(x, y)| (y, x)));
        out.extend(prev.iter().map(|&(x, y)| (x, y + h)));
        out.extend(prev.iter().map(|&(x, y)| (x + h, y + h)));
        out.extend(prev.iter().map(|&(x, y)| (2 * h - 1 - y, h - 1 - x)));
        out
    }
    let pos = curve(z).iter().position(|&c| c == (x, y)).unwrap_or(0);
    zoom_base(z) + pos as u64
}

/// One directory entry: a tile (or a run of `run_length` consecutive tile ids with the same
/// bytes), or with `run_length == 0` a leaf directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    /// First tile id.
    pub tile_id: u64,
    /// Offset of the bytes (tile data or leaf section relative).
    pub offset: u64,
    /// Length of the bytes.
    pub length: u32,
    /// Tiles this entry stands for; 0 for a leaf directory.
    pub run_length: u32,
}

fn write_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7f) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn read_varint(bytes: &[u8], pos: &mut usize) -> Result<u64, ArchiveError> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let b = *bytes
            .get(*pos)
            .ok_or_else(|| ArchiveError::Format("PMTiles directory ends inside a varint".into()))?;
        *pos += 1;
        v |= u64::from(b & 0x7f) << shift;
        if b < 0x80 {
            return Ok(v);
        }
    }
    Err(ArchiveError::Format(
        "PMTiles directory varint is too long".into(),
    ))
}

/// `bytes` gzip-compressed, with the fixed settings of every gzip terrasynth writes
/// ([`terrasynth_tiles::gzip`]).
fn gzip(bytes: &[u8]) -> Vec<u8> {
    // Compressing into memory cannot fail.
    terrasynth_tiles::gzip(bytes).unwrap_or_default()
}

fn gunzip(bytes: &[u8]) -> Result<Vec<u8>, ArchiveError> {
    terrasynth_tiles::gunzip(bytes)
        .map_err(|e| ArchiveError::Format(format!("PMTiles: corrupt gzip section: {e}")))
}

/// A directory serialised (columns of varints) and gzip-compressed.
pub fn serialize_directory(entries: &[Entry]) -> Vec<u8> {
    let mut out = Vec::new();
    write_varint(&mut out, entries.len() as u64);
    let mut last = 0;
    for e in entries {
        write_varint(&mut out, e.tile_id - last);
        last = e.tile_id;
    }
    for e in entries {
        write_varint(&mut out, u64::from(e.run_length));
    }
    for e in entries {
        write_varint(&mut out, u64::from(e.length));
    }
    for (i, e) in entries.iter().enumerate() {
        let contiguous =
            i > 0 && e.offset == entries[i - 1].offset + u64::from(entries[i - 1].length);
        write_varint(&mut out, if contiguous { 0 } else { e.offset + 1 });
    }
    gzip(&out)
}

/// The entries of a gzip-compressed directory.
pub fn deserialize_directory(compressed: &[u8]) -> Result<Vec<Entry>, ArchiveError> {
    let bytes = gunzip(compressed)?;
    let mut pos = 0;
    let n = read_varint(&bytes, &mut pos)?;
    if n > bytes.len() as u64 {
        return Err(ArchiveError::Format(format!(
            "PMTiles directory claims {n} entries"
        )));
    }
    let n = n as usize;
    let mut entries = vec![
        Entry {
            tile_id: 0,
            offset: 0,
            length: 0,
            run_length: 0
        };
        n
    ];
    let mut last = 0u64;
    for e in entries.iter_mut() {
        last = last
            .checked_add(read_varint(&bytes, &mut pos)?)
            .ok_or_else(|| ArchiveError::Format("PMTiles tile id overflows".into()))?;
        e.tile_id = last;
    }
    let small = |v: u64| {
        u32::try_from(v).map_err(|_| ArchiveError::Format("PMTiles entry field too large".into()))
    };
    for e in entries.iter_mut() {
        e.run_length = small(read_varint(&bytes, &mut pos)?)?;
    }
    for e in entries.iter_mut() {
        e.length = small(read_varint(&bytes, &mut pos)?)?;
    }
    for i in 0..n {
        let v = read_varint(&bytes, &mut pos)?;
        entries[i].offset = if v == 0 && i > 0 {
            entries[i - 1]
                .offset
                .saturating_add(u64::from(entries[i - 1].length))
        } else {
            v.checked_sub(1)
                .ok_or_else(|| ArchiveError::Format("PMTiles: first offset written as 0".into()))?
        };
    }
    Ok(entries)
}

/// The root directory and the leaf directories of `entries`, so that the root fits in
/// `max_root` bytes: everything in the root when it fits, else leaves of `leaf_size` entries
/// (at least 4096, growing by a fifth until the root fits), as the reference writer does.
pub fn build_directories(entries: &[Entry], max_root: usize) -> (Vec<u8>, Vec<u8>) {
    let root = serialize_directory(entries);
    if root.len() <= max_root {
        return (root, Vec::new());
    }
    let mut leaf_size = (entries.len() as f64 / 3500.0).max(4096.0);
    // With a tiny `max_root` (tests), allow leaves smaller than the reference's minimum.
    if max_root < ROOT_LIMIT - HEADER_LEN {
        leaf_size = (entries.len() as f64 / 64.0).max(1.0);
    }
    loop {
        let mut leaves = Vec::new();
        let mut root_entries = Vec::new();
        for chunk in entries.chunks(leaf_size.ceil() as usize) {
            let leaf = serialize_directory(chunk);
            root_entries.push(Entry {
                tile_id: chunk[0].tile_id,
                offset: leaves.len() as u64,
                length: leaf.len() as u32,
                run_length: 0,
            });
            leaves.extend_from_slice(&leaf);
        }
        let root = serialize_directory(&root_entries);
        if root.len() <= max_root || root_entries.len() == 1 {
            return (root, leaves);
        }
        leaf_size *= 1.2;
    }
}

/// What the header says besides offsets and counts.
#[derive(Clone, Debug, PartialEq)]
pub struct HeaderInfo {
    /// Tile format of every tile.
    pub format: TileFormat,
    /// Shallowest zoom.
    pub min_zoom: u8,
    /// Deepest zoom.
    pub max_zoom: u8,
    /// `[w, s, e, n]`, degrees.
    pub bounds: [f64; 4],
    /// `[lon, lat, zoom]`.
    pub center: [f64; 3],
}

fn e7(v: f64) -> i32 {
    (v * 1e7).round() as i32
}

/// A PMTiles archive being written: tiles spooled to an anonymous temporary file in tile-id
/// order; [`Writer::finish`] writes the archive under a temporary name beside the output and
/// renames it.
pub struct Writer {
    spool: BufWriter<File>,
    spool_len: u64,
    entries: Vec<Entry>,
    seen: HashMap<[u8; 32], (u64, u32)>,
    addressed: u64,
}

impl Writer {
    /// A writer whose spool lives in `dir` (the output's directory).
    pub fn new(dir: &Path) -> Result<Writer, ArchiveError> {
        let spool = tempfile::tempfile_in(dir).map_err(io_error(dir))?;
        Ok(Writer {
            spool: BufWriter::new(spool),
            spool_len: 0,
            entries: Vec::new(),
            seen: HashMap::new(),
            addressed: 0,
        })
    }

    /// Adds the tile `id` (ids strictly increasing).
    pub fn add(&mut self, id: u64, bytes: &[u8]) -> Result<(), ArchiveError> {
        if let Some(last) = self.entries.last() {
            if id < last.tile_id + u64::from(last.run_length) {
                return Err(ArchiveError::Format(format!(
                    "tile id {id} added after {} (ids must increase)",
                    last.tile_id
                )));
            }
        }
        let length = u32::try_from(bytes.len())
            .map_err(|_| ArchiveError::Format(format!("tile {id} is larger than 4 GiB")))?;
        let hash: [u8; 32] = Sha256::digest(bytes).into();
        let (offset, length) = match self.seen.get(&hash) {
            Some(&at) => at,
            None => {
                let at = (self.spool_len, length);
                self.spool
                    .write_all(bytes)
                    .map_err(|e| ArchiveError::Format(format!("writing the tile spool: {e}")))?;
                self.spool_len += u64::from(length);
                self.seen.insert(hash, at);
                at
            }
        };
        self.addressed += 1;
        if let Some(last) = self.entries.last_mut() {
            if last.tile_id + u64::from(last.run_length) == id
                && last.offset == offset
                && last.length == length
            {
                last.run_length += 1;
                return Ok(());
            }
        }
        self.entries.push(Entry {
            tile_id: id,
            offset,
            length,
            run_length: 1,
        });
        Ok(())
    }

    /// Tiles added, distinct contents, entries.
    pub fn counts(&self) -> (u64, u64, u64) {
        (
            self.addressed,
            self.seen.len() as u64,
            self.entries.len() as u64,
        )
    }

    /// Writes the archive to `output` (through a temporary name and a rename) with `metadata`
    /// (JSON) and the header fields of `info`; the root directory fits in `max_root` bytes
    /// (at most 16 KiB less the header). Returns the archive's size.
    pub fn finish(
        self,
        output: &Path,
        info: &HeaderInfo,
        metadata: &serde_json::Value,
        max_root: usize,
    ) -> Result<u64, ArchiveError> {
        let max_root = max_root.min(ROOT_LIMIT - HEADER_LEN);
        let (addressed, contents, n_entries) = self.counts();
        let (root, leaves) = build_directories(&self.entries, max_root);
        let meta = gzip(metadata.to_string().as_bytes());
        let root_off = HEADER_LEN as u64;
        let meta_off = root_off + root.len() as u64;
        let leaf_off = meta_off + meta.len() as u64;
        let data_off = leaf_off + leaves.len() as u64;
        let mut h = Vec::with_capacity(HEADER_LEN);
        h.extend_from_slice(b"PMTiles");
        h.push(3);
        for v in [
            root_off,
            root.len() as u64,
            meta_off,
            meta.len() as u64,
            leaf_off,
            leaves.len() as u64,
            data_off,
            self.spool_len,
            addressed,
            n_entries,
            contents,
        ] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        h.push(1); // clustered
        h.push(COMPRESSION_GZIP);
        h.push(tile_compression(info.format));
        h.push(tile_type(info.format));
        h.push(info.min_zoom);
        h.push(info.max_zoom);
        for v in [
            info.bounds[0],
            info.bounds[1],
            info.bounds[2],
            info.bounds[3],
        ] {
            h.extend_from_slice(&e7(v).to_le_bytes());
        }
        h.push(info.center[2].round().clamp(0.0, 255.0) as u8);
        h.extend_from_slice(&e7(info.center[0]).to_le_bytes());
        h.extend_from_slice(&e7(info.center[1]).to_le_bytes());
        debug_assert_eq!(h.len(), HEADER_LEN);

        let mut spool = self
            .spool
            .into_inner()
            .map_err(|e| ArchiveError::Format(format!("writing the tile spool: {}", e.error())))?;
        spool.seek(SeekFrom::Start(0)).map_err(io_error(output))?;
        let tmp = temporary_path(output);
        let result = (|| -> std::io::Result<u64> {
            let mut f = BufWriter::new(File::create(&tmp)?);
            f.write_all(&h)?;
            f.write_all(&root)?;
            f.write_all(&meta)?;
            f.write_all(&leaves)?;
            let copied = std::io::copy(&mut spool, &mut f)?;
            let f = f.into_inner().map_err(|e| e.into_error())?;
            f.sync_all()?;
            Ok(data_off + copied)
        })();
        match result {
            Ok(size) => {
                std::fs::rename(&tmp, output).map_err(io_error(output))?;
                Ok(size)
            }
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(io_error(output)(e))
            }
        }
    }
}

/// A PMTiles archive opened for reading.
pub struct Reader {
    file: File,
    header: Vec<u8>,
}

impl Reader {
    /// Opens `path` and checks its magic and version.
    pub fn open(path: &Path) -> Result<Reader, ArchiveError> {
        let mut file = File::open(path).map_err(io_error(path))?;
        let mut header = vec![0u8; HEADER_LEN];
        file.read_exact(&mut header).map_err(io_error(path))?;
        if &header[..7] != b"PMTiles" || header[7] != 3 {
            return Err(ArchiveError::Format(format!(
                "{}: not a PMTiles v3 archive",
                path.display()
            )));
        }
        if header[97] != COMPRESSION_GZIP {
            return Err(ArchiveError::Format(format!(
                "{}: directories are not gzip-compressed",
                path.display()
            )));
        }
        Ok(Reader { file, header })
    }

    fn u64_at(&self, at: usize) -> u64 {
        let mut b = [0u8; 8];
        b.copy_from_slice(&self.header[at..at + 8]);
        u64::from_le_bytes(b)
    }

    fn i32_at(&self, at: usize) -> f64 {
        let mut b = [0u8; 4];
        b.copy_from_slice(&self.header[at..at + 4]);
        f64::from(i32::from_le_bytes(b)) / 1e7
    }

    /// The raw 127-byte header.
    pub fn header(&self) -> &[u8] {
        &self.header
    }

    /// The header's tile format, zooms, bounds and centre.
    pub fn info(&self) -> Result<HeaderInfo, ArchiveError> {
        let format = match self.header[99] {
            1 => TileFormat::Mvt,
            2 => TileFormat::Png,
            4 => TileFormat::Webp,
            t => {
                return Err(ArchiveError::Format(format!(
                    "PMTiles tile type {t} is none of MVT, PNG and WebP"
                )))
            }
        };
        if self.header[98] != tile_compression(format) {
            return Err(ArchiveError::Format(format!(
                "PMTiles tile compression {} is not what terrasynth writes for tile type {}",
                self.header[98], self.header[99]
            )));
        }
        Ok(HeaderInfo {
            format,
            min_zoom: self.header[100],
            max_zoom: self.header[101],
            bounds: [
                self.i32_at(102),
                self.i32_at(106),
                self.i32_at(110),
                self.i32_at(114),
            ],
            center: [
                self.i32_at(119),
                self.i32_at(123),
                f64::from(self.header[118]),
            ],
        })
    }

    fn read_at(&mut self, offset: u64, len: u64) -> Result<Vec<u8>, ArchiveError> {
        let size = self.file.metadata().map(|m| m.len()).unwrap_or(0);
        if offset.checked_add(len).is_none_or(|end| end > size) {
            return Err(ArchiveError::Format(format!(
                "PMTiles: {len} bytes at {offset} lie past the end of the archive ({size} bytes)"
            )));
        }
        let len = usize::try_from(len)
            .map_err(|_| ArchiveError::Format("PMTiles section too large".into()))?;
        let mut buf = vec![0u8; len];
        self.file
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.file.read_exact(&mut buf))
            .map_err(|e| {
                ArchiveError::Format(format!("PMTiles: reading {len} bytes at {offset}: {e}"))
            })?;
        Ok(buf)
    }

    /// The metadata JSON.
    pub fn metadata(&mut self) -> Result<serde_json::Value, ArchiveError> {
        let raw = self.read_at(self.u64_at(24), self.u64_at(32))?;
        serde_json::from_slice(&gunzip(&raw)?)
            .map_err(|e| ArchiveError::Format(format!("PMTiles metadata is not JSON: {e}")))
    }

    /// Every tile entry (leaf directories followed), offsets relative to the tile data.
    pub fn entries(&mut self) -> Result<Vec<Entry>, ArchiveError> {
        let root = self.read_at(self.u64_at(8), self.u64_at(16))?;
        let leaf_off = self.u64_at(40);
        let mut out = Vec::new();
        for e in deserialize_directory(&root)? {
            if e.run_length > 0 {
                out.push(e);
                continue;
            }
            let leaf = self.read_at(leaf_off.saturating_add(e.offset), u64::from(e.length))?;
            for l in deserialize_directory(&leaf)? {
                if l.run_length == 0 {
                    return Err(ArchiveError::Format(
                        "PMTiles: leaf directories nested deeper than one level".into(),
                    ));
                }
                out.push(l);
            }
        }
        Ok(out)
    }

    /// The bytes of an entry.
    pub fn tile(&mut self, e: &Entry) -> Result<Vec<u8>, ArchiveError> {
        self.read_at(
            self.u64_at(56).saturating_add(e.offset),
            u64::from(e.length),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_ids_match_the_specification_examples() {
        assert_eq!(tile_id(0, 0, 0), 0);
        assert_eq!(tile_id(1, 0, 0), 1);
        assert_eq!(tile_id(1, 0, 1), 2);
        assert_eq!(tile_id(1, 1, 1), 3);
        assert_eq!(tile_id(1, 1, 0), 4);
        assert_eq!(tile_id(2, 0, 0), 5);
        assert_eq!(tile_id(3, 0, 0), 21);
        assert_eq!(tile_id(20, 0, 0), 366_503_875_925);
    }

    #[test]
    fn tile_ids_equal_the_naive_hilbert_walk() {
        for z in 0..=6u8 {
            let n = 1u32 << z;
            let mut seen = std::collections::HashSet::new();
            for x in 0..n {
                for y in 0..n {
                    let id = tile_id(z, x, y);
                    assert_eq!(id, tile_id_naive(z, x, y), "{z}/{x}/{y}");
                    assert!(seen.insert(id));
                }
            }
        }
    }

    #[test]
    fn consecutive_hilbert_cells_are_neighbours() {
        let z = 5u8;
        let n = 1u32 << z;
        let mut by_id = vec![(0u32, 0u32); (n * n) as usize];
        for x in 0..n {
            for y in 0..n {
                by_id[(tile_id(z, x, y) - zoom_base(z)) as usize] = (x, y);
            }
        }
        for w in by_id.windows(2) {
            let d = w[0].0.abs_diff(w[1].0) + w[0].1.abs_diff(w[1].1);
            assert_eq!(d, 1, "{w:?}");
        }
    }

    fn entries(n: u64) -> Vec<Entry> {
        // Gaps, runs and repeated offsets, as a real archive has.
        (0..n)
            .map(|i| Entry {
                tile_id: i * 10 + (i % 7),
                offset: if i % 5 == 0 { 0 } else { i * 1000 },
                length: 1000 - (i % 13) as u32,
                run_length: 1 + (i % 3) as u32,
            })
            .collect()
    }

    #[test]
    fn directories_round_trip() {
        let e = entries(5000);
        assert_eq!(deserialize_directory(&serialize_directory(&e)).unwrap(), e);
        assert_eq!(
            deserialize_directory(&serialize_directory(&[])).unwrap(),
            []
        );
    }

    #[test]
    fn corrupt_directories_are_errors_not_panics() {
        let good = serialize_directory(&entries(50));
        assert!(deserialize_directory(&good[..good.len() / 2]).is_err());
        assert!(deserialize_directory(b"not gzip").is_err());
        assert!(deserialize_directory(&gzip(&[0xff; 20])).is_err());
    }

    #[test]
    fn a_root_that_does_not_fit_gets_leaves_that_cover_every_entry() {
        let e = entries(60_000);
        let (root, leaves) = build_directories(&e, ROOT_LIMIT - HEADER_LEN);
        assert!(root.len() <= ROOT_LIMIT - HEADER_LEN);
        assert!(!leaves.is_empty());
        let root = deserialize_directory(&root).unwrap();
        assert!(root.len() > 1 && root.iter().all(|r| r.run_length == 0));
        let mut all = Vec::new();
        for r in &root {
            let at = r.offset as usize;
            let leaf = deserialize_directory(&leaves[at..at + r.length as usize]).unwrap();
            assert_eq!(leaf[0].tile_id, r.tile_id);
            all.extend(leaf);
        }
        assert_eq!(all, e);
        // A small directory stays in the root.
        let (root, leaves) = build_directories(&entries(100), ROOT_LIMIT - HEADER_LEN);
        assert!(leaves.is_empty());
        assert_eq!(deserialize_directory(&root).unwrap(), entries(100));
    }

    #[test]
    fn the_writer_deduplicates_runs_and_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = Writer::new(dir.path()).unwrap();
        let tiles: Vec<(u64, Vec<u8>)> = vec![
            (0, b"a".to_vec()),
            (1, b"same".to_vec()),
            (2, b"same".to_vec()),
            (3, b"same".to_vec()),
            (5, b"same".to_vec()),
            (6, b"a".to_vec()),
            (9, b"bbb".to_vec()),
        ];
        for (id, b) in &tiles {
            w.add(*id, b).unwrap();
        }
        assert!(w.add(8, b"x").is_err());
        assert_eq!(w.counts(), (7, 3, 5));
        let info = HeaderInfo {
            format: TileFormat::Png,
            min_zoom: 0,
            max_zoom: 2,
            bounds: [71.5, 42.1, 73.5, 42.7],
            center: [72.5, 42.4, 1.0],
        };
        let out = dir.path().join("t.pmtiles");
        let meta = serde_json::json!({"name": "t"});
        w.finish(&out, &info, &meta, 1_000_000).unwrap();
        // Only the archive is left in the directory: no temporary file.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let mut r = Reader::open(&out).unwrap();
        assert_eq!(r.info().unwrap(), info);
        assert_eq!(r.metadata().unwrap(), meta);
        let e = r.entries().unwrap();
        assert_eq!(e.len(), 5);
        assert_eq!((e[1].tile_id, e[1].run_length), (1, 3));
        let mut got = Vec::new();
        for entry in &e {
            let bytes = r.tile(entry).unwrap();
            for k in 0..u64::from(entry.run_length) {
                got.push((entry.tile_id + k, bytes.clone()));
            }
        }
        assert_eq!(got, tiles);
    }

    /// Vector tiles: tile type 1 (MVT) with gzip tile compression in the header (PMTiles v3
    /// §3.4: bytes 98 and 99), read back as such; a header whose compression does not go with
    /// its type is refused.
    #[test]
    fn vector_tile_archives_say_mvt_and_gzip() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = Writer::new(dir.path()).unwrap();
        w.add(0, &gzip(b"an MVT")).unwrap();
        let info = HeaderInfo {
            format: TileFormat::Mvt,
            min_zoom: 0,
            max_zoom: 0,
            bounds: [71.5, 42.1, 73.5, 42.7],
            center: [72.5, 42.4, 0.0],
        };
        let out = dir.path().join("v.pmtiles");
        w.finish(&out, &info, &serde_json::json!({}), 1_000_000)
            .unwrap();
        let r = Reader::open(&out).unwrap();
        assert_eq!((r.header()[98], r.header()[99]), (2, 1));
        assert_eq!(r.info().unwrap().format, TileFormat::Mvt);
        let mut bytes = std::fs::read(&out).unwrap();
        bytes[98] = COMPRESSION_NONE;
        std::fs::write(&out, &bytes).unwrap();
        let err = Reader::open(&out).and_then(|r| r.info()).unwrap_err();
        assert!(err.to_string().contains("tile compression"), "{err}");
    }
}
