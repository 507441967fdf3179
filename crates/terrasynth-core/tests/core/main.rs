//! The core crate's integration tests, in one binary (one link instead of five):
//!
//! - [`analysis`]: derivatives, flood filling, flow routing and the FFT against naive twins;
//! - [`dictionary`]: building, learning, the format (round trips, every truncation and flip);
//! - [`gradient`]: gradient tile sets, their format, the reconstruction against its dense
//!   solve, the gradient amplifier's invariants;
//! - [`matching`]: the fast matcher against the naive scan, orientation preservation;
//! - [`ppa`]: ridges and valleys against their naive twins, and against D8 drainage;
//! - [`raster_io`]: every GeoTIFF variant, PNG16 and EXR round trips, bad files;
//! - [`sketch`]: sketch synthesis and its kernels (distance transform, FFT SSD, graph cut,
//!   Poisson) against naive twins; a sketch world's acceptance figures;
//! - [`synth`]: window invariance, thread-count independence, zoom consistency.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod analysis;
mod dictionary;
mod gradient;
mod matching;
mod ppa;
mod projected;
mod raster_io;
mod sketch;
mod synth;
