//! A world's scale-aware chain: one dictionary (and the amplifiers built on it) per zoom band,
//! looked up per amplified zoom by the rule of [`terrasynth_core::synth::bands`].

use std::sync::Arc;

use terrasynth_core::dictionary::Dictionary;
use terrasynth_core::synth::{band_for, ZoomBand};

/// One band of a world's chain: a dictionary and the zooms it amplifies.
#[derive(Clone, Debug)]
pub struct DictionaryBand {
    /// The zooms; `None`: every amplified zoom (a world's single dictionary).
    pub zooms: Option<ZoomBand>,
    /// The dictionary.
    pub dictionary: Arc<Dictionary>,
    /// Its content id.
    pub id: String,
}

impl DictionaryBand {
    /// A world's single dictionary, used at every amplified zoom.
    pub fn every_zoom(dictionary: Arc<Dictionary>, id: impl Into<String>) -> Self {
        DictionaryBand {
            zooms: None,
            dictionary,
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
