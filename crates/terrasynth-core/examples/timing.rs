//! Scratch: times one amplification level on a 1024² window of the embedded Tien Shan grid, per
//! lever set (best of seven wall-clock runs; the criterion bench `pipeline` is the reference).
//!
//! `cargo run --release -p terrasynth-core --example timing -- DICT.dict [LEVERS...]`
use ndarray::s;
use std::error::Error;
use std::sync::Arc;
use std::time::Instant;
use terrasynth_core::dictionary::format::read_dictionary;
use terrasynth_core::dictionary::MatchWeights;
use terrasynth_core::raster::embedded;
use terrasynth_core::synth::{Amplifier, Field, Levers, Window};

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        return Err("usage: timing DICT.dict [LEVERS...]".into());
    };
    let dict = Arc::new(read_dictionary(
        std::io::BufReader::new(std::fs::File::open(path)?),
        1 << 34,
    )?);
    let grid = embedded::tienshan()?;
    let base = grid.filled()?;
    let cell_m = grid.georef.cell_sizes(grid.rows()).mean_cell();
    let lever_sets: Vec<&str> = if args.len() > 1 {
        args[1..].iter().map(String::as_str).collect()
    } else {
        vec!["default"]
    };
    for lev in lever_sets {
        let levers = Levers::parse(lev)?;
        let amp = Amplifier::new(dict.clone(), &MatchWeights::default())?.with_levers(levers);
        let out = Window::new(1000, 1200, 1024, 1024);
        let need = amp.parent_window_for(out);
        let parent = Field::elevation_only(
            need,
            base.slice(s![
                need.row0 as usize..need.row0 as usize + need.rows,
                need.col0 as usize..need.col0 as usize + need.cols
            ])
            .to_owned(),
        );
        let mut times = Vec::new();
        for _ in 0..7 {
            let t = Instant::now();
            let f = amp.amplify(&parent, out, cell_m as f32)?;
            times.push(t.elapsed().as_secs_f64());
            std::hint::black_box(f);
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{lev:50} {:.1} ms  {:.2} M points/s",
            times[0] * 1e3,
            out.len() as f64 / times[0] / 1e6
        );
    }
    Ok(())
}
