//! Errors of the amplifier.

use thiserror::Error;

use crate::dictionary::matching::MatchError;

/// An error setting up or running amplification.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SynthError {
    /// The matching weights do not fit the dictionary.
    #[error(transparent)]
    Match(#[from] MatchError),
    /// The dictionary's patch size cannot be used on a lattice.
    #[error("dictionary patch size {0} is not usable: it must be a multiple of 4, at least 8")]
    PatchSize(usize),
    /// The parent field given does not cover the window the output needs.
    #[error("parent window {given} does not cover the required {needed}")]
    ParentTooSmall {
        /// The window that was given.
        given: String,
        /// The window needed.
        needed: String,
    },
    /// The requested output is empty or too large.
    #[error("invalid output window: {0}")]
    BadWindow(String),
    /// A parent value is NaN or infinite.
    #[error("parent field holds non-finite values")]
    NonFinite,
}
