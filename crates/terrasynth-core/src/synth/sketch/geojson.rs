//! GeoJSON in and out: a sketch read from a GeoJSON `FeatureCollection` (or one `Feature`) of
//! `LineString`/`MultiLineString` geometries with a `kind` property (`ridge` or `valley`) and an
//! optional `height_m`; and PPA feature trees written as a `FeatureCollection` of `LineString`s
//! in longitude/latitude with `kind` and `mean_elevation_m`.

use serde::ser::{SerializeMap, SerializeSeq};
use serde::{Serialize, Serializer};
use serde_json::{Map, Value};

use crate::analysis::ppa::{FeatureKind, FeatureTree, NodeClass};
use crate::math;
use crate::raster::{Crs, Georef};

use super::geometry::{check_lines, OutputGrid, Sketch};
use super::SketchError;

/// Longitude/latitude pairs of a GeoJSON position array.
fn positions(v: &Value, what: &str) -> Result<Vec<[f64; 2]>, SketchError> {
    let bad = || SketchError::Invalid(format!("{what}: coordinates must be [[lon, lat], ...]"));
    let arr = v.as_array().ok_or_else(bad)?;
    arr.iter()
        .map(|p| {
            let p = p.as_array().ok_or_else(bad)?;
            match (
                p.first().and_then(Value::as_f64),
                p.get(1).and_then(Value::as_f64),
            ) {
                (Some(x), Some(y)) if p.len() <= 3 => Ok([x, y]),
                _ => Err(bad()),
            }
        })
        .collect()
}

/// A line as read: its kind, longitude/latitude vertices and asked height.
type RawLine = (FeatureKind, Vec<[f64; 2]>, Option<f64>);

/// The lines of one GeoJSON feature.
fn feature_lines(f: &Value, n: usize, out: &mut Vec<RawLine>) -> Result<(), SketchError> {
    let what = format!("feature {n}");
    let obj = f
        .as_object()
        .ok_or_else(|| SketchError::Invalid(format!("{what} is not an object")))?;
    if obj.get("type").and_then(Value::as_str) != Some("Feature") {
        return Err(SketchError::Invalid(format!(
            "{what}: type must be Feature"
        )));
    }
    let empty = Map::new();
    let props = match obj.get("properties") {
        Some(Value::Object(m)) => m,
        None | Some(Value::Null) => &empty,
        Some(_) => {
            return Err(SketchError::Invalid(format!(
                "{what}: properties must be an object"
            )))
        }
    };
    let kind = props
        .get("kind")
        .and_then(Value::as_str)
        .and_then(FeatureKind::parse)
        .ok_or_else(|| {
            SketchError::Invalid(format!(
                "{what}: properties.kind must be \"ridge\" or \"valley\""
            ))
        })?;
    let height =
        match props.get("height_m") {
            None | Some(Value::Null) => None,
            Some(v) => Some(v.as_f64().ok_or_else(|| {
                SketchError::Invalid(format!("{what}: height_m must be a number"))
            })?),
        };
    let geom = obj
        .get("geometry")
        .and_then(Value::as_object)
        .ok_or_else(|| SketchError::Invalid(format!("{what}: no geometry")))?;
    let coords = geom
        .get("coordinates")
        .ok_or_else(|| SketchError::Invalid(format!("{what}: no coordinates")))?;
    match geom.get("type").and_then(Value::as_str) {
        Some("LineString") => out.push((kind, positions(coords, &what)?, height)),
        Some("MultiLineString") => {
            let parts = coords.as_array().ok_or_else(|| {
                SketchError::Invalid(format!("{what}: MultiLineString coordinates"))
            })?;
            for p in parts {
                out.push((kind, positions(p, &what)?, height));
            }
        }
        _ => {
            return Err(SketchError::Invalid(format!(
                "{what}: geometry must be a LineString or MultiLineString"
            )))
        }
    }
    Ok(())
}

/// A sketch from GeoJSON on `grid`, checked ([`check_lines`]). Vertex counts are checked before
/// anything else is allocated per vertex.
pub fn parse_sketch(v: &Value, grid: OutputGrid) -> Result<Sketch, SketchError> {
    let features: Vec<&Value> = match v.get("type").and_then(Value::as_str) {
        Some("FeatureCollection") => v
            .get("features")
            .and_then(Value::as_array)
            .ok_or_else(|| SketchError::Invalid("FeatureCollection without features".into()))?
            .iter()
            .collect(),
        Some("Feature") => vec![v],
        _ => {
            return Err(SketchError::Invalid(
                "the sketch must be a GeoJSON FeatureCollection or Feature".into(),
            ))
        }
    };
    // Count vertices first, so that a huge sketch is refused before being copied.
    let mut vertices = 0usize;
    for f in &features {
        let c = f.get("geometry").and_then(|g| g.get("coordinates"));
        if let Some(Value::Array(a)) = c {
            for p in a {
                vertices = vertices.saturating_add(match p {
                    Value::Array(inner) if inner.first().is_some_and(Value::is_array) => {
                        inner.len()
                    }
                    _ => 1,
                });
            }
        }
    }
    if vertices > super::geometry::MAX_VERTICES {
        return Err(SketchError::Invalid(format!(
            "the sketch has {vertices} vertices; at most {} are allowed",
            super::geometry::MAX_VERTICES
        )));
    }
    let mut lines = Vec::new();
    for (i, f) in features.iter().enumerate() {
        feature_lines(f, i + 1, &mut lines)?;
    }
    check_lines(grid, lines)
}

/// Longitude/latitude of map coordinates in `crs`.
pub fn lonlat(crs: Crs, x: f64, y: f64) -> [f64; 2] {
    match crs {
        Crs::Epsg4326 => [x, y],
        Crs::Epsg3857 => {
            let r = crate::raster::georef::MERCATOR_RADIUS_M;
            [
                (x / r).to_degrees(),
                (2.0 * math::atan(math::exp(y / r)) - std::f64::consts::FRAC_PI_2).to_degrees(),
            ]
        }
        Crs::Projected(_) => crs
            .to_lonlat(x, y)
            .map_or([f64::NAN, f64::NAN], |(lon, lat)| [lon, lat]),
    }
}

/// Rounds to 7 decimals (about 1 cm in degrees), so that files stay small and stable.
fn round7(v: f64) -> f64 {
    (v * 1e7).round() / 1e7
}

/// Writes a GeoJSON `FeatureCollection` of the paths of `trees` on a grid georeferenced by
/// `georef` to `out`: one `LineString` per path through its cells' centres, in
/// longitude/latitude rounded to 7 decimals, with properties `kind`, `mean_elevation_m` (rounded
/// to 0.1 m), `cells`, and the classes of its two ends (`start`, `end`: `end` or `branch`).
/// Members are written in name order, compactly.
///
/// The document is serialised as it is written, path by path: a world's trees make tens of MB of
/// JSON, and a `serde_json::Value` of it would take about thirteen times that in memory. Errors
/// are `out`'s.
pub fn write_features_geojson<W: std::io::Write>(
    trees: &[&FeatureTree],
    georef: &Georef,
    out: W,
) -> serde_json::Result<()> {
    serde_json::to_writer(out, &FeatureCollection { trees, georef })
}

/// The document [`write_features_geojson`] writes. Every object below writes its members in
/// name order, as a `serde_json::Value` (a sorted map) would.
struct FeatureCollection<'a> {
    trees: &'a [&'a FeatureTree],
    georef: &'a Georef,
}

impl Serialize for FeatureCollection<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        typed_object(s, ("features", &FeatureArray(self)), "FeatureCollection")
    }
}

/// An object of one member and `"type": ty` (after it: `type` sorts last among the names used
/// here).
fn typed_object<S: Serializer, V: Serialize>(
    s: S,
    (name, value): (&'static str, &V),
    ty: &'static str,
) -> Result<S::Ok, S::Error> {
    let mut m = s.serialize_map(Some(2))?;
    m.serialize_entry(name, value)?;
    m.serialize_entry("type", ty)?;
    m.end()
}

/// The class written for a path's end of `degree` in its tree: `branch` or `end`.
fn end_class(degree: u8) -> &'static str {
    match NodeClass::of_degree(usize::from(degree)) {
        NodeClass::Branch => "branch",
        _ => "end",
    }
}

/// The `features` array: every non-empty path of every tree, in order.
struct FeatureArray<'a>(&'a FeatureCollection<'a>);

impl Serialize for FeatureArray<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let FeatureCollection { trees, georef } = *self.0;
        let mut seq = s.serialize_seq(None)?;
        for tree in trees {
            let degrees = tree.degrees();
            let class = |i: usize| end_class(degrees[i]);
            for path in &tree.paths {
                let (Some(&first), Some(&last)) = (path.cells.first(), path.cells.last()) else {
                    continue;
                };
                seq.serialize_element(&PathFeature {
                    geometry: PathGeometry {
                        tree,
                        cells: &path.cells,
                        georef,
                    },
                    properties: PathProperties {
                        cells: path.cells.len(),
                        end: class(last),
                        kind: tree.kind.as_str(),
                        mean_elevation_m: (path.mean_elevation * 10.0).round() / 10.0,
                        start: class(first),
                    },
                })?;
            }
        }
        seq.end()
    }
}

/// One path as a GeoJSON `Feature`.
struct PathFeature<'a> {
    geometry: PathGeometry<'a>,
    properties: PathProperties,
}

impl Serialize for PathFeature<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(3))?;
        m.serialize_entry("geometry", &self.geometry)?;
        m.serialize_entry("properties", &self.properties)?;
        m.serialize_entry("type", "Feature")?;
        m.end()
    }
}

/// A path's `LineString` through its cells' centres.
struct PathGeometry<'a> {
    tree: &'a FeatureTree,
    cells: &'a [usize],
    georef: &'a Georef,
}

impl Serialize for PathGeometry<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        typed_object(s, ("coordinates", &PathCoordinates(self)), "LineString")
    }
}

/// The positions of a [`PathGeometry`]; a non-finite coordinate is written `null`.
struct PathCoordinates<'a>(&'a PathGeometry<'a>);

impl Serialize for PathCoordinates<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let PathGeometry {
            tree,
            cells,
            georef,
        } = *self.0;
        s.collect_seq(cells.iter().map(|&i| {
            let (r, c) = (i / tree.cols, i % tree.cols);
            let (x, y) = georef.pixel_centre(c as f64, r as f64);
            let [lon, lat] = lonlat(georef.crs, x, y);
            [round7(lon), round7(lat)]
        }))
    }
}

/// A path's properties, fields in name order.
#[derive(Serialize)]
struct PathProperties {
    cells: usize,
    end: &'static str,
    kind: &'static str,
    mean_elevation_m: f64,
    start: &'static str,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::sketch::geometry::{OutputSpec, SizeLimits};
    use serde_json::json;

    fn grid() -> OutputGrid {
        OutputSpec {
            west: 10.0,
            south: 40.0,
            east: 11.0,
            north: 41.0,
            cell_deg: 0.01,
        }
        .grid(&SizeLimits::default())
        .unwrap()
    }

    /// The writer's reference: the document built as a `serde_json::Value` (a sorted map, so
    /// members in name order), as the server and `terrasynth features` built it before.
    fn features_value(trees: &[&FeatureTree], georef: &Georef) -> Value {
        let mut features = Vec::new();
        for tree in trees {
            let degrees = tree.degrees();
            let class = |i: usize| end_class(degrees[i]);
            for path in &tree.paths {
                let coords: Vec<Value> = path
                    .cells
                    .iter()
                    .map(|&i| {
                        let (r, c) = (i / tree.cols, i % tree.cols);
                        let (x, y) = georef.pixel_centre(c as f64, r as f64);
                        let [lon, lat] = lonlat(georef.crs, x, y);
                        json!([round7(lon), round7(lat)])
                    })
                    .collect();
                let (first, last) = match (path.cells.first(), path.cells.last()) {
                    (Some(&a), Some(&b)) => (a, b),
                    _ => continue,
                };
                features.push(json!({
                    "type": "Feature",
                    "geometry": {"type": "LineString", "coordinates": coords},
                    "properties": {
                        "kind": tree.kind.as_str(),
                        "mean_elevation_m": (path.mean_elevation * 10.0).round() / 10.0,
                        "cells": path.cells.len(),
                        "start": class(first),
                        "end": class(last),
                    },
                }));
            }
        }
        json!({"type": "FeatureCollection", "features": features})
    }

    /// Hills and valleys of two sines and a hash, with a NaN cell and a flat corner.
    fn terrain(rows: usize, cols: usize, seed: u64) -> ndarray::Array2<f32> {
        ndarray::Array2::from_shape_fn((rows, cols), |(r, c)| {
            if r == 7 && c == 9 {
                return f32::NAN;
            }
            if r < 4 && c < 4 {
                return 100.0;
            }
            let h =
                (r as u64 * 7919 + c as u64 * 104_729 + seed).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let noise = (h >> 40) as f32 / (1u64 << 24) as f32;
            let (y, x) = (r as f32 * 0.31, c as f32 * 0.23);
            500.0
                + 120.0 * (math::sinf(x) * math::cosf(y))
                + 40.0 * math::sinf(0.7 * x + 1.3 * y)
                + 25.0 * noise
        })
    }

    #[test]
    fn streamed_features_are_the_value_documents_bytes() {
        use crate::analysis::ppa::{features, PpaParams};
        use crate::raster::Crs;
        let georefs = [
            Georef {
                crs: Crs::Epsg4326,
                west: 66.85,
                north: 44.71,
                pixel_width: 1.0 / 240.0,
                pixel_height: 1.0 / 240.0,
            },
            Georef {
                crs: Crs::Epsg3857,
                west: 7_600_000.0,
                north: 5_200_000.0,
                pixel_width: 152.87,
                pixel_height: 152.87,
            },
        ];
        for (seed, georef) in georefs.iter().enumerate() {
            let z = terrain(61, 83, seed as u64);
            let f = features(&z, &PpaParams::default());
            assert!(f.ridges.paths.len() > 5 && f.valleys.paths.len() > 5);
            // A tree with an empty path, which both leave out.
            let mut valleys = f.valleys.clone();
            valleys.paths.insert(
                1,
                crate::analysis::ppa::FeaturePath {
                    cells: Vec::new(),
                    mean_elevation: 0.0,
                },
            );
            for trees in [
                vec![&f.ridges, &valleys],
                vec![&f.ridges],
                vec![&valleys],
                vec![],
            ] {
                let mut streamed = Vec::new();
                write_features_geojson(&trees, georef, &mut streamed).unwrap();
                let reference = serde_json::to_vec(&features_value(&trees, georef)).unwrap();
                assert_eq!(
                    String::from_utf8(streamed).unwrap(),
                    String::from_utf8(reference).unwrap()
                );
            }
        }
    }

    #[test]
    fn parses_lines_and_refuses_nonsense() {
        let ok = json!({"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {"kind": "ridge", "height_m": 2500},
             "geometry": {"type": "LineString", "coordinates": [[10.1, 40.5], [10.9, 40.6]]}},
            {"type": "Feature", "properties": {"kind": "valley"},
             "geometry": {"type": "MultiLineString", "coordinates": [[[10.2, 40.2], [10.8, 40.3]]]}}
        ]});
        let s = parse_sketch(&ok, grid()).unwrap();
        assert_eq!(s.lines.len(), 2);
        assert_eq!(s.lines[0].height_m, Some(2500.0));
        assert!((s.lines[0].points[0][0] - 9.5).abs() < 1e-9);
        for (bad, needle) in [
            (
                json!({"type": "FeatureCollection", "features": []}),
                "no ridge",
            ),
            (
                json!({"type": "Feature", "properties": {"kind": "hill"},
                "geometry": {"type": "LineString", "coordinates": [[10.1, 40.5], [10.9, 40.6]]}}),
                "kind",
            ),
            (
                json!({"type": "Feature", "properties": {"kind": "ridge"},
                "geometry": {"type": "LineString", "coordinates": [[10.1, 40.5], [11.9, 40.6]]}}),
                "outside",
            ),
            (
                json!({"type": "Feature", "properties": {"kind": "ridge"},
                "geometry": {"type": "Point", "coordinates": [10.1, 40.5]}}),
                "LineString",
            ),
            (
                json!({"type": "Feature", "properties": {"kind": "ridge"},
                "geometry": {"type": "LineString", "coordinates": [[10.1, 40.1], [10.9, 40.9], [10.9, 40.1], [10.1, 40.9]]}}),
                "itself",
            ),
            (
                json!({"type": "Feature", "properties": {"kind": "ridge"},
                "geometry": {"type": "LineString", "coordinates": [[10.1, 40.1], [10.1, 40.1]]}}),
                "shorter",
            ),
            (json!([1, 2]), "FeatureCollection"),
        ] {
            let e = parse_sketch(&bad, grid()).unwrap_err().to_string();
            assert!(e.contains(needle), "{bad}: {e}");
        }
        let many: Vec<Value> = (0..10_001)
            .map(|i| json!([10.0 + i as f64 * 1e-5, 40.5]))
            .collect();
        let big = json!({"type": "Feature", "properties": {"kind": "ridge"},
            "geometry": {"type": "LineString", "coordinates": many}});
        assert!(parse_sketch(&big, grid())
            .unwrap_err()
            .to_string()
            .contains("vertices"));
    }
}
