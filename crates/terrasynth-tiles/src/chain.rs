//! A world's scale-aware chain: one dictionary or gradient tile set (and the amplifiers built on
//! it) per zoom band, looked up per amplified zoom by the rule of
//! [`terrasynth_core::synth::bands`].

use terrasynth_core::dictionary::AnyDictionary;
use terrasynth_core::synth::{band_for, ZoomBand};

/// One band of a world's chain: a dictionary (dictionary amplifier) or a gradient tile set
/// (gradient amplifier) and the zooms it amplifies.
#[derive(Clone, Debug)]
pub struct DictionaryBand {
    /// The zooms; `None`: every amplified zoom (a world's single dictionary).
    pub zooms: Option<ZoomBand>,
    /// The dictionary or gradient tile set; its kind is the band's amplifier.
    pub dictionary: AnyDictionary,
    /// Its content id.
    pub id: String,
}

impl DictionaryBand {
    /// A world's single dictionary (or gradient tile set), used at every amplified zoom.
    pub fn every_zoom(dictionary: impl Into<AnyDictionary>, id: impl Into<String>) -> Self {
        DictionaryBand {
            zooms: None,
            dictionary: dictionary.into(),
            id: id.into(),
        }
    }
}

/// Something per band (an amplifier), looked up by zoom.
#[derive(Clone, Debug)]
pub struct Chain<T> {
    zooms: Vec<Option<ZoomBand>>,
    items: Vec<T>,
}

impl<T> Chain<T> {
    /// One item per band of `bands` (checked bands, non-empty), made by `make`.
    pub fn new<E>(
        bands: &[DictionaryBand],
        mut make: impl FnMut(&DictionaryBand) -> Result<T, E>,
    ) -> Result<Self, E> {
        Ok(Chain {
            zooms: bands.iter().map(|b| b.zooms).collect(),
            items: bands.iter().map(&mut make).collect::<Result<_, _>>()?,
        })
    }

    /// The item that amplifies zoom `z`.
    pub fn at(&self, z: u8) -> &T {
        &self.items[band_for(&self.zooms, z).min(self.items.len() - 1)]
    }
}
