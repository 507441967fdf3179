//! Hillshading: Lambertian illumination of the terrain surface by a distant light, the standard
//! ESRI/GDAL formula `cos(zenith)·cos(slope) + sin(zenith)·sin(slope)·cos(azimuth − aspect)`
//! written in vector form.

use ndarray::Array2;

use super::derivatives::gradient;
use crate::math;
use crate::raster::CellSizes;

/// Default light azimuth, degrees clockwise from north (north-west light).
pub const DEFAULT_AZIMUTH_DEG: f32 = 315.0;
/// Default light altitude above the horizon, degrees.
pub const DEFAULT_ALTITUDE_DEG: f32 = 45.0;

/// Hillshade in [0, 1] for a light at `azimuth_deg` (clockwise from north, towards the light)
/// and `altitude_deg` above the horizon. The surface normal from [`gradient`] is
/// `(−gx, −gy, 1)/√(1+gx²+gy²)` in (east, north, up); the light vector is
/// `(sin az·cos alt, cos az·cos alt, sin alt)`; the shade is their dot product clamped to [0, 1].
/// A flat cell gets `sin(altitude)`. NaN propagates.
pub fn hillshade(
    z: &Array2<f32>,
    cs: &CellSizes,
    azimuth_deg: f32,
    altitude_deg: f32,
) -> Array2<f32> {
    let (gx, gy) = gradient(z, cs);
    let light = Light::new(azimuth_deg, altitude_deg);
    ndarray::Zip::from(&gx)
        .and(&gy)
        .map_collect(|&x, &y| light.shade(x, y))
}

/// A distant light: the unit vector towards it in (east, north, up).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Light {
    east: f64,
    north: f64,
    up: f64,
}

impl Light {
    /// The light at `azimuth_deg` (clockwise from north) and `altitude_deg` above the horizon.
    pub(crate) fn new(azimuth_deg: f32, altitude_deg: f32) -> Light {
        let az = (azimuth_deg as f64).to_radians();
        let alt = (altitude_deg as f64).to_radians();
        Light {
            east: math::sin(az) * math::cos(alt),
            north: math::cos(az) * math::cos(alt),
            up: math::sin(alt),
        }
    }

    /// The shade (0–1, NaN propagates) of a cell of gradient `(x, y)`.
    #[inline]
    pub(crate) fn shade(&self, x: f32, y: f32) -> f32 {
        let (x, y) = (x as f64, y as f64);
        let norm = (1.0 + x * x + y * y).sqrt();
        let s = (-x * self.east - y * self.north + self.up) / norm;
        if s.is_nan() {
            f32::NAN
        } else {
            s.clamp(0.0, 1.0) as f32
        }
    }
}

/// [`hillshade`] scaled to 0..=255 and rounded; NaN cells give 0.
pub fn hillshade_u8(
    z: &Array2<f32>,
    cs: &CellSizes,
    azimuth_deg: f32,
    altitude_deg: f32,
) -> Array2<u8> {
    hillshade(z, cs, azimuth_deg, altitude_deg).mapv(|h| {
        if h.is_nan() {
            0
        } else {
            (h * 255.0).round().clamp(0.0, 255.0) as u8
        }
    })
}
