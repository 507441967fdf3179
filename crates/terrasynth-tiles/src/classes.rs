//! A world's land-cover classes (issue #15): its class raster (or RGB image) on the base grid,
//! turned once into one smoothed weight grid per class
//! ([`terrasynth_core::landscape::classes`]), and those weights on a tile: bilinear samples of
//! the weight grids at the tile's pixel centres ([`crate::resample`]), so a pixel's class weight
//! is a function of its global coordinates only (seamless, window-invariant, deterministic).
//! For worlds that weigh the `classes` matching term, also the class probability layers the
//! amplifier's matching reads (`classes_<v>`: 1 where the raster holds value `v` — or, for an RGB
//! image, class code `v`, 1 + the class's index —, 0 elsewhere, unsmoothed), sampled the same
//! way onto each level's parent window, matching the class layers of dictionaries built from
//! exemplars with a `classes` layer.

use std::sync::Arc;

use ndarray::Array2;

use terrasynth_core::landscape::classes::{class_values, class_weight};
use terrasynth_core::landscape::{ClassesConfig, LandscapeError};
use terrasynth_core::raster::reproject::to_geographic;
use terrasynth_core::raster::{nan_where_invalid, Crs, Grid};
use terrasynth_core::synth::Window;

use crate::biomes::BiomeWeights;
use crate::error::TileError;
use crate::resample::mercator_window_from_grid;

/// A world's classes as given: the settings and the raster on the base grid (class values with
/// a legend, or packed RGB with HSV ranges).
#[derive(Clone, Debug)]
pub struct WorldClasses {
    /// Legend or HSV ranges, and the smoothing distance.
    pub config: ClassesConfig,
    /// The raster, on the base's grid (same size and georeference as the base as given).
    pub raster: Grid,
}

/// The class weight grids of a world (on the base's grid, EPSG:4326 or 3857), by class name;
/// in a biome world also the painted biome weights, which [`ClassWeights::window`] gives under
/// `biome.<name>` for the `biome.<name>` terms of materials and species.
#[derive(Clone, Debug, Default)]
pub struct ClassWeights {
    grids: Vec<(String, Grid)>,
    /// A biome world's biome weights.
    biomes: Option<Arc<BiomeWeights>>,
    /// The matching's class probability layers (`classes_<v>`), when asked for.
    indicators: Vec<(String, Grid)>,
}

/// The matching term (and dictionary class group) of class layers.
pub const CLASS_GROUP: &str = "classes";

impl ClassWeights {
    /// The weights of `classes` for base `base` (as given, before any reprojection): checks the
    /// settings and that the raster lies on the base's grid, classifies it, smooths each class's
    /// indicator over `smoothing_m` and reprojects the weights as the base is.
    ///
    /// `indicators`: also the class probability layers of the amplifier's matching.
    pub fn of(
        classes: &WorldClasses,
        base: &Grid,
        indicators: bool,
    ) -> Result<ClassWeights, TileError> {
        let cfg = &classes.config;
        cfg.validate()?;
        let r = &classes.raster;
        if r.data.dim() != base.data.dim() || r.georef != base.georef {
            let (rows, cols) = r.data.dim();
            return Err(LandscapeError::Invalid(format!(
                "classes: the class raster is {cols}×{rows} at {:?}; it must lie on the base's \
                 grid, {}×{} at {:?}",
                r.georef,
                base.cols(),
                base.rows(),
                base.georef
            ))
            .into());
        }
        let mut values = r.data.clone();
        nan_where_invalid(&mut values, r.valid.as_ref());
        let codes = cfg.codes(&values)?;
        let reproject = |g: Grid| -> Result<Grid, TileError> {
            if matches!(g.georef.crs, Crs::Projected(_)) {
                to_geographic(&g).map_err(|e| TileError::Raster(e.to_string()))
            } else {
                Ok(g)
            }
        };
        let mut probabilities = Vec::new();
        if indicators {
            let (keys, source): (Vec<u16>, Array2<f32>) = if cfg.is_rgb() {
                let n = u16::try_from(cfg.names().len()).unwrap_or(u16::MAX);
                ((1..=n).collect(), codes.mapv(f32::from))
            } else {
                (class_values(&values)?, values.clone())
            };
            for v in keys {
                let x = f32::from(v);
                let ind = source.mapv(|s| if s == x { 1.0 } else { 0.0 });
                probabilities.push((
                    format!("{CLASS_GROUP}_{v}"),
                    reproject(Grid::new(ind, base.georef))?,
                ));
            }
        }
        let cell_m = base.georef.cell_sizes(base.rows()).mean_cell();
        let radius = cfg.radius_cells(cell_m)?;
        let mut grids = Vec::new();
        for (k, name) in cfg.names().into_iter().enumerate() {
            let code = u16::try_from(k + 1).unwrap_or(u16::MAX);
            let w = Grid::new(class_weight(&codes, code, radius), base.georef);
            grids.push((name, reproject(w)?));
        }
        Ok(ClassWeights {
            grids,
            biomes: None,
            indicators: probabilities,
        })
    }

    /// These weights with a biome world's biome weights (for `biome.<name>` terms).
    pub fn with_biomes(mut self, biomes: Arc<BiomeWeights>) -> Self {
        self.biomes = Some(biomes);
        self
    }

    /// The class names, in code order.
    pub fn names(&self) -> Vec<String> {
        self.grids.iter().map(|(n, _)| n.clone()).collect()
    }

    /// Whether the world has no classes.
    pub fn is_empty(&self) -> bool {
        self.grids.is_empty()
    }

    /// Bytes held by the weight grids.
    pub fn bytes(&self) -> u64 {
        self.grids
            .iter()
            .chain(&self.indicators)
            .map(|(_, g)| g.data.len() as u64 * 4)
            .sum()
    }

    /// The matching's class probability layers over window `w` of zoom `z` (empty when the
    /// world does not weigh the class term), by layer name.
    pub fn indicator_window(&self, z: u8, w: Window) -> Vec<(String, Array2<f32>)> {
        self.indicators
            .iter()
            .map(|(n, g)| {
                let (v, _) = mercator_window_from_grid(g, z, w.col0, w.row0, w.cols, w.rows, 0.0);
                (n.clone(), v)
            })
            .collect()
    }

    /// The weights over window `w` of zoom `z` (0 outside the classes' raster), by class name;
    /// then, in a biome world, every biome's normalised weight (as the amplifier blends them)
    /// under `biome.<name>`.
    pub fn window(&self, z: u8, w: Window) -> Vec<(String, Array2<f32>)> {
        let mut out: Vec<(String, Array2<f32>)> = self
            .grids
            .iter()
            .map(|(n, g)| {
                let (v, _) = mercator_window_from_grid(g, z, w.col0, w.row0, w.cols, w.rows, 0.0);
                (n.clone(), v)
            })
            .collect();
        if let Some(b) = &self.biomes {
            out.extend(b.named_window(z, w));
        }
        out
    }

    /// A hash input of the weights (for the world's fingerprint).
    pub fn fingerprint_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for (n, g) in self.grids.iter().chain(&self.indicators) {
            out.extend_from_slice(format!("{n}|{:?}|", g.georef).as_bytes());
            for v in g.data.iter() {
                out.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
        out
    }
}
