//! One amplification level of the served amplifier, repeated: a fixed amount of work whose time
//! two builds can be compared by (a measurement tool, not a test; README, *Performance*).
//!
//! The level is the criterion bench's `amplify_level/default/1024`: the default dictionary (built
//! from the embedded grid with its derived layers, kept in `target/level-speed.dict`), the
//! default levers, a 1024² output window of the embedded Tien Shan grid. It prints the output
//! points per second over `N` levels (default 30) and a hash of the last level's bits, so that two
//! builds can be checked to give the same bytes. To compare builds A and B on a machine whose
//! speed drifts, run them alternately several times and compare the medians:
//!
//! ```sh
//! for i in 1 2 3 4 5 6; do ./level_speed-A 30; ./level_speed-B 30; done
//! ```
//!
//! Usage: `cargo run --release --example level_speed [N]`.

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use ndarray::s;
use terrasynth_core::dictionary::build::{build, BuildOptions, Exemplar};
use terrasynth_core::dictionary::derive::derived_layers;
use terrasynth_core::dictionary::format::{read_dictionary, write_dictionary};
use terrasynth_core::dictionary::{Dictionary, MatchWeights};
use terrasynth_core::raster::embedded;
use terrasynth_core::synth::{Amplifier, Field, Window};

fn main() {
    let levels: usize = std::env::args()
        .nth(1)
        .map(|v| v.parse().expect("N: a number of levels"))
        .unwrap_or(30)
        .max(1);
    let grid = embedded::tienshan().expect("embedded grid");
    let base = grid.filled().expect("valid data");
    let cells = grid.georef.cell_sizes(grid.rows());
    let cell_m = cells.mean_cell();
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("target")
        .join("level-speed.dict");
    let stored = std::fs::File::open(&path)
        .ok()
        .and_then(|f| read_dictionary(std::io::BufReader::new(f), 1 << 32).ok());
    let dict: Dictionary = stored.unwrap_or_else(|| {
        let ex = Exemplar {
            elevation: base.clone(),
            valid: None,
            cell_m,
            layers: derived_layers(&base, &cells),
        };
        let d = build(&[ex], &BuildOptions::default(), &mut |_, _| {}).expect("build");
        let mut bytes = Vec::new();
        write_dictionary(&d, &mut bytes).expect("serialise");
        let _ = std::fs::write(&path, bytes);
        d
    });
    let amp = Amplifier::new(Arc::new(dict), &MatchWeights::default()).expect("amplifier");
    let out = Window::new(1000, 1200, 1024, 1024);
    let need = amp.parent_window_for(out);
    let (r0, c0) = (need.row0 as usize, need.col0 as usize);
    let parent = Field::elevation_only(
        need,
        base.slice(s![r0..r0 + need.rows, c0..c0 + need.cols])
            .to_owned(),
    );
    let mut hash = 0u64;
    let start = Instant::now();
    for _ in 0..levels {
        let level = amp.amplify(&parent, out, cell_m as f32).expect("amplify");
        hash = level.elevation.iter().fold(0u64, |h, v| {
            h.wrapping_mul(0x100_0000_01b3) ^ u64::from(v.to_bits())
        });
    }
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "{:.2} M points/s over {levels} levels of 1024², last level's hash {hash:016x}",
        (levels * out.len()) as f64 / seconds / 1e6
    );
}
