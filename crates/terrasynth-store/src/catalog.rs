//! The catalogue: metadata of the store's exemplars and dictionaries kept in memory, so that
//! listings and existence checks never read big files, and the public descriptions of both
//! ([`ExemplarInfo`], [`DictionaryInfo`]).

use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard};

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use terrasynth_core::dictionary::{AmplifierKind, AnyDictionary, Dictionary};

use crate::error::StoreError;
use crate::exemplar::{self, ExemplarHeader};
use crate::store::{ObjectKind, Store, Stored};

/// Locks a mutex, recovering the data of a poisoned one (a panic elsewhere never makes the
/// catalogue unusable).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Elevation statistics of an exemplar.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Statistics {
    /// Lowest elevation, metres.
    pub min: f32,
    /// Highest elevation, metres.
    pub max: f32,
    /// Mean elevation, metres.
    pub mean: f32,
    /// Valid (non-nodata) cells.
    pub valid_cells: u64,
}

/// An exemplar's description.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ExemplarInfo {
    /// Content id.
    pub id: String,
    /// Human name.
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Layer names, `elevation` first.
    pub layers: Vec<String>,
    /// `EPSG:4326` or `EPSG:3857`.
    pub crs: String,
    /// `[west, south, east, north]` in CRS units.
    pub bounds: [f64; 4],
    /// Cell width and height in CRS units.
    pub cell_size: [f64; 2],
    /// Elevation statistics.
    pub statistics: Statistics,
}

/// The description of exemplar `id` with header `h`.
pub fn exemplar_info(id: &str, h: &ExemplarHeader) -> ExemplarInfo {
    let (w, s, e, n) = h.georef.bounds(h.width, h.height);
    ExemplarInfo {
        id: id.to_string(),
        name: h.name.clone(),
        width: h.width,
        height: h.height,
        layers: h.layers.clone(),
        crs: format!("EPSG:{}", h.georef.crs.epsg()),
        bounds: [w, s, e, n],
        cell_size: [h.georef.pixel_width, h.georef.pixel_height],
        statistics: Statistics {
            min: h.stats.min,
            max: h.stats.max,
            mean: h.stats.mean,
            valid_cells: h.stats.valid_cells,
        },
    }
}

/// A dictionary's public metadata.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DictionaryInfo {
    /// Content id.
    pub id: String,
    /// Human name (an alias), if any.
    pub name: Option<String>,
    /// Number of atoms.
    pub atoms: usize,
    /// High-resolution patch side.
    pub patch: usize,
    /// Step between patches.
    pub stride: usize,
    /// `complete` or `medoids:N`.
    pub learning: String,
    /// Seed.
    pub seed: u64,
    /// Mean exemplar cell size, metres.
    pub cell_m: f64,
    /// Extra layers carried by the atoms.
    pub layers: Vec<String>,
    /// `dictionary` (patch atoms, the dictionary amplifier) or `gradient` (a gradient tile set,
    /// the gradient amplifier). For a gradient tile set `atoms` counts its tiles, `patch` is the
    /// tile side, `stride` half of it and `learning` is `gradient`.
    #[schema(value_type = String, example = "dictionary")]
    pub kind: AmplifierKind,
    /// The parameters of a gradient tile set (absent for a dictionary).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gradient: Option<GradientInfo>,
}

/// The paper's parameters of a stored gradient tile set.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct GradientInfo {
    /// Tile side in child pixels.
    pub tile: usize,
    /// Edge colours per layer.
    pub colours: usize,
    /// Alternatives per colour combination.
    pub alternatives: usize,
    /// Exemplar mixing in `[0, 1]`.
    pub mixing: f32,
    /// Colour combinations (per axis) the exemplars offered tiles for, of `colours²`.
    pub combinations_found: usize,
}

/// The description of dictionary or gradient tile set `id` (alias `name`).
pub fn any_dictionary_info(id: &str, name: Option<String>, d: &AnyDictionary) -> DictionaryInfo {
    match d {
        AnyDictionary::Dictionary(d) => dictionary_info(id, name, d),
        AnyDictionary::Gradient(g) => {
            let p = &g.params;
            let combos = p.combinations();
            DictionaryInfo {
                id: id.to_string(),
                name,
                atoms: 2 * combos * p.alternatives,
                patch: p.tile,
                stride: p.tile / 2,
                learning: "gradient".into(),
                seed: p.seed,
                cell_m: 0.0,
                layers: Vec::new(),
                kind: AmplifierKind::Gradient,
                gradient: Some(GradientInfo {
                    tile: p.tile,
                    colours: p.colours,
                    alternatives: p.alternatives,
                    mixing: p.mixing,
                    combinations_found: g.found.iter().take(combos).filter(|&&n| n > 0).count(),
                }),
            }
        }
    }
}

/// The description of dictionary `id` (alias `name`).
pub fn dictionary_info(id: &str, name: Option<String>, d: &Dictionary) -> DictionaryInfo {
    DictionaryInfo {
        id: id.to_string(),
        name,
        atoms: d.n_atoms,
        patch: d.params.patch,
        stride: d.params.stride,
        learning: d.params.learning.to_string(),
        seed: d.params.seed,
        cell_m: d.params.cell_m,
        layers: d.layers.iter().map(|l| l.name.clone()).collect(),
        kind: AmplifierKind::Dictionary,
        gradient: None,
    }
}

/// Metadata of the store's exemplars and dictionaries, kept in memory.
#[derive(Default)]
pub struct Catalog {
    exemplars: Mutex<BTreeMap<String, ExemplarHeader>>,
    dictionaries: Mutex<BTreeMap<String, DictionaryInfo>>,
}

impl Catalog {
    /// Reads the metadata of every exemplar and dictionary of `store`. Exemplars are described
    /// from their headers alone (their first bytes: the pixels of a large store are not read
    /// before the server listens; every read of the pixels verifies them, and the catalogue
    /// service verifies them all in the background); an exemplar whose header is unusable is
    /// quarantined. Dictionaries are read whole (and so verified).
    pub fn load(store: &Store) -> Result<Catalog, StoreError> {
        let catalog = Catalog::default();
        for id in store.object_ids(ObjectKind::Exemplar)? {
            let head = store.object_head(ObjectKind::Exemplar, &id, exemplar::MAX_HEAD);
            match head.and_then(|h| h.map(|p| exemplar::decode_header(&p)).transpose()) {
                Ok(Some(h)) => {
                    lock(&catalog.exemplars).insert(id, h);
                }
                Ok(None) => {}
                Err(e) => store.quarantine(Stored::Exemplar, &id, &e)?,
            }
        }
        let mut names: BTreeMap<String, String> = BTreeMap::new();
        for (alias, id) in store.aliases("")? {
            let name = alias
                .strip_prefix("dictionary.")
                .unwrap_or(&alias)
                .to_string();
            if alias.starts_with("dictionary.") || alias.starts_with("world-") {
                names.entry(id).or_insert(name);
            }
        }
        for id in store.dictionary_ids()? {
            match store.get_any_dictionary(&id) {
                Ok(Some(d)) => {
                    let info = any_dictionary_info(&id, names.get(&id).cloned(), &d);
                    lock(&catalog.dictionaries).insert(id, info);
                }
                Ok(None) => {}
                Err(e) => store.quarantine(Stored::Dictionary, &id, &e)?,
            }
        }
        Ok(catalog)
    }

    /// Stores dictionary or gradient tile set `d` under alias `dictionary.{name}` and records
    /// it; its id.
    pub fn add_dictionary(
        &self,
        store: &Store,
        name: &str,
        d: AnyDictionary,
    ) -> Result<String, StoreError> {
        let id = store.put_any_dictionary(&d)?;
        store.set_alias(&format!("dictionary.{name}"), &id)?;
        lock(&self.dictionaries)
            .insert(id.clone(), any_dictionary_info(&id, Some(name.into()), &d));
        Ok(id)
    }

    /// Records exemplar `id`.
    pub fn add_exemplar(&self, id: &str, header: ExemplarHeader) {
        lock(&self.exemplars).insert(id.to_string(), header);
    }

    /// Every dictionary.
    pub fn dictionaries(&self) -> Vec<DictionaryInfo> {
        lock(&self.dictionaries).values().cloned().collect()
    }

    /// Dictionary `id`.
    pub fn dictionary(&self, id: &str) -> Option<DictionaryInfo> {
        lock(&self.dictionaries).get(id).cloned()
    }

    /// Forgets dictionary `id`.
    pub fn remove_dictionary(&self, id: &str) {
        lock(&self.dictionaries).remove(id);
    }

    /// Every exemplar.
    pub fn exemplars(&self) -> Vec<ExemplarInfo> {
        lock(&self.exemplars)
            .iter()
            .map(|(id, h)| exemplar_info(id, h))
            .collect()
    }

    /// The header of exemplar `id`.
    pub fn exemplar(&self, id: &str) -> Option<ExemplarHeader> {
        lock(&self.exemplars).get(id).cloned()
    }

    /// Whether exemplar `id` is known.
    pub fn has_exemplar(&self, id: &str) -> bool {
        lock(&self.exemplars).contains_key(id)
    }

    /// Forgets exemplar `id`.
    pub fn remove_exemplar(&self, id: &str) {
        lock(&self.exemplars).remove(id);
    }
}
