//! Fixtures and helpers shared by terrasynth's test binaries (the core crate's and the root
//! package's), written once: synthetic terrain, small dictionaries and worlds, raster files in
//! every upload format ([this module](self)), measures of the landscape layers' coherence with
//! the served elevation (`coherence`, with the `tiles` feature), a Mapbox Vector Tile reader ([`mvt`]), and `terrasynth serve` processes on free ports with small
//! HTTP helpers ([`process`]). Test code: it panics on failure like the tests that use it.
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[cfg(feature = "tiles")]
pub mod coherence;
pub mod mvt;
pub mod process;

use std::sync::Arc;
use terrasynth_core::math;

use ndarray::Array2;
use terrasynth_core::dictionary::build::{build, BuildOptions, Exemplar};
use terrasynth_core::dictionary::{Dictionary, Learning};

/// A deterministic ridged terrain: sums of rotated sinusoids with a hashed perturbation, metres.
pub fn synthetic_terrain(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
    let s = seed as f64 * 0.37;
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let (x, y) = (c as f64, r as f64);
        let mut h = 800.0 + 3.0 * x - 2.0 * y;
        for (k, (fx, fy, amp)) in [
            (0.031, 0.017, 300.0),
            (-0.052, 0.047, 140.0),
            (0.11, -0.093, 60.0),
            (0.23, 0.19, 25.0),
            (-0.41, 0.37, 9.0),
        ]
        .iter()
        .enumerate()
        {
            let phase = s * (k as f64 + 1.0);
            let v = math::sin(fx * x + fy * y + phase);
            // Ridged: 1 − |sin| makes sharp crests.
            h += amp * (1.0 - 2.0 * v.abs());
        }
        h as f32
    })
}

/// A small dictionary built from synthetic terrain (patch 16, stride 4, 64 atoms).
pub fn small_dictionary(seed: u64) -> Arc<Dictionary> {
    small_dictionary_layers(seed, false)
}

/// [`small_dictionary`] whose atoms also carry the default world's vegetation layers (niche
/// model and seeding simulation on the exemplar, raised by 1000 m like the mini world's base).
/// Elevation atoms are the same as [`small_dictionary`]'s: learning only looks at elevation.
pub fn small_dictionary_with_vegetation(seed: u64) -> Arc<Dictionary> {
    small_dictionary_layers(seed, true)
}

fn small_dictionary_layers(seed: u64, vegetation: bool) -> Arc<Dictionary> {
    small_dictionary_of(synthetic_terrain(160, 160, seed), seed, vegetation)
}

/// A small dictionary (patch 16, stride 4, 64 atoms, as [`small_dictionary`]) built from the
/// square 100 m exemplar `z` (at least 32² cells), with the default world's vegetation layers when
/// `vegetation` (as [`small_dictionary_with_vegetation`]).
pub fn small_dictionary_of(z: Array2<f32>, seed: u64, vegetation: bool) -> Arc<Dictionary> {
    let rows = z.nrows();
    let layers = if vegetation {
        let cells = terrasynth_core::raster::CellSizes::uniform(rows, 100.0);
        terrasynth_core::landscape::exemplar_vegetation(
            &terrasynth_core::landscape::LandscapeConfig::tienshan(),
            &z.mapv(|v| v + 1000.0),
            &cells,
        )
    } else {
        Vec::new()
    };
    let ex = Exemplar {
        elevation: z,
        valid: None,
        cell_m: 100.0,
        layers,
    };
    let opts = BuildOptions {
        patch: 16,
        stride: 4,
        atoms: 64,
        learning: Learning::Medoids { iterations: 3 },
        seed,
        sparsity: 1,
    };
    Arc::new(build(&[ex], &opts, &mut |_, _| {}).expect("build a small dictionary"))
}

/// A 15″ EPSG:4326 georeference with its north-west corner at (74°E, 42.5°N).
pub fn georef_15s() -> terrasynth_core::raster::Georef {
    terrasynth_core::raster::Georef {
        crs: terrasynth_core::raster::Crs::Epsg4326,
        west: 74.0,
        north: 42.5,
        pixel_width: 1.0 / 240.0,
        pixel_height: 1.0 / 240.0,
    }
}

/// A GeoTIFF of synthetic terrain (`rows × cols` 15″ cells).
pub fn geotiff_bytes(rows: usize, cols: usize, seed: u64) -> Vec<u8> {
    let grid =
        terrasynth_core::raster::Grid::new(synthetic_terrain(rows, cols, seed), georef_15s());
    let mut out = std::io::Cursor::new(Vec::new());
    terrasynth_core::raster::write_geotiff(&grid, &mut out).expect("write a GeoTIFF");
    out.into_inner()
}

/// A 16-bit PNG of synthetic terrain.
pub fn png16_bytes(rows: usize, cols: usize, seed: u64) -> Vec<u8> {
    let grid =
        terrasynth_core::raster::Grid::new(synthetic_terrain(rows, cols, seed), georef_15s());
    terrasynth_core::raster::write_png16(&grid).expect("write a PNG")
}

/// An OpenEXR with an `elevation` and a `forest` channel.
pub fn exr_bytes(rows: usize, cols: usize, seed: u64) -> Vec<u8> {
    let grid =
        terrasynth_core::raster::Grid::new(synthetic_terrain(rows, cols, seed), georef_15s());
    let mut r = terrasynth_core::raster::LayeredRaster::from_elevation(grid);
    r.push_layer(
        "forest",
        Array2::from_shape_fn((rows, cols), |(a, b)| ((a + b) % 7) as f32 / 7.0),
    )
    .expect("a forest layer");
    terrasynth_core::raster::write_exr(&r).expect("write an EXR")
}

#[cfg(feature = "tiles")]
/// A world `mini` of synthetic terrain `heights` at 15″ whose north-west corner is 70°E 43°N
/// (EPSG:4326), native zoom 8, the default Tien Shan landscape.
pub fn mini_world(
    heights: Array2<f32>,
    dictionary: Arc<Dictionary>,
    dictionary_id: &str,
    max_zoom: u8,
    cache_bytes: u64,
) -> terrasynth_tiles::World {
    mini_world_bands(
        heights,
        vec![terrasynth_tiles::DictionaryBand::every_zoom(
            dictionary,
            dictionary_id,
        )],
        max_zoom,
        cache_bytes,
    )
    .expect("a valid mini world")
}

#[cfg(feature = "tiles")]
/// [`mini_world`] with a dictionary per zoom band.
pub fn mini_world_bands(
    heights: Array2<f32>,
    dictionaries: Vec<terrasynth_tiles::DictionaryBand>,
    max_zoom: u8,
    cache_bytes: u64,
) -> Result<terrasynth_tiles::World, terrasynth_tiles::TileError> {
    mini_world_parts(heights, dictionaries, Vec::new(), max_zoom, cache_bytes)
}

#[cfg(feature = "tiles")]
fn mini_world_parts(
    heights: Array2<f32>,
    dictionaries: Vec<terrasynth_tiles::DictionaryBand>,
    biomes: Vec<terrasynth_tiles::WorldBiome>,
    max_zoom: u8,
    cache_bytes: u64,
) -> Result<terrasynth_tiles::World, terrasynth_tiles::TileError> {
    let base = terrasynth_core::raster::Grid::new(heights, mini_georef());
    terrasynth_tiles::World::new(mini_parts(
        base,
        dictionaries,
        biomes,
        max_zoom,
        cache_bytes,
    ))
}

#[cfg(feature = "tiles")]
/// The parts of [`mini_world_bands`] (and of a biome world), for tests that change a few.
pub fn mini_parts(
    base: terrasynth_core::raster::Grid,
    dictionaries: Vec<terrasynth_tiles::DictionaryBand>,
    biomes: Vec<terrasynth_tiles::WorldBiome>,
    max_zoom: u8,
    cache_bytes: u64,
) -> terrasynth_tiles::WorldParts {
    terrasynth_tiles::WorldParts {
        name: "mini".into(),
        title: "Mini".into(),
        attribution: "synthetic".into(),
        base,
        z_base: Some(8),
        max_zoom,
        fill_m: 0.0,
        dictionaries,
        weights: terrasynth_core::dictionary::MatchWeights::default(),
        cache_bytes,
        landscape: terrasynth_core::landscape::LandscapeConfig::tienshan(),
        center: None,
        sparsity: None,
        water: terrasynth_core::landscape::WaterConfig::default(),
        classes: None,
        biomes,
        controls: Vec::new(),
    }
}

#[cfg(feature = "tiles")]
/// [`mini_world`] painted with `biomes` (no `dictionaries`): a biome world (#15).
pub fn mini_world_biomes(
    heights: Array2<f32>,
    biomes: Vec<terrasynth_tiles::WorldBiome>,
    max_zoom: u8,
    cache_bytes: u64,
) -> Result<terrasynth_tiles::World, terrasynth_tiles::TileError> {
    mini_world_parts(heights, Vec::new(), biomes, max_zoom, cache_bytes)
}

#[cfg(feature = "tiles")]
/// [`mini_world_biomes`] with landscape `landscape` instead of the default world's.
pub fn mini_world_biomes_with(
    heights: Array2<f32>,
    biomes: Vec<terrasynth_tiles::WorldBiome>,
    landscape: terrasynth_core::landscape::LandscapeConfig,
    max_zoom: u8,
    cache_bytes: u64,
) -> Result<terrasynth_tiles::World, terrasynth_tiles::TileError> {
    let base = terrasynth_core::raster::Grid::new(heights, mini_georef());
    terrasynth_tiles::World::new(terrasynth_tiles::WorldParts {
        landscape,
        ..mini_parts(base, Vec::new(), biomes, max_zoom, cache_bytes)
    })
}

#[cfg(feature = "tiles")]
/// The georeference of [`mini_world`]'s base: 15″ cells from 70°E 43°N.
pub fn mini_georef() -> terrasynth_core::raster::Georef {
    terrasynth_core::raster::Georef {
        crs: terrasynth_core::raster::Crs::Epsg4326,
        west: 70.0,
        north: 43.0,
        pixel_width: 1.0 / 240.0,
        pixel_height: 1.0 / 240.0,
    }
}

/// The XYZ tile `(x, y)` holding longitude/latitude `(lon, lat)` at zoom `z`: the standard
/// slippy-map formula, written independently of the tiles crate.
pub fn tile_of(lon: f64, lat: f64, z: u8) -> (u32, u32) {
    let n = f64::from(1u32 << z);
    let x = ((lon + 180.0) / 360.0 * n).floor() as u32;
    let lr = lat.to_radians();
    let y = ((1.0 - math::log(math::tan(lr) + 1.0 / math::cos(lr)) / std::f64::consts::PI) / 2.0
        * n)
        .floor() as u32;
    (x, y)
}

/// Every file of a store's object directories with its size (what a rejected request must not
/// change).
pub fn store_files(store: &std::path::Path) -> std::collections::BTreeMap<String, u64> {
    let mut out = std::collections::BTreeMap::new();
    for sub in ["exemplars", "dictionaries", "worlds", "aliases"] {
        if let Ok(rd) = std::fs::read_dir(store.join(sub)) {
            for e in rd.flatten() {
                let len = e.metadata().map(|m| m.len()).unwrap_or(0);
                out.insert(format!("{sub}/{}", e.file_name().to_string_lossy()), len);
            }
        }
    }
    out
}
