//! Typed configuration: the server settings of `config/default.toml` (or the file given with
//! `--config`), the world files it lists, and `TERRASYNTH_*` environment overrides. When no file
//! is given and `config/default.toml` does not exist in the working directory, the copies embedded
//! in the binary are used, so the binary serves the default world from anywhere. No global state:
//! loading returns a value.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use thiserror::Error;

use terrasynth_core::dictionary::{AmplifierKind, GradientParams, MatchWeights};
use terrasynth_core::synth::{check_bands, ZoomBand};

/// The embedded copy of `config/default.toml`.
pub const DEFAULT_TOML: &str = include_str!("../../config/default.toml");
/// The embedded copy of `config/worlds/tienshan.toml` (the core crate embeds it, beside the
/// default world's data).
pub const TIENSHAN_TOML: &str = terrasynth_core::assets::TIENSHAN_WORLD_TOML;
/// Where the default configuration file is looked for.
pub const DEFAULT_PATH: &str = "config/default.toml";

/// An error loading configuration.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A file is not valid TOML for its schema.
    #[error("invalid configuration in {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What was wrong.
        message: String,
    },
    /// An environment variable holds an invalid value.
    #[error("invalid value for {name}: {message}")]
    Env {
        /// The variable.
        name: String,
        /// What was wrong.
        message: String,
    },
    /// Values are individually valid but inconsistent.
    #[error("invalid configuration: {0}")]
    Invalid(String),
}

/// Server settings (`config/default.toml`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct ServerConfig {
    /// Address and port to bind.
    pub listen: String,
    /// Capacity of all tile caches together, MiB (see [`ServerConfig::encoded_cache_bytes`] and
    /// [`ServerConfig::level_cache_bytes`] for the split).
    pub cache_mb: u64,
    /// Directory of the on-disk store.
    pub store_dir: PathBuf,
    /// CORS origins (`*` for any).
    pub cors_origins: Vec<String>,
    /// `Cache-Control` of tile responses.
    pub cache_control: String,
    /// Tile computations running at once.
    pub synth_concurrency: usize,
    /// Tile requests allowed to wait for a computation slot (beyond: 503).
    pub synth_queue: usize,
    /// Request timeout, seconds (admin requests have [`ServerConfig::upload_timeout_s`]).
    pub request_timeout_s: u64,
    /// Timeout of admin API requests, seconds: an exemplar upload of `max_body_mb` over a slow
    /// link takes far longer than a tile.
    pub upload_timeout_s: u64,
    /// World files, relative to the configuration file's directory.
    pub worlds: Vec<String>,
    /// Directory of the MapLibre GL JS distribution the web map loads (relative paths are
    /// relative to the working directory).
    pub web_vendor_dir: PathBuf,
    /// Bearer token of the admin API (`/admin/...`); empty disables the admin API (its routes
    /// answer 404). Prefer `TERRASYNTH_ADMIN_TOKEN` to writing it in a file.
    pub admin_token: Secret,
    /// Dictionary builds running at once (each on its own low-priority worker).
    pub build_workers: usize,
    /// Threads of each build (a dedicated rayon pool, so builds never starve tile synthesis).
    pub build_threads: usize,
    /// Dictionary builds allowed to wait for a worker (beyond: 503).
    pub build_queue: usize,
    /// Largest admin request body, MiB (beyond: 413).
    pub max_body_mb: u64,
    /// Largest uploaded raster, pixels per layer (checked before decoding allocates).
    pub max_pixels: u64,
    /// Largest uploaded raster width or height, pixels.
    pub max_dimension: u64,
    /// Most layers of an uploaded exemplar (elevation included).
    pub max_layers: usize,
    /// The base URL clients reach the server at (`https://tiles.example.com` or with a path
    /// prefix, no trailing slash), used for the absolute URLs of TileJSON, styles and `/worlds`.
    /// Empty: the request's `Host` (and `X-Forwarded-Proto`) are reflected, with `Vary`, and the
    /// listening address stands in when the `Host` is missing or invalid.
    pub public_url: String,
    /// Seconds a client has to send a request's head (request line and headers) once the server
    /// waits for it; for HTTP/1 this includes the wait for the next request on a kept-alive
    /// connection. Beyond, the connection is closed.
    pub header_read_timeout_s: u64,
    /// Seconds a connection may stay open without a request in progress (beyond: closed).
    pub idle_timeout_s: u64,
    /// Open client connections at most. When full, a new connection closes the one idle the
    /// longest; when none is idle, it is refused.
    pub max_connections: usize,
    /// Longest request target (path and query), bytes (beyond: 414).
    pub max_uri_bytes: usize,
    /// Memory all exemplar uploads in progress may use together, MiB: each upload reserves its
    /// body and its decoded size (estimated from the file header before decoding) from it;
    /// beyond what is free, 503 (413 when one upload alone needs more).
    pub upload_memory_mb: u64,
    /// Exemplar uploads processed at once (beyond: 503).
    pub max_concurrent_uploads: usize,
    /// Failed admin authentications a client address may make per minute; beyond, its admin
    /// requests are answered 429 until the minute has passed.
    pub auth_failures_per_minute: u32,
}

impl ServerConfig {
    /// Bytes of the encoded-tile cache: a quarter of `cache_mb`.
    pub fn encoded_cache_bytes(&self) -> u64 {
        self.cache_mb.saturating_mul(1 << 20) / 4
    }

    /// Bytes of each world's share when `worlds` worlds are served (its whole-world landscape
    /// layers, then its level-tile caches): the other three quarters of `cache_mb`, shared
    /// equally, so that all caches together hold at most `cache_mb` MiB of tile data.
    pub fn level_cache_bytes(&self, worlds: usize) -> u64 {
        let total = self.cache_mb.saturating_mul(1 << 20);
        (total - self.encoded_cache_bytes()) / (worlds.max(1) as u64)
    }
}

/// A secret string (the admin token): compared by the admin API in constant time and never
/// printed by `Debug`.
#[derive(Clone, Default, Deserialize, PartialEq)]
#[serde(transparent)]
pub struct Secret(pub String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_empty() {
            f.write_str("Secret(unset)")
        } else {
            f.write_str("Secret(***)")
        }
    }
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            listen: "127.0.0.1:8080".into(),
            cache_mb: 512,
            store_dir: PathBuf::from("store"),
            cors_origins: vec!["*".into()],
            cache_control: "public, max-age=86400".into(),
            synth_concurrency: 2,
            synth_queue: 256,
            request_timeout_s: 60,
            upload_timeout_s: 3600,
            worlds: vec!["worlds/tienshan.toml".into()],
            web_vendor_dir: PathBuf::from("node_modules/maplibre-gl/dist"),
            admin_token: Secret::default(),
            build_workers: 1,
            build_threads: 1,
            build_queue: 8,
            max_body_mb: 512,
            max_pixels: 1 << 26,
            max_dimension: 32768,
            max_layers: 16,
            public_url: String::new(),
            header_read_timeout_s: 10,
            idle_timeout_s: 60,
            max_connections: 4096,
            max_uri_bytes: 8192,
            upload_memory_mb: 256,
            max_concurrent_uploads: 2,
            auth_failures_per_minute: 10,
        }
    }
}

/// How a world's dictionary is built.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct DictionaryConfig {
    /// Exemplars: `embedded:tienshan`, `embedded:carrizo` or GeoTIFF paths (relative to the
    /// world file).
    pub exemplars: Vec<String>,
    /// Number of atoms.
    pub atoms: usize,
    /// High-resolution patch side.
    pub patch: usize,
    /// Patch stride.
    pub stride: usize,
    /// Seed.
    pub seed: u64,
    /// The zooms this dictionary amplifies, `"FIRST-LAST"` or `"ZOOM"` (only in
    /// `[[dictionaries]]`, where it is required).
    pub zooms: Option<String>,
    /// Real vegetation rasters replacing the niche-model layer of a species: species name → one
    /// GeoTIFF path per exemplar (same order, same grid as the exemplar; `""` keeps the derived
    /// layer for that exemplar). Densities 0–1.
    pub vegetation_rasters: std::collections::BTreeMap<String, Vec<String>>,
    /// The amplifier of these zooms: `"dictionary"` (the default: a dictionary of `atoms`
    /// patches of side `patch`) or `"gradient"` (a gradient tile set of the same exemplars with
    /// `tile`, `colours`, `alternatives`, `mixing` and `seed`; issue #20).
    pub amplifier: AmplifierKind,
    /// Gradient tile side in child pixels, a multiple of 4 in 4–16 (`amplifier = "gradient"`;
    /// default 8).
    pub tile: Option<usize>,
    /// Edge colours per layer, 2–16 (`amplifier = "gradient"`; default 4).
    pub colours: Option<usize>,
    /// Alternatives per colour combination, 1–64 (`amplifier = "gradient"`; default 4).
    pub alternatives: Option<usize>,
    /// Exemplar mixing in `[0, 1]` (`amplifier = "gradient"`; default 0.25).
    pub mixing: Option<f32>,
}

/// Keys of a dictionary table that only the dictionary amplifier uses.
const DICTIONARY_ONLY_KEYS: [&str; 4] = ["atoms", "patch", "stride", "vegetation_rasters"];
/// Keys of a dictionary table that only the gradient amplifier uses.
const GRADIENT_ONLY_KEYS: [&str; 4] = ["tile", "colours", "alternatives", "mixing"];

impl DictionaryConfig {
    /// The gradient tile set parameters of a `amplifier = "gradient"` table (defaults for absent
    /// keys; the table's `seed`), validated.
    pub fn gradient_params(&self) -> Result<GradientParams, String> {
        let d = GradientParams::default();
        let p = GradientParams {
            tile: self.tile.unwrap_or(d.tile),
            colours: self.colours.unwrap_or(d.colours),
            alternatives: self.alternatives.unwrap_or(d.alternatives),
            mixing: self.mixing.unwrap_or(d.mixing),
            seed: self.seed,
        };
        p.validate().map_err(|e| e.to_string())?;
        Ok(p)
    }
}

impl Default for DictionaryConfig {
    fn default() -> Self {
        DictionaryConfig {
            exemplars: vec![EMBEDDED_TIENSHAN.into()],
            atoms: 256,
            patch: 16,
            stride: 8,
            seed: 1,
            zooms: None,
            vegetation_rasters: Default::default(),
            amplifier: AmplifierKind::Dictionary,
            tile: None,
            colours: None,
            alternatives: None,
            mixing: None,
        }
    }
}

/// The name of the embedded Tien Shan raster in `base` and `exemplars`.
pub const EMBEDDED_TIENSHAN: &str = "embedded:tienshan";
/// The name of the embedded Carrizo Plain lidar (2 m, EPSG:26911) in `base` and `exemplars`.
pub const EMBEDDED_CARRIZO: &str = "embedded:carrizo";

/// One world file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WorldConfig {
    /// URL name (letters, digits, `-`, `_`).
    pub name: String,
    /// Human title.
    #[serde(default)]
    pub title: String,
    /// Attribution for map clients.
    #[serde(default)]
    pub attribution: String,
    /// Base raster: `embedded:tienshan` or a GeoTIFF path (relative to the world file).
    pub base: String,
    /// Native zoom (derived from the base's cell size when absent).
    #[serde(default)]
    pub z_base: Option<u8>,
    /// Deepest zoom served.
    #[serde(default = "default_max_zoom")]
    pub max_zoom: u8,
    /// Elevation outside the base coverage, metres.
    #[serde(default)]
    pub fill_m: f32,
    /// Where map clients open, `[lon, lat]` (default: over the base's highest-relief region).
    #[serde(default)]
    pub center: Option<[f64; 2]>,
    /// Atoms per primitive of the amplifier, 1–8 (default: the dictionary's own sparsity, at
    /// least 2).
    #[serde(default)]
    pub sparsity: Option<u32>,
    /// Sea level, metres (default: 0 for a base with cells below 0, no sea otherwise).
    #[serde(default)]
    pub sea_level_m: Option<f32>,
    /// Lake minima and water colours (`[water]`).
    #[serde(default)]
    pub water: terrasynth_core::landscape::WaterConfig,
    /// Land-cover classes (`[classes]`) for the materials' `class.<name>` terms.
    #[serde(default)]
    pub classes: Option<ClassesFile>,
    /// Dictionary build settings of a world with one dictionary (`[dictionary]`: every amplified
    /// zoom).
    #[serde(default)]
    pub dictionary: DictionaryConfig,
    /// A dictionary per zoom band (`[[dictionaries]]`, each with `zooms`), instead of
    /// `[dictionary]`: see [`terrasynth_core::synth::bands`] for the rule.
    #[serde(default)]
    pub dictionaries: Vec<DictionaryConfig>,
    /// Painted biomes (`[[biomes]]`, each with a `weight` raster on the base's grid and its
    /// `dictionary` build settings), instead of `[dictionary]`/`[[dictionaries]]`: see
    /// [`terrasynth_tiles::biomes`].
    #[serde(default)]
    pub biomes: Vec<BiomeFile>,
    /// Painted controls of species densities (`[[controls]]`: `species`, `raster` on the base's
    /// grid, `mode` `"replace"` or `"scale"`): see [`terrasynth_tiles::controls`].
    #[serde(default)]
    pub controls: Vec<ControlFile>,
    /// Matching weights.
    #[serde(default)]
    pub weights: MatchWeights,
    /// Landscape layers: species niches, materials, drainage style (`[landscape]`; the default
    /// world's when absent).
    #[serde(default = "terrasynth_core::landscape::LandscapeConfig::tienshan")]
    pub landscape: terrasynth_core::landscape::LandscapeConfig,
    /// Directory the world file's relative paths are resolved against (set when loading).
    #[serde(skip)]
    pub dir: PathBuf,
}

/// The `[classes]` of a world file: a class raster with its legend, or an RGB image with HSV
/// ranges, on the base's grid.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClassesFile {
    /// A class raster: a GeoTIFF of integers on the base's grid (path relative to the world
    /// file), with `legend`.
    #[serde(default)]
    pub raster: Option<String>,
    /// An RGB image: an 8-bit RGB(A) PNG of the base's size, placed on the base's grid
    /// (transparent pixels: no class), with `hsv`.
    #[serde(default)]
    pub rgb: Option<String>,
    /// The class raster's legend, `"value" = "name"`.
    #[serde(default)]
    pub legend: std::collections::BTreeMap<String, String>,
    /// The RGB image's classes: `[[classes.hsv]]` with `name` and `hsv = { h = [min, max], s =
    /// [min, max], v = [min, max] }`.
    #[serde(default)]
    pub hsv: Vec<terrasynth_core::landscape::HsvClass>,
    /// Distance, metres, over which a class weight falls from 1 to 0 across a border.
    #[serde(default)]
    pub smoothing_m: f32,
}

/// One `[[biomes]]` entry of a world file: a dictionary and where it goes.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BiomeFile {
    /// The biome's name (default `biome<i>`, `i` its position from 0).
    #[serde(default)]
    pub name: Option<String>,
    /// The weight raster: a GeoTIFF on the base's grid (path relative to the world file),
    /// weights finite and ≥ 0.
    pub weight: String,
    /// The dictionary's build settings (the keys of `[dictionary]`, without `zooms`).
    #[serde(default)]
    pub dictionary: DictionaryConfig,
}

/// One `[[controls]]` entry of a world file: a painted raster that replaces or scales a
/// species' density.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControlFile {
    /// The species it steers (one of the world's).
    pub species: String,
    /// A GeoTIFF on the base's grid (path relative to the world file).
    pub raster: String,
    /// `replace` (values 0–1) or `scale` (values ≥ 0).
    pub mode: terrasynth_tiles::ControlMode,
}

impl BiomeFile {
    /// The biome's name, `biome<i>` when not given.
    pub fn name(&self, i: usize) -> String {
        self.name.clone().unwrap_or_else(|| format!("biome{i}"))
    }
}

impl ClassesFile {
    /// The classes' settings.
    pub fn config(&self) -> terrasynth_core::landscape::ClassesConfig {
        terrasynth_core::landscape::ClassesConfig {
            legend: self.legend.clone(),
            hsv: self.hsv.clone(),
            smoothing_m: self.smoothing_m,
        }
    }
}

fn default_max_zoom() -> u8 {
    16
}

impl WorldConfig {
    /// The world's dictionaries with their zooms (`None`: every amplified zoom), as checked by
    /// [`parse_world`]: `[[dictionaries]]` when given, else the one `[dictionary]`.
    pub fn dictionary_bands(&self) -> Vec<(Option<ZoomBand>, &DictionaryConfig)> {
        if self.dictionaries.is_empty() {
            return vec![(None, &self.dictionary)];
        }
        self.dictionaries
            .iter()
            .map(|d| (d.zooms.as_deref().and_then(|z| z.parse().ok()), d))
            .collect()
    }
}

/// Checks the dictionary tables of world file `path`: `[dictionary]` (no `zooms`) or
/// `[[dictionaries]]` (each with well-formed `zooms`, not overlapping, within `z_base` and
/// `max_zoom` as far as the file gives them), not both.
fn check_dictionaries(w: &WorldConfig, text: &str, path: &str) -> Result<(), ConfigError> {
    let invalid = |m: String| ConfigError::Invalid(format!("{path}: {m}"));
    if w.dictionary.zooms.is_some() {
        return Err(invalid(
            "dictionary.zooms: `zooms` belongs to [[dictionaries]] entries".into(),
        ));
    }
    if w.dictionaries.is_empty() {
        return Ok(());
    }
    let has_single = text
        .parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("dictionary"));
    if has_single {
        return Err(invalid(
            "give either [dictionary] or [[dictionaries]], not both".into(),
        ));
    }
    let mut bands = Vec::new();
    for (i, d) in w.dictionaries.iter().enumerate() {
        let Some(z) = &d.zooms else {
            return Err(invalid(format!(
                "dictionaries[{i}].zooms is missing (e.g. zooms = \"9-12\")"
            )));
        };
        let band: ZoomBand = z
            .parse()
            .map_err(|e| invalid(format!("dictionaries[{i}].zooms: {e}")))?;
        bands.push(Some(band));
    }
    check_bands(&bands, w.z_base.unwrap_or(0), w.max_zoom)
        .map_err(|e| invalid(format!("dictionaries: {e}")))
}

/// Checks the `[[biomes]]` of world file `path`: not with `[dictionary]` or `[[dictionaries]]`,
/// valid unique names, no `zooms` (a biome amplifies every zoom).
fn check_biomes(w: &WorldConfig, text: &str, path: &str) -> Result<(), ConfigError> {
    if w.biomes.is_empty() {
        return Ok(());
    }
    let invalid = |m: String| ConfigError::Invalid(format!("{path}: {m}"));
    let has_single = text
        .parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("dictionary"));
    if has_single || !w.dictionaries.is_empty() {
        return Err(invalid(
            "give either [[biomes]] or [dictionary]/[[dictionaries]], not both (each biome has \
             its own dictionary)"
                .into(),
        ));
    }
    let mut names = Vec::new();
    for (i, b) in w.biomes.iter().enumerate() {
        let name = b.name(i);
        if !terrasynth_core::names::is_valid_name(&name) {
            return Err(invalid(format!(
                "biomes[{i}].name `{name}` must be {}",
                terrasynth_core::names::NAME_RULE
            )));
        }
        if names.contains(&name) {
            return Err(invalid(format!("biomes[{i}].name `{name}` is used twice")));
        }
        if b.dictionary.zooms.is_some() {
            return Err(invalid(format!(
                "biomes[{i}].dictionary.zooms: a biome's dictionary amplifies every zoom"
            )));
        }
        names.push(name);
    }
    Ok(())
}

/// Checks that each dictionary table of world file `path` gives only the keys of its
/// `amplifier` (a gradient band with `atoms`, or a dictionary band with `tile`, is a mismatch)
/// and that a gradient band's parameters are valid.
fn check_amplifiers(w: &WorldConfig, text: &str, path: &str) -> Result<(), ConfigError> {
    let table = text.parse::<toml::Table>().unwrap_or_default();
    let raw: Vec<(String, Option<&toml::Table>, &DictionaryConfig)> = if !w.biomes.is_empty() {
        let list = table.get("biomes").and_then(toml::Value::as_array);
        w.biomes
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let t = list
                    .and_then(|l| l.get(i))
                    .and_then(|b| b.get("dictionary"))
                    .and_then(toml::Value::as_table);
                (format!("biomes[{i}].dictionary"), t, &b.dictionary)
            })
            .collect()
    } else if w.dictionaries.is_empty() {
        vec![(
            "dictionary".to_string(),
            table.get("dictionary").and_then(toml::Value::as_table),
            &w.dictionary,
        )]
    } else {
        let list = table.get("dictionaries").and_then(toml::Value::as_array);
        w.dictionaries
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let t = list.and_then(|l| l.get(i)).and_then(toml::Value::as_table);
                (format!("dictionaries[{i}]"), t, d)
            })
            .collect()
    };
    for (name, t, d) in raw {
        let (foreign, needs): (&[&str], &str) = match d.amplifier {
            AmplifierKind::Dictionary => (&GRADIENT_ONLY_KEYS, "amplifier = \"gradient\""),
            AmplifierKind::Gradient => (&DICTIONARY_ONLY_KEYS, "amplifier = \"dictionary\""),
        };
        if let Some(key) = foreign
            .iter()
            .find(|k| t.is_some_and(|t| t.contains_key(**k)))
        {
            return Err(ConfigError::Invalid(format!(
                "{path}: {name}.{key} does not apply to amplifier = \"{}\" (it belongs to {needs})",
                d.amplifier
            )));
        }
        if d.amplifier == AmplifierKind::Gradient {
            d.gradient_params()
                .map_err(|e| ConfigError::Invalid(format!("{path}: {name}: {e}")))?;
        }
    }
    Ok(())
}

/// The whole configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Server settings.
    pub server: ServerConfig,
    /// Worlds, in file order.
    pub worlds: Vec<WorldConfig>,
}

fn parse<T: for<'de> Deserialize<'de>>(text: &str, path: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError::Parse {
        path: path.to_string(),
        message: e.to_string(),
    })
}

fn read(path: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Parses the world file `text` (read from `path`, relative paths resolved in `dir`).
pub fn parse_world(text: &str, path: &str, dir: &Path) -> Result<WorldConfig, ConfigError> {
    let mut w: WorldConfig = parse(text, path)?;
    w.dir = dir.to_path_buf();
    if !terrasynth_core::names::is_valid_name(&w.name) {
        return Err(ConfigError::Invalid(format!(
            "{path}: world name `{}` must be {}",
            w.name,
            terrasynth_core::names::NAME_RULE
        )));
    }
    if w.center
        .is_some_and(|c| !terrasynth_core::raster::georef::is_map_point(c))
    {
        return Err(ConfigError::Invalid(format!(
            "{path}: center must be [lon, lat] with |lon| ≤ 180 and |lat| ≤ {}",
            terrasynth_core::raster::georef::MAX_MERCATOR_LAT
        )));
    }
    w.landscape
        .validate()
        .map_err(|e| ConfigError::Invalid(format!("{path}: {e}")))?;
    let class_names = match &w.classes {
        None => Vec::new(),
        Some(c) => {
            let cfg = c.config();
            cfg.validate()
                .map_err(|e| ConfigError::Invalid(format!("{path}: {e}")))?;
            cfg.names()
        }
    };
    w.landscape
        .check_classes(&class_names)
        .map_err(|e| ConfigError::Invalid(format!("{path}: {e}")))?;
    check_dictionaries(&w, text, path)?;
    check_biomes(&w, text, path)?;
    let biome_names: Vec<String> = w
        .biomes
        .iter()
        .enumerate()
        .map(|(i, b)| b.name(i))
        .collect();
    w.landscape
        .check_biomes(&biome_names)
        .map_err(|e| ConfigError::Invalid(format!("{path}: {e}")))?;
    check_amplifiers(&w, text, path)?;
    Ok(w)
}

/// Loads the configuration: `path` if given; else `config/default.toml` if it exists; else the
/// embedded defaults. Then applies `env` overrides (pass `std::env::vars()`).
pub fn load(
    path: Option<&Path>,
    env: impl IntoIterator<Item = (String, String)>,
) -> Result<Config, ConfigError> {
    let default_path = Path::new(DEFAULT_PATH);
    let (text, label, dir, embedded) = match path {
        Some(p) => (read(p)?, p.display().to_string(), parent_dir(p), false),
        None if default_path.exists() => (
            read(default_path)?,
            DEFAULT_PATH.to_string(),
            parent_dir(default_path),
            false,
        ),
        None => (
            DEFAULT_TOML.to_string(),
            "embedded default.toml".into(),
            PathBuf::from("."),
            true,
        ),
    };
    let mut server: ServerConfig = parse(&text, &label)?;
    apply_env(&mut server, env)?;
    let mut worlds = Vec::new();
    for file in &server.worlds {
        let p = dir.join(file);
        let world = if embedded || (!p.exists() && file == "worlds/tienshan.toml") {
            parse_world(TIENSHAN_TOML, "embedded worlds/tienshan.toml", &dir)?
        } else {
            parse_world(&read(&p)?, &p.display().to_string(), &parent_dir(&p))?
        };
        if worlds.iter().any(|w: &WorldConfig| w.name == world.name) {
            return Err(ConfigError::Invalid(format!(
                "world `{}` is defined twice",
                world.name
            )));
        }
        worlds.push(world);
    }
    validate(&server)?;
    Ok(Config { server, worlds })
}

fn parent_dir(p: &Path) -> PathBuf {
    p.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn validate(s: &ServerConfig) -> Result<(), ConfigError> {
    if s.listen.parse::<std::net::SocketAddr>().is_err() {
        return Err(ConfigError::Invalid(format!(
            "listen `{}` is not an address:port",
            s.listen
        )));
    }
    if s.synth_concurrency == 0 {
        return Err(ConfigError::Invalid("synth_concurrency must be ≥ 1".into()));
    }
    if s.build_workers == 0 || s.build_threads == 0 {
        return Err(ConfigError::Invalid(
            "build_workers and build_threads must be ≥ 1".into(),
        ));
    }
    if s.max_layers == 0 || s.max_pixels == 0 || s.max_dimension == 0 || s.max_body_mb == 0 {
        return Err(ConfigError::Invalid(
            "max_body_mb, max_pixels, max_dimension and max_layers must be ≥ 1".into(),
        ));
    }
    if s.request_timeout_s == 0 || s.upload_timeout_s == 0 {
        return Err(ConfigError::Invalid(
            "request_timeout_s and upload_timeout_s must be ≥ 1".into(),
        ));
    }
    if s.header_read_timeout_s == 0 || s.idle_timeout_s == 0 {
        return Err(ConfigError::Invalid(
            "header_read_timeout_s and idle_timeout_s must be ≥ 1".into(),
        ));
    }
    if s.max_connections == 0 || s.max_concurrent_uploads == 0 || s.upload_memory_mb == 0 {
        return Err(ConfigError::Invalid(
            "max_connections, max_concurrent_uploads and upload_memory_mb must be ≥ 1".into(),
        ));
    }
    if s.max_uri_bytes < 256 {
        return Err(ConfigError::Invalid(format!(
            "max_uri_bytes {} must be ≥ 256",
            s.max_uri_bytes
        )));
    }
    if s.auth_failures_per_minute == 0 {
        return Err(ConfigError::Invalid(
            "auth_failures_per_minute must be ≥ 1".into(),
        ));
    }
    check_public_url(&s.public_url)?;
    Ok(())
}

/// Checks `public_url`: empty, or `http(s)://host[:port][/path]` without query, fragment or
/// trailing slash.
pub fn check_public_url(url: &str) -> Result<(), ConfigError> {
    if url.is_empty() {
        return Ok(());
    }
    let bad = |why: &str| {
        Err(ConfigError::Invalid(format!(
            "public_url `{url}` {why} (expected http(s)://host[:port][/path], no trailing slash)"
        )))
    };
    let Ok(uri) = url.parse::<axum::http::Uri>() else {
        return bad("is not a URL");
    };
    if !matches!(uri.scheme_str(), Some("http" | "https")) {
        return bad("is not an http or https URL");
    }
    if uri
        .authority()
        .is_none_or(|a| a.host().is_empty() || a.as_str().contains('@'))
    {
        return bad("has no host (or carries credentials)");
    }
    if uri.query().is_some() || url.contains('#') {
        return bad("has a query or fragment");
    }
    if url.ends_with('/') {
        return bad("ends with a slash");
    }
    Ok(())
}

/// Applies `TERRASYNTH_<KEY>` overrides (`LISTEN`, `CACHE_MB`, `STORE_DIR`, `CORS_ORIGINS` as a
/// comma-separated list, `CACHE_CONTROL`, `SYNTH_CONCURRENCY`, `SYNTH_QUEUE`,
/// `REQUEST_TIMEOUT_S`, `UPLOAD_TIMEOUT_S`, `ADMIN_TOKEN`, `BUILD_WORKERS`, `BUILD_THREADS`, `BUILD_QUEUE`,
/// `MAX_BODY_MB`, `MAX_PIXELS`, `MAX_DIMENSION`, `MAX_LAYERS`, `WEB_VENDOR_DIR`, `PUBLIC_URL`,
/// `HEADER_READ_TIMEOUT_S`, `IDLE_TIMEOUT_S`, `MAX_CONNECTIONS`, `MAX_URI_BYTES`,
/// `UPLOAD_MEMORY_MB`, `MAX_CONCURRENT_UPLOADS`, `AUTH_FAILURES_PER_MINUTE`). Other
/// `TERRASYNTH_*` variables are ignored.
pub fn apply_env(
    s: &mut ServerConfig,
    env: impl IntoIterator<Item = (String, String)>,
) -> Result<(), ConfigError> {
    fn num<T: std::str::FromStr>(name: &str, v: &str) -> Result<T, ConfigError>
    where
        T::Err: std::fmt::Display,
    {
        v.trim().parse().map_err(|e: T::Err| ConfigError::Env {
            name: name.to_string(),
            message: e.to_string(),
        })
    }
    for (name, v) in env {
        let Some(key) = name.strip_prefix("TERRASYNTH_") else {
            continue;
        };
        match key {
            "LISTEN" => s.listen = v,
            "CACHE_MB" => s.cache_mb = num(&name, &v)?,
            "STORE_DIR" => s.store_dir = PathBuf::from(v),
            "WEB_VENDOR_DIR" => s.web_vendor_dir = PathBuf::from(v),
            "CORS_ORIGINS" => {
                s.cors_origins = v
                    .split(',')
                    .map(|o| o.trim().to_string())
                    .filter(|o| !o.is_empty())
                    .collect()
            }
            "CACHE_CONTROL" => s.cache_control = v,
            "SYNTH_CONCURRENCY" => s.synth_concurrency = num(&name, &v)?,
            "SYNTH_QUEUE" => s.synth_queue = num(&name, &v)?,
            "REQUEST_TIMEOUT_S" => s.request_timeout_s = num(&name, &v)?,
            "UPLOAD_TIMEOUT_S" => s.upload_timeout_s = num(&name, &v)?,
            "ADMIN_TOKEN" => s.admin_token = Secret(v.trim().to_string()),
            "BUILD_WORKERS" => s.build_workers = num(&name, &v)?,
            "BUILD_THREADS" => s.build_threads = num(&name, &v)?,
            "BUILD_QUEUE" => s.build_queue = num(&name, &v)?,
            "MAX_BODY_MB" => s.max_body_mb = num(&name, &v)?,
            "MAX_PIXELS" => s.max_pixels = num(&name, &v)?,
            "MAX_DIMENSION" => s.max_dimension = num(&name, &v)?,
            "MAX_LAYERS" => s.max_layers = num(&name, &v)?,
            "PUBLIC_URL" => s.public_url = v.trim().to_string(),
            "HEADER_READ_TIMEOUT_S" => s.header_read_timeout_s = num(&name, &v)?,
            "IDLE_TIMEOUT_S" => s.idle_timeout_s = num(&name, &v)?,
            "MAX_CONNECTIONS" => s.max_connections = num(&name, &v)?,
            "MAX_URI_BYTES" => s.max_uri_bytes = num(&name, &v)?,
            "UPLOAD_MEMORY_MB" => s.upload_memory_mb = num(&name, &v)?,
            "MAX_CONCURRENT_UPLOADS" => s.max_concurrent_uploads = num(&name, &v)?,
            "AUTH_FAILURES_PER_MINUTE" => s.auth_failures_per_minute = num(&name, &v)?,
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_defaults_parse_and_name_the_default_world() {
        let c = load(Some(Path::new("config/default.toml")), Vec::new()).unwrap();
        assert_eq!(c.server.listen, "127.0.0.1:8080");
        assert_eq!(c.server.cache_control, "public, max-age=86400");
        assert_eq!(c.worlds.len(), 1);
        assert_eq!(c.worlds[0].name, "tienshan");
        assert_eq!(c.worlds[0].z_base, Some(8));
        assert_eq!(c.worlds[0].max_zoom, 16);
        let embedded: ServerConfig = toml::from_str(DEFAULT_TOML).unwrap();
        assert_eq!(embedded, c.server);
    }

    #[test]
    fn cache_budget_is_split_and_never_exceeds_cache_mb() {
        let c = ServerConfig {
            cache_mb: 512,
            ..ServerConfig::default()
        };
        assert_eq!(c.encoded_cache_bytes(), 128 << 20);
        assert_eq!(c.level_cache_bytes(1), 384 << 20);
        assert_eq!(c.level_cache_bytes(3), 128 << 20);
        for worlds in 0..10 {
            let n = worlds.max(1) as u64;
            assert!(c.encoded_cache_bytes() + n * c.level_cache_bytes(worlds) <= 512 << 20);
        }
    }

    #[test]
    fn environment_overrides_the_file() {
        let env = vec![
            (
                "TERRASYNTH_LISTEN".to_string(),
                "127.0.0.1:9999".to_string(),
            ),
            ("TERRASYNTH_CACHE_MB".into(), "64".into()),
            (
                "TERRASYNTH_CORS_ORIGINS".into(),
                "https://a.example, https://b.example".into(),
            ),
            ("TERRASYNTH_UPLOAD_TIMEOUT_S".into(), "120".into()),
            ("UNRELATED".into(), "x".into()),
        ];
        let c = load(Some(Path::new("config/default.toml")), env).unwrap();
        assert_eq!(c.server.listen, "127.0.0.1:9999");
        assert_eq!(c.server.upload_timeout_s, 120);
        assert_eq!(c.server.request_timeout_s, 60);
        assert_eq!(c.server.cache_mb, 64);
        assert_eq!(
            c.server.cors_origins,
            vec!["https://a.example", "https://b.example"]
        );
        let bad = vec![("TERRASYNTH_CACHE_MB".to_string(), "lots".to_string())];
        assert!(matches!(
            load(Some(Path::new("config/default.toml")), bad),
            Err(ConfigError::Env { .. })
        ));
    }

    #[test]
    fn bad_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(&p, "listen = 5\n").unwrap();
        assert!(matches!(
            load(Some(&p), Vec::new()),
            Err(ConfigError::Parse { .. })
        ));
        std::fs::write(&p, "nonsense_key = 1\n").unwrap();
        assert!(matches!(
            load(Some(&p), Vec::new()),
            Err(ConfigError::Parse { .. })
        ));
        std::fs::write(&p, "listen = \"not an address\"\nworlds = []\n").unwrap();
        assert!(matches!(
            load(Some(&p), Vec::new()),
            Err(ConfigError::Invalid(_))
        ));
        std::fs::write(&p, "upload_timeout_s = 5\nworlds = []\n").unwrap();
        assert_eq!(
            load(Some(&p), Vec::new()).unwrap().server.upload_timeout_s,
            5
        );
        std::fs::write(&p, "upload_timeout_s = 0\nworlds = []\n").unwrap();
        assert!(matches!(
            load(Some(&p), Vec::new()),
            Err(ConfigError::Invalid(m)) if m.contains("upload_timeout_s")
        ));
        std::fs::write(&p, "worlds = [\"missing.toml\"]\n").unwrap();
        assert!(matches!(
            load(Some(&p), Vec::new()),
            Err(ConfigError::Io { .. })
        ));
        let w = "name = \"bad name!\"\nbase = \"x.tif\"\n";
        assert!(parse_world(w, "w.toml", dir.path()).is_err());
    }

    #[test]
    fn hardening_keys_are_read_overridden_and_validated() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(
            &p,
            "worlds = []\npublic_url = \"https://tiles.example.com/terrain\"\n\
             header_read_timeout_s = 5\nmax_connections = 64\n",
        )
        .unwrap();
        let env = vec![
            ("TERRASYNTH_IDLE_TIMEOUT_S".to_string(), "30".to_string()),
            ("TERRASYNTH_UPLOAD_MEMORY_MB".into(), "300".into()),
            ("TERRASYNTH_MAX_CONCURRENT_UPLOADS".into(), "3".into()),
            ("TERRASYNTH_AUTH_FAILURES_PER_MINUTE".into(), "4".into()),
            ("TERRASYNTH_MAX_URI_BYTES".into(), "4096".into()),
        ];
        let c = load(Some(&p), env).unwrap().server;
        assert_eq!(c.public_url, "https://tiles.example.com/terrain");
        assert_eq!((c.header_read_timeout_s, c.idle_timeout_s), (5, 30));
        assert_eq!((c.max_connections, c.max_uri_bytes), (64, 4096));
        assert_eq!((c.upload_memory_mb, c.max_concurrent_uploads), (300, 3));
        assert_eq!(c.auth_failures_per_minute, 4);
        for (line, key) in [
            ("public_url = \"ftp://x\"", "public_url"),
            ("public_url = \"https://x.example/\"", "public_url"),
            ("public_url = \"https://x.example/?a=1\"", "public_url"),
            ("public_url = \"tiles.example.com\"", "public_url"),
            ("header_read_timeout_s = 0", "header_read_timeout_s"),
            ("idle_timeout_s = 0", "idle_timeout_s"),
            ("max_connections = 0", "max_connections"),
            ("max_uri_bytes = 10", "max_uri_bytes"),
            ("upload_memory_mb = 0", "upload_memory_mb"),
            ("max_concurrent_uploads = 0", "max_concurrent_uploads"),
            ("auth_failures_per_minute = 0", "auth_failures_per_minute"),
        ] {
            std::fs::write(&p, format!("worlds = []\n{line}\n")).unwrap();
            assert!(
                matches!(load(Some(&p), Vec::new()), Err(ConfigError::Invalid(m)) if m.contains(key)),
                "{line}"
            );
        }
    }

    #[test]
    fn gradient_bands_parse_and_mismatched_keys_are_named() {
        let head = "name = \"w\"\nbase = \"b.tif\"\nz_base = 8\nmax_zoom = 16\n";
        let w = parse_world(
            &format!(
                "{head}[[dictionaries]]\nzooms = \"9-14\"\namplifier = \"gradient\"\ntile = 12\n\
                 colours = 6\nalternatives = 3\nmixing = 0.5\n\
                 [[dictionaries]]\nzooms = \"15-16\"\natoms = 32\n"
            ),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        let bands = w.dictionary_bands();
        assert_eq!(bands[0].1.amplifier, AmplifierKind::Gradient);
        assert_eq!(bands[1].1.amplifier, AmplifierKind::Dictionary);
        let p = bands[0].1.gradient_params().unwrap();
        assert_eq!(
            (p.tile, p.colours, p.alternatives, p.mixing, p.seed),
            (12, 6, 3, 0.5, 1)
        );
        // A single [dictionary] with the gradient amplifier and the defaults.
        let one = parse_world(
            &format!("{head}[dictionary]\namplifier = \"gradient\"\n"),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        assert_eq!(one.dictionary.gradient_params().unwrap().tile, 8);
        for (table, needle) in [
            (
                "[dictionary]\namplifier = \"gradient\"\natoms = 64\n",
                "dictionary.atoms does not apply to amplifier = \"gradient\"",
            ),
            (
                "[dictionary]\ntile = 8\n",
                "dictionary.tile does not apply to amplifier = \"dictionary\"",
            ),
            (
                "[[dictionaries]]\nzooms = \"9-16\"\namplifier = \"gradient\"\npatch = 8\n",
                "dictionaries[0].patch does not apply",
            ),
            (
                "[dictionary]\namplifier = \"gradient\"\ntile = 6\n",
                "dictionary: invalid dictionary parameters: tile 6 must be a multiple of 4",
            ),
            (
                "[dictionary]\namplifier = \"gradient\"\nmixing = 1.5\n",
                "mixing 1.5 must lie in [0, 1]",
            ),
            (
                "[dictionary]\namplifier = \"poisson\"\n",
                "unknown variant `poisson`",
            ),
        ] {
            let e = parse_world(&format!("{head}{table}"), "w.toml", Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle) && e.contains("w.toml"), "{table}: {e}");
        }
    }

    #[test]
    fn biomes_parse_and_bad_biomes_are_named() {
        let head = "name = \"w\"\nbase = \"b.tif\"\n";
        let w = parse_world(
            &format!(
                "{head}[[biomes]]\nname = \"alps\"\nweight = \"alps.tif\"\n\
                 dictionary = {{ atoms = 64 }}\n[[biomes]]\nweight = \"dry.tif\"\n\
                 [biomes.dictionary]\nexemplars = [\"dry.tif\"]\n"
            ),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        assert_eq!(w.biomes.len(), 2);
        assert_eq!(
            (w.biomes[0].name(0), w.biomes[1].name(1)),
            ("alps".into(), "biome1".into())
        );
        assert_eq!(w.biomes[0].dictionary.atoms, 64);
        assert_eq!(w.biomes[0].weight, "alps.tif");
        assert_eq!(
            w.biomes[1].dictionary.exemplars,
            vec!["dry.tif".to_string()]
        );
        assert_eq!(
            w.biomes[1].dictionary.atoms,
            DictionaryConfig::default().atoms
        );
        for (tables, needle) in [
            (
                "[dictionary]\natoms = 8\n[[biomes]]\nweight = \"a.tif\"\n",
                "either [[biomes]] or [dictionary]/[[dictionaries]]",
            ),
            (
                "[[dictionaries]]\nzooms = \"9-12\"\n[[biomes]]\nweight = \"a.tif\"\n",
                "either [[biomes]] or [dictionary]/[[dictionaries]]",
            ),
            (
                "[[biomes]]\nname = \"a\"\nweight = \"a.tif\"\n[[biomes]]\nname = \"a\"\nweight = \"b.tif\"\n",
                "biomes[1].name `a` is used twice",
            ),
            ("[[biomes]]\nname = \"a b\"\nweight = \"a.tif\"\n", "biomes[0].name `a b`"),
            (
                "[[biomes]]\nweight = \"a.tif\"\ndictionary = { zooms = \"9\" }\n",
                "biomes[0].dictionary.zooms",
            ),
            (
                "[[biomes]]\nweight = \"a.tif\"\ndictionary = { tile = 12 }\n",
                "biomes[0].dictionary.tile does not apply",
            ),
            ("[[biomes]]\nname = \"a\"\n", "weight"),
            ("[[biomes]]\nweight = \"a.tif\"\nlayer = \"x\"\n", "unknown field `layer`"),
            (
                "[[biomes]]\nname = \"alps\"\nweight = \"a.tif\"\n[landscape]\n\
                 [[landscape.materials]]\nname = \"sand\"\ncolour = [0, 0, 0]\n\
                 biome.desert = { min = 0.5, max = 1 }\n",
                "material sand names unknown biome `desert` (its biomes are alps)",
            ),
        ] {
            let e = parse_world(&format!("{head}{tables}"), "w.toml", Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle) && e.contains("w.toml"), "{tables}: {e}");
        }
    }

    #[test]
    fn species_controls_parse_and_bad_modes_are_named() {
        let head = "name = \"w\"\nbase = \"b.tif\"\n";
        let w = parse_world(
            &format!(
                "{head}[[controls]]\nspecies = \"spruce\"\nraster = \"drawn.tif\"\nmode = \"scale\"\n"
            ),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        assert_eq!(
            w.controls,
            vec![ControlFile {
                species: "spruce".into(),
                raster: "drawn.tif".into(),
                mode: terrasynth_tiles::ControlMode::Scale,
            }]
        );
        for (table, needle) in [
            (
                "[[controls]]\nspecies = \"spruce\"\nraster = \"d.tif\"\nmode = \"double\"\n",
                "unknown variant `double`",
            ),
            (
                "[[controls]]\nspecies = \"spruce\"\nraster = \"d.tif\"\n",
                "mode",
            ),
        ] {
            let e = parse_world(&format!("{head}{table}"), "w.toml", Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle) && e.contains("w.toml"), "{table}: {e}");
        }
    }

    #[test]
    fn dictionaries_per_zoom_band_parse_and_bad_bands_are_named() {
        let head = "name = \"w\"\nbase = \"b.tif\"\nz_base = 8\nmax_zoom = 16\n";
        let w = parse_world(
            &format!(
                "{head}[[dictionaries]]\nzooms = \"9-14\"\natoms = 64\n\
                 [[dictionaries]]\nzooms = \"15-16\"\nexemplars = [\"fine.tif\"]\npatch = 8\n"
            ),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        let bands = w.dictionary_bands();
        assert_eq!(bands.len(), 2);
        assert_eq!(bands[0].0, Some(ZoomBand { first: 9, last: 14 }));
        assert_eq!(bands[0].1.atoms, 64);
        assert_eq!(bands[0].1.exemplars, vec![EMBEDDED_TIENSHAN.to_string()]);
        assert_eq!(
            bands[1].0,
            Some(ZoomBand {
                first: 15,
                last: 16
            })
        );
        assert_eq!(bands[1].1.exemplars, vec!["fine.tif".to_string()]);
        assert_eq!(bands[1].1.patch, 8);
        // One [dictionary]: one band over every amplified zoom, as before.
        let one = parse_world(
            &format!("{head}[dictionary]\natoms = 32\n"),
            "w.toml",
            Path::new("."),
        )
        .unwrap();
        let bands = one.dictionary_bands();
        assert_eq!(bands.len(), 1);
        assert_eq!((bands[0].0, bands[0].1.atoms), (None, 32));
        for (tables, needle) in [
            (
                "[[dictionaries]]\nzooms = \"9-x\"\n",
                "dictionaries[0].zooms: zooms `9-x`",
            ),
            (
                "[[dictionaries]]\nzooms = \"9-12\"\n[[dictionaries]]\natoms = 8\n",
                "dictionaries[1].zooms is missing",
            ),
            (
                "[[dictionaries]]\nzooms = \"9-12\"\n[[dictionaries]]\nzooms = \"12-16\"\n",
                "zooms 9-12 and 12-16 overlap",
            ),
            (
                "[[dictionaries]]\nzooms = \"8-12\"\n",
                "outside the amplified zooms 9-16",
            ),
            (
                "[[dictionaries]]\nzooms = \"9-17\"\n",
                "outside the amplified zooms 9-16",
            ),
            (
                "[dictionary]\natoms = 8\n[[dictionaries]]\nzooms = \"9-12\"\n",
                "either [dictionary] or [[dictionaries]]",
            ),
            ("[dictionary]\nzooms = \"9-12\"\n", "dictionary.zooms"),
        ] {
            let e = parse_world(&format!("{head}{tables}"), "w.toml", Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle) && e.contains("w.toml"), "{tables}: {e}");
        }
    }
}
