//! The in-memory dictionary: a multi-resolution, multi-layer set of atoms cut from exemplars.
//!
//! Each atom `i` holds a high-resolution elevation patch (`patch × patch` cells) and the
//! low-resolution patch obtained from it by 2×2 box averaging (`patch/2 × patch/2`), both centred
//! and scaled by the *low-resolution* statistics (mean `a_i`, norm `s_i` of the centred low patch),
//! so that `box_down(hi_i) == lo_i` exactly in real arithmetic and `‖lo_i‖ = 1`. Extra layers
//! (vegetation, log upstream area, northness...) are stored raw at both resolutions.

use serde::{Deserialize, Serialize};

/// How atoms were selected from the exemplar patches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Learning {
    /// Every patch of the exemplars is an atom.
    Complete,
    /// Constrained learning: atoms are real exemplar patches chosen by a seeded k-medoids
    /// alternation with sparsity-1 OMP coding, `iterations` rounds.
    Medoids {
        /// Number of assignment/update rounds.
        iterations: u32,
    },
    /// Unconstrained learning (K-SVD): atoms are learned vectors, initialised from real patches
    /// and refined for `iterations` rounds of sparse coding (the build's sparsity) and rank-1
    /// atom updates; each atom carries the layers and statistics of the patch it started from.
    Ksvd {
        /// Number of coding/update rounds.
        iterations: u32,
    },
}

impl std::str::FromStr for Learning {
    type Err = String;

    /// Parses `complete`, `medoids[:ITERATIONS]` (6 rounds by default) or `ksvd[:ITERATIONS]`
    /// (10 rounds by default).
    fn from_str(s: &str) -> Result<Self, String> {
        let rounds = |n: &str| n.parse::<u32>().map_err(|e| format!("`{s}`: {e}"));
        match s.split_once(':') {
            None if s == "complete" => Ok(Learning::Complete),
            None if s == "medoids" => Ok(Learning::Medoids { iterations: 6 }),
            None if s == "ksvd" => Ok(Learning::Ksvd { iterations: 10 }),
            Some(("medoids", n)) => rounds(n).map(|iterations| Learning::Medoids { iterations }),
            Some(("ksvd", n)) => rounds(n).map(|iterations| Learning::Ksvd { iterations }),
            _ => Err(format!(
                "`{s}`: expected `complete`, `medoids[:ITERATIONS]` or `ksvd[:ITERATIONS]`"
            )),
        }
    }
}

impl std::fmt::Display for Learning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Learning::Complete => write!(f, "complete"),
            Learning::Medoids { iterations } => write!(f, "medoids:{iterations}"),
            Learning::Ksvd { iterations } => write!(f, "ksvd:{iterations}"),
        }
    }
}

/// Parameters a dictionary was built with (stored in the file header).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DictionaryParams {
    /// Side of a high-resolution patch in exemplar cells (even, at least 4).
    pub patch: usize,
    /// Step between patches on the exemplar, in exemplar cells.
    pub stride: usize,
    /// Requested number of atoms (after learning); 0 means keep every patch.
    pub atoms: usize,
    /// Atom selection method.
    pub learning: Learning,
    /// Seed of every random choice made while building.
    pub seed: u64,
    /// Mean metric cell size of the exemplars' high-resolution grid, metres.
    pub cell_m: f64,
    /// Atoms per code the dictionary was learned for (K-SVD); 1 otherwise. Not written when 1,
    /// so dictionaries built before it existed keep their bytes and content ids.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub sparsity: usize,
}

fn one() -> usize {
    1
}

fn is_one(v: &usize) -> bool {
    *v == 1
}

impl DictionaryParams {
    /// Side of a low-resolution patch (`patch / 2`).
    pub fn lo_patch(&self) -> usize {
        self.patch / 2
    }
}

/// How a layer is compared during matching.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum LayerKind {
    /// A continuous quantity (drainage, irradiance, density): compared by `(1 + P·D)/2` on
    /// centred, unit-norm patches.
    Continuous,
    /// One class-probability layer of the class group `group`: compared by the mean over pixels of
    /// the dot product of normalised class-probability vectors of the group.
    Class {
        /// Name of the class group this probability layer belongs to.
        group: String,
    },
}

/// Description of one extra (non-elevation) layer of a dictionary.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LayerInfo {
    /// Layer name (for example `log_area`, `northness`, `spruce`).
    pub name: String,
    /// How the layer is matched.
    pub kind: LayerKind,
}

/// Where an atom was cut from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AtomSource {
    /// Index of the exemplar in the build's exemplar list.
    pub exemplar: u32,
    /// Row of the patch's top-left cell in the exemplar.
    pub row: u32,
    /// Column of the patch's top-left cell in the exemplar.
    pub col: u32,
}

/// A multi-resolution, multi-layer dictionary. All arrays are flat, atom-major, row-major inside a
/// patch; `L = layers.len()`, `lo = patch/2`.
#[derive(Clone, Debug, PartialEq)]
pub struct Dictionary {
    /// Build parameters.
    pub params: DictionaryParams,
    /// Extra layers, in storage order.
    pub layers: Vec<LayerInfo>,
    /// Number of atoms `n`.
    pub n_atoms: usize,
    /// `n × lo²`: centred, unit-norm low-resolution elevation atoms `D_h,i`.
    pub lo_elev: Vec<f32>,
    /// `n × patch²`: high-resolution elevation atoms `D~_h,i`, centred and scaled with the low
    /// statistics so that their 2×2 box average is `lo_elev`.
    pub hi_elev: Vec<f32>,
    /// `n`: mean altitude `D_a,i` of the low patch, metres.
    pub mean_alt: Vec<f32>,
    /// `n`: mean slope of the low patch (gradient magnitude, m/m).
    pub mean_slope: Vec<f32>,
    /// `n`: norm `D_s,i` of the centred low patch, metres.
    pub relief: Vec<f32>,
    /// `n × L × lo²`: raw low-resolution extra layers (box averages of `hi_layers`).
    pub lo_layers: Vec<f32>,
    /// `n × L × patch²`: raw high-resolution extra layers, copied at reconstruction.
    pub hi_layers: Vec<f32>,
    /// `n`: provenance of each atom.
    pub sources: Vec<AtomSource>,
}

impl Dictionary {
    /// Side of a high-resolution patch.
    pub fn patch(&self) -> usize {
        self.params.patch
    }

    /// Side of a low-resolution patch.
    pub fn lo_patch(&self) -> usize {
        self.params.lo_patch()
    }

    /// Low-resolution elevation atom `i` (`lo²` values).
    pub fn lo_atom(&self, i: usize) -> &[f32] {
        let n = self.lo_patch() * self.lo_patch();
        &self.lo_elev[i * n..(i + 1) * n]
    }

    /// High-resolution elevation atom `i` (`patch²` values).
    pub fn hi_atom(&self, i: usize) -> &[f32] {
        let n = self.patch() * self.patch();
        &self.hi_elev[i * n..(i + 1) * n]
    }

    /// Low-resolution extra layer `l` of atom `i` (`lo²` values).
    pub fn lo_layer(&self, i: usize, l: usize) -> &[f32] {
        let n = self.lo_patch() * self.lo_patch();
        let base = (i * self.layers.len() + l) * n;
        &self.lo_layers[base..base + n]
    }

    /// High-resolution extra layer `l` of atom `i` (`patch²` values).
    pub fn hi_layer(&self, i: usize, l: usize) -> &[f32] {
        let n = self.patch() * self.patch();
        let base = (i * self.layers.len() + l) * n;
        &self.hi_layers[base..base + n]
    }

    /// Index of the extra layer called `name`.
    pub fn layer_index(&self, name: &str) -> Option<usize> {
        self.layers.iter().position(|l| l.name == name)
    }

    /// Checks that every array has the length the counts imply and that values are finite.
    pub fn check_consistency(&self) -> Result<(), String> {
        let n = self.n_atoms;
        let p = self.patch();
        let lo = self.lo_patch();
        let l = self.layers.len();
        if p < 4 || p % 2 != 0 {
            return Err(format!("patch size {p} must be even and at least 4"));
        }
        let checks = [
            ("lo_elev", self.lo_elev.len(), n * lo * lo),
            ("hi_elev", self.hi_elev.len(), n * p * p),
            ("mean_alt", self.mean_alt.len(), n),
            ("mean_slope", self.mean_slope.len(), n),
            ("relief", self.relief.len(), n),
            ("lo_layers", self.lo_layers.len(), n * l * lo * lo),
            ("hi_layers", self.hi_layers.len(), n * l * p * p),
            ("sources", self.sources.len(), n),
        ];
        for (name, got, want) in checks {
            if got != want {
                return Err(format!("{name} holds {got} values, expected {want}"));
            }
        }
        if n == 0 {
            return Err("dictionary has no atoms".into());
        }
        let all_finite = [
            &self.lo_elev,
            &self.hi_elev,
            &self.mean_alt,
            &self.mean_slope,
            &self.relief,
            &self.lo_layers,
            &self.hi_layers,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()));
        if !all_finite {
            return Err("dictionary holds non-finite values".into());
        }
        Ok(())
    }
}
