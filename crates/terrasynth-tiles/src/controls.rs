//! Painted control layers of species (issue #15): a raster on the base's grid that replaces or
//! scales a species' density (e.g. a vegetation density the user drew).
//!
//! A control acts on the whole-world vegetation of the native zoom ([`crate::base_layers`]),
//! after the niche model and the seeding simulation: `replace` sets the species' density to the
//! control's value, `scale` multiplies it by the control's value, both sampled bilinearly at
//! the native zoom's pixel centres ([`crate::resample`]; pixels outside the raster take 0 for
//! `replace` and 1 for `scale`). Deeper zooms refine the controlled density as they refine any
//! density (their 2×2 averages follow their parents', then the niche redistributes and fades
//! it), and overviews average it; so one control steers every zoom, deterministically and
//! seamlessly (a function of position only).
//!
//! **Checks** ([`SpeciesControls::of`]): the species exists, at most one control per species,
//! the raster lies on the base's grid, values are finite and ≥ 0 at every cell (≤ 1 for
//! `replace`: a density).

use ndarray::{Array2, Zip};
use serde::{Deserialize, Serialize};

use terrasynth_core::landscape::LandscapeConfig;
use terrasynth_core::raster::reproject::to_geographic;
use terrasynth_core::raster::{nan_where_invalid, Crs, Grid};
use terrasynth_core::synth::Window;

use crate::error::TileError;
use crate::resample::mercator_window_from_grid;

/// What a control does to its species' density.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ControlMode {
    /// The density is the control's value (0–1).
    Replace,
    /// The density is multiplied by the control's value (≥ 0, clamped to 1 after).
    Scale,
}

/// One painted control of a world as given.
#[derive(Clone, Debug)]
pub struct SpeciesControl {
    /// The species it steers.
    pub species: String,
    /// Replace or scale.
    pub mode: ControlMode,
    /// The painted values, on the base's grid (as given, before any reprojection).
    pub raster: Grid,
}

/// A world's controls, checked and reprojected like the base.
#[derive(Clone, Debug, Default)]
pub struct SpeciesControls {
    /// (species index, mode, grid).
    controls: Vec<(usize, ControlMode, Grid)>,
}

impl SpeciesControls {
    /// The controls `controls` of a world with landscape `landscape` and base `base` (as given):
    /// checks them (see the module documentation).
    pub fn of(
        controls: &[SpeciesControl],
        landscape: &LandscapeConfig,
        base: &Grid,
    ) -> Result<SpeciesControls, TileError> {
        let bad = |m: String| TileError::Controls(m);
        let mut out: Vec<(usize, ControlMode, Grid)> = Vec::new();
        for (i, c) in controls.iter().enumerate() {
            let Some(k) = landscape.species.iter().position(|s| s.name == c.species) else {
                return Err(bad(format!(
                    "controls[{i}]: unknown species `{}`",
                    c.species
                )));
            };
            if out.iter().any(|(j, _, _)| *j == k) {
                return Err(bad(format!(
                    "controls[{i}]: species `{}` has a control already",
                    c.species
                )));
            }
            let r = &c.raster;
            if r.data.dim() != base.data.dim() || r.georef != base.georef {
                return Err(bad(format!(
                    "controls[{i}] (`{}`): the raster is {}×{} at {:?}; it must lie on the base's \
                     grid, {}×{} at {:?}",
                    c.species,
                    r.cols(),
                    r.rows(),
                    r.georef,
                    base.cols(),
                    base.rows(),
                    base.georef
                )));
            }
            let mut values = r.data.clone();
            nan_where_invalid(&mut values, r.valid.as_ref());
            let max = if c.mode == ControlMode::Replace {
                1.0
            } else {
                f32::MAX
            };
            if let Some(((row, col), v)) = values
                .indexed_iter()
                .find(|(_, v)| !v.is_finite() || **v < 0.0 || **v > max)
            {
                let range = if c.mode == ControlMode::Replace {
                    "within 0–1 (a density)"
                } else {
                    "finite and ≥ 0"
                };
                return Err(bad(format!(
                    "controls[{i}] (`{}`): value {v} at row {row}, column {col}; values must be \
                     {range}",
                    c.species
                )));
            }
            let g = Grid::new(values, base.georef);
            let g = if matches!(g.georef.crs, Crs::Projected(_)) {
                to_geographic(&g).map_err(|e| TileError::Raster(e.to_string()))?
            } else {
                g
            };
            out.push((k, c.mode, g));
        }
        Ok(SpeciesControls { controls: out })
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.controls.is_empty()
    }

    /// Bytes held by the grids.
    pub fn bytes(&self) -> u64 {
        self.controls
            .iter()
            .map(|(_, _, g)| g.data.len() as u64 * 4)
            .sum()
    }

    /// Applies the controls to `densities` (one grid per species) over window `w` of zoom `z`.
    pub fn apply(&self, z: u8, w: Window, densities: &mut [Array2<f32>]) {
        for (k, mode, g) in &self.controls {
            let Some(d) = densities.get_mut(*k) else {
                continue;
            };
            let fill = match mode {
                ControlMode::Replace => 0.0,
                ControlMode::Scale => 1.0,
            };
            let (v, _) = mercator_window_from_grid(g, z, w.col0, w.row0, w.cols, w.rows, fill);
            Zip::from(d).and(&v).for_each(|d, &c| {
                *d = match mode {
                    ControlMode::Replace => c,
                    ControlMode::Scale => (*d * c).min(1.0),
                };
            });
        }
    }

    /// A hash input of the controls (for the world's fingerprint).
    pub fn fingerprint_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for (k, mode, g) in &self.controls {
            out.extend_from_slice(format!("{k}|{mode:?}|{:?}|", g.georef).as_bytes());
            for v in g.data.iter() {
                out.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
        out
    }
}
