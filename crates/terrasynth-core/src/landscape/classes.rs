//! Land-cover classes (issue #15; procedural texturing paper §IV.D): an RGB image (a satellite
//! image on the base grid) classified into named classes by per-class HSV ranges, and the
//! `class.<name>` weight of a class (1 inside, 0 outside, smoothed over a distance).
//!
//! Hue is in degrees `[0, 360)`, saturation and value in `[0, 1]` (the usual hexcone model). A
//! hue range whose minimum exceeds its maximum wraps through 0° (reds: `[330, 20]`). A pixel
//! takes the first class (in the definition's order) whose three ranges all hold it, else none.
//!
//! A world's classes ([`ClassesConfig`], `[classes]` in a world file, `"classes"` in the admin
//! API) come either from a class raster (integers) with a `legend` `{value: name}`, or from an RGB
//! image (a raster of packed `0xRRGGBB` values, see [`pack_rgb`]) with `hsv` ranges; either way
//! they become a raster of class codes ([`ClassesConfig::codes`]: 1 + the index of the class in
//! [`ClassesConfig::names`], 0 for none) and one smoothed weight grid per class.

use std::collections::BTreeMap;

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use super::LandscapeError;
use crate::dictionary::LayerKind;
pub use crate::raster::png16::{pack_rgb, unpack_rgb};

/// The HSV ranges of one class, each `[min, max]` inclusive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HsvRanges {
    /// Hue, degrees in `[0, 360]`; `min > max` wraps through 0°.
    pub h: [f32; 2],
    /// Saturation, `[0, 1]`.
    pub s: [f32; 2],
    /// Value (brightness), `[0, 1]`.
    pub v: [f32; 2],
}

/// A named class of an RGB classification.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HsvClass {
    /// The class name (`class.<name>` in materials and species).
    pub name: String,
    /// Its HSV ranges.
    pub hsv: HsvRanges,
}

/// Checks class names (non-empty, unique, letters, digits, `_` or `-`) and HSV ranges (hue in
/// `[0, 360]`, saturation and value in `[0, 1]` with `min ≤ max`); the error names the class
/// and the range.
pub fn validate_classes(classes: &[HsvClass]) -> Result<(), LandscapeError> {
    let bad = |m: String| Err(LandscapeError::Invalid(m));
    for (i, c) in classes.iter().enumerate() {
        if c.name.is_empty()
            || !c
                .name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
        {
            return bad(format!(
                "classes[{i}].name `{}` must be letters, digits, `_` or `-`",
                c.name
            ));
        }
        if classes[..i].iter().any(|o| o.name == c.name) {
            return bad(format!("classes[{i}].name `{}` is repeated", c.name));
        }
        let in_range =
            |r: [f32; 2], hi: f32| r.iter().all(|&x| x.is_finite() && (0.0..=hi).contains(&x));
        if !in_range(c.hsv.h, 360.0) {
            return bad(format!(
                "classes[{i}] ({}): hsv.h must lie within 0–360 degrees",
                c.name
            ));
        }
        for (what, r) in [("s", c.hsv.s), ("v", c.hsv.v)] {
            if !in_range(r, 1.0) || r[0] > r[1] {
                return bad(format!(
                    "classes[{i}] ({}): hsv.{what} must be [min, max] within 0–1",
                    c.name
                ));
            }
        }
    }
    Ok(())
}

/// Hue (degrees, `[0, 360)`, 0 for greys), saturation and value of an 8-bit RGB colour.
pub fn rgb_to_hsv(rgb: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = rgb.map(|x| f32::from(x) / 255.0);
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let d = max - min;
    let s = if max > 0.0 { d / max } else { 0.0 };
    let h = if d == 0.0 {
        0.0
    } else if max == r {
        60.0 * ((g - b) / d).rem_euclid(6.0)
    } else if max == g {
        60.0 * ((b - r) / d + 2.0)
    } else {
        60.0 * ((r - g) / d + 4.0)
    };
    [h.rem_euclid(360.0), s, max]
}

fn holds(r: [f32; 2], x: f32) -> bool {
    r[0] <= x && x <= r[1]
}

fn hue_holds(r: [f32; 2], h: f32) -> bool {
    if r[0] <= r[1] {
        holds(r, h)
    } else {
        h >= r[0] || h <= r[1]
    }
}

/// Most classes a world may define.
pub const MAX_CLASSES: usize = 64;
/// Largest smoothing radius, cells of the class raster.
pub const MAX_SMOOTHING_CELLS: usize = 64;

/// Where a world's land-cover classes come from and how their weights are smoothed (the raster
/// itself is given next to it: a file in a world file, an exemplar layer in the admin API).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassesConfig {
    /// A class raster's legend: raster value (an integer 0–65535, written as a string key) →
    /// class name. Several values may name one class. Exclusive with `hsv`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub legend: BTreeMap<String, String>,
    /// An RGB image's classes by HSV ranges, first match wins. Exclusive with `legend`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hsv: Vec<HsvClass>,
    /// Distance, metres, over which a class weight falls from 1 to 0 across a class border: the
    /// weight is box-averaged over `2·r + 1` cells with `r = round(smoothing_m / (2·cell))`
    /// (0: the sharp indicator, still interpolated bilinearly between cells on tiles).
    #[serde(default)]
    pub smoothing_m: f32,
}

impl ClassesConfig {
    /// Whether the classes come from an RGB image (`hsv`) rather than a class raster (`legend`).
    pub fn is_rgb(&self) -> bool {
        !self.hsv.is_empty()
    }

    /// The class names in code order (code `k + 1` is `names()[k]`): the `hsv` classes in their
    /// order, or the legend's names in the order of their first value.
    pub fn names(&self) -> Vec<String> {
        if self.is_rgb() {
            return self.hsv.iter().map(|c| c.name.clone()).collect();
        }
        let mut out: Vec<String> = Vec::new();
        for (_, n) in self.legend_values().unwrap_or_default() {
            if !out.contains(&n) {
                out.push(n);
            }
        }
        out
    }

    /// The legend as `(value, name)` pairs, in value order; the error names a bad key.
    fn legend_values(&self) -> Result<Vec<(u16, String)>, LandscapeError> {
        let mut v = Vec::with_capacity(self.legend.len());
        for (k, n) in &self.legend {
            let value = k.trim().parse::<u16>().map_err(|_| {
                LandscapeError::Invalid(format!(
                    "classes.legend: key `{k}` must be an integer raster value 0–65535"
                ))
            })?;
            v.push((value, n.clone()));
        }
        v.sort_by_key(|p| p.0);
        Ok(v)
    }

    /// Checks the settings: exactly one of `legend` and `hsv`, valid names and ranges, at most
    /// [`MAX_CLASSES`] classes, a finite non-negative `smoothing_m`.
    pub fn validate(&self) -> Result<(), LandscapeError> {
        let bad = |m: String| Err(LandscapeError::Invalid(m));
        match (self.legend.is_empty(), self.hsv.is_empty()) {
            (true, true) => {
                return bad(
                    "classes: give a `legend` (class raster) or `hsv` ranges (RGB image)".into(),
                )
            }
            (false, false) => {
                return bad("classes: give either a `legend` or `hsv` ranges, not both".into())
            }
            _ => {}
        }
        if self.is_rgb() {
            validate_classes(&self.hsv)?;
        } else {
            for (value, name) in self.legend_values()? {
                if !crate::names::is_valid_name(&name) {
                    return bad(format!(
                        "classes.legend: name `{name}` of value {value} must be {}",
                        crate::names::NAME_RULE
                    ));
                }
            }
        }
        let n = self.names().len();
        if n > MAX_CLASSES {
            return bad(format!("classes: {n} classes (at most {MAX_CLASSES})"));
        }
        if !(self.smoothing_m.is_finite() && self.smoothing_m >= 0.0) {
            return bad("classes.smoothing_m must be a finite distance ≥ 0".into());
        }
        Ok(())
    }

    /// The smoothing radius in cells of `cell_m` metres; the error names `smoothing_m` when it
    /// exceeds [`MAX_SMOOTHING_CELLS`] cells.
    pub fn radius_cells(&self, cell_m: f64) -> Result<usize, LandscapeError> {
        if self.smoothing_m <= 0.0 {
            return Ok(0);
        }
        let r = (f64::from(self.smoothing_m) / (2.0 * cell_m)).round();
        if !(r.is_finite() && r <= MAX_SMOOTHING_CELLS as f64) {
            return Err(LandscapeError::Invalid(format!(
                "classes.smoothing_m {} m is more than {MAX_SMOOTHING_CELLS} cells of {cell_m:.1} m \
                 each way",
                self.smoothing_m
            )));
        }
        Ok(r as usize)
    }

    /// The class codes of `raster` (a class raster with a legend, or packed RGB with `hsv`):
    /// 1 + the class's index in [`ClassesConfig::names`], 0 for none (NaN cells, or colours no
    /// range holds). A class raster's value must be an integer in the legend: the error names
    /// the first value (in raster order) that is not.
    pub fn codes(&self, raster: &Array2<f32>) -> Result<Array2<u16>, LandscapeError> {
        if self.is_rgb() {
            let mut rgb = Array2::from_elem(raster.dim(), [0u8; 3]);
            let mut valid = Array2::from_elem(raster.dim(), false);
            for ((p, v), &x) in rgb.iter_mut().zip(valid.iter_mut()).zip(raster) {
                if let Some(c) = unpack_rgb(x) {
                    *p = c;
                    *v = true;
                } else if !x.is_nan() {
                    return Err(LandscapeError::Invalid(format!(
                        "classes: the RGB raster holds {x}, not a packed 0xRRGGBB colour"
                    )));
                }
            }
            let mut codes = classify_rgb(&self.hsv, &rgb);
            ndarray::Zip::from(&mut codes)
                .and(&valid)
                .for_each(|c, &v| {
                    if !v {
                        *c = 0;
                    }
                });
            return Ok(codes);
        }
        let names = self.names();
        let table: Vec<(u16, u16)> = self
            .legend_values()?
            .into_iter()
            .map(|(value, n)| {
                let code = names.iter().position(|x| *x == n).map_or(0, |k| k + 1);
                (value, code as u16)
            })
            .collect();
        let mut out = Array2::zeros(raster.dim());
        for (o, &x) in out.iter_mut().zip(raster) {
            if x.is_nan() {
                continue;
            }
            let code = (x.fract() == 0.0 && (0.0..=65535.0).contains(&x))
                .then(|| table.iter().find(|p| f32::from(p.0) == x).map(|p| p.1))
                .flatten();
            match code {
                Some(c) => *o = c,
                None => {
                    return Err(LandscapeError::Invalid(format!(
                        "classes.legend has no entry for raster value {x}"
                    )))
                }
            }
        }
        Ok(out)
    }
}

/// The distinct values of a class raster (NaN cells skipped), ascending; the error names a value
/// that is no integer 0–65535, or more than [`MAX_CLASSES`] values.
pub fn class_values(raster: &Array2<f32>) -> Result<Vec<u16>, LandscapeError> {
    let mut values = std::collections::BTreeSet::new();
    for &x in raster {
        if x.is_nan() {
            continue;
        }
        if !(x.fract() == 0.0 && (0.0..=65535.0).contains(&x)) {
            return Err(LandscapeError::Invalid(format!(
                "class raster value {x} is no integer 0–65535"
            )));
        }
        values.insert(x as u16);
        if values.len() > MAX_CLASSES {
            return Err(LandscapeError::Invalid(format!(
                "the class raster holds more than {MAX_CLASSES} values"
            )));
        }
    }
    Ok(values.into_iter().collect())
}

/// The class layers of a dictionary build (multi-layer synthesis, class layers): one layer
/// `{group}_{v}` per value `v` of `values`, 1 where `raster` holds `v` and 0 elsewhere, of kind
/// [`LayerKind::Class`] in group `group` (matching weighs the group by its name).
pub fn class_layers(
    group: &str,
    raster: &Array2<f32>,
    values: &[u16],
) -> Vec<(String, Array2<f32>, LayerKind)> {
    values
        .iter()
        .map(|&v| {
            let x = f32::from(v);
            (
                format!("{group}_{v}"),
                raster.mapv(|r| if r == x { 1.0 } else { 0.0 }),
                LayerKind::Class {
                    group: group.to_string(),
                },
            )
        })
        .collect()
}

/// The class of one colour: the index of the first class whose ranges hold it.
pub fn class_of(classes: &[HsvClass], rgb: [u8; 3]) -> Option<usize> {
    let [h, s, v] = rgb_to_hsv(rgb);
    classes
        .iter()
        .position(|c| hue_holds(c.hsv.h, h) && holds(c.hsv.s, s) && holds(c.hsv.v, v))
}

/// Classifies an RGB image: per pixel, 1 + the index of its class, 0 where no class holds it.
pub fn classify_rgb(classes: &[HsvClass], rgb: &Array2<[u8; 3]>) -> Array2<u16> {
    rgb.mapv(|p| class_of(classes, p).map_or(0, |k| k as u16 + 1))
}

/// The weight of class `code` (a value of a class raster): 1 on its cells, 0 elsewhere, then
/// box-averaged over `radius` cells each way (separable, edges clamped), so it falls from 1 to 0
/// over `2·radius + 1` cells across a class border. `radius = 0`: the sharp indicator.
pub fn class_weight(classes: &Array2<u16>, code: u16, radius: usize) -> Array2<f32> {
    let ind = classes.mapv(|c| if c == code { 1.0f32 } else { 0.0 });
    if radius == 0 {
        return ind;
    }
    let blur_rows = box_along(&ind, radius, true);
    box_along(&blur_rows, radius, false)
}

/// Box average along columns (`vertical`) or rows, window `2·radius + 1`, edges clamped.
fn box_along(a: &Array2<f32>, radius: usize, vertical: bool) -> Array2<f32> {
    let (rows, cols) = a.dim();
    let n = 2 * radius + 1;
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let mut sum = 0.0f64;
        for k in 0..n {
            let off = k as i64 - radius as i64;
            let (rr, cc) = if vertical {
                ((r as i64 + off).clamp(0, rows as i64 - 1) as usize, c)
            } else {
                (r, (c as i64 + off).clamp(0, cols as i64 - 1) as usize)
            };
            sum += f64::from(a[[rr, cc]]);
        }
        (sum / n as f64) as f32
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn class(name: &str, h: [f32; 2], s: [f32; 2], v: [f32; 2]) -> HsvClass {
        HsvClass {
            name: name.into(),
            hsv: HsvRanges { h, s, v },
        }
    }

    /// Water (blues), forest (dark greens), snow (bright greys), and red roofs across 0°.
    fn classes() -> Vec<HsvClass> {
        vec![
            class("water", [180.0, 250.0], [0.3, 1.0], [0.1, 1.0]),
            class("forest", [70.0, 170.0], [0.2, 1.0], [0.0, 0.6]),
            class("snow", [0.0, 360.0], [0.0, 0.1], [0.85, 1.0]),
            class("roofs", [340.0, 20.0], [0.5, 1.0], [0.3, 1.0]),
        ]
    }

    #[test]
    fn hsv_of_known_colours() {
        // Worked by hand: pure primaries, a grey, and (0, 51, 102): max = b = 0.4, d = 0.4,
        // h = 60·((0 − 0.2)/0.4 + 4) = 210°, s = 1, v = 0.4.
        assert_eq!(rgb_to_hsv([255, 0, 0]), [0.0, 1.0, 1.0]);
        assert_eq!(rgb_to_hsv([0, 255, 0]), [120.0, 1.0, 1.0]);
        assert_eq!(rgb_to_hsv([0, 0, 255]), [240.0, 1.0, 1.0]);
        assert_eq!(rgb_to_hsv([128, 128, 128])[..2], [0.0, 0.0]);
        let [h, s, v] = rgb_to_hsv([0, 51, 102]);
        assert!((h - 210.0).abs() < 1e-4 && (s - 1.0).abs() < 1e-6 && (v - 0.4).abs() < 1e-6);
        // (255, 0, 51): max = r, (g − b)/d = −0.2 → −0.2 mod 6 = 5.8 → 348°.
        assert!((rgb_to_hsv([255, 0, 51])[0] - 348.0).abs() < 1e-3);
    }

    #[test]
    fn a_small_image_gets_the_classes_worked_by_hand() {
        // 3 × 3 pixels; expected class per pixel worked by hand from the HSV values:
        //  (0, 51, 102)    h 210 s 1    v 0.4  → water
        //  (30, 100, 40)   h 129 s 0.7  v 0.39 → forest
        //  (250, 250, 252) h 240 s 0.008 v 0.99 → snow (water needs s ≥ 0.3)
        //  (200, 30, 40)   h 356 s 0.85 v 0.78 → roofs (wrapping hue range)
        //  (200, 60, 20)   h 13  s 0.9  v 0.78 → roofs
        //  (120, 120, 120) h 0   s 0    v 0.47 → none (snow needs v ≥ 0.85)
        //  (60, 200, 60)   h 120 s 0.7  v 0.78 → none (forest needs v ≤ 0.6)
        //  (20, 200, 200)  h 180 s 0.9  v 0.78 → water (inclusive minimum)
        //  (220, 200, 40)  h 53  s 0.82 v 0.86 → none
        let px = [
            [0, 51, 102],
            [30, 100, 40],
            [250, 250, 252],
            [200, 30, 40],
            [200, 60, 20],
            [120, 120, 120],
            [60, 200, 60],
            [20, 200, 200],
            [220, 200, 40],
        ];
        let img = Array2::from_shape_fn((3, 3), |(r, c)| px[3 * r + c]);
        let got = classify_rgb(&classes(), &img);
        let want = ndarray::arr2(&[[1u16, 2, 3], [4, 4, 0], [0, 1, 0]]);
        assert_eq!(got, want);
    }

    #[test]
    fn bad_ranges_and_names_are_refused_by_name() {
        let mut c = classes();
        assert!(validate_classes(&c).is_ok());
        c[1].hsv.s = [0.5, 1.2];
        let e = validate_classes(&c).unwrap_err().to_string();
        assert!(e.contains("forest") && e.contains("hsv.s"), "{e}");
        let mut c = classes();
        c[0].hsv.h = [-10.0, 200.0];
        let e = validate_classes(&c).unwrap_err().to_string();
        assert!(e.contains("water") && e.contains("hsv.h"), "{e}");
        let mut c = classes();
        c[2].hsv.v = [0.9, 0.8];
        assert!(validate_classes(&c)
            .unwrap_err()
            .to_string()
            .contains("hsv.v"));
        let mut c = classes();
        c[3].name = "water".into();
        assert!(validate_classes(&c)
            .unwrap_err()
            .to_string()
            .contains("repeated"));
        let mut c = classes();
        c[3].name = "class.x".into();
        assert!(validate_classes(&c).is_err());
    }

    #[test]
    fn a_legend_maps_raster_values_to_codes_and_names_missing_values() {
        let cfg = ClassesConfig {
            legend: [("10", "forest"), ("20", "rock"), ("30", "forest")]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            ..ClassesConfig::default()
        };
        cfg.validate().unwrap();
        assert_eq!(cfg.names(), vec!["forest".to_string(), "rock".to_string()]);
        let raster = ndarray::arr2(&[[10.0f32, 20.0], [30.0, f32::NAN]]);
        // 10 and 30 are forest (code 1), 20 rock (code 2), NaN no class.
        assert_eq!(
            cfg.codes(&raster).unwrap(),
            ndarray::arr2(&[[1u16, 2], [1, 0]])
        );
        let e = cfg
            .codes(&ndarray::arr2(&[[10.0f32, 25.0]]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no entry for raster value 25"), "{e}");
        let e = cfg
            .codes(&ndarray::arr2(&[[10.5f32]]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("10.5"), "{e}");
        let mut bad = cfg.clone();
        bad.legend.insert("x".into(), "a".into());
        assert!(bad.validate().unwrap_err().to_string().contains("`x`"));
        let mut both = cfg.clone();
        both.hsv = classes();
        assert!(both
            .validate()
            .unwrap_err()
            .to_string()
            .contains("not both"));
        assert!(ClassesConfig::default().validate().is_err());
        let mut far = cfg;
        far.smoothing_m = 1000.0;
        // r = round(1000 / (2·10)) = 50 cells; 1000 m over 5 m cells is 100 > 64.
        assert_eq!(far.radius_cells(10.0).unwrap(), 50);
        assert!(far
            .radius_cells(5.0)
            .unwrap_err()
            .to_string()
            .contains("smoothing_m"));
    }

    #[test]
    fn packed_rgb_rasters_are_classified_by_hsv() {
        assert_eq!(pack_rgb([1, 2, 3]), 65536.0 + 512.0 + 3.0);
        assert_eq!(unpack_rgb(pack_rgb([255, 254, 253])), Some([255, 254, 253]));
        assert_eq!(unpack_rgb(-1.0), None);
        let cfg = ClassesConfig {
            hsv: classes(),
            ..ClassesConfig::default()
        };
        cfg.validate().unwrap();
        // (0, 51, 102) water, (30, 100, 40) forest, NaN none, (120, 120, 120) none.
        let raster = ndarray::arr2(&[
            [pack_rgb([0, 51, 102]), pack_rgb([30, 100, 40])],
            [f32::NAN, pack_rgb([120, 120, 120])],
        ]);
        assert_eq!(
            cfg.codes(&raster).unwrap(),
            ndarray::arr2(&[[1u16, 2], [0, 0]])
        );
        assert!(cfg.codes(&ndarray::arr2(&[[0.5f32]])).is_err());
    }

    #[test]
    fn class_weight_is_one_inside_zero_far_outside_and_ramps_over_the_distance() {
        // Left half class 1, right half class 2, 12 columns.
        let raster = Array2::from_shape_fn((4, 12), |(_, c)| if c < 6 { 1u16 } else { 2 });
        let sharp = class_weight(&raster, 1, 0);
        assert_eq!(sharp[[0, 0]], 1.0);
        assert_eq!(sharp[[0, 6]], 0.0);
        let w = class_weight(&raster, 1, 2);
        // Five-cell box: deep inside 1, far outside 0, across the border 4/5, 3/5, 2/5, 1/5.
        assert_eq!(w[[1, 0]], 1.0);
        assert_eq!(w[[1, 3]], 1.0);
        assert_eq!(w[[1, 11]], 0.0);
        for (c, want) in [(4, 0.8f32), (5, 0.6), (6, 0.4), (7, 0.2), (8, 0.0)] {
            assert!((w[[2, c]] - want).abs() < 1e-6, "col {c}: {}", w[[2, c]]);
        }
        // Complementary classes sum to 1 everywhere.
        let w2 = class_weight(&raster, 2, 2);
        assert!(w.iter().zip(&w2).all(|(a, b)| (a + b - 1.0).abs() < 1e-6));
    }
}
