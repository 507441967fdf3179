//! The command line's commands as library functions, so that they can be tested without a
//! process: `dictionary build`, `amplify`, `eval`, `crop`, `compress` and `decompress`. `src/main.rs` only parses arguments
//! and calls these.

#![warn(clippy::arithmetic_side_effects)]

pub mod amplify;
pub mod build;
pub mod compact;
pub mod crop;
pub mod error;
pub mod eval;

pub use error::CliError;
