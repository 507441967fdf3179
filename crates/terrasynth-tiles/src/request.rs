//! Tile requests: the layer, format and parameters a tile URL asks for, parsed and validated
//! ([`parse_request`]), checked against a world ([`check_against_world`]), and the strong ETag of
//! the bytes they produce ([`etag`]). No HTTP types: the server hands over path segments and
//! query pairs and maps [`RequestError`] to 400 and 404.

use std::collections::HashMap;

use sha2::{Digest, Sha256};
use thiserror::Error;

use terrasynth_core::analysis::{DEFAULT_ALTITUDE_DEG, DEFAULT_AZIMUTH_DEG};

use crate::world::World;

/// A tile URL that names no tile.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RequestError {
    /// A path segment or query parameter is malformed (400).
    #[error("{0}")]
    BadRequest(String),
    /// No such layer or format (404).
    #[error("{0}")]
    NotFound(String),
}

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
    /// The `Content-Type` of the tile bytes.
    pub fn content_type(&self) -> &'static str {
        match self {
            TileKind::ElevationExr | TileKind::VegetationExr | TileKind::DrainageExr => {
                "image/x-exr"
            }
            _ => "image/png",
        }
    }
}

fn parse_num<T: std::str::FromStr>(what: &str, v: &str) -> Result<T, RequestError> {
    v.parse()
        .map_err(|_| RequestError::BadRequest(format!("{what} `{v}` is not a valid number")))
}

/// The `set` query parameter (default 0).
fn parse_set(query: &HashMap<String, String>) -> Result<usize, RequestError> {
    match query.get("set") {
        None => Ok(0),
        Some(v) => v.parse().map_err(|_| {
            RequestError::BadRequest(format!("set `{v}` is not a non-negative integer"))
        }),
    }
}

/// Checks the parts of a request that depend on the world: the `set` of splat (materials) and
/// vegetation (species) tiles must exist (400 otherwise).
pub fn check_against_world(world: &World, req: &TileRequest) -> Result<(), RequestError> {
    let l = world.landscape();
    let (set, count, what) = match req.kind {
        TileKind::Splat { set } => (set, l.materials.len(), "materials"),
        TileKind::VegetationPng { set, .. } => (set, l.species.len().max(1), "species"),
        _ => return Ok(()),
    };
    let sets = count.div_ceil(4);
    if set >= sets {
        return Err(RequestError::BadRequest(format!(
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
) -> Result<TileRequest, RequestError> {
    let z: u8 = parse_num("zoom", z)?;
    let x: u32 = parse_num("x", x)?;
    let (stem, ext) = y_ext
        .rsplit_once('.')
        .ok_or_else(|| RequestError::NotFound(format!("`{y_ext}` has no format extension")))?;
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
            return Err(RequestError::BadRequest(format!(
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
                    return Err(RequestError::BadRequest(format!(
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
                return Err(RequestError::BadRequest(format!(
                    "azimuth {azimuth} must lie in [0, 360]"
                )));
            }
            if !altitude.is_finite() || !(0.0..=90.0).contains(&altitude) {
                return Err(RequestError::BadRequest(format!(
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
                    return Err(RequestError::BadRequest(format!(
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
            return Err(RequestError::NotFound(format!(
                "layer `{layer}` has no format `{}{ext}`",
                if retina { "@2x." } else { "" }
            )))
        }
        _ => return Err(RequestError::NotFound(format!("unknown layer `{layer}`"))),
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
