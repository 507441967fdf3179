//! Dictionaries: multi-resolution, multi-layer atoms cut from exemplars, their learning, their
//! versioned binary format, and matching of low-resolution input patches against them.

pub mod atoms;
pub mod features;
pub mod matching;

pub use atoms::{AtomSource, Dictionary, DictionaryParams, LayerInfo, LayerKind, Learning};
pub use matching::{MatchWeights, Matcher};
