//! `terrasynth dictionary build --kind gradient`: read exemplars (or the embedded default), build
//! a gradient tile set (issue #20) and write it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::error::CliError;
use super::output::write_bytes;
use terrasynth_core::dictionary::gradient_format::{content_id, to_bytes};
use terrasynth_core::dictionary::{
    build_gradient_tiles, exemplar_plane, GradientParams, PixelWindow,
};
use terrasynth_core::raster::{embedded, read_raster_file, ReadLimits};

/// Arguments of `dictionary build --kind gradient`.
#[derive(Clone, Debug, Default)]
pub struct GradientBuildArgs {
    /// Exemplar DEM files (GeoTIFF).
    pub exemplars: Vec<PathBuf>,
    /// Use the embedded default exemplar (in addition to any files).
    pub default_exemplar: bool,
    /// Windows of the exemplars to keep out of the tile set (held-out evaluation).
    pub exclude: Vec<PixelWindow>,
    /// The tile set's parameters.
    pub params: GradientParams,
}

/// What a gradient build produced.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GradientBuildSummary {
    /// Content id (hex SHA-256) of the tile set bytes.
    pub id: String,
    /// Colour combinations (of each axis) that the exemplars offered patches for.
    pub combinations_found: usize,
    /// Colour combinations of each axis.
    pub combinations: usize,
    /// Wall-clock seconds (reading, building, writing).
    pub seconds: f64,
    /// Bytes written.
    pub bytes: usize,
}

/// Runs the build and writes the tile set to `output`.
pub fn run(args: &GradientBuildArgs, output: &Path) -> Result<GradientBuildSummary, CliError> {
    let start = Instant::now();
    if args.exemplars.is_empty() && !args.default_exemplar {
        return Err(CliError::Usage(
            "give at least one --exemplar FILE, or --default".into(),
        ));
    }
    // Parameters first: a bad one is reported before any exemplar is read.
    args.params.validate()?;
    let limits = ReadLimits::default();
    let mut grids = Vec::new();
    if args.default_exemplar {
        grids.push(exemplar_plane(
            &embedded::default_exemplar()?,
            &args.exclude,
        ));
    }
    for path in &args.exemplars {
        let raster = read_raster_file(path, None, &limits)?;
        let grid = raster
            .elevation()
            .ok_or_else(|| CliError::Usage(format!("{}: no elevation layer", path.display())))?;
        grids.push(exemplar_plane(&grid, &args.exclude));
    }
    let set = build_gradient_tiles(&grids, &args.params)?;
    let bytes = to_bytes(&set)?;
    write_bytes(output, &bytes)?;
    let combinations = args.params.combinations();
    Ok(GradientBuildSummary {
        id: content_id(&set)?,
        combinations_found: set.found[..combinations].iter().filter(|&&n| n > 0).count(),
        combinations,
        seconds: start.elapsed().as_secs_f64(),
        bytes: bytes.len(),
    })
}
