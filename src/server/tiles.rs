//! Tile handlers: elevation (terrarium or mapbox PNG, 256 or 512 px, float32 EXR), hillshade
//! PNG, and the landscape layers: vegetation (RGBA or coloured overlay PNG, EXR), drainage (EXR,
//! overlay PNG), splat (RGBA PNG per set of four materials) and the colour map (PNG). Encoded tiles are cached by everything that determines their bytes; a miss is computed on
//! the blocking pool behind a bounded queue (full → 503), never on an async runtime thread.

use std::collections::HashMap;
use std::sync::Arc;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use ndarray::{s, Array2};
use sha2::{Digest, Sha256};

use super::error::ServerError;
use super::AppState;
use crate::analysis::{hillshade_u8, DEFAULT_ALTITUDE_DEG, DEFAULT_AZIMUTH_DEG};
use crate::landscape::{colour_of, quantise_weights};
use crate::synth::Window;
use crate::tiles::{
    encode_float_exr, encode_gray_png, encode_mapbox_png, encode_rgba_png, encode_terrarium_png,
    World,
};

/// What a tile request asks for, parsed and validated.
#[derive(Clone, Debug, PartialEq)]
pub struct TileRequest {
    /// World name.
    pub world: String,
    /// Layer and format.
    pub kind: TileKind,
    /// Zoom.
    pub z: u8,
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
}

/// A layer in one encoding.
#[derive(Clone, Debug, PartialEq)]
pub enum TileKind {
    /// Terrarium (or mapbox Terrain-RGB) PNG; `retina` for 512 px.
    ElevationPng {
        /// Mapbox Terrain-RGB instead of terrarium.
        mapbox: bool,
        /// 512 px (`@2x`).
        retina: bool,
    },
    /// Float32 metres, one channel.
    ElevationExr,
    /// Grey hillshade with sun azimuth and altitude in degrees.
    Hillshade {
        /// Sun azimuth, degrees clockwise from north.
        azimuth: f32,
        /// Sun altitude above the horizon, degrees.
        altitude: f32,
    },
    /// Vegetation densities × 255, species `4·set .. 4·set+3` in R, G, B, A; or with `overlay`
    /// the species colours blended by density, alpha the total density.
    VegetationPng {
        /// Set of four species.
        set: usize,
        /// Coloured overlay instead of raw channels.
        overlay: bool,
    },
    /// Float32 densities, one channel per species, named after it.
    VegetationExr,
    /// Float32 upstream area, m² (channel `upstream_area`).
    DrainageExr,
    /// Log-scaled rivers on transparent.
    DrainagePng,
    /// Material weights of materials `4·set .. 4·set+3` in R, G, B, A (all sets of a pixel sum
    /// to 255).
    Splat {
        /// Set of four materials.
        set: usize,
    },
    /// The baked colour map, shaded by the hillshade.
    Color,
}

impl TileKind {
    fn content_type(&self) -> &'static str {
        match self {
            TileKind::ElevationExr | TileKind::VegetationExr | TileKind::DrainageExr => {
                "image/x-exr"
            }
            _ => "image/png",
        }
    }
}

fn parse_num<T: std::str::FromStr>(what: &str, v: &str) -> Result<T, ServerError> {
    v.parse()
        .map_err(|_| ServerError::BadRequest(format!("{what} `{v}` is not a valid number")))
}

/// The `set` query parameter (default 0).
fn parse_set(query: &HashMap<String, String>) -> Result<usize, ServerError> {
    match query.get("set") {
        None => Ok(0),
        Some(v) => v.parse().map_err(|_| {
            ServerError::BadRequest(format!("set `{v}` is not a non-negative integer"))
        }),
    }
}

/// Checks the parts of a request that depend on the world: the `set` of splat (materials) and
/// vegetation (species) tiles must exist (400 otherwise).
pub fn check_against_world(world: &World, req: &TileRequest) -> Result<(), ServerError> {
    let l = world.landscape();
    let (set, count, what) = match req.kind {
        TileKind::Splat { set } => (set, l.materials.len(), "materials"),
        TileKind::VegetationPng { set, .. } => (set, l.species.len().max(1), "species"),
        _ => return Ok(()),
    };
    let sets = count.div_ceil(4);
    if set >= sets {
        return Err(ServerError::BadRequest(format!(
            "set {set} does not exist: {count} {what} make {sets} set(s) of four"
        )));
    }
    Ok(())
}

/// Parses `{layer}/{z}/{x}/{y}.{ext}` and the query into a request.
pub fn parse_request(
    world: &str,
    layer: &str,
    z: &str,
    x: &str,
    y_ext: &str,
    query: &HashMap<String, String>,
) -> Result<TileRequest, ServerError> {
    let z: u8 = parse_num("zoom", z)?;
    let x: u32 = parse_num("x", x)?;
    let (stem, ext) = y_ext
        .rsplit_once('.')
        .ok_or_else(|| ServerError::NotFound(format!("`{y_ext}` has no format extension")))?;
    let (y_str, retina) = match stem.strip_suffix("@2x") {
        Some(y) => (y, true),
        None => (stem, false),
    };
    let y: u32 = parse_num("y", y_str)?;
    for key in query.keys() {
        let allowed = matches!(
            (layer, key.as_str()),
            ("elevation", "encoding")
                | ("hillshade", "azimuth" | "altitude")
                | ("splat", "set")
                | ("vegetation", "set" | "style")
        );
        if !allowed {
            return Err(ServerError::BadRequest(format!(
                "unknown query parameter `{key}`"
            )));
        }
    }
    let kind = match (layer, ext) {
        ("elevation", "png") => {
            let mapbox = match query.get("encoding").map(String::as_str) {
                None | Some("terrarium") => false,
                Some("mapbox") => true,
                Some(other) => {
                    return Err(ServerError::BadRequest(format!(
                        "encoding `{other}`: expected `terrarium` or `mapbox`"
                    )))
                }
            };
            TileKind::ElevationPng { mapbox, retina }
        }
        ("elevation", "exr") if !retina => TileKind::ElevationExr,
        ("hillshade", "png") if !retina => {
            let azimuth = match query.get("azimuth") {
                Some(v) => parse_num::<f32>("azimuth", v)?,
                None => DEFAULT_AZIMUTH_DEG,
            };
            let altitude = match query.get("altitude") {
                Some(v) => parse_num::<f32>("altitude", v)?,
                None => DEFAULT_ALTITUDE_DEG,
            };
            if !azimuth.is_finite() || !(0.0..=360.0).contains(&azimuth) {
                return Err(ServerError::BadRequest(format!(
                    "azimuth {azimuth} must lie in [0, 360]"
                )));
            }
            if !altitude.is_finite() || !(0.0..=90.0).contains(&altitude) {
                return Err(ServerError::BadRequest(format!(
                    "altitude {altitude} must lie in [0, 90]"
                )));
            }
            TileKind::Hillshade { azimuth, altitude }
        }
        ("vegetation", "png") if !retina => {
            let overlay = match query.get("style").map(String::as_str) {
                None | Some("channels") => false,
                Some("overlay") => true,
                Some(other) => {
                    return Err(ServerError::BadRequest(format!(
                        "style `{other}`: expected `channels` or `overlay`"
                    )))
                }
            };
            TileKind::VegetationPng {
                set: parse_set(query)?,
                overlay,
            }
        }
        ("vegetation", "exr") if !retina => TileKind::VegetationExr,
        ("drainage", "exr") if !retina => TileKind::DrainageExr,
        ("drainage", "png") if !retina => TileKind::DrainagePng,
        ("splat", "png") if !retina => TileKind::Splat {
            set: parse_set(query)?,
        },
        ("color", "png") if !retina => TileKind::Color,
        ("elevation" | "hillshade" | "vegetation" | "drainage" | "splat" | "color", _) => {
            return Err(ServerError::NotFound(format!(
                "layer `{layer}` has no format `{}{ext}`",
                if retina { "@2x." } else { "" }
            )))
        }
        _ => return Err(ServerError::NotFound(format!("unknown layer `{layer}`"))),
    };
    Ok(TileRequest {
        world: world.to_string(),
        kind,
        z,
        x,
        y,
    })
}

/// The strong ETag of a request: a hash of everything that determines the tile's bytes (the
/// world's fingerprint, layer, encoding, parameters and coordinates), so that a matching
/// `If-None-Match` is answered without computing anything.
pub fn etag(world: &World, req: &TileRequest) -> String {
    let mut h = Sha256::new();
    h.update(world.fingerprint().as_bytes());
    h.update(format!("|{:?}|{}|{}|{}", req.kind, req.z, req.x, req.y).as_bytes());
    let d = h.finalize();
    let hex: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
    format!("\"{hex}\"")
}

/// Computes and encodes a tile (CPU-bound: runs on the blocking pool).
pub fn render(world: &World, req: &TileRequest) -> Result<Vec<u8>, ServerError> {
    let (z, x, y) = (req.z, req.x, req.y);
    world.check_tile(z, x, y)?;
    let bytes = match &req.kind {
        TileKind::ElevationPng { mapbox, retina } => {
            let heights = if *retina {
                let w = Window::new(i64::from(x) * 512, i64::from(y) * 512, 512, 512);
                Arc::new(world.elevation_window(z + 1, w)?)
            } else {
                world.elevation_tile(z, x, y)?
            };
            if *mapbox {
                encode_mapbox_png(&heights)?
            } else {
                encode_terrarium_png(&heights)?
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
            let (lo, hi) = (st.png_min_m2.log10(), st.png_max_m2.log10());
            let [cr, cg, cb] = st.colour;
            let rgba = area.mapv(|a| {
                let t = if a > 0.0 {
                    ((f64::from(a).log10() - lo) / (hi - lo)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                [cr, cg, cb, (t * 255.0).round() as u8]
            });
            encode_rgba_png(&rgba)?
        }
        TileKind::Splat { set } => {
            let (weights, _) = world.material_tile(z, x, y)?;
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
        TileKind::Color => {
            let (weights, shade) = world.material_tile(z, x, y)?;
            let l = world.landscape();
            let flat = DEFAULT_ALTITUDE_DEG.to_radians().sin();
            let mut w = vec![0.0f32; weights.len()];
            let rgba = Array2::from_shape_fn((256, 256), |(r, c)| {
                for (k, v) in w.iter_mut().enumerate() {
                    *v = weights[k][[r, c]];
                }
                let rgb = colour_of(l, &w);
                // Flat ground keeps its colour; slopes facing the light brighten, others darken.
                let f = (0.35 + 0.65 * shade[[r, c]] / flat).clamp(0.0, 1.4);
                let px = |v: f32| (v * f).round().clamp(0.0, 255.0) as u8;
                [px(rgb[0]), px(rgb[1]), px(rgb[2]), 255]
            });
            encode_rgba_png(&rgba)?
        }
    };
    Ok(bytes)
}

fn etag_matches(headers: &HeaderMap, tag: &str) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .any(|t| t == "*" || t == tag || t.strip_prefix("W/") == Some(tag))
}

/// `GET/HEAD /tiles/{world}/{layer}/{z}/{x}/{y}.{ext}`.
pub async fn tile(
    State(state): State<AppState>,
    Path((world_name, layer, z, x, y_ext)): Path<(String, String, String, String, String)>,
    Query(query): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, ServerError> {
    let world = state
        .worlds
        .get(&world_name)
        .cloned()
        .ok_or_else(|| ServerError::NotFound(format!("unknown world `{world_name}`")))?;
    let req = parse_request(&world_name, &layer, &z, &x, &y_ext, &query)?;
    check_against_world(&world, &req)?;
    world.check_tile(req.z, req.x, req.y)?;
    let tag = etag(&world, &req);
    let cache_control = state.cache_control.clone();
    let respond = |status: StatusCode, body: Body| -> Response {
        let mut resp = (status, body).into_response();
        let h = resp.headers_mut();
        if let Ok(v) = HeaderValue::from_str(&tag) {
            h.insert(header::ETAG, v);
        }
        h.insert(header::CACHE_CONTROL, cache_control.clone());
        resp
    };
    if etag_matches(&headers, &tag) {
        return Ok(respond(StatusCode::NOT_MODIFIED, Body::empty()));
    }
    let content_type = HeaderValue::from_static(req.kind.content_type());
    let bytes = match state.tile_bytes.get(&tag) {
        Some(b) => b,
        None => {
            let _slot = state.queue.enter()?;
            let permit = state
                .synth
                .clone()
                .acquire_owned()
                .await
                .map_err(|e| ServerError::Internal(e.to_string()))?;
            let cache = state.tile_bytes.clone();
            let key = tag.clone();
            tokio::task::spawn_blocking(move || {
                let _permit = permit;
                cache
                    .try_get_with(key, || render(&world, &req).map(Bytes::from))
                    .map_err(|e: Arc<ServerError>| match &*e {
                        ServerError::Tile(t) => ServerError::Tile(t.clone()),
                        other => ServerError::Internal(other.to_string()),
                    })
            })
            .await
            .map_err(|e| ServerError::Internal(e.to_string()))??
        }
    };
    let mut resp = respond(StatusCode::OK, Body::from(bytes));
    resp.headers_mut()
        .insert(header::CONTENT_TYPE, content_type);
    Ok(resp)
}
