//! Chains of amplification levels: from a base field to any window of level `N`, computing at each
//! level exactly the window the next one needs, with levels of either kind ([`Level`],
//! [`AnyAmplifier`]).

use ndarray::Array2;

use super::error::SynthError;
use super::field::{Field, Window};
use super::gradient::GradientAmplifier;
use super::level::Amplifier;

/// One ×2 level of a chain: what every amplifier offers (the dictionary [`Amplifier`] and the
/// [`GradientAmplifier`]): the parent window an output window needs, and the window-invariant
/// amplification of that window.
pub trait Level: Sync {
    /// The parent window [`Level::amplify`] needs for output window `out`.
    fn parent_window_for(&self, out: Window) -> Window;
    /// Window `out` of this level from `parent` (covering [`Level::parent_window_for`]`(out)`),
    /// `parent_cell_m` the parent's metric cell size.
    fn amplify(&self, parent: &Field, out: Window, parent_cell_m: f32)
        -> Result<Field, SynthError>;
    /// The parent window [`Level::amplify_layers`] needs for output window `out` (at most
    /// [`Level::parent_window_for`]`(out)`; that window unless the level reads less for its
    /// layers).
    fn layers_parent_window_for(&self, out: Window) -> Window {
        self.parent_window_for(out)
    }
    /// The extra layers of [`Level::amplify`]`(parent, out, parent_cell_m)`, bit for bit, from a
    /// `parent` covering [`Level::layers_parent_window_for`]`(out)`; a level may skip the work
    /// its elevation alone needs.
    fn amplify_layers(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Vec<(String, Array2<f32>)>, SynthError> {
        Ok(self.amplify(parent, out, parent_cell_m)?.layers)
    }
}

impl Level for Amplifier {
    fn parent_window_for(&self, out: Window) -> Window {
        Amplifier::parent_window_for(self, out)
    }
    fn amplify(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Field, SynthError> {
        Amplifier::amplify(self, parent, out, parent_cell_m)
    }
    fn layers_parent_window_for(&self, out: Window) -> Window {
        Amplifier::layers_parent_window_for(self, out)
    }
    fn amplify_layers(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Vec<(String, Array2<f32>)>, SynthError> {
        Amplifier::amplify_layers(self, parent, out, parent_cell_m)
    }
}

impl Level for GradientAmplifier {
    fn parent_window_for(&self, out: Window) -> Window {
        GradientAmplifier::parent_window_for(self, out)
    }
    fn amplify(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Field, SynthError> {
        GradientAmplifier::amplify(self, parent, out, parent_cell_m)
    }
}

/// An amplifier of either kind, chosen per world or per zoom band.
#[derive(Debug)]
pub enum AnyAmplifier {
    /// Dictionary matching (methods 1 and 2).
    Dictionary(Box<Amplifier>),
    /// Gradient tiles (method 3).
    Gradient(GradientAmplifier),
}

impl Level for AnyAmplifier {
    fn parent_window_for(&self, out: Window) -> Window {
        match self {
            AnyAmplifier::Dictionary(a) => a.parent_window_for(out),
            AnyAmplifier::Gradient(g) => g.parent_window_for(out),
        }
    }
    fn amplify(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Field, SynthError> {
        match self {
            AnyAmplifier::Dictionary(a) => a.amplify(parent, out, parent_cell_m),
            AnyAmplifier::Gradient(g) => g.amplify(parent, out, parent_cell_m),
        }
    }
    fn layers_parent_window_for(&self, out: Window) -> Window {
        match self {
            AnyAmplifier::Dictionary(a) => a.layers_parent_window_for(out),
            AnyAmplifier::Gradient(g) => g.layers_parent_window_for(out),
        }
    }
    fn amplify_layers(
        &self,
        parent: &Field,
        out: Window,
        parent_cell_m: f32,
    ) -> Result<Vec<(String, Array2<f32>)>, SynthError> {
        match self {
            AnyAmplifier::Dictionary(a) => a.amplify_layers(parent, out, parent_cell_m),
            AnyAmplifier::Gradient(g) => g.amplify_layers(parent, out, parent_cell_m),
        }
    }
}

/// Reads a window of the base (level 0) plane. Implementations define the base everywhere on the
/// plane (for example by clamping to a raster's edges), so that any window can be asked for.
pub trait BaseSource: Sync {
    /// The base field over `w`.
    fn read(&self, w: Window) -> Result<Field, SynthError>;
}

/// A raster extended beyond its edges by repeating the nearest edge cell, as a base source.
#[derive(Clone, Debug)]
pub struct ClampedRaster<'a> {
    /// Elevation values, row 0 north; must be finite.
    pub elevation: &'a Array2<f32>,
    /// Extra layers on the same grid.
    pub layers: Vec<(String, &'a Array2<f32>)>,
}

impl ClampedRaster<'_> {
    fn sample(a: &Array2<f32>, w: Window) -> Array2<f32> {
        let (rows, cols) = a.dim();
        let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
        Array2::from_shape_fn((w.rows, w.cols), |(r, c)| {
            a[[
                clamp(w.row0 + r as i64, rows),
                clamp(w.col0 + c as i64, cols),
            ]]
        })
    }
}

impl BaseSource for ClampedRaster<'_> {
    fn read(&self, w: Window) -> Result<Field, SynthError> {
        let (rows, cols) = self.elevation.dim();
        if rows == 0 || cols == 0 {
            return Err(SynthError::BadWindow("the base raster is empty".into()));
        }
        Ok(Field {
            window: w,
            elevation: Self::sample(self.elevation, w),
            layers: self
                .layers
                .iter()
                .map(|(n, a)| (n.clone(), Self::sample(a, w)))
                .collect(),
        })
    }
}

/// The windows each level must compute so that level `levels.len()` covers `out`:
/// element 0 is the base window, the last is `out`.
pub fn chain_windows<L: Level>(levels: &[L], out: Window) -> Vec<Window> {
    let mut windows = vec![out];
    for amp in levels.iter().rev() {
        let next = amp.parent_window_for(windows[windows.len() - 1]);
        windows.push(next);
    }
    windows.reverse();
    windows
}

/// Amplifies `levels.len()` times: reads the base window the chain needs, then runs each level on
/// the window the next needs, ending with `out` at the last level. `base_cell_m` is the metric cell
/// size of level 0; each level halves it.
pub fn amplify_chain<L: Level>(
    levels: &[L],
    base: &dyn BaseSource,
    out: Window,
    base_cell_m: f64,
) -> Result<Field, SynthError> {
    let windows = chain_windows(levels, out);
    let mut field = base.read(windows[0])?;
    let mut cell = base_cell_m;
    for (amp, w) in levels.iter().zip(&windows[1..]) {
        field = amp.amplify(&field, *w, cell as f32)?;
        cell *= 0.5;
    }
    Ok(field)
}
