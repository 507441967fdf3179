//! Dictionaries: multi-resolution, multi-layer atoms cut from exemplars, their learning, their
//! versioned binary format, and matching of low-resolution input patches against them.

pub mod analytic;
pub mod any;
pub mod atoms;
pub mod build;
pub mod derive;
pub mod error;
pub mod exemplar;
pub mod features;
pub mod format;
pub mod gradient_format;
pub mod gradient_tiles;
pub mod ksvd;
pub mod matching;
pub mod omp;
pub mod rng;

pub use any::{read_any, AmplifierKind, AnyDictionary};
pub use atoms::{AtomSource, Dictionary, DictionaryParams, LayerInfo, LayerKind, Learning};
pub use build::{build, build_cancellable, BuildOptions, Exemplar};
pub use error::DictionaryError;
pub use exemplar::{no_species, ExemplarLayer, ExemplarOptions, PixelWindow};
pub use features::{box_down2, centre_normalise, patch_mean_slope, MIN_RELIEF_M};
pub use format::{content_id, from_bytes, read_dictionary, to_bytes, write_dictionary};
pub use gradient_tiles::{build_gradient_tiles, exemplar_plane, GradientParams, GradientTileSet};
pub use matching::{MatchWeights, Matcher};
pub use rng::{hash2, Rng};
