//! `terrasynth amplify`: amplify a DEM by `N` ×2 levels with a dictionary or a gradient tile set
//! (told apart by the file's magic) and write a float32 GeoTIFF with the same bounds and `2^N`
//! times finer cells (plus one GeoTIFF per extra layer).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use ndarray::Array2;

use super::error::CliError;
use super::output::write_grid;
use terrasynth_core::dictionary::derive::derived_layers;
use terrasynth_core::dictionary::format::read_dictionary;
use terrasynth_core::dictionary::{
    read_any, AnyDictionary, Dictionary, GradientTileSet, MatchWeights,
};
use terrasynth_core::raster::{read_raster_file, Grid, ReadLimits};
use terrasynth_core::synth::{
    amplify_chain, Amplifier, ClampedRaster, GradientAmplifier, Level, Levers, Window,
};

/// Extra layers by name.
pub type NamedLayers = Vec<(String, Array2<f32>)>;

/// Largest dictionary file read, bytes.
pub const MAX_DICTIONARY_BYTES: u64 = 4 << 30;

/// Arguments of `amplify`.
#[derive(Clone, Debug)]
pub struct AmplifyArgs {
    /// Dictionary file.
    pub dictionary: PathBuf,
    /// Low-resolution input DEM (GeoTIFF, EPSG:4326 or EPSG:3857).
    pub input: PathBuf,
    /// Number of ×2 levels.
    pub levels: u32,
    /// Output GeoTIFF; extra layers go to `OUT.<layer>.tif`.
    pub output: PathBuf,
    /// Matching weights.
    pub weights: MatchWeights,
    /// Amplifier levers (for ablations; [`Levers::default`] is what the server runs).
    pub levers: Levers,
}

/// What an amplification produced.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AmplifySummary {
    /// Output width in cells.
    pub width: usize,
    /// Output height in cells.
    pub height: usize,
    /// Files written.
    pub files: Vec<String>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Reads a dictionary file.
pub fn load_dictionary(path: &Path) -> Result<Dictionary, CliError> {
    let f = std::fs::File::open(path).map_err(|source| CliError::Io {
        path: path.display().to_string(),
        source,
    })?;
    Ok(read_dictionary(
        std::io::BufReader::new(f),
        MAX_DICTIONARY_BYTES,
    )?)
}

/// Reads a dictionary or a gradient tile set, told apart by the file's magic
/// ([`terrasynth_core::dictionary::read_any`]).
pub fn load_amplifier(path: &Path) -> Result<AnyDictionary, CliError> {
    let f = std::fs::File::open(path).map_err(|source| CliError::Io {
        path: path.display().to_string(),
        source,
    })?;
    Ok(read_any(std::io::BufReader::new(f), MAX_DICTIONARY_BYTES)?)
}

/// Amplifies `grid` by `levels` gradient-domain levels; returns the elevation grid.
pub fn amplify_grid_gradient(
    set: &Arc<GradientTileSet>,
    grid: &Grid,
    levels: u32,
) -> Result<(Grid, NamedLayers), CliError> {
    check_levels(levels)?;
    let filled = grid.filled()?;
    let base = ClampedRaster {
        elevation: &filled,
        layers: Vec::new(),
    };
    let amps = (0..levels)
        .map(|_| GradientAmplifier::new(set.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    amplify_levels(&amps, &base, grid, levels)
}

/// `--levels` must be 1–8.
fn check_levels(levels: u32) -> Result<(), CliError> {
    if levels == 0 || levels > 8 {
        return Err(CliError::Usage(format!(
            "--levels {levels}: expected 1 to 8"
        )));
    }
    Ok(())
}

/// Runs a chain of levels of either kind over the whole of `grid` (`base` holds its filled
/// values): the output grid with `grid`'s validity, and the extra layers.
fn amplify_levels<L: Level>(
    amps: &[L],
    base: &ClampedRaster<'_>,
    grid: &Grid,
    levels: u32,
) -> Result<(Grid, NamedLayers), CliError> {
    let cells = grid.georef.cell_sizes(grid.rows());
    let factor = 1usize << levels;
    let too_large = || CliError::Usage(format!("{levels} levels make the output too large"));
    let out = Window::new(
        0,
        0,
        grid.cols().checked_mul(factor).ok_or_else(too_large)?,
        grid.rows().checked_mul(factor).ok_or_else(too_large)?,
    );
    let field = amplify_chain(amps, base, out, cells.mean_cell())?;
    let has_invalid = grid.valid_count() < grid.data.len();
    let valid = has_invalid.then(|| {
        Array2::from_shape_fn((out.rows, out.cols), |(r, c)| {
            grid.is_valid(r >> levels, c >> levels)
        })
    });
    let georef = grid.georef.refined(factor as f64);
    let elevation = Grid {
        data: field.elevation,
        georef,
        valid,
    };
    Ok((elevation, field.layers))
}

/// Amplifies `grid` by `levels` levels; returns the elevation grid and the extra layers.
pub fn amplify_grid(
    dict: &Arc<Dictionary>,
    weights: &MatchWeights,
    grid: &Grid,
    levels: u32,
) -> Result<(Grid, NamedLayers), CliError> {
    amplify_grid_with(dict, weights, grid, levels, Levers::default())
}

/// [`amplify_grid`] with explicit amplifier levers.
pub fn amplify_grid_with(
    dict: &Arc<Dictionary>,
    weights: &MatchWeights,
    grid: &Grid,
    levels: u32,
    levers: Levers,
) -> Result<(Grid, NamedLayers), CliError> {
    check_levels(levels)?;
    let filled = grid.filled()?;
    let cells = grid.georef.cell_sizes(grid.rows());
    // Layers the weights match on are derived from the input the same way as on exemplars.
    let wanted: Vec<&str> = weights
        .layers
        .iter()
        .filter(|(_, w)| *w > 0.0)
        .map(|(n, _)| n.as_str())
        .collect();
    let derived: Vec<(String, Array2<f32>)> = if wanted.is_empty() {
        Vec::new()
    } else {
        derived_layers(&filled, &cells)
            .into_iter()
            .filter(|(n, _, _)| wanted.contains(&n.as_str()))
            .map(|(n, a, _)| (n, a))
            .collect()
    };
    let base = ClampedRaster {
        elevation: &filled,
        layers: derived.iter().map(|(n, a)| (n.clone(), a)).collect(),
    };
    let amps = (0..levels)
        .map(|_| Amplifier::new(dict.clone(), weights).map(|a| a.with_levers(levers)))
        .collect::<Result<Vec<_>, _>>()?;
    amplify_levels(&amps, &base, grid, levels)
}

/// The path of extra layer `name` beside `output` (`OUT.tif` → `OUT.<name>.tif`).
pub fn layer_path(output: &Path, name: &str) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = output
        .extension()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "tif".into());
    output.with_file_name(format!("{stem}.{name}.{ext}"))
}

/// Runs `amplify`.
pub fn run(args: &AmplifyArgs) -> Result<AmplifySummary, CliError> {
    let start = Instant::now();
    let loaded = load_amplifier(&args.dictionary)?;
    let raster = read_raster_file(&args.input, None, &ReadLimits::default())?;
    let grid = raster
        .elevation()
        .ok_or_else(|| CliError::Usage("the input has no elevation layer".into()))?;
    let (out, layers) = match loaded {
        AnyDictionary::Dictionary(d) => {
            amplify_grid_with(&d, &args.weights, &grid, args.levels, args.levers)?
        }
        AnyDictionary::Gradient(set) => amplify_grid_gradient(&set, &grid, args.levels)?,
    };
    write_grid(&out, &args.output)?;
    let mut files = vec![args.output.display().to_string()];
    for (name, data) in layers {
        let path = layer_path(&args.output, &name);
        let g = Grid {
            data,
            georef: out.georef,
            valid: out.valid.clone(),
        };
        write_grid(&g, &path)?;
        files.push(path.display().to_string());
    }
    Ok(AmplifySummary {
        width: out.cols(),
        height: out.rows(),
        files,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Parses `--weights elevation=0.8,altitude=0.1,slope=0.1,log_area=0.1`.
pub fn parse_weights(s: &str) -> Result<MatchWeights, String> {
    let mut w = MatchWeights {
        elevation: 0.0,
        altitude: 0.0,
        slope: 0.0,
        layers: Vec::new(),
    };
    for part in s.split(',').filter(|p| !p.trim().is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("`{part}`: expected NAME=WEIGHT"))?;
        let v: f32 = v.trim().parse().map_err(|e| format!("`{part}`: {e}"))?;
        match k.trim() {
            "elevation" => w.elevation = v,
            "altitude" => w.altitude = v,
            "slope" => w.slope = v,
            name => w.layers.push((name.to_string(), v)),
        }
    }
    Ok(w)
}
