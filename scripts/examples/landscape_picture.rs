//! Renders the picture of the README: the colour map of the default world with the drainage
//! overlay composited on top, as served (the tiles come from the same `render` the HTTP handler
//! calls). Builds the default dictionary into a store directory on first use.
//!
//! Usage: `cargo run --release --example landscape_picture -- [STORE_DIR] [OUT.png] [Z X0 Y0 COLS ROWS]`
//! (defaults: `target/picture-store`, `tests/pictures/landscape.png`, zoom 9 tiles 358..361 × 189..191 over
//! the Talas range).

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::error::Error;

use ndarray::Array2;
use terrasynth_tiles::{parse_request, render};

fn decode(bytes: &[u8]) -> Result<Vec<u8>, Box<dyn Error>> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info()?;
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("PNG too large")?];
    let info = reader.next_frame(&mut buf)?;
    buf.truncate(info.buffer_size());
    Ok(buf)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let store = args.first().map_or("target/picture-store", String::as_str);
    let out = args
        .get(1)
        .map_or("tests/pictures/landscape.png", String::as_str);
    let num = |i: usize, d: u32| args.get(i).and_then(|v| v.parse().ok()).unwrap_or(d);
    let (z, x0, y0, cols, rows) = (num(2, 9), num(3, 358), num(4, 189), num(5, 3), num(6, 2));
    let mut config = terrasynth::config::load(None, Vec::new())?;
    config.server.store_dir = store.into();
    let store = terrasynth_store::Store::open(&config.server.store_dir)?;
    let worlds = terrasynth::server::load_worlds(&config, &store)?;
    let world = worlds.get("tienshan").ok_or("no default world")?;
    let mut img = Array2::from_elem((256 * rows as usize, 256 * cols as usize), [0u8; 4]);
    let none = Default::default();
    for ty in 0..rows {
        for tx in 0..cols {
            let (x, y) = (x0 + tx, y0 + ty);
            let tile = |layer: &str| -> Result<Vec<u8>, Box<dyn Error>> {
                let req = parse_request(
                    "tienshan",
                    layer,
                    &z.to_string(),
                    &x.to_string(),
                    &format!("{y}.png"),
                    &none,
                )?;
                decode(&render(world, &req)?)
            };
            let colour = tile("color")?;
            let rivers = tile("drainage")?;
            for i in 0..256 * 256 {
                let a = u16::from(rivers[4 * i + 3]);
                let mut px = [0u8, 0, 0, 255];
                for k in 0..3 {
                    let c = u16::from(colour[4 * i + k]);
                    let r = u16::from(rivers[4 * i + k]);
                    px[k] = ((c * (255 - a) + r * a + 127) / 255) as u8;
                }
                img[[256 * ty as usize + i / 256, 256 * tx as usize + i % 256]] = px;
            }
        }
    }
    std::fs::write(out, terrasynth_tiles::encode_rgba_png(&img)?)?;
    println!(
        "wrote {out} (zoom {z}, tiles {x0}..{} × {y0}..{})",
        x0 + cols,
        y0 + rows
    );
    Ok(())
}
