//! The geometry of a sketch: the grid of the world to make (bounds and cell size in degrees,
//! checked against size limits), sketch lines in that grid's cell coordinates, and the checks a
//! sketch must pass (vertex count, inside the bounds, no line crossing or doubling back on
//! itself). Cell coordinates are continuous: `(x, y) = (col, row)` of a cell's centre, `x`
//! eastwards and `y` southwards.

use crate::analysis::ppa::FeatureKind;
use crate::raster::{Crs, Georef};

use super::SketchError;

/// Most vertices a sketch may have (all lines together).
pub const MAX_VERTICES: usize = 10_000;

/// Shortest sketch line, cells.
pub const MIN_LINE_CELLS: f64 = 2.0;

/// Smallest output side, cells.
pub const MIN_SIDE: usize = 32;

/// Heights a sketch line may ask for, metres (the deepest trench to above the highest peak).
pub const HEIGHT_RANGE_M: (f64, f64) = (-11_000.0, 9_000.0);

/// Size limits of the world to make.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SizeLimits {
    /// Most cells (rows × columns).
    pub max_pixels: u64,
    /// Longest side, cells.
    pub max_dimension: u64,
}

impl Default for SizeLimits {
    /// 4096 × 4096 cells.
    fn default() -> Self {
        SizeLimits {
            max_pixels: 4096 * 4096,
            max_dimension: 4096,
        }
    }
}

/// The world to make: bounds `west, south, east, north` (degrees, EPSG:4326) and a square cell
/// size in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputSpec {
    /// Western edge, degrees east.
    pub west: f64,
    /// Southern edge, degrees north.
    pub south: f64,
    /// Eastern edge, degrees east.
    pub east: f64,
    /// Northern edge, degrees north.
    pub north: f64,
    /// Cell size, degrees.
    pub cell_deg: f64,
}

/// The grid of an [`OutputSpec`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputGrid {
    /// Georeference (EPSG:4326, north-up, square cells).
    pub georef: Georef,
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
}

impl OutputSpec {
    /// The grid: `round((east − west) / cell)` columns and `round((north − south) / cell)` rows
    /// from the north-west corner. Errors for non-finite or inverted bounds, bounds beyond
    /// ±180° / ±85°, a cell size outside `[1e-5, 1]` degrees, fewer than [`MIN_SIDE`] cells a
    /// side, or more than the limits allow.
    pub fn grid(&self, limits: &SizeLimits) -> Result<OutputGrid, SketchError> {
        let b = [self.west, self.south, self.east, self.north, self.cell_deg];
        if b.iter().any(|v| !v.is_finite()) {
            return Err(SketchError::Invalid(
                "bounds and cell size must be finite numbers".into(),
            ));
        }
        if self.west >= self.east || self.south >= self.north {
            return Err(SketchError::Invalid(
                "bounds must be west < east and south < north".into(),
            ));
        }
        if self.west < -180.0 || self.east > 180.0 || self.south < -85.0 || self.north > 85.0 {
            return Err(SketchError::Invalid(
                "bounds must lie within ±180° longitude and ±85° latitude".into(),
            ));
        }
        if !(1e-5..=1.0).contains(&self.cell_deg) {
            return Err(SketchError::Invalid(format!(
                "cell size {} must lie between 0.00001 and 1 degree",
                self.cell_deg
            )));
        }
        let cols_f = ((self.east - self.west) / self.cell_deg).round();
        let rows_f = ((self.north - self.south) / self.cell_deg).round();
        let max_dim = limits.max_dimension as f64;
        if cols_f > max_dim || rows_f > max_dim || cols_f * rows_f > limits.max_pixels as f64 {
            return Err(SketchError::TooLarge(format!(
                "{cols_f}×{rows_f} cells exceed the limits ({} cells, {} a side)",
                limits.max_pixels, limits.max_dimension
            )));
        }
        if cols_f < MIN_SIDE as f64 || rows_f < MIN_SIDE as f64 {
            return Err(SketchError::Invalid(format!(
                "{cols_f}×{rows_f} cells: the world needs at least {MIN_SIDE} cells a side"
            )));
        }
        Ok(OutputGrid {
            georef: Georef {
                crs: Crs::Epsg4326,
                west: self.west,
                north: self.north,
                pixel_width: self.cell_deg,
                pixel_height: self.cell_deg,
            },
            rows: rows_f as usize,
            cols: cols_f as usize,
        })
    }
}

impl OutputGrid {
    /// Cell coordinates `(x, y)` of longitude/latitude.
    pub fn to_cell(&self, lon: f64, lat: f64) -> [f64; 2] {
        let g = &self.georef;
        [
            (lon - g.west) / g.pixel_width - 0.5,
            (g.north - lat) / g.pixel_height - 0.5,
        ]
    }

    /// Longitude/latitude of cell coordinates `(x, y)`.
    pub fn to_lonlat(&self, p: [f64; 2]) -> [f64; 2] {
        let g = &self.georef;
        [
            g.west + (p[0] + 0.5) * g.pixel_width,
            g.north - (p[1] + 0.5) * g.pixel_height,
        ]
    }

    /// Whether cell coordinates lie inside the grid's bounds (its outer cell edges).
    pub fn contains(&self, p: [f64; 2]) -> bool {
        let eps = 1e-6;
        p[0] >= -0.5 - eps
            && p[1] >= -0.5 - eps
            && p[0] <= self.cols as f64 - 0.5 + eps
            && p[1] <= self.rows as f64 - 0.5 + eps
    }
}

/// One line of a sketch, in cell coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct SketchLine {
    /// Ridge or valley.
    pub kind: FeatureKind,
    /// Vertices `(x, y)`, consecutive duplicates removed.
    pub points: Vec<[f64; 2]>,
    /// The height the line should have, metres, when given.
    pub height_m: Option<f64>,
}

impl SketchLine {
    /// Total length, cells.
    pub fn length(&self) -> f64 {
        self.points.windows(2).map(|w| dist(w[0], w[1])).sum()
    }

    /// Points every `step` cells along the line (the first vertex, then every `step`, then the
    /// last vertex).
    pub fn resampled(&self, step: f64) -> Vec<[f64; 2]> {
        resample(&self.points, step)
    }
}

/// A checked sketch on its output grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Sketch {
    /// The grid of the world to make.
    pub grid: OutputGrid,
    /// Its lines.
    pub lines: Vec<SketchLine>,
}

/// Euclidean distance.
pub fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Points every `step` along a polyline, ending with its last vertex.
pub fn resample(points: &[[f64; 2]], step: f64) -> Vec<[f64; 2]> {
    let Some(&first) = points.first() else {
        return Vec::new();
    };
    let step = if step > 0.0 && step.is_finite() {
        step
    } else {
        1.0
    };
    let mut out = vec![first];
    // Distance along the line to the next output point, measured from the current vertex.
    let mut next = step;
    for w in points.windows(2) {
        let len = dist(w[0], w[1]);
        let mut at = next;
        while at < len {
            let t = at / len;
            out.push([
                w[0][0] + t * (w[1][0] - w[0][0]),
                w[0][1] + t * (w[1][1] - w[0][1]),
            ]);
            at += step;
        }
        next = at - len;
    }
    if let Some(&last) = points.last() {
        if out.last().is_some_and(|&p| dist(p, last) > 1e-9) {
            out.push(last);
        }
    }
    out
}

/// Orientation of the triangle `(a, b, c)`: > 0 counter-clockwise.
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn on_segment(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0]) - 1e-12
        && p[0] <= a[0].max(b[0]) + 1e-12
        && p[1] >= a[1].min(b[1]) - 1e-12
        && p[1] <= a[1].max(b[1]) + 1e-12
}

/// Whether segments `ab` and `cd` share a point (touching counts).
pub fn segments_intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (o1, o2, o3, o4) = (
        orient(a, b, c),
        orient(a, b, d),
        orient(c, d, a),
        orient(c, d, b),
    );
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    (o1 == 0.0 && on_segment(a, b, c))
        || (o2 == 0.0 && on_segment(a, b, d))
        || (o3 == 0.0 && on_segment(c, d, a))
        || (o4 == 0.0 && on_segment(c, d, b))
}

/// Whether a polyline crosses or touches itself (non-adjacent segments sharing a point), or
/// doubles back (two consecutive segments folding onto each other). Sweep over segments sorted
/// by their western end.
pub fn self_intersects(points: &[[f64; 2]]) -> bool {
    let n = points.len();
    if n < 3 {
        return false;
    }
    for w in points.windows(3) {
        // Folding back: the turn is (nearly) 180°.
        let (u, v) = (
            [w[1][0] - w[0][0], w[1][1] - w[0][1]],
            [w[2][0] - w[1][0], w[2][1] - w[1][1]],
        );
        let cross = u[0] * v[1] - u[1] * v[0];
        let dot = u[0] * v[0] + u[1] * v[1];
        let norm = dist(w[0], w[1]) * dist(w[1], w[2]);
        if dot < 0.0 && cross.abs() <= 1e-9 * norm {
            return true;
        }
    }
    let segs = n - 1;
    let mut order: Vec<usize> = (0..segs).collect();
    let min_x = |i: usize| points[i][0].min(points[i + 1][0]);
    let max_x = |i: usize| points[i][0].max(points[i + 1][0]);
    order.sort_by(|&a, &b| min_x(a).total_cmp(&min_x(b)).then(a.cmp(&b)));
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if min_x(j) > max_x(i) {
                break;
            }
            if i.abs_diff(j) <= 1 {
                continue;
            }
            // A closed ring (last vertex = first) is a self-intersection too.
            if segments_intersect(points[i], points[i + 1], points[j], points[j + 1]) {
                return true;
            }
        }
    }
    false
}

/// Checks lines given in longitude/latitude and converts them to cell coordinates of `grid`:
/// at least one line, at most [`MAX_VERTICES`] vertices, every vertex finite and inside the
/// bounds, no line shorter than [`MIN_LINE_CELLS`], none crossing itself, heights within
/// [`HEIGHT_RANGE_M`].
pub fn check_lines(
    grid: OutputGrid,
    lines: Vec<(FeatureKind, Vec<[f64; 2]>, Option<f64>)>,
) -> Result<Sketch, SketchError> {
    if lines.is_empty() {
        return Err(SketchError::Invalid(
            "the sketch has no ridge or valley lines".into(),
        ));
    }
    let vertices: usize = lines.iter().map(|l| l.1.len()).sum();
    if vertices > MAX_VERTICES {
        return Err(SketchError::Invalid(format!(
            "the sketch has {vertices} vertices; at most {MAX_VERTICES} are allowed"
        )));
    }
    let mut out = Vec::with_capacity(lines.len());
    for (i, (kind, lonlat, height)) in lines.into_iter().enumerate() {
        let n = i + 1;
        if let Some(h) = height {
            if !h.is_finite() || h < HEIGHT_RANGE_M.0 || h > HEIGHT_RANGE_M.1 {
                return Err(SketchError::Invalid(format!(
                    "line {n}: height_m {h} is not between {} and {} m",
                    HEIGHT_RANGE_M.0, HEIGHT_RANGE_M.1
                )));
            }
        }
        let mut points: Vec<[f64; 2]> = Vec::with_capacity(lonlat.len());
        for p in lonlat {
            if !p[0].is_finite() || !p[1].is_finite() {
                return Err(SketchError::Invalid(format!(
                    "line {n}: coordinates must be finite numbers"
                )));
            }
            let c = grid.to_cell(p[0], p[1]);
            if !grid.contains(c) {
                return Err(SketchError::Invalid(format!(
                    "line {n}: vertex ({}, {}) lies outside the bounds",
                    p[0], p[1]
                )));
            }
            if points.last().is_none_or(|&q| dist(q, c) > 1e-9) {
                points.push(c);
            }
        }
        let line = SketchLine {
            kind,
            points,
            height_m: height,
        };
        if line.points.len() < 2 || line.length() < MIN_LINE_CELLS {
            return Err(SketchError::Invalid(format!(
                "line {n} is shorter than {MIN_LINE_CELLS} cells"
            )));
        }
        if self_intersects(&line.points) {
            return Err(SketchError::Invalid(format!(
                "line {n} crosses or doubles back on itself"
            )));
        }
        out.push(line);
    }
    Ok(Sketch { grid, lines: out })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resample_keeps_ends_and_spacing() {
        let p = resample(&[[0.0, 0.0], [3.0, 0.0], [3.0, 2.5]], 1.0);
        assert_eq!(p.first(), Some(&[0.0, 0.0]));
        assert_eq!(p.last(), Some(&[3.0, 2.5]));
        assert_eq!(p.len(), 7);
        for w in p.windows(2).take(5) {
            assert!((dist(w[0], w[1]) - 1.0).abs() < 1e-9 || w[0][0] == 3.0 || w[1][0] == 3.0);
        }
    }

    #[test]
    fn crossings_and_folds_are_found() {
        assert!(!self_intersects(&[
            [0.0, 0.0],
            [5.0, 0.0],
            [5.0, 5.0],
            [0.0, 6.0]
        ]));
        assert!(self_intersects(&[
            [0.0, 0.0],
            [5.0, 0.0],
            [5.0, 5.0],
            [2.0, -3.0]
        ]));
        assert!(self_intersects(&[[0.0, 0.0], [5.0, 0.0], [2.0, 0.0]]));
        assert!(self_intersects(&[
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [0.0, 0.0]
        ]));
    }

    #[test]
    fn grid_of_bounds() {
        let spec = OutputSpec {
            west: 74.0,
            south: 42.0,
            east: 74.5,
            north: 42.25,
            cell_deg: 1.0 / 240.0,
        };
        let g = spec.grid(&SizeLimits::default()).unwrap();
        assert_eq!((g.cols, g.rows), (120, 60));
        let c = g.to_cell(74.0 + 0.5 / 240.0, 42.25 - 0.5 / 240.0);
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9);
        let small = SizeLimits {
            max_pixels: 1000,
            max_dimension: 4096,
        };
        assert!(matches!(spec.grid(&small), Err(SketchError::TooLarge(_))));
    }
}
