//! `terrasynth crop`: cut a pixel window out of a GeoTIFF, optionally resample it to square cells
//! (as dictionary builds do with their exemplars) and box-down-sample it, to prepare held-out
//! truth and low-resolution inputs for `eval`.

use std::path::PathBuf;

use ndarray::s;

use super::error::CliError;
use super::output::write_grid;
use terrasynth_core::dictionary::PixelWindow;
use terrasynth_core::raster::{read_raster_file, Grid, ReadLimits, SquareCells};

/// Arguments of `crop`.
#[derive(Clone, Debug)]
pub struct CropArgs {
    /// Input GeoTIFF.
    pub input: PathBuf,
    /// Window `COL,ROW,WIDTH,HEIGHT` in input cells.
    pub window: PixelWindow,
    /// Box down-sampling factor applied after cropping (1 = none; must divide the window).
    pub down: usize,
    /// Resample the window to square cells ([`SquareCells`]) before down-sampling; the resampled
    /// axis is cut to a multiple of [`SQUARE_MULTIPLE`] cells, so that the truth and its
    /// down-sampled input of one window keep the same extent.
    pub square: bool,
    /// Output GeoTIFF.
    pub output: PathBuf,
}

/// The resampled axis of a `--square` crop is cut to a multiple of this many cells.
pub const SQUARE_MULTIPLE: usize = 8;

/// Runs `crop`.
pub fn run(args: &CropArgs) -> Result<Grid, CliError> {
    let raster = read_raster_file(&args.input, None, &ReadLimits::default())?;
    let grid = raster
        .elevation()
        .ok_or_else(|| CliError::Usage("the input has no elevation layer".into()))?;
    let w = args.window;
    // Checked sums: a window of absurd numbers is an error, not a wrap-around.
    let (col_end, row_end) = match (w.col_end(), w.row_end()) {
        (Some(c), Some(r)) if c <= grid.cols() && r <= grid.rows() => (c, r),
        _ => (0, 0),
    };
    if w.width == 0 || w.height == 0 || col_end == 0 || row_end == 0 {
        return Err(CliError::Usage(format!(
            "window {},{},{},{} does not fit the {}×{} input",
            w.col,
            w.row,
            w.width,
            w.height,
            grid.cols(),
            grid.rows()
        )));
    }
    let cut = Grid {
        data: grid
            .data
            .slice(s![w.row..row_end, w.col..col_end])
            .to_owned(),
        georef: grid.georef.window(w.col as i64, w.row as i64),
        valid: grid
            .valid
            .as_ref()
            .map(|m| m.slice(s![w.row..row_end, w.col..col_end]).to_owned()),
    };
    cut.require_some_valid()?;
    let cut = if args.square { squared(&cut)? } else { cut };
    if cut.cols().checked_rem(args.down) != Some(0) || cut.rows().checked_rem(args.down) != Some(0)
    {
        return Err(CliError::Usage(format!(
            "--down {} must divide the window size {}×{}",
            args.down,
            cut.cols(),
            cut.rows()
        )));
    }
    let out = if args.down > 1 {
        let filled = cut.filled()?;
        let down = terrasynth_core::analysis::box_down(&filled, args.down)
            .map_err(|e| CliError::Usage(e.to_string()))?;
        Grid::new(down, cut.georef.refined(1.0 / args.down as f64))
    } else {
        cut
    };
    write_grid(&out, &args.output)?;
    Ok(out)
}

/// `grid` on square cells, its resampled axis cut to a multiple of [`SQUARE_MULTIPLE`].
fn squared(grid: &Grid) -> Result<Grid, CliError> {
    let square = SquareCells::for_grid(&grid.georef, grid.rows(), grid.cols());
    let mut out = square.grid(grid)?;
    let (rows, cols) = out.data.dim();
    let keep = |n: usize| n.saturating_sub(n % SQUARE_MULTIPLE);
    let (rows, cols) = match square.decimation() {
        None => (rows, cols),
        Some((terrasynth_core::raster::square::SquaredAxis::Columns, _)) => (rows, keep(cols)),
        Some((terrasynth_core::raster::square::SquaredAxis::Rows, _)) => (keep(rows), cols),
    };
    if rows == 0 || cols == 0 {
        return Err(CliError::Usage(format!(
            "the window is too small to square: fewer than {SQUARE_MULTIPLE} cells remain"
        )));
    }
    out.data = out.data.slice(s![..rows, ..cols]).to_owned();
    out.valid = out.valid.map(|v| v.slice(s![..rows, ..cols]).to_owned());
    Ok(out)
}
