//! What a world publishes about its layers: the list of layers, the TileJSON 3.0.0 document of
//! each ([`tilejson_of`]) and a MapLibre GL style (version 8) that shows them ([`style_json`]).
//! Every URL is absolute, built on the base URL the server was reached at.

use crate::contours::{auto_interval, CONTOURS_LAYER, INDEX_EVERY};
use crate::instances::kinds;
use crate::tilejson::{TerrainEncoding, TileJson, VectorLayer};
use crate::world::World;

/// The vector layer of plants and rocks, served by worlds with scattering rules.
pub const INSTANCES: &str = "instances";

/// Whether world `w` serves instance tiles: it has scattering rules and its deepest zoom reaches
/// their `instances_min_zoom` (else every instance tile would be 404, and no TileJSON or style
/// source may promise them).
pub fn serves_instances(w: &World) -> bool {
    !w.landscape().scatter.is_empty() && w.landscape().instances_min_zoom <= w.max_zoom()
}

/// The vector layer of contour lines, served by every world.
pub const CONTOURS: &str = CONTOURS_LAYER;

/// The layers world `w` serves: [`LAYERS`], [`CONTOURS`], and [`INSTANCES`] when it has
/// scattering rules (`/worlds` lists [`LAYERS`] only, the raster layers, so that clients
/// iterating them as PNG layers keep working; the vector layers have their TileJSON and style
/// layers).
pub fn layers_of(w: &World) -> Vec<&'static str> {
    let mut v = LAYERS.to_vec();
    v.push(CONTOURS);
    if serves_instances(w) {
        v.push(INSTANCES);
    }
    v
}

/// The zoom from which the style draws contours: the native zoom (coarser zooms have
/// intervals of hundreds of metres or more).
pub fn contours_min_zoom(w: &World) -> u8 {
    w.z_base()
}

/// The TileJSON of the contour tiles: `.mvt` at every zoom, one vector layer `contours`.
fn contours_tilejson(w: &World, base: &str) -> TileJson {
    let z = w.max_zoom();
    let mut tj = TileJson::new(
        &format!("{base}/tiles"),
        w.name(),
        CONTOURS,
        "mvt",
        w.min_zoom(),
        z,
        w.bounds(),
    )
    .with_attribution(w.attribution())
    .with_description(format!(
        "Contour lines of the served elevation: Mapbox Vector Tiles 2.1, layer contours, line \
         strings with elevation_m and index (every {INDEX_EVERY}th interval). Interval: the \
         largest of 1, 2, 5 × 10^n m not above four pixels ({} m at zoom {z}), or ?interval= in \
         metres (at least a quarter of a pixel)",
        auto_interval(w.level_cell_m(z))
    ));
    tj.center = w.center();
    tj.name = format!("{} {CONTOURS}", w.title());
    tj.vector_layers = Some(vec![VectorLayer {
        id: CONTOURS.to_string(),
        fields: [("elevation_m", "Number"), ("index", "Boolean")]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect(),
        description: Some("Lines of equal elevation; index lines every fifth interval".into()),
        minzoom: w.min_zoom(),
        maxzoom: z,
    }]);
    tj
}

/// The TileJSON of the instance tiles: `.mvt` from the world's `instances_min_zoom`, one
/// vector layer per kind.
fn instances_tilejson(w: &World, base: &str) -> TileJson {
    let l = w.landscape();
    let min = l.instances_min_zoom;
    let mut tj = TileJson::new(
        &format!("{base}/tiles"),
        w.name(),
        INSTANCES,
        "mvt",
        min,
        w.max_zoom(),
        w.bounds(),
    )
    .with_attribution(w.attribution())
    .with_description(
        "Plants and rocks: Mapbox Vector Tiles 2.1, one layer per kind, points with species, \
         height_m, radius_m, rotation_deg, age; .json: GeoJSON [lon, lat, ground elevation]",
    );
    tj.center = w.center();
    tj.name = format!("{} {INSTANCES}", w.title());
    let fields: std::collections::BTreeMap<String, String> = [
        ("species", "String"),
        ("height_m", "Number"),
        ("radius_m", "Number"),
        ("rotation_deg", "Number"),
        ("age", "Number"),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    tj.vector_layers = Some(
        kinds(w)
            .into_iter()
            .map(|kind| VectorLayer {
                description: Some(format!(
                    "{kind}: {}",
                    l.scatter
                        .iter()
                        .filter(|r| r.kind == kind)
                        .flat_map(|r| r.source_names())
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
                id: kind,
                fields: fields.clone(),
                minzoom: min,
                maxzoom: w.max_zoom(),
            })
            .collect(),
    );
    tj
}

/// The colour of each value of the instances' `species` (a MapLibre `match` expression): the
/// species' colour, or the first material's for rocks.
fn species_colours(w: &World) -> serde_json::Value {
    let l = w.landscape();
    let hex = |c: [u8; 3]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
    let colour_of = |name: &str| {
        l.species
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.colour)
            .or_else(|| {
                l.materials
                    .iter()
                    .find(|m| m.name == name)
                    .map(|m| m.colour)
            })
            .map_or_else(|| "#808080".to_string(), hex)
    };
    let mut pairs: Vec<(String, String)> = Vec::new();
    for r in &l.scatter {
        let names: Vec<String> = match &r.name {
            Some(n) => vec![n.clone()],
            None => r.source_names().iter().map(|s| s.to_string()).collect(),
        };
        let first = r.source_names().first().map_or("", |s| *s).to_string();
        for n in names {
            if !pairs.iter().any(|(k, _)| *k == n) {
                let c = colour_of(if r.name.is_some() { &first } else { &n });
                pairs.push((n, c));
            }
        }
    }
    let mut expr = vec![
        serde_json::json!("match"),
        serde_json::json!(["get", "species"]),
    ];
    for (k, c) in pairs {
        expr.push(serde_json::json!(k));
        expr.push(serde_json::json!(c));
    }
    expr.push(serde_json::json!("#808080"));
    serde_json::Value::Array(expr)
}

/// The layers every world serves.
pub const LAYERS: [&str; 7] = [
    "elevation",
    "hillshade",
    "vegetation",
    "drainage",
    "splat",
    "color",
    "water",
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
            names(crate::materials::splat_names(l))
        )),
        "color" => Some("Baked material colour shaded by the hillshade".into()),
        "water" => Some(
            "Sea and lakes: .exr float32 channels depth (m, 0 where dry) and surface (m, NaN \
             where dry); .png water colour by depth, alpha by depth (transparent where dry)"
                .into(),
        ),
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
    if layer == INSTANCES && format == "png" && serves_instances(w) {
        return Some(instances_tilejson(w, base));
    }
    if layer == CONTOURS && format == "png" {
        return Some(contours_tilejson(w, base));
    }
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
/// hillshade, and the colour map, the water above it, vegetation overlay and drainage overlay as
/// raster layers
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
    let mut style = serde_json::json!({
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
            "water": raster(tiles("water", "png")),
        },
        "terrain": { "source": "terrain", "exaggeration": 1.0 },
        "layers": [
            { "id": "background", "type": "background",
              "paint": { "background-color": "#d8d4c8" } },
            { "id": "color", "type": "raster", "source": "color",
              "layout": { "visibility": "visible" } },
            { "id": "water", "type": "raster", "source": "water",
              "layout": { "visibility": "visible" } },
            { "id": "vegetation", "type": "raster", "source": "vegetation",
              "layout": { "visibility": "none" }, "paint": { "raster-opacity": 0.8 } },
            { "id": "hillshade", "type": "hillshade", "source": "hillshade",
              "layout": { "visibility": "visible" },
              "paint": { "hillshade-exaggeration": 0.35 } },
            { "id": "drainage", "type": "raster", "source": "drainage",
              "layout": { "visibility": "visible" } },
        ],
    });
    add_contours(w, base, &mut style);
    add_instances(w, base, &mut style);
    style
}

/// The contours as brown lines from the native zoom, index lines thicker (under the instances;
/// no labels: the style has no glyphs).
fn add_contours(w: &World, base: &str, style: &mut serde_json::Value) {
    style["sources"][CONTOURS] = serde_json::json!({
        "type": "vector",
        "url": format!("{base}/tiles/{}/{CONTOURS}.json", w.name()),
    });
    let min = contours_min_zoom(w);
    if let Some(layers) = style["layers"].as_array_mut() {
        layers.push(serde_json::json!({
            "id": CONTOURS,
            "type": "line",
            "source": CONTOURS,
            "source-layer": CONTOURS_LAYER,
            "minzoom": min,
            "filter": ["!=", ["get", "index"], true],
            "layout": { "visibility": "visible", "line-join": "round" },
            "paint": { "line-color": "#7a4a1e", "line-width": 0.6, "line-opacity": 0.6 },
        }));
        layers.push(serde_json::json!({
            "id": format!("{CONTOURS}-index"),
            "type": "line",
            "source": CONTOURS,
            "source-layer": CONTOURS_LAYER,
            "minzoom": min,
            "filter": ["==", ["get", "index"], true],
            "layout": { "visibility": "visible", "line-join": "round" },
            "paint": { "line-color": "#6b3a12", "line-width": 1.4, "line-opacity": 0.8 },
        }));
    }
}

/// The instances as circles coloured by species from zoom 15 (one layer per kind, on top), for a
/// world with scattering rules.
fn add_instances(w: &World, base: &str, style: &mut serde_json::Value) {
    if !serves_instances(w) {
        return;
    }
    style["sources"][INSTANCES] = serde_json::json!({
        "type": "vector",
        "url": format!("{base}/tiles/{}/{INSTANCES}.json", w.name()),
    });
    let colours = species_colours(w);
    if let Some(layers) = style["layers"].as_array_mut() {
        for kind in kinds(w) {
            layers.push(serde_json::json!({
                "id": format!("{INSTANCES}-{kind}"),
                "type": "circle",
                "source": INSTANCES,
                "source-layer": kind,
                "minzoom": 15,
                "layout": { "visibility": "visible" },
                "paint": {
                    "circle-color": colours.clone(),
                    "circle-radius": ["interpolate", ["exponential", 2], ["zoom"],
                        15, ["max", 1, ["*", 0.25, ["get", "radius_m"]]],
                        18, ["max", 2, ["*", 2, ["get", "radius_m"]]]],
                    "circle-opacity": 0.9,
                    "circle-stroke-color": "#1a1a1a",
                    "circle-stroke-width": 0.3,
                },
            }));
        }
    }
}
