//! `terrasynth dictionary build`: read exemplars (or the embedded default), derive extra layers,
//! build a dictionary and write it.

use std::path::PathBuf;
use std::time::Instant;

use super::error::CliError;
use super::output::write_bytes;
use terrasynth_core::dictionary::build::{build, BuildOptions, Exemplar};
use terrasynth_core::dictionary::format::{content_id, write_dictionary};
use terrasynth_core::dictionary::{no_species, ExemplarOptions, LayerKind, PixelWindow};
use terrasynth_core::raster::{embedded, read_raster_file, Grid, ReadLimits, ELEVATION};

/// Arguments of `dictionary build`.
#[derive(Clone, Debug, Default)]
pub struct BuildArgs {
    /// Exemplar DEM files (GeoTIFF).
    pub exemplars: Vec<PathBuf>,
    /// Use the embedded Tien Shan exemplar (in addition to any files).
    pub default_exemplar: bool,
    /// Extra named layers `(name, file)`, on the grid of the (single) exemplar.
    pub layers: Vec<(String, PathBuf)>,
    /// Windows of the exemplars to keep out of the dictionary.
    pub exclude: Vec<PixelWindow>,
    /// Build options (patch, stride, atoms, learning, seed).
    pub options: BuildOptions,
    /// Skip the derived layers (`log_area`, `northness`).
    pub no_derived: bool,
}

/// What a build produced.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BuildSummary {
    /// Content id (hex SHA-256) of the dictionary bytes.
    pub id: String,
    /// Number of atoms.
    pub atoms: usize,
    /// Extra layer names.
    pub layers: Vec<String>,
    /// Wall-clock seconds of the build (reading, deriving, learning, writing).
    pub seconds: f64,
    /// Bytes written.
    pub bytes: usize,
}

/// Runs the build and writes the dictionary to `output`. `progress(stage, fraction)` is called as
/// the build advances.
pub fn run(
    args: &BuildArgs,
    output: &std::path::Path,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<BuildSummary, CliError> {
    let start = Instant::now();
    if args.exemplars.is_empty() && !args.default_exemplar {
        return Err(CliError::Usage(
            "give at least one --exemplar FILE, or --default".into(),
        ));
    }
    if !args.layers.is_empty()
        && args
            .exemplars
            .len()
            .saturating_add(usize::from(args.default_exemplar))
            != 1
    {
        return Err(CliError::Usage(
            "--layer needs exactly one exemplar (layers lie on its grid)".into(),
        ));
    }
    let limits = ReadLimits::default();
    let mut grids = Vec::new();
    if args.default_exemplar {
        progress("reading", 0.0);
        grids.push(embedded::default_exemplar()?);
    }
    for path in &args.exemplars {
        progress("reading", 0.0);
        let raster = read_raster_file(path, None, &limits)?;
        let grid = raster
            .elevation()
            .ok_or_else(|| CliError::Usage(format!("{}: no elevation layer", path.display())))?;
        grids.push(grid);
    }
    let mut extra = Vec::new();
    for (name, path) in &args.layers {
        if name == ELEVATION || name.is_empty() {
            return Err(CliError::Usage(format!("invalid layer name `{name}`")));
        }
        let raster = read_raster_file(path, Some(grids[0].georef), &limits)?;
        let grid = raster
            .elevation()
            .or_else(|| {
                raster
                    .layers
                    .first()
                    .map(|(_, a)| Grid::new(a.clone(), raster.georef))
            })
            .ok_or_else(|| CliError::Usage(format!("{}: no layer", path.display())))?;
        if grid.data.dim() != grids[0].data.dim() {
            return Err(CliError::Usage(format!(
                "layer `{name}` is {}×{} but the exemplar is {}×{}",
                grid.cols(),
                grid.rows(),
                grids[0].cols(),
                grids[0].rows()
            )));
        }
        extra.push((name.clone(), grid.filled()?, LayerKind::Continuous));
    }
    progress("deriving layers", 0.0);
    let exemplars = grids
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let options = ExemplarOptions {
                extra: if i == 0 { extra.clone() } else { Vec::new() },
                exclude: args.exclude.clone(),
                derive: !args.no_derived,
            };
            Exemplar::from_grid(g, options, no_species)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let dict = build(&exemplars, &args.options, progress)?;
    let mut bytes = Vec::new();
    write_dictionary(&dict, &mut bytes)?;
    write_bytes(output, &bytes)?;
    Ok(BuildSummary {
        id: content_id(&dict)?,
        atoms: dict.n_atoms,
        layers: dict.layers.iter().map(|l| l.name.clone()).collect(),
        seconds: start.elapsed().as_secs_f64(),
        bytes: bytes.len(),
    })
}
