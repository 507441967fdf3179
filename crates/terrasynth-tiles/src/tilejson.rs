//! TileJSON 3.0.0 documents describing one layer of a world, as MapLibre GL JS (`raster-dem` and
//! `raster` sources), Cesium and OpenLayers consume them.

use serde::{Deserialize, Serialize};

/// The TileJSON specification version written by terrasynth.
pub const TILEJSON_VERSION: &str = "3.0.0";

/// How elevation is packed into RGB tiles (MapLibre's `raster-dem` `encoding`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TerrainEncoding {
    /// `h = R·256 + G + B/256 − 32768`.
    Terrarium,
    /// `h = −10000 + (R·65536 + G·256 + B)·0.1`.
    Mapbox,
}

/// A TileJSON 3.0.0 document (only the fields terrasynth uses; `vector_layers` only for the
/// vector instance tiles).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct TileJson {
    /// Always [`TILEJSON_VERSION`].
    pub tilejson: String,
    /// Tile URL templates with `{z}`, `{x}` and `{y}` placeholders.
    pub tiles: Vec<String>,
    /// Human-readable name of the tileset.
    pub name: String,
    /// Attribution shown by the map client.
    pub attribution: String,
    /// Shallowest zoom served.
    pub minzoom: u8,
    /// Deepest zoom served.
    pub maxzoom: u8,
    /// `[west, south, east, north]` in degrees.
    pub bounds: [f64; 4],
    /// `[longitude, latitude, zoom]` of the default view.
    pub center: [f64; 3],
    /// Elevation packing of RGB elevation tiles; absent for other layers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<TerrainEncoding>,
    /// Tile size in pixels (256, or 512 for `@2x`); absent means 256.
    #[serde(rename = "tileSize", default, skip_serializing_if = "Option::is_none")]
    pub tile_size: Option<u32>,
    /// Longer description of the tileset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Format of the tiles the URLs name: `png`, `webp` (lossless) or `exr`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_format: Option<String>,
    /// The layers of a vector tile source (TileJSON 3.0.0 `vector_layers`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vector_layers: Option<Vec<VectorLayer>>,
}

/// One layer of a vector tile source: its id (the MVT layer name) and its fields.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct VectorLayer {
    /// The MVT layer name.
    pub id: String,
    /// Field names and their types (`String` or `Number`).
    pub fields: std::collections::BTreeMap<String, String>,
    /// What the layer holds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Shallowest zoom with features.
    pub minzoom: u8,
    /// Deepest zoom with features.
    pub maxzoom: u8,
}

/// The attribution written by [`TileJson::new`].
pub const DEFAULT_ATTRIBUTION: &str = "terrasynth synthesized terrain";

impl TileJson {
    /// The TileJSON of layer `layer` of world `world` served at
    /// `{base_url}/{world}/{layer}/{z}/{x}/{y}.{extension}` (a trailing `/` on `base_url` is
    /// ignored), for zooms `minzoom..=maxzoom` (swapped if given in the wrong order) over `bounds`
    /// `[west, south, east, north]` in degrees. The name is `"{world} {layer}"`, the attribution
    /// [`DEFAULT_ATTRIBUTION`], the centre the middle of the bounds at `minzoom`; encoding, tile
    /// size and description are unset (see the `with_*` methods).
    pub fn new(
        base_url: &str,
        world: &str,
        layer: &str,
        extension: &str,
        minzoom: u8,
        maxzoom: u8,
        bounds: [f64; 4],
    ) -> TileJson {
        let (minzoom, maxzoom) = (minzoom.min(maxzoom), minzoom.max(maxzoom));
        let base = base_url.trim_end_matches('/');
        let [w, s, e, n] = bounds;
        TileJson {
            tilejson: TILEJSON_VERSION.to_string(),
            tiles: vec![format!(
                "{base}/{world}/{layer}/{{z}}/{{x}}/{{y}}.{extension}"
            )],
            name: format!("{world} {layer}"),
            attribution: DEFAULT_ATTRIBUTION.to_string(),
            minzoom,
            maxzoom,
            bounds,
            center: [(w + e) / 2.0, (s + n) / 2.0, f64::from(minzoom)],
            encoding: None,
            tile_size: None,
            description: None,
            tile_format: Some(extension.to_string()),
            vector_layers: None,
        }
    }

    /// The same document with an elevation encoding.
    pub fn with_encoding(mut self, encoding: TerrainEncoding) -> TileJson {
        self.encoding = Some(encoding);
        self
    }

    /// The same document with a tile size in pixels.
    pub fn with_tile_size(mut self, tile_size: u32) -> TileJson {
        self.tile_size = Some(tile_size);
        self
    }

    /// The same document with a description.
    pub fn with_description(mut self, description: impl Into<String>) -> TileJson {
        self.description = Some(description.into());
        self
    }

    /// The same document with another attribution.
    pub fn with_attribution(mut self, attribution: impl Into<String>) -> TileJson {
        self.attribution = attribution.into();
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serialises_to_tilejson_3() {
        let tj = TileJson::new(
            "https://tiles.example.org/",
            "tienshan",
            "elevation",
            "png",
            0,
            14,
            [66.0, 39.0, 81.0, 44.0],
        )
        .with_encoding(TerrainEncoding::Terrarium)
        .with_tile_size(256);
        let v = serde_json::to_value(&tj).expect("serialises");
        assert_eq!(v["tilejson"], "3.0.0");
        assert_eq!(
            v["tiles"][0],
            "https://tiles.example.org/tienshan/elevation/{z}/{x}/{y}.png"
        );
        assert_eq!(v["encoding"], "terrarium");
        assert_eq!(v["tileSize"], 256);
        assert_eq!(v["minzoom"], 0);
        assert_eq!(v["maxzoom"], 14);
        assert_eq!(v["bounds"], serde_json::json!([66.0, 39.0, 81.0, 44.0]));
        assert_eq!(v["center"], serde_json::json!([73.5, 41.5, 0.0]));
        assert!(v.get("description").is_none());
        assert!(v.get("tile_size").is_none());
        let back: TileJson = serde_json::from_value(v).expect("deserialises");
        assert_eq!(back, tj);
    }

    #[test]
    fn optional_fields_are_omitted_and_default_on_read() {
        let tj = TileJson::new(
            "http://h",
            "w",
            "hillshade",
            "png",
            9,
            3,
            [0.0, 0.0, 1.0, 1.0],
        );
        assert_eq!((tj.minzoom, tj.maxzoom), (3, 9));
        let s = serde_json::to_string(&tj).expect("serialises");
        assert!(!s.contains("encoding") && !s.contains("tileSize") && !s.contains("description"));
        let back: TileJson = serde_json::from_str(&s).expect("deserialises");
        assert_eq!(back, tj);
        let mapbox = tj
            .with_encoding(TerrainEncoding::Mapbox)
            .with_description("d")
            .with_attribution("a");
        let v = serde_json::to_value(&mapbox).expect("serialises");
        assert_eq!(v["encoding"], "mapbox");
        assert_eq!(v["description"], "d");
        assert_eq!(v["attribution"], "a");
    }
}
