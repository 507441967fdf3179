//! The `terrasynth` command: parses arguments and calls the library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use terrasynth::cli::export::{self, ArchiveFormat, Shard, TileFormat};
use terrasynth::cli::{amplify, build, compact, crop, eval, features, gradient, sketch, CliError};
use terrasynth::config::ConfigError;
use terrasynth::server::StartupError;
use terrasynth_core::dictionary::analytic::AnalyticKind;
use terrasynth_core::dictionary::build::BuildOptions;
use terrasynth_core::dictionary::{Learning, MatchWeights, PixelWindow};

#[derive(Parser)]
#[command(
    name = "terrasynth",
    version,
    about = "Synthesized terrain: amplify DEMs with dictionaries learned from real terrain"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Dictionaries of exemplar patches.
    #[command(subcommand)]
    Dictionary(DictionaryCommand),
    /// Amplify a DEM by N ×2 levels.
    Amplify(AmplifyCli),
    /// Print JSON metrics of an amplified DEM against the truth, with bicubic and fBm baselines.
    Eval(EvalCli),
    /// Cut a window out of a GeoTIFF, optionally box-down-sampling it.
    Crop(CropCli),
    /// Write a DEM as a compact terrain (.sct): a sparse construction tree over dictionary atoms.
    Compress(CompressCli),
    /// Decode a compact terrain (.sct) into a float32 GeoTIFF.
    Decompress(DecompressCli),
    /// Extract ridges and valleys (PPA) of a DEM as GeoJSON.
    Features(FeaturesCli),
    /// Synthesize a base terrain from a sketch of ridge and valley lines and exemplar DEMs.
    Sketch(SketchCli),
    /// Write a world's tiles over a bounding box to PMTiles or MBTiles archives (one per layer);
    /// `export merge` joins the parts of a sharded export.
    Export(ExportCli),
    /// Serve tiles over HTTP (the default command).
    Serve(ServeCli),
    /// Print the OpenAPI 3.1 description of the HTTP API (as committed in openapi/openapi.json).
    Openapi,
}

#[derive(Args, Default)]
struct ServeCli {
    /// Configuration file (default: config/default.toml, else the embedded defaults).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Address and port to listen on (overrides the configuration).
    #[arg(long, value_name = "ADDR")]
    listen: Option<String>,
}

#[derive(Subcommand)]
enum DictionaryCommand {
    /// Build a dictionary from exemplar DEMs.
    Build(BuildCli),
}

#[derive(Args)]
struct BuildCli {
    /// Exemplar DEM (GeoTIFF); repeat for several.
    #[arg(long = "exemplar", value_name = "FILE")]
    exemplars: Vec<PathBuf>,
    /// Use the embedded Tien Shan exemplar.
    #[arg(long)]
    default: bool,
    /// Extra layer on the exemplar's grid, NAME=FILE; repeat for several.
    #[arg(long = "layer", value_name = "NAME=FILE", value_parser = parse_layer)]
    layers: Vec<(String, PathBuf)>,
    /// Output dictionary file.
    #[arg(long, value_name = "DICT")]
    output: PathBuf,
    /// Number of atoms (0 = every patch).
    #[arg(long, default_value_t = BuildOptions::default().atoms)]
    atoms: usize,
    /// High-resolution patch side in exemplar cells (multiple of 4).
    #[arg(long, default_value_t = BuildOptions::default().patch)]
    patch: usize,
    /// Step between patches, exemplar cells.
    #[arg(long, default_value_t = BuildOptions::default().stride)]
    stride: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = BuildOptions::default().seed)]
    seed: u64,
    /// Atom selection: `complete`, `medoids[:ITERATIONS]` or `ksvd[:ITERATIONS]`.
    #[arg(long, default_value = "medoids")]
    learning: Learning,
    /// Atoms per code while learning with K-SVD.
    #[arg(long, default_value_t = 1)]
    sparsity: usize,
    /// Keep a window COL,ROW,WIDTH,HEIGHT of the exemplar out of the dictionary; repeatable.
    #[arg(long, value_name = "COL,ROW,WIDTH,HEIGHT")]
    exclude: Vec<PixelWindow>,
    /// Do not add the derived layers (log_area, northness).
    #[arg(long)]
    no_derived: bool,
    /// What to build: `dictionary` (patch atoms) or `gradient` (a gradient tile set, issue #20).
    #[arg(long, value_enum, default_value_t = BuildKind::Dictionary)]
    kind: BuildKind,
    /// Gradient tile side in child pixels (`--kind gradient`; multiple of 4, 4–16).
    #[arg(long, default_value_t = terrasynth_core::dictionary::GradientParams::default().tile)]
    tile: usize,
    /// Edge colours per layer (`--kind gradient`; 2–16).
    #[arg(long, default_value_t = terrasynth_core::dictionary::GradientParams::default().colours)]
    colours: usize,
    /// Alternatives per colour combination (`--kind gradient`; 1–64).
    #[arg(long, default_value_t = terrasynth_core::dictionary::GradientParams::default().alternatives)]
    alternatives: usize,
    /// Exemplar mixing in [0, 1] (`--kind gradient`).
    #[arg(long, default_value_t = terrasynth_core::dictionary::GradientParams::default().mixing)]
    mixing: f32,
}

/// What `dictionary build` builds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum BuildKind {
    /// A dictionary of patch atoms.
    Dictionary,
    /// A gradient tile set.
    Gradient,
}

#[derive(Args)]
struct CompressCli {
    /// Dictionary whose atoms write the terrain.
    #[arg(long, value_name = "DICT")]
    dictionary: Option<PathBuf>,
    /// Procedural atoms (`perlin` or `ridged`) added to the dictionary's, or used alone.
    #[arg(long, value_name = "KIND")]
    analytic: Option<AnalyticKind>,
    /// How many procedural atoms.
    #[arg(long, default_value_t = 256)]
    analytic_atoms: usize,
    /// Atom side without a dictionary (even).
    #[arg(long, default_value_t = 16)]
    patch: usize,
    /// The DEM (GeoTIFF, PNG16 or EXR).
    #[arg(long, value_name = "DEM")]
    input: PathBuf,
    /// Atoms per primitive.
    #[arg(long, default_value_t = 1)]
    sparsity: usize,
    /// Coefficient quantum, metres per unit-norm atom (default: half a metre per patch side).
    #[arg(long)]
    coef_quantum: Option<f32>,
    /// Joint refinement passes after the first fit (each refits every primitive to what the
    /// others leave).
    #[arg(long, default_value_t = 3)]
    passes: usize,
    /// The compact terrain to write.
    #[arg(long, value_name = "OUT.sct")]
    output: PathBuf,
}

#[derive(Args)]
struct DecompressCli {
    /// The compact terrain.
    #[arg(long, value_name = "IN.sct")]
    input: PathBuf,
    /// The GeoTIFF to write.
    #[arg(long, value_name = "OUT.tif")]
    output: PathBuf,
}

#[derive(Args)]
struct AmplifyCli {
    /// Dictionary file.
    #[arg(long, value_name = "DICT")]
    dictionary: PathBuf,
    /// Low-resolution DEM (GeoTIFF).
    #[arg(long, value_name = "LOW.tif")]
    input: PathBuf,
    /// Number of ×2 levels.
    #[arg(long, default_value_t = 1)]
    levels: u32,
    /// Output GeoTIFF (extra layers are written to OUT.<layer>.tif).
    #[arg(long, value_name = "OUT.tif")]
    output: PathBuf,
    /// Matching weights, e.g. `elevation=0.8,altitude=0.1,slope=0.1`.
    #[arg(long, value_parser = amplify::parse_weights)]
    weights: Option<MatchWeights>,
    /// Amplifier levers for ablations (see `synth::Levers::parse`; default: the served amplifier).
    #[arg(long, hide = true, value_parser = terrasynth_core::synth::Levers::parse)]
    levers: Option<terrasynth_core::synth::Levers>,
    /// Atoms per primitive: the matcher's atom plus OMP on the rest of the parent patch
    /// (1–8; default: the dictionary's own sparsity, at least 2; 1: one atom).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8))]
    sparsity: Option<u32>,
}

#[derive(Args)]
struct EvalCli {
    /// The real high-resolution terrain.
    #[arg(long, value_name = "TRUTH.tif")]
    truth: PathBuf,
    /// The low-resolution input that was amplified.
    #[arg(long, value_name = "LOW.tif")]
    input: PathBuf,
    /// The amplified result.
    #[arg(long, value_name = "OUT.tif")]
    output: PathBuf,
    /// Also write hillshades of truth, bicubic, bicubic + fBm and output side by side to FILE.
    #[arg(long, value_name = "FILE.png")]
    picture: Option<PathBuf>,
}

#[derive(Args)]
struct CropCli {
    /// Input GeoTIFF.
    #[arg(long)]
    input: PathBuf,
    /// Window COL,ROW,WIDTH,HEIGHT in input cells.
    #[arg(long)]
    window: PixelWindow,
    /// Box down-sampling factor after cropping.
    #[arg(long, default_value_t = 1)]
    down: usize,
    /// Resample the window to square cells first (Lanczos-3 along its finer axis, as dictionary
    /// builds do with exemplars on longitude/latitude grids), cut to a multiple of 8 cells.
    #[arg(long)]
    square: bool,
    /// Output GeoTIFF.
    #[arg(long)]
    output: PathBuf,
}

#[derive(Args)]
struct FeaturesCli {
    /// Input DEM (GeoTIFF).
    #[arg(long, value_name = "DEM.tif")]
    input: PathBuf,
    /// Output GeoJSON.
    #[arg(long, value_name = "F.geojson")]
    output: PathBuf,
    /// Which features to write.
    #[arg(long, value_enum, default_value = "all")]
    kind: features::Kinds,
    /// Also print how well they agree with D8 drainage (valleys on channels of 10 km² and
    /// more, ridges between basins), as JSON.
    #[arg(long)]
    check: bool,
}

#[derive(Args)]
struct SketchCli {
    /// Exemplar DEM (GeoTIFF); repeat for several.
    #[arg(long = "exemplar", value_name = "DEM.tif", required = true)]
    exemplars: Vec<PathBuf>,
    /// The sketch: GeoJSON LineStrings with `kind` (`ridge` or `valley`) and optional
    /// `height_m`.
    #[arg(long, value_name = "S.geojson")]
    sketch: PathBuf,
    /// Bounds of the world to make, degrees: W,S,E,N.
    #[arg(long, value_name = "W,S,E,N", value_parser = sketch::parse_bounds, allow_hyphen_values = true)]
    bounds: [f64; 4],
    /// Cell size, degrees.
    #[arg(long, value_name = "DEG")]
    cell_size: f64,
    /// Output GeoTIFF (float32, EPSG:4326).
    #[arg(long, value_name = "BASE.tif")]
    output: PathBuf,
    /// Seed of the random choices.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct ExportCli {
    #[command(subcommand)]
    command: Option<ExportCommand>,
    /// The world (a configured world or one created through the admin API in the store).
    #[arg(long, required = true)]
    world: Option<String>,
    /// Bounding box W,S,E,N in degrees.
    #[arg(long, value_name = "W,S,E,N", value_parser = export::parse_bbox, allow_hyphen_values = true, required = true)]
    bbox: Option<[f64; 4]>,
    /// Zooms, `FIRST-LAST` (e.g. `0-14`) or one zoom.
    #[arg(long, value_name = "A-B", value_parser = export::parse_zooms, required = true)]
    zooms: Option<(u8, u8)>,
    /// Layers, comma-separated (e.g. `elevation,color`); several layers write one archive each,
    /// named FILE with `-LAYER` before the extension.
    #[arg(long, value_delimiter = ',', required = true)]
    layers: Vec<String>,
    /// Archive format.
    #[arg(long, value_enum, required = true)]
    format: Option<ArchiveFormat>,
    /// The archive to write.
    #[arg(long, value_name = "FILE", required = true)]
    output: Option<PathBuf>,
    /// Tile format (as served at `{y}.png`, `{y}.webp`, or `{y}.mvt` gzip-compressed for the
    /// vector layers `instances` and `contours`).
    #[arg(long, value_enum, default_value = "png")]
    tile_format: TileFormat,
    /// Write only part I of N (numbered from 1) of the tiles; `export merge` joins the parts.
    #[arg(long, value_name = "I/N")]
    shard: Option<Shard>,
    /// Configuration file (as for `serve`; the same `TERRASYNTH_*` variables apply).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Largest PMTiles root directory, bytes (smaller values force leaf directories; tests).
    #[arg(long, hide = true, default_value_t = 16_384 - 127)]
    max_root_bytes: usize,
}

#[derive(Subcommand)]
enum ExportCommand {
    /// Join the parts of a sharded export (all PMTiles or all MBTiles) into one archive.
    Merge(MergeCli),
}

#[derive(Args)]
struct MergeCli {
    /// The archive to write.
    #[arg(long, value_name = "FILE")]
    output: PathBuf,
    /// The parts, in any order.
    #[arg(value_name = "PART", required = true)]
    parts: Vec<PathBuf>,
}

fn run_export(a: ExportCli) -> Result<(), Failure> {
    if let Some(ExportCommand::Merge(m)) = a.command {
        let s = export::merge(&m.parts, &m.output).map_err(CliError::from)?;
        eprintln!(
            "merged {} parts into {}: {} tiles ({} distinct), {} bytes",
            m.parts.len(),
            m.output.display(),
            s.tiles,
            s.unique,
            s.bytes
        );
        return Ok(());
    }
    let missing = |what: &str| CliError::Usage(format!("export needs --{what}"));
    let name = a.world.ok_or_else(|| missing("world"))?;
    let args = export::ExportArgs {
        bbox: a.bbox.ok_or_else(|| missing("bbox"))?,
        zooms: a.zooms.ok_or_else(|| missing("zooms"))?,
        layers: a.layers,
        format: a.format.ok_or_else(|| missing("format"))?,
        output: a.output.ok_or_else(|| missing("output"))?,
        tile_format: a.tile_format,
        shard: a.shard,
        max_root_bytes: a.max_root_bytes,
    };
    let config = terrasynth::config::load(a.config.as_deref(), std::env::vars())?;
    eprintln!("loading world `{name}`…");
    let state = terrasynth::server::startup::build_state(&config)?;
    let world = state.live.get(&name).ok_or_else(|| {
        let known: Vec<String> = state.live.snapshot().keys().cloned().collect();
        CliError::Usage(format!("no world `{name}` (known: {})", known.join(", ")))
    })?;
    // Landscape layers start from the whole-world layers: read them from the store when an
    // earlier run (a server, another shard) stored them, else compute and store them once.
    let whole_world = |l: &String| !matches!(l.as_str(), "elevation" | "hillshade" | "contours");
    if args.layers.iter().any(whole_world) {
        terrasynth::server::worlds::prepare_landscape(&world, state.store().as_ref());
    }
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{spinner} {pos}/{len} tiles [{bar:40}] {per_sec} ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let summary = export::run(&world, &args, &mut |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    let s = summary?;
    for a in &s.archives {
        eprintln!(
            "wrote {}: {} tiles ({} distinct), {} bytes",
            a.path, a.tiles, a.unique, a.bytes
        );
    }
    eprintln!(
        "exported {} tiles in {:.1} s: {:.1} tiles/s",
        s.tiles, s.seconds, s.tiles_per_second
    );
    let json = serde_json::to_string_pretty(&s).map_err(|e| CliError::Usage(e.to_string()))?;
    println!("{json}");
    Ok(())
}

fn progress_bar() -> ProgressBar {
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg:>16} [{bar:40}] {percent:>3}% {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Shows a staged run's progress on a [`progress_bar`]: the stage's name and its fraction done.
fn show_stage(bar: &ProgressBar, stage: &str, fraction: f64) {
    bar.set_message(stage.to_string());
    bar.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
}

fn run_sketch(a: SketchCli) -> Result<(), CliError> {
    let bar = progress_bar();
    let summary = sketch::run(
        &sketch::SketchArgs {
            exemplars: a.exemplars,
            sketch: a.sketch,
            bounds: a.bounds,
            cell_size: a.cell_size,
            output: a.output.clone(),
            seed: a.seed,
        },
        &mut |stage, fraction| show_stage(&bar, stage, fraction),
    );
    bar.finish_and_clear();
    let summary = summary?;
    eprintln!(
        "wrote {} ({}×{}) in {:.1} s",
        a.output.display(),
        summary.width,
        summary.height,
        summary.seconds
    );
    let json =
        serde_json::to_string_pretty(&summary).map_err(|e| CliError::Usage(e.to_string()))?;
    println!("{json}");
    Ok(())
}

fn parse_layer(s: &str) -> Result<(String, PathBuf), String> {
    let (name, file) = s
        .split_once('=')
        .ok_or_else(|| format!("`{s}`: expected NAME=FILE"))?;
    Ok((name.to_string(), PathBuf::from(file)))
}

fn run_build(args: BuildCli) -> Result<(), CliError> {
    if args.kind == BuildKind::Gradient {
        return run_gradient_build(args);
    }
    let bar = progress_bar();
    let build_args = build::BuildArgs {
        exemplars: args.exemplars,
        default_exemplar: args.default,
        layers: args.layers,
        exclude: args.exclude,
        options: BuildOptions {
            patch: args.patch,
            stride: args.stride,
            atoms: args.atoms,
            learning: args.learning,
            seed: args.seed,
            sparsity: args.sparsity,
        },
        no_derived: args.no_derived,
    };
    let summary = build::run(&build_args, &args.output, &mut |stage, fraction| {
        show_stage(&bar, stage, fraction)
    });
    bar.finish_and_clear();
    let summary = summary?;
    println!(
        "built {}: {} atoms, layers [{}], {:.1} s, {} bytes, id {}",
        args.output.display(),
        summary.atoms,
        summary.layers.join(", "),
        summary.seconds,
        summary.bytes,
        &summary.id[..16.min(summary.id.len())]
    );
    Ok(())
}

fn run_gradient_build(args: BuildCli) -> Result<(), CliError> {
    if !args.layers.is_empty() {
        return Err(CliError::Usage(
            "--layer is not used by --kind gradient (tile sets hold elevation gradients only)"
                .into(),
        ));
    }
    let gradient_args = gradient::GradientBuildArgs {
        exemplars: args.exemplars,
        default_exemplar: args.default,
        exclude: args.exclude,
        params: terrasynth_core::dictionary::GradientParams {
            tile: args.tile,
            colours: args.colours,
            alternatives: args.alternatives,
            mixing: args.mixing,
            seed: args.seed,
        },
    };
    let s = gradient::run(&gradient_args, &args.output)?;
    println!(
        "built gradient tile set {}: {}/{} colour combinations found, {:.1} s, {} bytes, id {}",
        args.output.display(),
        s.combinations_found,
        s.combinations,
        s.seconds,
        s.bytes,
        &s.id[..16.min(s.id.len())]
    );
    Ok(())
}

/// Why a command failed.
#[derive(Debug, thiserror::Error)]
enum Failure {
    /// A command-line command failed.
    #[error(transparent)]
    Cli(#[from] CliError),
    /// The configuration could not be loaded.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The server could not start or stopped on an error.
    #[error(transparent)]
    Serve(#[from] StartupError),
}

fn run_serve(args: ServeCli) -> Result<(), Failure> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,tower_http=warn")),
        )
        // Colour codes only on a terminal: log files and journald get plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stdout()))
        .init();
    let mut config = terrasynth::config::load(args.config.as_deref(), std::env::vars())?;
    if let Some(listen) = args.listen {
        config.server.listen = listen;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| StartupError::Runtime(format!("cannot start the runtime: {e}")))?;
    Ok(runtime.block_on(terrasynth::server::serve(config))?)
}

fn run(cli: Cli) -> Result<(), Failure> {
    let command = cli.command.unwrap_or(Command::Serve(ServeCli::default()));
    match command {
        Command::Serve(args) => run_serve(args),
        Command::Export(args) => run_export(args),
        Command::Openapi => {
            print!("{}", terrasynth::server::openapi::spec_json());
            Ok(())
        }
        Command::Dictionary(DictionaryCommand::Build(args)) => Ok(run_build(args)?),
        Command::Amplify(a) => {
            let s = amplify::run(&amplify::AmplifyArgs {
                dictionary: a.dictionary,
                input: a.input,
                levels: a.levels,
                output: a.output,
                weights: a.weights.unwrap_or_default(),
                levers: {
                    let mut l = a.levers.unwrap_or_default();
                    if let Some(s) = a.sparsity {
                        l.sparsity = s;
                    }
                    l
                },
            })?;
            println!(
                "amplified to {}×{} in {:.2} s: {}",
                s.width,
                s.height,
                s.seconds,
                s.files.join(", ")
            );
            Ok(())
        }
        Command::Eval(a) => {
            let report = eval::run(&eval::EvalArgs {
                truth: a.truth,
                input: a.input,
                output: a.output,
                picture: a.picture,
            })?;
            let json = serde_json::to_string_pretty(&report)
                .map_err(|e| CliError::Usage(e.to_string()))?;
            println!("{json}");
            Ok(())
        }
        Command::Compress(a) => {
            let s = compact::run_compress(&compact::CompressArgs {
                dictionary: a.dictionary,
                analytic: a.analytic,
                analytic_atoms: a.analytic_atoms,
                patch: a.patch,
                input: a.input,
                sparsity: a.sparsity,
                coef_quantum: a.coef_quantum,
                passes: a.passes,
                output: a.output,
            })?;
            let json =
                serde_json::to_string_pretty(&s).map_err(|e| CliError::Usage(e.to_string()))?;
            println!("{json}");
            Ok(())
        }
        Command::Decompress(a) => {
            let g = compact::run_decompress(&a.input, &a.output)?;
            println!("wrote {} ({}×{})", a.output.display(), g.cols(), g.rows());
            Ok(())
        }
        Command::Features(a) => {
            let s = features::run(&features::FeaturesArgs {
                input: a.input,
                output: a.output.clone(),
                kinds: a.kind,
                check: a.check,
            })?;
            eprintln!(
                "wrote {}: {} ridge and {} valley lines",
                a.output.display(),
                s.ridge_paths,
                s.valley_paths
            );
            if let Some(d) = s.drainage {
                let json =
                    serde_json::to_string_pretty(&d).map_err(|e| CliError::Usage(e.to_string()))?;
                println!("{json}");
            }
            Ok(())
        }
        Command::Sketch(a) => Ok(run_sketch(a)?),
        Command::Crop(a) => {
            let g = crop::run(&crop::CropArgs {
                input: a.input,
                window: a.window,
                down: a.down,
                square: a.square,
                output: a.output.clone(),
            })?;
            println!("wrote {} ({}×{})", a.output.display(), g.cols(), g.rows());
            Ok(())
        }
    }
}

/// jemalloc serves every allocation: the cold path's transient grids (routing regions, halos)
/// are reused from its arenas instead of being mapped and faulted in afresh, at the same peak RSS
/// as glibc malloc with a 512 KiB mmap threshold (README, *The allocator*).
#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static GLOBAL: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("terrasynth: {e}");
            ExitCode::FAILURE
        }
    }
}
