//! Painted biomes (#15, acceptance 4): a world painted 1 for biome A everywhere serves the tiles
//! of the world with A alone (every layer, bit for bit); across a painted boundary tiles stay
//! seamless (the seam measure of [`crate::server::border_and_interior_steps`]) and carry each
//! biome's own detail away from it; a biome world is deterministic, a tile alone equals the
//! window of a block, and any window equals the same part of a larger one; materials and
//! species follow `biome.<name>` terms; gradient tile sets are biomes too; painted species
//! controls replace or scale a species' density.

use std::sync::Arc;

use ndarray::{s, Array2};

use terrasynth_core::dictionary::Dictionary;
use terrasynth_core::math;
use terrasynth_core::raster::Grid;
use terrasynth_core::synth::Window;
use terrasynth_test_support::coherence::mosaic_of;
use terrasynth_test_support::{
    mini_georef, mini_world, mini_world_biomes, small_dictionary_of,
    small_dictionary_with_vegetation, synthetic_terrain, tile_of,
};
use terrasynth_tiles::{World, WorldBiome};

use crate::server::border_and_interior_steps;

const ROWS: usize = 240;
const COLS: usize = 288;
/// The painted boundary: columns west of it are biome A's, east of it biome B's.
const BOUNDARY_COL: usize = 144;

fn base() -> Array2<f32> {
    synthetic_terrain(ROWS, COLS, 3).mapv(|v| v + 1000.0)
}

/// Biome A: the tests' usual small dictionary (ridged terrain).
fn dict_a() -> Arc<Dictionary> {
    small_dictionary_with_vegetation(2)
}

/// Biome B: a dictionary of other terrain (another seed, a tenth of the relief, tilted).
fn dict_b() -> Arc<Dictionary> {
    let z = synthetic_terrain(160, 160, 9);
    let low = Array2::from_shape_fn((160, 160), |(r, c)| {
        0.1 * z[[r, c]] + 0.5 * r as f32 + 30.0 * math::sinf((c as f32) * 0.3)
    });
    small_dictionary_of(low, 9, true)
}

fn biome(name: &str, d: Arc<Dictionary>, id: &str, w: impl Fn(usize, usize) -> f32) -> WorldBiome {
    WorldBiome {
        name: name.into(),
        dictionary: d.into(),
        id: id.into(),
        weight: Grid::new(
            Array2::from_shape_fn((ROWS, COLS), |(r, c)| w(r, c)),
            mini_georef(),
        ),
    }
}

fn world_alone(d: Arc<Dictionary>, id: &str) -> World {
    mini_world(base(), d, id, 11, 64 << 20)
}

/// A west of [`BOUNDARY_COL`], B east of it.
fn painted_world() -> World {
    mini_world_biomes(
        base(),
        vec![
            biome("ridges", dict_a(), "a", |_, c| {
                f32::from(u8::from(c < BOUNDARY_COL))
            }),
            biome("steppe", dict_b(), "b", |_, c| {
                f32::from(u8::from(c >= BOUNDARY_COL))
            }),
        ],
        11,
        64 << 20,
    )
    .unwrap()
}

fn same_bits(a: &Array2<f32>, b: &Array2<f32>) -> bool {
    a.dim() == b.dim() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Longitude of the painted boundary (the west edge of column [`BOUNDARY_COL`]).
fn boundary_lon() -> f64 {
    70.0 + BOUNDARY_COL as f64 / 240.0
}

/// Global pixel column of longitude `lon` at zoom `z` (the Web Mercator formula, written here).
fn pixel_col(lon: f64, z: u8) -> f64 {
    (lon + 180.0) / 360.0 * f64::from(1u32 << z) * 256.0
}

#[test]
fn a_biome_painted_everywhere_serves_the_tiles_of_its_world_alone() {
    let alone = world_alone(dict_a(), "a");
    // B listed first with weight 0 everywhere, A with 1: A is the dominant biome, B is never
    // computed, and nothing of the blend touches A's bits.
    let painted = mini_world_biomes(
        base(),
        vec![
            biome("steppe", dict_b(), "b", |_, _| 0.0),
            biome("ridges", dict_a(), "a", |_, _| 1.0),
        ],
        11,
        64 << 20,
    )
    .unwrap();
    assert_eq!(painted.biome_names(), ["steppe", "ridges"]);
    assert_eq!(painted.dictionary_ids(), ["b", "a"]);
    let mut tiles = Vec::new();
    for z in [8u8, 9, 10, 11] {
        // Inside the base, and straddling its west edge (pixels outside it: the fill).
        tiles.push((z, tile_of(70.5, 42.5, z)));
        tiles.push((z, tile_of(70.0, 42.5, z)));
    }
    for (z, (x, y)) in tiles {
        let what = format!("{z}/{x}/{y}");
        assert!(
            same_bits(
                &alone.elevation_tile(z, x, y).unwrap(),
                &painted.elevation_tile(z, x, y).unwrap()
            ),
            "elevation {what}"
        );
        let (va, vp) = (
            alone.vegetation_tile(z, x, y).unwrap(),
            painted.vegetation_tile(z, x, y).unwrap(),
        );
        assert_eq!(va.len(), vp.len());
        for (a, p) in va.iter().zip(vp.iter()) {
            assert!(same_bits(a, p), "vegetation {what}");
        }
        assert!(
            same_bits(
                &alone.drainage_tile(z, x, y).unwrap(),
                &painted.drainage_tile(z, x, y).unwrap()
            ),
            "drainage {what}"
        );
        let (alone_materials, painted_materials) = (
            alone.material_tile(z, x, y).unwrap(),
            painted.material_tile(z, x, y).unwrap(),
        );
        let (ma, ha) = (&alone_materials.weights, &alone_materials.shade);
        let (mp, hp) = (&painted_materials.weights, &painted_materials.shade);
        assert!(same_bits(ha, hp), "hillshade {what}");
        for (a, p) in ma.iter().zip(mp) {
            assert!(same_bits(a, p), "materials {what}");
        }
        let ((da, la), (dp, lp)) = (
            alone.water_tile(z, x, y).unwrap(),
            painted.water_tile(z, x, y).unwrap(),
        );
        assert!(same_bits(&da, &dp) && same_bits(&la, &lp), "water {what}");
    }
    // The comparison can fail: B alone amplifies differently.
    let (x, y) = tile_of(70.5, 42.5, 10);
    let b = world_alone(dict_b(), "b");
    assert!(!same_bits(
        &alone.elevation_tile(10, x, y).unwrap(),
        &b.elevation_tile(10, x, y).unwrap()
    ));
}

#[test]
fn tiles_are_seamless_across_a_painted_boundary_and_carry_each_biome_away_from_it() {
    let z = 10u8;
    let (bx, by) = tile_of(boundary_lon(), 42.5, z);
    let (x0, y0) = (bx - 1, by - 1);
    let painted = painted_world();
    let mosaic = |w: &World| {
        mosaic_of(3, |dx, dy| {
            w.elevation_tile(z, x0 + dx, y0 + dy)
                .unwrap()
                .as_ref()
                .clone()
        })
    };
    let m = mosaic(&painted);
    let (border, inner) = border_and_interior_steps(&m);
    eprintln!("z{z} across the painted boundary: border step {border:.4} vs interior {inner:.4}");
    assert!(
        border <= 1.25 * inner,
        "z{z} across the painted boundary: border step {border} vs interior {inner}"
    );
    // West of the boundary the tiles are biome A's, east of it biome B's: away from the
    // boundary (64 pixels, more than the reach of two levels' halos) bit for bit those of the
    // worlds with A or B alone; between, a blend of both.
    let boundary = pixel_col(boundary_lon(), z) - f64::from(x0 * 256);
    let b_col = boundary.round() as usize;
    let a = mosaic(&world_alone(dict_a(), "a"));
    let b = mosaic(&world_alone(dict_b(), "b"));
    let cols = m.ncols();
    assert!(
        b_col > 64 + 8 && b_col + 64 + 8 < cols,
        "boundary at column {b_col}"
    );
    let west = s![.., ..b_col - 64];
    let east = s![.., b_col + 64..];
    assert!(same_bits(
        &m.slice(west).to_owned(),
        &a.slice(west).to_owned()
    ));
    assert!(same_bits(
        &m.slice(east).to_owned(),
        &b.slice(east).to_owned()
    ));
    assert!(!same_bits(
        &m.slice(east).to_owned(),
        &a.slice(east).to_owned()
    ));
    assert!(!same_bits(
        &m.slice(west).to_owned(),
        &b.slice(west).to_owned()
    ));
}

#[test]
fn a_biome_world_is_deterministic_and_window_invariant() {
    let z = 11u8;
    let (bx, by) = tile_of(boundary_lon(), 42.5, z);
    // The tile holding the boundary, alone, in a fresh world (a cold chain of windows).
    let alone = painted_world();
    let tile = alone.elevation_tile(z, bx, by).unwrap();
    let veg = alone.vegetation_tile(z, bx, by).unwrap();
    // Determinism: a second world built from the same parts gives the same bits.
    let again = painted_world();
    assert!(same_bits(&tile, &again.elevation_tile(z, bx, by).unwrap()));
    // Seamless: the tile is the window of the 2×2 block around it, computed in one call.
    let block_world = painted_world();
    let block = Window::new(i64::from(bx - 1) * 256, i64::from(by - 1) * 256, 512, 512);
    let e = block_world.elevation_window(z, block).unwrap();
    assert!(same_bits(&tile, &e.slice(s![256.., 256..]).to_owned()));
    let v = block_world.vegetation_window(z, block).unwrap();
    for (t, b) in veg.iter().zip(&v) {
        assert!(same_bits(t, &b.slice(s![256.., 256..]).to_owned()));
    }
    // Window-invariant: odd windows across the boundary, each in a fresh world, equal the same
    // pixels of the block.
    for (dc, dr, cols, rows) in [
        (300i64, 270i64, 97usize, 61usize),
        (131, 411, 250, 40),
        (0, 0, 33, 500),
    ] {
        let w = Window::new(block.col0 + dc, block.row0 + dr, cols, rows);
        let got = painted_world().elevation_window(z, w).unwrap();
        let want = e
            .slice(s![
                dr as usize..dr as usize + rows,
                dc as usize..dc as usize + cols
            ])
            .to_owned();
        assert!(same_bits(&got, &want), "window {w}");
    }
}

/// Writes the painted world's files into `dir` (base, two exemplars, two weight rasters, the
/// world file `painted.toml` with `[[biomes]]`, and `server.toml`); returns the server file.
fn write_painted_world_files(dir: &std::path::Path) -> std::path::PathBuf {
    use terrasynth_core::raster::{write_geotiff_file, Georef};
    let on_base = |a: Array2<f32>| Grid::new(a, mini_georef());
    write_geotiff_file(&on_base(base()), &dir.join("base.tif")).unwrap();
    let west = Array2::from_shape_fn((ROWS, COLS), |(_, c)| f32::from(u8::from(c < BOUNDARY_COL)));
    write_geotiff_file(&on_base(west.clone()), &dir.join("ridges.tif")).unwrap();
    write_geotiff_file(&on_base(west.mapv(|v| 1.0 - v)), &dir.join("steppe.tif")).unwrap();
    let ridged = synthetic_terrain(128, 128, 2);
    let low = synthetic_terrain(128, 128, 9).mapv(|v| 0.1 * v);
    for (name, z) in [("ex_ridges.tif", ridged), ("ex_steppe.tif", low)] {
        write_geotiff_file(&Grid::new(z, Georef::local_metric(100.0)), &dir.join(name)).unwrap();
    }
    let world = dir.join("painted.toml");
    std::fs::write(
        &world,
        "name = \"painted\"\nbase = \"base.tif\"\nz_base = 8\nmax_zoom = 11\n\
         [[biomes]]\nname = \"ridges\"\nweight = \"ridges.tif\"\n\
         dictionary = { exemplars = [\"ex_ridges.tif\"], atoms = 32, patch = 16, stride = 8 }\n\
         [[biomes]]\nname = \"steppe\"\nweight = \"steppe.tif\"\n\
         [biomes.dictionary]\nexemplars = [\"ex_steppe.tif\"]\natoms = 32\npatch = 16\nstride = 8\n",
    )
    .unwrap();
    let cfg = dir.join("server.toml");
    std::fs::write(&cfg, format!("worlds = [{:?}]\n", world.to_str().unwrap())).unwrap();
    cfg
}

#[test]
fn a_biome_world_file_serves_the_same_bytes_from_two_processes() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_painted_world_files(dir.path());
    let (bx, by) = tile_of(boundary_lon(), 42.5, 10);
    let mut urls = Vec::new();
    for dx in 0..3 {
        let x = bx + dx - 1;
        urls.push(format!("/tiles/painted/elevation/10/{x}/{by}.png"));
        urls.push(format!("/tiles/painted/vegetation/10/{x}/{by}.exr"));
        urls.push(format!("/tiles/painted/drainage/10/{x}/{by}.exr"));
        urls.push(format!("/tiles/painted/color/10/{x}/{by}.png"));
    }
    let (x11, y11) = tile_of(boundary_lon(), 42.5, 11);
    urls.push(format!("/tiles/painted/elevation/11/{x11}/{y11}.png"));
    let mut bodies: Vec<Vec<Vec<u8>>> = Vec::new();
    for run in 0..2 {
        let s = crate::support::start(
            &["--config", cfg.to_str().unwrap()],
            &[],
            &dir.path().join(format!("store{run}")),
        );
        let (status, w) = terrasynth_test_support::process::get(&s, "/worlds/painted", None);
        assert_eq!(status, 200);
        assert_eq!(
            terrasynth_test_support::process::json(&w)["dictionaries"]
                .as_array()
                .unwrap()
                .len(),
            2
        );
        let mut got = Vec::new();
        for u in &urls {
            let (status, body) = terrasynth_test_support::process::get(&s, u, None);
            assert_eq!(status, 200, "{u}");
            got.push(body);
        }
        s.kill();
        bodies.push(got);
    }
    for (u, (a, b)) in urls.iter().zip(bodies[0].iter().zip(&bodies[1])) {
        assert!(a == b, "{u} differs between processes");
    }
}

#[test]
fn a_world_file_with_a_bad_weight_raster_is_refused_naming_the_biome() {
    use terrasynth_core::raster::write_geotiff_file;
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_painted_world_files(dir.path());
    let load = || {
        let config = terrasynth::config::load(Some(&cfg), Vec::new()).unwrap();
        let store = terrasynth_store::Store::open(&dir.path().join("store")).unwrap();
        terrasynth::server::load_worlds(&config, &store).map(|w| w.len())
    };
    assert_eq!(load().unwrap(), 1);
    let steppe = dir.path().join("steppe.tif");
    for (weights, needle) in
        [
            // Off the base's grid: a row short.
            (
                Grid::new(Array2::from_elem((ROWS - 1, COLS), 1.0), mini_georef()),
                "biomes[1] (`steppe`): the weight raster is 288×239",
            ),
            // Negative and NaN weights.
            (
                Grid::new(Array2::from_elem((ROWS, COLS), -0.5), mini_georef()),
                "biomes[1] (`steppe`): weight -0.5 at row 0, column 0",
            ),
            (
                Grid::new(
                    Array2::from_shape_fn((ROWS, COLS), |(r, c)| {
                        if (r, c) == (3, 5) {
                            f32::NAN
                        } else {
                            1.0
                        }
                    }),
                    mini_georef(),
                ),
                "biomes[1] (`steppe`): weight NaN at row 3, column 5",
            ),
        ]
    {
        write_geotiff_file(&weights, &steppe).unwrap();
        let e = load().unwrap_err().to_string();
        assert!(e.contains("painted") && e.contains(needle), "{needle}: {e}");
    }
    // Weights 0 everywhere in both rasters.
    let zeros = Grid::new(Array2::zeros((ROWS, COLS)), mini_georef());
    write_geotiff_file(&zeros, &steppe).unwrap();
    write_geotiff_file(&zeros, &dir.path().join("ridges.tif")).unwrap();
    let e = load().unwrap_err().to_string();
    assert!(e.contains("0 everywhere"), "{e}");
}

#[test]
fn materials_and_species_follow_biome_terms() {
    use terrasynth_core::landscape::{LandscapeConfig, Trapezoid};
    let inside = Trapezoid {
        min: 0.5,
        max: 1.0,
        falloff: 0.0,
    };
    let mut landscape = LandscapeConfig::tienshan();
    landscape.materials.truncate(2);
    landscape.fallback_material = None;
    for (m, biome) in landscape.materials.iter_mut().zip(["ridges", "steppe"]) {
        *m = terrasynth_core::landscape::Material {
            name: format!("{biome}_ground"),
            ..m.clone()
        };
        m.elevation = None;
        m.slope = None;
        m.northness = None;
        m.curvature = None;
        m.wetness = None;
        m.vegetation.clear();
        m.class.clear();
        m.spread = 0.0;
        m.biome.insert(biome.into(), inside);
    }
    landscape.scatter.clear();
    // The first species grows only where the steppe is painted.
    landscape.species[0].biome.insert("steppe".into(), inside);
    let biomes = || {
        vec![
            biome("ridges", dict_a(), "a", |_, c| {
                f32::from(u8::from(c < BOUNDARY_COL))
            }),
            biome("steppe", dict_b(), "b", |_, c| {
                f32::from(u8::from(c >= BOUNDARY_COL))
            }),
        ]
    };
    let world = terrasynth_test_support::mini_world_biomes_with(
        base(),
        biomes(),
        landscape.clone(),
        11,
        64 << 20,
    )
    .unwrap();
    // Without the species' term: the same species grows on both sides.
    let mut free = landscape.clone();
    free.species[0].biome.clear();
    let free =
        terrasynth_test_support::mini_world_biomes_with(base(), biomes(), free, 11, 64 << 20)
            .unwrap();
    for z in [8u8, 10] {
        let (x, y) = tile_of(boundary_lon(), 42.5, z);
        let b = (pixel_col(boundary_lon(), z) - f64::from(x * 256)).round() as usize;
        // Beyond 8 pixels from the boundary (the bilinear ramp is one base cell wide, at most
        // 3 pixels at zoom 10), one biome alone is painted.
        let (west, east) = (..b.saturating_sub(8), b + 8..);
        let m = &world.material_tile(z, x, y).unwrap().weights;
        let (ridges, steppe) = (&m[0], &m[1]);
        let coverage = world.coverage_tile(z, x, y).unwrap();
        let mut checked = [0, 0];
        for r in 0..256 {
            for c in 0..256 {
                // Outside the base every overlay is empty.
                if coverage[[r, c]] < 1.0 {
                    continue;
                }
                let want = if west.contains(&c) {
                    checked[0] += 1;
                    (1.0, 0.0)
                } else if east.contains(&c) {
                    checked[1] += 1;
                    (0.0, 1.0)
                } else {
                    continue;
                };
                assert_eq!((ridges[[r, c]], steppe[[r, c]]), want, "z{z} ({r}, {c})");
            }
        }
        assert!(checked[0] > 1000 && checked[1] > 1000, "z{z}: {checked:?}");
        let spruce = &world.vegetation_tile(z, x, y).unwrap()[0];
        let grows = &free.vegetation_tile(z, x, y).unwrap()[0];
        let sum = |a: &Array2<f32>, cols: std::ops::Range<usize>| {
            a.slice(s![.., cols])
                .iter()
                .map(|&v| f64::from(v))
                .sum::<f64>()
        };
        let w = 0..b.saturating_sub(8);
        assert_eq!(
            sum(spruce, w.clone()),
            0.0,
            "z{z}: no species outside its biome"
        );
        assert!(
            sum(grows, w) > 0.0,
            "z{z}: the species grows there without the term"
        );
        assert!(
            sum(spruce, b + 8..256) > 0.0,
            "z{z}: the species grows in its biome"
        );
    }
    // A term naming a biome the world lacks is refused by name.
    let mut bad = landscape;
    bad.materials[0].biome.insert("desert".into(), inside);
    let e = terrasynth_test_support::mini_world_biomes_with(base(), biomes(), bad, 11, 64 << 20)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("names unknown biome `desert`") && e.contains("ridges, steppe"),
        "{e}"
    );
}

#[test]
fn gradient_tile_sets_are_biomes_too() {
    use terrasynth_core::dictionary::{build_gradient_tiles, GradientParams};
    let set = Arc::new(
        build_gradient_tiles(&[synthetic_terrain(96, 96, 4)], &GradientParams::default()).unwrap(),
    );
    let gradient_biome = |w: fn(usize, usize) -> f32| WorldBiome {
        name: "gradient".into(),
        dictionary: set.clone().into(),
        id: "g".into(),
        weight: Grid::new(
            Array2::from_shape_fn((ROWS, COLS), |(r, c)| w(r, c)),
            mini_georef(),
        ),
    };
    let alone = terrasynth_test_support::mini_world_bands(
        base(),
        vec![terrasynth_tiles::DictionaryBand::every_zoom(
            set.clone(),
            "g",
        )],
        11,
        64 << 20,
    )
    .unwrap();
    let everywhere = mini_world_biomes(
        base(),
        vec![
            biome("steppe", dict_b(), "b", |_, _| 0.0),
            gradient_biome(|_, _| 1.0),
        ],
        11,
        64 << 20,
    )
    .unwrap();
    let z = 10u8;
    let (x, y) = tile_of(boundary_lon(), 42.5, z);
    assert!(same_bits(
        &alone.elevation_tile(z, x, y).unwrap(),
        &everywhere.elevation_tile(z, x, y).unwrap()
    ));
    for (a, b) in alone
        .vegetation_tile(z, x, y)
        .unwrap()
        .iter()
        .zip(everywhere.vegetation_tile(z, x, y).unwrap().iter())
    {
        assert!(same_bits(a, b));
    }
    // Gradient tiles west, dictionary east: a tile alone is the window of a block.
    let painted = || {
        mini_world_biomes(
            base(),
            vec![
                gradient_biome(|_, c| f32::from(u8::from(c < BOUNDARY_COL))),
                biome("steppe", dict_b(), "b", |_, c| {
                    f32::from(u8::from(c >= BOUNDARY_COL))
                }),
            ],
            11,
            64 << 20,
        )
        .unwrap()
    };
    let tile = painted().elevation_tile(z, x, y).unwrap();
    let block = Window::new(i64::from(x - 1) * 256, i64::from(y - 1) * 256, 512, 512);
    let e = painted().elevation_window(z, block).unwrap();
    assert!(same_bits(&tile, &e.slice(s![256.., 256..]).to_owned()));
    assert!(!same_bits(&tile, &alone.elevation_tile(z, x, y).unwrap()));
}

// --- painted control layers of species densities (#15) ---

fn controlled_world(
    controls: Vec<terrasynth_tiles::SpeciesControl>,
) -> Result<World, terrasynth_tiles::TileError> {
    let parts = terrasynth_test_support::mini_parts(
        Grid::new(base(), mini_georef()),
        vec![terrasynth_tiles::DictionaryBand::every_zoom(dict_a(), "a")],
        Vec::new(),
        11,
        64 << 20,
    );
    World::new(terrasynth_tiles::WorldParts { controls, ..parts })
}

fn control(
    species: &str,
    mode: terrasynth_tiles::ControlMode,
    v: f32,
) -> terrasynth_tiles::SpeciesControl {
    terrasynth_tiles::SpeciesControl {
        species: species.into(),
        mode,
        raster: Grid::new(Array2::from_elem((ROWS, COLS), v), mini_georef()),
    }
}

#[test]
fn a_painted_control_replaces_or_scales_a_species_density() {
    use terrasynth_tiles::ControlMode::{Replace, Scale};
    let species = terrasynth_core::landscape::LandscapeConfig::tienshan().species[0]
        .name
        .clone();
    let free = controlled_world(Vec::new()).unwrap();
    let replaced = controlled_world(vec![control(&species, Replace, 0.3)]).unwrap();
    let scaled = controlled_world(vec![control(&species, Scale, 0.5)]).unwrap();
    // The native zoom: the control's value, or the free density times it, wherever the base
    // covers the pixel (no water in this world).
    let (x, y) = tile_of(70.5, 42.5, 8);
    let coverage = free.coverage_tile(8, x, y).unwrap();
    let (f, r, s) = (
        free.vegetation_tile(8, x, y).unwrap()[0].clone(),
        replaced.vegetation_tile(8, x, y).unwrap()[0].clone(),
        scaled.vegetation_tile(8, x, y).unwrap()[0].clone(),
    );
    let mut covered = 0;
    for ((p, &c), &fv) in coverage.indexed_iter().zip(f.iter()) {
        if c < 1.0 {
            continue;
        }
        covered += 1;
        assert!((r[p] - 0.3).abs() < 1e-6, "{p:?}: {}", r[p]);
        assert!((s[p] - 0.5 * fv).abs() < 1e-6, "{p:?}: {} vs {fv}", s[p]);
    }
    assert!(covered > 10_000, "{covered}");
    assert!(f.iter().any(|&v| v > 0.0 && (v - 0.3).abs() > 0.05));
    // Deeper zooms refine the controlled density: a zoom-10 tile's mean follows.
    let (x, y) = tile_of(70.5, 42.5, 10);
    let mean = |w: &World| {
        let d = &w.vegetation_tile(10, x, y).unwrap()[0];
        d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64
    };
    let (mf, mr, ms) = (mean(&free), mean(&replaced), mean(&scaled));
    let (m0, m1) = (
        mean(&controlled_world(vec![control(&species, Replace, 0.0)]).unwrap()),
        mean(&controlled_world(vec![control(&species, Replace, 1.0)]).unwrap()),
    );
    eprintln!(
        "zoom-10 mean density: free {mf:.4}, scaled by 0.5 {ms:.4}, replaced by 0 {m0:.4}, \
         0.3 {mr:.4}, 1 {m1:.4}"
    );
    assert!(
        mf > 0.0 && (0.35..0.65).contains(&(ms / mf)),
        "{ms} vs {mf}"
    );
    // The niche fades the painted density on marginal ground, so the zoom-10 means are below
    // the painted values, but they follow them.
    assert!(
        m0 < 0.25 * m1 && m0 < mr && mr < m1 && m1 <= 1.0,
        "{m0} {mr} {m1}"
    );
    // Bad controls are refused by name.
    for (c, needle) in [
        (
            vec![control("oak", Replace, 0.5)],
            "controls[0]: unknown species `oak`",
        ),
        (
            vec![control(&species, Replace, 1.5)],
            "value 1.5 at row 0, column 0; values must be within 0–1",
        ),
        (
            vec![control(&species, Scale, -1.0)],
            "value -1 at row 0, column 0; values must be finite and ≥ 0",
        ),
        (
            vec![
                control(&species, Scale, 1.0),
                control(&species, Replace, 0.5),
            ],
            "has a control already",
        ),
        (
            vec![terrasynth_tiles::SpeciesControl {
                species: species.clone(),
                mode: Scale,
                raster: Grid::new(Array2::from_elem((ROWS, COLS + 1), 1.0), mini_georef()),
            }],
            "must lie on the base's grid",
        ),
    ] {
        let e = controlled_world(c).unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    }
}
