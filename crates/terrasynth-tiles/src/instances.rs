//! Instance tiles: the plants and rocks of a world's scattering rules
//! ([`terrasynth_core::landscape::scatter`]) over a window of a zoom's plane, with the ground
//! elevation under each (the elevation tile's pixel that holds it), encoded as a Mapbox Vector
//! Tile 2.1 (one layer per kind, point features with `species`, `height_m`, `radius_m`,
//! `rotation_deg`, `age`; the `mvt` crate) or a GeoJSON FeatureCollection in longitude/latitude
//! with the ground elevation as third coordinate.
//!
//! The rules' inputs (species densities, material weights) are windows of the zoom's plane
//! reaching [`halo_px`] beyond the output window, so every instance belongs to the one tile that
//! holds it and a tile alone has exactly the instances of the same window of a larger block.

use ndarray::Array2;
use serde_json::{json, Value};

use terrasynth_core::landscape::scatter::{halo_px, scatter, Instance, RuleField};
use terrasynth_core::synth::Window;

use crate::error::TileError;
use crate::mercator::{mercator_to_lonlat, pixel_size_m, TILE_SIZE};
use crate::pyramid::tile_window;
use crate::world::World;

/// Extent of the MVT tiles' coordinate grid (16 units per pixel).
pub const MVT_EXTENT: u32 = 4096;

/// One instance of a world's rule, with its ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed {
    /// Index of the scattering rule in the landscape.
    pub rule: usize,
    /// The instance (global pixels of its zoom).
    pub instance: Instance,
    /// Elevation of the ground under it, metres: the value of the elevation pixel holding it.
    pub ground_m: f32,
}

/// The instances of tile `(z, x, y)` of `world` (a tile outside the world, or below the
/// landscape's `instances_min_zoom`: `OutsideWorld`): every scattering rule's, with their ground.
pub fn instances_tile(world: &World, z: u8, x: u32, y: u32) -> Result<Vec<Placed>, TileError> {
    world.check_tile(z, x, y)?;
    if z < world.landscape().instances_min_zoom {
        return Err(TileError::OutsideWorld { z, x, y });
    }
    instances_in(world, z, tile_window(i64::from(x), i64::from(y)))
}

/// The instances of every rule of `world` inside window `w` of zoom `z`, in rule order, each
/// rule's sorted by (row, column). CPU-bound.
pub fn instances_in(world: &World, z: u8, w: Window) -> Result<Vec<Placed>, TileError> {
    let l = world.landscape();
    if l.scatter.is_empty() || w.is_empty() {
        return Ok(Vec::new());
    }
    let cell_m = world.level_cell_m(z);
    let halo = l
        .scatter
        .iter()
        .map(|r| halo_px(r, cell_m))
        .fold(0.0, f64::max) as i64;
    let big = w.grown(halo);
    let needs_materials = l
        .scatter
        .iter()
        .any(|r| !r.materials.is_empty() || !r.exclude_materials.is_empty());
    // The materials read the same vegetation window: one assembly serves both, and its inputs
    // (terrain, drainage, vegetation) are computed side by side.
    let (species, materials) = if needs_materials {
        let m = world.materials_and_vegetation(z, big)?;
        (m.vegetation, m.weights)
    } else {
        (world.vegetation_window(z, big)?, Vec::new())
    };
    let ground = world.elevation_window(z, w)?;
    // Nothing is scattered outside the base's coverage.
    let coverage = world.coverage_window(z, w)?;
    let rect = [
        w.col0 as f64,
        w.row0 as f64,
        w.col1() as f64,
        w.row1() as f64,
    ];
    let mut out = Vec::new();
    for (k, rule) in l.scatter.iter().enumerate() {
        let species_index = |name: &String| l.species.iter().position(|s| &s.name == name);
        let material_index = |name: &String| l.materials.iter().position(|m| &m.name == name);
        let mut sources: Vec<&Array2<f32>> = Vec::new();
        for s in &rule.species {
            sources.push(&species[species_index(s).ok_or_else(|| unknown(s))?]);
        }
        for m in &rule.materials {
            sources.push(&materials[material_index(m).ok_or_else(|| unknown(m))?]);
        }
        let exclude: Vec<&Array2<f32>> = rule
            .exclude_materials
            .iter()
            .map(|m| {
                material_index(m)
                    .map(|i| &materials[i])
                    .ok_or_else(|| unknown(m))
            })
            .collect::<Result<_, _>>()?;
        let field = RuleField {
            row0: big.row0,
            col0: big.col0,
            sources: &sources,
            exclude: &exclude,
            exclude_weight: rule.exclude_weight,
        };
        for instance in scatter(rule, k as u64, cell_m, &field, rect) {
            let r = (instance.y.floor() as i64 - w.row0) as usize;
            let c = (instance.x.floor() as i64 - w.col0) as usize;
            if coverage
                .get((r, c))
                .is_none_or(|&v| crate::coverage::uncovered(v))
            {
                continue;
            }
            out.push(Placed {
                rule: k,
                instance,
                ground_m: ground.get((r, c)).copied().unwrap_or(f32::NAN),
            });
        }
    }
    Ok(out)
}

fn unknown(name: &str) -> TileError {
    TileError::Encode(format!("scatter names unknown layer `{name}`"))
}

/// The `species` value of an instance of rule `rule`.
fn species_of<'a>(world: &'a World, p: &Placed) -> &'a str {
    let rule = &world.landscape().scatter[p.rule];
    if let Some(n) = &rule.name {
        return n;
    }
    rule.species
        .iter()
        .chain(&rule.materials)
        .nth(p.instance.source)
        .map_or("", String::as_str)
}

/// The kinds (MVT layers) of a world in the order of their first rule.
pub fn kinds(world: &World) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in &world.landscape().scatter {
        if !out.contains(&r.kind) {
            out.push(r.kind.clone());
        }
    }
    out
}

/// Rounds a value to `digits` decimals, for stable and compact text.
fn round_to(v: f64, digits: i32) -> f64 {
    let f = 10f64.powi(digits);
    (v * f).round() / f
}

/// The instances of tile `(z, x, y)` as a Mapbox Vector Tile 2.1: one layer per kind (in rule
/// order, empty kinds left out), point features in tile coordinates of extent 4096.
pub fn encode_mvt(world: &World, placed: &[Placed], x: u32, y: u32) -> Result<Vec<u8>, TileError> {
    let err = |e: mvt::Error| TileError::Encode(format!("MVT: {e}"));
    let mut tile = mvt::Tile::new(MVT_EXTENT);
    let scale = f64::from(MVT_EXTENT) / f64::from(TILE_SIZE);
    let (ox, oy) = (f64::from(x) * 256.0, f64::from(y) * 256.0);
    for kind in kinds(world) {
        let mut layer = tile.create_layer(&kind);
        let mut any = false;
        for p in placed
            .iter()
            .filter(|p| world.landscape().scatter[p.rule].kind == kind)
        {
            let i = &p.instance;
            let geom = mvt::GeomEncoder::new(mvt::GeomType::Point)
                .point(
                    ((i.x - ox) * scale).round().min(4095.0),
                    ((i.y - oy) * scale).round().min(4095.0),
                )
                .map_err(err)?
                .encode()
                .map_err(err)?;
            let mut f = layer.into_feature(geom);
            f.add_tag_string("species", species_of(world, p));
            f.add_tag_double("height_m", round_to(f64::from(i.height_m), 2));
            f.add_tag_double("radius_m", round_to(f64::from(i.radius_m), 2));
            f.add_tag_double("rotation_deg", round_to(f64::from(i.rotation_deg), 1));
            f.add_tag_uint("age", u64::from(i.age));
            layer = f.into_layer();
            any = true;
        }
        if any {
            tile.add_layer(layer).map_err(err)?;
        }
    }
    tile.to_bytes().map_err(err)
}

/// Longitude/latitude of a point of zoom `z`'s global pixel plane.
pub fn global_pixel_to_lonlat(z: u8, px: f64, py: f64) -> (f64, f64) {
    let m = pixel_size_m(z);
    let half = m * f64::from(TILE_SIZE) * 2f64.powi(i32::from(z)) / 2.0;
    mercator_to_lonlat(px * m - half, half - py * m)
}

/// The instances of a tile of zoom `z` as a GeoJSON FeatureCollection: points
/// `[lon, lat, ground elevation]` with the MVT's properties plus `kind`.
pub fn encode_geojson(world: &World, z: u8, placed: &[Placed]) -> Result<Vec<u8>, TileError> {
    let features: Vec<Value> = placed
        .iter()
        .map(|p| {
            let i = &p.instance;
            let (lon, lat) = global_pixel_to_lonlat(z, i.x, i.y);
            json!({
                "type": "Feature",
                "geometry": {
                    "type": "Point",
                    // Full precision: a client finds the elevation pixel holding the point.
                    "coordinates": [lon, lat, f64::from(p.ground_m)],
                },
                "properties": {
                    "kind": world.landscape().scatter[p.rule].kind,
                    "species": species_of(world, p),
                    "height_m": round_to(f64::from(i.height_m), 2),
                    "radius_m": round_to(f64::from(i.radius_m), 2),
                    "rotation_deg": round_to(f64::from(i.rotation_deg), 1),
                    "age": i.age,
                },
            })
        })
        .collect();
    serde_json::to_vec(&json!({ "type": "FeatureCollection", "features": features }))
        .map_err(|e| TileError::Encode(e.to_string()))
}
