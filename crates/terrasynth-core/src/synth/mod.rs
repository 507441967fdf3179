//! Amplification: one ×2 level on a global lattice of primitives ([`level`]), the windows and
//! fields it works on ([`field`]), and chains of levels from a base ([`chain`]); and sketch
//! synthesis, which makes a base from ridge and valley lines ([`sketch`]). Everything is a
//! pure function of the parent values, the dictionary and the requested pixels: no caching, no
//! HTTP, no dependence on thread count.

pub mod baselines;
pub mod chain;
pub mod error;
pub mod field;
pub mod level;
pub mod sketch;

pub use chain::{amplify_chain, chain_windows, BaseSource, ClampedRaster};
pub use error::SynthError;
pub use field::{Field, Window};
pub use level::Amplifier;
