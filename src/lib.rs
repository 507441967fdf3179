//! terrasynth: the tile server and command line over the pipeline crates. [`config`] loads the
//! server and world settings, [`server`] is the HTTP API (axum) and [`cli`] holds the command
//! line's commands as library functions, [`archive`] the PMTiles and MBTiles formats of `export`; `main.rs` parses arguments and calls them. The layers
//! below live in their own crates: `terrasynth-core` (the numeric pipeline), `terrasynth-tiles`
//! (pyramids, renderers, encoders) and `terrasynth-store` (the on-disk store and its rules). See
//! `ARCHITECTURE.md`.

pub mod archive;
pub mod cli;
pub mod config;
pub mod server;
