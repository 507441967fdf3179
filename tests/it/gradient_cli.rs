//! The gradient amplifier on the command line (issue #20), as a real process on real files:
//! `dictionary build --kind gradient`, `amplify --dictionary` with a tile set (told apart from a
//! dictionary by its magic), determinism across processes, zoom consistency of the output, and
//! clear errors for bad parameters (exit 1, a message naming the parameter, no file written).

use std::path::{Path, PathBuf};
use std::process::Command;

use terrasynth_core::raster::{read_geotiff_file, write_geotiff_file, Georef, Grid, ReadLimits};
use terrasynth_test_support::synthetic_terrain;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_terrasynth"))
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("run terrasynth");
    assert!(
        out.status.success(),
        "terrasynth failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn write_grid(path: &Path, rows: usize, cols: usize, seed: u64) -> PathBuf {
    let g = Grid::new(
        synthetic_terrain(rows, cols, seed),
        Georef {
            crs: terrasynth_core::raster::Crs::Epsg4326,
            west: 70.0,
            north: 41.5,
            pixel_width: 1.0 / 240.0,
            pixel_height: 1.0 / 240.0,
        },
    );
    write_geotiff_file(&g, path).unwrap();
    path.to_path_buf()
}

fn amplify(set: &Path, input: &Path, out: &Path) {
    run_ok(
        bin()
            .args(["amplify", "--dictionary"])
            .arg(set)
            .arg("--input")
            .arg(input)
            .args(["--levels", "2", "--output"])
            .arg(out),
    );
}

#[test]
fn gradient_build_then_amplify_is_deterministic_and_consistent() {
    let dir = tempfile::tempdir().unwrap();
    let ex = write_grid(&dir.path().join("ex.tif"), 160, 180, 5);
    let set = dir.path().join("t.grad");
    let summary = run_ok(
        bin()
            .args(["dictionary", "build", "--kind", "gradient", "--exemplar"])
            .arg(&ex)
            .args(["--tile", "8", "--colours", "3", "--alternatives", "2"])
            .args(["--mixing", "0.5", "--output"])
            .arg(&set),
    );
    assert!(summary.contains("gradient tile set"), "{summary}");
    assert!(summary.contains("/9 colour combinations"), "{summary}");
    let bytes = std::fs::read(&set).unwrap();
    assert_eq!(&bytes[..8], b"TSGRAD\0\x01");

    let low = write_grid(&dir.path().join("low.tif"), 30, 40, 9);
    let (a, b) = (dir.path().join("a.tif"), dir.path().join("b.tif"));
    amplify(&set, &low, &a);
    amplify(&set, &low, &b);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let out = read_geotiff_file(&a, &ReadLimits::default()).unwrap();
    let input = read_geotiff_file(&low, &ReadLimits::default()).unwrap();
    assert_eq!((out.cols(), out.rows()), (160, 120));
    // 4×4 block means reproduce the input (zoom consistency).
    let mut worst = 0.0f32;
    for r in 0..30 {
        for c in 0..40 {
            let mut sum = 0.0f32;
            for dr in 0..4 {
                for dc in 0..4 {
                    sum += out.data[[4 * r + dr, 4 * c + dc]];
                }
            }
            worst = worst.max((sum / 16.0 - input.data[[r, c]]).abs());
        }
    }
    assert!(worst < 0.05, "worst block error {worst} m");
}

#[test]
fn bad_gradient_parameters_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let ex = write_grid(&dir.path().join("ex.tif"), 64, 64, 5);
    let set = dir.path().join("t.grad");
    for (flag, value, word) in [
        ("--tile", "6", "tile 6"),
        ("--colours", "1", "colours 1"),
        ("--alternatives", "0", "alternatives 0"),
        ("--mixing", "2", "mixing 2"),
    ] {
        let out = bin()
            .args(["dictionary", "build", "--kind", "gradient", "--exemplar"])
            .arg(&ex)
            .args([flag, value, "--output"])
            .arg(&set)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{flag} {value}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(word), "{flag}: {err}");
        assert!(!set.exists());
    }
    // A corrupted tile set is refused by `amplify`.
    std::fs::write(&set, b"TSGRAD\0\x01garbage").unwrap();
    let o = dir.path().join("o.tif");
    let out = bin()
        .args(["amplify", "--dictionary"])
        .arg(&set)
        .arg("--input")
        .arg(&ex)
        .args(["--levels", "1", "--output"])
        .arg(&o)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(!o.exists());
}
