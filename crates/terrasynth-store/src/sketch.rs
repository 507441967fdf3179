//! Sketch worlds (`POST /admin/worlds/sketch`): the request, the checks it must pass before a
//! job is queued (so that a bad sketch stores nothing), and the synthesis a job runs
//! (`synth::sketch` on stored exemplars). What happens to the result — storing it as the base
//! exemplar of a new world and serving that world — is the catalogue service's
//! ([`crate::Catalogue::submit_sketch`]).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use terrasynth_core::raster::Grid;
use terrasynth_core::synth::sketch::geojson::parse_sketch;
use terrasynth_core::synth::sketch::geometry::Sketch;
use terrasynth_core::synth::sketch::{
    synthesize, OutputSpec, SizeLimits, SketchError, SketchOptions,
};

use crate::error::ServiceError;
use crate::worlds::check_world_name;

/// Most exemplars one sketch may draw patches from.
pub const MAX_SKETCH_EXEMPLARS: usize = 8;

/// `POST /admin/worlds/sketch`: a world made from a sketch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SketchRequest {
    /// URL name of the world to make: 1–64 letters, digits, `-` or `_`.
    #[schema(pattern = "^[A-Za-z0-9_-]{1,64}$")]
    pub name: String,
    /// The sketch: a GeoJSON `FeatureCollection` (or `Feature`) of `LineString`s (or
    /// `MultiLineString`s) in longitude/latitude, each with `properties.kind` `ridge` or
    /// `valley` and optionally `properties.height_m`; at most 10 000 vertices, inside the bounds,
    /// no line crossing itself.
    #[schema(value_type = Object)]
    pub sketch: serde_json::Value,
    /// `[west, south, east, north]` of the world, degrees (EPSG:4326).
    pub bounds: [f64; 4],
    /// Cell size of the base, degrees.
    pub cell_size: f64,
    /// Ids of stored exemplars whose patches make the terrain (1–8).
    pub exemplars: Vec<String>,
    /// Dictionary ids of the world's synthesis chain (exactly one for now).
    pub dictionaries: Vec<String>,
    /// Seed of the synthesis's small random choices. Default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl SketchRequest {
    /// The grid and sketch the request describes, checked: the name, the bounds and cell size
    /// against `limits`, the sketch's lines. Errors are [`ServiceError::Invalid`] (a 422).
    pub fn checked_sketch(&self, limits: &SizeLimits) -> Result<Sketch, ServiceError> {
        check_world_name(&self.name)?;
        if self.exemplars.is_empty() || self.exemplars.len() > MAX_SKETCH_EXEMPLARS {
            return Err(ServiceError::Invalid(format!(
                "give 1–{MAX_SKETCH_EXEMPLARS} exemplar ids"
            )));
        }
        let [west, south, east, north] = self.bounds;
        let grid = OutputSpec {
            west,
            south,
            east,
            north,
            cell_deg: self.cell_size,
        }
        .grid(limits)
        .map_err(invalid)?;
        parse_sketch(&self.sketch, grid).map_err(invalid)
    }
}

/// A sketch error as a catalogue error: every one is the request's fault (422).
pub fn invalid(e: SketchError) -> ServiceError {
    ServiceError::Invalid(e.to_string())
}

/// Why a sketch job did not make its terrain.
#[derive(Debug, thiserror::Error)]
pub enum SketchFailure {
    /// Cancelled.
    #[error("cancelled")]
    Cancelled,
    /// The synthesis failed.
    #[error(transparent)]
    Sketch(SketchError),
    /// Reading the exemplars or storing the result failed.
    #[error(transparent)]
    Service(#[from] ServiceError),
}

/// Runs the synthesis of a checked `sketch` from `exemplars`, reporting `(stage, fraction)` to
/// `progress`, which returns `false` to cancel.
pub fn run_sketch(
    sketch: &Sketch,
    exemplars: &[Grid],
    seed: u64,
    progress: &mut dyn FnMut(&str, f64) -> bool,
) -> Result<Grid, SketchFailure> {
    let opts = SketchOptions {
        seed,
        ..SketchOptions::default()
    };
    match synthesize(sketch, exemplars, &opts, progress) {
        Ok(world) => Ok(world.grid),
        Err(SketchError::Cancelled) => Err(SketchFailure::Cancelled),
        Err(e) => Err(SketchFailure::Sketch(e)),
    }
}
