//! The root package's integration tests, in one binary (one link instead of seven):
//!
//! - [`server`]: the HTTP API on the real router via `oneshot` and the tile invariants of a
//!   synthetic world (seamlessness, zoom consistency, determinism) for every layer;
//! - [`admin`]: the admin API and catalogue via `oneshot` with a store in a temporary directory;
//! - [`web`]: the web map's routes;
//! - [`openapi`]: the committed OpenAPI description equals the generated one;
//! - [`cli`]: the command line (the real binary);
//! - [`gradient_cli`]: the gradient amplifier on the command line (#20): build, amplify,
//!   determinism, consistency, bad parameters;
//! - [`sketch`]: feature extraction and sketch synthesis: `features` and `sketch` on the real
//!   binary;
//! - [`e2e`]: `terrasynth serve` on a real socket on the default world;
//! - [`admin_e2e`]: the admin flow, restarts and crashes on the real binary;
//! - [`hardening`]: one test per defect of issue #14 (bounded under abuse, one error shape,
//!   strict parsing, store hygiene, failed authentication);
//! - [`instances`]: instance tiles (#17): a tile alone is the window of a block, distances across
//!   borders, coherence with the layers and the ground, counts following the density;
//! - [`tile_hashes`]: the default world's tiles are byte-identical to a committed list;
//! - [`coverage`]: overlays are transparent exactly outside a small base and in its hole (#15);
//! - [`classes`]: land-cover classes (#15): splat weights following a class raster by pixel,
//!   bad control rasters refused with 422 on the real binary;
//! - [`biomes`]: painted biomes (#15): a biome painted everywhere serves its world's tiles bit
//!   for bit, seams across a painted boundary, determinism and window invariance, `biome.<name>`
//!   terms, painted species controls;
//! - [`water`]: sea and lakes (#15): flat lake surfaces and beds, drainage ending at the shore,
//!   seamless and deterministic water tiles;
//! - [`webp`]: lossless WebP tiles carry the PNG tiles' pixels;
//! - [`points`]: point queries answer the EXR tiles' values;
//! - [`contours`]: contour tiles (#19): lines meet across tile borders, a tile alone is the
//!   window of a block, lines lie on the served elevation, interval rule and index flags.
//!
//! Shared helpers are in [`support`] and the `terrasynth-test-support` crate.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod admin;
mod admin_e2e;
mod biomes;
mod classes;
mod cli;
mod contours;
mod coverage;
mod e2e;
mod gradient_cli;
mod gradient_world;
mod hardening;
mod instances;
mod openapi;
mod points;
mod server;
mod sketch;
mod support;
mod tile_hashes;
mod water;
mod web;
mod webp;
