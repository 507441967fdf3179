//! Tile requests: the layer, format and parameters a tile URL asks for, parsed and validated
//! ([`parse_request`]), checked against a world ([`check_against_world`]), and the strong ETag of
//! the bytes they produce ([`etag`]). No HTTP types: the server hands over the raw (still
//! percent-encoded) path segments and the query pairs ([`query_map`]) and maps [`RequestError`]
//! to 400 and 404.
//!
//! Parsing is strict, so that a tile has exactly one URL (one cache key for every CDN and
//! browser): coordinates are canonical decimal integers (no sign, no leading zeros, no
//! percent-encoding: 400), a query key may appear once (400), and a parameter is accepted only by
//! the layer and format it applies to (400, e.g. `encoding` on an `.exr` tile).

use std::collections::HashMap;

use sha2::Digest;
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
    /// Float32 water depth, m (channel `depth`; 0 where dry) and surface (channel `surface`, m;
    /// NaN where dry).
    WaterExr,
    /// Water colour by depth, alpha by depth (transparent where dry).
    WaterPng,
    /// Material weights of materials `4·set .. 4·set+3` in R, G, B, A (all sets of a pixel sum
    /// to 255).
    Splat {
        /// Set of four materials.
        set: usize,
    },
    /// The baked colour map, shaded by the hillshade.
    Color,
    /// [`TileKind::ElevationPng`]'s pixels as a lossless WebP (`{y}.webp`, `{y}@2x.webp`).
    ElevationWebp {
        /// Mapbox Terrain-RGB instead of terrarium.
        mapbox: bool,
        /// 512 px (`@2x`).
        retina: bool,
    },
    /// [`TileKind::Color`]'s pixels as a lossless WebP.
    ColorWebp,
    /// Plants and rocks: a Mapbox Vector Tile 2.1 (one layer per kind), or with `geojson` a
    /// GeoJSON FeatureCollection in longitude/latitude with the ground elevation.
    Instances {
        /// GeoJSON (`.json`) instead of MVT (`.mvt`).
        geojson: bool,
    },
    /// Contour lines of the served elevation: a Mapbox Vector Tile 2.1 with layer `contours`
    /// ([`crate::contours`]).
    Contours {
        /// `?interval=` in metres; `None`: the zoom's default.
        interval: Option<f64>,
    },
}

impl TileKind {
    /// Whether the tile's format leaves its bytes uncompressed, so that they are worth a
    /// transfer coding ([`crate::gzip`]): the vector tiles (MVT) and GeoJSON. PNG, WebP and EXR
    /// (ZIP) are compressed by their formats already.
    pub fn compressible(&self) -> bool {
        matches!(self, TileKind::Instances { .. } | TileKind::Contours { .. })
    }

    /// The `Content-Type` of the tile bytes.
    pub fn content_type(&self) -> &'static str {
        match self {
            TileKind::ElevationExr
            | TileKind::VegetationExr
            | TileKind::DrainageExr
            | TileKind::WaterExr => "image/x-exr",
            TileKind::ElevationWebp { .. } | TileKind::ColorWebp => "image/webp",
            TileKind::Instances { geojson: false } | TileKind::Contours { .. } => {
                "application/vnd.mapbox-vector-tile"
            }
            TileKind::Instances { geojson: true } => "application/geo+json",
            _ => "image/png",
        }
    }
}

fn parse_num<T: std::str::FromStr>(what: &str, v: &str) -> Result<T, RequestError> {
    v.parse()
        .map_err(|_| RequestError::BadRequest(format!("{what} `{v}` is not a valid number")))
}

/// A tile coordinate: a canonical decimal integer (ASCII digits, no sign, no leading zero, no
/// percent-encoding) that fits `T`; anything else is a 400.
fn parse_coordinate<T: std::str::FromStr>(what: &str, raw: &str) -> Result<T, RequestError> {
    let canonical = !raw.is_empty()
        && raw.bytes().all(|b| b.is_ascii_digit())
        && (raw == "0" || !raw.starts_with('0'));
    if !canonical {
        return Err(RequestError::BadRequest(format!(
            "{what} `{raw}` is not a canonical tile coordinate: write it as a decimal integer \
             without sign, leading zeros or percent-encoding"
        )));
    }
    raw.parse()
        .map_err(|_| RequestError::BadRequest(format!("{what} `{raw}` is out of range")))
}

/// The query pairs as a map: 400 when a key appears more than once (a repeated key would
/// otherwise silently take one of its values).
pub fn query_map(pairs: &[(String, String)]) -> Result<HashMap<String, String>, RequestError> {
    let mut map = HashMap::with_capacity(pairs.len());
    for (k, v) in pairs {
        if map.insert(k.clone(), v.clone()).is_some() {
            return Err(RequestError::BadRequest(format!(
                "query parameter `{k}` is given more than once"
            )));
        }
    }
    Ok(map)
}

/// The query parameters a layer accepts in a format.
fn allowed_parameters(layer: &str, ext: &str) -> &'static [&'static str] {
    match (layer, ext) {
        ("elevation", "png" | "webp") => &["encoding"],
        ("hillshade", "png") => &["azimuth", "altitude"],
        ("vegetation", "png") => &["set", "style"],
        ("splat", "png") => &["set"],
        ("contours", "mvt") => &["interval"],
        _ => &[],
    }
}

/// The `set` query parameter (default 0).
fn parse_set(query: &HashMap<String, String>) -> Result<usize, RequestError> {
    match query.get("set") {
        None => Ok(0),
        Some(v) => parse_coordinate("set", v),
    }
}

/// Checks the parts of a request that depend on the world: the `set` of splat (materials) and
/// vegetation (species) tiles must exist (400 otherwise); instance tiles exist from the world's
/// `instances_min_zoom` on (404 otherwise); a contour `interval` must not be too dense for the
/// zoom (400, [`crate::contours::check_interval`]).
pub fn check_against_world(world: &World, req: &TileRequest) -> Result<(), RequestError> {
    let l = world.landscape();
    if let TileKind::Contours {
        interval: Some(interval),
    } = req.kind
    {
        crate::contours::check_interval(world, req.z, interval)
            .map_err(RequestError::BadRequest)?;
    }
    if matches!(req.kind, TileKind::Instances { .. }) && req.z < l.instances_min_zoom {
        return Err(RequestError::NotFound(format!(
            "instance tiles start at zoom {} (zoom {} asked)",
            l.instances_min_zoom, req.z
        )));
    }
    let (set, count, what) = match req.kind {
        TileKind::Splat { set } => (set, crate::materials::splat_names(l).len(), "materials"),
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

/// Parses `{layer}/{z}/{x}/{y}.{ext}` (raw path segments: percent-encoding is not decoded, so a
/// coordinate has one spelling) and the query into a request. Unknown layers and formats are
/// 404; malformed or non-canonical coordinates, unknown parameters and parameters that do not
/// apply to the layer's format are 400.
pub fn parse_request(
    world: &str,
    layer: &str,
    z: &str,
    x: &str,
    y_ext: &str,
    query: &HashMap<String, String>,
) -> Result<TileRequest, RequestError> {
    let z: u8 = parse_coordinate("zoom", z)?;
    let x: u32 = parse_coordinate("x", x)?;
    let (stem, ext) = y_ext
        .rsplit_once('.')
        .ok_or_else(|| RequestError::NotFound(format!("`{y_ext}` has no format extension")))?;
    let (y_str, retina) = match stem.strip_suffix("@2x") {
        Some(y) => (y, true),
        None => (stem, false),
    };
    let y: u32 = parse_coordinate("y", y_str)?;
    let has_format = match (layer, ext) {
        ("elevation", "png" | "webp") => true,
        ("color", "webp") => !retina,
        ("elevation" | "vegetation" | "drainage" | "water", "exr")
        | ("hillshade" | "vegetation" | "drainage" | "splat" | "color" | "water", "png")
        | ("instances", "mvt" | "json")
        | ("contours", "mvt") => !retina,
        _ => false,
    };
    // Unknown layers and formats are 404 below, whatever the query.
    if has_format {
        let allowed = allowed_parameters(layer, ext);
        let mut keys: Vec<&String> = query.keys().collect();
        keys.sort();
        if let Some(key) = keys.into_iter().find(|k| !allowed.contains(&k.as_str())) {
            let applies = ["png", "exr", "webp"]
                .iter()
                .any(|e| allowed_parameters(layer, e).contains(&key.as_str()));
            return Err(RequestError::BadRequest(if applies {
                format!("query parameter `{key}` does not apply to `.{ext}` {layer} tiles")
            } else {
                format!("unknown query parameter `{key}`")
            }));
        }
    }
    let kind = match (layer, ext) {
        ("elevation", "png" | "webp") => {
            let mapbox = match query.get("encoding").map(String::as_str) {
                None | Some("terrarium") => false,
                Some("mapbox") => true,
                Some(other) => {
                    return Err(RequestError::BadRequest(format!(
                        "encoding `{other}`: expected `terrarium` or `mapbox`"
                    )))
                }
            };
            if ext == "webp" {
                TileKind::ElevationWebp { mapbox, retina }
            } else {
                TileKind::ElevationPng { mapbox, retina }
            }
        }
        ("color", "webp") if !retina => TileKind::ColorWebp,
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
        ("water", "exr") if !retina => TileKind::WaterExr,
        ("water", "png") if !retina => TileKind::WaterPng,
        ("splat", "png") if !retina => TileKind::Splat {
            set: parse_set(query)?,
        },
        ("color", "png") if !retina => TileKind::Color,
        ("instances", "mvt") if !retina => TileKind::Instances { geojson: false },
        ("instances", "json") if !retina => TileKind::Instances { geojson: true },
        ("contours", "mvt") if !retina => TileKind::Contours {
            interval: match query.get("interval") {
                None => None,
                Some(v) => {
                    let i = parse_num::<f64>("interval", v)?;
                    if !i.is_finite() || i <= 0.0 {
                        return Err(RequestError::BadRequest(format!(
                            "interval `{v}` must be a positive number of metres"
                        )));
                    }
                    Some(i)
                }
            },
        },
        (
            "elevation" | "hillshade" | "vegetation" | "drainage" | "water" | "splat" | "color"
            | "instances" | "contours",
            _,
        ) => {
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
    use std::fmt::Write;
    let mut h = world
        .etag_seed(matches!(req.kind, TileKind::Instances { .. }))
        .clone();
    let mut key = String::with_capacity(96);
    // Writing into a String cannot fail.
    let _ = write!(key, "|{:?}|{}|{}|{}", req.kind, req.z, req.x, req.y);
    h.update(key.as_bytes());
    let digest = h.finalize();
    const HEX: &[u8; 16] = b"0123456789abcdef";
    let mut tag = String::with_capacity(34);
    tag.push('"');
    for b in digest.iter().take(16) {
        tag.push(char::from(HEX[usize::from(b >> 4)]));
        tag.push(char::from(HEX[usize::from(b & 15)]));
    }
    tag.push('"');
    tag
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(pairs: &[(&str, &str)]) -> HashMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    fn parse(
        layer: &str,
        z: &str,
        x: &str,
        y: &str,
        query: &[(&str, &str)],
    ) -> Result<TileRequest, RequestError> {
        parse_request("w", layer, z, x, y, &q(query))
    }

    #[test]
    fn coordinates_have_one_spelling() {
        assert!(parse("elevation", "12", "2896", "1512.png", &[]).is_ok());
        assert!(parse("elevation", "0", "0", "0.png", &[]).is_ok());
        for (z, x, y) in [
            ("+12", "2896", "1512.png"),
            ("12", "+2896", "1512.png"),
            ("012", "2896", "1512.png"),
            ("12", "02896", "1512.png"),
            ("12", "2896", "01512.png"),
            ("12", "2896", "%31512.png"),
            ("12", "289%36", "1512.png"),
            ("1%32", "2896", "1512.png"),
            ("12", "2896", "1512%402x.png"),
            ("12", " 2896", "1512.png"),
            ("12", "2896", "-1.png"),
            ("", "2896", "1512.png"),
            ("256", "0", "0.png"),
            ("12", "4294967296", "0.png"),
        ] {
            let r = parse("elevation", z, x, y, &[]);
            assert!(
                matches!(r, Err(RequestError::BadRequest(_))),
                "{z}/{x}/{y}: {r:?}"
            );
        }
    }

    #[test]
    fn repeated_keys_are_refused() {
        let pairs = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        assert_eq!(
            query_map(&pairs(&[("a", "1"), ("b", "2")])).unwrap().len(),
            2
        );
        assert!(matches!(
            query_map(&pairs(&[("encoding", "mapbox"), ("encoding", "terrarium")])),
            Err(RequestError::BadRequest(m)) if m.contains("more than once")
        ));
    }

    #[test]
    fn parameters_apply_only_to_their_format() {
        assert!(parse("elevation", "1", "0", "0.png", &[("encoding", "mapbox")]).is_ok());
        assert!(parse("elevation", "1", "0", "0@2x.png", &[("encoding", "mapbox")]).is_ok());
        assert!(parse(
            "vegetation",
            "1",
            "0",
            "0.png",
            &[("set", "0"), ("style", "overlay")]
        )
        .is_ok());
        for (layer, y, key) in [
            ("elevation", "0.exr", "encoding"),
            ("vegetation", "0.exr", "set"),
            ("vegetation", "0.exr", "style"),
            ("drainage", "0.png", "set"),
            ("splat", "0.png", "style"),
            ("color", "0.png", "encoding"),
        ] {
            let r = parse(layer, "1", "0", y, &[(key, "1")]);
            assert!(
                matches!(r, Err(RequestError::BadRequest(_))),
                "{layer} {y} {key}: {r:?}"
            );
        }
        let r = parse("elevation", "1", "0", "0.exr", &[("encoding", "mapbox")]);
        assert!(matches!(r, Err(RequestError::BadRequest(m)) if m.contains("does not apply")));
        assert!(matches!(
            parse("splat", "1", "0", "0.png", &[("set", "01")]),
            Err(RequestError::BadRequest(_))
        ));
        for v in ["0", "-5", "abc", "NaN", "inf", "1e999", ""] {
            let r = parse("contours", "12", "0", "0.mvt", &[("interval", v)]);
            assert!(matches!(r, Err(RequestError::BadRequest(_))), "{v}: {r:?}");
        }
        assert_eq!(
            parse("contours", "12", "0", "0.mvt", &[("interval", "25")]).map(|r| r.kind),
            Ok(TileKind::Contours {
                interval: Some(25.0)
            })
        );
        assert!(matches!(
            parse("contours", "12", "0", "0.mvt", &[("set", "1")]),
            Err(RequestError::BadRequest(_))
        ));
        assert!(matches!(
            parse("contours", "12", "0", "0.png", &[]),
            Err(RequestError::NotFound(_))
        ));
        // A format that does not exist stays a 404 whatever the query.
        assert!(matches!(
            parse("hillshade", "1", "0", "0.exr", &[("azimuth", "1")]),
            Err(RequestError::NotFound(_))
        ));
    }
}
