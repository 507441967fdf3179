//! The vegetation pyramid: one density grid (0–1) per species at every zoom.
//!
//! - **Native zoom `z_b`**: cut from the whole-world niche model and seeding simulation
//!   ([`crate::base_layers`]).
//! - **Amplified zooms**: synthesized by the amplifier from the *same matched atoms* as the
//!   elevation (the parent elevation window decides the matches; the species layers of the atoms
//!   are blended and corrected so their 2×2 averages reproduce the parent densities; a species the
//!   dictionary lacks is carried by the smooth up-sampling of its parent). Then the niche model on
//!   the served terrain moves the density of each parent pixel among its 2×2 children in
//!   proportion to their suitability (the parent's density is kept), and the viability step fades
//!   it on marginal ground and zeroes it where the niche excludes it. In a biome world each
//!   biome painted over the tile amplifies the densities with its own matches and they are
//!   blended by the painted weights before the niche ([`crate::biomes`]).
//! - **Coverage and water**: density is 0 outside the base's coverage ([`crate::coverage`]) and
//!   under water ([`crate::water`]).
//! - **Overviews** (`z < z_b`): the 2×2 box average of the children (densities average).

use std::sync::Arc;

use ndarray::Array2;

use terrasynth_core::landscape::{vegetation, LandscapeConfig};

use crate::classes::ClassWeights;
use terrasynth_core::math;
use terrasynth_core::raster::box2;
use terrasynth_core::synth::{AnyAmplifier, Field, LayerAtoms, Level, SynthError, Window};

use crate::base_layers::{cut, WholeWorld};
use crate::biomes::{blend, Biomes};
use crate::cancel::join;
use crate::chain::Chain;
use crate::coverage::mask_in_place;
use crate::drainage::DrainageLevels;
use crate::elevation::ElevationLevels;
use crate::error::TileError;
use crate::pyramid::{assemble_concurrently, overview, tile_window, LevelCache};
use crate::terrain::Terrain;
use crate::water::{zero_under_water, WaterLevels, DEPTH};

/// The pyramids vegetation is computed from.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<'a> {
    /// Elevation levels (the matches and the niche's terrain).
    pub elevation: &'a ElevationLevels,
    /// Drainage levels (the niche's wetness).
    pub drainage: &'a DrainageLevels,
    /// Whole-world layers (the native zoom).
    pub whole: &'a WholeWorld,
    /// Water levels (vegetation is 0 under water).
    pub water: &'a WaterLevels,
}

/// The vegetation levels of a world.
#[derive(Debug)]
pub struct VegetationLevels {
    landscape: Arc<LandscapeConfig>,
    /// Land-cover class weights for the species' `class.<name>` terms.
    classes: Arc<ClassWeights>,
    /// The amplifiers (one per zoom band) reconstructing the species layers from the same
    /// matches as elevation.
    amplifiers: Chain<AnyAmplifier>,
    /// A biome world's biomes (amplifiers reconstructing the species layers), blended as the
    /// elevation's are; `None`: the chain amplifies alone.
    biomes: Option<Biomes<AnyAmplifier>>,
    /// Whether the elevation tile's matches are the vegetation's: the matching reads no species
    /// layer (the elevation's parent field carries none), so the atoms the elevation tile kept
    /// ([`ElevationLevels::layer_atoms`]) are the ones the species layers would match.
    elevation_atoms: bool,
    cache: LevelCache<Vec<Array2<f32>>>,
}

impl VegetationLevels {
    /// Vegetation of `landscape`'s species, amplified with the zoom's band of `amplifiers` (which
    /// reconstruct only the species layers) or, in a biome world, `biomes`, cached in at most
    /// `cache_bytes` bytes. `matched_layers`: the extra layers the world's matching weighs (with
    /// none of the species among them, a tile's species layers take the elevation tile's atoms).
    pub fn new(
        landscape: Arc<LandscapeConfig>,
        classes: Arc<ClassWeights>,
        amplifiers: Chain<AnyAmplifier>,
        biomes: Option<Biomes<AnyAmplifier>>,
        cache_bytes: u64,
        matched_layers: &[String],
    ) -> Self {
        let elevation_atoms = !landscape
            .species
            .iter()
            .any(|sp| matched_layers.contains(&sp.name));
        VegetationLevels {
            landscape,
            classes,
            amplifiers,
            biomes,
            elevation_atoms,
            cache: LevelCache::new("vegetation", cache_bytes),
        }
    }

    /// The cache of level tiles.
    pub fn cache(&self) -> &LevelCache<Vec<Array2<f32>>> {
        &self.cache
    }

    /// The vegetation level tile `(z, tx, ty)`, computed once.
    pub fn tile(
        &self,
        inputs: Inputs<'_>,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Arc<Vec<Array2<f32>>>, TileError> {
        self.cache
            .get_or_compute((z, tx, ty), || self.compute(inputs, z, tx, ty))
    }

    /// Vegetation over window `w` of zoom `z`, one grid per species.
    pub fn window(
        &self,
        inputs: Inputs<'_>,
        z: u8,
        w: Window,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        assemble_concurrently(
            w,
            self.landscape.species.len(),
            |tx, ty| self.cache.is_known(&(z, tx, ty)),
            |tx, ty| self.tile(inputs, z, tx, ty),
        )
    }

    fn compute(
        &self,
        inputs: Inputs<'_>,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        let w = tile_window(tx, ty);
        let extent = inputs.elevation.extent();
        let zb = extent.z_base;
        let species = &self.landscape.species;
        if z == zb {
            let base = inputs.whole.get(inputs.elevation)?;
            let coverage = inputs.elevation.coverage_tile(z, tx, ty)?;
            let depth = &inputs.water.tile(inputs.elevation, z, tx, ty)?[DEPTH];
            return Ok(base
                .vegetation
                .iter()
                .map(|a| {
                    let mut d = cut(a, base.window, w, 0.0);
                    mask_in_place(&mut d, &coverage);
                    zero_under_water(&mut d, depth);
                    d
                })
                .collect());
        }
        if z < zb {
            return overview(tx, ty, species.len(), 0.0, box2, |cx, cy| {
                if extent.tile_outside(z + 1, cx, cy) {
                    return Ok(None);
                }
                self.tile(inputs, z + 1, cx, cy).map(Some)
            });
        }
        // The amplified densities (down the vegetation chain) and the drainage tile (down its own
        // chain) side by side; what the two chains share is computed once.
        let (amplified, area) = join(
            || self.amplified(inputs, z, tx, ty),
            || {
                inputs
                    .drainage
                    .tile(inputs.elevation, inputs.whole, inputs.water, z, tx, ty)
            },
        );
        let amplified = amplified?;
        // The niche on the served terrain moves density inside each parent pixel's 2×2 children
        // (the parent's density is kept where the children can hold it).
        let terrain = Terrain::of(inputs.elevation, z, w)?;
        let area = area?;
        let wet = wetness(&area);
        let viability = self.landscape.viability;
        let coverage = inputs.elevation.coverage_tile(z, tx, ty)?;
        let depth = &inputs.water.tile(inputs.elevation, z, tx, ty)?[DEPTH];
        let class_weights = if species
            .iter()
            .any(|s| !s.class.is_empty() || !s.biome.is_empty())
        {
            self.classes.window(z, w)
        } else {
            Vec::new()
        };
        let mut out = Vec::with_capacity(species.len());
        for (sp, mut d) in species.iter().zip(amplified) {
            let mut suit = vegetation::suitability_grid(
                sp,
                &terrain.elevation,
                &terrain.slope,
                &terrain.northness,
                &wet,
            );
            if let Some(f) = vegetation::class_factor(sp, &class_weights) {
                suit *= &f;
            }
            vegetation::redistribute_in_blocks(&mut d, &suit, w.row0, w.col0);
            // Then the viability step fades density on marginal ground.
            ndarray::Zip::from(&mut d)
                .and(&suit)
                .for_each(|v, &s| *v *= vegetation::viability_gate(s, viability));
            mask_in_place(&mut d, &coverage);
            zero_under_water(&mut d, depth);
            out.push(d);
        }
        Ok(out)
    }

    /// Every species' density over tile `(z, tx, ty)` of amplified zoom `z` before the niche:
    /// amplified from the parent zoom's densities with the elevation's matches (the atoms the
    /// elevation tile kept, when it can), or, in a biome world, every painted biome's blended.
    fn amplified(
        &self,
        inputs: Inputs<'_>,
        z: u8,
        tx: i64,
        ty: i64,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        let w = tile_window(tx, ty);
        let species = &self.landscape.species;
        let cell = inputs.elevation.extent().level_cell_m(z - 1) as f32;
        // The same parent elevation, hence the same matches, as the elevation tile; the parent
        // window is the one the species layers read (the elevation's breaching reads further).
        Ok(match &self.biomes {
            None => {
                let amp = self.amplifiers.at(z);
                // The elevation tile first: computing it keeps the atoms its matching found.
                let atoms = if self.elevation_atoms {
                    inputs.elevation.tile(z, tx, ty)?;
                    inputs.elevation.layer_atoms(z, tx, ty)
                } else {
                    None
                };
                let need = amp.layers_parent_window_for(w);
                let parent_elev = inputs.elevation.window(z - 1, need)?;
                let parent_veg = self.window(inputs, z - 1, need)?;
                let species = Species {
                    window: need,
                    parent_elev,
                    parent_veg: &parent_veg,
                    atoms: atoms.as_deref(),
                };
                self.amplify_species(amp, z, w, species, cell)?
            }
            Some(biomes) => {
                // Every biome painted over the tile, blended as the elevation is.
                let need = biomes.layers_parent_window_for(w);
                let parent_elev = inputs.elevation.window(z - 1, need)?;
                let parent_veg = self.window(inputs, z - 1, need)?;
                let painted = biomes.weights.window(z, w);
                let mut per_biome = Vec::with_capacity(painted.len());
                for (i, _) in &painted {
                    let species = Species {
                        window: need,
                        parent_elev: parent_elev.clone(),
                        parent_veg: &parent_veg,
                        atoms: None,
                    };
                    per_biome.push(self.amplify_species(
                        &biomes.amplifiers[*i],
                        z,
                        w,
                        species,
                        cell,
                    )?);
                }
                (0..species.len())
                    .map(|k| {
                        let pairs: Vec<_> = painted
                            .iter()
                            .map(|(_, wt)| wt)
                            .zip(per_biome.iter().map(|layers| &layers[k]))
                            .collect();
                        blend(&pairs)
                    })
                    .collect()
            }
        })
    }

    /// Every species' density over window `w` of amplified zoom `z` as amplifier `amp` makes it
    /// from the parent window of `parent` (elevation and densities): the amplified layers of the
    /// species its dictionary carries, the smooth up-sampling of the others (before the niche).
    fn amplify_species(
        &self,
        amp: &AnyAmplifier,
        z: u8,
        w: Window,
        parent: Species<'_>,
        cell: f32,
    ) -> Result<Vec<Array2<f32>>, TileError> {
        let Species {
            window: need,
            parent_elev,
            parent_veg,
            atoms,
        } = parent;
        let species = &self.landscape.species;
        // The gradient amplifier reconstructs every layer it is given (from its coarse gradients).
        let in_dict: Vec<bool> = species
            .iter()
            .map(|sp| match amp {
                AnyAmplifier::Dictionary(a) => a.dictionary().layer_index(&sp.name).is_some(),
                AnyAmplifier::Gradient(_) => true,
            })
            .collect();
        let mut layers: Vec<(String, Array2<f32>)> = species
            .iter()
            .zip(parent_veg)
            .zip(&in_dict)
            .filter(|(_, &d)| d)
            .map(|((sp, a), _)| (sp.name.clone(), a.clone()))
            .collect();
        // The class probabilities the elevation's matching reads: the same matches.
        if let AnyAmplifier::Dictionary(_) = amp {
            layers.extend(self.classes.indicator_window(z - 1, need));
        }
        let parent = Field {
            window: need,
            elevation: parent_elev,
            layers,
        };
        // The species layers alone: the elevation tile has the level's elevation already, so
        // its reconstruction and breaching are not run again (the same layers, bit for bit).
        let amplified = if in_dict.iter().any(|&d| d) {
            match (amp, atoms) {
                (AnyAmplifier::Dictionary(a), Some(atoms)) => {
                    a.amplify_layers_with(&parent, w, atoms)?
                }
                _ => amp.amplify_layers(&parent, w, cell)?,
            }
        } else {
            Vec::new()
        };
        let mut out = Vec::with_capacity(species.len());
        for (k, sp) in species.iter().enumerate() {
            let layer = amplified.iter().find(|(name, _)| name == &sp.name);
            out.push(match layer.map(|(_, a)| a) {
                Some(a) => a.clone(),
                None => match amp {
                    AnyAmplifier::Dictionary(a) => a.upsample_layer(&parent_veg[k], need, w)?,
                    AnyAmplifier::Gradient(_) => {
                        return Err(TileError::Synth(SynthError::BadWindow(format!(
                            "the gradient level returned no `{}` layer",
                            sp.name
                        ))))
                    }
                },
            });
        }
        Ok(out)
    }
}

/// The parent window a tile's species layers are amplified from.
struct Species<'a> {
    /// The parent window.
    window: Window,
    /// Its elevation.
    parent_elev: Array2<f32>,
    /// Its densities, one grid per species.
    parent_veg: &'a [Array2<f32>],
    /// The atoms the elevation tile at the same address matched, when they are the species'.
    atoms: Option<&'a LayerAtoms>,
}

/// Wetness (log10 of the upstream area, 0 where there is none) of a drainage tile.
pub fn wetness(area: &Array2<f32>) -> Array2<f32> {
    area.mapv(|a| if a > 0.0 { math::log10f(a) } else { 0.0 })
}
