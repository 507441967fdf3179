//! The on-disk store: content-addressed dictionaries (id = hex SHA-256 of the canonical bytes)
//! with human-name aliases. Every write goes to a temporary file in the same directory, is
//! fsynced and renamed, then the directory is fsynced, so a crash never leaves a partial object
//! under a final name; opening the store removes leftovers of interrupted writes. Reading an
//! object verifies its checksum (a corrupted object is an error, never served).

use std::io::Write;
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::dictionary::{self, Dictionary, DictionaryError};

/// Largest dictionary the store reads, bytes.
pub const MAX_DICTIONARY_BYTES: u64 = 4 << 30;

/// Prefix of temporary files of in-progress writes.
const TMP_PREFIX: &str = ".tmp-";

/// An error of the store.
#[derive(Debug, Error)]
pub enum StoreError {
    /// A file operation failed.
    #[error("store io error on {path}: {source}")]
    Io {
        /// The file or directory.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A stored dictionary is corrupted or unreadable.
    #[error("stored dictionary {id} is unusable: {source}")]
    Corrupt {
        /// Its id.
        id: String,
        /// Why.
        source: DictionaryError,
    },
    /// A dictionary could not be serialised.
    #[error(transparent)]
    Dictionary(#[from] DictionaryError),
    /// An alias or id is not a safe file name.
    #[error("invalid store name `{0}`")]
    BadName(String),
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Writes `bytes` to `path` atomically: temporary file in the same directory, fsync, rename,
/// fsync of the directory.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "object".into());
    let tmp = dir.join(format!("{TMP_PREFIX}{name}-{}", std::process::id()));
    let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
    f.write_all(bytes).map_err(io(&tmp))?;
    f.sync_all().map_err(io(&tmp))?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(io(path))?;
    if let Ok(d) = std::fs::File::open(dir) {
        // Directory fsync makes the rename durable; not supported on every platform.
        let _ = d.sync_all();
    }
    Ok(())
}

fn safe_name(name: &str) -> Result<&str, StoreError> {
    let ok = !name.is_empty()
        && name.len() <= 128
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
        && !name.starts_with('.');
    if ok {
        Ok(name)
    } else {
        Err(StoreError::BadName(name.to_string()))
    }
}

/// A store rooted at a directory.
#[derive(Clone, Debug)]
pub struct Store {
    dir: PathBuf,
}

impl Store {
    /// Opens (creating if needed) the store at `dir` and removes leftovers of interrupted writes.
    pub fn open(dir: &Path) -> Result<Store, StoreError> {
        let store = Store {
            dir: dir.to_path_buf(),
        };
        for sub in ["dictionaries", "aliases"] {
            let d = dir.join(sub);
            std::fs::create_dir_all(&d).map_err(io(&d))?;
            for entry in std::fs::read_dir(&d).map_err(io(&d))?.flatten() {
                if entry.file_name().to_string_lossy().starts_with(TMP_PREFIX) {
                    let p = entry.path();
                    std::fs::remove_file(&p).map_err(io(&p))?;
                }
            }
        }
        Ok(store)
    }

    /// The store's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn dictionary_path(&self, id: &str) -> Result<PathBuf, StoreError> {
        Ok(self
            .dir
            .join("dictionaries")
            .join(format!("{}.dict", safe_name(id)?)))
    }

    /// Stores a dictionary; returns its content id. Storing the same dictionary twice is a no-op.
    pub fn put_dictionary(&self, d: &Dictionary) -> Result<String, StoreError> {
        let bytes = dictionary::to_bytes(d)?;
        let id = dictionary::content_id(d)?;
        let path = self.dictionary_path(&id)?;
        if !path.exists() {
            write_atomically(&path, &bytes)?;
        }
        Ok(id)
    }

    /// Reads and verifies dictionary `id`; `Ok(None)` when absent.
    pub fn get_dictionary(&self, id: &str) -> Result<Option<Dictionary>, StoreError> {
        let path = self.dictionary_path(id)?;
        let f = match std::fs::File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io(&path)(e)),
        };
        let d = dictionary::read_dictionary(std::io::BufReader::new(f), MAX_DICTIONARY_BYTES)
            .map_err(|source| StoreError::Corrupt {
                id: id.to_string(),
                source,
            })?;
        let actual = dictionary::content_id(&d)?;
        if actual != id {
            return Err(StoreError::Corrupt {
                id: id.to_string(),
                source: DictionaryError::ChecksumMismatch,
            });
        }
        Ok(Some(d))
    }

    /// Points alias `name` at object `id`.
    pub fn set_alias(&self, name: &str, id: &str) -> Result<(), StoreError> {
        let path = self.dir.join("aliases").join(safe_name(name)?);
        write_atomically(&path, safe_name(id)?.as_bytes())
    }

    /// The object id alias `name` points at, if any.
    pub fn alias(&self, name: &str) -> Result<Option<String>, StoreError> {
        let path = self.dir.join("aliases").join(safe_name(name)?);
        match std::fs::read_to_string(&path) {
            Ok(s) => Ok(Some(s.trim().to_string())),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io(&path)(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_leaves_no_temporary_and_open_cleans_leftovers() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let leftover = dir.path().join("dictionaries").join(".tmp-x.dict-1");
        std::fs::write(&leftover, b"partial").unwrap();
        store.set_alias("world-a", "abc123").unwrap();
        assert_eq!(store.alias("world-a").unwrap().as_deref(), Some("abc123"));
        assert_eq!(store.alias("missing").unwrap(), None);
        let _ = Store::open(dir.path()).unwrap();
        assert!(!leftover.exists());
        assert!(store.set_alias("../evil", "x").is_err());
        assert!(store.get_dictionary("../../etc/passwd").is_err());
        assert_eq!(store.get_dictionary("0123abcd").unwrap(), None);
    }
}
