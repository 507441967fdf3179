//! Tile archives: PMTiles v3 ([`pmtiles`]) and MBTiles 1.3 ([`mbtiles`]) writers and readers,
//! and [`merge`], which joins the parts of a sharded export into one archive. Archives are
//! written under a temporary name ([`temporary_path`]) and renamed when complete, so that an
//! interrupted write leaves nothing that looks like a finished archive. No knowledge of worlds or
//! tiles' contents: `cli::export` feeds them bytes.

pub mod mbtiles;
pub mod pmtiles;

use std::path::{Path, PathBuf};

use thiserror::Error;

/// An archive that cannot be written or read.
#[derive(Debug, Error)]
pub enum ArchiveError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The archive (or a part given to merge) is malformed or inconsistent.
    #[error("{0}")]
    Format(String),
}

/// What [`merge`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Merged {
    /// Tiles in the archive.
    pub tiles: u64,
    /// Distinct tile contents.
    pub unique: u64,
    /// Archive size in bytes.
    pub bytes: u64,
}

/// The archive format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ArchiveFormat {
    /// PMTiles v3 (clustered, gzip directories).
    Pmtiles,
    /// MBTiles 1.3 (SQLite).
    Mbtiles,
}

/// The tile format inside the archive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TileFormat {
    /// PNG, as served at `{y}.png`.
    Png,
    /// Lossless WebP, as served at `{y}.webp`.
    Webp,
    /// Mapbox Vector Tiles 2.1 (instances, contours), gzip-compressed: the bytes served at
    /// `{y}.mvt` to a client that accepts gzip.
    Mvt,
}

impl TileFormat {
    /// The file extension of the served tiles.
    pub fn extension(self) -> &'static str {
        match self {
            TileFormat::Png => "png",
            TileFormat::Webp => "webp",
            TileFormat::Mvt => "mvt",
        }
    }

    /// The metadata's `format` (MBTiles 1.3 names vector tiles `pbf`).
    pub fn metadata_format(self) -> &'static str {
        match self {
            TileFormat::Mvt => "pbf",
            other => other.extension(),
        }
    }

    /// Whether the archive's tiles are gzip-compressed (vector tiles; PNG and WebP are
    /// compressed by their formats).
    pub fn gzipped(self) -> bool {
        self == TileFormat::Mvt
    }
}

/// The error-mapper for IO on `path`.
pub fn io_error(path: &Path) -> impl Fn(std::io::Error) -> ArchiveError + '_ {
    move |source| ArchiveError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// The temporary name an archive (or any command's output, `cli::output`) is written under:
/// `.NAME.tmp-PID` in the same directory.
pub fn temporary_path(output: &Path) -> PathBuf {
    let name = output
        .file_name()
        .map_or_else(|| "export".into(), |n| n.to_string_lossy().into_owned());
    output.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Removes the temporary files (`.NAME.tmp-PID`, [`temporary_path`]) that exports to `output`
/// killed before they finished left beside it: those whose process no longer runs. A file of a
/// process that still runs (another export to the same name) is kept, and so is every file where
/// liveness cannot be told (no `/proc`). Returns how many files were removed.
pub fn remove_stale_temporaries(output: &Path) -> usize {
    let Some(name) = output.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return 0;
    };
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let proc = Path::new("/proc");
    let (Ok(entries), true) = (std::fs::read_dir(dir), proc.join("self").exists()) else {
        return 0;
    };
    let prefix = format!(".{name}.tmp-");
    let mut removed = 0;
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(pid) = file
            .to_str()
            .and_then(|f| f.strip_prefix(&prefix))
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        let dead = pid != std::process::id() && !proc.join(pid.to_string()).exists();
        if dead && std::fs::remove_file(entry.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// Joins the parts of a sharded export (all PMTiles or all MBTiles, told by their first bytes)
/// into `output`. Returns the archive's summary.
pub fn merge(parts: &[PathBuf], output: &Path) -> Result<Merged, ArchiveError> {
    let first = parts
        .first()
        .ok_or_else(|| ArchiveError::Format("export merge: no parts given".into()))?;
    let kind = |p: &Path| -> Result<ArchiveFormat, ArchiveError> {
        let mut magic = [0u8; 16];
        let mut f = std::fs::File::open(p).map_err(io_error(p))?;
        std::io::Read::read_exact(&mut f, &mut magic).map_err(io_error(p))?;
        if magic.starts_with(b"PMTiles") {
            Ok(ArchiveFormat::Pmtiles)
        } else if &magic == b"SQLite format 3\0" {
            Ok(ArchiveFormat::Mbtiles)
        } else {
            Err(ArchiveError::Format(format!(
                "{}: neither a PMTiles nor an MBTiles archive",
                p.display()
            )))
        }
    };
    let format = kind(first)?;
    for p in parts {
        if kind(p)? != format {
            return Err(ArchiveError::Format(format!(
                "{} and {} are not the same archive format",
                first.display(),
                p.display()
            )));
        }
    }
    let (tiles, unique, bytes) = match format {
        ArchiveFormat::Mbtiles => {
            let (tiles, bytes) = mbtiles::merge(parts, output)?;
            (tiles, tiles, bytes)
        }
        ArchiveFormat::Pmtiles => merge_pmtiles(parts, output)?,
    };
    Ok(Merged {
        tiles,
        unique,
        bytes,
    })
}

fn merge_pmtiles(parts: &[PathBuf], output: &Path) -> Result<(u64, u64, u64), ArchiveError> {
    let mut readers = Vec::new();
    for p in parts {
        readers.push((p, pmtiles::Reader::open(p)?));
    }
    let (info, metadata) = {
        let (_, r) = &mut readers[0];
        (r.info()?, r.metadata()?)
    };
    // Every entry of every part, by tile id.
    let mut all = Vec::new();
    for (k, (p, r)) in readers.iter_mut().enumerate() {
        if r.info()? != info || r.metadata()? != metadata {
            return Err(ArchiveError::Format(format!(
                "{} and {} are parts of different exports (their headers or metadata differ)",
                parts[0].display(),
                p.display()
            )));
        }
        all.extend(r.entries()?.into_iter().map(|e| (e, k)));
    }
    all.sort_by_key(|(e, _)| e.tile_id);
    for w in all.windows(2) {
        let (a, b) = (&w[0].0, &w[1].0);
        if a.tile_id.saturating_add(u64::from(a.run_length)) > b.tile_id {
            return Err(ArchiveError::Format(format!(
                "tile id {} is in two parts ({} and {})",
                b.tile_id,
                parts[w[0].1].display(),
                parts[w[1].1].display()
            )));
        }
    }
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut writer = pmtiles::Writer::new(&dir)?;
    for (e, k) in &all {
        let bytes = readers[*k].1.tile(e)?;
        for i in 0..u64::from(e.run_length) {
            writer.add(e.tile_id.saturating_add(i), &bytes)?;
        }
    }
    let (tiles, unique, _) = writer.counts();
    let bytes = writer.finish(
        output,
        &info,
        &metadata,
        pmtiles::ROOT_LIMIT - pmtiles::HEADER_LEN,
    )?;
    Ok((tiles, unique, bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_temporaries_of_dead_exports_to_the_same_output_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("a.pmtiles");
        // Linux PIDs stay below 2^22, so this process never runs; PID 1 always does.
        let dead = dir.path().join(".a.pmtiles.tmp-4000000000");
        let kept = [
            dir.path()
                .join(format!(".a.pmtiles.tmp-{}", std::process::id())),
            dir.path().join(".a.pmtiles.tmp-1"),
            dir.path().join(".b.pmtiles.tmp-4000000000"),
            dir.path().join(".a.pmtiles.tmp-x"),
            dir.path().join("a.pmtiles"),
        ];
        for p in kept.iter().chain([&dead]) {
            std::fs::write(p, b"x").unwrap();
        }
        assert_eq!(remove_stale_temporaries(&output), 1);
        assert!(!dead.exists());
        for p in &kept {
            assert!(p.exists(), "{} was removed", p.display());
        }
        assert_eq!(remove_stale_temporaries(&output), 0);
    }
}
