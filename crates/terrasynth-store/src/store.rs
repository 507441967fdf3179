//! The store itself: a directory of content-addressed objects, aliases and job records with
//! atomic writes, verified on open (see the crate documentation for the layout).

use std::io::Write;
use std::path::{Path, PathBuf};

use terrasynth_core::dictionary::{self, Dictionary, DictionaryError};

use crate::error::StoreError;
use crate::object;

/// Largest dictionary the store reads, bytes.
pub const MAX_DICTIONARY_BYTES: u64 = 4 << 30;

/// Prefix of temporary files of in-progress writes.
const TMP_PREFIX: &str = ".tmp-";

/// Version of the store's layout.
pub const STORE_VERSION: u32 = 1;

/// The kinds of enveloped objects (dictionaries have their own format).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectKind {
    /// An uploaded exemplar raster ([`crate::exemplar`]).
    Exemplar,
    /// A world definition (JSON).
    World,
}

impl ObjectKind {
    fn dir(self) -> &'static str {
        match self {
            ObjectKind::Exemplar => "exemplars",
            ObjectKind::World => "worlds",
        }
    }

    /// The byte identifying the kind in the envelope.
    pub fn code(self) -> u8 {
        match self {
            ObjectKind::Exemplar => 1,
            ObjectKind::World => 2,
        }
    }
}

const SUBDIRS: [&str; 5] = ["dictionaries", "aliases", "exemplars", "worlds", "jobs"];

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
    static SEQ: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let seq = SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!("{TMP_PREFIX}{name}-{}-{seq}", std::process::id()));
    let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
    f.write_all(bytes).map_err(io(&tmp))?;
    f.sync_all().map_err(io(&tmp))?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(io(path))?;
    sync_dir(dir);
    Ok(())
}

/// Fsyncs a directory, making renames and removals in it durable (not supported on every
/// platform, hence best effort).
fn sync_dir(dir: &Path) {
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Removes `path` (absent is fine) and fsyncs its directory.
fn remove_durably(path: &Path) -> Result<bool, StoreError> {
    match std::fs::remove_file(path) {
        Ok(()) => {
            if let Some(d) = path.parent() {
                sync_dir(d);
            }
            Ok(true)
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(io(path)(e)),
    }
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
    /// Opens (creating if needed) the store at `dir`: checks its format version, removes
    /// leftovers of interrupted writes, and verifies every object, moving corrupted ones to
    /// `corrupt/` with a warning.
    pub fn open(dir: &Path) -> Result<Store, StoreError> {
        let store = Store {
            dir: dir.to_path_buf(),
        };
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let version_path = dir.join("VERSION");
        let want = format!("terrasynth-store {STORE_VERSION}");
        match std::fs::read_to_string(&version_path) {
            Ok(v) if v.trim() == want => {}
            Ok(v) => {
                return Err(StoreError::Version {
                    found: v.trim().to_string(),
                    supported: STORE_VERSION,
                })
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                write_atomically(&version_path, format!("{want}\n").as_bytes())?
            }
            Err(e) => return Err(io(&version_path)(e)),
        }
        for sub in SUBDIRS {
            let d = dir.join(sub);
            std::fs::create_dir_all(&d).map_err(io(&d))?;
            for entry in std::fs::read_dir(&d).map_err(io(&d))?.flatten() {
                if entry.file_name().to_string_lossy().starts_with(TMP_PREFIX) {
                    let p = entry.path();
                    tracing::info!(path = %p.display(), "store: removing the leftover of an interrupted write");
                    std::fs::remove_file(&p).map_err(io(&p))?;
                }
            }
        }
        store.verify_all()?;
        Ok(store)
    }

    /// Verifies every object; corrupted ones are moved to `corrupt/`.
    fn verify_all(&self) -> Result<(), StoreError> {
        for id in self.list_ids("dictionaries", ".dict")? {
            if let Err(e) = self.get_dictionary(&id) {
                self.quarantine("dictionaries", &format!("{id}.dict"), &e)?;
            }
        }
        for kind in [ObjectKind::Exemplar, ObjectKind::World] {
            for id in self.list_ids(kind.dir(), ".obj")? {
                if let Err(e) = self.get_object(kind, &id) {
                    self.quarantine(kind.dir(), &format!("{id}.obj"), &e)?;
                }
            }
        }
        Ok(())
    }

    fn quarantine(&self, sub: &str, file: &str, why: &StoreError) -> Result<(), StoreError> {
        tracing::warn!(object = %format!("{sub}/{file}"), error = %why, "store: corrupted object skipped (moved to corrupt/)");
        let dst_dir = self.dir.join("corrupt");
        std::fs::create_dir_all(&dst_dir).map_err(io(&dst_dir))?;
        let src = self.dir.join(sub).join(file);
        let dst = dst_dir.join(format!("{sub}-{file}"));
        std::fs::rename(&src, &dst).map_err(io(&src))?;
        sync_dir(&self.dir.join(sub));
        Ok(())
    }

    /// Ids of the files `{id}{ext}` of a subdirectory, sorted.
    fn list_ids(&self, sub: &str, ext: &str) -> Result<Vec<String>, StoreError> {
        let d = self.dir.join(sub);
        let mut ids: Vec<String> = std::fs::read_dir(&d)
            .map_err(io(&d))?
            .flatten()
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.strip_suffix(ext)
                    .filter(|id| safe_name(id).is_ok())
                    .map(str::to_string)
            })
            .collect();
        ids.sort();
        Ok(ids)
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

    /// Removes alias `name` (absent is fine).
    pub fn remove_alias(&self, name: &str) -> Result<(), StoreError> {
        remove_durably(&self.dir.join("aliases").join(safe_name(name)?)).map(|_| ())
    }

    /// Every alias `(name, id)` whose name starts with `prefix`, sorted by name.
    pub fn aliases(&self, prefix: &str) -> Result<Vec<(String, String)>, StoreError> {
        let d = self.dir.join("aliases");
        let mut out = Vec::new();
        for e in std::fs::read_dir(&d).map_err(io(&d))?.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if !name.starts_with(prefix) || name.starts_with(TMP_PREFIX) {
                continue;
            }
            if let Some(id) = self.alias(&name)? {
                out.push((name, id));
            }
        }
        out.sort();
        Ok(out)
    }

    /// Ids of the stored dictionaries, sorted.
    pub fn dictionary_ids(&self) -> Result<Vec<String>, StoreError> {
        self.list_ids("dictionaries", ".dict")
    }

    /// Deletes dictionary `id`; `false` when it was absent.
    pub fn delete_dictionary(&self, id: &str) -> Result<bool, StoreError> {
        remove_durably(&self.dictionary_path(id)?)
    }

    fn object_path(&self, kind: ObjectKind, id: &str) -> Result<PathBuf, StoreError> {
        Ok(self
            .dir
            .join(kind.dir())
            .join(format!("{}.obj", safe_name(id)?)))
    }

    /// Stores `payload` as an object of `kind`; returns its id (the hex SHA-256 of the envelope).
    /// Storing the same payload twice is a no-op.
    pub fn put_object(&self, kind: ObjectKind, payload: &[u8]) -> Result<String, StoreError> {
        let (bytes, id) = object::seal(kind, payload);
        let path = self.object_path(kind, &id)?;
        if !path.exists() {
            write_atomically(&path, &bytes)?;
        }
        Ok(id)
    }

    /// The verified payload of object `id` of `kind`; `Ok(None)` when absent.
    pub fn get_object(&self, kind: ObjectKind, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let path = self.object_path(kind, id)?;
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io(&path)(e)),
        };
        object::open(kind, &bytes, id).map(Some)
    }

    /// Ids of the stored objects of `kind`, sorted.
    pub fn object_ids(&self, kind: ObjectKind) -> Result<Vec<String>, StoreError> {
        self.list_ids(kind.dir(), ".obj")
    }

    /// Deletes object `id` of `kind`; `false` when it was absent.
    pub fn delete_object(&self, kind: ObjectKind, id: &str) -> Result<bool, StoreError> {
        remove_durably(&self.object_path(kind, id)?)
    }

    /// Writes (or rewrites) the record of job `id`.
    pub fn put_job(&self, id: &str, json: &[u8]) -> Result<(), StoreError> {
        let path = self
            .dir
            .join("jobs")
            .join(format!("{}.json", safe_name(id)?));
        write_atomically(&path, json)
    }

    /// Every job record `(id, bytes)`, sorted by id.
    pub fn jobs(&self) -> Result<Vec<(String, Vec<u8>)>, StoreError> {
        let mut out = Vec::new();
        for id in self.list_ids("jobs", ".json")? {
            let p = self.dir.join("jobs").join(format!("{id}.json"));
            match std::fs::read(&p) {
                Ok(b) => out.push((id, b)),
                Err(e) => {
                    tracing::warn!(path = %p.display(), error = %e, "store: unreadable job record")
                }
            }
        }
        Ok(out)
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

#[cfg(test)]
mod object_tests {
    use super::*;

    #[test]
    fn objects_round_trip_and_corruption_is_quarantined_on_open() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let a = store.put_object(ObjectKind::World, b"{\"a\":1}").unwrap();
        let b = store.put_object(ObjectKind::World, b"{\"b\":2}").unwrap();
        assert_eq!(
            store.put_object(ObjectKind::World, b"{\"a\":1}").unwrap(),
            a
        );
        assert_eq!(
            store.get_object(ObjectKind::World, &a).unwrap().unwrap(),
            b"{\"a\":1}"
        );
        assert!(store
            .get_object(ObjectKind::Exemplar, &a)
            .unwrap()
            .is_none());
        // Flip one payload byte of b: reopening moves it away and keeps a.
        let pb = dir.path().join("worlds").join(format!("{b}.obj"));
        let mut bytes = std::fs::read(&pb).unwrap();
        let n = bytes.len();
        bytes[n - 40] ^= 1;
        std::fs::write(&pb, bytes).unwrap();
        assert!(store.get_object(ObjectKind::World, &b).is_err());
        let store = Store::open(dir.path()).unwrap();
        assert_eq!(
            store.object_ids(ObjectKind::World).unwrap(),
            vec![a.clone()]
        );
        assert_eq!(dir.path().join("corrupt").read_dir().unwrap().count(), 1);
        assert!(store.delete_object(ObjectKind::World, &a).unwrap());
        assert!(!store.delete_object(ObjectKind::World, &a).unwrap());
        std::fs::write(dir.path().join("VERSION"), "terrasynth-store 99").unwrap();
        assert!(matches!(
            Store::open(dir.path()),
            Err(StoreError::Version { .. })
        ));
    }
}
