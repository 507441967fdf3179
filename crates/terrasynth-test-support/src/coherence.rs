//! Coherence of the landscape layers with the served elevation (issue #4, acceptance 3 and 4),
//! measured on mosaics of tiles of any world. Used by the server tests on the synthetic mini
//! world and by `scripts/examples/landscape_check.rs` on the default world. Expected values are computed
//! here from the decoded elevation tiles with `analysis` and the configured ranges written out by
//! hand, never by the landscape code under test.

use ndarray::{s, Array2};
use terrasynth_core::landscape::{Species, Trapezoid};
use terrasynth_core::math;
use terrasynth_tiles::{decode_terrarium_png, encode_terrarium_png, plane_cell_sizes, World};

/// An `n × n` mosaic of 256-px tiles given by `tile(dx, dy)`.
pub fn mosaic_of(n: u32, mut tile: impl FnMut(u32, u32) -> Array2<f32>) -> Array2<f32> {
    let mut out = Array2::zeros((256 * n as usize, 256 * n as usize));
    for dy in 0..n {
        for dx in 0..n {
            let t = tile(dx, dy);
            out.slice_mut(s![
                dy as usize * 256..(dy as usize + 1) * 256,
                dx as usize * 256..(dx as usize + 1) * 256
            ])
            .assign(&t);
        }
    }
    out
}

/// Pearson correlation.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

/// Ranks with ties averaged.
pub fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
    let mut out = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        let r = (i + j) as f64 / 2.0;
        for &k in &idx[i..=j] {
            out[k] = r;
        }
        i = j + 1;
    }
    out
}

/// The niche of a species written out from its configured ranges (smooth trapezoids: 0 outside
/// `[min, max]`, 1 inside the falloff bands, smoothstep between).
pub fn niche_by_hand(sp: &Species, e: f32, s: f32, n: f32, w: f32) -> f64 {
    let curve = |t: Option<Trapezoid>, x: f32| -> f64 {
        let Some(t) = t else { return 1.0 };
        let (x, lo, hi) = (f64::from(x), f64::from(t.min), f64::from(t.max));
        if x <= lo || x >= hi {
            return 0.0;
        }
        let f = f64::from(t.falloff).min((hi - lo) / 2.0);
        let u = ((x - lo) / f).min((hi - x) / f).min(1.0);
        u * u * (3.0 - 2.0 * u)
    };
    curve(sp.elevation, e) * curve(sp.slope, s) * curve(sp.northness, n) * curve(sp.wetness, w)
}

/// The elevation mosaic as a client decodes it from terrarium tiles.
pub fn decoded_elevation(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> Array2<f32> {
    mosaic_of(n, |dx, dy| {
        let t = world.elevation_tile(z, x0 + dx, y0 + dy).unwrap();
        decode_terrarium_png(&encode_terrarium_png(&t).unwrap()).unwrap()
    })
}

/// The served upstream area (m²) over the mosaic.
pub fn served_drainage(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> Array2<f32> {
    mosaic_of(n, |dx, dy| {
        world
            .drainage_tile(z, x0 + dx, y0 + dy)
            .unwrap()
            .as_ref()
            .clone()
    })
}

/// How one species fits its niche over a mosaic.
#[derive(Debug)]
pub struct SpeciesFit {
    /// Species name.
    pub name: String,
    /// Share of the mosaic where the niche exceeds 0.2.
    pub present: f64,
    /// Pearson correlation of density and niche.
    pub pearson: f64,
    /// Largest density where the niche is 0.
    pub worst_excluded: f32,
}

/// Acceptance 3 over the `n × n` mosaic of zoom-`z` tiles from `(x0, y0)` of `world`: see
/// [`vegetation_fit_of`].
pub fn vegetation_fit(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> Vec<SpeciesFit> {
    let elev = decoded_elevation(world, z, x0, y0, n);
    let wet = served_drainage(world, z, x0, y0, n).mapv(math::log10f);
    let vegs: Vec<Vec<Array2<f32>>> = (0..n * n)
        .map(|i| {
            world
                .vegetation_tile(z, x0 + i % n, y0 + i / n)
                .unwrap()
                .to_vec()
        })
        .collect();
    let densities: Vec<Array2<f32>> = (0..world.landscape().species.len())
        .map(|k| mosaic_of(n, |dx, dy| vegs[(dy * n + dx) as usize][k].clone()))
        .collect();
    vegetation_fit_of(&world.landscape().species, z, y0, &elev, &wet, &densities)
}

/// Acceptance 3 on mosaics whose first row is row `256·y0` of zoom `z`'s plane: the niche model
/// on the decoded elevation `elev` (slope and northness from `analysis`, wetness `wet` = log10 of
/// the served upstream area) against each species' served density (`densities`, in species
/// order), one-pixel frame ignored.
pub fn vegetation_fit_of(
    species: &[Species],
    z: u8,
    y0: u32,
    elev: &Array2<f32>,
    wet: &Array2<f32>,
    densities: &[Array2<f32>],
) -> Vec<SpeciesFit> {
    let size = elev.nrows();
    let cells = plane_cell_sizes(z, i64::from(y0) * 256, size);
    let slope = terrasynth_core::analysis::slope_degrees(elev, &cells);
    let north = terrasynth_core::analysis::northness(elev, &cells);
    let mut out = Vec::new();
    for (sp, d) in species.iter().zip(densities) {
        let (mut model, mut dens, mut worst) = (Vec::new(), Vec::new(), 0.0f32);
        for r in 1..size - 1 {
            for c in 1..size - 1 {
                let m = niche_by_hand(sp, elev[[r, c]], slope[[r, c]], north[[r, c]], wet[[r, c]]);
                if m == 0.0 {
                    worst = worst.max(d[[r, c]]);
                }
                model.push(m);
                dens.push(f64::from(d[[r, c]]));
            }
        }
        let present = model.iter().filter(|&&m| m > 0.2).count() as f64 / model.len() as f64;
        out.push(SpeciesFit {
            name: sp.name.clone(),
            present,
            pearson: pearson(&model, &dens),
            worst_excluded: worst,
        });
    }
    out
}

/// How the drainage of a mosaic fits its elevation.
#[derive(Debug)]
pub struct DrainageFit {
    /// Spearman correlation of the served log area and D8 on the decoded mosaic (16-px frame
    /// ignored).
    pub spearman: f64,
    /// Main-channel border crossings walked.
    pub crossings: usize,
    /// Descriptions of channels that broke at or after a border.
    pub breaks: Vec<String>,
}

/// Acceptance 4 over the `n × n` mosaic of zoom-`z` tiles from `(x0, y0)`. The channel walk
/// starts at every main-channel pixel (top 1 % of the served area) within 3 px of a tile border
/// and steps to the neighbour of largest area; a step across a border must land on a main-channel
/// pixel carrying at least the flow of the last one, and the walk must end on the main channel.
pub fn drainage_fit(world: &World, z: u8, x0: u32, y0: u32, n: u32) -> DrainageFit {
    let elev = decoded_elevation(world, z, x0, y0, n);
    let served = served_drainage(world, z, x0, y0, n);
    drainage_fit_of(z, y0, &elev, &served)
}

/// Acceptance 4 on mosaics whose first row is row `256·y0` of zoom `z`'s plane: the decoded
/// elevation `elev` and the served upstream area `served` (m²); see [`drainage_fit`].
pub fn drainage_fit_of(z: u8, y0: u32, elev: &Array2<f32>, served: &Array2<f32>) -> DrainageFit {
    let size = elev.nrows();
    let cells = plane_cell_sizes(z, i64::from(y0) * 256, size);
    let filled = terrasynth_core::analysis::priority_flood_fill(elev);
    let d8 = terrasynth_core::analysis::flow_accumulation_d8(&filled, &cells);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for r in 16..size - 16 {
        for c in 16..size - 16 {
            a.push(math::log10(f64::from(served[[r, c]])));
            b.push(math::log10(d8[[r, c]]));
        }
    }
    let spearman = pearson(&ranks(&a), &ranks(&b));
    let mut sorted: Vec<f32> = served.iter().copied().collect();
    sorted.sort_by(f32::total_cmp);
    let top = sorted[sorted.len() * 99 / 100];
    let near_border = |v: usize| (v % 256 < 3 || v % 256 > 252) && v > 3 && v < size - 4;
    let (mut crossings, mut breaks) = (0, Vec::new());
    for r in 1..size - 1 {
        for c in 1..size - 1 {
            if served[[r, c]] < top || !(near_border(r) || near_border(c)) {
                continue;
            }
            let (mut cur, mut steps, mut crossed) = ((r, c), 0, false);
            while steps < 12 && cur.0 > 0 && cur.1 > 0 && cur.0 < size - 1 && cur.1 < size - 1 {
                let mut next = cur;
                for dr in -1i64..=1 {
                    for dc in -1i64..=1 {
                        let p = ((cur.0 as i64 + dr) as usize, (cur.1 as i64 + dc) as usize);
                        if served[p] > served[next] {
                            next = p;
                        }
                    }
                }
                if next == cur {
                    break;
                }
                if next.0 / 256 != cur.0 / 256 || next.1 / 256 != cur.1 / 256 {
                    crossed = true;
                    crossings += 1;
                    if served[next] < top || served[next] < served[cur] {
                        breaks.push(format!("{cur:?} → {next:?}"));
                    }
                }
                cur = next;
                steps += 1;
            }
            if crossed && served[cur] < top {
                breaks.push(format!("channel from ({r},{c}) fades after the border"));
            }
        }
    }
    DrainageFit {
        spearman,
        crossings,
        breaks,
    }
}
