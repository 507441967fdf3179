//! `terrasynth eval`: realism and fidelity metrics of an amplified DEM against the real terrain it
//! should resemble, beside two baselines computed on the fly from the same low-resolution input:
//! cell-centred bicubic, and bicubic plus slope-scaled fBm noise. Optionally writes a picture:
//! hillshades of the truth and the three candidates side by side.

use std::path::PathBuf;

use ndarray::{s, Array2};
use serde::Serialize;

use super::error::CliError;
use super::output::write_bytes;
use terrasynth_core::analysis;
use terrasynth_core::math;
use terrasynth_core::raster::{read_raster_file, CellSizes, Grid, ReadLimits};
use terrasynth_core::synth::baselines::{bicubic_upsample, fbm_upsample};

/// Seed of the fBm baseline's noise.
pub const FBM_SEED: u64 = 0x7e55_a5e1;

/// Arguments of `eval`.
#[derive(Clone, Debug)]
pub struct EvalArgs {
    /// The real high-resolution terrain.
    pub truth: PathBuf,
    /// The low-resolution input that was amplified.
    pub input: PathBuf,
    /// The amplified result.
    pub output: PathBuf,
    /// Where to write the hillshade picture (truth, bicubic, bicubic + fBm, output), if wanted.
    pub picture: Option<PathBuf>,
}

/// Metrics of one candidate against the truth.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Metrics {
    /// Root-mean-square height error, metres.
    pub rmse_m: f64,
    /// 1-Wasserstein distance between slope distributions, degrees.
    pub slope_wasserstein_deg: f64,
    /// Energy in the band the down-sampling removed, relative to the truth's (1 = same).
    pub band_energy_ratio: f64,
    /// The same ratio in each octave of that band ([`EvalReport::band_octaves`], coarsest
    /// first): where the band's energy sits, which the single ratio hides (0 where the truth has
    /// none in an octave).
    pub band_octave_energy_ratios: Vec<f64>,
    /// Flood extent, percent of cells.
    pub flood_extent_pct: f64,
    /// |flood extent − truth's flood extent|, percentage points.
    pub flood_extent_error_pct: f64,
    /// 1-Wasserstein distance between log10 D8 upstream-area distributions.
    pub log_area_wasserstein: f64,
    /// RMSE of the box-down-sampled candidate against the input, percent of the input's relief.
    pub consistency_pct: f64,
    /// 1-Wasserstein distance between curvature (negative Laplacian) distributions, 1/m.
    pub curvature_wasserstein_per_m: f64,
    /// Drainage density: km of channel (upstream area ≥ [`analysis::CHANNEL_AREA_M2`]) per km².
    pub drainage_density_km_per_km2: f64,
    /// Pixel-axis anisotropy of the high-frequency spectrum ([`analysis::axis_anisotropy`]).
    pub axis_anisotropy: f64,
    /// [`Metrics::axis_anisotropy`] divided by the truth's (1 = the truth's own).
    pub anisotropy_vs_truth: f64,
    /// The candidate's detail against the truth's, both measured from the bicubic baseline
    /// (`candidate − bicubic`, `truth − bicubic`): their correlation `ρ` (the cosine of the two
    /// grids as vectors; 0 when the candidate has no detail, as bicubic itself).
    pub detail_correlation: f64,
    /// The RMS of the candidate's detail over the truth's, `r`. With `ρ`, the RMSE follows:
    /// `(RMSE / bicubic's)² = 1 + r² − 2ρr`.
    pub detail_rms_ratio: f64,
    /// [`Metrics::detail_correlation`] in each of [`EvalReport::detail_octaves`]: where in the
    /// spectrum the candidate's detail agrees with the truth's.
    pub detail_octave_correlations: Vec<f64>,
}

/// The truth's own reference values.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TruthStats {
    /// Flood extent of the truth, percent.
    pub flood_extent_pct: f64,
    /// Band energy of the truth.
    pub band_energy: f64,
    /// The truth's energy in each octave of the band ([`EvalReport::band_octaves`]).
    pub band_octave_energies: Vec<f64>,
    /// The truth's energy in each of [`EvalReport::octaves_below_band`]: the slope of its
    /// spectrum where the input still shows it, to set against the band's first octave.
    pub octave_below_band_energies: Vec<f64>,
    /// Relief (max − min) of the input, metres.
    pub input_relief_m: f64,
    /// Drainage density of the truth, km per km².
    pub drainage_density_km_per_km2: f64,
    /// Pixel-axis anisotropy of the truth.
    pub axis_anisotropy: f64,
}

/// The full report printed by `eval`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EvalReport {
    /// Up-sampling factor between input and truth.
    pub factor: usize,
    /// The octaves of the band the down-sampling removed, `[low, high]` radial frequency in
    /// cycles per cell of the truth: from the input's Nyquist (`0.5 / factor`) up, each twice the
    /// last, the finest ending at 1 (past the spectrum's corners, `√2 / 2`).
    pub band_octaves: Vec<[f64; 2]>,
    /// The two octaves just below the input's Nyquist, `[0.125/factor, 0.25/factor]` and
    /// `[0.25/factor, 0.5/factor]`: frequencies the input still holds.
    pub octaves_below_band: Vec<[f64; 2]>,
    /// The octaves of [`Metrics::detail_octave_correlations`]: [`EvalReport::octaves_below_band`]
    /// then [`EvalReport::band_octaves`].
    pub detail_octaves: Vec<[f64; 2]>,
    /// Truth reference values.
    pub truth: TruthStats,
    /// The amplified output.
    pub amplified: Metrics,
    /// Cell-centred bicubic baseline.
    pub bicubic: Metrics,
    /// Bicubic plus slope-scaled fBm baseline.
    pub bicubic_fbm: Metrics,
}

/// Precomputed truth quantities shared by every candidate.
struct Reference<'a> {
    cells: &'a CellSizes,
    input: &'a Array2<f32>,
    input_relief: f64,
    factor: usize,
    slopes: Vec<f64>,
    log_area: Vec<f64>,
    flood: f64,
    band: f64,
    octaves: Vec<[f64; 2]>,
    octave_energies: Vec<f64>,
    curvature: Vec<f64>,
    drainage_density: f64,
    anisotropy: f64,
    truth: &'a Array2<f32>,
    /// The bicubic baseline, from which the candidates' and the truth's details are measured.
    bicubic: &'a Array2<f32>,
    /// `truth − bicubic`.
    truth_detail: Array2<f32>,
    /// The bands of [`Metrics::detail_octave_correlations`].
    detail_octaves: Vec<[f64; 2]>,
}

/// The octaves of the band that down-sampling by `factor` removed (every frequency above the coarse
/// grid's Nyquist, radially up to the corners of the spectrum): `[0.5/factor, 1/factor]`, `[1/factor, 2/factor]`, … up to the grid's
/// Nyquist (0.5), then `[0.5, 1]` (the spectrum's corners). Together they cover the band once.
fn band_octaves(factor: usize) -> Vec<[f64; 2]> {
    let mut octaves = Vec::new();
    let mut lo = 0.5 / factor as f64;
    while lo < 0.5 {
        let hi = (2.0 * lo).min(0.5);
        octaves.push([lo, hi]);
        lo = hi;
    }
    octaves.push([0.5, 1.0]);
    octaves
}

/// The two octaves just below the input's Nyquist (`0.5 / factor`), coarsest first.
fn octaves_below_band(factor: usize) -> Vec<[f64; 2]> {
    let nyquist = 0.5 / factor as f64;
    vec![[nyquist / 4.0, nyquist / 2.0], [nyquist / 2.0, nyquist]]
}

/// Energy of `z` in the whole removed band `[0.5/factor, 1]` and in each of `octaves` (any radial
/// bands), from one spectrum.
fn band_and_octave_energies(
    z: &Array2<f32>,
    factor: usize,
    octaves: &[[f64; 2]],
) -> (f64, Vec<f64>) {
    let bands: Vec<[f64; 2]> = std::iter::once([0.5 / factor as f64, 1.0])
        .chain(octaves.iter().copied())
        .collect();
    let mut energies = analysis::band_energies(z, &bands);
    let band = energies.remove(0);
    (band, energies)
}

fn slopes_deg(z: &Array2<f32>, cells: &CellSizes) -> Vec<f64> {
    analysis::slope_degrees(z, cells)
        .iter()
        .map(|&v| f64::from(v))
        .collect()
}

fn log_areas(z: &Array2<f32>, cells: &CellSizes) -> Vec<f64> {
    let filled = analysis::priority_flood_fill(z);
    analysis::flow_accumulation_d8(&filled, cells)
        .iter()
        .map(|a| math::log10(a.max(1.0)))
        .collect()
}

fn metrics(reference: &Reference<'_>, z: &Array2<f32>) -> Metrics {
    let flood = analysis::flood_extent(z);
    let anisotropy = analysis::axis_anisotropy(z);
    let (band, octave_energies) = band_and_octave_energies(z, reference.factor, &reference.octaves);
    let (correlation, rms_ratio) = detail_against_truth(z, reference.truth, reference.bicubic);
    let detail_octave_correlations = analysis::band_correlations(
        &difference(z, reference.bicubic),
        &reference.truth_detail,
        &reference.detail_octaves,
    );
    let consistency = match analysis::box_down(z, reference.factor) {
        Ok(down) if reference.input_relief > 0.0 => {
            100.0 * analysis::rmse(&down, reference.input) / reference.input_relief
        }
        _ => 0.0,
    };
    Metrics {
        rmse_m: analysis::rmse(z, reference.truth),
        slope_wasserstein_deg: analysis::wasserstein1(
            &slopes_deg(z, reference.cells),
            &reference.slopes,
        ),
        band_energy_ratio: if reference.band > 0.0 {
            band / reference.band
        } else {
            0.0
        },
        band_octave_energy_ratios: octave_energies
            .iter()
            .zip(&reference.octave_energies)
            .map(|(&e, &t)| if t > 0.0 { e / t } else { 0.0 })
            .collect(),
        flood_extent_pct: flood,
        flood_extent_error_pct: (flood - reference.flood).abs(),
        log_area_wasserstein: analysis::wasserstein1(
            &log_areas(z, reference.cells),
            &reference.log_area,
        ),
        consistency_pct: consistency,
        curvature_wasserstein_per_m: analysis::wasserstein1(
            &analysis::curvature_values(z, reference.cells),
            &reference.curvature,
        ),
        drainage_density_km_per_km2: analysis::drainage_density(
            z,
            reference.cells,
            analysis::CHANNEL_AREA_M2,
        ),
        axis_anisotropy: anisotropy,
        anisotropy_vs_truth: anisotropy / reference.anisotropy,
        detail_correlation: correlation,
        detail_rms_ratio: rms_ratio,
        detail_octave_correlations,
    }
}

/// `a − b` cell by cell (same shapes: the evaluated grids are checked to match).
fn difference(a: &Array2<f32>, b: &Array2<f32>) -> Array2<f32> {
    ndarray::Zip::from(a).and(b).map_collect(|&x, &y| x - y)
}

/// `(ρ, r)` of [`Metrics::detail_correlation`] and [`Metrics::detail_rms_ratio`] for candidate
/// `z` against `truth`, both measured from `bicubic` (all the same shape).
fn detail_against_truth(z: &Array2<f32>, truth: &Array2<f32>, bicubic: &Array2<f32>) -> (f64, f64) {
    let (mut zt, mut zz, mut tt) = (0.0f64, 0.0f64, 0.0f64);
    for ((&v, &t), &b) in z.iter().zip(truth).zip(bicubic) {
        let (dz, dt) = (f64::from(v) - f64::from(b), f64::from(t) - f64::from(b));
        zt += dz * dt;
        zz += dz * dz;
        tt += dt * dt;
    }
    let correlation = if zz > 0.0 && tt > 0.0 {
        zt / (zz * tt).sqrt()
    } else {
        0.0
    };
    let rms_ratio = if tt > 0.0 { (zz / tt).sqrt() } else { 0.0 };
    (correlation, rms_ratio)
}

/// Evaluates `output` (and the baselines computed from `input`) against `truth`. The three grids
/// must cover the same extent, `truth` and `output` at the same resolution, `input` coarser by an
/// integer factor.
pub fn evaluate(truth: &Grid, input: &Grid, output: &Grid) -> Result<EvalReport, CliError> {
    evaluate_with_picture(truth, input, output, None)
}

/// [`evaluate`], also writing the hillshade picture to `picture` when given (see
/// [`picture_png`]).
pub fn evaluate_with_picture(
    truth: &Grid,
    input: &Grid,
    output: &Grid,
    picture: Option<&std::path::Path>,
) -> Result<EvalReport, CliError> {
    if truth.data.dim() != output.data.dim() {
        return Err(CliError::Usage(format!(
            "truth is {}×{} but output is {}×{}",
            truth.cols(),
            truth.rows(),
            output.cols(),
            output.rows()
        )));
    }
    let factor = truth.cols().checked_div(input.cols()).unwrap_or(0);
    let scaled = |n: usize| n.checked_mul(factor);
    if factor < 2
        || scaled(input.cols()) != Some(truth.cols())
        || scaled(input.rows()) != Some(truth.rows())
    {
        return Err(CliError::Usage(format!(
            "the input ({}×{}) must be the truth ({}×{}) down-sampled by an integer factor ≥ 2",
            input.cols(),
            input.rows(),
            truth.cols(),
            truth.rows()
        )));
    }
    let truth_z = truth.filled()?;
    let input_z = input.filled()?;
    let output_z = output.filled()?;
    let cells = truth.georef.cell_sizes(truth.rows());
    let input_relief = analysis::relief(&input_z);
    let bicubic = bicubic_upsample(&input_z, factor);
    let octaves = band_octaves(factor);
    let below = octaves_below_band(factor);
    let (band, mut octave_energies) =
        band_and_octave_energies(&truth_z, factor, &[octaves.as_slice(), &below].concat());
    let below_energies = octave_energies.split_off(octaves.len());
    let detail_octaves = [below.as_slice(), &octaves].concat();
    let reference = Reference {
        cells: &cells,
        input: &input_z,
        input_relief,
        factor,
        slopes: slopes_deg(&truth_z, &cells),
        log_area: log_areas(&truth_z, &cells),
        flood: analysis::flood_extent(&truth_z),
        band,
        octave_energies,
        octaves,
        curvature: analysis::curvature_values(&truth_z, &cells),
        drainage_density: analysis::drainage_density(&truth_z, &cells, analysis::CHANNEL_AREA_M2),
        anisotropy: analysis::axis_anisotropy(&truth_z),
        truth: &truth_z,
        bicubic: &bicubic,
        truth_detail: difference(&truth_z, &bicubic),
        detail_octaves,
    };
    let coarse_cell = input.georef.cell_sizes(input.rows()).mean_cell();
    let fbm = fbm_upsample(&input_z, factor, coarse_cell, FBM_SEED);
    if let Some(path) = picture {
        let bytes = picture_png(&[&truth_z, &bicubic, &fbm, &output_z], &cells)?;
        write_bytes(path, &bytes)?;
    }
    Ok(EvalReport {
        factor,
        band_octaves: reference.octaves.clone(),
        octaves_below_band: below,
        detail_octaves: reference.detail_octaves.clone(),
        truth: TruthStats {
            flood_extent_pct: reference.flood,
            band_energy: reference.band,
            band_octave_energies: reference.octave_energies.clone(),
            octave_below_band_energies: below_energies,
            input_relief_m: input_relief,
            drainage_density_km_per_km2: reference.drainage_density,
            axis_anisotropy: reference.anisotropy,
        },
        amplified: metrics(&reference, &output_z),
        bicubic: metrics(&reference, &bicubic),
        bicubic_fbm: metrics(&reference, &fbm),
    })
}

/// Runs `eval`: reads the three files and evaluates.
pub fn run(args: &EvalArgs) -> Result<EvalReport, CliError> {
    let limits = ReadLimits::default();
    let read = |p: &PathBuf| -> Result<Grid, CliError> {
        read_raster_file(p, None, &limits)?
            .elevation()
            .ok_or_else(|| CliError::Usage(format!("{}: no elevation layer", p.display())))
    };
    evaluate_with_picture(
        &read(&args.truth)?,
        &read(&args.input)?,
        &read(&args.output)?,
        args.picture.as_deref(),
    )
}

/// Gap between the picture's panels, pixels.
const PICTURE_GAP: usize = 8;

/// Mean slope (tan) the picture's vertical exaggeration aims at, so that low hills show as well
/// as high ranges.
const PICTURE_SLOPE: f64 = 0.3;

/// A grey 8-bit PNG of hillshades (light from the north-west, 45° high) of `grids` (all of one
/// shape, on `cells`), side by side in the given order, separated by white gaps. All panels share
/// one vertical exaggeration, `PICTURE_SLOPE` over the first grid's mean slope, clamped to
/// 1–10. A second row shows the centre quarter of each (half the width and height), enlarged ×2
/// by pixel repetition, so fine detail can be judged.
pub fn picture_png(grids: &[&Array2<f32>], cells: &CellSizes) -> Result<Vec<u8>, CliError> {
    let Some(first) = grids.first() else {
        return Err(CliError::Usage("no grid to picture".into()));
    };
    let (rows, cols) = first.dim();
    if grids.iter().any(|g| g.dim() != (rows, cols)) || rows < 4 || cols < 4 {
        return Err(CliError::Usage(
            "the pictured grids must share one shape of at least 4×4".into(),
        ));
    }
    let n = grids.len();
    let too_large = || CliError::Usage("the picture would be too large".into());
    let panel = cols.checked_add(PICTURE_GAP).ok_or_else(too_large)?;
    let width = n
        .checked_mul(panel)
        .and_then(|w| w.checked_sub(PICTURE_GAP))
        .ok_or_else(too_large)?;
    let second_row = rows.checked_add(PICTURE_GAP).ok_or_else(too_large)?;
    let height = second_row.checked_add(rows).ok_or_else(too_large)?;
    let mut img = Array2::<u8>::from_elem((height, width), 255);
    let (zr0, zc0) = (rows / 4, cols / 4);
    let slope = analysis::slope(first, cells);
    let mean_slope = slope.iter().map(|&v| f64::from(v)).sum::<f64>() / slope.len() as f64;
    let exaggeration = if mean_slope > 0.0 {
        (PICTURE_SLOPE / mean_slope).clamp(1.0, 10.0) as f32
    } else {
        1.0
    };
    let mut x0 = 0usize;
    for g in grids {
        let shade = analysis::hillshade_u8(
            &g.mapv(|v| v * exaggeration),
            cells,
            analysis::DEFAULT_AZIMUTH_DEG,
            analysis::DEFAULT_ALTITUDE_DEG,
        );
        let x1 = x0.checked_add(cols).ok_or_else(too_large)?;
        img.slice_mut(s![..rows, x0..x1]).assign(&shade);
        // The centre quarter, each pixel repeated 2×2 (integer division maps r to zr0 + r/2).
        let zoomed = Array2::from_shape_fn((rows, cols), |(r, c)| {
            shade[[zr0.saturating_add(r / 2), zc0.saturating_add(c / 2)]]
        });
        img.slice_mut(s![second_row.., x0..x1]).assign(&zoomed);
        x0 = x0.saturating_add(panel);
    }
    terrasynth_tiles::encode_gray_png(&img).map_err(|e| CliError::Usage(format!("picture: {e}")))
}

#[cfg(test)]
mod tests {
    use super::{band_octaves, octaves_below_band};

    #[test]
    fn the_octaves_below_the_band_end_at_the_input_nyquist() {
        assert_eq!(
            octaves_below_band(4),
            vec![[0.03125, 0.0625], [0.0625, 0.125]]
        );
        assert_eq!(octaves_below_band(2), vec![[0.0625, 0.125], [0.125, 0.25]]);
    }

    #[test]
    fn band_octaves_double_from_the_input_nyquist_to_the_corners() {
        assert_eq!(
            band_octaves(4),
            vec![[0.125, 0.25], [0.25, 0.5], [0.5, 1.0]]
        );
        assert_eq!(band_octaves(2), vec![[0.25, 0.5], [0.5, 1.0]]);
        // A factor that is not a power of two: the last octave below Nyquist is cut short.
        let third = 0.5 / 3.0;
        assert_eq!(
            band_octaves(3),
            vec![[third, 2.0 * third], [2.0 * third, 0.5], [0.5, 1.0]]
        );
    }
}
