//! `terrasynth compress` and `terrasynth decompress`: a DEM as a compact terrain (a sparse
//! construction tree over dictionary atoms, `.sct`), and back. `compress` prints the fit (PSNR on
//! the terrain's relief, RMSE) and the storage against the raw int16 grid.

use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use super::amplify::load_dictionary;
use super::error::CliError;
use super::output::{write_bytes, write_grid};
use terrasynth_core::dictionary::analytic::{analytic_atoms, AnalyticKind};
use terrasynth_core::dictionary::build::MAX_SPARSITY;
use terrasynth_core::dictionary::format::content_id;
use terrasynth_core::raster::{read_raster_file, Grid, ReadLimits};
use terrasynth_core::synth::compact::{compress, psnr_db};
use terrasynth_core::synth::compact_format::{from_bytes, to_bytes};

/// Arguments of `compress`.
#[derive(Clone, Debug)]
pub struct CompressArgs {
    /// Dictionary whose high-resolution atoms the terrain is written with.
    pub dictionary: Option<PathBuf>,
    /// Procedural atoms added to (or, without a dictionary, instead of) the dictionary's.
    pub analytic: Option<AnalyticKind>,
    /// How many procedural atoms.
    pub analytic_atoms: usize,
    /// Atom side when no dictionary gives it.
    pub patch: usize,
    /// The DEM.
    pub input: PathBuf,
    /// Atoms per primitive.
    pub sparsity: usize,
    /// Coefficient quantum, metres per unit-norm atom (`None`: half a metre per patch side).
    pub coef_quantum: Option<f32>,
    /// Joint refinement passes after the first fit.
    pub passes: usize,
    /// The `.sct` file to write.
    pub output: PathBuf,
}

/// What `compress` measured.
#[derive(Clone, Debug, Serialize)]
pub struct CompressSummary {
    /// Grid rows.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    /// Lattice primitives.
    pub primitives: usize,
    /// Atoms per primitive (at most).
    pub sparsity: usize,
    /// Atoms offered.
    pub atoms_available: usize,
    /// Atoms the codes use (stored in the file).
    pub atoms_used: usize,
    /// Bytes of the file.
    pub bytes: usize,
    /// Bytes of the stored atoms (deflated), which a shared dictionary would spare.
    pub atom_bytes: usize,
    /// Bytes of the raw grid as int16.
    pub raw_int16_bytes: usize,
    /// `bytes / raw_int16_bytes`.
    pub storage_ratio: f64,
    /// `(bytes − atom_bytes) / raw_int16_bytes`: the ratio with a shared dictionary.
    pub storage_ratio_shared_dictionary: f64,
    /// PSNR of the decoded terrain on the input's relief, dB.
    pub psnr_db: f64,
    /// RMSE of the decoded terrain, metres.
    pub rmse_m: f64,
    /// Relief (max − min) of the input, metres.
    pub relief_m: f64,
    /// Plain baselines at (at least) the storage of the codes (the file without its atoms: the
    /// storage with a shared dictionary, which is what the paper's figures compare).
    pub baselines: Baselines,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// What plain methods reach with at least the compact terrain's bytes.
#[derive(Clone, Debug, Serialize)]
pub struct Baselines {
    /// Box down-sampling by the largest factor dividing the grid whose int16 grid is no smaller
    /// than the compact file, then bicubic up-sampling: the factor.
    pub bicubic_factor: usize,
    /// Its storage ratio (int16 of the down-sampled grid).
    pub bicubic_storage_ratio: f64,
    /// Its PSNR, dB (absent when no factor divides the grid).
    pub bicubic_psnr_db: Option<f64>,
    /// Heights quantised to the coarsest step whose deflated int32 deltas fit in the compact
    /// file's bytes: the step, metres.
    pub deflate_step_m: f64,
    /// Its storage ratio.
    pub deflate_storage_ratio: f64,
    /// Its PSNR, dB.
    pub deflate_psnr_db: f64,
}

/// Deflated bytes of `heights` quantised to `step` metres (row-major int32 differences).
fn deflated_size(heights: &ndarray::Array2<f32>, step: f64) -> (usize, ndarray::Array2<f32>) {
    use std::io::Write;
    let mut raw = Vec::with_capacity(heights.len().saturating_mul(4));
    let mut prev = 0i64;
    let q = heights.mapv(|v| (f64::from(v) / step).round());
    for &v in q.iter() {
        let v = v as i64;
        raw.extend_from_slice(&(v.wrapping_sub(prev) as i32).to_le_bytes());
        prev = v;
    }
    let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    let _ = enc.write_all(&raw);
    let n = enc.finish().map(|b| b.len()).unwrap_or(usize::MAX);
    (n, q.mapv(|v| (v * step) as f32))
}

/// The plain baselines of `heights` against a compact file of `bytes` bytes.
pub fn baselines(heights: &ndarray::Array2<f32>, bytes: usize) -> Baselines {
    let (rows, cols) = heights.dim();
    let raw = rows.saturating_mul(cols).saturating_mul(2).max(1);
    // Bicubic: the largest factor that still stores at least `bytes`.
    let mut factor = 1;
    for f in 2..=64usize {
        let divides = rows.checked_rem(f) == Some(0) && cols.checked_rem(f) == Some(0);
        let stored = rows
            .checked_div(f)
            .unwrap_or(0)
            .saturating_mul(cols.checked_div(f).unwrap_or(0))
            .saturating_mul(2);
        if divides && stored >= bytes {
            factor = f;
        }
    }
    let (bicubic_psnr_db, bicubic_storage_ratio) = match factor {
        1 => (None, 1.0),
        f => match terrasynth_core::analysis::box_down(heights, f) {
            Ok(low) => {
                let up = terrasynth_core::synth::baselines::bicubic_upsample(&low, f);
                (
                    Some(psnr_db(heights, &up)),
                    low.len() as f64 * 2.0 / raw as f64,
                )
            }
            Err(_) => (None, 1.0),
        },
    };
    // Deflate: bisect the quantisation step (log scale) for the finest step that fits.
    let (mut lo, mut hi) = (1e-3f64, 1e4f64);
    for _ in 0..24 {
        let mid = (lo * hi).sqrt();
        if deflated_size(heights, mid).0 <= bytes {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let (size, q) = deflated_size(heights, hi);
    Baselines {
        bicubic_factor: factor,
        bicubic_storage_ratio,
        bicubic_psnr_db,
        deflate_step_m: hi,
        deflate_storage_ratio: size as f64 / raw as f64,
        deflate_psnr_db: psnr_db(heights, &q),
    }
}

/// The atoms to write with: the dictionary's high-resolution atoms (centred, scaled to unit norm)
/// and any procedural ones; their side; a description of where they came from.
fn atoms_of(args: &CompressArgs) -> Result<(Vec<f32>, usize, String), CliError> {
    let mut atoms = Vec::new();
    let mut origin = Vec::new();
    let mut patch = args.patch;
    if let Some(path) = &args.dictionary {
        let d = load_dictionary(path)?;
        patch = d.patch();
        atoms.extend(terrasynth_core::synth::compact::unit_hi_atoms(&d));
        origin.push(format!("dictionary:{}", content_id(&d)?));
    }
    if let Some(kind) = args.analytic {
        atoms.extend(analytic_atoms(kind, patch, args.analytic_atoms, 1));
        origin.push(format!(
            "analytic:{}:{}",
            match kind {
                AnalyticKind::Perlin => "perlin",
                AnalyticKind::Ridged => "ridged",
            },
            args.analytic_atoms
        ));
    }
    if atoms.is_empty() {
        return Err(CliError::Usage(
            "give --dictionary DICT, --analytic perlin|ridged, or both".into(),
        ));
    }
    Ok((atoms, patch, origin.join("+")))
}

/// Runs `compress`.
pub fn run_compress(args: &CompressArgs) -> Result<CompressSummary, CliError> {
    let start = Instant::now();
    if args.sparsity == 0 || args.sparsity > MAX_SPARSITY {
        return Err(CliError::Usage(format!(
            "--sparsity {} must lie between 1 and {MAX_SPARSITY}",
            args.sparsity
        )));
    }
    if args.patch < 4 || args.patch > 256 || args.patch % 2 != 0 {
        return Err(CliError::Usage(format!(
            "--patch {} must be even, between 4 and 256",
            args.patch
        )));
    }
    if let Some(q) = args.coef_quantum {
        if !(q.is_finite() && q > 0.0) {
            return Err(CliError::Usage(format!(
                "--coef-quantum {q} must be positive"
            )));
        }
    }
    let raster = read_raster_file(&args.input, None, &ReadLimits::default())?;
    let grid = raster
        .elevation()
        .ok_or_else(|| CliError::Usage("the input has no elevation layer".into()))?;
    let heights = grid.filled()?;
    let (atoms, patch, origin) = atoms_of(args)?;
    let coef_quantum = args.coef_quantum.unwrap_or(0.5 * patch as f32);
    let terrain = compress(
        &heights,
        &atoms,
        patch,
        args.sparsity,
        coef_quantum,
        args.passes,
    );
    let (bytes, sizes) =
        to_bytes(&terrain, grid.georef, &origin).map_err(|e| CliError::Usage(e.to_string()))?;
    write_bytes(&args.output, &bytes)?;
    let decoded = terrain.decode();
    let (rows, cols) = heights.dim();
    let raw = rows.saturating_mul(cols).saturating_mul(2).max(1);
    Ok(CompressSummary {
        rows,
        cols,
        primitives: terrain.primitives(),
        sparsity: args.sparsity,
        atoms_available: atoms
            .len()
            .checked_div(patch.saturating_mul(patch))
            .unwrap_or(0),
        atoms_used: terrain.atom_scales.len(),
        bytes: sizes.total,
        atom_bytes: sizes.atoms,
        raw_int16_bytes: raw,
        storage_ratio: sizes.total as f64 / raw as f64,
        storage_ratio_shared_dictionary: sizes.total.saturating_sub(sizes.atoms) as f64
            / raw as f64,
        psnr_db: psnr_db(&heights, &decoded),
        rmse_m: terrasynth_core::analysis::rmse(&heights, &decoded),
        relief_m: terrasynth_core::analysis::relief(&heights),
        baselines: baselines(&heights, sizes.total.saturating_sub(sizes.atoms)),
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Runs `decompress`: reads a `.sct` file and writes its decoded grid as a float32 GeoTIFF;
/// returns the grid.
pub fn run_decompress(input: &std::path::Path, output: &std::path::Path) -> Result<Grid, CliError> {
    let bytes = std::fs::read(input).map_err(|source| CliError::Io {
        path: input.display().to_string(),
        source,
    })?;
    let (terrain, header) = from_bytes(&bytes, &ReadLimits::default())
        .map_err(|e| CliError::Usage(format!("{}: {e}", input.display())))?;
    let grid = Grid::new(terrain.decode(), header.georef);
    write_grid(&grid, output)?;
    Ok(grid)
}
