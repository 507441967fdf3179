//! What an amplification band is built on: a dictionary (TSDICT) or a gradient tile set
//! (TSGRAD), told apart by the file's magic ([`read_any`]), and the amplifier kind a world names
//! for a band (`amplifier = "dictionary" | "gradient"`, [`AmplifierKind`]).

use std::io::Read;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::error::DictionaryError;
use super::{format, gradient_format, Dictionary, GradientTileSet};

/// The amplifier of a zoom band: dictionary matching or gradient tiles (issue #20).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AmplifierKind {
    /// Dictionary matching (a TSDICT file).
    #[default]
    Dictionary,
    /// Gradient tiles with the precomputed Poisson reconstruction (a TSGRAD file).
    Gradient,
}

impl AmplifierKind {
    /// The name used in world files and the admin API.
    pub fn as_str(self) -> &'static str {
        match self {
            AmplifierKind::Dictionary => "dictionary",
            AmplifierKind::Gradient => "gradient",
        }
    }

    /// Whether this is the default kind (not written into stored definitions).
    pub fn is_default(&self) -> bool {
        *self == AmplifierKind::Dictionary
    }

    /// What a file of this kind is called in messages.
    pub fn file_noun(self) -> &'static str {
        match self {
            AmplifierKind::Dictionary => "a dictionary",
            AmplifierKind::Gradient => "a gradient tile set",
        }
    }
}

impl std::fmt::Display for AmplifierKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A dictionary or a gradient tile set.
#[derive(Clone, Debug)]
pub enum AnyDictionary {
    /// A dictionary.
    Dictionary(Arc<Dictionary>),
    /// A gradient tile set.
    Gradient(Arc<GradientTileSet>),
}

impl AnyDictionary {
    /// The amplifier kind this file serves.
    pub fn kind(&self) -> AmplifierKind {
        match self {
            AnyDictionary::Dictionary(_) => AmplifierKind::Dictionary,
            AnyDictionary::Gradient(_) => AmplifierKind::Gradient,
        }
    }

    /// The content id (hex SHA-256 ending the file).
    pub fn content_id(&self) -> Result<String, DictionaryError> {
        match self {
            AnyDictionary::Dictionary(d) => format::content_id(d),
            AnyDictionary::Gradient(g) => gradient_format::content_id(g),
        }
    }

    /// The canonical bytes of the file.
    pub fn to_bytes(&self) -> Result<Vec<u8>, DictionaryError> {
        match self {
            AnyDictionary::Dictionary(d) => format::to_bytes(d),
            AnyDictionary::Gradient(g) => gradient_format::to_bytes(g),
        }
    }

    /// This file, if it is of kind `want`; otherwise a message naming both kinds, e.g.
    /// "`X` is a dictionary, but the band's amplifier is gradient".
    pub fn expect(self, want: AmplifierKind, what: &str) -> Result<Self, String> {
        if self.kind() == want {
            Ok(self)
        } else {
            Err(format!(
                "{what} is {}, but the amplifier is \"{want}\" (it needs {})",
                self.kind().file_noun(),
                want.file_noun()
            ))
        }
    }
}

impl From<Arc<Dictionary>> for AnyDictionary {
    fn from(d: Arc<Dictionary>) -> Self {
        AnyDictionary::Dictionary(d)
    }
}

impl From<Arc<GradientTileSet>> for AnyDictionary {
    fn from(g: Arc<GradientTileSet>) -> Self {
        AnyDictionary::Gradient(g)
    }
}

/// Reads a dictionary or a gradient tile set (by the first 8 bytes), refusing files larger than
/// `max_bytes`. A stream shorter than the magic goes to the dictionary reader, which names the
/// problem.
pub fn read_any<R: Read>(mut r: R, max_bytes: u64) -> Result<AnyDictionary, DictionaryError> {
    let mut magic = [0u8; 8];
    let mut got = 0;
    while got < magic.len() {
        match r.read(&mut magic[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    let whole = std::io::Cursor::new(magic[..got].to_vec()).chain(r);
    if gradient_format::is_gradient(&magic[..got]) {
        let set = gradient_format::read_gradient_tiles(whole, max_bytes)?;
        return Ok(AnyDictionary::Gradient(Arc::new(set)));
    }
    let d = format::read_dictionary(whole, max_bytes)?;
    Ok(AnyDictionary::Dictionary(Arc::new(d)))
}
