//! Amplification: one ×2 level on a global lattice of primitives ([`level`]) with its switches
//! ([`levers`]) and up-sampling kernels ([`kernel`]), the windows and fields it works on
//! ([`field`]), and chains of levels from a base ([`chain`]) with a dictionary per zoom band ([`bands`]); the gradient-domain level ([`gradient`], its
//! precomputed Poisson reconstruction [`gradient_solve`]); compact terrains on the same
//! lattice (sparse construction trees, [`compact`], and their file format, [`compact_format`]);
//! and sketch synthesis, which makes a base from ridge and valley lines ([`sketch`]). Everything
//! is a
//! pure function of the parent values, the dictionary and the requested pixels: no caching, no
//! HTTP, no dependence on thread count.

pub mod bands;
pub mod baselines;
pub mod chain;
pub mod compact;
pub mod compact_format;
pub mod error;
pub mod field;
pub mod gradient;
pub mod gradient_solve;
pub mod kernel;
pub mod level;
pub mod levers;
pub mod sketch;

pub use bands::{band_for, check_bands, BandError, ZoomBand};
pub use chain::{amplify_chain, chain_windows, AnyAmplifier, BaseSource, ClampedRaster, Level};
pub use error::SynthError;
pub use field::{Field, Window};
pub use gradient::GradientAmplifier;
pub use kernel::KernelKind;
pub use level::{Amplifier, LayerAtoms};
pub use levers::Levers;
pub use levers::{DEFAULT_AMPLIFY_SPARSITY, MAX_AMPLIFY_SPARSITY};
