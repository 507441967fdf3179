//! The catalogue service: the rules of the admin API without HTTP. It owns the store (opened once), the in-memory [`Catalog`] and the build [`Jobs`], and decides what may be
//! stored, built, created and deleted: an exemplar used by a queued or running build or by a
//! stored world cannot be deleted, nor a dictionary a world uses, nor a world of the
//! configuration; names follow the one name rule; nothing is written for a rejected request.
//! Every method does blocking IO (fsync'd writes, deletions): call it off any async runtime.
//!
//! Opening the service reads no exemplar pixels: it verifies the (small) world definitions and
//! dictionaries, describes exemplars from their headers, and verifies the exemplars' checksums on
//! a low-priority background thread, quarantining corrupted ones (and their aliases). Exemplar
//! pixels are verified whenever they are read, and a request that describes or uses an exemplar
//! the background thread has not reached yet verifies it first, so nothing unverified is ever
//! served or used.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use terrasynth_core::dictionary::{AmplifierKind, AnyDictionary};
use terrasynth_core::landscape::{ClassesConfig, LandscapeConfig};
use terrasynth_core::names::is_content_id;
use terrasynth_core::raster::{Grid, LayeredRaster};
use terrasynth_core::synth::sketch::SizeLimits;
use terrasynth_core::synth::ZoomBand;

use crate::catalog::{exemplar_info, lock, Catalog, DictionaryInfo, ExemplarInfo};
use crate::error::{ServiceError, StoreError};
use crate::exemplar;
use crate::jobs::{
    build_options, gradient_params, DictionaryRequest, Job, JobRequest, JobSettings, Jobs,
    SketchJob,
};
use crate::sketch::SketchRequest;
use crate::store::{ObjectKind, Store, Stored};
use crate::worlds::{
    check_name, WorldBiomeRef, WorldClassesRef, WorldDefaults, WorldDefinition, WorldDictionary,
    WorldRequest,
};

/// Most exemplars one build may read.
pub const MAX_BUILD_EXEMPLARS: usize = 64;

/// Whether a world of this name is served (the caller knows the live worlds).
pub type Served = Arc<dyn Fn(&str) -> bool + Send + Sync>;

/// What starts serving a stored world: called once its definition is stored.
pub type Publish = Box<dyn FnOnce() + Send>;

/// Builds what serves a resolved world (CPU-bound) and returns how to publish it.
pub type Assemble = Box<dyn FnOnce(ResolvedWorld) -> Result<Publish, ServiceError> + Send>;

/// A world definition resolved against the store: everything needed to serve it.
#[derive(Clone, Debug)]
pub struct ResolvedWorld {
    /// The definition.
    pub definition: WorldDefinition,
    /// The base raster's elevation.
    pub base: Grid,
    /// The dictionaries of the chain, in the definition's order.
    pub dictionaries: Vec<ResolvedDictionary>,
    /// The landscape (defaults with the definition's materials and species).
    pub landscape: LandscapeConfig,
    /// The land-cover classes' settings and raster (on the base's grid), when the world has
    /// classes.
    pub classes: Option<(ClassesConfig, Grid)>,
    /// The painted biomes (empty: not a biome world), in the definition's order.
    pub biomes: Vec<ResolvedBiome>,
    /// The painted species controls: (species, mode, layer on its exemplar's grid), in the
    /// definition's order.
    pub controls: Vec<(String, String, Grid)>,
}

/// One painted biome of a resolved world.
#[derive(Clone, Debug)]
pub struct ResolvedBiome {
    /// Its name.
    pub name: String,
    /// Its dictionary (or gradient tile set).
    pub dictionary: AnyDictionary,
    /// The dictionary's content id.
    pub id: String,
    /// The weight layer, on its exemplar's grid (checked against the base's by the world).
    pub weight: Grid,
}

/// One dictionary of a resolved world's chain.
#[derive(Clone, Debug)]
pub struct ResolvedDictionary {
    /// Its zooms (`None`: every amplified zoom).
    pub zooms: Option<ZoomBand>,
    /// The dictionary, or the gradient tile set (of the kind the band's amplifier names).
    pub dictionary: AnyDictionary,
    /// Its content id.
    pub id: String,
}

/// The catalogue service.
pub struct Catalogue {
    store: Store,
    catalog: Arc<Catalog>,
    jobs: Jobs,
    defaults: WorldDefaults,
    /// Names of the configured worlds (read-only, and shadowing stored worlds of the same name).
    configured: BTreeSet<String>,
    /// Serialises the operations that check "in use" and then change the store.
    changes: Arc<Mutex<()>>,
    /// Whether the background verification of the exemplars has finished.
    verified: Arc<AtomicBool>,
    /// Exemplars whose checksum has been verified since start (or that were stored since).
    checked: Arc<Mutex<BTreeSet<String>>>,
}

/// Verifies exemplar `id` unless it was already checked: a corrupted one is quarantined (file
/// and aliases) and forgotten. `true` when the exemplar is usable.
fn check_exemplar(
    store: &Store,
    catalog: &Catalog,
    changes: &Mutex<()>,
    checked: &Mutex<BTreeSet<String>>,
    id: &str,
) -> bool {
    if lock(checked).contains(id) {
        return true;
    }
    match store.verify(Stored::Exemplar, id) {
        Ok(true) => {
            lock(checked).insert(id.to_string());
            true
        }
        Ok(false) => false,
        Err(e) => {
            let _changes = lock(changes);
            if catalog.has_exemplar(id) {
                catalog.remove_exemplar(id);
                if let Err(q) = store.quarantine(Stored::Exemplar, id, &e) {
                    tracing::error!(exemplar = %id, error = %q, "store: cannot quarantine a corrupted exemplar");
                }
            }
            false
        }
    }
}

impl Catalogue {
    /// The service over an opened `store`: loads the catalogue and the job records (marking
    /// interrupted jobs failed) and starts the build workers.
    pub fn open(
        store: Store,
        jobs: JobSettings,
        defaults: WorldDefaults,
        configured: BTreeSet<String>,
    ) -> Result<Catalogue, ServiceError> {
        for id in store.ids(Stored::World)? {
            if let Err(e) = store.verify(Stored::World, &id) {
                store.quarantine(Stored::World, &id, &e)?;
            }
        }
        let catalog = Arc::new(Catalog::load(&store)?);
        let jobs = Jobs::start(
            store.clone(),
            catalog.clone(),
            Arc::new(defaults.landscape.clone()),
            jobs,
        )?;
        let catalogue = Catalogue {
            store,
            catalog,
            jobs,
            defaults,
            configured,
            changes: Arc::new(Mutex::new(())),
            verified: Arc::new(AtomicBool::new(false)),
            checked: Arc::new(Mutex::new(BTreeSet::new())),
        };
        catalogue.verify_in_background()?;
        Ok(catalogue)
    }

    /// Starts the low-priority thread that verifies every exemplar's checksum, quarantining
    /// corrupted ones (file and aliases) and forgetting them.
    fn verify_in_background(&self) -> Result<(), ServiceError> {
        let ids: Vec<String> = self.catalog.exemplars().into_iter().map(|e| e.id).collect();
        let (store, catalog) = (self.store.clone(), self.catalog.clone());
        let (changes, verified) = (self.changes.clone(), self.verified.clone());
        let checked = self.checked.clone();
        std::thread::Builder::new()
            .name("store-verify".into())
            .spawn(move || {
                crate::jobs::lower_priority();
                let start = Instant::now();
                let mut bad = 0usize;
                for id in &ids {
                    if !check_exemplar(&store, &catalog, &changes, &checked, id) {
                        bad += 1;
                    }
                }
                verified.store(true, Ordering::Release);
                tracing::info!(
                    exemplars = ids.len(),
                    quarantined = bad,
                    seconds = start.elapsed().as_secs_f64(),
                    "store: exemplars verified"
                );
            })
            .map_err(|e| ServiceError::Internal(format!("verification thread: {e}")))?;
        Ok(())
    }

    /// Whether the background verification of the exemplars (started by
    /// [`Catalogue::open`]) has finished.
    pub fn verification_finished(&self) -> bool {
        self.verified.load(Ordering::Acquire)
    }

    /// The store.
    pub fn store(&self) -> &Store {
        &self.store
    }

    /// What created worlds inherit.
    pub fn defaults(&self) -> &WorldDefaults {
        &self.defaults
    }

    /// Stores an uploaded (decoded, checked) exemplar under alias `exemplar.{name}`.
    pub fn put_exemplar(
        &self,
        name: &str,
        raster: &LayeredRaster,
    ) -> Result<ExemplarInfo, ServiceError> {
        check_name("exemplar name", name)?;
        // Streamed to the store: the payload is never assembled in memory.
        let encoder = exemplar::Encoder::new(name, raster)?;
        let id = self
            .store
            .put_object_streamed(ObjectKind::Exemplar, encoder.len(), |w| encoder.write(w))?;
        let header = encoder.header;
        self.store.set_alias(&format!("exemplar.{name}"), &id)?;
        lock(&self.checked).insert(id.clone());
        let info = exemplar_info(&id, &header);
        self.catalog.add_exemplar(&id, header);
        tracing::info!(exemplar = %id, name = %name, "exemplar stored");
        Ok(info)
    }

    /// Verifies exemplar `id` now if the background verification has not reached it yet (an
    /// unverified exemplar is never described or used); `false` when it is absent or corrupted.
    fn ensure_checked(&self, id: &str) -> bool {
        if self.catalog.has_exemplar(id)
            && check_exemplar(&self.store, &self.catalog, &self.changes, &self.checked, id)
        {
            return true;
        }
        // Not usable: if another thread is quarantining it (holding `changes`), wait until its
        // file and aliases are gone too, so that nobody sees an alias of an exemplar that is
        // not described any more.
        drop(lock(&self.changes));
        false
    }

    /// Every exemplar (each verified first, if the background verification has not yet).
    pub fn exemplars(&self) -> Vec<ExemplarInfo> {
        for e in self.catalog.exemplars() {
            self.ensure_checked(&e.id);
        }
        self.catalog.exemplars()
    }

    /// Exemplar `id` (verified first, if the background verification has not yet).
    pub fn exemplar(&self, id: &str) -> Result<ExemplarInfo, ServiceError> {
        self.ensure_checked(id);
        self.catalog
            .exemplar(id)
            .map(|h| exemplar_info(id, &h))
            .ok_or_else(|| ServiceError::NotFound(format!("no exemplar `{id}`")))
    }

    /// Deletes exemplar `id`, unless a queued or running build or a stored world uses it.
    pub fn delete_exemplar(&self, id: &str) -> Result<(), ServiceError> {
        let _changes = lock(&self.changes);
        let header = self
            .catalog
            .exemplar(id)
            .ok_or_else(|| ServiceError::NotFound(format!("no exemplar `{id}`")))?;
        if self.jobs.uses_exemplar(id) {
            return Err(ServiceError::Conflict(format!(
                "exemplar `{id}` is used by a dictionary build"
            )));
        }
        if let Some((_, def)) = self
            .stored_worlds()?
            .into_iter()
            .find(|(_, d)| d.base == id)
        {
            return Err(ServiceError::Conflict(format!(
                "exemplar `{id}` is the base of world `{}`",
                def.name
            )));
        }
        if let Some((_, def)) = self.stored_worlds()?.into_iter().find(|(_, d)| {
            d.classes
                .as_ref()
                .and_then(|c| c.exemplar.as_deref())
                .is_some_and(|e| e == id)
        }) {
            return Err(ServiceError::Conflict(format!(
                "exemplar `{id}` holds the classes of world `{}`",
                def.name
            )));
        }
        if let Some((_, def)) = self.stored_worlds()?.into_iter().find(|(_, d)| {
            d.biomes
                .iter()
                .any(|b| b.exemplar.as_deref().is_some_and(|e| e == id))
                || d.controls
                    .iter()
                    .any(|c| c.exemplar.as_deref().is_some_and(|e| e == id))
        }) {
            return Err(ServiceError::Conflict(format!(
                "exemplar `{id}` holds biome weights or controls of world `{}`",
                def.name
            )));
        }
        self.catalog.remove_exemplar(id);
        let alias = format!("exemplar.{}", header.name);
        if self.store.alias(&alias)?.as_deref() == Some(id) {
            self.store.remove_alias(&alias)?;
        }
        self.store.delete_object(ObjectKind::Exemplar, id)?;
        Ok(())
    }

    /// Queues a dictionary build after checking its request.
    pub fn submit_build(&self, request: DictionaryRequest) -> Result<Job, ServiceError> {
        check_name("dictionary name", &request.name)?;
        if request.exemplars.is_empty() || request.exemplars.len() > MAX_BUILD_EXEMPLARS {
            return Err(ServiceError::Invalid(format!(
                "give 1–{MAX_BUILD_EXEMPLARS} exemplar ids"
            )));
        }
        if let Some(e) = request.exemplars.iter().find(|e| !self.ensure_checked(e)) {
            return Err(ServiceError::Invalid(format!("unknown exemplar `{e}`")));
        }
        if request.build_kind()? == AmplifierKind::Gradient {
            gradient_params(&request)?;
            let job = self.jobs.submit(request)?;
            tracing::info!(job = %job.id, "gradient tile set job queued");
            return Ok(job);
        }
        build_options(&request)?;
        if let Some(weights) = &request.weights {
            let known = self.weight_names(&request);
            if let Some(bad) = weights.keys().find(|k| !known.contains(*k)) {
                return Err(ServiceError::Invalid(format!(
                    "unknown weight `{bad}`: a weight names `elevation`, `altitude`, `slope` or a \
                     layer the dictionary will carry ({})",
                    known.iter().cloned().collect::<Vec<_>>().join(", ")
                )));
            }
        }
        let job = self.jobs.submit(request)?;
        tracing::info!(job = %job.id, "dictionary job queued");
        Ok(job)
    }

    /// The names a build request's weights may use: the terms `elevation`, `altitude` and
    /// `slope`, and the layers the dictionary will carry — the derived `log_area` and
    /// `northness`, the species (the request's or the defaults'), and the exemplars' own layers.
    fn weight_names(&self, request: &DictionaryRequest) -> BTreeSet<String> {
        use terrasynth_core::dictionary::derive::{LOG_AREA, NORTHNESS};
        let mut known: BTreeSet<String> = ["elevation", "altitude", "slope", LOG_AREA, NORTHNESS]
            .into_iter()
            .map(String::from)
            .collect();
        let species = request
            .species
            .as_deref()
            .unwrap_or(&self.defaults.landscape.species);
        known.extend(species.iter().map(|s| s.name.clone()));
        for e in &request.exemplars {
            if let Some(h) = self.catalog.exemplar(e) {
                known.extend(h.layers.iter().skip(1).cloned());
            }
        }
        known
    }

    /// Every job, oldest first.
    pub fn jobs(&self) -> Vec<Job> {
        self.jobs.list()
    }

    /// Job `id`.
    pub fn job(&self, id: &str) -> Result<Job, ServiceError> {
        self.jobs
            .get(id)
            .ok_or_else(|| ServiceError::NotFound(format!("no job `{id}`")))
    }

    /// Cancels a queued or running job.
    pub fn cancel_job(&self, id: &str) -> Result<Job, ServiceError> {
        self.jobs.cancel(id)
    }

    /// Every dictionary.
    pub fn dictionaries(&self) -> Vec<DictionaryInfo> {
        self.catalog.dictionaries()
    }

    /// Dictionary `id`.
    pub fn dictionary(&self, id: &str) -> Result<DictionaryInfo, ServiceError> {
        self.catalog
            .dictionary(id)
            .ok_or_else(|| ServiceError::NotFound(format!("no dictionary `{id}`")))
    }

    /// Deletes dictionary `id` and its aliases, unless a world uses it: `served_by` names a
    /// served world using it (the caller knows the live worlds), stored worlds are checked here.
    pub fn delete_dictionary(
        &self,
        id: &str,
        served_by: impl Fn(&str) -> Option<String>,
    ) -> Result<(), ServiceError> {
        let _changes = lock(&self.changes);
        self.dictionary(id)?;
        let user = match served_by(id) {
            Some(w) => Some(w),
            None => self
                .stored_worlds()?
                .into_iter()
                .find(|(_, d)| {
                    d.dictionaries.iter().any(|x| x.id() == id)
                        || d.biomes.iter().any(|b| b.dictionary == id)
                })
                .map(|(_, d)| d.name),
        };
        if let Some(w) = user {
            return Err(ServiceError::Conflict(format!(
                "dictionary `{id}` is used by world `{w}`"
            )));
        }
        self.catalog.remove_dictionary(id);
        for (alias, target) in self.store.aliases("")? {
            if target == id {
                self.store.remove_alias(&alias)?;
            }
        }
        self.store.delete_dictionary(id)?;
        Ok(())
    }

    /// The stored (API-created) world definitions with their ids, in alias order; unreadable
    /// ones are left out.
    pub fn stored_worlds(&self) -> Result<Vec<(String, WorldDefinition)>, ServiceError> {
        let mut out = Vec::new();
        for (_, id) in self.store.aliases("world.")? {
            if let Some(p) = self.store.get_object(ObjectKind::World, &id)? {
                if let Ok(def) = serde_json::from_slice::<WorldDefinition>(&p) {
                    out.push((id, def));
                }
            }
        }
        Ok(out)
    }

    /// The stored definition of world `name` and its id, if the store holds one that no
    /// configured world shadows: how a replica sharing the store picks up a world another
    /// process created (one alias read and, when present, one object read; IO-bound).
    pub fn stored_world(
        &self,
        name: &str,
    ) -> Result<Option<(String, WorldDefinition)>, ServiceError> {
        if self.configured.contains(name) || !terrasynth_core::names::is_valid_name(name) {
            return Ok(None);
        }
        let Some(id) = self.store.alias(&format!("world.{name}"))? else {
            return Ok(None);
        };
        let Some(payload) = self.store.get_object(ObjectKind::World, &id)? else {
            return Ok(None);
        };
        let def = serde_json::from_slice::<WorldDefinition>(&payload)
            .map_err(|e| ServiceError::Internal(format!("stored world `{name}`: {e}")))?;
        Ok(Some((id, def)))
    }

    /// The stored world definitions to serve at start: those a configured world does not shadow
    /// (shadowed and unreadable ones are logged and skipped).
    pub fn worlds_to_load(&self) -> Result<Vec<(String, WorldDefinition)>, ServiceError> {
        let mut out = Vec::new();
        for (alias, id) in self.store.aliases("world.")? {
            let name = alias.trim_start_matches("world.");
            if self.configured.contains(name) {
                tracing::warn!(world = %name, "stored world shadowed by a configured world; skipped");
                continue;
            }
            match self.store.get_object(ObjectKind::World, &id) {
                Ok(Some(p)) => match serde_json::from_slice::<WorldDefinition>(&p) {
                    Ok(def) => out.push((id, def)),
                    Err(e) => {
                        tracing::warn!(world = %name, error = %e, "stored world unreadable; skipped")
                    }
                },
                Ok(None) => {
                    tracing::warn!(world = %name, "stored world definition missing; skipped")
                }
                Err(e) => {
                    tracing::warn!(world = %name, error = %e, "stored world unusable; skipped")
                }
            }
        }
        Ok(out)
    }

    /// Reads what definition `def` names from the store (CPU- and IO-bound).
    pub fn resolve(&self, def: &WorldDefinition) -> Result<ResolvedWorld, ServiceError> {
        let landscape = def.landscape(&self.defaults.landscape)?;
        let unknown_base =
            || ServiceError::Invalid(format!("unknown base exemplar `{}`", def.base));
        if !is_content_id(&def.base) {
            return Err(unknown_base());
        }
        let bands = def.dictionary_bands()?;
        let payload = match self.store.get_object(ObjectKind::Exemplar, &def.base) {
            Ok(p) => p.ok_or_else(unknown_base)?,
            Err(StoreError::BadName(_)) => return Err(unknown_base()),
            Err(e) => return Err(e.into()),
        };
        let (_, raster) = exemplar::decode(&payload)?;
        let base = raster
            .elevation()
            .ok_or_else(|| ServiceError::Invalid("the base has no elevation".into()))?;
        let classes = match &def.classes {
            None => None,
            Some(c) => Some((c.config(), self.class_raster(c, &def.base, &raster)?)),
        };
        let mut dictionaries = Vec::with_capacity(bands.len());
        for (i, ((zooms, id), entry)) in bands.into_iter().zip(&def.dictionaries).enumerate() {
            let dictionary = self
                .store
                .get_any_dictionary(id)?
                .ok_or_else(|| ServiceError::Invalid(format!("unknown dictionary `{id}`")))?
                .expect(entry.amplifier(), &format!("dictionaries[{i}] `{id}`"))
                .map_err(ServiceError::Invalid)?;
            dictionaries.push(ResolvedDictionary {
                zooms,
                dictionary,
                id: id.to_string(),
            });
        }
        let mut biomes = Vec::with_capacity(def.biomes.len());
        for (i, b) in def.biomes.iter().enumerate() {
            let id = &b.dictionary;
            let dictionary = self
                .store
                .get_any_dictionary(id)?
                .ok_or_else(|| {
                    ServiceError::Invalid(format!("biomes[{i}]: unknown dictionary `{id}`"))
                })?
                .expect(b.amplifier, &format!("biomes[{i}] `{id}`"))
                .map_err(ServiceError::Invalid)?;
            biomes.push(ResolvedBiome {
                name: b.name().to_string(),
                dictionary,
                id: id.clone(),
                weight: self.biome_weight(i, b, &def.base, &raster)?,
            });
        }
        let mut controls = Vec::with_capacity(def.controls.len());
        for (i, c) in def.controls.iter().enumerate() {
            let raster = self.exemplar_layer(
                &format!("controls[{i}]"),
                c.exemplar.as_deref(),
                &c.layer,
                &def.base,
                &raster,
            )?;
            controls.push((c.species.clone(), c.mode.clone(), raster));
        }
        Ok(ResolvedWorld {
            definition: def.clone(),
            base,
            dictionaries,
            landscape,
            classes,
            biomes,
            controls,
        })
    }

    /// The weight layer of biome `i` (`b.weight` of `b.exemplar`, default the base).
    fn biome_weight(
        &self,
        i: usize,
        b: &WorldBiomeRef,
        base: &str,
        base_raster: &LayeredRaster,
    ) -> Result<Grid, ServiceError> {
        let what = format!("biomes[{i}]");
        let weight =
            self.exemplar_layer(&what, b.exemplar.as_deref(), &b.weight, base, base_raster);
        // The layer is named by `weight` in a biome.
        weight.map_err(|e| match e {
            ServiceError::Invalid(m) => ServiceError::Invalid(
                m.replace(&format!("{what}.layer"), &format!("{what}.weight")),
            ),
            e => e,
        })
    }

    /// Layer `layer` of exemplar `exemplar` (default: the base, `base` decoded as
    /// `base_raster`), which must lie on the base's grid; `what` names the request's entry in
    /// errors. Cells hold the layer's values (NaN where the upload had none: refused by the
    /// world's checks).
    fn exemplar_layer(
        &self,
        what: &str,
        exemplar: Option<&str>,
        layer: &str,
        base: &str,
        base_raster: &LayeredRaster,
    ) -> Result<Grid, ServiceError> {
        let id = exemplar.unwrap_or(base);
        let other;
        let raster = if id == base {
            base_raster
        } else {
            other = self.exemplar_on_base_grid(what, id, base_raster)?;
            &other
        };
        let data = raster.layer(layer).cloned().ok_or_else(|| {
            ServiceError::Invalid(format!(
                "{what}.layer: exemplar `{id}` has no layer `{layer}` (upload it as a `{layer}` \
                 part)"
            ))
        })?;
        Ok(Grid::new(data, raster.georef))
    }

    /// Exemplar `id`, decoded, which must lie on the base's grid (`base_raster`'s size and
    /// georeference); errors name `what` (`classes`, `biomes[0]`, ...).
    fn exemplar_on_base_grid(
        &self,
        what: &str,
        id: &str,
        base_raster: &LayeredRaster,
    ) -> Result<LayeredRaster, ServiceError> {
        let unknown = || ServiceError::Invalid(format!("{what}.exemplar: unknown exemplar `{id}`"));
        let payload = match self.store.get_object(ObjectKind::Exemplar, id) {
            Ok(p) => p.ok_or_else(unknown)?,
            Err(StoreError::BadName(_)) => return Err(unknown()),
            Err(e) => return Err(e.into()),
        };
        let other = exemplar::decode(&payload)?.1;
        if other.dim() != base_raster.dim() || other.georef != base_raster.georef {
            let ((r, c), (br, bc)) = (other.dim(), base_raster.dim());
            return Err(ServiceError::Invalid(format!(
                "{what}.exemplar `{id}` is {c}×{r} at {:?}: the raster must lie on the base's \
                 grid, {bc}×{br} at {:?}",
                other.georef, base_raster.georef
            )));
        }
        Ok(other)
    }

    /// The raster of a world's classes: layer [`WorldClassesRef::layer`] of exemplar
    /// `c.exemplar` (default: the base, `base` decoded as `base_raster`), which must lie on the
    /// base's grid; invalid cells are NaN (no class).
    fn class_raster(
        &self,
        c: &WorldClassesRef,
        base: &str,
        base_raster: &LayeredRaster,
    ) -> Result<Grid, ServiceError> {
        let id = c.exemplar.as_deref().unwrap_or(base);
        let other;
        let raster = if id == base {
            base_raster
        } else {
            other = self.exemplar_on_base_grid("classes", id, base_raster)?;
            &other
        };
        let layer = c.layer();
        let mut data = raster.layer(layer).cloned().ok_or_else(|| {
            ServiceError::Invalid(format!(
                "classes: exemplar `{id}` has no `{layer}` layer (upload it as a `{layer}` part)"
            ))
        })?;
        terrasynth_core::raster::nan_where_invalid(&mut data, raster.valid.as_ref());
        Ok(Grid::new(data, raster.georef))
    }

    /// Creates world `def`: checks that its name is free (not configured, not `served`, not
    /// stored), resolves it, lets `assemble` build what serves it, and stores the definition
    /// under alias `world.{name}` — all under one lock, so two requests cannot take one name.
    /// Returns what `assemble` built and the definition's id; nothing is stored on error.
    pub fn create_world<W>(
        &self,
        def: &WorldDefinition,
        served: impl Fn(&str) -> bool,
        assemble: impl FnOnce(ResolvedWorld) -> Result<W, ServiceError>,
    ) -> Result<(W, String), ServiceError> {
        let _changes = lock(&self.changes);
        let alias = format!("world.{}", def.name);
        if self.configured.contains(&def.name)
            || served(&def.name)
            || self.store.alias(&alias)?.is_some()
        {
            return Err(ServiceError::Conflict(format!(
                "world `{}` already exists",
                def.name
            )));
        }
        let built = assemble(self.resolve(def)?)?;
        let json = serde_json::to_vec(def).map_err(|e| ServiceError::Internal(e.to_string()))?;
        let id = self.store.put_object(ObjectKind::World, &json)?;
        self.store.set_alias(&alias, &id)?;
        tracing::info!(world = %def.name, id = %id, "world stored");
        Ok((built, id))
    }

    /// Checks a sketch world request and queues its job. Everything that can be checked before
    /// the synthesis is checked here, so that a refused request stores nothing: the name (valid,
    /// not taken, not being made by another sketch job), the bounds and cell size against
    /// `limits`, the sketch, the exemplars and the dictionary. When the job has made the
    /// terrain, it is stored as exemplar `sketch-{name}` (the world's base), the world is
    /// created from it like `POST /admin/worlds` (`assemble`, then the definition is stored,
    /// then published), and the job's result is the world's name; if that fails the base is
    /// deleted again.
    pub fn submit_sketch(
        self: &Arc<Self>,
        request: SketchRequest,
        limits: &SizeLimits,
        served: Served,
        assemble: Assemble,
    ) -> Result<Job, ServiceError> {
        let sketch = request.checked_sketch(limits)?;
        if let Some(e) = request
            .exemplars
            .iter()
            .find(|e| !self.catalog.has_exemplar(e))
        {
            return Err(ServiceError::Invalid(format!("unknown exemplar `{e}`")));
        }
        let def = WorldDefinition::from_request(
            WorldRequest {
                name: request.name.clone(),
                base: String::new(),
                dictionaries: request
                    .dictionaries
                    .iter()
                    .cloned()
                    .map(WorldDictionary::Id)
                    .collect(),
                max_zoom: None,
                weights: None,
                materials: None,
                species: None,
                title: None,
                attribution: None,
                fill_m: None,
                center: None,
                sea_level_m: None,
                water: None,
                scatter: None,
                classes: None,
                biomes: Vec::new(),
                controls: Vec::new(),
            },
            &self.defaults,
        )?;
        if let Some((_, dict)) = def
            .dictionary_bands()?
            .into_iter()
            .find(|(_, d)| self.catalog.dictionary(d).is_none())
        {
            return Err(ServiceError::Invalid(format!(
                "unknown dictionary `{dict}`"
            )));
        }
        let name = def.name.clone();
        let pending = self.jobs.list().into_iter().any(|j| {
            j.state.is_active() && matches!(&j.request, JobRequest::Sketch(r) if r.name == name)
        });
        if self.configured.contains(&name)
            || served(&name)
            || self.store.alias(&format!("world.{name}"))?.is_some()
            || pending
        {
            return Err(ServiceError::Conflict(format!(
                "world `{name}` already exists"
            )));
        }
        let this = self.clone();
        let finish = Box::new(move |grid: Grid| this.finish_sketch(def, grid, &served, assemble));
        let job = self
            .jobs
            .submit_sketch(request, SketchJob { sketch, finish })?;
        tracing::info!(job = %job.id, world = %name, "sketch job queued");
        Ok(job)
    }

    /// Stores a sketch job's terrain as the base of world `def` and creates the world.
    fn finish_sketch(
        &self,
        mut def: WorldDefinition,
        grid: Grid,
        served: &Served,
        assemble: Assemble,
    ) -> Result<String, ServiceError> {
        let mut base_name = format!("sketch-{}", def.name);
        base_name.truncate(64);
        let info = self.put_exemplar(&base_name, &LayeredRaster::from_elevation(grid))?;
        def.base = info.id.clone();
        match self.create_world(&def, |n| served(n), assemble) {
            Ok((publish, _)) => {
                publish();
                Ok(def.name)
            }
            Err(e) => {
                if let Err(d) = self.delete_exemplar(&info.id) {
                    tracing::warn!(exemplar = %info.id, error = %d, "cannot delete the base of a failed sketch world");
                }
                Err(e)
            }
        }
    }

    /// Deletes the stored world `name`; configured worlds are read-only.
    pub fn delete_world(&self, name: &str) -> Result<(), ServiceError> {
        let _changes = lock(&self.changes);
        if self.configured.contains(name) {
            return Err(ServiceError::Conflict(format!(
                "world `{name}` comes from the configuration and is read-only"
            )));
        }
        let alias = format!("world.{name}");
        let id = match self.store.alias(&alias) {
            Ok(Some(id)) => id,
            Ok(None) | Err(StoreError::BadName(_)) => {
                return Err(ServiceError::NotFound(format!("unknown world `{name}`")))
            }
            Err(e) => return Err(e.into()),
        };
        self.store.remove_alias(&alias)?;
        self.store.delete_object(ObjectKind::World, &id)?;
        // Its whole-world layers are a cache of the deleted world; a failure leaves a file that
        // a later world of the same name refuses (its key differs).
        if let Err(e) = self.store.delete_landscape(name) {
            tracing::warn!(world = %name, error = %e, "store: cannot delete the world's stored layers");
        }
        Ok(())
    }
}
