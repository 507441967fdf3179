//! The default world's tiles are byte-identical to a committed list: the SHA-256 of 65 responses
//! (every layer and format — terrarium and mapbox PNG, `@2x`, EXR, hillshade with two suns,
//! vegetation channels, overlay and EXR, drainage PNG and EXR, splat set 1, colour — at zooms 6,
//! 8, 10, 12 and 14 over the Kyrgyz Ala-Too), recorded before the workspace move with the
//! release binary of the previous layout. A change that alters any tile byte fails here; the list
//! is updated only with a change that means to alter the amplifier or a layer (say so in its
//! commit). The check runs on the second server of `e2e`'s determinism test, so it costs no
//! extra start-up.

use sha2::{Digest, Sha256};

use crate::support::{proc, Server};

/// The committed list: `sha256 path` per line.
const LIST: &str = include_str!("../data/default_world_tiles.sha256");

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
