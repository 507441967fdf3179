//! Zoom bands of a scale-aware chain: which dictionary amplifies which zoom. A world may use a
//! different dictionary per band of zooms (`zooms = "9-12"`), so that fine exemplars drive the
//! deep zooms and coarse ones the shallow zooms.
//!
//! The rule, in one place: bands lie within `(z_base, max_zoom]` and do not overlap; an
//! amplified zoom uses the band that covers it; a zoom no band covers uses the nearest
//! shallower band (the chain keeps its dictionary until the next band starts), and zooms above
//! `z_base` but below the first band use the first band. A band without zooms (the single
//! `[dictionary]` of a world file, a bare id in the admin API) covers every amplified zoom.

use std::fmt;

use thiserror::Error;

/// A band's zooms, `first..=last`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ZoomBand {
    /// Shallowest zoom of the band.
    pub first: u8,
    /// Deepest zoom of the band.
    pub last: u8,
}

/// A malformed or inconsistent set of zoom bands.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum BandError {
    /// A `zooms` string is not `A-B` or `A` with `A ≤ B ≤ 30`.
    #[error(
        "zooms `{0}` must be `FIRST-LAST` or `ZOOM` (integers 0–30, FIRST ≤ LAST), e.g. \"9-12\""
    )]
    Malformed(String),
    /// A band lies (partly) at or below the native zoom or beyond the deepest zoom.
    #[error("zooms {band} lie outside the amplified zooms {first}-{last} (native zoom {z_base}, max_zoom {last})", first = .z_base + 1)]
    OutOfRange {
        /// The band.
        band: ZoomBand,
        /// The world's native zoom.
        z_base: u8,
        /// The world's deepest zoom.
        last: u8,
    },
    /// Two bands share a zoom.
    #[error("zooms {0} and {1} overlap")]
    Overlap(ZoomBand, ZoomBand),
    /// More than one band but one of them has no zooms, or no band at all.
    #[error("{0}")]
    Shape(String),
}

impl fmt::Display for ZoomBand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}-{}", self.first, self.last)
        }
    }
}

impl std::str::FromStr for ZoomBand {
    type Err = BandError;

    /// Parses `"9-12"` or `"15"` (spaces around the numbers allowed).
    fn from_str(s: &str) -> Result<ZoomBand, BandError> {
        let bad = || BandError::Malformed(s.to_string());
        let num = |t: &str| -> Result<u8, BandError> {
            let t = t.trim();
            if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
                return Err(bad());
            }
            t.parse::<u8>().ok().filter(|&z| z <= 30).ok_or_else(bad)
        };
        let (first, last) = match s.split_once('-') {
            Some((a, b)) => (num(a)?, num(b)?),
            None => {
                let z = num(s)?;
                (z, z)
            }
        };
        if first > last {
            return Err(bad());
        }
        Ok(ZoomBand { first, last })
    }
}

impl ZoomBand {
    /// Whether zoom `z` lies in the band.
    pub fn contains(&self, z: u8) -> bool {
        (self.first..=self.last).contains(&z)
    }
}

/// Checks bands (`None`: every amplified zoom) against a world's native zoom `z_base` and
/// deepest zoom `max_zoom`: one band without zooms alone, or bands with zooms inside
/// `(z_base, max_zoom]` that do not overlap.
pub fn check_bands(bands: &[Option<ZoomBand>], z_base: u8, max_zoom: u8) -> Result<(), BandError> {
    match bands {
        [] => return Err(BandError::Shape("a world needs a dictionary".into())),
        [None] => return Ok(()),
        _ if bands.iter().any(Option::is_none) => {
            return Err(BandError::Shape(
                "with several dictionaries every one must give its zooms".into(),
            ))
        }
        _ => {}
    }
    let mut sorted: Vec<ZoomBand> = bands.iter().flatten().copied().collect();
    sorted.sort();
    for b in &sorted {
        if b.first <= z_base || b.last > max_zoom {
            return Err(BandError::OutOfRange {
                band: *b,
                z_base,
                last: max_zoom,
            });
        }
    }
    for pair in sorted.windows(2) {
        if pair[1].first <= pair[0].last {
            return Err(BandError::Overlap(pair[0], pair[1]));
        }
    }
    Ok(())
}

/// The index of the band that amplifies zoom `z` (see the module's rule), for bands already
/// checked by [`check_bands`]; `0` for an empty list.
pub fn band_for(bands: &[Option<ZoomBand>], z: u8) -> usize {
    let mut best: Option<(u8, usize)> = None;
    let mut shallowest: Option<(u8, usize)> = None;
    for (i, b) in bands.iter().enumerate() {
        let Some(b) = b else { return i };
        if b.first <= z && best.is_none_or(|(f, _)| b.first > f) {
            best = Some((b.first, i));
        }
        if shallowest.is_none_or(|(f, _)| b.first < f) {
            shallowest = Some((b.first, i));
        }
    }
    best.or(shallowest).map_or(0, |(_, i)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band(s: &str) -> Option<ZoomBand> {
        Some(s.parse().unwrap())
    }

    #[test]
    fn zoom_strings_parse_or_are_refused_by_name() {
        assert_eq!("9-12".parse(), Ok(ZoomBand { first: 9, last: 12 }));
        assert_eq!(
            " 15 ".parse(),
            Ok(ZoomBand {
                first: 15,
                last: 15
            })
        );
        assert_eq!(
            "15 - 16".parse(),
            Ok(ZoomBand {
                first: 15,
                last: 16
            })
        );
        for bad in [
            "", "-", "12-9", "a-b", "9-", "-3", "9-12-14", "+9", "31", "9.5", "1e1",
        ] {
            let e = bad.parse::<ZoomBand>().unwrap_err();
            assert_eq!(e, BandError::Malformed(bad.to_string()));
            assert!(e.to_string().contains("FIRST-LAST"), "{e}");
        }
    }

    #[test]
    fn bands_must_lie_in_the_amplified_zooms_and_not_overlap() {
        assert_eq!(check_bands(&[None], 8, 16), Ok(()));
        assert_eq!(check_bands(&[band("9-14"), band("15-16")], 8, 16), Ok(()));
        assert_eq!(check_bands(&[band("15-16"), band("9-12")], 8, 16), Ok(()));
        assert!(matches!(
            check_bands(&[band("8-12")], 8, 16),
            Err(BandError::OutOfRange { .. })
        ));
        assert!(matches!(
            check_bands(&[band("9-17")], 8, 16),
            Err(BandError::OutOfRange { .. })
        ));
        let e = check_bands(&[band("9-13"), band("13-16")], 8, 16).unwrap_err();
        assert_eq!(e.to_string(), "zooms 9-13 and 13-16 overlap");
        assert!(check_bands(&[None, band("13-16")], 8, 16).is_err());
        assert!(check_bands(&[], 8, 16).is_err());
    }

    #[test]
    fn uncovered_zooms_use_the_nearest_shallower_band() {
        let bands = [band("15-16"), band("10-12")];
        // Below the first band: the first band; in a gap: the band before it.
        assert_eq!(band_for(&bands, 9), 1);
        assert_eq!(band_for(&bands, 10), 1);
        assert_eq!(band_for(&bands, 12), 1);
        assert_eq!(band_for(&bands, 13), 1);
        assert_eq!(band_for(&bands, 14), 1);
        assert_eq!(band_for(&bands, 15), 0);
        assert_eq!(band_for(&bands, 16), 0);
        assert_eq!(band_for(&[None], 13), 0);
    }
}
