//! Water on a world's native-zoom plane: the sea (every covered cell below `sea_level_m`
//! connected to the edge of the window or to uncovered cells through such cells, 8-neighbour)
//! and lakes (depressions of the terrain, filled flat to their spill level by Priority-Flood,
//! whose area and depth reach the configured minima; depressions touching the sea or uncovered
//! cells drain there and are no lakes). The result is the water surface level of each cell (NaN
//! where dry) and whether it is sea; depths are `level − bed`.
//!
//! A pure function of its inputs; the order of every traversal is fixed (row-major seeds, FIFO
//! queues), so the result is deterministic.

use std::collections::VecDeque;

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::analysis::priority_flood_fill_flat;
use crate::raster::CellSizes;

use super::LandscapeError;

/// The water settings of a world (`sea_level_m` at the top of its TOML file and in the admin
/// API, the rest in its `[water]` section).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WaterConfig {
    /// Sea level, metres (`None`: no sea). Given at the top of a world file and in the admin
    /// API (`sea_level_m`), not in `[water]`; see [`default_sea_level`].
    #[serde(skip)]
    pub sea_level_m: Option<f32>,
    /// Whether depressions become lakes (default `false`: only the sea; worlds opt in, so the
    /// landscape of existing worlds does not change).
    pub lakes: bool,
    /// Smallest filled area of a depression that becomes a lake, m².
    pub lake_min_area_m2: f64,
    /// Smallest depth (spill level minus the lowest bed) of a depression that becomes a lake,
    /// metres.
    pub lake_min_depth_m: f32,
    /// Smallest area (m²) of a flat of the base (connected cells of exactly one elevation) that
    /// is a lake's surface ([`super::surface_lakes`]; `None`, the default: no such lakes). The
    /// flat's elevation is the lake's level; its bed is sunk below it by
    /// `surface_lake_bed_slope`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_lake_min_area_m2: Option<f64>,
    /// Depth gained per metre of distance from the shore by the bed of a surface lake (the base
    /// holds no bathymetry of it), m/m.
    pub surface_lake_bed_slope: f32,
    /// Colour of shallow water `[r, g, b]` (depth 0).
    pub shallow_colour: [u8; 3],
    /// Colour of deep water `[r, g, b]` (at and below `deep_m`).
    pub deep_colour: [u8; 3],
    /// Depth (m) at and below which water has the deep colour and is opaque in the PNG tiles.
    pub deep_m: f32,
}

impl Default for WaterConfig {
    fn default() -> Self {
        WaterConfig {
            sea_level_m: None,
            lakes: false,
            lake_min_area_m2: 1e6,
            lake_min_depth_m: 20.0,
            surface_lake_min_area_m2: None,
            surface_lake_bed_slope: 0.01,
            shallow_colour: [120, 190, 220],
            deep_colour: [20, 60, 130],
            deep_m: 50.0,
        }
    }
}

impl WaterConfig {
    /// Whether a world with these settings can have any water at all: a sea level, lakes or
    /// surface lakes.
    /// A world without either is dry everywhere, so it needs no water grids or tiles.
    pub fn may_have_water(&self) -> bool {
        self.sea_level_m.is_some() || self.lakes || self.surface_lake_min_area_m2.is_some()
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<(), LandscapeError> {
        let bad = |m: &str| Err(LandscapeError::Invalid(m.into()));
        if self
            .sea_level_m
            .is_some_and(|s| !s.is_finite() || s.abs() > 12_000.0)
        {
            return bad("sea_level_m must be a finite elevation within ±12,000 m");
        }
        if !(self.lake_min_area_m2.is_finite() && self.lake_min_area_m2 >= 0.0) {
            return bad("water.lake_min_area_m2 must be finite and ≥ 0");
        }
        if !(self.lake_min_depth_m.is_finite() && self.lake_min_depth_m > 0.0) {
            return bad("water.lake_min_depth_m must be finite and > 0");
        }
        if self
            .surface_lake_min_area_m2
            .is_some_and(|a| !(a.is_finite() && a > 0.0))
        {
            return bad("water.surface_lake_min_area_m2 must be finite and > 0");
        }
        if !(self.surface_lake_bed_slope.is_finite()
            && self.surface_lake_bed_slope > 0.0
            && self.surface_lake_bed_slope <= 1.0)
        {
            return bad("water.surface_lake_bed_slope must be finite, > 0 and ≤ 1");
        }
        if !(self.deep_m.is_finite() && self.deep_m > 0.0) {
            return bad("water.deep_m must be finite and > 0");
        }
        Ok(())
    }

    /// Colour and PNG alpha of water `depth` metres deep: the shallow colour blended towards
    /// the deep one, alpha from 96 (a film) to 255 at `deep_m`.
    pub fn colour_at(&self, depth: f32) -> ([u8; 3], u8) {
        let t = (depth / self.deep_m).clamp(0.0, 1.0);
        let mix = |a: u8, b: u8| (f32::from(a) + t * (f32::from(b) - f32::from(a))).round() as u8;
        let [s, d] = [self.shallow_colour, self.deep_colour];
        // Alpha rises from a visible film to opaque at `deep_m`.
        let alpha = (96.0 + 159.0 * t).round() as u8;
        ([mix(s[0], d[0]), mix(s[1], d[1]), mix(s[2], d[2])], alpha)
    }
}

/// The sea level of a world whose definition gives none: 0 m for a base with valid cells below
/// 0 (bathymetry), none otherwise. `base_min` is the lowest valid base value.
pub fn default_sea_level(base_min: Option<f32>) -> Option<f32> {
    base_min.filter(|&m| m < 0.0).map(|_| 0.0)
}

/// The water of a window: surface level (NaN where dry) and sea flags.
#[derive(Clone, Debug, PartialEq)]
pub struct Water {
    /// Water surface, metres; NaN where dry.
    pub level: Array2<f32>,
    /// Whether a wet cell is sea (else lake).
    pub sea: Array2<bool>,
}

/// The eight neighbour offsets `(dr, dc)`, row by row.
pub(super) const N8: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// The in-grid 8-neighbours of `(r, c)` on a `rows × cols` grid, in [`N8`]'s order.
pub(super) fn neighbours(
    r: usize,
    c: usize,
    rows: usize,
    cols: usize,
) -> impl Iterator<Item = (usize, usize)> {
    N8.iter().filter_map(move |&(dr, dc)| {
        let (nr, nc) = (r.checked_add_signed(dr)?, c.checked_add_signed(dc)?);
        (nr < rows && nc < cols).then_some((nr, nc))
    })
}

/// The sea and lakes of `heights` (bed elevation, metres) where `covered` holds; `cells` gives
/// the metric cell sizes of its rows.
pub fn water(
    heights: &Array2<f32>,
    covered: &Array2<bool>,
    cells: &CellSizes,
    cfg: &WaterConfig,
) -> Water {
    let (rows, cols) = heights.dim();
    let mut level = Array2::from_elem((rows, cols), f32::NAN);
    let mut sea = Array2::from_elem((rows, cols), false);
    if let Some(s) = cfg.sea_level_m {
        let below = |r: usize, c: usize| covered[[r, c]] && heights[[r, c]] < s;
        let mut queue = VecDeque::new();
        for r in 0..rows {
            for c in 0..cols {
                if !below(r, c) {
                    continue;
                }
                let edge = r == 0 || c == 0 || r + 1 == rows || c + 1 == cols;
                if edge || neighbours(r, c, rows, cols).any(|(nr, nc)| !covered[[nr, nc]]) {
                    sea[[r, c]] = true;
                    queue.push_back((r, c));
                }
            }
        }
        while let Some((r, c)) = queue.pop_front() {
            for (nr, nc) in neighbours(r, c, rows, cols) {
                if !sea[[nr, nc]] && below(nr, nc) {
                    sea[[nr, nc]] = true;
                    queue.push_back((nr, nc));
                }
            }
        }
        for ((r, c), &is_sea) in sea.indexed_iter() {
            if is_sea {
                level[[r, c]] = s;
            }
        }
    }
    if !cfg.lakes {
        return Water { level, sea };
    }
    // Lakes: depressions of the terrain, with sea and uncovered cells as outlets (lowest).
    let outlet = |r: usize, c: usize| sea[[r, c]] || !covered[[r, c]];
    let surface = Array2::from_shape_fn((rows, cols), |(r, c)| {
        if outlet(r, c) {
            f32::MIN
        } else {
            heights[[r, c]]
        }
    });
    let filled = priority_flood_fill_flat(&surface);
    let depressed = |r: usize, c: usize| !outlet(r, c) && filled[[r, c]] > heights[[r, c]];
    let mut seen = Array2::from_elem((rows, cols), false);
    let mut component = Vec::new();
    for r0 in 0..rows {
        for c0 in 0..cols {
            if seen[[r0, c0]] || !depressed(r0, c0) {
                continue;
            }
            // One depression: connected cells filled to the same level.
            let spill = filled[[r0, c0]];
            component.clear();
            seen[[r0, c0]] = true;
            let mut queue = VecDeque::from([(r0, c0)]);
            let (mut area, mut depth, mut drains) = (0.0f64, 0.0f32, false);
            while let Some((r, c)) = queue.pop_front() {
                component.push((r, c));
                area += cells.area(r);
                depth = depth.max(spill - heights[[r, c]]);
                for (nr, nc) in neighbours(r, c, rows, cols) {
                    if outlet(nr, nc) && filled[[nr, nc]] >= spill {
                        drains = true;
                    }
                    if !seen[[nr, nc]] && depressed(nr, nc) && filled[[nr, nc]] == spill {
                        seen[[nr, nc]] = true;
                        queue.push_back((nr, nc));
                    }
                }
            }
            if !drains && area >= cfg.lake_min_area_m2 && depth >= cfg.lake_min_depth_m {
                for &(r, c) in &component {
                    level[[r, c]] = spill;
                }
            }
        }
    }
    Water { level, sea }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(sea: Option<f32>, area: f64, depth: f32) -> WaterConfig {
        WaterConfig {
            sea_level_m: sea,
            lakes: true,
            lake_min_area_m2: area,
            lake_min_depth_m: depth,
            ..WaterConfig::default()
        }
    }

    #[test]
    fn a_bowl_becomes_a_lake_at_its_spill_level_only_above_the_minima() {
        // 7×7 at 100 m, a 3×3 bowl at 90 (centre 80) whose rim has a notch at 95.
        let mut h = Array2::from_elem((7, 7), 100.0f32);
        for r in 2..5 {
            for c in 2..5 {
                h[[r, c]] = 90.0;
            }
        }
        h[[3, 3]] = 80.0;
        h[[1, 3]] = 95.0;
        h[[0, 3]] = 95.0;
        // The notch reaches the edge: the spill level is 95.
        let covered = Array2::from_elem((7, 7), true);
        let cells = CellSizes::uniform(7, 100.0);
        let w = water(&h, &covered, &cells, &cfg(None, 9.0 * 1e4, 15.0));
        for r in 0..7 {
            for c in 0..7 {
                let inside = (2..5).contains(&r) && (2..5).contains(&c);
                if inside {
                    assert_eq!(w.level[[r, c]], 95.0, "{r},{c}");
                } else {
                    assert!(w.level[[r, c]].is_nan(), "{r},{c}");
                }
            }
        }
        assert!(!w.sea.iter().any(|&s| s));
        // 9 cells of 1 ha: too small for 10 ha, too shallow for 16 m.
        assert!(water(&h, &covered, &cells, &cfg(None, 1e5, 1.0))
            .level
            .iter()
            .all(|v| v.is_nan()));
        assert!(water(&h, &covered, &cells, &cfg(None, 1.0, 16.0))
            .level
            .iter()
            .all(|v| v.is_nan()));
        // A bowl touching an uncovered cell drains there.
        let mut holed = covered.clone();
        holed[[3, 3]] = false;
        assert!(water(&h, &holed, &cells, &cfg(None, 1.0, 1.0))
            .level
            .iter()
            .all(|v| v.is_nan()));
    }

    #[test]
    fn the_sea_is_what_lies_below_sea_level_and_reaches_the_edge() {
        // A ramp from −30 (west) to +30 (east) with an inland pit below 0 behind a ridge.
        let mut h = Array2::from_shape_fn((5, 7), |(_, c)| -30.0 + 10.0 * c as f32);
        for r in 0..5 {
            h[[r, 4]] = 50.0;
        }
        h[[2, 5]] = -5.0;
        let covered = Array2::from_elem((5, 7), true);
        let cells = CellSizes::uniform(5, 100.0);
        let w = water(&h, &covered, &cells, &cfg(Some(0.0), f64::MAX, 1e6));
        for r in 0..5 {
            for c in 0..7 {
                let is_sea = c < 3;
                assert_eq!(w.sea[[r, c]], is_sea, "{r},{c}");
                assert_eq!(w.level[[r, c]] == 0.0, is_sea, "{r},{c}");
            }
        }
    }
}
