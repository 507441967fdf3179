//! The core crate's integration tests, in one binary (one link instead of five):
//!
//! - [`analysis`]: derivatives, flood filling, flow routing and the FFT against naive twins;
//! - [`dictionary`]: building, learning, the format (round trips, every truncation and flip);
//! - [`matching`]: the fast matcher against the naive scan, orientation preservation;
//! - [`raster_io`]: every GeoTIFF variant, PNG16 and EXR round trips, bad files;
//! - [`synth`]: window invariance, thread-count independence, zoom consistency.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod analysis;
mod dictionary;
mod matching;
mod raster_io;
mod synth;
