//! terrasynth: synthesized terrain, real at coarse scale and detailed at any zoom.
//!
//! The library holds the synchronous, deterministic pipeline — [`raster`] (grids and files),
//! [`analysis`] (terrain derivatives, flow routing, realism metrics), [`dictionary`] (multi-layer
//! dictionaries of exemplar patches and matching), [`synth`] (one ×2 amplification level and level
//! chains) — plus the command line's building blocks in [`cli`]. See `ARCHITECTURE.md`.
#![deny(missing_docs)]

pub mod analysis;
pub mod cli;
pub mod config;
pub mod dictionary;
pub mod landscape;
pub mod raster;
pub mod server;
pub mod store;
pub mod synth;
pub mod tiles;
