//! Renders the README picture of a sketch and the world `terrasynth sketch` made from it: on the
//! left the sketch's lines (ridges red, valleys blue) over the world's extent, on the right the
//! world shaded (hillshade × a hypsometric tint, stretched to the world's own range).
//!
//! Usage: `cargo run --example sketch_picture -- SKETCH.geojson BASE.tif OUT.png`

// A picture tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::error::Error;
use std::io::BufWriter;

use terrasynth_core::analysis::hillshade_u8;
use terrasynth_core::raster::{read_geotiff_file, ReadLimits};

const RIDGE: [u8; 3] = [215, 35, 35];
const VALLEY: [u8; 3] = [30, 70, 225];

/// The colour of relative height `t` (0–1): green lowlands to brown slopes to white peaks.
fn tint(t: f64) -> [f64; 3] {
    let ramp = [
        (0.0, [70.0, 120.0, 60.0]),
        (0.35, [150.0, 160.0, 90.0]),
        (0.6, [170.0, 130.0, 80.0]),
        (0.85, [140.0, 110.0, 100.0]),
        (1.0, [250.0, 250.0, 250.0]),
    ];
    for w in ramp.windows(2) {
        if t <= w[1].0 {
            let f = ((t - w[0].0) / (w[1].0 - w[0].0)).clamp(0.0, 1.0);
            return [0, 1, 2].map(|k| w[0].1[k] * (1.0 - f) + w[1].1[k] * f);
        }
    }
    ramp[4].1
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [sketch, base, out] = args.as_slice() else {
        return Err("usage: sketch_picture SKETCH.geojson BASE.tif OUT.png".into());
    };
    let fc: serde_json::Value = serde_json::from_slice(&std::fs::read(sketch)?)?;
    let grid = read_geotiff_file(std::path::Path::new(base), &ReadLimits::default())?;
    let (rows, cols) = grid.data.dim();
    let g = grid.georef;
    let (lo, hi) = grid.min_max().ok_or("empty base")?;
    let shade = hillshade_u8(&grid.data, &g.cell_sizes(rows), 315.0, 45.0);
    let w = 2 * cols + 8;
    let mut img = vec![255u8; w * rows * 3];
    let mut put = |r: i64, c: i64, panel: usize, col: [u8; 3]| {
        if r >= 0 && c >= 0 && (r as usize) < rows && (c as usize) < cols {
            let i = (r as usize * w + panel * (cols + 8) + c as usize) * 3;
            img[i..i + 3].copy_from_slice(&col);
        }
    };
    for r in 0..rows {
        for c in 0..cols {
            put(r as i64, c as i64, 0, [236, 233, 226]);
            let t = f64::from((grid.data[[r, c]] - lo) / (hi - lo).max(1.0));
            let s = 0.4 + 0.6 * f64::from(shade[[r, c]]) / 255.0;
            put(
                r as i64,
                c as i64,
                1,
                tint(t).map(|v| (v * s).clamp(0.0, 255.0) as u8),
            );
        }
    }
    for f in fc["features"].as_array().ok_or("no features")? {
        let colour = if f["properties"]["kind"] == "ridge" {
            RIDGE
        } else {
            VALLEY
        };
        let pts: Vec<(f64, f64)> = f["geometry"]["coordinates"]
            .as_array()
            .ok_or("no coordinates")?
            .iter()
            .map(|p| {
                let (lon, lat) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
                (
                    (lon - g.west) / g.pixel_width,
                    (g.north - lat) / g.pixel_height,
                )
            })
            .collect();
        for seg in pts.windows(2) {
            let ((x0, y0), (x1, y1)) = (seg[0], seg[1]);
            let steps = ((x1 - x0).abs().max((y1 - y0).abs()) * 2.0).ceil() as usize + 1;
            for k in 0..=steps {
                let t = k as f64 / steps as f64;
                let (x, y) = ((x0 + t * (x1 - x0)) as i64, (y0 + t * (y1 - y0)) as i64);
                for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1), (-1, 0), (0, -1)] {
                    put(y + dr, x + dc, 0, colour);
                }
            }
        }
    }
    let file = std::fs::File::create(out)?;
    let mut enc = png::Encoder::new(BufWriter::new(file), w as u32, rows as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    enc.write_header()?.write_image_data(&img)?;
    println!("wrote {out} ({w}×{rows})");
    Ok(())
}
