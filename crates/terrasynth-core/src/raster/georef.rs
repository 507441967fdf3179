//! Georeference: the affine transform from pixel to map coordinates for north-up grids in
//! EPSG:4326 (degrees), EPSG:3857 (Web Mercator metres) or a projected CRS in metres (UTM: see
//! [`super::projection`]), and the metric cell sizes derived from it.

use serde::{Deserialize, Serialize};

use crate::math;

/// Mean Earth radius used for metric cell sizes in EPSG:4326 (metres).
pub const EARTH_RADIUS_M: f64 = 6_371_008.8;
/// The WGS84 semi-major axis, which is the sphere radius of Web Mercator (metres).
pub const MERCATOR_RADIUS_M: f64 = 6_378_137.0;

/// Latitude limit of Web Mercator, degrees.
pub const MAX_MERCATOR_LAT: f64 = 85.051_128_78;

/// Whether `[lon, lat]` is a finite point on the Web Mercator map (|lon| ≤ 180°, |lat| ≤
/// [`MAX_MERCATOR_LAT`]): the rule for user-given map centres.
pub fn is_map_point([lon, lat]: [f64; 2]) -> bool {
    lon.is_finite() && lat.is_finite() && lon.abs() <= 180.0 && lat.abs() <= MAX_MERCATOR_LAT
}

/// The coordinate reference systems terrasynth understands. Serialised as `"EPSG:{code}"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum Crs {
    /// Geographic WGS84 longitude/latitude in degrees.
    Epsg4326,
    /// Web Mercator, metres on the sphere of radius [`MERCATOR_RADIUS_M`].
    Epsg3857,
    /// A projected CRS in metres (an EPSG code [`super::projection`] understands, e.g. UTM):
    /// a metric grid whose cells are taken at their nominal size (the projection's scale error,
    /// under 0.1 % in UTM, is ignored).
    Projected(u16),
}

impl Crs {
    /// The EPSG code of this CRS.
    pub fn epsg(self) -> u16 {
        match self {
            Crs::Epsg4326 => 4326,
            Crs::Epsg3857 => 3857,
            Crs::Projected(code) => code,
        }
    }

    /// The CRS for an EPSG code, if supported.
    pub fn from_epsg(code: u32) -> Option<Crs> {
        match code {
            4326 => Some(Crs::Epsg4326),
            3857 | 900913 | 3785 => Some(Crs::Epsg3857),
            c => u16::try_from(c)
                .ok()
                .filter(|&c| super::projection::is_supported(c))
                .map(Crs::Projected),
        }
    }

    /// Longitude/latitude in degrees of map coordinates `(x, y)`; `None` where a projection has
    /// no answer.
    pub fn to_lonlat(self, x: f64, y: f64) -> Option<(f64, f64)> {
        match self {
            Crs::Epsg4326 => Some((x, y)),
            Crs::Epsg3857 => Some((
                (x / MERCATOR_RADIUS_M).to_degrees(),
                (2.0 * math::atan(math::exp(y / MERCATOR_RADIUS_M)) - std::f64::consts::FRAC_PI_2)
                    .to_degrees(),
            )),
            Crs::Projected(code) => super::projection::Projection::new(code)
                .ok()?
                .to_lonlat(x, y),
        }
    }
}

impl From<Crs> for String {
    fn from(c: Crs) -> String {
        format!("EPSG:{}", c.epsg())
    }
}

impl TryFrom<String> for Crs {
    type Error = String;

    fn try_from(s: String) -> Result<Crs, String> {
        s.strip_prefix("EPSG:")
            .and_then(|c| c.parse::<u32>().ok())
            .and_then(Crs::from_epsg)
            .ok_or_else(|| format!("unsupported CRS `{s}`"))
    }
}

/// A north-up affine georeference. Pixel `(col, row)` covers map coordinates
/// `[west + col·dx, west + (col+1)·dx] × [north − (row+1)·dy, north − row·dy]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Georef {
    /// Coordinate reference system of `west`, `north` and the pixel sizes.
    pub crs: Crs,
    /// Map x of the left edge of column 0 (degrees or metres).
    pub west: f64,
    /// Map y of the top edge of row 0 (degrees or metres).
    pub north: f64,
    /// Pixel width in map units (> 0).
    pub pixel_width: f64,
    /// Pixel height in map units (> 0; rows run southwards).
    pub pixel_height: f64,
}

/// Metric cell sizes of a grid, one value per row (they vary with latitude).
#[derive(Clone, Debug, PartialEq)]
pub struct CellSizes {
    /// East-west extent of a cell of each row, metres.
    pub dx: Vec<f64>,
    /// North-south extent of a cell of each row, metres.
    pub dy: Vec<f64>,
}

impl CellSizes {
    /// The same square cell size for every one of `rows` rows.
    pub fn uniform(rows: usize, cell_m: f64) -> Self {
        CellSizes {
            dx: vec![cell_m; rows],
            dy: vec![cell_m; rows],
        }
    }

    /// Area of a cell of `row` in square metres.
    pub fn area(&self, row: usize) -> f64 {
        self.dx[row] * self.dy[row]
    }

    /// Mean cell size over all rows (geometric mean of dx and dy), metres.
    pub fn mean_cell(&self) -> f64 {
        if self.dx.is_empty() {
            return 0.0;
        }
        let n = self.dx.len() as f64;
        self.dx
            .iter()
            .zip(&self.dy)
            .map(|(a, b)| (a * b).sqrt())
            .sum::<f64>()
            / n
    }
}

impl Georef {
    /// A Web Mercator georeference with square `cell_m` pixels whose top-left corner is at the
    /// origin (the equator, where Mercator metres are true metres). Handy for synthetic grids.
    pub fn local_metric(cell_m: f64) -> Self {
        Georef {
            crs: Crs::Epsg3857,
            west: 0.0,
            north: 0.0,
            pixel_width: cell_m,
            pixel_height: cell_m,
        }
    }

    /// Map coordinates of the centre of pixel `(col, row)`.
    pub fn pixel_centre(&self, col: f64, row: f64) -> (f64, f64) {
        (
            self.west + (col + 0.5) * self.pixel_width,
            self.north - (row + 0.5) * self.pixel_height,
        )
    }

    /// Latitude in degrees of map y in this CRS (for a projected CRS, which needs x too: 0).
    pub fn latitude_of(&self, y: f64) -> f64 {
        match self.crs {
            Crs::Epsg4326 | Crs::Epsg3857 => self.crs.to_lonlat(0.0, y).map_or(0.0, |p| p.1),
            Crs::Projected(_) => 0.0,
        }
    }

    /// Metric cell size `(dx, dy)` in metres of a pixel on row `row` (may be fractional).
    pub fn cell_size_m(&self, row: f64) -> (f64, f64) {
        let y = self.north - (row + 0.5) * self.pixel_height;
        let lat = self.latitude_of(y).clamp(-89.9, 89.9).to_radians();
        match self.crs {
            Crs::Projected(_) => (self.pixel_width, self.pixel_height),
            Crs::Epsg4326 => {
                let k = EARTH_RADIUS_M * std::f64::consts::PI / 180.0;
                (self.pixel_width * k * math::cos(lat), self.pixel_height * k)
            }
            Crs::Epsg3857 => (
                self.pixel_width * math::cos(lat),
                self.pixel_height * math::cos(lat),
            ),
        }
    }

    /// Metric cell sizes for every row of a grid with `rows` rows.
    pub fn cell_sizes(&self, rows: usize) -> CellSizes {
        let (dx, dy) = (0..rows).map(|r| self.cell_size_m(r as f64)).unzip();
        CellSizes { dx, dy }
    }

    /// The georeference of the same extent sampled `factor` times finer.
    pub fn refined(&self, factor: f64) -> Georef {
        Georef {
            pixel_width: self.pixel_width / factor,
            pixel_height: self.pixel_height / factor,
            ..*self
        }
    }

    /// The georeference of the window whose top-left pixel is `(col, row)` of this grid.
    pub fn window(&self, col: i64, row: i64) -> Georef {
        Georef {
            west: self.west + col as f64 * self.pixel_width,
            north: self.north - row as f64 * self.pixel_height,
            ..*self
        }
    }

    /// Bounds `(west, south, east, north)` of a `cols × rows` grid, in map units.
    pub fn bounds(&self, cols: usize, rows: usize) -> (f64, f64, f64, f64) {
        (
            self.west,
            self.north - rows as f64 * self.pixel_height,
            self.west + cols as f64 * self.pixel_width,
            self.north,
        )
    }

    /// Whether the transform is finite, has positive pixel sizes and stays in the CRS's domain.
    pub fn is_sane(&self, cols: usize, rows: usize) -> bool {
        let finite = [self.west, self.north, self.pixel_width, self.pixel_height]
            .iter()
            .all(|v| v.is_finite());
        if !finite || self.pixel_width <= 0.0 || self.pixel_height <= 0.0 {
            return false;
        }
        let (w, s, e, n) = self.bounds(cols, rows);
        match self.crs {
            Crs::Epsg4326 => w >= -360.0 && e <= 360.0 && s >= -90.0 - 1e-9 && n <= 90.0 + 1e-9,
            Crs::Epsg3857 => {
                let lim = std::f64::consts::PI * MERCATOR_RADIUS_M * 1.0001;
                w >= -lim * 2.0 && e <= lim * 2.0 && s >= -lim && n <= lim
            }
            // UTM eastings and northings stay well within ±10⁸ m.
            Crs::Projected(_) => [w, s, e, n].iter().all(|v| v.abs() <= 1e8),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degree_cells_shrink_east_west_with_latitude() {
        let g = Georef {
            crs: Crs::Epsg4326,
            west: 66.0,
            north: 41.0 + 1.0 / 480.0,
            pixel_width: 1.0 / 240.0,
            pixel_height: 1.0 / 240.0,
        };
        let (dx, dy) = g.cell_size_m(0.0);
        assert!((dy - 463.3).abs() < 1.0, "dy {dy}");
        assert!(
            (dx - 463.3 * math::cos(41f64.to_radians())).abs() < 1.0,
            "dx {dx}"
        );
    }

    #[test]
    fn mercator_cells_scale_with_cos_latitude() {
        let g = Georef::local_metric(100.0);
        let (dx, dy) = g.cell_size_m(0.0);
        assert!((dx - 100.0).abs() < 1e-3 && (dy - 100.0).abs() < 1e-3);
        let far = Georef {
            north: 5_000_000.0,
            ..g
        };
        let (dx2, _) = far.cell_size_m(0.0);
        let lat = far.latitude_of(5_000_000.0 - 50.0).to_radians();
        assert!((dx2 - 100.0 * math::cos(lat)).abs() < 1e-6);
        assert!(dx2 < 80.0);
    }
}
