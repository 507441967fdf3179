//! The on-disk store ([`store`]) and the catalogue service over it ([`service`]: the admin API's
//! rules without HTTP — the in-memory [`catalog`], build and sketch [`jobs`], upload decoding in
//! [`ingest`] within a memory [`budget`], world definitions in [`worlds`], sketch worlds in
//! [`sketch`]).
//!
//! The store holds content-addressed, immutable objects — exemplars, dictionaries and world
//! definitions, each named by the hex SHA-256 of its canonical bytes — human-name aliases, and
//! job records. Every write goes to a temporary file in the same directory, is fsynced and
//! renamed, then the directory is fsynced, so a crash never leaves a partial object under a final
//! name; large objects are streamed to their file, never assembled in memory. Opening the store
//! refuses a non-empty directory that is not a store, removes leftovers of interrupted writes,
//! aliases of missing objects and world definitions no alias names; every read of an object
//! verifies its checksum, and the catalogue service verifies every object after start (exemplars
//! on a background thread), moving a corrupted one to `corrupt/` with its aliases removed, so it
//! is never served. An unreadable job record is moved to `corrupt/` too.
//!
//! Layout (format version [`STORE_VERSION`], written to `VERSION`):
//!
//! | path | content |
//! | --- | --- |
//! | `VERSION` | `terrasynth-store 1` |
//! | `dictionaries/{id}.dict` | a dictionary in `dictionary::format` (its id is its checksum) |
//! | `exemplars/{id}.obj`, `worlds/{id}.obj` | an object envelope ([`object`]): magic, kind, version, payload, SHA-256 |
//! | `aliases/{name}` | the id an alias points at (`exemplar.N`, `dictionary.N`, `world.N`; `world-…` for configured worlds' dictionaries) |
//! | `jobs/{id}.json` | the record of a dictionary build or sketch job (rewritten atomically) |
//! | `uploads/` | upload bodies being received (temporary, removed once decoded) |
//! | `landscape/{world}.layers` | a world's whole-world landscape layers, a cache the server rewrites when its key (inputs and build) changes (`terrasynth_tiles::layer_file`) |
//! | `corrupt/` | objects that failed verification, unreadable job records |

pub mod budget;
pub mod catalog;
pub mod error;
pub mod exemplar;
pub mod ingest;
pub mod jobs;
pub mod object;
pub mod service;
pub mod sketch;
pub mod store;
pub mod time;
pub mod worlds;

pub use budget::{MemoryBudget, Reservation};
pub use catalog::{Catalog, DictionaryInfo, ExemplarInfo, Statistics};
pub use error::{ServiceError, StoreError};
pub use jobs::{DictionaryRequest, Job, JobRequest, JobSettings, JobState};
pub use service::{Catalogue, ResolvedBiome, ResolvedDictionary, ResolvedWorld};
pub use sketch::SketchRequest;
pub use store::{
    write_atomically, write_atomically_via, write_atomically_with, ObjectKind, Store, Stored,
    MAX_DICTIONARY_BYTES, STORE_VERSION,
};
pub use worlds::{
    DictionaryBandRef, WorldBiomeRef, WorldControlRef, WorldDefaults, WorldDefinition,
    WorldDictionary, WorldRequest,
};
