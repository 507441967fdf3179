//! `terrasynth sketch`: a base terrain from a sketch of ridge and valley lines (GeoJSON) and one
//! or more exemplar DEMs (`synth::sketch`), written as a float32 GeoTIFF on the grid the bounds
//! and cell size define, with a report of how well it follows the sketch.

use std::path::PathBuf;
use std::time::Instant;

use super::error::CliError;
use super::output::write_grid;
use terrasynth_core::analysis::{flood_extent, ppa::PpaParams};
use terrasynth_core::raster::{read_raster_file, Grid, ReadLimits};
use terrasynth_core::synth::sketch::geojson::parse_sketch;
use terrasynth_core::synth::sketch::quality::{self, Fidelity, Seams};
use terrasynth_core::synth::sketch::{
    synthesize, OutputSpec, SizeLimits, SketchOptions, SketchStats,
};

/// Largest sketch file read, bytes.
pub const MAX_SKETCH_BYTES: u64 = 16 << 20;

/// Arguments of `sketch`.
#[derive(Clone, Debug)]
pub struct SketchArgs {
    /// Exemplar DEMs.
    pub exemplars: Vec<PathBuf>,
    /// The sketch (GeoJSON).
    pub sketch: PathBuf,
    /// Bounds `[west, south, east, north]`, degrees.
    pub bounds: [f64; 4],
    /// Cell size, degrees.
    pub cell_size: f64,
    /// Output GeoTIFF.
    pub output: PathBuf,
    /// Seed.
    pub seed: u64,
}

/// What `sketch` made.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SketchSummary {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Patches and seams.
    pub stats: SketchStats,
    /// Distances from the sketched lines to the extracted features (cells).
    pub fidelity: Fidelity,
    /// Steps across seams against steps inside patches.
    pub seams: Seams,
    /// Flood extent of the result, %.
    pub flood_extent: f64,
    /// Wall-clock seconds of the synthesis.
    pub seconds: f64,
}

/// Parses `W,S,E,N`.
pub fn parse_bounds(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("`{p}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [w, s, e, n] => Ok([*w, *s, *e, *n]),
        _ => Err(format!("`{s}`: expected W,S,E,N")),
    }
}

/// Runs `sketch`, reporting `(stage, fraction)` to `progress`.
pub fn run(
    args: &SketchArgs,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<SketchSummary, CliError> {
    if args.exemplars.is_empty() {
        return Err(CliError::Usage("give at least one --exemplar".into()));
    }
    let [west, south, east, north] = args.bounds;
    let grid = OutputSpec {
        west,
        south,
        east,
        north,
        cell_deg: args.cell_size,
    }
    .grid(&SizeLimits::default())?;
    let len = std::fs::metadata(&args.sketch)
        .map_err(|source| CliError::Io {
            path: args.sketch.display().to_string(),
            source,
        })?
        .len();
    if len > MAX_SKETCH_BYTES {
        return Err(CliError::Usage(format!(
            "{}: the sketch is larger than {MAX_SKETCH_BYTES} bytes",
            args.sketch.display()
        )));
    }
    let text = std::fs::read(&args.sketch).map_err(|source| CliError::Io {
        path: args.sketch.display().to_string(),
        source,
    })?;
    let json: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| CliError::Usage(format!("{}: {e}", args.sketch.display())))?;
    let sketch = parse_sketch(&json, grid)?;
    let mut exemplars: Vec<Grid> = Vec::new();
    for path in &args.exemplars {
        let raster = read_raster_file(path, None, &ReadLimits::default())?;
        exemplars.push(
            raster.elevation().ok_or_else(|| {
                CliError::Usage(format!("{}: no elevation layer", path.display()))
            })?,
        );
    }
    let opts = SketchOptions {
        seed: args.seed,
        ..SketchOptions::default()
    };
    let start = Instant::now();
    let world = synthesize(&sketch, &exemplars, &opts, &mut |stage, f| {
        progress(stage, f);
        true
    })?;
    let seconds = start.elapsed().as_secs_f64();
    write_grid(&world.grid, &args.output)?;
    Ok(SketchSummary {
        width: world.grid.cols(),
        height: world.grid.rows(),
        stats: world.stats,
        fidelity: quality::fidelity(&world.grid.data, &world.trees, &PpaParams::default()),
        seams: quality::seams(&world.grid.data, &world.labels),
        flood_extent: flood_extent(&world.grid.data),
        seconds,
    })
}
