//! Jobs — dictionary builds and sketch worlds: a bounded queue (full → 503) feeding a fixed pool of low-priority worker
//! threads, each running builds on its own small rayon pool so that builds never compete with
//! tile synthesis for the blocking pool or the global rayon pool. Job records live in memory and
//! are written to the store on every state change; on start, jobs a previous process left queued
//! or running are recorded as failed. A cancelled or failed build writes nothing to the store: the
//! dictionary is stored (atomically) only once the build has succeeded; a sketch job hands its
//! terrain to the catalogue service, which stores the world only once it is complete.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use terrasynth_core::dictionary::build::{build_cancellable, BuildOptions, Exemplar};
use terrasynth_core::dictionary::{
    build_gradient_tiles, exemplar_plane, AmplifierKind, AnyDictionary, DictionaryError,
    ExemplarOptions, GradientParams, LayerKind, Learning,
};
use terrasynth_core::landscape::{exemplar_vegetation, LandscapeConfig, Species};
use terrasynth_core::raster::Grid;
use terrasynth_core::synth::sketch::geometry::Sketch;

use crate::catalog::{lock, Catalog};
use crate::error::{ServiceError, StoreError};
use crate::exemplar;
use crate::sketch::{run_sketch, SketchFailure, SketchRequest};
use crate::store::{ObjectKind, Store};
use crate::time::now_rfc3339;
use crate::worlds::CLASSES_LAYER;
use terrasynth_core::landscape::classes::{class_layers, class_values, MAX_CLASSES};

/// State of a job.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    /// Waiting for a worker.
    Queued,
    /// Building.
    Running,
    /// Done; `result` holds the dictionary id.
    Succeeded,
    /// Failed; `error` says why.
    Failed,
    /// Cancelled by `DELETE /admin/jobs/{id}`.
    Cancelled,
}

impl JobState {
    /// Whether the job can still change state.
    pub fn is_active(self) -> bool {
        matches!(self, JobState::Queued | JobState::Running)
    }
}

/// `POST /admin/dictionaries`: what to build.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DictionaryRequest {
    /// Human name of the dictionary (an alias of its content id): 1–64 letters, digits, `-`
    /// or `_`.
    #[schema(pattern = "^[A-Za-z0-9_-]{1,64}$")]
    pub name: String,
    /// Ids of stored exemplars.
    pub exemplars: Vec<String>,
    /// Number of atoms (0 keeps every patch). Default 256.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub atoms: Option<usize>,
    /// High-resolution patch side, a multiple of 4 between 4 and 64. Default 16.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch: Option<usize>,
    /// Step between patches, ≥ 1. Default 8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<usize>,
    /// `complete` or `medoids[:ITERATIONS]`. Default `medoids` (6 rounds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learning: Option<String>,
    /// Matching weights recommended with this dictionary, by term or layer name
    /// (`elevation`, `altitude`, `slope`, or an exemplar layer); checked against the built
    /// dictionary's layers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<BTreeMap<String, f32>>,
    /// Seed of every random choice. Default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Species whose vegetation layers the atoms carry, each `{"name", "colour", "elevation",
    /// "slope", "northness", "wetness"}` as in a world file's `[[landscape.species]]` (niche
    /// ranges `{"min", "max", "falloff"}`). Default: the default world's species, so that worlds
    /// built on the dictionary synthesize vegetation from its atoms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Object>>)]
    pub species: Option<Vec<Species>>,
    /// What to build: `dictionary` (patch atoms for the dictionary amplifier, the default) or
    /// `gradient` (a gradient tile set for the gradient amplifier, issue #20: takes `tile`,
    /// `colours`, `alternatives`, `mixing` and `seed`; the dictionary parameters `atoms`,
    /// `patch`, `stride`, `learning`, `weights` and `species` are refused).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(example = "gradient")]
    pub kind: Option<String>,
    /// Gradient tile side in child pixels, a multiple of 4 in 4–16 (`kind: gradient`). Default
    /// 8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile: Option<usize>,
    /// Edge colours per layer, 2–16 (`kind: gradient`). Default 4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colours: Option<usize>,
    /// Alternatives per colour combination, 1–64 (`kind: gradient`). Default 4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alternatives: Option<usize>,
    /// Exemplar mixing in `[0, 1]` (`kind: gradient`). Default 0.25.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mixing: Option<f32>,
}

impl DictionaryRequest {
    /// What the request builds (`kind`, default `dictionary`), or why `kind` is invalid.
    pub fn build_kind(&self) -> Result<AmplifierKind, ServiceError> {
        match self.kind.as_deref() {
            None | Some("dictionary") => Ok(AmplifierKind::Dictionary),
            Some("gradient") => Ok(AmplifierKind::Gradient),
            Some(k) => Err(ServiceError::Invalid(format!(
                "kind `{k}` must be `dictionary` or `gradient`"
            ))),
        }
    }
}

/// What a job was asked to do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum JobRequest {
    /// Build a dictionary (`POST /admin/dictionaries`).
    Dictionary(DictionaryRequest),
    /// Make a world from a sketch (`POST /admin/worlds/sketch`).
    Sketch(SketchRequest),
}

impl JobRequest {
    /// The stored exemplars the job reads.
    pub fn exemplars(&self) -> &[String] {
        match self {
            JobRequest::Dictionary(r) => &r.exemplars,
            JobRequest::Sketch(r) => &r.exemplars,
        }
    }
}

/// The part of a sketch job that does not go into its record: the checked sketch, and what to
/// do with the terrain (store it and the world, serve the world; returns the world's name).
pub struct SketchJob {
    /// The sketch, checked when the job was submitted.
    pub sketch: Sketch,
    /// Stores and serves the synthesized base.
    pub finish: Box<dyn FnOnce(Grid) -> Result<String, ServiceError> + Send>,
}

/// A job record.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Job {
    /// Job id.
    pub id: String,
    /// What the job does: `dictionary` or `sketch`.
    pub kind: String,
    /// State.
    pub state: JobState,
    /// Progress 0–1.
    pub progress: f64,
    /// Current stage (`queued`, `reading`, then for dictionaries `patches`, `learning`, for
    /// gradient tile sets `tiles`, for sketches `features`, `filling`, `seams`; `storing`,
    /// `done`).
    pub stage: String,
    /// Why it failed.
    pub error: Option<String>,
    /// Once succeeded: the dictionary id, or the sketch world's name.
    pub result: Option<String>,
    /// When it was submitted (RFC 3339, UTC).
    pub created: String,
    /// When a worker started it.
    pub started: Option<String>,
    /// When it ended.
    pub finished: Option<String>,
    /// The request.
    pub request: JobRequest,
}

struct Inner {
    store: Store,
    catalog: Arc<Catalog>,
    /// The landscape whose species (and seeding simulation) derive the vegetation layers of
    /// builds that name no species.
    landscape: Arc<LandscapeConfig>,
    records: Mutex<BTreeMap<String, Job>>,
    cancels: Mutex<BTreeMap<String, Arc<AtomicBool>>>,
    /// What sketch jobs do with their terrain, until they run.
    sketches: Mutex<BTreeMap<String, SketchJob>>,
    tx: SyncSender<String>,
}

/// Why a build job did not produce a dictionary (its record's `error` is this, worded).
#[derive(Debug, thiserror::Error)]
enum BuildFailure {
    /// Cancelled by `DELETE /admin/jobs/{id}`.
    #[error("cancelled")]
    Cancelled,
    /// The request cannot be built (an exemplar is gone, the species or weights do not fit).
    #[error("invalid dictionary parameters: {0}")]
    Invalid(String),
    /// Building failed.
    #[error(transparent)]
    Build(#[from] DictionaryError),
    /// The store failed reading an exemplar or writing the dictionary.
    #[error("store: {0}")]
    Store(#[from] StoreError),
    /// A sketch world could not be made.
    #[error(transparent)]
    Sketch(#[from] SketchFailure),
}

/// How many builds run and wait.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JobSettings {
    /// Builds running at once (each on its own low-priority worker thread).
    pub workers: usize,
    /// Threads of each build (a dedicated rayon pool).
    pub threads: usize,
    /// Builds allowed to wait for a worker (beyond: [`ServiceError::QueueFull`]).
    pub queue: usize,
}

/// The job queue and its workers.
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
}

/// Lowers the calling thread's scheduling priority (Linux: per-thread nice value).
pub(crate) fn lower_priority() {
    #[cfg(unix)]
    // SAFETY: nice(2) only changes the calling thread's scheduling priority.
    unsafe {
        let _ = libc::nice(10);
    }
}

impl Jobs {
    /// Loads the job records of `store` (marking interrupted ones failed) and starts `workers`
    /// worker threads, each building on `threads` threads, with `queue` waiting places. Builds
    /// that name no species derive the vegetation layers of `landscape`.
    pub fn start(
        store: Store,
        catalog: Arc<Catalog>,
        landscape: Arc<LandscapeConfig>,
        settings: JobSettings,
    ) -> Result<Jobs, ServiceError> {
        let JobSettings {
            workers,
            threads,
            queue,
        } = settings;
        let (tx, rx) = sync_channel::<String>(queue);
        let mut records = BTreeMap::new();
        for (id, bytes) in store.jobs()? {
            match serde_json::from_slice::<Job>(&bytes) {
                Ok(mut job) => {
                    if job.state.is_active() {
                        job.state = JobState::Failed;
                        job.error = Some("interrupted: the server stopped during the build".into());
                        job.finished = Some(now_rfc3339());
                        store.put_job(&id, &serde_json::to_vec_pretty(&job).unwrap_or_default())?;
                        tracing::warn!(job = %id, "job interrupted by a restart: marked failed");
                    }
                    records.insert(id, job);
                }
                Err(e) => store.quarantine_job(&id, &e)?,
            }
        }
        let jobs = Jobs {
            inner: Arc::new(Inner {
                store,
                catalog,
                landscape,
                records: Mutex::new(records),
                cancels: Mutex::new(BTreeMap::new()),
                sketches: Mutex::new(BTreeMap::new()),
                tx,
            }),
        };
        let rx = Arc::new(Mutex::new(rx));
        for i in 0..workers.max(1) {
            let jobs = jobs.clone();
            let rx = rx.clone();
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads.max(1))
                .thread_name(move |t| format!("build-{i}-{t}"))
                .start_handler(|_| lower_priority())
                .build()
                .map_err(|e| ServiceError::Internal(format!("build pool: {e}")))?;
            std::thread::Builder::new()
                .name(format!("build-worker-{i}"))
                .spawn(move || {
                    lower_priority();
                    jobs.work(&rx, &pool)
                })
                .map_err(|e| ServiceError::Internal(format!("build worker: {e}")))?;
        }
        Ok(jobs)
    }

    fn work(&self, rx: &Mutex<Receiver<String>>, pool: &rayon::ThreadPool) {
        loop {
            let next = lock(rx).recv();
            let Ok(id) = next else { return };
            let cancel = Arc::new(AtomicBool::new(false));
            let request = {
                let mut records = lock(&self.inner.records);
                let Some(job) = records.get_mut(&id) else {
                    continue;
                };
                if job.state != JobState::Queued {
                    continue;
                }
                job.state = JobState::Running;
                job.stage = "reading".into();
                job.started = Some(now_rfc3339());
                lock(&self.inner.cancels).insert(id.clone(), cancel.clone());
                job.request.clone()
            };
            self.persist(&id);
            let outcome = pool.install(|| match &request {
                JobRequest::Dictionary(r) if r.kind.as_deref() == Some("gradient") => {
                    self.run_gradient(&id, r, &cancel)
                }
                JobRequest::Dictionary(r) => self.run(&id, r, &cancel),
                JobRequest::Sketch(r) => self.run_sketch(&id, r, &cancel),
            });
            lock(&self.inner.sketches).remove(&id);
            lock(&self.inner.cancels).remove(&id);
            {
                let mut records = lock(&self.inner.records);
                if let Some(job) = records.get_mut(&id) {
                    job.finished = Some(now_rfc3339());
                    match outcome {
                        Ok(dict_id) => {
                            job.state = JobState::Succeeded;
                            job.progress = 1.0;
                            job.stage = "done".into();
                            job.result = Some(dict_id);
                        }
                        Err(BuildFailure::Cancelled)
                        | Err(BuildFailure::Sketch(SketchFailure::Cancelled))
                        | Err(BuildFailure::Build(DictionaryError::Cancelled)) => {
                            job.state = JobState::Cancelled;
                            job.stage = "cancelled".into();
                        }
                        Err(e) => {
                            job.state = JobState::Failed;
                            job.error = Some(e.to_string());
                        }
                    }
                    tracing::info!(job = %id, kind = %job.kind, state = ?job.state, "job ended");
                }
            }
            self.persist(&id);
        }
    }

    fn set_progress(&self, id: &str, stage: &str, progress: f64) {
        let changed = {
            let mut records = lock(&self.inner.records);
            match records.get_mut(id) {
                Some(job) => {
                    let changed = job.stage != stage;
                    job.stage = stage.to_string();
                    job.progress = progress.clamp(0.0, 1.0);
                    changed
                }
                None => false,
            }
        };
        if changed {
            self.persist(id);
        }
    }

    /// Builds and stores the dictionary of `request`; its id.
    fn run(
        &self,
        id: &str,
        request: &DictionaryRequest,
        cancel: &AtomicBool,
    ) -> Result<String, BuildFailure> {
        let params = BuildFailure::Invalid;
        let landscape = species_landscape(&self.inner.landscape, request.species.as_deref())
            .map_err(|e| params(e.to_string()))?;
        let mut exemplars: Vec<Exemplar> = Vec::new();
        // Each exemplar's `classes` layer, made into class layers once every value is known.
        let mut class_rasters: Vec<Option<ndarray::Array2<f32>>> = Vec::new();
        for (i, ex_id) in request.exemplars.iter().enumerate() {
            let payload = self
                .inner
                .store
                .get_object(ObjectKind::Exemplar, ex_id)
                .map_err(BuildFailure::Store)?
                .ok_or_else(|| params(format!("exemplar {ex_id} is gone")))?;
            let (_, raster) = exemplar::decode(&payload).map_err(BuildFailure::Store)?;
            let grid = raster
                .elevation()
                .ok_or_else(|| params(format!("exemplar {ex_id} has no elevation")))?;
            let mut extra = Vec::new();
            let mut class_raster = None;
            for (name, data) in raster.layers.iter().skip(1) {
                if name == CLASSES_LAYER {
                    let mut d = data.clone();
                    terrasynth_core::raster::nan_where_invalid(&mut d, raster.valid.as_ref());
                    // On the squared cells the exemplar's elevation takes (labels: nearest).
                    let square = terrasynth_core::raster::SquareCells::for_grid(
                        &grid.georef,
                        grid.rows(),
                        grid.cols(),
                    );
                    class_raster = Some(square.nearest(&d).map_err(|e| params(e.to_string()))?);
                    continue;
                }
                if name == crate::ingest::RGB_LAYER {
                    // Packed colours are no quantity to match: the image is for worlds' classes.
                    continue;
                }
                let g = terrasynth_core::raster::Grid {
                    data: data.clone(),
                    georef: raster.georef,
                    valid: raster.valid.clone(),
                };
                let filled = g
                    .filled()
                    .map_err(|e| params(format!("layer {name}: {e}")))?;
                extra.push((name.clone(), filled, LayerKind::Continuous));
            }
            // An uploaded layer named after a species is that species' vegetation: it replaces
            // the niche model's.
            let uploaded: Vec<String> = extra.iter().map(|(n, _, _)| n.clone()).collect();
            let options = ExemplarOptions {
                extra,
                exclude: Vec::new(),
                derive: true,
            };
            let ex = Exemplar::from_grid(&grid, options, |filled, cells| {
                let mut species = exemplar_vegetation(&landscape, filled, cells);
                species.retain(|(n, _, _)| !uploaded.contains(n));
                species
            })?;
            exemplars.push(ex);
            class_rasters.push(class_raster);
            if cancel.load(Ordering::Relaxed) {
                return Err(BuildFailure::Cancelled);
            }
            let n = request.exemplars.len() as f64;
            self.set_progress(id, "reading", 0.1 * (i as f64 + 1.0) / n);
        }
        add_class_layers(&mut exemplars, &class_rasters, &request.exemplars).map_err(params)?;
        let opts = build_options(request).map_err(|e| params(e.to_string()))?;
        let mut last = std::time::Instant::now();
        let d = build_cancellable(&exemplars, &opts, cancel, &mut |stage, f| {
            let p = match stage {
                "patches" => 0.1 + 0.3 * f,
                "learning" => 0.4 + 0.55 * f,
                _ => 0.95,
            };
            // Progress goes to memory at most every 100 ms (and to disk on stage changes).
            if last.elapsed().as_millis() >= 100 || f >= 1.0 {
                last = std::time::Instant::now();
                self.set_progress(id, stage, p);
            }
        })?;
        if let Some(w) = &request.weights {
            let weights = crate::worlds::match_weights(w);
            terrasynth_core::dictionary::matching::ResolvedWeights::resolve(&weights, &d)
                .map_err(|e| params(e.to_string()))?;
        }
        self.store_dictionary(id, &request.name, Arc::new(d).into(), cancel)
    }

    /// The last stage of every dictionary job `id`: unless cancelled, stores `dictionary` under
    /// `name` in the catalogue; its id.
    fn store_dictionary(
        &self,
        id: &str,
        name: &str,
        dictionary: AnyDictionary,
        cancel: &AtomicBool,
    ) -> Result<String, BuildFailure> {
        self.set_progress(id, "storing", 0.97);
        if cancel.load(Ordering::Relaxed) {
            return Err(BuildFailure::Cancelled);
        }
        self.inner
            .catalog
            .add_dictionary(&self.inner.store, name, dictionary)
            .map_err(BuildFailure::Store)
    }

    /// Builds and stores the gradient tile set of `request` (`kind: gradient`); its id.
    fn run_gradient(
        &self,
        id: &str,
        request: &DictionaryRequest,
        cancel: &AtomicBool,
    ) -> Result<String, BuildFailure> {
        let params = gradient_params(request).map_err(|e| BuildFailure::Invalid(e.to_string()))?;
        let mut planes = Vec::with_capacity(request.exemplars.len());
        for (i, ex_id) in request.exemplars.iter().enumerate() {
            let payload = self
                .inner
                .store
                .get_object(ObjectKind::Exemplar, ex_id)?
                .ok_or_else(|| BuildFailure::Invalid(format!("exemplar {ex_id} is gone")))?;
            let (_, raster) = exemplar::decode(&payload)?;
            let grid = raster.elevation().ok_or_else(|| {
                BuildFailure::Invalid(format!("exemplar {ex_id} has no elevation"))
            })?;
            planes.push(exemplar_plane(&grid, &[]));
            if cancel.load(Ordering::Relaxed) {
                return Err(BuildFailure::Cancelled);
            }
            let n = request.exemplars.len() as f64;
            self.set_progress(id, "reading", 0.3 * (i as f64 + 1.0) / n);
        }
        self.set_progress(id, "tiles", 0.3);
        let set = build_gradient_tiles(&planes, &params)?;
        self.store_dictionary(id, &request.name, Arc::new(set).into(), cancel)
    }

    /// Synthesizes the terrain of sketch job `id` from its stored exemplars and hands it to the
    /// job's `finish`; the world's name.
    fn run_sketch(
        &self,
        id: &str,
        request: &SketchRequest,
        cancel: &AtomicBool,
    ) -> Result<String, BuildFailure> {
        let job = lock(&self.inner.sketches).remove(id).ok_or_else(|| {
            BuildFailure::Invalid("the sketch job lost its state (server restarted)".into())
        })?;
        let mut exemplars: Vec<Grid> = Vec::new();
        for ex_id in &request.exemplars {
            let payload = self
                .inner
                .store
                .get_object(ObjectKind::Exemplar, ex_id)?
                .ok_or_else(|| BuildFailure::Invalid(format!("exemplar {ex_id} is gone")))?;
            let (_, raster) = exemplar::decode(&payload)?;
            let grid = raster.elevation().ok_or_else(|| {
                BuildFailure::Invalid(format!("exemplar {ex_id} has no elevation"))
            })?;
            exemplars.push(grid);
        }
        self.set_progress(id, "reading", 0.05);
        let mut last = std::time::Instant::now();
        let grid = run_sketch(
            &job.sketch,
            &exemplars,
            request.seed.unwrap_or(1),
            &mut |stage, f| {
                let p = match stage {
                    "exemplars" => 0.05 + 0.05 * f,
                    "features" => 0.1 + 0.5 * f,
                    "filling" => 0.6 + 0.3 * f,
                    _ => 0.9 + 0.05 * f,
                };
                if last.elapsed().as_millis() >= 100 || f >= 1.0 {
                    last = std::time::Instant::now();
                    self.set_progress(id, stage, p);
                }
                !cancel.load(Ordering::Relaxed)
            },
        )?;
        self.set_progress(id, "storing", 0.97);
        if cancel.load(Ordering::Relaxed) {
            return Err(BuildFailure::Cancelled);
        }
        Ok((job.finish)(grid).map_err(SketchFailure::Service)?)
    }

    fn persist(&self, id: &str) {
        let json = lock(&self.inner.records)
            .get(id)
            .and_then(|j| serde_json::to_vec_pretty(j).ok());
        if let Some(json) = json {
            if let Err(e) = self.inner.store.put_job(id, &json) {
                tracing::error!(job = %id, error = %e, "cannot write the job record");
            }
        }
    }

    /// Queues a build; the job id. 503 when the queue is full.
    pub fn submit(&self, request: DictionaryRequest) -> Result<Job, ServiceError> {
        let name = request.name.clone();
        self.queue("dictionary", &name, JobRequest::Dictionary(request), None)
    }

    /// Queues a sketch world; the job. 503 when the queue is full.
    pub fn submit_sketch(
        &self,
        request: SketchRequest,
        job: SketchJob,
    ) -> Result<Job, ServiceError> {
        let name = request.name.clone();
        self.queue("sketch", &name, JobRequest::Sketch(request), Some(job))
    }

    fn queue(
        &self,
        kind: &str,
        name: &str,
        request: JobRequest,
        sketch: Option<SketchJob>,
    ) -> Result<Job, ServiceError> {
        let id = new_id(name);
        let job = Job {
            id: id.clone(),
            kind: kind.into(),
            state: JobState::Queued,
            progress: 0.0,
            stage: "queued".into(),
            error: None,
            result: None,
            created: now_rfc3339(),
            started: None,
            finished: None,
            request,
        };
        lock(&self.inner.records).insert(id.clone(), job.clone());
        if let Some(s) = sketch {
            lock(&self.inner.sketches).insert(id.clone(), s);
        }
        match self.inner.tx.try_send(id.clone()) {
            Ok(()) => {
                self.persist(&id);
                Ok(job)
            }
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                lock(&self.inner.records).remove(&id);
                lock(&self.inner.sketches).remove(&id);
                Err(ServiceError::QueueFull)
            }
        }
    }

    /// Every job, oldest first.
    pub fn list(&self) -> Vec<Job> {
        let mut v: Vec<Job> = lock(&self.inner.records).values().cloned().collect();
        v.sort_by(|a, b| (&a.created, &a.id).cmp(&(&b.created, &b.id)));
        v
    }

    /// Job `id`.
    pub fn get(&self, id: &str) -> Option<Job> {
        lock(&self.inner.records).get(id).cloned()
    }

    /// Cancels a queued or running job: 404 unknown, 409 already finished.
    pub fn cancel(&self, id: &str) -> Result<Job, ServiceError> {
        let job = {
            let mut records = lock(&self.inner.records);
            let job = records
                .get_mut(id)
                .ok_or_else(|| ServiceError::NotFound(format!("no job `{id}`")))?;
            match job.state {
                JobState::Queued => {
                    lock(&self.inner.sketches).remove(id);
                    job.state = JobState::Cancelled;
                    job.stage = "cancelled".into();
                    job.finished = Some(now_rfc3339());
                }
                JobState::Running => {
                    if let Some(flag) = lock(&self.inner.cancels).get(id) {
                        flag.store(true, Ordering::Relaxed);
                    }
                }
                s => {
                    return Err(ServiceError::Conflict(format!(
                        "job `{id}` has already ended ({s:?})"
                    )))
                }
            }
            job.clone()
        };
        self.persist(id);
        Ok(job)
    }

    /// Whether a queued or running job uses exemplar `id`.
    pub fn uses_exemplar(&self, id: &str) -> bool {
        lock(&self.inner.records)
            .values()
            .any(|j| j.state.is_active() && j.request.exemplars().iter().any(|e| e == id))
    }
}

/// The gradient tile set parameters of a `kind: gradient` request (defaults for absent fields),
/// validated, naming the first bad field; the dictionary-only fields are refused.
pub fn gradient_params(r: &DictionaryRequest) -> Result<GradientParams, ServiceError> {
    let dictionary_only = [
        ("atoms", r.atoms.is_some()),
        ("patch", r.patch.is_some()),
        ("stride", r.stride.is_some()),
        ("learning", r.learning.is_some()),
        ("weights", r.weights.is_some()),
        ("species", r.species.is_some()),
    ];
    if let Some((field, _)) = dictionary_only.iter().find(|(_, given)| *given) {
        return Err(ServiceError::Invalid(format!(
            "{field} is a dictionary parameter; a gradient tile set (kind `gradient`) takes \
             tile, colours, alternatives, mixing and seed"
        )));
    }
    let d = GradientParams::default();
    let p = GradientParams {
        tile: r.tile.unwrap_or(d.tile),
        colours: r.colours.unwrap_or(d.colours),
        alternatives: r.alternatives.unwrap_or(d.alternatives),
        mixing: r.mixing.unwrap_or(d.mixing),
        seed: r.seed.unwrap_or(d.seed),
    };
    p.validate()
        .map_err(|e| ServiceError::Invalid(e.to_string()))?;
    Ok(p)
}

/// The build options of a request (defaults for absent fields), validated; the gradient-only
/// fields are refused.
pub fn build_options(r: &DictionaryRequest) -> Result<BuildOptions, ServiceError> {
    let gradient_only = [
        ("tile", r.tile.is_some()),
        ("colours", r.colours.is_some()),
        ("alternatives", r.alternatives.is_some()),
        ("mixing", r.mixing.is_some()),
    ];
    if let Some((field, _)) = gradient_only.iter().find(|(_, given)| *given) {
        return Err(ServiceError::Invalid(format!(
            "{field} is a gradient tile set parameter: give \"kind\": \"gradient\" to build one"
        )));
    }
    let d = BuildOptions::default();
    let learning = match &r.learning {
        None => d.learning,
        Some(s) => s.parse::<Learning>().map_err(ServiceError::Invalid)?,
    };
    let opts = BuildOptions {
        patch: r.patch.unwrap_or(d.patch),
        stride: r.stride.unwrap_or(d.stride),
        atoms: r.atoms.unwrap_or(d.atoms),
        learning,
        seed: r.seed.unwrap_or(d.seed),
        sparsity: 1,
    };
    if opts.patch < 4 || opts.patch > 64 || opts.patch % 4 != 0 {
        return Err(ServiceError::Invalid(format!(
            "patch {} must be a multiple of 4 between 4 and 64",
            opts.patch
        )));
    }
    if opts.stride == 0 || opts.stride > 1024 {
        return Err(ServiceError::Invalid(format!(
            "stride {} must lie between 1 and 1024",
            opts.stride
        )));
    }
    if opts.atoms > 65536 {
        return Err(ServiceError::Invalid(format!(
            "atoms {} exceeds 65536",
            opts.atoms
        )));
    }
    if let Learning::Medoids { iterations } = opts.learning {
        if iterations > 100 {
            return Err(ServiceError::Invalid("at most 100 learning rounds".into()));
        }
    }
    if let Some(w) = &r.weights {
        if w.values().any(|v| !v.is_finite() || *v < 0.0) || w.values().all(|v| *v == 0.0) {
            return Err(ServiceError::Invalid(
                "weights must be finite, non-negative and not all zero".into(),
            ));
        }
    }
    if let Some(species) = &r.species {
        species_landscape(&LandscapeConfig::default(), Some(species))?;
    }
    Ok(opts)
}

/// The landscape whose species layers a build derives: `base`'s species and seeding simulation,
/// or `species` (when given) with `base`'s seeding simulation; validated. Materials play no part
/// in a dictionary, so the default ones stand in.
fn species_landscape(
    base: &LandscapeConfig,
    species: Option<&[Species]>,
) -> Result<LandscapeConfig, ServiceError> {
    let l = LandscapeConfig {
        species: species.map_or_else(|| base.species.clone(), <[Species]>::to_vec),
        clustering: base.clustering.clone(),
        ..LandscapeConfig::default()
    };
    l.validate()
        .map_err(|e| ServiceError::Invalid(format!("species: {e}")))?;
    Ok(l)
}

/// A fresh job id: 16 hex digits of SHA-256 over the clock, the process and a counter.
fn new_id(salt: &str) -> String {
    use sha2::{Digest, Sha256};
    static SEQ: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let seq = SEQ.fetch_add(1, Ordering::Relaxed);
    let digest = Sha256::digest(format!("{nanos}|{}|{seq}|{salt}", std::process::id()));
    crate::object::hex(&digest[..8])
}

/// The class layers of a build's exemplars (`LayerKind::Class`, group `classes`, one layer per
/// raster value, see [`class_layers`]): when any exemplar has a `classes` layer, every one must,
/// and each gets a layer for every value of all of them (so that the layers agree).
fn add_class_layers(
    exemplars: &mut [Exemplar],
    rasters: &[Option<ndarray::Array2<f32>>],
    ids: &[String],
) -> Result<(), String> {
    if rasters.iter().all(Option::is_none) {
        return Ok(());
    }
    let mut values = std::collections::BTreeSet::new();
    for (r, id) in rasters.iter().zip(ids) {
        let r = r.as_ref().ok_or_else(|| {
            format!(
                "exemplar {id} has no `{CLASSES_LAYER}` layer: every exemplar of a build with \
                 class layers needs one"
            )
        })?;
        values.extend(class_values(r).map_err(|e| format!("exemplar {id}: {e}"))?);
    }
    let values: Vec<u16> = values.into_iter().collect();
    if values.len() > MAX_CLASSES {
        return Err(format!(
            "the class rasters hold {} values (at most {MAX_CLASSES})",
            values.len()
        ));
    }
    for (ex, r) in exemplars.iter_mut().zip(rasters.iter().flatten()) {
        if r.dim() != ex.elevation.dim() {
            return Err(format!(
                "the `{CLASSES_LAYER}` layer is {:?}, the exemplar {:?}",
                r.dim(),
                ex.elevation.dim()
            ));
        }
        ex.layers.extend(class_layers(CLASSES_LAYER, r, &values));
    }
    Ok(())
}
