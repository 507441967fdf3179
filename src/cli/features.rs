//! `terrasynth features`: the ridges and valleys of a DEM (PPA, `analysis::ppa`) as a GeoJSON
//! `FeatureCollection` of `LineString`s in longitude/latitude, with `--check` the agreement of the
//! extracted features with D8 drainage (the acceptance figures).

use std::path::PathBuf;

use super::error::CliError;
use super::output::write_bytes;
use terrasynth_core::analysis::ppa::{self, DrainageAgreement, FeatureTree, PpaParams};
use terrasynth_core::raster::{read_raster_file, ReadLimits};
use terrasynth_core::synth::sketch::geojson::write_features_geojson;

/// Which trees to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kinds {
    /// Ridges only.
    Ridge,
    /// Valleys only.
    Valley,
    /// Both.
    All,
}

/// Arguments of `features`.
#[derive(Clone, Debug)]
pub struct FeaturesArgs {
    /// Input DEM (GeoTIFF, or EXR/PNG16 with a georeference).
    pub input: PathBuf,
    /// Output GeoJSON.
    pub output: PathBuf,
    /// Which trees to write.
    pub kinds: Kinds,
    /// Also measure the agreement with D8 drainage.
    pub check: bool,
}

/// What `features` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FeaturesSummary {
    /// Ridge paths written.
    pub ridge_paths: usize,
    /// Valley paths written.
    pub valley_paths: usize,
    /// Agreement with D8 drainage (channels of 10 km² and more, 2 cells), with `--check`.
    pub drainage: Option<DrainageAgreement>,
}

/// Runs `features`.
pub fn run(args: &FeaturesArgs) -> Result<FeaturesSummary, CliError> {
    let raster = read_raster_file(&args.input, None, &ReadLimits::default())?;
    let grid = raster
        .elevation()
        .ok_or_else(|| CliError::Usage("the input has no elevation layer".into()))?;
    let z = grid.filled()?;
    let features = ppa::features(&z, &PpaParams::default());
    let mut trees: Vec<&FeatureTree> = Vec::new();
    if args.kinds != Kinds::Valley {
        trees.push(&features.ridges);
    }
    if args.kinds != Kinds::Ridge {
        trees.push(&features.valleys);
    }
    let mut bytes = Vec::new();
    write_features_geojson(&trees, &grid.georef, &mut bytes)
        .map_err(|e| CliError::Usage(e.to_string()))?;
    write_bytes(&args.output, &bytes)?;
    let drainage = args.check.then(|| {
        let cells = grid.georef.cell_sizes(grid.rows());
        ppa::drainage_agreement(&z, &cells, &features, 1e7, 2)
    });
    Ok(FeaturesSummary {
        ridge_paths: trees
            .iter()
            .filter(|t| t.kind == ppa::FeatureKind::Ridge)
            .map(|t| t.paths.len())
            .sum(),
        valley_paths: trees
            .iter()
            .filter(|t| t.kind == ppa::FeatureKind::Valley)
            .map(|t| t.paths.len())
            .sum(),
        drainage,
    })
}
