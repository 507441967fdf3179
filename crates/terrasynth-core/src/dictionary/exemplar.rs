//! The one way an exemplar is assembled for a dictionary build, used by the command line, the
//! configured worlds and the admin API's build jobs: the elevation on square cells (a
//! longitude/latitude grid's columns resampled: [`SquareCells`]) with its invalid cells filled
//! (so numeric kernels never see NaN) and kept out of every patch by the validity mask, windows
//! held out for evaluation, and the extra layers in a fixed order — the caller's own layers, then
//! the derived layers (`log_area`, `northness`), then the species layers a hook supplies (the
//! landscape's niche model, or rasters the user brought).

use ndarray::Array2;

use super::atoms::LayerKind;
use super::build::Exemplar;
use super::derive::derived_layers;
use super::error::DictionaryError;
use crate::raster::{CellSizes, Grid, SquareCells};

/// One named extra layer of an exemplar: `(name, values on the exemplar's grid, kind)`.
pub type ExemplarLayer = (String, Array2<f32>, LayerKind);

/// A pixel window `col,row,width,height` of an exemplar kept out of the dictionary (for held-out
/// evaluation) or cut out of a raster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelWindow {
    /// First column.
    pub col: usize,
    /// First row.
    pub row: usize,
    /// Width in cells.
    pub width: usize,
    /// Height in cells.
    pub height: usize,
}

impl PixelWindow {
    /// One past the last column, or `None` when it overflows.
    pub fn col_end(&self) -> Option<usize> {
        self.col.checked_add(self.width)
    }

    /// One past the last row, or `None` when it overflows.
    pub fn row_end(&self) -> Option<usize> {
        self.row.checked_add(self.height)
    }
}

impl std::str::FromStr for PixelWindow {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let v: Vec<usize> = s
            .split(',')
            .map(|p| p.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("`{s}`: {e}; expected COL,ROW,WIDTH,HEIGHT"))?;
        match v[..] {
            [col, row, width, height] => Ok(PixelWindow {
                col,
                row,
                width,
                height,
            }),
            _ => Err(format!("`{s}`: expected COL,ROW,WIDTH,HEIGHT")),
        }
    }
}

/// How an exemplar is assembled (see [`Exemplar::from_grid`]).
#[derive(Clone, Debug, Default)]
pub struct ExemplarOptions {
    /// The caller's own layers on the exemplar's grid (uploaded or given on the command line).
    pub extra: Vec<ExemplarLayer>,
    /// Windows kept out of every patch.
    pub exclude: Vec<PixelWindow>,
    /// Whether to add the derived layers (`log_area`, `northness`).
    pub derive: bool,
}

impl Exemplar {
    /// The build exemplar of `grid`: elevation with invalid cells filled, a validity mask that
    /// excludes them and the `exclude` windows, the metric cell size, and the layers `extra`,
    /// derived (with `derive`) and `species(filled elevation, cells)`, in that order.
    ///
    /// A grid whose cells are not square in metres (longitude/latitude away from the equator) is
    /// first resampled to square cells ([`SquareCells`]): elevation and continuous `extra` layers
    /// with its Lanczos-3 taps, class layers by nearest sample, and validity (with the `exclude`
    /// windows, given in the input's cells) false wherever an invalid or excluded cell was drawn
    /// on. `extra` layers come on the input's grid; `species` sees the squared elevation and cells.
    pub fn from_grid(
        grid: &Grid,
        options: ExemplarOptions,
        species: impl FnOnce(&Array2<f32>, &CellSizes) -> Vec<ExemplarLayer>,
    ) -> Result<Exemplar, DictionaryError> {
        let raster = |e: crate::raster::RasterError| DictionaryError::InvalidParams(e.to_string());
        grid.require_some_valid().map_err(raster)?;
        let (rows0, cols0) = grid.data.dim();
        for (name, values, _) in &options.extra {
            if values.dim() != (rows0, cols0) {
                return Err(DictionaryError::InvalidParams(format!(
                    "layer `{name}` is {}×{} but the exemplar is {cols0}×{rows0}",
                    values.ncols(),
                    values.nrows()
                )));
            }
        }
        // Validity and exclusions in the input's own cells, before squaring.
        let mut valid = Array2::from_shape_fn((rows0, cols0), |(r, c)| grid.is_valid(r, c));
        for ex in &options.exclude {
            let r1 = ex.row_end().unwrap_or(usize::MAX).min(rows0);
            let c1 = ex.col_end().unwrap_or(usize::MAX).min(cols0);
            for r in ex.row.min(r1)..r1 {
                for c in ex.col.min(c1)..c1 {
                    valid[[r, c]] = false;
                }
            }
        }
        let square = SquareCells::for_grid(&grid.georef, rows0, cols0);
        let filled = square
            .resample(&grid.filled().map_err(raster)?)
            .map_err(raster)?;
        let valid = square.all_taps_valid(&valid).map_err(raster)?;
        let cells = square.georef(&grid.georef).cell_sizes(filled.nrows());
        let mut layers = Vec::with_capacity(options.extra.len());
        for (name, values, kind) in options.extra {
            let values = match kind {
                LayerKind::Continuous => square.resample(&values),
                LayerKind::Class { .. } => square.nearest(&values),
            }
            .map_err(raster)?;
            layers.push((name, values, kind));
        }
        if options.derive {
            layers.extend(derived_layers(&filled, &cells));
        }
        layers.extend(species(&filled, &cells));
        Ok(Exemplar {
            elevation: filled,
            valid: Some(valid),
            cell_m: cells.mean_cell(),
            layers,
        })
    }
}

/// No species layers (the hook for exemplars built without a landscape).
pub fn no_species(_: &Array2<f32>, _: &CellSizes) -> Vec<ExemplarLayer> {
    Vec::new()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Georef;

    fn hill() -> Grid {
        let mut g = Grid::new(
            Array2::from_shape_fn((40, 50), |(r, c)| (r * 3 + c) as f32),
            Georef::local_metric(30.0),
        );
        g.data[[5, 7]] = f32::NAN;
        g
    }

    #[test]
    fn layers_come_in_a_fixed_order_and_invalid_cells_are_masked() {
        let extra = vec![(
            "forest".to_string(),
            Array2::zeros((40, 50)),
            LayerKind::Continuous,
        )];
        let ex = Exemplar::from_grid(
            &hill(),
            ExemplarOptions {
                extra,
                exclude: vec![PixelWindow {
                    col: 45,
                    row: 38,
                    width: usize::MAX,
                    height: 9,
                }],
                derive: true,
            },
            |_, _| {
                vec![(
                    "spruce".to_string(),
                    Array2::zeros((40, 50)),
                    LayerKind::Continuous,
                )]
            },
        )
        .unwrap();
        let names: Vec<&str> = ex.layers.iter().map(|(n, _, _)| n.as_str()).collect();
        assert_eq!(names, ["forest", "log_area", "northness", "spruce"]);
        let valid = ex.valid.unwrap();
        assert!(!valid[[5, 7]] && valid[[5, 8]]);
        assert!(ex.elevation[[5, 7]].is_finite());
        // The exclusion (its width overflows) is clamped to the grid.
        assert!(!valid[[39, 49]] && !valid[[38, 45]] && valid[[37, 45]] && valid[[39, 44]]);
    }

    #[test]
    fn degree_grids_are_squared_with_their_layers_and_exclusions() {
        // 15″ cells at 42° N are about 0.74 times as wide as tall: 200 columns become 148.
        let georef = Georef {
            crs: crate::raster::Crs::Epsg4326,
            west: 70.0,
            north: 42.1,
            pixel_width: 1.0 / 240.0,
            pixel_height: 1.0 / 240.0,
        };
        let grid = Grid::new(
            Array2::from_shape_fn((24, 200), |(r, c)| (r + 2 * c) as f32),
            georef,
        );
        let extra = vec![
            (
                "wetness".to_string(),
                Array2::from_elem((24, 200), 0.25f32),
                LayerKind::Continuous,
            ),
            (
                "soil".to_string(),
                Array2::from_shape_fn((24, 200), |(_, c)| (c / 50) as f32),
                LayerKind::Class {
                    group: "soil".to_string(),
                },
            ),
        ];
        let exclude = vec![PixelWindow {
            col: 100,
            row: 0,
            width: 100,
            height: 24,
        }];
        let ex = Exemplar::from_grid(
            &grid,
            ExemplarOptions {
                extra,
                exclude,
                derive: false,
            },
            |filled, cells| {
                assert_eq!(filled.dim(), (24, 148));
                assert!((cells.dx[0] / cells.dy[0] - 1.0).abs() < 0.02);
                Vec::new()
            },
        )
        .unwrap();
        assert_eq!(ex.elevation.dim(), (24, 148));
        assert!((ex.cell_m - 463.3).abs() < 2.0, "{}", ex.cell_m);
        assert!(ex.layers[0].1.iter().all(|v| (v - 0.25).abs() < 1e-6));
        assert!(ex.layers[1].1.iter().all(|v| v.fract() == 0.0));
        // Input column 100 sits at output column 74.3 (source coordinate (j + ½)/0.743 − ½);
        // Lanczos-3 widened to the output spacing reaches 3 output columns (4.04 input columns),
        // so column 72 (centre 97.1) is the first to draw on it and 71 (centre 95.7) is not.
        let valid = ex.valid.unwrap();
        let first = (0..148).find(|&c| !valid[[5, c]]);
        assert_eq!(first, Some(72));
        assert!((74..148).all(|c| !valid[[23, c]]));
    }

    #[test]
    fn mismatched_layers_and_empty_grids_are_errors() {
        let extra = vec![(
            "forest".to_string(),
            Array2::zeros((4, 5)),
            LayerKind::Continuous,
        )];
        let err = Exemplar::from_grid(
            &hill(),
            ExemplarOptions {
                extra,
                ..Default::default()
            },
            no_species,
        )
        .unwrap_err();
        assert!(err.to_string().contains("layer `forest` is 5×4"), "{err}");
        let empty = Grid::new(
            Array2::from_elem((4, 4), f32::NAN),
            Georef::local_metric(1.0),
        );
        assert!(Exemplar::from_grid(&empty, ExemplarOptions::default(), no_species).is_err());
    }
}
