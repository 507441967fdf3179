//! `terrasynth dictionary build`: read exemplars (or the embedded default), derive extra layers,
//! build a dictionary and write it.

use std::path::PathBuf;
use std::time::Instant;

use ndarray::Array2;

use super::error::CliError;
use crate::dictionary::build::{build, BuildOptions, Exemplar};
use crate::dictionary::derive::derived_layers;
use crate::dictionary::format::{content_id, write_dictionary};
use crate::dictionary::{LayerKind, Learning};
use crate::raster::{embedded, read_raster_file, Grid, ReadLimits, ELEVATION};

/// A pixel window `col,row,width,height` of an exemplar kept out of the dictionary (for held-out
/// evaluation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exclusion {
    /// First column.
    pub col: usize,
    /// First row.
    pub row: usize,
    /// Width in cells.
    pub width: usize,
    /// Height in cells.
    pub height: usize,
}

impl std::str::FromStr for Exclusion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let v: Vec<usize> = s
            .split(',')
            .map(|p| p.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("`{s}`: {e}; expected COL,ROW,WIDTH,HEIGHT"))?;
        match v[..] {
            [col, row, width, height] => Ok(Exclusion {
                col,
                row,
                width,
                height,
            }),
            _ => Err(format!("`{s}`: expected COL,ROW,WIDTH,HEIGHT")),
        }
    }
}

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
    pub exclude: Vec<Exclusion>,
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

/// The build exemplar of `grid`: NaN-free elevation, validity mask (minus `exclude`), metric cell
/// size, the `extra` layers and, with `derive`, the derived layers.
pub fn to_exemplar(
    grid: &Grid,
    extra: Vec<(String, Array2<f32>, LayerKind)>,
    exclude: &[Exclusion],
    derive: bool,
) -> Result<Exemplar, CliError> {
    grid.require_some_valid()?;
    let filled = grid.filled()?;
    let cells = grid.georef.cell_sizes(grid.rows());
    let mut layers = extra;
    if derive {
        layers.extend(derived_layers(&filled, &cells));
    }
    let mut valid = Array2::from_shape_fn(grid.data.dim(), |(r, c)| grid.is_valid(r, c));
    for ex in exclude {
        for r in ex.row..(ex.row + ex.height).min(grid.rows()) {
            for c in ex.col..(ex.col + ex.width).min(grid.cols()) {
                valid[[r, c]] = false;
            }
        }
    }
    Ok(Exemplar {
        elevation: filled,
        valid: Some(valid),
        cell_m: cells.mean_cell(),
        layers,
    })
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
    if !args.layers.is_empty() && args.exemplars.len() + usize::from(args.default_exemplar) != 1 {
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
            let layers = if i == 0 { extra.clone() } else { Vec::new() };
            to_exemplar(g, layers, &args.exclude, !args.no_derived)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let dict = build(&exemplars, &args.options, progress)?;
    let mut bytes = Vec::new();
    write_dictionary(&dict, &mut bytes)?;
    crate::store::write_atomically(output, &bytes)?;
    Ok(BuildSummary {
        id: content_id(&dict)?,
        atoms: dict.n_atoms,
        layers: dict.layers.iter().map(|l| l.name.clone()).collect(),
        seconds: start.elapsed().as_secs_f64(),
        bytes: bytes.len(),
    })
}

/// Parses `--learning`: `complete` or `medoids[:ITERATIONS]`.
pub fn parse_learning(s: &str) -> Result<Learning, String> {
    match s.split_once(':') {
        None if s == "complete" => Ok(Learning::Complete),
        None if s == "medoids" => Ok(Learning::Medoids { iterations: 6 }),
        Some(("medoids", n)) => n
            .parse()
            .map(|iterations| Learning::Medoids { iterations })
            .map_err(|e| format!("`{s}`: {e}")),
        _ => Err(format!(
            "`{s}`: expected `complete` or `medoids[:ITERATIONS]`"
        )),
    }
}
