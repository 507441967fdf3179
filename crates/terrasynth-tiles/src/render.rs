//! Renderers: a tile request computed from a world's pyramids and encoded — terrarium or mapbox
//! PNG (256 or 512 px) and float32 EXR elevation, hillshade PNG, vegetation (RGBA channels,
//! coloured overlay, EXR), drainage (EXR, log-alpha rivers), splat weights (RGBA per set of four
//! materials, quantised to sum 255), water (EXR depth and surface, PNG coloured by depth), the
//! hillshaded colour map (transparent outside the base's coverage, water coloured by depth),
//! instance tiles (MVT, GeoJSON) and contour tiles (MVT). CPU-bound: callers run it off
//! any async runtime.

use std::sync::Arc;

use ndarray::{s, Array2};

use terrasynth_core::analysis::{hillshade_u8, DEFAULT_ALTITUDE_DEG};
use terrasynth_core::landscape::{colour_of, quantise_weights};
use terrasynth_core::math;
use terrasynth_core::synth::Window;

use crate::contours::encode_contours_mvt;
use crate::coverage::uncovered;
use crate::encode::{
    encode_float_exr, encode_gray_png, encode_mapbox_png, encode_mapbox_webp, encode_rgba_png,
    encode_rgba_webp, encode_terrarium_png, encode_terrarium_webp,
};
use crate::error::TileError;
use crate::instances::{encode_geojson, encode_mvt};
use crate::request::{TileKind, TileRequest};
use crate::world::World;

/// Computes and encodes a tile (CPU-bound: runs on the blocking pool).
pub fn render(world: &World, req: &TileRequest) -> Result<Vec<u8>, TileError> {
    let (z, x, y) = (req.z, req.x, req.y);
    world.check_tile(z, x, y)?;
    let bytes = match &req.kind {
        TileKind::ElevationPng { mapbox, retina } => {
            let heights = elevation_heights(world, z, x, y, *retina)?;
            if *mapbox {
                encode_mapbox_png(&heights)?
            } else {
                encode_terrarium_png(&heights)?
            }
        }
        TileKind::ElevationWebp { mapbox, retina } => {
            let heights = elevation_heights(world, z, x, y, *retina)?;
            if *mapbox {
                encode_mapbox_webp(&heights)?
            } else {
                encode_terrarium_webp(&heights)?
            }
        }
        TileKind::ElevationExr => {
            let heights = world.elevation_tile(z, x, y)?;
            encode_float_exr(&[("elevation", &heights)])?
        }
        TileKind::Hillshade { azimuth, altitude } => {
            // One pixel of border from the neighbouring tiles makes the shade seamless.
            let w = Window::new(i64::from(x) * 256 - 1, i64::from(y) * 256 - 1, 258, 258);
            let heights = world.elevation_window(z, w)?;
            let cells = world.cell_sizes(z, w.row0, w.rows);
            let shade = hillshade_u8(&heights, &cells, *azimuth, *altitude);
            encode_gray_png(&shade.slice(s![1..257, 1..257]).to_owned())?
        }
        TileKind::VegetationPng { set, overlay } => {
            let veg = world.vegetation_tile(z, x, y)?;
            let l = world.landscape();
            let rgba = if *overlay {
                Array2::from_shape_fn((256, 256), |(r, c)| {
                    let (mut rgb, mut total) = ([0.0f32; 3], 0.0f32);
                    for (sp, d) in l.species.iter().zip(veg.iter()) {
                        let v = d[[r, c]];
                        total += v;
                        for (o, &k) in rgb.iter_mut().zip(&sp.colour) {
                            *o += v * f32::from(k);
                        }
                    }
                    if total <= 0.0 {
                        return [0, 0, 0, 0];
                    }
                    let px = |v: f32| (v / total).round().clamp(0.0, 255.0) as u8;
                    let a = (total.min(1.0) * 255.0).round() as u8;
                    [px(rgb[0]), px(rgb[1]), px(rgb[2]), a]
                })
            } else {
                Array2::from_shape_fn((256, 256), |(r, c)| {
                    let mut px = [0u8; 4];
                    for (k, o) in px.iter_mut().enumerate() {
                        if let Some(d) = veg.get(4 * set + k) {
                            *o = (d[[r, c]].clamp(0.0, 1.0) * 255.0).round() as u8;
                        }
                    }
                    px
                })
            };
            encode_rgba_png(&rgba)?
        }
        TileKind::VegetationExr => {
            let veg = world.vegetation_tile(z, x, y)?;
            let l = world.landscape();
            let channels: Vec<(&str, &Array2<f32>)> = l
                .species
                .iter()
                .zip(veg.iter())
                .map(|(sp, a)| (sp.name.as_str(), a))
                .collect();
            encode_float_exr(&channels)?
        }
        TileKind::DrainageExr => {
            let area = world.drainage_tile(z, x, y)?;
            encode_float_exr(&[("upstream_area", &area)])?
        }
        TileKind::DrainagePng => {
            let area = world.drainage_tile(z, x, y)?;
            let st = &world.landscape().drainage;
            let [cr, cg, cb] = st.colour;
            let alpha = st.alpha_ramp();
            let rgba = area.mapv(|a| [cr, cg, cb, alpha(a)]);
            encode_rgba_png(&rgba)?
        }
        TileKind::WaterExr => {
            let (depth, level) = world.water_tile(z, x, y)?;
            encode_float_exr(&[("depth", &depth), ("surface", &level)])?
        }
        TileKind::WaterPng => {
            let (depth, _) = world.water_tile(z, x, y)?;
            let cfg = world.water_config();
            let rgba = depth.mapv(|d| {
                if d > 0.0 {
                    let ([r, g, b], a) = cfg.colour_at(d);
                    [r, g, b, a]
                } else {
                    [0, 0, 0, 0]
                }
            });
            encode_rgba_png(&rgba)?
        }
        TileKind::Splat { set } => {
            let weights = &world.material_tile(z, x, y)?.weights;
            let n = weights.len();
            let mut w = vec![0.0f32; n];
            let mut q = vec![0u8; n];
            let rgba = Array2::from_shape_fn((256, 256), |(r, c)| {
                for (k, v) in w.iter_mut().enumerate() {
                    *v = weights[k][[r, c]];
                }
                quantise_weights(&w, &mut q);
                let mut px = [0u8; 4];
                for (k, o) in px.iter_mut().enumerate() {
                    *o = q.get(4 * set + k).copied().unwrap_or(0);
                }
                px
            });
            encode_rgba_png(&rgba)?
        }
        TileKind::Color => encode_rgba_png(&colour_map(world, z, x, y)?)?,
        TileKind::ColorWebp => encode_rgba_webp(&colour_map(world, z, x, y)?)?,
        TileKind::Instances { geojson } => {
            let placed = crate::instances::instances_tile(world, z, x, y)?;
            if *geojson {
                encode_geojson(world, z, &placed)?
            } else {
                encode_mvt(world, &placed, x, y)?
            }
        }
        TileKind::Contours { interval } => {
            encode_contours_mvt(&crate::contours::contour_tile(world, z, x, y, *interval)?)?
        }
    };
    Ok(bytes)
}

/// The heights of an elevation tile: 256 px of zoom `z`, or with `retina` the 512 px of zoom
/// `z + 1` it covers.
fn elevation_heights(
    world: &World,
    z: u8,
    x: u32,
    y: u32,
    retina: bool,
) -> Result<Arc<Array2<f32>>, TileError> {
    if retina {
        let w = Window::new(i64::from(x) * 512, i64::from(y) * 512, 512, 512);
        Ok(Arc::new(world.elevation_window(z + 1, w)?))
    } else {
        world.elevation_tile(z, x, y)
    }
}

/// The colour map's pixels: the baked material colour shaded by the hillshade.
fn colour_map(world: &World, z: u8, x: u32, y: u32) -> Result<Array2<[u8; 4]>, TileError> {
    let material = world.material_tile(z, x, y)?;
    let (weights, shade) = (&material.weights, &material.shade);
    let coverage = world.coverage_tile(z, x, y)?;
    let (depth, _) = world.water_tile(z, x, y)?;
    let water = world.water_config();
    let l = world.landscape();
    let flat = math::sinf(DEFAULT_ALTITUDE_DEG.to_radians());
    let mut w = vec![0.0f32; weights.len()];
    let rgba = Array2::from_shape_fn((256, 256), |(r, c)| {
        // Outside the base's coverage there is nothing to draw; on an overview's border the
        // covered fraction is the alpha and the weights (which sum to it) are renormalised.
        let cov = coverage[[r, c]];
        if uncovered(cov) {
            return [0, 0, 0, 0];
        }
        let a = (cov.min(1.0) * 255.0).round() as u8;
        let d = depth[[r, c]];
        if d > 0.0 {
            // Submerged: the water colour by depth, unshaded (the surface is flat).
            let ([wr, wg, wb], _) = water.colour_at(d);
            return [wr, wg, wb, a];
        }
        for (k, v) in w.iter_mut().enumerate() {
            *v = weights[k][[r, c]];
            if cov < 1.0 {
                *v /= cov;
            }
        }
        let rgb = colour_of(l, &w);
        // Flat ground keeps its colour; slopes facing the light brighten, others darken.
        let f = (0.35 + 0.65 * shade[[r, c]] / flat).clamp(0.0, 1.4);
        let px = |v: f32| (v * f).round().clamp(0.0, 255.0) as u8;
        [px(rgb[0]), px(rgb[1]), px(rgb[2]), a]
    });
    Ok(rgba)
}
