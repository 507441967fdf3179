//! Measures issue #12's served-tile acceptance (points 3 and 5) on the default world, on the
//! tiles exactly as the server renders them (elevation decoded from terrarium PNGs as a client
//! sees it, upstream area as the drainage EXR carries it), around the Kyrgyz Ala-Too point whose
//! tiles the tile-hash list holds (zoom-10 tile 724/378 and its descendants):
//!
//! - flood extent (% of the mosaic that priority-flood filling raises) of 8×8 mosaics at zooms
//!   10, 12 and 14 (acceptance 5: ≤ 5 %);
//! - drainage continuity: over the same mosaics, the runs of channel pixels (upstream area
//!   ≥ 10⁶ m², what the drainage PNG draws) that lie on a tile's outermost row or column next to
//!   another tile of the mosaic, and the share of them with a channel pixel among the three
//!   pixels facing them across the border (acceptance 5: ≥ 90 %);
//! - pixel-axis anisotropy ([`axis_anisotropy`]) of 2×2 mosaics (512²) at zooms 8 (native, for
//!   reference), 10, 12, 13 and 14 (acceptance 3: ≤ 1.5);
//! - over the 8×8 mosaics, the share of channel pixels below [`FAINT_M2`]: those a drainage PNG
//!   without its opacity floor (`png_min_opacity` 0, the ramp from 10⁶ to 10¹⁰ m²) drew at under
//!   25 % opacity, and the floor now draws at 40–55 %.
//!
//! Usage: `cargo run --release --example served_realism -- [STORE_DIR [WORLD X10 Y10
//! [EXEMPLAR.tif]]]` (default `target/picture-store`, which builds the default dictionary there on
//! first use; `WORLD`: any world of the configuration or created through the admin API in that
//! store, its mosaics centred on the corner of zoom-10 tile `X10/Y10` instead of the default
//! world's; `EXEMPLAR.tif`: the raster the world's dictionary was cut from, whose own anisotropy,
//! on its pixel grid and on the square cells the atoms are cut from, is printed first: the
//! amplifier carries the exemplar's axis statistics into every level). Prints a markdown table.

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::error::Error;
use std::path::Path;

use ndarray::Array2;
use terrasynth_core::analysis::flood_extent;
use terrasynth_core::analysis::realism::axis_anisotropy;
use terrasynth_core::raster::{read_raster_file, ReadLimits, SquareCells};
use terrasynth_test_support::coherence::{decoded_elevation, served_drainage};

/// Upstream area from which the drainage PNG draws a channel (its default `png_min_m2`).
const CHANNEL_M2: f32 = 1e6;

/// Upstream area below which the drainage PNG's ramp from 10⁶ to 10¹⁰ m² (log-linear, without
/// an opacity floor) stays under 25 % opacity.
const FAINT_M2: f32 = 1e7;

/// The zoom-10 tile whose corner every mosaic is centred on.
const CENTRE_Z10: (u32, u32) = (724, 378);

/// The first tile of an `n × n` mosaic at zoom `z` centred on the corner of zoom-10 tile
/// `centre`.
fn origin(centre: (u32, u32), z: u8, n: u32) -> (u32, u32) {
    let (x, y) = if z >= 10 {
        (centre.0 << (z - 10), centre.1 << (z - 10))
    } else {
        (centre.0 >> (10 - z), centre.1 >> (10 - z))
    };
    (x - n / 2, y - n / 2)
}

/// Runs of channel pixels on tile borders and how many continue across (see the module docs).
fn continuity(area: &Array2<f32>) -> (usize, usize) {
    let size = area.nrows();
    let ch = |r: usize, c: usize| area[[r, c]] >= CHANNEL_M2;
    let (mut reached, mut continued) = (0, 0);
    // Every internal border line: between column/row b−1 and b for b = 256, 512, ...
    for b in (256..size).step_by(256) {
        for (inside, across) in [(b - 1, b), (b, b - 1)] {
            for vertical in [true, false] {
                let at = |t: usize, line: usize| if vertical { ch(t, line) } else { ch(line, t) };
                let mut t = 0;
                while t < size {
                    if !at(t, inside) {
                        t += 1;
                        continue;
                    }
                    let start = t;
                    while t < size && at(t, inside) {
                        t += 1;
                    }
                    reached += 1;
                    let lo = start.saturating_sub(1);
                    let hi = (t + 1).min(size);
                    if (lo..hi).any(|u| at(u, across)) {
                        continued += 1;
                    }
                }
            }
        }
    }
    (reached, continued)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let store = args.first().map_or("target/picture-store", String::as_str);
    let mut config = terrasynth::config::load(None, Vec::new())?;
    config.server.store_dir = store.into();
    // The configured worlds and those created through the admin API, as the server loads them.
    let state = terrasynth::server::startup::build_state(&config)?;
    let (name, centre, exemplar) = match args.get(1..).unwrap_or_default() {
        [] => ("tienshan", CENTRE_Z10, None),
        [name, x, y] => (name.as_str(), (x.parse()?, y.parse()?), None),
        [name, x, y, exemplar] => (name.as_str(), (x.parse()?, y.parse()?), Some(exemplar)),
        _ => return Err("usage: served_realism [STORE_DIR [WORLD X10 Y10 [EXEMPLAR.tif]]]".into()),
    };
    if let Some(path) = exemplar {
        let grid = read_raster_file(Path::new(path), None, &ReadLimits::default())?
            .elevation()
            .ok_or("the exemplar has no elevation band")?;
        let (rows, cols) = grid.data.dim();
        // The grid the atoms are cut from: dictionary builds square the cells first.
        let square = SquareCells::for_grid(&grid.georef, rows, cols).grid(&grid)?;
        let (sq_rows, sq_cols) = square.data.dim();
        println!(
            "exemplar {path} ({cols}×{rows}): anisotropy {:.3} on its own pixel grid, {:.3} on \
             the square cells ({sq_cols}×{sq_rows}) the atoms are cut from\n",
            axis_anisotropy(&grid.filled()?),
            axis_anisotropy(&square.filled()?)
        );
    }
    let world = state
        .world(name)
        .map_err(|_| format!("no world {name} in the configuration or the store"))?;
    let world = world.as_ref();

    println!("| zoom | mosaic (tiles from) | flood extent, % | channel runs on borders | continue across | anisotropy (2×2) | channel px under 10⁷ m² |");
    println!("| ---: | --- | ---: | ---: | ---: | ---: | ---: |");
    for z in [8u8, 10, 12, 13, 14] {
        let (ax, ay) = origin(centre, z, 2);
        let small = decoded_elevation(world, z, ax, ay, 2);
        let aniso = axis_anisotropy(&small);
        if matches!(z, 10 | 12 | 14) {
            let n = 8;
            let (x0, y0) = origin(centre, z, n);
            let elev = decoded_elevation(world, z, x0, y0, n);
            let area = served_drainage(world, z, x0, y0, n);
            let flood = flood_extent(&elev);
            let (reached, continued) = continuity(&area);
            let channel = area.iter().filter(|&&a| a >= CHANNEL_M2).count();
            let faint = area
                .iter()
                .filter(|&&a| (CHANNEL_M2..FAINT_M2).contains(&a))
                .count();
            println!(
                "| {z} | 8×8 ({x0}, {y0}) | {flood:.2} | {reached} | {:.1} % | {aniso:.3} | {:.1} % of {channel} |",
                100.0 * continued as f64 / reached.max(1) as f64,
                100.0 * faint as f64 / channel.max(1) as f64
            );
        } else {
            println!("| {z} | 2×2 ({ax}, {ay}) | — | — | — | {aniso:.3} | — |");
        }
    }
    Ok(())
}
