//! A command's output files, every one written atomically (a temporary file beside it, fsync,
//! rename; `terrasynth_store::write_atomically_with`): a command that fails or is interrupted
//! leaves the file it was to replace as it was, or no file, never a truncated one.

use std::path::Path;

use terrasynth_core::raster::{write_geotiff, Grid};

use super::error::CliError;

/// Writes `grid` to `path` as a GeoTIFF.
pub fn write_grid(grid: &Grid, path: &Path) -> Result<(), CliError> {
    terrasynth_store::write_atomically_with(path, |out| Ok(write_geotiff(grid, out)?))
}

/// Writes `bytes` to `path`.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    Ok(terrasynth_store::write_atomically(path, bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;
    use terrasynth_core::raster::{read_geotiff_file, Georef, ReadLimits};

    /// A GeoTIFF whose writing fails (an empty grid) leaves the file it was to replace whole:
    /// written in place, the file would have been truncated first.
    #[test]
    fn a_failed_grid_write_keeps_the_previous_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.tif");
        let georef = Georef::local_metric(30.0);
        let good = Grid::new(
            Array2::from_shape_fn((4, 5), |(r, c)| (r * 5 + c) as f32),
            georef,
        );
        write_grid(&good, &path).unwrap();
        let empty = Grid::new(Array2::zeros((0, 0)), georef);
        assert!(write_grid(&empty, &path).is_err());
        let back = read_geotiff_file(&path, &ReadLimits::default()).unwrap();
        assert_eq!(back.data, good.data);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.tif")]);
    }
}
