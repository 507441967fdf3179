//! Renders the README picture of painted biomes (#15): a world over the Kyrgyz Ala-Too whose west
//! half is painted with the default dictionary (the whole western Tien Shan: alpine relief) and
//! whose east half with a dictionary of Karatau and the steppe (the low-relief crop
//! `256,0,512,512` of the committed GEBCO raster), served through `[[biomes]]` in a world file,
//! and drawn as the served hillshade of a mosaic of tiles across the painted boundary (the same
//! `render` the HTTP handler calls), red ticks at the top and bottom marking the boundary. Dictionaries are built into a store directory on first use.
//!
//! Usage: `cargo run --example biomes_picture -- [STORE_DIR] [OUT.png] [Z]`
//! (defaults: `target/biomes-picture-store`, `tests/pictures/biomes.png`, zoom 11).

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::error::Error;
use std::path::Path;

use ndarray::{s, Array2};
use terrasynth_core::math;
use terrasynth_core::raster::{embedded, write_geotiff_file, Grid};
use terrasynth_tiles::{parse_request, render};

/// The base: columns 1900..2160 and rows 440..600 of the embedded raster (73.6–74.7°E,
/// 42.2–42.9°N, the Kyrgyz Ala-Too south of Bishkek).
const BASE: (usize, usize, usize, usize) = (1900, 440, 260, 160);
/// The painted boundary: base columns west of it are alpine, east of it steppe.
const BOUNDARY: usize = 130;

fn crop(g: &Grid, (col, row, w, h): (usize, usize, usize, usize)) -> Grid {
    Grid::new(
        g.data.slice(s![row..row + h, col..col + w]).to_owned(),
        g.georef.window(col as i64, row as i64),
    )
}

fn decode(bytes: &[u8]) -> Result<Vec<u8>, Box<dyn Error>> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info()?;
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("PNG too large")?];
    let info = reader.next_frame(&mut buf)?;
    buf.truncate(info.buffer_size());
    Ok(buf)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let store_dir = args
        .first()
        .map_or("target/biomes-picture-store", String::as_str);
    let out = args
        .get(1)
        .map_or("tests/pictures/biomes.png", String::as_str);
    let z: u8 = args.get(2).and_then(|v| v.parse().ok()).unwrap_or(11);
    std::fs::create_dir_all(store_dir)?;
    let files = Path::new(store_dir).join("world");
    std::fs::create_dir_all(&files)?;
    let tienshan = embedded::tienshan()?;
    let base = crop(&tienshan, BASE);
    write_geotiff_file(&base, &files.join("base.tif"))?;
    write_geotiff_file(
        &crop(&tienshan, (256, 0, 512, 512)),
        &files.join("karatau.tif"),
    )?;
    let (rows, cols) = base.data.dim();
    let west = Array2::from_shape_fn((rows, cols), |(_, c)| f32::from(u8::from(c < BOUNDARY)));
    write_geotiff_file(
        &Grid::new(west.clone(), base.georef),
        &files.join("alpine.tif"),
    )?;
    write_geotiff_file(
        &Grid::new(west.mapv(|v| 1.0 - v), base.georef),
        &files.join("steppe.tif"),
    )?;
    let world_file = files.join("biomes.toml");
    std::fs::write(
        &world_file,
        "name = \"biomes\"\nbase = \"base.tif\"\nz_base = 8\nmax_zoom = 13\n\
         [[biomes]]\nname = \"alpine\"\nweight = \"alpine.tif\"\n\
         [biomes.dictionary]\nexemplars = [\"embedded:tienshan\"]\n\
         [[biomes]]\nname = \"steppe\"\nweight = \"steppe.tif\"\n\
         [biomes.dictionary]\nexemplars = [\"karatau.tif\"]\n",
    )?;
    let server = Path::new(store_dir).join("server.toml");
    std::fs::write(
        &server,
        format!(
            "worlds = [{:?}]\n",
            world_file.canonicalize()?.display().to_string(),
        ),
    )?;
    let mut config = terrasynth::config::load(Some(&server), Vec::new())?;
    config.server.store_dir = Path::new(store_dir).join("store");
    let store = terrasynth_store::Store::open(&config.server.store_dir)?;
    let worlds = terrasynth::server::load_worlds(&config, &store)?;
    let world = worlds.get("biomes").ok_or("no biome world")?;
    // 4 × 2 tiles centred on the boundary's longitude, at the base's middle latitude.
    let lon = base.georef.west + BOUNDARY as f64 * base.georef.pixel_width;
    let lat = base.georef.north - rows as f64 / 2.0 * base.georef.pixel_height;
    let n = f64::from(1u32 << z);
    let tx = ((lon + 180.0) / 360.0 * n).floor() as u32;
    let lr = lat.to_radians();
    let ty = ((1.0 - math::log(math::tan(lr) + 1.0 / math::cos(lr)) / std::f64::consts::PI) / 2.0
        * n)
        .floor() as u32;
    let (x0, y0, tcols, trows) = (tx - 2, ty - 1, 4u32, 2u32);
    let mut img = Array2::from_elem((256 * trows as usize, 256 * tcols as usize), [0u8; 4]);
    let none = Default::default();
    for dy in 0..trows {
        for dx in 0..tcols {
            let (x, y) = (x0 + dx, y0 + dy);
            let req = parse_request(
                "biomes",
                "hillshade",
                &z.to_string(),
                &x.to_string(),
                &format!("{y}.png"),
                &none,
            )?;
            let px = decode(&render(world, &req)?)?;
            let channels = px.len() / (256 * 256);
            for i in 0..256 * 256 {
                let v = px[channels * i];
                img[[256 * dy as usize + i / 256, 256 * dx as usize + i % 256]] = [v, v, v, 255];
            }
        }
    }
    // Red ticks (12 px) at the top and bottom edges mark the painted boundary's column.
    let bc = ((lon + 180.0) / 360.0 * n * 256.0).floor() as usize - 256 * x0 as usize;
    let h = img.nrows();
    for r in (0..12).chain(h - 12..h) {
        for c in bc.saturating_sub(1)..=bc + 1 {
            img[[r, c]] = [220, 30, 30, 255];
        }
    }
    std::fs::write(out, terrasynth_tiles::encode_rgba_png(&img)?)?;
    println!(
        "wrote {out} (zoom {z}, tiles {x0}..{} × {y0}..{}, boundary at {lon:.4}°E)",
        x0 + tcols,
        y0 + trows
    );
    Ok(())
}
