//! Measures issue #4's acceptance 3 and 4 on the default world (the tests measure them on a small
//! synthetic world): vegetation against the niche model on the served elevation, and drainage
//! against D8 on the decoded elevation, over a 4×4 mosaic of amplified tiles. Builds the default
//! dictionary into a store directory on first use.
//!
//! Usage: `cargo run --release --example landscape_check -- [STORE_DIR] [Z X0 Y0]` (defaults:
//! `target/picture-store`, zoom 10 tiles 716..720 × 379..383 over the Talas range).

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use terrasynth_test_support::coherence;

use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let store = args.first().map_or("target/picture-store", String::as_str);
    let num = |i: usize, d: u32| args.get(i).and_then(|v| v.parse().ok()).unwrap_or(d);
    let (z, x0, y0) = (num(1, 10) as u8, num(2, 716), num(3, 379));
    let mut config = terrasynth::config::load(None, Vec::new())?;
    config.server.store_dir = store.into();
    let store = terrasynth_store::Store::open(&config.server.store_dir)?;
    let worlds = terrasynth::server::load_worlds(&config, &store)?;
    let world = worlds.get("tienshan").ok_or("no default world")?;
    println!(
        "default world, zoom {z}, tiles {x0}..{} × {y0}..{}",
        x0 + 4,
        y0 + 4
    );
    for f in coherence::vegetation_fit(world, z, x0, y0, 4) {
        println!(
            "vegetation {:8} present on {:5.1} %  Pearson {:.3}  max density where excluded {:.4}",
            f.name,
            100.0 * f.present,
            f.pearson,
            f.worst_excluded
        );
    }
    let d = coherence::drainage_fit(world, z, x0, y0, 4);
    println!(
        "drainage Spearman {:.3}, {} main-channel border crossings, {} breaks",
        d.spearman,
        d.crossings,
        d.breaks.len()
    );
    Ok(())
}
