//! terrasynth's numeric pipeline: synchronous, pure and deterministic. [`raster`] (grids,
//! georeference and the file formats), [`analysis`] (terrain derivatives, flow routing, realism
//! metrics), [`dictionary`] (multi-layer dictionaries of exemplar patches and matching), [`synth`]
//! (one ×2 amplification level and level chains), [`landscape`] (vegetation niches, materials,
//! splat and colour), the embedded default data ([`assets`]) and the transcendental functions
//! that give the same bits on every machine ([`math`]).
//!
//! Architecture invariant: this crate does no async work and no HTTP; its only IO is through
//! `Read`/`Write` and the file helpers of [`raster`]. A CI check (`scripts/check_layers.sh`)
//! fails if tokio, axum, hyper, tower or moka enter its dependency tree. See `ARCHITECTURE.md`.

pub mod analysis;
pub mod assets;
pub mod dictionary;
pub mod landscape;
pub mod math;
pub mod names;
pub mod raster;
pub mod simd;
pub mod synth;
