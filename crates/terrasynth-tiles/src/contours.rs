//! Contour tiles: lines of equal served elevation (the values of the EXR elevation tile) over a
//! tile, encoded as a Mapbox Vector Tile 2.1 with one layer `contours` of line strings carrying
//! `elevation_m` (a double) and `index` (a bool, every fifth interval).
//!
//! The interval of zoom `z` is [`auto_interval`] of the world's metric cell size at that zoom
//! (the largest of 1, 2, 5 × 10ⁿ metres not above four cells: about one line per four pixels
//! on a 45° slope, i.e. 100 m at zoom 12, 20 m at zoom 14, 5 m at zoom 16 at 42°N), or the
//! request's `?interval=` in metres, which must be at least [`min_interval`] (a quarter of a
//! cell, and at least 1 cm).
//!
//! Seamless across tile borders: marching squares
//! ([`terrasynth_core::analysis::contour`]) runs over the tile's pixels plus a border of
//! [`BUFFER_PX`] + 1 pixels assembled from the neighbouring tiles (the pyramid's
//! [`World::elevation_window`], window-invariant), so every crossing is computed from the same
//! two global pixels in both tiles, and the lines are clipped to the tile plus the MVT buffer of
//! [`BUFFER_PX`] pixels.

use terrasynth_core::analysis::contour::contour_lines;
use terrasynth_core::math;
use terrasynth_core::synth::Window;

use crate::error::TileError;
use crate::instances::MVT_EXTENT;
use crate::mercator::TILE_SIZE;
use crate::world::World;

/// The MVT layer name of contour tiles.
pub const CONTOURS_LAYER: &str = "contours";

/// Lines reach this many pixels beyond the tile on every side (the MVT buffer: 64 of 4096).
pub const BUFFER_PX: f64 = 4.0;

/// Every `INDEX_EVERY`-th level (elevations multiple of `INDEX_EVERY × interval`) is an index
/// line.
pub const INDEX_EVERY: i64 = 5;

/// The smallest interval accepted anywhere, metres.
pub const MIN_INTERVAL_M: f64 = 0.01;

/// One piece of a contour line inside the tile plus buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct Contour {
    /// The line's elevation, metres.
    pub elevation_m: f64,
    /// Whether it is an index line (a multiple of five intervals).
    pub index: bool,
    /// Points `(x, y)` in pixels from the tile's north-west corner (may lie up to
    /// [`BUFFER_PX`] outside `[0, 256]`).
    pub points: Vec<(f64, f64)>,
}

/// The default interval for pixels of `cell_m` metres: the largest of 1, 2, 5 × 10ⁿ metres not
/// above `4 × cell_m`.
pub fn auto_interval(cell_m: f64) -> f64 {
    let target = (4.0 * cell_m).max(MIN_INTERVAL_M);
    let mut p = 10f64.powi(math::log10(target).floor() as i32);
    // log10 may round across a power of ten.
    while p > target {
        p /= 10.0;
    }
    while p * 10.0 <= target {
        p *= 10.0;
    }
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&v| v <= target)
        .unwrap_or(p)
}

/// The smallest `?interval=` accepted for pixels of `cell_m` metres: a quarter of a cell (at
/// most four lines per pixel on a 45° slope), and at least [`MIN_INTERVAL_M`].
pub fn min_interval(cell_m: f64) -> f64 {
    (cell_m / 4.0).max(MIN_INTERVAL_M)
}

/// Checks `?interval=` against zoom `z` of `world`: the message names the minimum when the
/// interval is too dense.
pub fn check_interval(world: &World, z: u8, interval: f64) -> Result<(), String> {
    let min = min_interval(world.level_cell_m(z));
    if !interval.is_finite() || interval <= 0.0 {
        return Err(format!(
            "interval {interval} must be a positive number of metres"
        ));
    }
    if interval < min {
        return Err(format!(
            "interval {interval} m is too dense for zoom {z}: at least {min:.3} m (a quarter of \
             the zoom's {:.3} m pixels)",
            world.level_cell_m(z)
        ));
    }
    Ok(())
}

/// The interval of tile requests of zoom `z`: `interval`, or [`auto_interval`].
pub fn interval_for(world: &World, z: u8, interval: Option<f64>) -> f64 {
    interval.unwrap_or_else(|| auto_interval(world.level_cell_m(z)))
}

/// Rounds a level to a micrometre, so that `k × interval` prints as the decimal it means.
fn level_value(k: i64, interval: f64) -> f64 {
    ((k as f64) * interval * 1e6).round() / 1e6
}

/// The contours of tile `(z, x, y)` of `world` at `interval` metres (`None`: the zoom's
/// [`auto_interval`]), ascending by elevation. CPU-bound.
pub fn contour_tile(
    world: &World,
    z: u8,
    x: u32,
    y: u32,
    interval: Option<f64>,
) -> Result<Vec<Contour>, TileError> {
    world.check_tile(z, x, y)?;
    let interval = interval_for(world, z, interval);
    check_interval(world, z, interval).map_err(TileError::Encode)?;
    let border = BUFFER_PX as i64 + 1;
    let n = TILE_SIZE as i64;
    let w = Window::new(
        i64::from(x) * n - border,
        i64::from(y) * n - border,
        (n + 2 * border) as usize,
        (n + 2 * border) as usize,
    );
    let heights = world.elevation_window(z, w)?;
    let (lo, hi) = heights
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(f64::from(v)), b.max(f64::from(v)))
        });
    if lo > hi {
        return Ok(Vec::new());
    }
    let (k0, k1) = (
        (lo / interval).ceil() as i64,
        (hi / interval).floor() as i64,
    );
    let ks: Vec<i64> = (k0..=k1).collect();
    let levels: Vec<f64> = ks.iter().map(|&k| level_value(k, interval)).collect();
    // Grid point (c, r) is the centre of pixel (r, c) of the window: tile pixels c − border + ½.
    let offset = 0.5 - border as f64;
    let (min, max) = (-BUFFER_PX, TILE_SIZE as f64 + BUFFER_PX);
    let mut out = Vec::new();
    for line in contour_lines(&heights, &levels) {
        let k = ks[line.level];
        let points: Vec<(f64, f64)> = line
            .points
            .iter()
            .map(|&(px, py)| (px + offset, py + offset))
            .collect();
        for piece in clip_polyline(&points, min, max) {
            out.push(Contour {
                elevation_m: levels[line.level],
                index: k.rem_euclid(INDEX_EVERY) == 0,
                points: piece,
            });
        }
    }
    Ok(out)
}

/// Segment `p → q` clipped to the square `[min, max]²` (Liang–Barsky); an end inside is kept
/// bit for bit.
fn clip_segment(
    p: (f64, f64),
    q: (f64, f64),
    min: f64,
    max: f64,
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (den, num) in [
        (-dx, p.0 - min),
        (dx, max - p.0),
        (-dy, p.1 - min),
        (dy, max - p.1),
    ] {
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = num / den;
            if den < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| (p.0 + t * dx, p.1 + t * dy);
    let a = if t0 > 0.0 { at(t0) } else { p };
    let b = if t1 < 1.0 { at(t1) } else { q };
    Some((a, b))
}

/// The pieces of a polyline inside the square `[min, max]²`.
pub fn clip_polyline(points: &[(f64, f64)], min: f64, max: f64) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let mut flush = |cur: &mut Vec<(f64, f64)>| {
        if cur.len() >= 2 {
            out.push(std::mem::take(cur));
        } else {
            cur.clear();
        }
    };
    for w in points.windows(2) {
        match clip_segment(w[0], w[1], min, max) {
            None => flush(&mut cur),
            Some((a, b)) => {
                if cur.last() != Some(&a) {
                    flush(&mut cur);
                    cur.push(a);
                }
                cur.push(b);
                if b != w[1] {
                    flush(&mut cur);
                }
            }
        }
    }
    flush(&mut cur);
    out
}

/// Contours as a Mapbox Vector Tile 2.1: layer [`CONTOURS_LAYER`], one line string per piece
/// in tile coordinates of extent 4096 (consecutive points rounding to the same coordinate
/// merged, pieces shorter than one unit left out), properties `elevation_m` and `index`. A tile
/// without lines has no layer.
pub fn encode_contours_mvt(contours: &[Contour]) -> Result<Vec<u8>, TileError> {
    let err = |e: mvt::Error| TileError::Encode(format!("MVT: {e}"));
    let mut tile = mvt::Tile::new(MVT_EXTENT);
    let scale = f64::from(MVT_EXTENT) / f64::from(TILE_SIZE);
    let mut layer = tile.create_layer(CONTOURS_LAYER);
    let mut any = false;
    for c in contours {
        let mut pts: Vec<(f64, f64)> = Vec::with_capacity(c.points.len());
        for &(px, py) in &c.points {
            let p = ((px * scale).round(), (py * scale).round());
            if pts.last() != Some(&p) {
                pts.push(p);
            }
        }
        if pts.len() < 2 {
            continue;
        }
        let mut enc = mvt::GeomEncoder::new(mvt::GeomType::Linestring);
        for (px, py) in pts {
            enc.add_point(px, py).map_err(err)?;
        }
        let mut f = layer.into_feature(enc.encode().map_err(err)?);
        f.add_tag_double("elevation_m", c.elevation_m);
        f.add_tag_bool("index", c.index);
        layer = f.into_layer();
        any = true;
    }
    if any {
        tile.add_layer(layer).map_err(err)?;
    }
    tile.to_bytes().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interval_rule_picks_one_two_five_steps_under_four_cells() {
        // Hand-computed: 4 × cell, rounded down to 1, 2 or 5 × 10ⁿ.
        for (cell, want) in [
            (29.0, 100.0),
            (14.5, 50.0),
            (7.3, 20.0),
            (3.6, 10.0),
            (1.8, 5.0),
            (0.9, 2.0),
            (117.0, 200.0),
            (25.0, 100.0),
            (0.5, 2.0),
            (0.3, 1.0),
            (0.001, 0.01),
        ] {
            let got = auto_interval(cell);
            assert!((got - want).abs() < 1e-9 * want, "{cell}: {got} vs {want}");
        }
        assert_eq!(min_interval(40.0), 10.0);
        assert_eq!(min_interval(0.001), MIN_INTERVAL_M);
    }

    #[test]
    fn clipping_keeps_inside_points_and_cuts_at_the_square() {
        let pieces = clip_polyline(
            &[(-10.0, 5.0), (5.0, 5.0), (8.0, 6.0), (20.0, 6.0)],
            0.0,
            10.0,
        );
        assert_eq!(
            pieces,
            vec![vec![(0.0, 5.0), (5.0, 5.0), (8.0, 6.0), (10.0, 6.0)]]
        );
        // Out, in, out, in: two pieces.
        let pieces = clip_polyline(
            &[(5.0, -5.0), (5.0, 5.0), (5.0, 15.0), (6.0, 5.0)],
            0.0,
            10.0,
        );
        assert_eq!(pieces.len(), 2);
        assert_eq!(pieces[0], vec![(5.0, 0.0), (5.0, 5.0), (5.0, 10.0)]);
        assert_eq!(pieces[1][1], (6.0, 5.0));
        assert!(clip_polyline(&[(-5.0, -5.0), (-1.0, 20.0)], 0.0, 10.0).is_empty());
    }
}
