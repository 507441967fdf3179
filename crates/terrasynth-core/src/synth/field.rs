//! Windows onto the infinite pixel plane of a level, and fields (elevation plus extra layers)
//! held over such a window.

use std::fmt;

use ndarray::Array2;

/// A rectangle of a level's global pixel plane: columns `col0 .. col0+cols`, rows
/// `row0 .. row0+rows`. Global coordinates may be negative (margins beyond a raster's edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Window {
    /// First column.
    pub col0: i64,
    /// First row.
    pub row0: i64,
    /// Number of columns.
    pub cols: usize,
    /// Number of rows.
    pub rows: usize,
}

impl fmt::Display for Window {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[{}..{}) × [{}..{})",
            self.col0,
            self.col0 + self.cols as i64,
            self.row0,
            self.row0 + self.rows as i64
        )
    }
}

impl Window {
    /// A window from its first column/row and size.
    pub fn new(col0: i64, row0: i64, cols: usize, rows: usize) -> Self {
        Window {
            col0,
            row0,
            cols,
            rows,
        }
    }

    /// The window spanning `[col0, col1) × [row0, row1)`; empty when reversed.
    pub fn from_bounds(col0: i64, row0: i64, col1: i64, row1: i64) -> Self {
        Window {
            col0,
            row0,
            cols: (col1 - col0).max(0) as usize,
            rows: (row1 - row0).max(0) as usize,
        }
    }

    /// This window with `margin` more pixels on every side (a halo).
    pub fn grown(&self, margin: i64) -> Self {
        Window::from_bounds(
            self.col0 - margin,
            self.row0 - margin,
            self.col1() + margin,
            self.row1() + margin,
        )
    }

    /// One past the last column.
    pub fn col1(&self) -> i64 {
        self.col0 + self.cols as i64
    }

    /// One past the last row.
    pub fn row1(&self) -> i64 {
        self.row0 + self.rows as i64
    }

    /// Whether `other` lies inside this window.
    pub fn contains(&self, other: &Window) -> bool {
        other.col0 >= self.col0
            && other.row0 >= self.row0
            && other.col1() <= self.col1()
            && other.row1() <= self.row1()
    }

    /// Whether this window and `other` share a pixel.
    pub fn intersects(&self, other: &Window) -> bool {
        !self.is_empty()
            && !other.is_empty()
            && self.col0 < other.col1()
            && other.col0 < self.col1()
            && self.row0 < other.row1()
            && other.row0 < self.row1()
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.cols * self.rows
    }

    /// Whether the window holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Values of a level over a window: elevation and any extra layers, all `(rows, cols)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Where the values lie on the level's pixel plane.
    pub window: Window,
    /// Elevation in metres.
    pub elevation: Array2<f32>,
    /// Extra layers by name.
    pub layers: Vec<(String, Array2<f32>)>,
}

impl Field {
    /// A field holding elevation only.
    pub fn elevation_only(window: Window, elevation: Array2<f32>) -> Self {
        Field {
            window,
            elevation,
            layers: Vec::new(),
        }
    }

    /// The layer called `name`.
    pub fn layer(&self, name: &str) -> Option<&Array2<f32>> {
        self.layers.iter().find(|(n, _)| n == name).map(|(_, a)| a)
    }

    /// The sub-field over `w`, which must lie inside this field's window.
    pub fn crop(&self, w: Window) -> Option<Field> {
        if !self.window.contains(&w) {
            return None;
        }
        let r0 = (w.row0 - self.window.row0) as usize;
        let c0 = (w.col0 - self.window.col0) as usize;
        let cut = |a: &Array2<f32>| {
            a.slice(ndarray::s![r0..r0 + w.rows, c0..c0 + w.cols])
                .to_owned()
        };
        Some(Field {
            window: w,
            elevation: cut(&self.elevation),
            layers: self
                .layers
                .iter()
                .map(|(n, a)| (n.clone(), cut(a)))
                .collect(),
        })
    }
}
