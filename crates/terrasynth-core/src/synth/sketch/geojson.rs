//! GeoJSON in and out: a sketch read from a GeoJSON `FeatureCollection` (or one `Feature`) of
//! `LineString`/`MultiLineString` geometries with a `kind` property (`ridge` or `valley`) and an
//! optional `height_m`; and PPA feature trees written as a `FeatureCollection` of `LineString`s
//! in longitude/latitude with `kind` and `mean_elevation_m`.

use serde_json::{json, Map, Value};

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

/// A GeoJSON `FeatureCollection` of the paths of `trees` on a grid georeferenced by `georef`:
/// one `LineString` per path through its cells' centres, in longitude/latitude, with properties
/// `kind`, `mean_elevation_m` (rounded to 0.1 m), `cells`, and the classes of its two ends
/// (`start`, `end`: `end` or `branch`).
pub fn features_geojson(trees: &[&FeatureTree], georef: &Georef) -> Value {
    let mut features = Vec::new();
    for tree in trees {
        let degrees = tree.degrees();
        let class = |i: usize| match NodeClass::of_degree(usize::from(degrees[i])) {
            NodeClass::Branch => "branch",
            _ => "end",
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::sketch::geometry::{OutputSpec, SizeLimits};

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
