//! A world's landscape layers on its tile pyramid: vegetation, drainage, splat weights and the
//! colour map, all windows of one plane per zoom like elevation.
//!
//! - **Native zoom `z_b`**: computed once per world on the window of the zoom-`z_b` plane that
//!   covers the world ([`BaseLayers`]): priority-flood filling and D8 flow accumulation of the
//!   whole base (upstream area in m²), and the niche model with the seeding simulation for
//!   vegetation.
//! - **Amplified zooms**: vegetation is synthesized by the amplifier from the *same matched
//!   atoms* as the elevation (the parent elevation window decides the matches; the species layers
//!   of the atoms are blended and corrected so their 2×2 averages reproduce the parent densities;
//!   a species the dictionary lacks is carried by the smooth up-sampling of its parent), then the
//!   niche model on the served terrain moves the density of each parent pixel among its 2×2
//!   children in proportion to their suitability (the parent's density is kept), and the
//!   viability step fades it on marginal ground and zeroes it where the niche excludes it. Drainage routes D8 on the amplified surface over the tile plus a [`DRAIN_HALO`]-pixel
//!   halo (priority-flood filled), with sources = cell areas plus the parent level's upstream area
//!   injected where parent flow enters the region: every parent pixel of the ring around the
//!   region whose steepest descent points into it hands its area to the lowest child of the
//!   pixel it drains into. The region is a function of the tile's global coordinates only, so a
//!   drainage value is a pure function of `(z, x, y)`: a tile alone equals the same window of any
//!   larger assembled region, and the halo keeps routing identical near tile borders.
//! - **Overviews** (`z < z_b`): vegetation is the 2×2 box average of the children (densities
//!   average), drainage their maximum (the upstream area of the coarse pixel's main channel).
//!
//! Splat weights and the colour map are per-pixel functions of the tile's elevation (slope,
//! northness and curvature from a one-pixel border), wetness (log10 of the drainage) and
//! vegetation, so they are seamless and deterministic whenever those are.

use std::sync::Arc;

use ndarray::{s, Array2};

use super::error::TileError;
use super::mercator::{lonlat_to_global_pixel, pixel_size_m, TILE_SIZE};
use super::world::{for_each_tile_part, World};
use crate::analysis::{self, D8_OFFSETS};
use crate::landscape::{self, vegetation, LayerInputs};
use crate::synth::{Field, Window};

const T: i64 = TILE_SIZE as i64;
/// Halo (pixels, even) of the local drainage routing around an amplified tile.
pub const DRAIN_HALO: i64 = 128;

/// Whole-world layers at the native zoom.
#[derive(Debug)]
pub struct BaseLayers {
    /// The window of the native zoom's plane they cover.
    pub window: Window,
    /// D8 upstream area, m².
    pub area: Array2<f32>,
    /// Vegetation densities, one grid per species.
    pub vegetation: Vec<Array2<f32>>,
}

/// Copies the part of `a` (held over `aw`) that lies in `w` into a `w`-shaped grid, `fill`
/// elsewhere.
fn cut(a: &Array2<f32>, aw: Window, w: Window, fill: f32) -> Array2<f32> {
    let mut out = Array2::from_elem((w.rows, w.cols), fill);
    let c0 = w.col0.max(aw.col0);
    let c1 = w.col1().min(aw.col1());
    let r0 = w.row0.max(aw.row0);
    let r1 = w.row1().min(aw.row1());
    if c0 < c1 && r0 < r1 {
        out.slice_mut(s![
            (r0 - w.row0) as usize..(r1 - w.row0) as usize,
            (c0 - w.col0) as usize..(c1 - w.col0) as usize
        ])
        .assign(&a.slice(s![
            (r0 - aw.row0) as usize..(r1 - aw.row0) as usize,
            (c0 - aw.col0) as usize..(c1 - aw.col0) as usize
        ]));
    }
    out
}

/// The window of zoom `z`'s plane that the whole-world layers cover: the world's bounds
/// `(w, s, e, n)` plus two pixels.
pub(super) fn base_layer_window(z: u8, bounds: [f64; 4]) -> Window {
    let (px0, py0) = lonlat_to_global_pixel(z, bounds[0], bounds[3]);
    let (px1, py1) = lonlat_to_global_pixel(z, bounds[2], bounds[1]);
    Window::from_bounds(
        px0.floor() as i64 - 2,
        py0.floor() as i64 - 2,
        px1.ceil() as i64 + 2,
        py1.ceil() as i64 + 2,
    )
}

/// Bytes the whole-world layers over `window` hold: the upstream area and one grid per species,
/// f32 each.
pub(super) fn base_layer_bytes(window: Window, species: usize) -> u64 {
    (window.len() as u64).saturating_mul(4 * (1 + species as u64))
}

fn synth_err(e: impl std::fmt::Display) -> TileError {
    TileError::Synthesis(e.to_string())
}

/// Slope (degrees), northness and curvature of the window `w` of zoom `z`, from the elevation
/// over `w` plus a one-pixel border (so values are seamless).
struct Terrain {
    elevation: Array2<f32>,
    slope: Array2<f32>,
    northness: Array2<f32>,
    curvature: Array2<f32>,
    shade: Array2<f32>,
}

impl World {
    /// The landscape configuration.
    pub fn landscape(&self) -> &landscape::LandscapeConfig {
        &self.landscape
    }

    fn base_layers(&self) -> Result<Arc<BaseLayers>, TileError> {
        self.base_layers
            .get_or_init(|| self.compute_base_layers().map(Arc::new))
            .clone()
    }

    /// Computes the whole-world layers of the native zoom now (drainage of the whole base and
    /// the base vegetation), which are otherwise computed by the first landscape request that
    /// needs them; a request arriving meanwhile waits for the same computation. Returns the bytes
    /// they hold.
    pub fn prepare_landscape(&self) -> Result<u64, TileError> {
        self.base_layers()
            .map(|b| base_layer_bytes(b.window, b.vegetation.len()))
    }

    fn compute_base_layers(&self) -> Result<BaseLayers, TileError> {
        let z = self.z_base();
        let window = base_layer_window(z, self.bounds());
        if window.len() > (1 << 26) {
            return Err(synth_err(format!(
                "the native-zoom window {window} is too large for whole-world layers"
            )));
        }
        let elevation = self.elevation_window(z, window)?;
        let cells = self.cell_sizes(z, window.row0, window.rows);
        let area64 =
            analysis::flow_accumulation_d8(&analysis::priority_flood_fill(&elevation), &cells);
        let wet = analysis::log_upstream_area(&area64);
        let area = area64.mapv(|v| v as f32);
        drop(area64);
        let vegetation = vegetation::densities(
            &self.landscape,
            &elevation,
            &cells,
            &wet,
            (window.row0, window.col0),
        );
        Ok(BaseLayers {
            window,
            area,
            vegetation,
        })
    }

    /// The drainage tile `(z, x, y)`: upstream area in m² (after [`World::check_tile`]).
    pub fn drainage_tile(&self, z: u8, x: u32, y: u32) -> Result<Arc<Array2<f32>>, TileError> {
        self.check_tile(z, x, y)?;
        self.drainage_level_tile(z, i64::from(x), i64::from(y))
    }

    /// The vegetation tile `(z, x, y)`: one density grid (0–1) per species.
    pub fn vegetation_tile(
        &self,
        z: u8,
        x: u32,
        y: u32,
    ) -> Result<Arc<Vec<Array2<f32>>>, TileError> {
        self.check_tile(z, x, y)?;
        self.vegetation_level_tile(z, i64::from(x), i64::from(y))
    }

    /// Drainage over an arbitrary window of zoom `z`, assembled from drainage tiles.
    pub fn drainage_window(&self, z: u8, w: Window) -> Result<Array2<f32>, TileError> {
        let mut out = Array2::<f32>::zeros((w.rows, w.cols));
        for_each_tile_part(w, |tx, ty, src, dst| {
            let t = self.drainage_level_tile(z, tx, ty)?;
            out.slice_mut(s![dst.0, dst.1])
                .assign(&t.slice(s![src.0, src.1]));
            Ok(())
        })?;
        Ok(out)
    }

    /// Vegetation over an arbitrary window of zoom `z`, one grid per species.
    pub fn vegetation_window(&self, z: u8, w: Window) -> Result<Vec<Array2<f32>>, TileError> {
        let n = self.landscape.species.len();
        let mut out: Vec<Array2<f32>> = (0..n).map(|_| Array2::zeros((w.rows, w.cols))).collect();
        for_each_tile_part(w, |tx, ty, src, dst| {
            let t = self.vegetation_level_tile(z, tx, ty)?;
            for (o, a) in out.iter_mut().zip(t.iter()) {
                o.slice_mut(s![dst.0.clone(), dst.1.clone()])
                    .assign(&a.slice(s![src.0.clone(), src.1.clone()]));
            }
            Ok(())
        })?;
        Ok(out)
    }

    fn drainage_level_tile(&self, z: u8, tx: i64, ty: i64) -> Result<Arc<Array2<f32>>, TileError> {
        let key = (z, tx, ty);
        if let Some(t) = self.drainage_cache.get(&key) {
            return Ok(t);
        }
        self.drainage_cache
            .try_get_with(key, || self.compute_drainage(z, tx, ty).map(Arc::new))
            .map_err(|e: Arc<TileError>| (*e).clone())
    }

    fn vegetation_level_tile(
        &self,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Vec<Array2<f32>>>, TileError> {
        let key = (z, tx, ty);
        if let Some(t) = self.vegetation_cache.get(&key) {
            return Ok(t);
        }
        self.vegetation_cache
            .try_get_with(key, || self.compute_vegetation(z, tx, ty).map(Arc::new))
            .map_err(|e: Arc<TileError>| (*e).clone())
    }

    fn tile_window(tx: i64, ty: i64) -> Window {
        Window::new(tx * T, ty * T, T as usize, T as usize)
    }

    /// Combines the four children of an overview tile with `f` over each 2×2 block (`fill` where
    /// a child lies outside the world).
    fn overview_of(
        &self,
        z: u8,
        tx: i64,
        ty: i64,
        child: &dyn Fn(i64, i64) -> Result<Arc<Array2<f32>>, TileError>,
        f: fn([f32; 4]) -> f32,
    ) -> Result<Array2<f32>, TileError> {
        let half = (T / 2) as usize;
        let mut out = Array2::<f32>::zeros((T as usize, T as usize));
        for (dy, dx) in [(0i64, 0i64), (0, 1), (1, 0), (1, 1)] {
            let (cx, cy) = (2 * tx + dx, 2 * ty + dy);
            if self.tile_outside(z + 1, cx, cy) {
                continue;
            }
            let c = child(cx, cy)?;
            let (r0, c0) = (dy as usize * half, dx as usize * half);
            for r in 0..half {
                for k in 0..half {
                    out[[r0 + r, c0 + k]] = f([
                        c[[2 * r, 2 * k]],
                        c[[2 * r, 2 * k + 1]],
                        c[[2 * r + 1, 2 * k]],
                        c[[2 * r + 1, 2 * k + 1]],
                    ]);
                }
            }
        }
        Ok(out)
    }

    fn compute_drainage(&self, z: u8, tx: i64, ty: i64) -> Result<Array2<f32>, TileError> {
        let w = Self::tile_window(tx, ty);
        let zb = self.z_base();
        if z == zb {
            let base = self.base_layers()?;
            return Ok(cut(&base.area, base.window, w, 0.0));
        }
        if z < zb {
            return self.overview_of(
                z,
                tx,
                ty,
                &|cx, cy| self.drainage_level_tile(z + 1, cx, cy),
                |v| v[0].max(v[1]).max(v[2]).max(v[3]),
            );
        }
        // The routing region: the tile plus an even halo, so that it maps onto whole parent
        // pixels.
        let h = DRAIN_HALO;
        let region = Window::new(
            w.col0 - h,
            w.row0 - h,
            w.cols + 2 * h as usize,
            w.rows + 2 * h as usize,
        );
        let elevation = self.elevation_window(z, region)?;
        let cells = self.cell_sizes(z, region.row0, region.rows);
        let filled = analysis::priority_flood_fill(&elevation);
        let receivers = analysis::d8_receivers(&filled, &cells);
        let mut sources = Array2::from_shape_fn(elevation.dim(), |(r, _)| cells.area(r));
        // Parent inflow: parent pixels on the ring around the region's parent window whose
        // steepest descent points into it.
        let pw = Window::new(
            region.col0 / 2,
            region.row0 / 2,
            region.cols / 2,
            region.rows / 2,
        );
        let ew = Window::new(pw.col0 - 2, pw.row0 - 2, pw.cols + 4, pw.rows + 4);
        let pe = self.elevation_window(z - 1, ew)?;
        let aw = Window::new(pw.col0 - 1, pw.row0 - 1, pw.cols + 2, pw.rows + 2);
        let pa = self.drainage_window(z - 1, aw)?;
        let pcells = self.cell_sizes(z - 1, ew.row0, ew.rows);
        for (qr, qc) in ring(aw) {
            // (qr, qc) are global parent coordinates on the ring.
            let er = (qr - ew.row0) as usize;
            let ec = (qc - ew.col0) as usize;
            let zq = f64::from(pe[[er, ec]]);
            let (dx, dy) = (pcells.dx[er], pcells.dy[er]);
            let mut best = 0.0f64;
            let mut target = None;
            for &(dr, dc) in &D8_OFFSETS {
                let (nr, nc) = (er as isize + dr, ec as isize + dc);
                let dist = match (dr != 0, dc != 0) {
                    (true, true) => dx.hypot(dy),
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
                if elevation[[r, c]] < elevation[low] {
                    low = (r, c);
                }
            }
            sources[low] += inflow;
        }
        let area = analysis::accumulate_sources(&receivers, &sources);
        let hs = h as usize;
        Ok(area
            .slice(s![hs..hs + w.rows, hs..hs + w.cols])
            .mapv(|v| v as f32))
    }

    /// Elevation, slope, northness, curvature and hillshade of a tile window, seamless thanks
    /// to a one-pixel border read from the neighbouring tiles.
    fn terrain(&self, z: u8, w: Window) -> Result<Terrain, TileError> {
        let b = Window::new(w.col0 - 1, w.row0 - 1, w.cols + 2, w.rows + 2);
        let e = self.elevation_window(z, b)?;
        let cells = self.cell_sizes(z, b.row0, b.rows);
        let inner = |a: Array2<f32>| a.slice(s![1..=w.rows, 1..=w.cols]).to_owned();
        Ok(Terrain {
            slope: inner(analysis::slope_degrees(&e, &cells)),
            northness: inner(analysis::northness(&e, &cells)),
            curvature: inner(analysis::curvature(&e, &cells)),
            shade: inner(analysis::hillshade(
                &e,
                &cells,
                analysis::DEFAULT_AZIMUTH_DEG,
                analysis::DEFAULT_ALTITUDE_DEG,
            )),
            elevation: inner(e),
        })
    }

    fn compute_vegetation(&self, z: u8, tx: i64, ty: i64) -> Result<Vec<Array2<f32>>, TileError> {
        let w = Self::tile_window(tx, ty);
        let zb = self.z_base();
        let species = &self.landscape.species;
        if z == zb {
            let base = self.base_layers()?;
            return Ok(base
                .vegetation
                .iter()
                .map(|a| cut(a, base.window, w, 0.0))
                .collect());
        }
        if z < zb {
            return (0..species.len())
                .map(|k| {
                    self.overview_of(
                        z,
                        tx,
                        ty,
                        &|cx, cy| {
                            self.vegetation_level_tile(z + 1, cx, cy)
                                .map(|t| Arc::new(t[k].clone()))
                        },
                        |v| (v[0] + v[1] + v[2] + v[3]) * 0.25,
                    )
                })
                .collect();
        }
        // Same parent elevation window, hence same matches, as the elevation tile.
        let amp = &self.layer_amplifier;
        let need = amp.parent_window_for(w);
        let parent_elev = self.elevation_window(z - 1, need)?;
        let parent_veg = self.vegetation_window(z - 1, need)?;
        let in_dict: Vec<bool> = species
            .iter()
            .map(|sp| amp.dictionary().layer_index(&sp.name).is_some())
            .collect();
        let parent = Field {
            window: need,
            elevation: parent_elev,
            layers: species
                .iter()
                .zip(&parent_veg)
                .zip(&in_dict)
                .filter(|(_, &d)| d)
                .map(|((sp, a), _)| (sp.name.clone(), a.clone()))
                .collect(),
        };
        let field = if in_dict.iter().any(|&d| d) {
            Some(
                amp.amplify(&parent, w, self.level_cell_m(z - 1) as f32)
                    .map_err(synth_err)?,
            )
        } else {
            None
        };
        // The niche on the served terrain moves density inside each parent pixel's 2×2 children
        // (the parent's density is kept where the children can hold it).
        let terrain = self.terrain(z, w)?;
        let wet = self
            .drainage_level_tile(z, tx, ty)?
            .mapv(|a| if a > 0.0 { a.log10() } else { 0.0 });
        let viability = self.landscape.viability;
        let mut out = Vec::with_capacity(species.len());
        for (k, sp) in species.iter().enumerate() {
            let mut d = match field.as_ref().and_then(|f| f.layer(&sp.name)) {
                Some(a) => a.clone(),
                None => amp
                    .upsample_layer(&parent_veg[k], need, w)
                    .map_err(synth_err)?,
            };
            let suit = vegetation::suitability_grid(
                sp,
                &terrain.elevation,
                &terrain.slope,
                &terrain.northness,
                &wet,
            );
            vegetation::redistribute_in_blocks(&mut d, &suit, w.row0, w.col0);
            // Then the viability step fades density on marginal ground.
            ndarray::Zip::from(&mut d)
                .and(&suit)
                .for_each(|v, &s| *v *= vegetation::viability_gate(s, viability));
            out.push(d);
        }
        Ok(out)
    }

    /// Normalised material weights of tile `(z, x, y)` (one grid per material, summing to 1),
    /// and the tile's hillshade (0–1).
    pub fn material_tile(
        &self,
        z: u8,
        x: u32,
        y: u32,
    ) -> Result<(Vec<Array2<f32>>, Array2<f32>), TileError> {
        self.check_tile(z, x, y)?;
        let (tx, ty) = (i64::from(x), i64::from(y));
        let w = Self::tile_window(tx, ty);
        let terrain = self.terrain(z, w)?;
        let wet = self
            .drainage_level_tile(z, tx, ty)?
            .mapv(|a| if a > 0.0 { a.log10() } else { 0.0 });
        let veg = self.vegetation_level_tile(z, tx, ty)?;
        let inputs = LayerInputs {
            elevation: &terrain.elevation,
            slope: &terrain.slope,
            northness: &terrain.northness,
            curvature: &terrain.curvature,
            wetness: &wet,
            vegetation: &veg,
            origin: (w.row0, w.col0),
            pixel_m: pixel_size_m(z),
        };
        Ok((
            landscape::material_weights(&self.landscape, &inputs),
            terrain.shade,
        ))
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
