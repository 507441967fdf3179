//! Measures the default world's deep dictionary band (zoom 16 amplified with detail learned
//! from the Carrizo Plain 2 m lidar) against the same world with its Tien Shan dictionary at
//! every zoom, on served tiles (elevation decoded from terrarium PNGs) around the Kyrgyz Ala-Too
//! corner of zoom-10 tile 724/378 (the tile-hash list's point): per zoom 14–16, a 4×4 mosaic's
//! flood extent, slope (mean, 90th percentile), curvature spread (standard deviation of the
//! Laplacian, 1/m), the share of spectral energy in the finest octave (0.25–0.5 cycles/pixel)
//! and pixel-axis anisotropy; the same figures of the lidar exemplar itself for reference; and
//! hillshades of zoom-16 2×2 mosaics of both worlds side by side (`OUT/deep-band-z16.png`).
//!
//! Usage: `cargo run --release --example deep_band -- [STORE_DIR] [OUT_DIR]` (defaults
//! `target/picture-store`, `target/deep-band`; builds missing dictionaries there). Prints a
//! markdown table and the time the world load took (the dictionary builds on a fresh store).

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::error::Error;
use std::fs::File;
use std::io::BufWriter;
use std::time::Instant;

use ndarray::{concatenate, s, Array2, Axis};
use terrasynth_core::analysis::realism::axis_anisotropy;
use terrasynth_core::analysis::{
    band_energy, curvature, flood_extent, hillshade_u8, slope_degrees,
};
use terrasynth_core::raster::{embedded, CellSizes};
use terrasynth_test_support::coherence::decoded_elevation;
use terrasynth_tiles::World;

/// The zoom-10 tile whose corner every mosaic is centred on.
const CENTRE_Z10: (u32, u32) = (724, 378);

/// The first tile of an `n × n` mosaic at zoom `z ≥ 10` centred on [`CENTRE_Z10`]'s corner.
fn origin(z: u8, n: u32) -> (u32, u32) {
    let (x, y) = (CENTRE_Z10.0 << (z - 10), CENTRE_Z10.1 << (z - 10));
    (x - n / 2, y - n / 2)
}

/// Flood extent %, mean and 90th-percentile slope (°), Laplacian standard deviation (1/m),
/// finest-octave energy share, anisotropy.
fn figures(z: &Array2<f32>, cs: &CellSizes) -> [f64; 6] {
    let mut sl: Vec<f64> = slope_degrees(z, cs).iter().map(|&v| f64::from(v)).collect();
    sl.retain(|v| v.is_finite());
    sl.sort_by(f64::total_cmp);
    let mean = sl.iter().sum::<f64>() / sl.len() as f64;
    let p90 = sl[sl.len() * 9 / 10];
    let k: Vec<f64> = curvature(z, cs)
        .iter()
        .map(|&v| f64::from(v))
        .filter(|v| v.is_finite())
        .collect();
    let km = k.iter().sum::<f64>() / k.len() as f64;
    let ksd = (k.iter().map(|v| (v - km).powi(2)).sum::<f64>() / k.len() as f64).sqrt();
    let fine = band_energy(z, 0.25, 0.5) / band_energy(z, 0.0, 0.5);
    [flood_extent(z), mean, p90, ksd, fine, axis_anisotropy(z)]
}

fn row(label: &str, f: [f64; 6]) {
    println!(
        "| {label} | {:.2} | {:.1} | {:.1} | {:.4} | {:.2e} | {:.2} |",
        f[0], f[1], f[2], f[3], f[4], f[5]
    );
}

fn hillshade(world: &World, z: u8, n: u32) -> Array2<u8> {
    let (x0, y0) = origin(z, n);
    let e = decoded_elevation(world, z, x0, y0, n);
    let cs = world.cell_sizes(z, i64::from(y0) * 256, e.nrows());
    hillshade_u8(&e, &cs, 315.0, 45.0)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let store_dir = args.first().map_or("target/picture-store", String::as_str);
    let out_dir = args.get(1).map_or("target/deep-band", String::as_str);
    std::fs::create_dir_all(out_dir)?;
    let mut config = terrasynth::config::load(None, Vec::new())?;
    config.server.store_dir = store_dir.into();
    // The same world with its first (Tien Shan) dictionary at every zoom.
    let mut one = config.worlds[0].clone();
    one.name = "tienshan-one".into();
    one.dictionaries.truncate(1);
    one.dictionaries[0].zooms = None;
    config.worlds.push(one);
    let store = terrasynth_store::Store::open(&config.server.store_dir)?;
    let t = Instant::now();
    let worlds = terrasynth::server::load_worlds(&config, &store)?;
    println!("worlds loaded in {:.1} s\n", t.elapsed().as_secs_f64());
    let banded = worlds.get("tienshan").ok_or("no default world")?;
    let one = worlds.get("tienshan-one").ok_or("no comparison world")?;

    println!("| world, zoom (4×4 mosaic) | flood extent, % | slope mean, ° | slope p90, ° | Laplacian sd, 1/m | finest-octave energy share | anisotropy |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: |");
    for z in [14u8, 15, 16] {
        let (x0, y0) = origin(z, 4);
        for (name, w) in [("Tien Shan only", one), ("lidar band", banded)] {
            let e = decoded_elevation(w, z, x0, y0, 4);
            let cs = w.cell_sizes(z, i64::from(y0) * 256, e.nrows());
            row(&format!("{name}, z{z}"), figures(&e, &cs));
        }
    }
    let lidar = embedded::carrizo()?;
    let window = lidar.data.slice(s![0..512, 0..504]).to_owned();
    row(
        "Carrizo lidar itself (2 m, 512×504)",
        figures(&window, &CellSizes::uniform(512, 2.0)),
    );

    // Zoom-16 hillshades side by side, a 16-px white gap between.
    let a = hillshade(one, 16, 2);
    let b = hillshade(banded, 16, 2);
    let gap = Array2::from_elem((a.nrows(), 16), 255u8);
    let pic = concatenate(Axis(1), &[a.view(), gap.view(), b.view()])?;
    let path = format!("{out_dir}/deep-band-z16.png");
    let mut enc = png::Encoder::new(
        BufWriter::new(File::create(&path)?),
        pic.ncols() as u32,
        pic.nrows() as u32,
    );
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    let mut w = enc.write_header()?;
    w.write_image_data(&pic.iter().copied().collect::<Vec<u8>>())?;
    w.finish()?;
    println!("\n{path}: zoom-16 hillshades, Tien Shan dictionary only (left), lidar band (right)");
    Ok(())
}
