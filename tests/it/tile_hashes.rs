//! The default world's tiles are byte-identical to a committed list: the SHA-256 of 65 responses
//! (every layer and format — terrarium and mapbox PNG, `@2x`, EXR, hillshade with two suns,
//! vegetation channels, overlay and EXR, drainage PNG and EXR, splat set 1, colour — at zooms 6,
//! 8, 10, 12 and 14 over the Kyrgyz Ala-Too), first recorded before the workspace move with the
//! release binary of the previous layout. A change that alters any tile byte fails here; the list
//! is updated only with a change that means to alter the amplifier or a layer (say so in its
//! commit), and with it the tiles' revision that every ETag hashes
//! ([`terrasynth_tiles::TILE_BYTES_REVISION`], pinned to the list here). The check runs on the
//! second server of `e2e`'s determinism test, so it costs no extra start-up.

use sha2::{Digest, Sha256};

use crate::support::{proc, Server};

/// The committed list: `sha256 path` per line.
const LIST: &str = include_str!("../data/default_world_tiles.sha256");

/// Each revision of the tiles' bytes ([`terrasynth_tiles::TILE_BYTES_REVISION`], hashed into
/// every ETag) with the SHA-256 of the list that records it, oldest first. A change that rewrites
/// the list appends a row with the next revision and raises the constant to it.
const REVISIONS: &[(u32, &str)] = &[(
    1,
    "d5ca3b16fd55726947dcd4e103b87e8df5e90b09dc5b7c0f4b199cda0ed61c50",
)];

/// The list is the one recorded for the current revision, so a change that alters tile bytes
/// (and so the list) also changes every ETag: no client keeps a tile of the revision before on
/// a 304.
#[test]
fn the_hash_list_is_the_current_revisions() {
    let list: String = Sha256::digest(LIST.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let (revision, recorded) = *REVISIONS.last().expect("at least one revision");
    for (i, (r, _)) in REVISIONS.iter().enumerate() {
        assert_eq!(*r as usize, i + 1, "revisions count up from 1");
    }
    assert_eq!(
        revision,
        terrasynth_tiles::TILE_BYTES_REVISION,
        "the last revision recorded here is the tiles crate's"
    );
    assert_eq!(
        list,
        recorded,
        "the tile-hash list changed: raise terrasynth_tiles::TILE_BYTES_REVISION to {} and \
         append ({}, \"{list}\") to REVISIONS",
        revision + 1,
        revision + 1
    );
}

/// Fetches every tile of the list from `server` and compares the hashes.
pub fn assert_default_world_tiles(server: &Server) {
    let mut differ = Vec::new();
    let mut n = 0;
    for line in LIST.lines().filter(|l| !l.trim().is_empty()) {
        let (want, path) = line.split_once(' ').expect("`sha256 path` lines");
        let (status, body) = proc::get(server, path, None);
        assert_eq!(status, 200, "{path}");
        let got: String = Sha256::digest(&body)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        if got != want {
            differ.push(path.to_string());
        }
        n += 1;
    }
    assert!(n >= 60, "the list holds {n} tiles");
    assert!(
        differ.is_empty(),
        "tiles differ from the committed list: {differ:?}"
    );
}
