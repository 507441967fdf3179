//! The command line's commands as library functions, so that they can be tested without a
//! process: `dictionary build` (`--kind gradient`: [`gradient`]), `amplify`, `eval`, `crop`, `compress`, `decompress`, `features`, `sketch` and `export`. `src/main.rs` only parses arguments
//! and calls these.

#![warn(clippy::arithmetic_side_effects)]

pub mod amplify;
pub mod build;
pub mod compact;
pub mod crop;
pub mod error;
pub mod eval;
pub mod export;
pub mod features;
pub mod gradient;
pub mod output;
pub mod sketch;

pub use error::CliError;
