//! The file form of a world's whole-world layers ([`crate::base_layers`]), so that a server
//! started again on the same store reads them instead of computing them (1.5 s for the default
//! world) before its first landscape tile.
//!
//! The file is a cache: whatever is wrong with it — another world's, another build's, truncated,
//! a flipped bit — it is refused and the layers are computed as if it were absent. A file holds
//! the upstream area and the species' densities *before* the painted controls (applied after
//! reading, as after computing) and, for a world that may have water, the base water's level and
//! sea grids. Layout, little-endian:
//!
//! | bytes | field |
//! | --- | --- |
//! | 8 | magic `TSLAYERS` |
//! | 4 | format version (`u32`, [`FORMAT_VERSION`]) |
//! | 32 | key: SHA-256 of everything the layers are computed from and of the build |
//! | 32 | window: `col0`, `row0` (`i64`), `cols`, `rows` (`u64`) |
//! | 4 | species (`u32`) |
//! | 1 | water: 0 none, 1 level and sea grids follow the densities |
//! | 4 · cells each | upstream area, each species' densities, then water level and sea (`f32`) |
//! | 4 | CRC-32 (IEEE) of every byte before it (`u32`) |
//!
//! Values are written and read bit for bit, so a layer read back is the layer computed. The
//! trailing checksum guards against damage, not against forgery (the key is what ties a file to
//! its inputs), so it is a CRC: version 1 took a SHA-256 of the whole file, which at about
//! 1.3 GB/s was the longest step of reading the default world's 86 MB.

use ndarray::Array2;
use terrasynth_core::synth::Window;

use crate::cancel::join;
use crate::elevation::BaseWater;

/// The file's first bytes.
pub const MAGIC: &[u8; 8] = b"TSLAYERS";

/// Version of the layout above.
pub const FORMAT_VERSION: u32 = 2;

/// Bytes before the grids.
const HEAD: usize = 8 + 4 + 32 + 32 + 4 + 1;

/// Bytes of the trailing checksum.
const SUM: usize = 4;

/// What a file holds.
#[derive(Debug)]
pub struct LayerFile {
    /// The window of the native zoom's plane the grids cover.
    pub window: Window,
    /// D8 upstream area, m².
    pub area: Array2<f32>,
    /// Vegetation densities before the painted controls, one grid per species.
    pub vegetation: Vec<Array2<f32>>,
    /// The base water, when the world may have water and has some.
    pub water: Option<BaseWater>,
}

/// Why a file was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// Shorter or longer than its header says, or not a layers file at all.
    Malformed,
    /// Another version of this layout.
    Version,
    /// Computed from other inputs or by another build.
    Key,
    /// Its checksum does not match its bytes.
    Checksum,
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Refused::Malformed => "not a whole-world layers file, or truncated",
            Refused::Version => "another version of the layers file format",
            Refused::Key => "computed from other inputs or by another build",
            Refused::Checksum => "its checksum does not match (corrupted)",
        })
    }
}

/// The file of upstream `area` and `vegetation` densities (before the painted controls) over
/// window `w`, and `water`, under `key`.
pub fn encode(
    key: &[u8; 32],
    w: Window,
    area: &Array2<f32>,
    vegetation: &[Array2<f32>],
    water: Option<&BaseWater>,
) -> Vec<u8> {
    let grids = 1 + vegetation.len() + if water.is_some() { 2 } else { 0 };
    let mut out = Vec::with_capacity(HEAD + grids * 4 * w.len() + SUM);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(key);
    out.extend_from_slice(&w.col0.to_le_bytes());
    out.extend_from_slice(&w.row0.to_le_bytes());
    out.extend_from_slice(&(w.cols as u64).to_le_bytes());
    out.extend_from_slice(&(w.rows as u64).to_le_bytes());
    out.extend_from_slice(&(vegetation.len() as u32).to_le_bytes());
    out.push(u8::from(water.is_some()));
    let mut put = |a: &Array2<f32>| {
        for v in a.iter() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    };
    put(area);
    vegetation.iter().for_each(&mut put);
    if let Some(water) = water {
        put(&water.level);
        put(&water.sea);
    }
    let sum = crc32fast::hash(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Reads a file written by [`encode`], refusing it unless it was written under `key` for
/// `window` with `species` density grids and is intact.
pub fn decode(
    bytes: &[u8],
    key: &[u8; 32],
    window: Window,
    species: usize,
) -> Result<LayerFile, Refused> {
    if bytes.len() < HEAD + SUM || &bytes[..8] != MAGIC {
        return Err(Refused::Malformed);
    }
    let mut at = 8;
    let mut take = |n: usize| {
        let s = &bytes[at..at + n];
        at += n;
        s
    };
    if u32::from_le_bytes(le4(take(4))) != FORMAT_VERSION {
        return Err(Refused::Version);
    }
    if take(32) != key {
        return Err(Refused::Key);
    }
    let col0 = i64::from_le_bytes(le8(take(8)));
    let row0 = i64::from_le_bytes(le8(take(8)));
    let cols = u64::from_le_bytes(le8(take(8)));
    let rows = u64::from_le_bytes(le8(take(8)));
    let n_species = u32::from_le_bytes(le4(take(4)));
    let has_water = take(1)[0];
    // The key covers the window and the landscape; a file that matches it and disagrees with
    // them is malformed.
    let same_window = (col0, row0, cols, rows)
        == (
            window.col0,
            window.row0,
            window.cols as u64,
            window.rows as u64,
        );
    if !same_window || n_species as usize != species || has_water > 1 {
        return Err(Refused::Malformed);
    }
    let grids = 1 + species + if has_water == 1 { 2 } else { 0 };
    let body = (grids as u64)
        .checked_mul(4)
        .and_then(|b| b.checked_mul(window.len() as u64));
    if body != Some((bytes.len() - HEAD - SUM) as u64) {
        return Err(Refused::Malformed);
    }
    let (content, sum) = bytes.split_at(bytes.len() - SUM);
    let cells = window.len();
    let grid_at = |g: usize| {
        let from = HEAD + g * 4 * cells;
        let values = content[from..from + 4 * cells]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(le4(b)))
            .collect();
        Array2::from_shape_vec((window.rows, window.cols), values).map_err(|_| Refused::Malformed)
    };
    let grids = || -> Result<LayerFile, Refused> {
        let area = grid_at(0)?;
        let vegetation = (1..=species).map(grid_at).collect::<Result<_, _>>()?;
        let water = if has_water == 1 {
            Some(BaseWater {
                window,
                level: grid_at(1 + species)?,
                sea: grid_at(2 + species)?,
            })
        } else {
            None
        };
        Ok(LayerFile {
            window,
            area,
            vegetation,
            water,
        })
    };
    // The checksum is taken while the grids are read out; they count only if it matches.
    let (digest, file) = join(|| crc32fast::hash(content), grids);
    if digest.to_le_bytes() != sum {
        return Err(Refused::Checksum);
    }
    file
}

fn le4(b: &[u8]) -> [u8; 4] {
    let mut a = [0; 4];
    a.copy_from_slice(b);
    a
}

fn le8(b: &[u8]) -> [u8; 8] {
    let mut a = [0; 8];
    a.copy_from_slice(b);
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(water: bool) -> LayerFile {
        let window = Window::new(-3, 7, 5, 4);
        let grid = |k: f32| Array2::from_shape_fn((4, 5), |(r, c)| k * (r * 5 + c) as f32 - 2.5);
        let mut area = grid(1.0e6);
        area[[1, 2]] = f32::NAN;
        LayerFile {
            window,
            area,
            vegetation: vec![grid(0.01), grid(-0.5)],
            water: water.then(|| BaseWater {
                window,
                level: grid(f32::NAN),
                sea: grid(0.0),
            }),
        }
    }

    fn encoded(f: &LayerFile, key: &[u8; 32]) -> Vec<u8> {
        encode(key, f.window, &f.area, &f.vegetation, f.water.as_ref())
    }

    fn same_bits(a: &Array2<f32>, b: &Array2<f32>) -> bool {
        a.dim() == b.dim() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    #[test]
    fn layers_come_back_bit_for_bit() {
        for with_water in [false, true] {
            let file = sample(with_water);
            let key = [7u8; 32];
            let back = decode(&encoded(&file, &key), &key, file.window, 2).unwrap();
            assert!(same_bits(&back.area, &file.area));
            assert_eq!(back.vegetation.len(), 2);
            for (a, b) in back.vegetation.iter().zip(&file.vegetation) {
                assert!(same_bits(a, b));
            }
            assert_eq!(back.water.is_some(), with_water);
            if let (Some(a), Some(b)) = (&back.water, &file.water) {
                assert!(same_bits(&a.level, &b.level) && same_bits(&a.sea, &b.sea));
            }
        }
    }

    #[test]
    fn other_keys_windows_and_damaged_files_are_refused() {
        let file = sample(true);
        let key = [7u8; 32];
        let bytes = encoded(&file, &key);
        let w = file.window;
        assert_eq!(decode(&bytes, &[8u8; 32], w, 2).unwrap_err(), Refused::Key);
        assert_eq!(
            decode(&bytes, &key, Window::new(-3, 7, 5, 5), 2).unwrap_err(),
            Refused::Malformed
        );
        assert_eq!(decode(&bytes, &key, w, 3).unwrap_err(), Refused::Malformed);
        for at in [HEAD, HEAD + 37, bytes.len() - 1] {
            let mut flipped = bytes.clone();
            flipped[at] ^= 0x10;
            assert_eq!(decode(&flipped, &key, w, 2).unwrap_err(), Refused::Checksum);
        }
        assert_eq!(
            decode(&bytes[..bytes.len() - 4], &key, w, 2).unwrap_err(),
            Refused::Malformed
        );
        assert_eq!(
            decode(b"short", &key, w, 2).unwrap_err(),
            Refused::Malformed
        );
        let mut version = bytes.clone();
        version[8] = 9;
        assert_eq!(decode(&version, &key, w, 2).unwrap_err(), Refused::Version);
    }
}
