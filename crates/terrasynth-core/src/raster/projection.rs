//! Projected coordinate systems in metres, through the pure-Rust `proj4rs`: which EPSG codes
//! are understood (UTM zones on WGS84 north 326xx and south 327xx, on NAD83 269xx, on ETRS89
//! 258xx), and the conversions between their metres and WGS84 longitude/latitude. NAD83 and
//! ETRS89 are taken as WGS84 (they differ by about a metre: far below a served pixel).

use proj4rs::proj::Proj;

use super::error::RasterError;

/// Whether EPSG `code` is a projected CRS this module understands.
pub fn is_supported(code: u16) -> bool {
    proj_string(code).is_some()
}

/// The PROJ string of a supported projected EPSG code.
fn proj_string(code: u16) -> Option<String> {
    let utm = |zone: u16, south: bool, datum: &str| {
        Some(format!(
            "+proj=utm +zone={zone}{} {datum} +units=m +no_defs",
            if south { " +south" } else { "" }
        ))
    };
    match code {
        32601..=32660 => utm(code - 32600, false, "+datum=WGS84"),
        32701..=32760 => utm(code - 32700, true, "+datum=WGS84"),
        26901..=26923 => utm(code - 26900, false, "+datum=NAD83"),
        25828..=25838 => utm(code - 25800, false, "+ellps=GRS80 +towgs84=0,0,0"),
        _ => None,
    }
}

fn unsupported(code: u16) -> RasterError {
    RasterError::unsupported(
        "GeoTIFF",
        format!(
            "projected CRS EPSG:{code}; read are EPSG:4326, EPSG:3857 and the UTM zones \
             EPSG:326xx/327xx (WGS84), 269xx (NAD83) and 258xx (ETRS89)"
        ),
    )
}

/// Converts between one projected CRS and WGS84 longitude/latitude in degrees.
pub struct Projection {
    code: u16,
    projected: Proj,
    geographic: Proj,
}

impl std::fmt::Debug for Projection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Projection(EPSG:{})", self.code)
    }
}

impl Projection {
    /// The projection of EPSG `code`; an error naming the code when it is not supported.
    pub fn new(code: u16) -> Result<Projection, RasterError> {
        let text = proj_string(code).ok_or_else(|| unsupported(code))?;
        let bad = |e: proj4rs::errors::Error| {
            RasterError::unsupported("GeoTIFF", format!("projected CRS EPSG:{code}: {e}"))
        };
        Ok(Projection {
            code,
            projected: Proj::from_proj_string(&text).map_err(bad)?,
            geographic: Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs")
                .map_err(bad)?,
        })
    }

    /// Longitude/latitude (degrees) of projected metres `(x, y)`; `None` where the projection
    /// has no answer.
    pub fn to_lonlat(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let mut p = (x, y, 0.0);
        proj4rs::transform::transform(&self.projected, &self.geographic, &mut p).ok()?;
        let (lon, lat) = (p.0.to_degrees(), p.1.to_degrees());
        (lon.is_finite() && lat.is_finite()).then_some((lon, lat))
    }

    /// Projected metres of longitude/latitude `(lon, lat)` in degrees; `None` where the
    /// projection has no answer.
    pub fn from_lonlat(&self, lon: f64, lat: f64) -> Option<(f64, f64)> {
        let mut p = (lon.to_radians(), lat.to_radians(), 0.0);
        proj4rs::transform::transform(&self.geographic, &self.projected, &mut p).ok()?;
        (p.0.is_finite() && p.1.is_finite()).then_some((p.0, p.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utm_round_trips_and_matches_known_points() {
        // The central meridian of zone 11 (117°W) at the equator: x = 500 000 m, y = 0.
        let p = Projection::new(32611).unwrap();
        let (x, y) = p.from_lonlat(-117.0, 0.0).unwrap();
        assert!((x - 500_000.0).abs() < 1e-3 && y.abs() < 1e-3, "{x} {y}");
        // 1° north on the central meridian: k0 × meridian arc of 1° (110 574.4 m × 0.9996).
        let (_, y) = p.from_lonlat(-117.0, 1.0).unwrap();
        assert!((y - 110_574.4 * 0.9996).abs() < 1.0, "{y}");
        // A point of the Carrizo Plain and back.
        let n = Projection::new(26911).unwrap();
        let (x, y) = n.from_lonlat(-119.87, 35.27).unwrap();
        let (lon, lat) = n.to_lonlat(x, y).unwrap();
        assert!((lon + 119.87).abs() < 1e-9 && (lat - 35.27).abs() < 1e-9);
        // Southern zones have a false northing of 10 000 km.
        let s = Projection::new(32733).unwrap();
        let (_, y) = s.from_lonlat(15.0, -1.0).unwrap();
        assert!((y - (10_000_000.0 - 110_574.4 * 0.9996)).abs() < 1.0, "{y}");
    }

    #[test]
    fn unknown_codes_are_named() {
        for code in [32661, 26924, 2154, 27700] {
            let e = Projection::new(code).unwrap_err().to_string();
            assert!(e.contains(&format!("EPSG:{code}")), "{e}");
            assert!(!is_supported(code));
        }
    }
}
