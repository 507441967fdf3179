//! A command's output files, every one written atomically, as the export archives are: under
//! the temporary name `.NAME.tmp-PID` beside the output ([`crate::archive::temporary_path`]),
//! fsync, rename (`terrasynth_store::write_atomically_via`). A command that fails or is
//! interrupted leaves the file it was to replace as it was, or no file, never a truncated one;
//! what a killed command left is removed by the next command writing the same output
//! ([`crate::archive::remove_stale_temporaries`]).

use std::io::Write;
use std::path::Path;

use terrasynth_core::raster::{write_geotiff, Grid};
use terrasynth_store::StoreError;

use super::error::CliError;
use crate::archive::{remove_stale_temporaries, temporary_path};

/// Writes `grid` to `path` as a GeoTIFF.
pub fn write_grid(grid: &Grid, path: &Path) -> Result<(), CliError> {
    write_file(path, |out| Ok(write_geotiff(grid, out)?))
}

/// Writes `bytes` to `path`.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    write_file(path, |out| {
        out.write_all(bytes).map_err(|source| CliError::Io {
            path: path.display().to_string(),
            source,
        })
    })
}

/// Writes `path` with `write`, through its temporary name.
fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<(), CliError>,
) -> Result<(), CliError> {
    remove_stale_temporaries(path);
    terrasynth_store::write_atomically_via(&temporary_path(path), path, write).map_err(file_error)
}

/// A failed file operation as the command line says it (`PATH: the OS error`), not as the
/// store's.
fn file_error(e: CliError) -> CliError {
    match e {
        CliError::Store(StoreError::Io { path, source }) => CliError::Io { path, source },
        other => other,
    }
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
        // What a killed command left under the temporary name is removed by the next write.
        let leftover = dir.path().join(".out.tif.tmp-4000000000");
        std::fs::write(&leftover, b"partial").unwrap();
        write_grid(&good, &path).unwrap();
        assert!(!leftover.exists());
        // A directory that is not there: the message names the output, as a file error.
        let missing = dir.path().join("nowhere").join("x.geojson");
        let e = write_bytes(&missing, b"{}").unwrap_err();
        assert!(matches!(e, CliError::Io { .. }), "{e:?}");
        assert!(
            e.to_string().starts_with(&missing.display().to_string()),
            "{e}"
        );
    }
}
