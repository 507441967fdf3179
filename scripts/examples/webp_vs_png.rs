//! Bytes and encode time of lossless WebP against PNG on the load-test trace (README, "WebP
//! tiles"). Loads the configured world as `serve` does, takes the elevation (terrarium, mapbox,
//! `@2x`) and colour URLs of a trace (`scripts/make_trace.py` output, one URL a line), renders
//! each tile once as PNG to warm the level caches, then renders it as PNG and as WebP three times
//! each and keeps the fastest: with the levels cached, the time is the tile's encoding (plus, for
//! colour, the shading both formats share). Prints a markdown table.
//!
//! Usage: cargo run --release --example webp_vs_png -- TRACE [MAX_TILES]
//! (TERRASYNTH_STORE_DIR as for `serve`: the dictionary store to load the world from.)

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::HashMap;
use std::time::Instant;

use terrasynth_tiles::{parse_request, render, World};

struct Row {
    tiles: usize,
    png_bytes: usize,
    webp_bytes: usize,
    png_s: f64,
    webp_s: f64,
}

fn fastest(world: &World, req: &terrasynth_tiles::TileRequest) -> (usize, f64) {
    let mut best = f64::INFINITY;
    let mut len = 0;
    for _ in 0..3 {
        let t = Instant::now();
        let bytes = render(world, req).expect("render");
        best = best.min(t.elapsed().as_secs_f64());
        len = bytes.len();
    }
    (len, best)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let trace = std::fs::read_to_string(args.get(1).expect("usage: webp_vs_png TRACE [MAX]"))
        .expect("read trace");
    let max: usize = args.get(2).map_or(200, |m| m.parse().expect("MAX_TILES"));
    let config = terrasynth::config::load(None, std::env::vars()).expect("config");
    let state = terrasynth::server::startup::build_state(&config).expect("world");
    let mut rows: Vec<(String, Row)> = Vec::new();
    let mut done = 0;
    for url in trace.lines() {
        let path = url.split("/tiles/").nth(1).unwrap_or("");
        let (path, query) = path.split_once('?').unwrap_or((path, ""));
        let p: Vec<&str> = path.split('/').collect();
        let [world_name, layer, z, x, y_ext] = p[..] else {
            continue;
        };
        if !(layer == "elevation" || layer == "color") || !y_ext.ends_with(".png") {
            continue;
        }
        if done >= max {
            break;
        }
        let world = state.live.get(world_name).expect("world of the trace");
        let q: HashMap<String, String> = query
            .split('&')
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let png = parse_request(world_name, layer, z, x, y_ext, &q).expect("png request");
        let webp_ext = y_ext.replace(".png", ".webp");
        let webp = parse_request(world_name, layer, z, x, &webp_ext, &q).expect("webp request");
        render(&world, &png).expect("warm");
        let (pb, ps) = fastest(&world, &png);
        let (wb, ws) = fastest(&world, &webp);
        let kind = match (
            layer,
            q.get("encoding").map(String::as_str),
            y_ext.contains("@2x"),
        ) {
            ("color", _, _) => "colour (RGBA)",
            (_, Some("mapbox"), _) => "elevation, mapbox",
            (_, _, true) => "elevation, terrarium @2x",
            _ => "elevation, terrarium",
        };
        let i = match rows.iter().position(|(k, _)| k == kind) {
            Some(i) => i,
            None => {
                rows.push((
                    kind.to_string(),
                    Row {
                        tiles: 0,
                        png_bytes: 0,
                        webp_bytes: 0,
                        png_s: 0.0,
                        webp_s: 0.0,
                    },
                ));
                rows.len() - 1
            }
        };
        let r = &mut rows[i].1;
        r.tiles += 1;
        r.png_bytes += pb;
        r.webp_bytes += wb;
        r.png_s += ps;
        r.webp_s += ws;
        done += 1;
    }
    println!("| tiles | n | PNG mean bytes | WebP mean bytes | WebP / PNG | PNG ms/tile | WebP ms/tile |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for (kind, r) in &rows {
        let n = r.tiles as f64;
        println!(
            "| {kind} | {} | {:.0} | {:.0} | {:.2} | {:.2} | {:.2} |",
            r.tiles,
            r.png_bytes as f64 / n,
            r.webp_bytes as f64 / n,
            r.webp_bytes as f64 / r.png_bytes as f64,
            1e3 * r.png_s / n,
            1e3 * r.webp_s / n
        );
    }
}
