//! What a world publishes about its layers: the list of layers, the TileJSON 3.0.0 document of
//! each ([`tilejson_of`]) and a MapLibre GL style (version 8) that shows them ([`style_json`]).
//! Every URL is absolute, built on the base URL the server was reached at.

use crate::tilejson::{TerrainEncoding, TileJson};
use crate::world::World;

/// The layers every world serves.
pub const LAYERS: [&str; 6] = [
    "elevation",
    "hillshade",
    "vegetation",
    "drainage",
    "splat",
    "color",
];

/// What the TileJSON of a landscape layer says about its tiles.
fn layer_description(w: &World, layer: &str) -> Option<String> {
    let l = w.landscape();
    let names = |v: Vec<&str>| v.join(", ");
    match layer {
        "vegetation" => Some(format!(
            "Species densities × 255, one a channel (set n = species 4n..4n+3 with ?set=n; \
             ?style=overlay for a coloured overlay); .exr: float densities, one named channel \
             per species. Species: {}",
            names(l.species.iter().map(|s| s.name.as_str()).collect())
        )),
        "drainage" => Some(
            "Upstream area in m²: .exr float32 channel upstream_area; .png log-scaled rivers on \
             transparent"
                .into(),
        ),
        "splat" => Some(format!(
            "Material weights, RGBA = materials 4n..4n+3 of ?set=n (all sets of a pixel sum to \
             255). Materials: {}",
            names(l.materials.iter().map(|m| m.name.as_str()).collect())
        )),
        "color" => Some("Baked material colour shaded by the hillshade".into()),
        _ => None,
    }
}

/// The TileJSON of layer `layer` of world `w` served under `base` (the server's scheme and
/// host); `None` for a layer the world does not serve.
pub fn tilejson_of(w: &World, base: &str, layer: &str) -> Option<TileJson> {
    tilejson_in(w, base, layer, "png")
}

/// Layers served as lossless WebP too (`{y}.webp`).
pub const WEBP_LAYERS: &[&str] = &["elevation", "color"];

/// [`tilejson_of`] with tiles in `format` (`png`, or `webp` for the [`WEBP_LAYERS`]); `None` for
/// a layer the world does not serve in that format.
pub fn tilejson_in(w: &World, base: &str, layer: &str, format: &str) -> Option<TileJson> {
    let served = match format {
        "png" => true,
        "webp" => WEBP_LAYERS.contains(&layer),
        _ => false,
    };
    if !LAYERS.contains(&layer) || !served {
        return None;
    }
    let mut tj = TileJson::new(
        &format!("{base}/tiles"),
        w.name(),
        layer,
        format,
        w.min_zoom(),
        w.max_zoom(),
        w.bounds(),
    )
    .with_attribution(w.attribution());
    tj.center = w.center();
    tj.name = format!("{} {layer}", w.title());
    if layer == "elevation" {
        tj = tj
            .with_encoding(TerrainEncoding::Terrarium)
            .with_tile_size(256);
    }
    if let Some(d) = layer_description(w, layer) {
        tj = tj.with_description(d).with_tile_size(256);
    }
    Some(tj)
}

/// The MapLibre style of world `w` served at `base`: the world's raster-dem as 3D terrain and
/// hillshade, and the colour map, vegetation overlay and drainage overlay as raster layers
/// switchable through `layout.visibility` (colour and drainage visible, vegetation not).
pub fn style_json(w: &World, base: &str) -> serde_json::Value {
    let n = w.name();
    let tiles =
        |layer: &str, ext: &str| format!("{base}/tiles/{n}/{layer}/{{z}}/{{x}}/{{y}}.{ext}");
    let raster = |url: String| {
        serde_json::json!({
            "type": "raster",
            "tiles": [url],
            "tileSize": 256,
            "minzoom": w.min_zoom(),
            "maxzoom": w.max_zoom(),
            "bounds": w.bounds(),
            "attribution": w.attribution(),
        })
    };
    let dem = serde_json::json!({
        "type": "raster-dem",
        "url": format!("{base}/tiles/{n}/elevation.json"),
        "tileSize": 256,
        "encoding": "terrarium",
    });
    let c = w.center();
    serde_json::json!({
        "version": 8,
        "name": w.title(),
        "center": [c[0], c[1]],
        "zoom": c[2],
        "pitch": 45,
        "sources": {
            "terrain": dem.clone(),
            "hillshade": dem,
            "color": raster(tiles("color", "png")),
            "vegetation": raster(format!("{}?style=overlay", tiles("vegetation", "png"))),
            "drainage": raster(tiles("drainage", "png")),
        },
        "terrain": { "source": "terrain", "exaggeration": 1.0 },
        "layers": [
            { "id": "background", "type": "background",
              "paint": { "background-color": "#d8d4c8" } },
            { "id": "color", "type": "raster", "source": "color",
              "layout": { "visibility": "visible" } },
            { "id": "vegetation", "type": "raster", "source": "vegetation",
              "layout": { "visibility": "none" }, "paint": { "raster-opacity": 0.8 } },
            { "id": "hillshade", "type": "hillshade", "source": "hillshade",
              "layout": { "visibility": "visible" },
              "paint": { "hillshade-exaggeration": 0.35 } },
            { "id": "drainage", "type": "raster", "source": "drainage",
              "layout": { "visibility": "visible" } },
        ],
    })
}
