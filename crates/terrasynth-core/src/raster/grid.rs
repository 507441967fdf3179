//! Grids: a single-layer elevation raster (`Grid`) and a multi-layer raster of named layers on one
//! grid (`LayeredRaster`), both georeferenced and carrying a validity (nodata) mask.

use ndarray::Array2;

use super::error::RasterError;
use super::georef::Georef;

/// The name of the elevation layer in a [`LayeredRaster`].
pub const ELEVATION: &str = "elevation";

/// Sets `data` to NaN wherever the nodata mask `valid` (`true` where a value is valid, on
/// `data`'s shape) is `false`: how a layer that keeps no mask of its own carries its nodata
/// cells. `None` (every value valid) leaves `data` as it is.
pub fn nan_where_invalid(data: &mut Array2<f32>, valid: Option<&Array2<bool>>) {
    if let Some(valid) = valid {
        ndarray::Zip::from(data).and(valid).for_each(|v, &ok| {
            if !ok {
                *v = f32::NAN;
            }
        });
    }
}

/// A georeferenced single-layer raster of `f32` values, row 0 north.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Values, shape `(rows, cols)`.
    pub data: Array2<f32>,
    /// Where the grid lies.
    pub georef: Georef,
    /// `Some(mask)` with `true` where a value is valid; `None` when every value is valid.
    pub valid: Option<Array2<bool>>,
}

impl Grid {
    /// A grid where every value is valid.
    pub fn new(data: Array2<f32>, georef: Georef) -> Self {
        Grid {
            data,
            georef,
            valid: None,
        }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.data.nrows()
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.data.ncols()
    }

    /// Whether the value at `(row, col)` is valid (finite and not masked).
    pub fn is_valid(&self, row: usize, col: usize) -> bool {
        self.data[[row, col]].is_finite() && self.valid.as_ref().is_none_or(|m| m[[row, col]])
    }

    /// Number of valid cells.
    pub fn valid_count(&self) -> usize {
        let mut n = 0;
        for ((r, c), _) in self.data.indexed_iter() {
            if self.is_valid(r, c) {
                n += 1;
            }
        }
        n
    }

    /// Minimum and maximum over valid cells, or `None` when no cell is valid.
    pub fn min_max(&self) -> Option<(f32, f32)> {
        let mut out: Option<(f32, f32)> = None;
        for ((r, c), &v) in self.data.indexed_iter() {
            if self.is_valid(r, c) {
                out = Some(match out {
                    None => (v, v),
                    Some((lo, hi)) => (lo.min(v), hi.max(v)),
                });
            }
        }
        out
    }

    /// Returns an error when no cell holds a valid value.
    pub fn require_some_valid(&self) -> Result<(), RasterError> {
        if self.min_max().is_none() {
            return Err(RasterError::NoValidData);
        }
        Ok(())
    }

    /// A copy where invalid cells are replaced by the value of the nearest valid cell along rows
    /// and columns (a deterministic two-pass fill), so that numeric kernels never see NaN.
    /// Errors when no cell is valid.
    pub fn filled(&self) -> Result<Array2<f32>, RasterError> {
        let (rows, cols) = self.data.dim();
        let (lo, hi) = self.min_max().ok_or(RasterError::NoValidData)?;
        let mean = 0.5 * (lo + hi);
        let mut out = self.data.clone();
        let mut known = Array2::from_shape_fn((rows, cols), |(r, c)| self.is_valid(r, c));
        if known.iter().all(|&k| k) {
            return Ok(out);
        }
        // Iterative dilation: each pass fills unknown cells that have a known 4-neighbour with
        // the mean of those neighbours. Bounded by rows + cols passes; a fallback fills the rest.
        for _ in 0..(rows + cols) {
            let mut changed = false;
            let prev_known = known.clone();
            let prev = out.clone();
            for r in 0..rows {
                for c in 0..cols {
                    if prev_known[[r, c]] {
                        continue;
                    }
                    let mut sum = 0.0f64;
                    let mut n = 0;
                    let neigh = [
                        (r.wrapping_sub(1), c),
                        (r + 1, c),
                        (r, c.wrapping_sub(1)),
                        (r, c + 1),
                    ];
                    for (rr, cc) in neigh {
                        if rr < rows && cc < cols && prev_known[[rr, cc]] {
                            sum += prev[[rr, cc]] as f64;
                            n += 1;
                        }
                    }
                    if n > 0 {
                        out[[r, c]] = (sum / n as f64) as f32;
                        known[[r, c]] = true;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        for (v, k) in out.iter_mut().zip(known.iter()) {
            if !k {
                *v = mean;
            }
        }
        Ok(out)
    }
}

/// Several named layers on one grid (elevation first by convention), sharing a georeference and
/// a validity mask.
#[derive(Clone, Debug, PartialEq)]
pub struct LayeredRaster {
    /// Where the grid lies.
    pub georef: Georef,
    /// Named layers, all of the same shape.
    pub layers: Vec<(String, Array2<f32>)>,
    /// `Some(mask)` with `true` where values are valid; `None` when all are.
    pub valid: Option<Array2<bool>>,
}

impl LayeredRaster {
    /// A raster with a single elevation layer taken from `grid`.
    pub fn from_elevation(grid: Grid) -> Self {
        LayeredRaster {
            georef: grid.georef,
            layers: vec![(ELEVATION.to_string(), grid.data)],
            valid: grid.valid,
        }
    }

    /// Shape `(rows, cols)` of the layers, `(0, 0)` when there are none.
    pub fn dim(&self) -> (usize, usize) {
        self.layers.first().map_or((0, 0), |(_, a)| a.dim())
    }

    /// The layer called `name`.
    pub fn layer(&self, name: &str) -> Option<&Array2<f32>> {
        self.layers.iter().find(|(n, _)| n == name).map(|(_, a)| a)
    }

    /// Adds a layer, checking that its shape matches and its name is new.
    pub fn push_layer(&mut self, name: &str, data: Array2<f32>) -> Result<(), RasterError> {
        if !self.layers.is_empty() && data.dim() != self.dim() {
            let (er, ec) = self.dim();
            return Err(RasterError::LayerMismatch(format!(
                "layer `{name}` is {}×{} but the grid is {er}×{ec}",
                data.nrows(),
                data.ncols()
            )));
        }
        if self.layer(name).is_some() {
            return Err(RasterError::LayerMismatch(format!(
                "layer `{name}` given twice"
            )));
        }
        self.layers.push((name.to_string(), data));
        Ok(())
    }

    /// The elevation layer as a [`Grid`].
    pub fn elevation(&self) -> Option<Grid> {
        self.layer(ELEVATION).map(|a| Grid {
            data: a.clone(),
            georef: self.georef,
            valid: self.valid.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Masked cells become NaN, valid ones keep their value (a NaN already there stays), and
    /// no mask changes nothing.
    #[test]
    fn nan_where_invalid_marks_exactly_the_masked_cells() {
        let original = ndarray::array![[1.0, 2.0, f32::NAN], [4.0, 5.0, 6.0]];
        let valid = ndarray::array![[true, false, true], [false, true, true]];
        let mut data = original.clone();
        nan_where_invalid(&mut data, Some(&valid));
        for ((r, c), &v) in data.indexed_iter() {
            if valid[[r, c]] {
                assert_eq!(v.to_bits(), original[[r, c]].to_bits(), "({r}, {c})");
            } else {
                assert!(v.is_nan(), "({r}, {c}) is {v}");
            }
        }
        let mut unmasked = original.clone();
        nan_where_invalid(&mut unmasked, None);
        assert_eq!(unmasked[[1, 0]], 4.0);
        assert_eq!(unmasked[[0, 1]], 2.0);
    }
}
