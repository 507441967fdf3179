//! The drainage pyramid: upstream area in m² at every zoom.
//!
//! - **Native zoom `z_b`**: cut from the whole-world D8 accumulation ([`crate::base_layers`]).
//! - **Amplified zooms**: D8 on the amplified surface over the tile plus a halo of
//!   [`drain_halo`] pixels (priority-flood filled to the spill levels, flats drained by
//!   [`analysis::d8_receivers_over_flats`], resolved in full up to the halo's width, wider
//!   ones guided by the parent level's rivers, [`FLAT_GUIDE_M2`]), with sources = cell areas plus the parent
//!   level's upstream area injected where parent flow enters the region: every parent pixel of
//!   the ring around the region whose steepest descent points into it hands its area to the
//!   lowest child of the pixel it drains into. The region is a function of the tile's global coordinates only, so a
//!   drainage value is a pure function of `(z, x, y)`: a tile alone equals the same window of any
//!   larger assembled region, and the halo keeps routing identical near tile borders.
//! - **Coverage**: upstream area is 0 outside the base's coverage ([`crate::coverage`]), where
//!   amplified levels have no sources either: nothing is routed there.
//! - **Water** ([`crate::water`]): the upstream area is 0 under water; sea pixels are sinks and
//!   have no sources (flow ends at the coast), lakes are routed across their filled surface so
//!   they pass their inflow on at their outlet.
//! - **Overviews** (`z < z_b`): the maximum of the 2×2 children (the upstream area of the coarse
//!   pixel's main channel).

use std::sync::Arc;

use ndarray::{s, Array2};

use terrasynth_core::analysis::{self, D8_OFFSETS};
use terrasynth_core::math;
use terrasynth_core::synth::Window;

use crate::base_layers::{cut, WholeWorld};
use crate::coverage::mask_in_place;
use crate::elevation::ElevationLevels;
use crate::error::TileError;
use crate::pyramid::{assemble_concurrently, overview, tile_window, LevelCache};
use crate::water::{zero_under_water, WaterLevels, DEPTH, SEA};

/// Ground the routing halo of an amplified drainage tile aims to reach (metres of the zoom's
/// Mercator pixel at the equator, within [`MIN_DRAIN_HALO`] and [`MAX_DRAIN_HALO`] pixels): about
/// twice the side of the catchment of the smallest channel the drainage PNG draws (10⁶ m²), so
/// that two neighbouring tiles route a drawn channel over the same ground near their border.
pub const DRAIN_HALO_M: f64 = 2000.0;

/// Smallest routing halo (pixels): every zoom up to 13 uses it.
pub const MIN_DRAIN_HALO: i64 = 128;

/// Largest routing halo (pixels): the most that keeps a tile's region within its 3×3 tiles and
/// its parent ring within 2×2 parent tiles, so a deeper halo does not widen the chain below.
pub const MAX_DRAIN_HALO: i64 = 254;

/// The routing halo (pixels, even, so that the region maps onto whole parent pixels) of an
/// amplified drainage tile of zoom `z`: [`DRAIN_HALO_M`] in the zoom's equatorial pixels, within
/// [`MIN_DRAIN_HALO`]–[`MAX_DRAIN_HALO`] (128 up to zoom 13, 210 at 14, 254 from 15).
pub fn drain_halo(z: u8) -> i64 {
    let px = (DRAIN_HALO_M / crate::mercator::pixel_size_m(z)).ceil() as i64;
    (px + px % 2).clamp(MIN_DRAIN_HALO, MAX_DRAIN_HALO)
}

/// Upstream area (m²) from which a parent-level pixel guides the flow across a wide flat of its
/// children ([`analysis::flats`]): a river of 100 km², so that a lake wider than the routing
/// halo is crossed by the channel its parent level drew across it.
pub const FLAT_GUIDE_M2: f32 = 1e8;

/// The drainage levels of a world.
#[derive(Debug)]
pub struct DrainageLevels {
    cache: LevelCache<Array2<f32>>,
}

fn max4(v: [f32; 4]) -> f32 {
    v[0].max(v[1]).max(v[2]).max(v[3])
}

impl DrainageLevels {
    /// Drainage levels cached in at most `cache_bytes` bytes.
    pub fn new(cache_bytes: u64) -> Self {
        DrainageLevels {
            cache: LevelCache::new("drainage", cache_bytes),
        }
    }

    /// The cache of level tiles.
    pub fn cache(&self) -> &LevelCache<Array2<f32>> {
        &self.cache
    }

    /// The drainage level tile `(z, tx, ty)`, computed once.
    pub fn tile(
        &self,
        elevation: &ElevationLevels,
        whole: &WholeWorld,
        water: &WaterLevels,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Array2<f32>>, TileError> {
        self.cache.get_or_compute((z, tx, ty), || {
            self.compute(elevation, whole, water, z, tx, ty)
        })
    }

    /// Drainage over window `w` of zoom `z`, assembled from tiles.
    pub fn window(
        &self,
        elevation: &ElevationLevels,
        whole: &WholeWorld,
        water: &WaterLevels,
        z: u8,
        w: Window,
    ) -> Result<Array2<f32>, TileError> {
        assemble_concurrently(
            w,
            1,
            |tx, ty| self.cache.is_known(&(z, tx, ty)),
            |tx, ty| self.tile(elevation, whole, water, z, tx, ty),
        )
    }

    fn compute(
        &self,
        elevation: &ElevationLevels,
        whole: &WholeWorld,
        water: &WaterLevels,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Array2<f32>, TileError> {
        let w = tile_window(tx, ty);
        let extent = elevation.extent();
        let zb = extent.z_base;
        if z == zb {
            let base = whole.get(elevation)?;
            let mut area = cut(&base.area, base.window, w, 0.0);
            let coverage = elevation.coverage_tile(z, tx, ty)?;
            mask_in_place(&mut area, &coverage);
            zero_under_water(&mut area, &water.tile(elevation, z, tx, ty)?[DEPTH]);
            return Ok(area);
        }
        if z < zb {
            return overview(tx, ty, 1, 0.0, max4, |cx, cy| {
                if extent.tile_outside(z + 1, cx, cy) {
                    return Ok(None);
                }
                self.tile(elevation, whole, water, z + 1, cx, cy).map(Some)
            });
        }
        // The routing region: the tile plus an even halo, so that it maps onto whole parent
        // pixels.
        let h = drain_halo(z);
        let region = w.grown(h);
        // The parent level first: a chain of cold levels waits here, level under level, and a
        // level that waits holds none of its own region's grids yet (computed after the wait,
        // the routing's buffers live one level at a time instead of down the whole chain).
        let pw = Window::new(
            region.col0 / 2,
            region.row0 / 2,
            region.cols / 2,
            region.rows / 2,
        );
        let aw = Window::new(pw.col0 - 1, pw.row0 - 1, pw.cols + 2, pw.rows + 2);
        let pa = self.window(elevation, whole, water, z - 1, aw)?;
        let heights = elevation.window(z, region)?;
        let cells = extent.cell_sizes(z, region.row0, region.rows);
        // Filled to the spill levels; flats drain towards their outlets and away from higher
        // ground (converging into a flat valley floor's middle, not down parallel lines), those
        // wider than the halo or on the region's border ring towards their outlets and the
        // parent level's rivers across them (a flat resolved in full that reaches the tile's
        // border lies inside the neighbour's region too, so both give it the same directions).
        let filled = analysis::priority_flood_fill_flat(&heights);
        let flat_span = usize::try_from(h).unwrap_or(0);
        // Asked of flat cells only: a region without flats costs nothing here.
        let guide = |r: usize, c: usize| pa[[r / 2 + 1, c / 2 + 1]] >= FLAT_GUIDE_M2;
        let mut receivers =
            analysis::d8_receivers_over_flats(&filled, &cells, flat_span, Some(&guide));
        // Nothing is routed outside the base's coverage or from the sea: no sources there; flow
        // ends where it enters the sea.
        let coverage = elevation.coverage_window(z, region)?;
        let wet = water.window(elevation, z, region)?;
        ndarray::Zip::from(&mut receivers)
            .and(&wet[SEA])
            .for_each(|code, &sea| {
                if sea > 0.0 {
                    *code = analysis::D8_NONE;
                }
            });
        let mut sources =
            ndarray::Zip::indexed(&coverage)
                .and(&wet[SEA])
                .map_collect(|(r, _), &cover, &sea| {
                    if crate::coverage::uncovered(cover) || sea > 0.0 {
                        0.0
                    } else {
                        cells.area(r)
                    }
                });
        // Parent inflow: parent pixels on the ring around the region's parent window whose
        // steepest descent points into it.
        let ew = Window::new(pw.col0 - 2, pw.row0 - 2, pw.cols + 4, pw.rows + 4);
        let pe = elevation.window(z - 1, ew)?;
        let pcells = extent.cell_sizes(z - 1, ew.row0, ew.rows);
        for (qr, qc) in ring(aw) {
            // (qr, qc) are global parent coordinates on the ring.
            let er = (qr - ew.row0) as usize;
            let ec = (qc - ew.col0) as usize;
            let zq = f64::from(pe[[er, ec]]);
            let (dx, dy) = (pcells.dx[er], pcells.dy[er]);
            let diagonal = math::hypot(dx, dy);
            let mut best = 0.0f64;
            let mut target = None;
            for &(dr, dc) in &D8_OFFSETS {
                let (nr, nc) = (er as isize + dr, ec as isize + dc);
                let dist = match (dr != 0, dc != 0) {
                    (true, true) => diagonal,
                    (true, false) => dy,
                    _ => dx,
                };
                let drop = zq - f64::from(pe[[nr as usize, nc as usize]]);
                if drop > 0.0 && drop / dist > best {
                    best = drop / dist;
                    target = Some((qr + dr as i64, qc + dc as i64));
                }
            }
            let Some((trow, tcol)) = target else { continue };
            if trow < pw.row0 || trow >= pw.row1() || tcol < pw.col0 || tcol >= pw.col1() {
                continue;
            }
            let inflow = f64::from(pa[[(qr - aw.row0) as usize, (qc - aw.col0) as usize]]);
            // The lowest of the target's four children (ties: row-major first).
            let (cr, cc) = (
                (2 * trow - region.row0) as usize,
                (2 * tcol - region.col0) as usize,
            );
            let mut low = (cr, cc);
            for (r, c) in [(cr, cc + 1), (cr + 1, cc), (cr + 1, cc + 1)] {
                if heights[[r, c]] < heights[low] {
                    low = (r, c);
                }
            }
            sources[low] += inflow;
        }
        let area = analysis::accumulate_sources(&receivers, &sources);
        let hs = h as usize;
        let mut out = area
            .slice(s![hs..hs + w.rows, hs..hs + w.cols])
            .mapv(|v| v as f32);
        mask_in_place(
            &mut out,
            &coverage
                .slice(s![hs..hs + w.rows, hs..hs + w.cols])
                .to_owned(),
        );
        zero_under_water(
            &mut out,
            &wet[DEPTH]
                .slice(s![hs..hs + w.rows, hs..hs + w.cols])
                .to_owned(),
        );
        Ok(out)
    }
}

/// The global coordinates `(row, col)` of the one-pixel ring just inside window `w`'s edge, in
/// row-major order.
fn ring(w: Window) -> Vec<(i64, i64)> {
    let mut out = Vec::new();
    for r in w.row0..w.row1() {
        if r == w.row0 || r == w.row1() - 1 {
            out.extend((w.col0..w.col1()).map(|c| (r, c)));
        } else {
            out.push((r, w.col0));
            out.push((r, w.col1() - 1));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The halo reaches about 2 km at zoom 14 (as far as the bounds allow deeper) and stays within
    /// the bounds that keep a tile's chain as narrow as before: its region within its 3×3 tiles,
    /// the ring of its parent window within 2×2 parent tiles (both parities of the tile's column
    /// and row).
    #[test]
    fn the_routing_halo_grows_with_depth_within_the_narrow_chain() {
        let halos: Vec<i64> = (0..=24).map(drain_halo).collect();
        assert!(
            halos[..=13].iter().all(|&h| h == MIN_DRAIN_HALO),
            "{halos:?}"
        );
        assert_eq!(halos[14], 210);
        assert!(
            halos[15..].iter().all(|&h| h == MAX_DRAIN_HALO),
            "{halos:?}"
        );
        for h in MIN_DRAIN_HALO..=MAX_DRAIN_HALO + 2 {
            if h % 2 != 0 {
                continue;
            }
            let narrow = [0i64, 1].iter().all(|&t| {
                let region = tile_window(t, t).grown(h);
                // Tiles holding columns first..=last.
                let tiles_over =
                    |first: i64, last: i64| last.div_euclid(256) - first.div_euclid(256) + 1;
                // The parent window's ring: one column either side of the region's half.
                let parents = tiles_over(region.col0 / 2 - 1, region.col1() / 2);
                let tiles = tiles_over(region.col0, region.col1() - 1);
                parents == 2 && tiles == 3
            });
            assert_eq!(narrow, h <= MAX_DRAIN_HALO, "halo {h}");
        }
    }
}
