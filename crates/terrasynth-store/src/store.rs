//! The store itself: a directory of content-addressed objects, aliases and job records with
//! atomic writes (see the crate documentation for the layout). Opening it is cheap: it checks
//! the layout version (and refuses a non-empty directory that is not a store), removes leftovers
//! of interrupted writes, aliases whose object is gone and world objects no alias names. Objects
//! are verified against their checksum whenever they are read, and [`Store::verify`] checks one
//! without keeping it in memory (the catalogue runs it in the background after start).

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use terrasynth_core::dictionary::{self, AnyDictionary, Dictionary, DictionaryError};

use crate::error::StoreError;
use crate::object;

/// Largest dictionary (or gradient tile set) the store reads, bytes.
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

/// The kinds of stored things that have an id and can be verified and quarantined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stored {
    /// A dictionary (`dictionaries/{id}.dict`).
    Dictionary,
    /// An exemplar (`exemplars/{id}.obj`).
    Exemplar,
    /// A world definition (`worlds/{id}.obj`).
    World,
}

impl Stored {
    /// Every kind, in the order start-up verifies them.
    pub const ALL: [Stored; 3] = [Stored::World, Stored::Dictionary, Stored::Exemplar];

    fn dir(self) -> &'static str {
        match self {
            Stored::Dictionary => "dictionaries",
            Stored::Exemplar => "exemplars",
            Stored::World => "worlds",
        }
    }

    fn ext(self) -> &'static str {
        match self {
            Stored::Dictionary => ".dict",
            Stored::Exemplar | Stored::World => ".obj",
        }
    }

    /// The kind an alias names by its prefix (`exemplar.`, `dictionary.` and `world-`, `world.`),
    /// if it is one of ours.
    pub fn of_alias(alias: &str) -> Option<Stored> {
        if alias.starts_with("exemplar.") {
            Some(Stored::Exemplar)
        } else if alias.starts_with("dictionary.") || alias.starts_with("world-") {
            Some(Stored::Dictionary)
        } else if alias.starts_with("world.") {
            Some(Stored::World)
        } else {
            None
        }
    }
}

const SUBDIRS: [&str; 7] = [
    "dictionaries",
    "aliases",
    "exemplars",
    "worlds",
    "jobs",
    "uploads",
    "landscape",
];

/// Bytes read at a time when verifying an object.
const VERIFY_CHUNK: usize = 1 << 20;

/// A temporary file path beside `path` (same directory, so that a rename is atomic), named so
/// that opening the store removes it if it is left behind.
fn temp_beside(dir: &Path, name: &str) -> PathBuf {
    static SEQ: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let seq = SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    dir.join(format!("{TMP_PREFIX}{name}-{}-{seq}", std::process::id()))
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
    write_atomically_with(path, |f| f.write_all(bytes).map_err(io(path)))
}

/// Writes `path` atomically with `write`, which writes the whole file into a buffered temporary
/// file in the same directory; then fsync, rename, fsync of the directory. Whatever happens
/// before the rename (an error of `write` or of the disk, a crash), `path` keeps what it held,
/// or stays absent; on an error the temporary file is removed.
pub fn write_atomically_with<E: From<StoreError>>(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<(), E>,
) -> Result<(), E> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "object".into());
    let tmp = temp_beside(parent_dir(path), &name);
    write_atomically_via(&tmp, path, write)
}

/// [`write_atomically_with`] through the temporary file `tmp`, which the caller names (it must
/// be in `path`'s directory, so that the rename is atomic).
pub fn write_atomically_via<E: From<StoreError>>(
    tmp: &Path,
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<(), E>,
) -> Result<(), E> {
    let dir = parent_dir(path);
    // Errors name `path`, the file the caller asked for, not the temporary one.
    let file = std::fs::File::create(tmp).map_err(io(path))?;
    let mut out = std::io::BufWriter::new(file);
    let written = write(&mut out).and_then(|()| {
        let file = out.into_inner().map_err(|e| io(path)(e.into_error()))?;
        file.sync_all().map_err(io(path))?;
        drop(file);
        std::fs::rename(tmp, path).map_err(io(path))?;
        Ok(())
    });
    if written.is_err() {
        let _ = std::fs::remove_file(tmp);
        return written;
    }
    sync_dir(dir);
    Ok(())
}

/// The directory `path` is in (`.` for a bare name).
fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
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
    /// Opens (creating if needed) the store at `dir`: checks its format version (a non-empty
    /// directory without `VERSION` is not a store and is refused), removes leftovers of
    /// interrupted writes, aliases whose object is gone and world objects no alias names. It
    /// reads no object: objects are verified when read, and by [`Store::verify`].
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
                let mut entries = std::fs::read_dir(dir).map_err(io(dir))?;
                if entries.next().is_some() {
                    return Err(StoreError::NotAStore(dir.display().to_string()));
                }
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
        store.remove_dangling_aliases()?;
        store.remove_orphaned_worlds()?;
        Ok(store)
    }

    fn path_of(&self, kind: Stored, id: &str) -> Result<PathBuf, StoreError> {
        Ok(self
            .dir
            .join(kind.dir())
            .join(format!("{}{}", safe_name(id)?, kind.ext())))
    }

    /// Removes the aliases of our kinds whose object does not exist (removed, quarantined, or
    /// never written because a process died in between).
    fn remove_dangling_aliases(&self) -> Result<(), StoreError> {
        for (alias, id) in self.aliases("")? {
            let Some(kind) = Stored::of_alias(&alias) else {
                continue;
            };
            let exists = self.path_of(kind, &id).map(|p| p.exists()).unwrap_or(false);
            if !exists {
                tracing::warn!(alias = %alias, id = %id, "store: alias of a missing object removed");
                self.remove_alias(&alias)?;
            }
        }
        Ok(())
    }

    /// Removes world definitions no `world.` alias names (left by a process that died between
    /// writing the definition and its alias, or by a deletion that died half-way).
    fn remove_orphaned_worlds(&self) -> Result<(), StoreError> {
        let named: std::collections::BTreeSet<String> = self
            .aliases("world.")?
            .into_iter()
            .map(|(_, id)| id)
            .collect();
        for id in self.ids(Stored::World)? {
            if !named.contains(&id) {
                tracing::warn!(world = %id, "store: orphaned world definition removed");
                remove_durably(&self.path_of(Stored::World, &id)?)?;
            }
        }
        Ok(())
    }

    /// Ids of the stored objects of `kind`, sorted.
    pub fn ids(&self, kind: Stored) -> Result<Vec<String>, StoreError> {
        self.list_ids(kind.dir(), kind.ext())
    }

    /// Verifies object `id` of `kind` against its checksum (and its id), reading it in chunks so
    /// that an object of any size is checked in constant memory; `Ok(false)` when it is absent.
    pub fn verify(&self, kind: Stored, id: &str) -> Result<bool, StoreError> {
        match kind {
            Stored::Dictionary => self.get_any_dictionary(id).map(|d| d.is_some()),
            Stored::Exemplar | Stored::World => {
                let okind = if kind == Stored::World {
                    ObjectKind::World
                } else {
                    ObjectKind::Exemplar
                };
                let path = self.path_of(kind, id)?;
                let f = match std::fs::File::open(&path) {
                    Ok(f) => f,
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
                    Err(e) => return Err(io(&path)(e)),
                };
                let len = f.metadata().map_err(io(&path))?.len();
                object::verify_stream(
                    okind,
                    std::io::BufReader::with_capacity(VERIFY_CHUNK, f),
                    len,
                    id,
                )?;
                Ok(true)
            }
        }
    }

    /// Moves object `id` of `kind` to `corrupt/` (logging `why`) and removes every alias naming
    /// it, so that nothing points at an object that is not served.
    pub fn quarantine(&self, kind: Stored, id: &str, why: &StoreError) -> Result<(), StoreError> {
        let file = format!("{}{}", safe_name(id)?, kind.ext());
        self.quarantine_file(kind.dir(), &file, why)?;
        for (alias, target) in self.aliases("")? {
            if target == id {
                tracing::warn!(alias = %alias, "store: alias of a quarantined object removed");
                self.remove_alias(&alias)?;
            }
        }
        Ok(())
    }

    fn quarantine_file(
        &self,
        sub: &str,
        file: &str,
        why: &dyn std::fmt::Display,
    ) -> Result<(), StoreError> {
        tracing::warn!(object = %format!("{sub}/{file}"), error = %why, "store: unusable file moved to corrupt/");
        let dst_dir = self.dir.join("corrupt");
        std::fs::create_dir_all(&dst_dir).map_err(io(&dst_dir))?;
        let src = self.dir.join(sub).join(file);
        let dst = dst_dir.join(format!("{sub}-{file}"));
        match std::fs::rename(&src, &dst) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(io(&src)(e)),
        }
        sync_dir(&self.dir.join(sub));
        Ok(())
    }

    /// Moves the record of job `id` to `corrupt/` (it cannot be read or parsed).
    pub fn quarantine_job(&self, id: &str, why: &dyn std::fmt::Display) -> Result<(), StoreError> {
        self.quarantine_file("jobs", &format!("{}.json", safe_name(id)?), why)
    }

    /// A new temporary file for an upload body arriving, in `uploads/` (removed by whoever
    /// created it once done, or when the store is next opened).
    pub fn spool_file(&self) -> Result<(std::fs::File, PathBuf), StoreError> {
        let path = temp_beside(&self.dir.join("uploads"), "upload");
        let f = std::fs::File::create_new(&path).map_err(io(&path))?;
        Ok((f, path))
    }

    /// Stores an object of `kind` whose payload of `len` bytes `fill` writes, streaming it to
    /// its file (hashing as it goes) instead of assembling it in memory; returns its id. Storing
    /// an object that exists is a no-op.
    pub fn put_object_streamed(
        &self,
        kind: ObjectKind,
        len: u64,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<String, StoreError> {
        let dir = self.dir.join(kind.dir());
        let tmp = temp_beside(&dir, "object");
        let written = (|| -> Result<String, StoreError> {
            let f = std::fs::File::create_new(&tmp).map_err(io(&tmp))?;
            let mut sealer = object::SealWriter::new(
                kind,
                len,
                std::io::BufWriter::with_capacity(VERIFY_CHUNK, f),
            )
            .map_err(io(&tmp))?;
            fill(&mut sealer).map_err(io(&tmp))?;
            let (buffered, id) = sealer.finish().map_err(io(&tmp))?;
            let f = buffered
                .into_inner()
                .map_err(|e| io(&tmp)(e.into_error()))?;
            f.sync_all().map_err(io(&tmp))?;
            Ok(id)
        })();
        let id = match written {
            Ok(id) => id,
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                return Err(e);
            }
        };
        let path = self.object_path(kind, &id)?;
        if path.exists() {
            remove_durably(&tmp)?;
        } else {
            std::fs::rename(&tmp, &path).map_err(io(&path))?;
            sync_dir(&dir);
        }
        Ok(id)
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
        self.put_dictionary_bytes(&id, &bytes)?;
        Ok(id)
    }

    /// Stores a dictionary or a gradient tile set (both live in `dictionaries/`, told apart by
    /// their magic); returns its content id. Storing the same file twice is a no-op.
    pub fn put_any_dictionary(&self, d: &AnyDictionary) -> Result<String, StoreError> {
        let bytes = d.to_bytes()?;
        let id = d.content_id()?;
        self.put_dictionary_bytes(&id, &bytes)?;
        Ok(id)
    }

    fn put_dictionary_bytes(&self, id: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let path = self.dictionary_path(id)?;
        if !path.exists() {
            write_atomically(&path, bytes)?;
        }
        Ok(())
    }

    /// Reads and verifies dictionary `id`; `Ok(None)` when absent. A gradient tile set stored
    /// under `id` is an error ([`Store::get_any_dictionary`] reads either).
    pub fn get_dictionary(&self, id: &str) -> Result<Option<Dictionary>, StoreError> {
        match self.get_any_dictionary(id)? {
            None => Ok(None),
            Some(AnyDictionary::Dictionary(d)) => Ok(Some(Arc::unwrap_or_clone(d))),
            Some(AnyDictionary::Gradient(_)) => Err(StoreError::Corrupt {
                id: id.to_string(),
                source: DictionaryError::Malformed(
                    "it is a gradient tile set, not a dictionary".into(),
                ),
            }),
        }
    }

    /// Reads and verifies dictionary or gradient tile set `id` (by its magic); `Ok(None)` when
    /// absent.
    pub fn get_any_dictionary(&self, id: &str) -> Result<Option<AnyDictionary>, StoreError> {
        let path = self.dictionary_path(id)?;
        let f = match std::fs::File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io(&path)(e)),
        };
        let d = dictionary::read_any(std::io::BufReader::new(f), MAX_DICTIONARY_BYTES).map_err(
            |source| StoreError::Corrupt {
                id: id.to_string(),
                source,
            },
        )?;
        let actual = d.content_id()?;
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

    fn landscape_path(&self, world: &str) -> Result<PathBuf, StoreError> {
        Ok(self
            .dir
            .join("landscape")
            .join(format!("{}.layers", safe_name(world)?)))
    }

    /// The stored whole-world layers of world `world` (`landscape/{world}.layers`, written by
    /// [`Store::put_landscape`]); `Ok(None)` when absent. A derived cache: the bytes carry their
    /// own key and checksum, which the reader checks (`terrasynth_tiles::layer_file`).
    pub fn get_landscape(&self, world: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let path = self.landscape_path(world)?;
        match std::fs::read(&path) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io(&path)(e)),
        }
    }

    /// Stores the whole-world layers of world `world` atomically, replacing earlier ones.
    pub fn put_landscape(&self, world: &str, bytes: &[u8]) -> Result<(), StoreError> {
        write_atomically(&self.landscape_path(world)?, bytes)
    }

    /// Deletes the stored whole-world layers of world `world`; `false` when there were none.
    pub fn delete_landscape(&self, world: &str) -> Result<bool, StoreError> {
        remove_durably(&self.landscape_path(world)?)
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

    /// The first (at most `max`) payload bytes of object `id` of `kind`, after checking the
    /// envelope's magic, kind, version and length against the file — but not its checksum (see
    /// [`Store::verify`]): for reading a header without reading a large payload. `Ok(None)` when
    /// absent.
    pub fn object_head(
        &self,
        kind: ObjectKind,
        id: &str,
        max: usize,
    ) -> Result<Option<Vec<u8>>, StoreError> {
        let path = self.object_path(kind, id)?;
        let f = match std::fs::File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io(&path)(e)),
        };
        let len = f.metadata().map_err(io(&path))?.len();
        let mut head = Vec::new();
        f.take(object::PREFIX as u64 + max as u64)
            .read_to_end(&mut head)
            .map_err(io(&path))?;
        object::open_head(kind, &head, len, id).map(Some)
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

    /// Every job record `(id, bytes)`, sorted by id; a record that cannot be read is moved to
    /// `corrupt/`.
    pub fn jobs(&self) -> Result<Vec<(String, Vec<u8>)>, StoreError> {
        let mut out = Vec::new();
        for id in self.list_ids("jobs", ".json")? {
            let p = self.dir.join("jobs").join(format!("{id}.json"));
            match std::fs::read(&p) {
                Ok(b) => out.push((id, b)),
                Err(e) => self.quarantine_job(&id, &e)?,
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn landscape_layers_are_stored_replaced_and_deleted_by_world_name() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        assert_eq!(store.get_landscape("alps").unwrap(), None);
        store.put_landscape("alps", b"first").unwrap();
        store.put_landscape("alps", b"second").unwrap();
        store.put_landscape("andes", b"other").unwrap();
        assert_eq!(
            store.get_landscape("alps").unwrap().as_deref(),
            Some(&b"second"[..])
        );
        // An interrupted write's leftover goes at the next open; the stored copy stays.
        let leftover = dir.path().join("landscape").join(".tmp-alps.layers-9-0");
        std::fs::write(&leftover, b"part").unwrap();
        let store = Store::open(dir.path()).unwrap();
        assert!(!leftover.exists());
        assert!(store.delete_landscape("alps").unwrap());
        assert!(!store.delete_landscape("alps").unwrap());
        assert_eq!(store.get_landscape("alps").unwrap(), None);
        assert_eq!(
            store.get_landscape("andes").unwrap().as_deref(),
            Some(&b"other"[..])
        );
        assert!(matches!(
            store.put_landscape("../x", b"no"),
            Err(StoreError::BadName(_))
        ));
    }

    /// A file written with `write_atomically_with` whose writer fails half-way keeps its old
    /// bytes, and nothing else is left in the directory; one that succeeds is replaced whole.
    #[test]
    fn failed_atomic_write_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.tif");
        write_atomically(&path, b"old bytes").unwrap();
        let failed = write_atomically_with(&path, |f| {
            f.write_all(&[7u8; 100_000]).map_err(io(&path))?;
            Err(StoreError::BadName("the writer failed".into()))
        });
        assert!(matches!(failed, Err(StoreError::BadName(_))));
        assert_eq!(std::fs::read(&path).unwrap(), b"old bytes");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.tif")]);
        write_atomically_with(&path, |f| f.write_all(b"new").map_err(io(&path))).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        // A missing file stays missing when the writer fails.
        let absent = dir.path().join("absent.tif");
        let _ = write_atomically_with(&absent, |_| Err(StoreError::BadName("no".into())));
        assert!(!absent.exists());
        // Errors name the file asked for, not the temporary one.
        let missing = dir.path().join("no-such-dir").join("x.tif");
        let e = write_atomically(&missing, b"x").unwrap_err().to_string();
        assert!(e.contains(&missing.display().to_string()), "{e}");
    }

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

    /// Flips one payload byte of object `id` of `kind`.
    fn corrupt(dir: &Path, kind: Stored, id: &str) {
        let p = dir.join(kind.dir()).join(format!("{id}{}", kind.ext()));
        let mut bytes = std::fs::read(&p).unwrap();
        let n = bytes.len();
        bytes[n - 40] ^= 1;
        std::fs::write(&p, bytes).unwrap();
    }

    #[test]
    fn objects_round_trip_and_corruption_is_quarantined_with_its_aliases() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let a = store
            .put_object(ObjectKind::Exemplar, b"{\"a\":1}")
            .unwrap();
        let b = store
            .put_object(ObjectKind::Exemplar, b"{\"b\":2}")
            .unwrap();
        assert_eq!(
            store
                .put_object(ObjectKind::Exemplar, b"{\"a\":1}")
                .unwrap(),
            a
        );
        let streamed = store
            .put_object_streamed(ObjectKind::Exemplar, 7, |w| w.write_all(b"{\"a\":1}"))
            .unwrap();
        assert_eq!(streamed, a, "streaming and sealing in memory agree");
        assert_eq!(
            store.get_object(ObjectKind::Exemplar, &a).unwrap().unwrap(),
            b"{\"a\":1}"
        );
        assert!(store.get_object(ObjectKind::World, &a).unwrap().is_none());
        assert!(store.verify(Stored::Exemplar, &a).unwrap());
        store.set_alias("exemplar.bee", &b).unwrap();
        // Flip one payload byte of b: reading or verifying it fails; quarantining moves it away
        // with its alias and keeps a.
        corrupt(dir.path(), Stored::Exemplar, &b);
        assert!(store.get_object(ObjectKind::Exemplar, &b).is_err());
        let e = store.verify(Stored::Exemplar, &b).unwrap_err();
        store.quarantine(Stored::Exemplar, &b, &e).unwrap();
        assert_eq!(
            store.object_ids(ObjectKind::Exemplar).unwrap(),
            vec![a.clone()]
        );
        assert_eq!(store.alias("exemplar.bee").unwrap(), None);
        assert_eq!(dir.path().join("corrupt").read_dir().unwrap().count(), 1);
        assert!(store.delete_object(ObjectKind::Exemplar, &a).unwrap());
        assert!(!store.delete_object(ObjectKind::Exemplar, &a).unwrap());
        std::fs::write(dir.path().join("VERSION"), "terrasynth-store 99").unwrap();
        assert!(matches!(
            Store::open(dir.path()),
            Err(StoreError::Version { .. })
        ));
    }

    #[test]
    fn opening_repairs_aliases_and_orphans_and_refuses_foreign_directories() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let named = store.put_object(ObjectKind::World, b"{\"w\":1}").unwrap();
        let orphan = store.put_object(ObjectKind::World, b"{\"w\":2}").unwrap();
        store.set_alias("world.named", &named).unwrap();
        store.set_alias("exemplar.gone", &"ab".repeat(32)).unwrap();
        store
            .set_alias("dictionary.gone", &"cd".repeat(32))
            .unwrap();
        store
            .set_alias("world-configured-x", &"ef".repeat(32))
            .unwrap();
        let leftover = dir.path().join("uploads").join(".tmp-upload-1-1");
        std::fs::write(&leftover, b"half a body").unwrap();
        let store = Store::open(dir.path()).unwrap();
        assert_eq!(store.ids(Stored::World).unwrap(), vec![named.clone()]);
        assert!(!dir
            .path()
            .join("worlds")
            .join(format!("{orphan}.obj"))
            .exists());
        assert_eq!(
            store.aliases("").unwrap(),
            vec![("world.named".to_string(), named)]
        );
        assert!(!leftover.exists());
        // A directory holding anything but a store is refused, and left as it was.
        let foreign = tempfile::tempdir().unwrap();
        std::fs::write(foreign.path().join("notes.txt"), b"mine").unwrap();
        assert!(matches!(
            Store::open(foreign.path()),
            Err(StoreError::NotAStore(_))
        ));
        assert!(!foreign.path().join("VERSION").exists());
        assert_eq!(foreign.path().read_dir().unwrap().count(), 1);
    }
}
