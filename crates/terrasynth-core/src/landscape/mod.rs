//! Landscape layers (DESIGN.md, methods 1 and 4): the per-world niche model of vegetation species
//! and the material list of splat and colour maps ([`model`]), the evaluation of species niches and
//! the deterministic seeding simulation that makes densities patchy ([`vegetation`]), and material
//! weights, their RGBA packing and the baked colour ([`splat`]), and instances (plants and rocks)
//! scattered by the world's rules ([`scatter`]), and the sea and lakes of the native zoom
//! ([`water`](mod@water)) with the lakes a base records as flat surfaces ([`surface_lakes`]), and
//! land-cover classes from RGB images by HSV ranges ([`classes`]).
//!
//! Everything here is a pure function of its arguments and of global pixel coordinates (noise and
//! seeding hash the coordinates with [`crate::dictionary::hash2`]): no IO, no global state.

pub mod classes;
pub mod model;
pub mod scatter;
pub mod splat;
pub mod surface_lakes;
pub mod vegetation;
pub mod water;

pub use classes::{classify_rgb, validate_classes, ClassesConfig, HsvClass, HsvRanges};
pub use model::{Clustering, DrainageStyle, LandscapeConfig, Material, Species, Trapezoid};
pub use scatter::{Instance, Method, RuleField, ScatterRule, SizeRange};
pub use splat::{colour_of, material_weights, quantise_weights, LayerInputs};
pub use vegetation::{
    biome_key, class_factor, cluster_densities, exemplar_vegetation, suitability, viability_gate,
};
pub use water::{water, Water, WaterConfig};

use thiserror::Error;

/// An invalid landscape configuration.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LandscapeError {
    /// A value is out of range or inconsistent.
    #[error("invalid landscape configuration: {0}")]
    Invalid(String),
}
