//! `terrasynth export`: a world's tiles over a bounding box and a range of zooms written to
//! PMTiles v3 ([`pmtiles`]) or MBTiles 1.3 ([`mbtiles`]) archives, one archive per layer (an
//! archive holds one tile type), and `export merge`, which joins the parts a sharded export
//! (`--shard I/N`) wrote.
//!
//! Tiles are produced by the tiles crate's [`render`](fn@terrasynth_tiles::render) from requests parsed by [`parse_request`]
//! from the same path the server serves (`{layer}/{z}/{x}/{y}.{ext}` without query), so an
//! exported tile is byte-identical to the served one (vector tiles, `--tile-format mvt`: to the
//! gzip-coded one the server sends a client that accepts gzip, [`terrasynth_tiles::gzip`]). Tiles are rendered in parallel in chunks
//! (on plain threads, `on_threads`; their kernels use rayon's pool) and written in PMTiles
//! tile-id (Hilbert) order; shard `I` of `N` takes the `I`-th of `N` equal consecutive slices of
//! that order, so that a merge is a concatenation. Archives are
//! written under a temporary name (`.NAME.tmp-PID` beside the output) and renamed when complete:
//! an interrupted export leaves nothing that looks like a finished archive, and the next export
//! to the same name removes the temporary files of exports whose process no longer runs.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde::Serialize;
use sha2::{Digest, Sha256};

use terrasynth_tiles::style::{self, tilejson_of};
use terrasynth_tiles::{
    check_against_world, gzip, parse_request, render, tile_range_for_bounds, TileRequest, World,
};

use super::CliError;
use crate::archive::{mbtiles, pmtiles};
pub use crate::archive::{merge, ArchiveFormat, TileFormat};

/// Shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which part, `1..=count`.
    pub index: u32,
    /// How many parts.
    pub count: u32,
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Shard, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("`{s}`: expected I/N, e.g. 1/4"))?;
        let index: u32 = i
            .trim()
            .parse()
            .map_err(|_| format!("`{i}` is not a number"))?;
        let count: u32 = n
            .trim()
            .parse()
            .map_err(|_| format!("`{n}` is not a number"))?;
        if count == 0 || index == 0 || index > count {
            return Err(format!(
                "shard `{s}`: I must lie in 1..=N (shards are numbered from 1)"
            ));
        }
        Ok(Shard { index, count })
    }
}

/// A bounding box `W,S,E,N` in degrees.
pub fn parse_bbox(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{s}`: expected four numbers W,S,E,N"))?;
    let [w, so, e, n] = v[..] else {
        return Err(format!("`{s}`: expected four numbers W,S,E,N"));
    };
    if !(-180.0..=180.0).contains(&w) || !(-180.0..=180.0).contains(&e) || w >= e {
        return Err(format!(
            "`{s}`: west and east must lie in [-180, 180] with west < east"
        ));
    }
    if !(-90.0..=90.0).contains(&so) || !(-90.0..=90.0).contains(&n) || so >= n {
        return Err(format!(
            "`{s}`: south and north must lie in [-90, 90] with south < north"
        ));
    }
    Ok([w, so, e, n])
}

/// A zoom range `A-B` (or one zoom `A`).
pub fn parse_zooms(s: &str) -> Result<(u8, u8), String> {
    let (a, b) = s.split_once('-').unwrap_or((s, s));
    let z = |v: &str| {
        v.trim()
            .parse::<u8>()
            .map_err(|_| format!("`{v}` is not a zoom"))
    };
    let (a, b) = (z(a)?, z(b)?);
    if a > b {
        return Err(format!("zooms `{s}`: the first must not exceed the last"));
    }
    Ok((a, b))
}

/// Arguments of `export`.
#[derive(Clone, Debug)]
pub struct ExportArgs {
    /// `[W, S, E, N]`, degrees.
    pub bbox: [f64; 4],
    /// First and last zoom.
    pub zooms: (u8, u8),
    /// Layers, one archive each.
    pub layers: Vec<String>,
    /// Archive format.
    pub format: ArchiveFormat,
    /// The archive (with several layers: the layer's name is inserted before the extension).
    pub output: PathBuf,
    /// Tile format.
    pub tile_format: TileFormat,
    /// Only this part of the tiles.
    pub shard: Option<Shard>,
    /// Largest PMTiles root directory in bytes (16 KiB less the header; smaller values force
    /// leaf directories, for tests).
    pub max_root_bytes: usize,
}

/// One archive written.
#[derive(Clone, Debug, Serialize)]
pub struct ArchiveSummary {
    /// Layer.
    pub layer: String,
    /// Path.
    pub path: String,
    /// Tiles in the archive.
    pub tiles: u64,
    /// Distinct tile contents.
    pub unique: u64,
    /// Archive size in bytes.
    pub bytes: u64,
}

/// What an export did.
#[derive(Clone, Debug, Serialize)]
pub struct ExportSummary {
    /// Archives written.
    pub archives: Vec<ArchiveSummary>,
    /// Tiles rendered (all layers).
    pub tiles: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Tiles per second.
    pub tiles_per_second: f64,
}

/// The archive of `layer`: `output` itself for a one-layer export, else `output` with `-LAYER`
/// inserted before its extension (`talas.pmtiles` → `talas-elevation.pmtiles`).
pub fn layer_output(output: &Path, layers: &[String], layer: &str) -> PathBuf {
    if layers.len() <= 1 {
        return output.to_path_buf();
    }
    let stem = output
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match output.extension() {
        Some(ext) => format!("{stem}-{layer}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{layer}"),
    };
    output.with_file_name(name)
}

/// A tile to export: its PMTiles id and coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlannedTile {
    /// PMTiles tile id.
    pub id: u64,
    /// Zoom.
    pub z: u8,
    /// Column.
    pub x: u32,
    /// Row (XYZ, from the north).
    pub y: u32,
}

/// The tiles of `bbox` over `zooms` that exist in `world`, in tile-id order, restricted to
/// `shard`.
pub fn plan(
    world: &World,
    bbox: [f64; 4],
    zooms: (u8, u8),
    shard: Option<Shard>,
) -> Result<Vec<PlannedTile>, CliError> {
    if zooms.1 > world.max_zoom() {
        return Err(CliError::Usage(format!(
            "zoom {} is deeper than world `{}`'s maximum zoom {}",
            zooms.1,
            world.name(),
            world.max_zoom()
        )));
    }
    let mut tiles = Vec::new();
    for z in zooms.0..=zooms.1 {
        let (x0, y0, x1, y1) = tile_range_for_bounds(z, (bbox[0], bbox[1], bbox[2], bbox[3]));
        for x in x0..=x1 {
            for y in y0..=y1 {
                if world.check_tile(z, x, y).is_ok() {
                    let id = pmtiles::tile_id(z, x, y);
                    tiles.push(PlannedTile { id, z, x, y });
                }
            }
        }
    }
    if tiles.is_empty() {
        return Err(CliError::Usage(format!(
            "the bounding box {bbox:?} does not overlap world `{}` (bounds {:?})",
            world.name(),
            world.bounds()
        )));
    }
    tiles.sort_unstable_by_key(|t| t.id);
    if let Some(s) = shard {
        let n = tiles.len();
        // Index · n fits: n is a count of tiles in memory, index ≤ count ≤ u32::MAX.
        let cut = |i: u32| {
            (n as u128)
                .saturating_mul(u128::from(i))
                .checked_div(u128::from(s.count))
                .map_or(n, |c| c as usize)
        };
        tiles = tiles[cut(s.index.saturating_sub(1))..cut(s.index)].to_vec();
    }
    Ok(tiles)
}

/// The request the server parses from `/tiles/{world}/{layer}/{z}/{x}/{y}.{ext}`.
fn request(
    world: &World,
    layer: &str,
    format: TileFormat,
    t: (u8, u32, u32),
) -> Result<TileRequest, CliError> {
    let req = parse_request(
        world.name(),
        layer,
        &t.0.to_string(),
        &t.1.to_string(),
        &format!("{}.{}", t.2, format.extension()),
        &HashMap::new(),
    )
    .map_err(|e| {
        let vector = [style::INSTANCES, style::CONTOURS].contains(&layer);
        let hint = match (vector, format) {
            (true, TileFormat::Png | TileFormat::Webp) => " (a vector layer: --tile-format mvt)",
            (false, TileFormat::Mvt) => " (--tile-format mvt is for instances and contours)",
            _ => "",
        };
        CliError::Usage(format!("layer `{layer}`: {e}{hint}"))
    })?;
    check_against_world(world, &req).map_err(|e| CliError::Usage(e.to_string()))?;
    Ok(req)
}

/// The metadata of a layer's archive (PMTiles: the JSON object; MBTiles: its members as rows).
fn metadata(
    world: &World,
    layer: &str,
    format: TileFormat,
    bounds: [f64; 4],
    center: [f64; 3],
    zooms: (u8, u8),
) -> serde_json::Value {
    let mut m = serde_json::json!({
        "name": format!("{} {layer}", world.name()),
        "description": world.title(),
        "attribution": world.attribution(),
        "format": format.metadata_format(),
        "type": if layer == "elevation" || layer == "color" { "baselayer" } else { "overlay" },
        "version": "1",
        "minzoom": zooms.0,
        "maxzoom": zooms.1,
        "bounds": bounds,
        "center": center,
        "generator": format!("terrasynth {}", env!("CARGO_PKG_VERSION")),
    });
    if layer == "elevation" {
        m["encoding"] = "terrarium".into();
    }
    // Vector tiles name their layers and fields (the TileJSON's `vector_layers`, which MBTiles
    // 1.3 and PMTiles v3 ask for).
    if format == TileFormat::Mvt {
        if let Some(layers) = tilejson_of(world, "", layer).and_then(|tj| tj.vector_layers) {
            m["vector_layers"] = serde_json::to_value(layers).unwrap_or_default();
        }
    }
    m
}

/// MBTiles metadata rows: strings as they are, numbers as text, `bounds` and `center` as the
/// comma-separated lists the specification asks for, `vector_layers` in the `json` row (as
/// `{"vector_layers": [...]}`).
fn mbtiles_rows(m: &serde_json::Value) -> Vec<(String, String)> {
    let Some(obj) = m.as_object() else {
        return Vec::new();
    };
    obj.iter()
        .map(|(k, v)| {
            if k == "vector_layers" {
                return ("json".to_string(), serde_json::json!({ k: v }).to_string());
            }
            let text = match v {
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Array(a) => a
                    .iter()
                    .map(|x| x.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
                other => other.to_string(),
            };
            (k.clone(), text)
        })
        .collect()
}

/// An archive being written.
enum Sink {
    Pmtiles(pmtiles::Writer),
    Mbtiles(mbtiles::Writer),
}

/// Runs an export of `world`; `progress(done, total)` after each chunk of tiles.
pub fn run(
    world: &World,
    args: &ExportArgs,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ExportSummary, CliError> {
    let start = Instant::now();
    if args.layers.is_empty() {
        return Err(CliError::Usage("--layers names no layer".into()));
    }
    let wb = world.bounds();
    let bounds = [
        args.bbox[0].max(wb[0]),
        args.bbox[1].max(wb[1]),
        args.bbox[2].min(wb[2]),
        args.bbox[3].min(wb[3]),
    ];
    let tiles = plan(world, args.bbox, args.zooms, args.shard)?;
    // Check every layer before rendering anything (at the first zoom: instance tiles start at
    // the world's `instances_min_zoom`).
    for layer in &args.layers {
        request(world, layer, args.tile_format, (args.zooms.0, 0, 0))?;
    }
    let center = [
        (bounds[0] + bounds[2]) / 2.0,
        (bounds[1] + bounds[3]) / 2.0,
        world
            .center()
            .get(2)
            .copied()
            .unwrap_or(0.0)
            .clamp(f64::from(args.zooms.0), f64::from(args.zooms.1)),
    ];
    let total = (tiles.len() as u64).saturating_mul(args.layers.len() as u64);
    let mut done = 0u64;
    progress(0, total);
    let threads = rayon::current_num_threads().clamp(1, 64);
    let chunk = threads.saturating_mul(8);
    let mut archives = Vec::new();
    for layer in &args.layers {
        let output = layer_output(&args.output, &args.layers, layer);
        let dir = match output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let stale = crate::archive::remove_stale_temporaries(&output);
        if stale > 0 {
            eprintln!(
                "removed {stale} temporary file(s) that killed exports to {} left",
                output.display()
            );
        }
        let meta = metadata(world, layer, args.tile_format, bounds, center, args.zooms);
        let mut sink = match args.format {
            ArchiveFormat::Pmtiles => Sink::Pmtiles(pmtiles::Writer::new(&dir)?),
            ArchiveFormat::Mbtiles => {
                Sink::Mbtiles(mbtiles::Writer::create(&output, &mbtiles_rows(&meta))?)
            }
        };
        let mut unique = std::collections::HashSet::new();
        for part in tiles.chunks(chunk) {
            let rendered: Vec<Result<Vec<u8>, CliError>> = on_threads(part, threads, |t| {
                let req = request(world, layer, args.tile_format, (t.z, t.x, t.y))?;
                let bytes = render(world, &req)?;
                Ok(if args.tile_format.gzipped() {
                    gzip(&bytes)?
                } else {
                    bytes
                })
            });
            for (t, bytes) in part.iter().zip(rendered) {
                let bytes = bytes?;
                match &mut sink {
                    Sink::Pmtiles(w) => w.add(t.id, &bytes)?,
                    Sink::Mbtiles(w) => {
                        let hash: [u8; 32] = Sha256::digest(&bytes).into();
                        unique.insert(hash);
                        w.add(t.z, t.x, t.y, &bytes)?
                    }
                }
            }
            done = done.saturating_add(part.len() as u64);
            progress(done, total);
        }
        let (count, distinct, size) = match sink {
            Sink::Pmtiles(w) => {
                let (count, distinct, _) = w.counts();
                let info = pmtiles::HeaderInfo {
                    format: args.tile_format,
                    min_zoom: args.zooms.0,
                    max_zoom: args.zooms.1,
                    bounds,
                    center,
                };
                let size = w.finish(&output, &info, &meta, args.max_root_bytes)?;
                (count, distinct, size)
            }
            Sink::Mbtiles(w) => (tiles.len() as u64, unique.len() as u64, w.finish()?),
        };
        archives.push(ArchiveSummary {
            layer: layer.clone(),
            path: output.display().to_string(),
            tiles: count,
            unique: distinct,
            bytes: size,
        });
    }
    let seconds = start.elapsed().as_secs_f64();
    Ok(ExportSummary {
        archives,
        tiles: total,
        seconds,
        tiles_per_second: total as f64 / seconds.max(1e-9),
    })
}

/// `f` of every item on `threads` plain threads (this one and scoped ones, not rayon's
/// workers), the results in the order of `items`.
///
/// A tile's computation can wait for a tile another computation is making (a flight). A rayon
/// worker that waits inside a parallel loop runs other jobs meanwhile, so on rayon's pool a
/// tile's wait could sit on top of the stolen half of the very kernel it waits for; with every
/// worker caught so the export hung (8 rayon threads on 2 cores, in about half the runs). Plain
/// threads block without taking rayon's jobs, as the server's blocking threads do; the
/// kernels' own parallel loops still run on rayon's pool. A thread that cannot be created
/// leaves its share to the others (at worst to this thread alone); a panic in `f` is passed on.
fn on_threads<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let work = || {
        let mut out = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(i) else { break };
            out.push((i, f(item)));
        }
        out
    };
    let mut done: Vec<(usize, R)> = std::thread::scope(|s| {
        let helpers: Vec<_> = (1..threads.clamp(1, items.len().max(1)))
            .filter_map(|k| {
                std::thread::Builder::new()
                    .name(format!("ts-export-{k}"))
                    .spawn_scoped(s, work)
                    .ok()
            })
            .collect();
        let mut all = work();
        for h in helpers {
            match h.join() {
                Ok(part) => all.extend(part),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        all
    });
    done.sort_unstable_by_key(|&(i, _)| i);
    done.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_run_on_plain_threads_and_come_back_in_order() {
        let items: Vec<u32> = (0..100).collect();
        for threads in [1, 3, 8] {
            let out = on_threads(&items, threads, |&i| {
                // Never on one of rayon's workers, where a wait could hold a stolen kernel.
                (i * 2, rayon::current_thread_index().is_none())
            });
            assert_eq!(out.len(), items.len());
            for (k, &(v, plain)) in out.iter().enumerate() {
                assert_eq!(v, 2 * k as u32, "order, {threads} threads");
                assert!(plain, "item {k} ran on a rayon worker");
            }
        }
        // More than one thread works when asked to.
        let ids: Vec<std::thread::ThreadId> = on_threads(&items, 4, |_| {
            std::thread::sleep(std::time::Duration::from_millis(2));
            std::thread::current().id()
        });
        let distinct: std::collections::HashSet<_> = ids.into_iter().collect();
        assert!(distinct.len() > 1, "one thread did everything");
        assert!(on_threads(&[] as &[u32], 4, |&i| i).is_empty());
    }

    #[test]
    fn arguments_parse_and_bad_ones_are_named() {
        assert_eq!(
            parse_bbox("71.5,42.1,73.5,42.7").unwrap(),
            [71.5, 42.1, 73.5, 42.7]
        );
        assert!(parse_bbox("71.5,42.1,73.5").is_err());
        assert!(parse_bbox("73.5,42.1,71.5,42.7").is_err());
        assert!(parse_bbox("a,b,c,d").is_err());
        assert_eq!(parse_zooms("0-14").unwrap(), (0, 14));
        assert_eq!(parse_zooms("7").unwrap(), (7, 7));
        assert!(parse_zooms("9-3").is_err());
        assert_eq!(
            "2/4".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 4 }
        );
        for bad in ["0/4", "5/4", "1/0", "1", "a/b"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn several_layers_get_one_archive_each() {
        let layers = vec!["elevation".to_string(), "color".to_string()];
        let out = Path::new("/tmp/x/talas.pmtiles");
        assert_eq!(
            layer_output(out, &layers, "color"),
            Path::new("/tmp/x/talas-color.pmtiles")
        );
        assert_eq!(layer_output(out, &layers[..1], "elevation"), out);
        assert!(crate::archive::temporary_path(out)
            .to_string_lossy()
            .starts_with("/tmp/x/.talas.pmtiles.tmp-"));
    }

    #[test]
    fn mbtiles_rows_write_bounds_and_center_as_lists() {
        let m = serde_json::json!({"name": "w", "bounds": [1.5, 2.0, 3.0, 4.0], "minzoom": 0});
        let rows = mbtiles_rows(&m);
        assert!(rows.contains(&("bounds".into(), "1.5,2.0,3.0,4.0".into())));
        assert!(rows.contains(&("minzoom".into(), "0".into())));
        assert!(rows.contains(&("name".into(), "w".into())));
    }

    #[test]
    fn mbtiles_rows_put_vector_layers_in_the_json_row() {
        let m = serde_json::json!({"format": "pbf", "vector_layers": [{"id": "contours"}]});
        let rows = mbtiles_rows(&m);
        assert!(rows.contains(&("format".into(), "pbf".into())));
        let json = rows.iter().find(|(k, _)| k == "json").map(|(_, v)| v);
        let v: serde_json::Value = serde_json::from_str(json.expect("a json row")).unwrap();
        assert_eq!(v["vector_layers"][0]["id"], "contours");
        assert!(!rows.iter().any(|(k, _)| k == "vector_layers"));
    }
}
