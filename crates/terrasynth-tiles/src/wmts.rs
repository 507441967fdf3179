//! The OGC WMTS 1.0.0 capabilities document of a world (`/worlds/{world}/WMTSCapabilities.xml`),
//! for GIS clients that take WMTS rather than TileJSON or an XYZ template (QGIS, ArcGIS, OWSLib,
//! GDAL). RESTful only: each raster layer of [`LAYERS`] as a `Layer` with its PNG tile template
//! (`{TileMatrix}/{TileCol}/{TileRow}` are zoom, column and row of the XYZ scheme), on one tile
//! matrix set, `WebMercatorQuad` (EPSG:3857, the well-known scale set `GoogleMapsCompatible`,
//! 256-pixel tiles, zooms 0 to the world's deepest), with the tile limits of each zoom from the
//! world's minimum zoom on: the tiles that overlap the world's bounds, exactly those that
//! [`World::check_tile`] accepts. Like the TileJSON documents, it only describes what the tile
//! routes already serve.

use std::fmt::Write;

use crate::mercator::tile_range_for_bounds;
use crate::style::LAYERS;
use crate::world::World;

/// The identifier of the one tile matrix set (OGC Two Dimensional Tile Matrix Set, Web
/// Mercator quad).
pub const TILE_MATRIX_SET: &str = "WebMercatorQuad";

/// The scale denominator of zoom 0 of `GoogleMapsCompatible`: the 156 543.03 m pixels of a
/// 256-pixel world at the standard 0.28 mm rendering pixel.
const SCALE_DENOMINATOR_Z0: f64 = 559_082_264.028_717_8;

/// Mercator metres from the projection's centre to the edge of the square world (π × 6 378 137).
const HALF_WORLD_M: f64 = 20_037_508.342_789_244;

/// `s` with the five characters XML gives a meaning escaped, for text and attribute values.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// The capabilities of world `w` with its tiles served at `base` (scheme and host, no trailing
/// slash).
pub fn capabilities_xml(w: &World, base: &str) -> String {
    let name = w.name();
    let here = escape(&format!("{base}/worlds/{name}/WMTSCapabilities.xml"));
    let tiles = escape(&format!("{base}/tiles/{name}/"));
    let [west, south, east, north] = w.bounds();
    let mut x = String::new();
    // Writing to a String cannot fail.
    let _ = write!(
        x,
        r#"<?xml version="1.0" encoding="UTF-8"?>
<Capabilities xmlns="http://www.opengis.net/wmts/1.0" xmlns:ows="http://www.opengis.net/ows/1.1" xmlns:xlink="http://www.w3.org/1999/xlink" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:schemaLocation="http://www.opengis.net/wmts/1.0 http://schemas.opengis.net/wmts/1.0/wmtsGetCapabilities_response.xsd" version="1.0.0">
  <ows:ServiceIdentification>
    <ows:Title>{title}</ows:Title>
    <ows:Abstract>{abstract_}</ows:Abstract>
    <ows:ServiceType>OGC WMTS</ows:ServiceType>
    <ows:ServiceTypeVersion>1.0.0</ows:ServiceTypeVersion>
    <ows:AccessConstraints>{attribution}</ows:AccessConstraints>
  </ows:ServiceIdentification>
  <ows:OperationsMetadata>
"#,
        title = escape(w.title()),
        abstract_ = escape(&format!(
            "Synthesized terrain of the world `{name}` served by terrasynth"
        )),
        attribution = escape(w.attribution()),
    );
    for (operation, href) in [("GetCapabilities", &here), ("GetTile", &tiles)] {
        let _ = write!(
            x,
            r#"    <ows:Operation name="{operation}">
      <ows:DCP>
        <ows:HTTP>
          <ows:Get xlink:href="{href}">
            <ows:Constraint name="GetEncoding">
              <ows:AllowedValues>
                <ows:Value>RESTful</ows:Value>
              </ows:AllowedValues>
            </ows:Constraint>
          </ows:Get>
        </ows:HTTP>
      </ows:DCP>
    </ows:Operation>
"#
        );
    }
    x.push_str("  </ows:OperationsMetadata>\n  <Contents>\n");
    for layer in LAYERS {
        let _ = write!(
            x,
            r#"    <Layer>
      <ows:Title>{title}</ows:Title>
      <ows:WGS84BoundingBox crs="urn:ogc:def:crs:OGC:2:84">
        <ows:LowerCorner>{west} {south}</ows:LowerCorner>
        <ows:UpperCorner>{east} {north}</ows:UpperCorner>
      </ows:WGS84BoundingBox>
      <ows:Identifier>{layer}</ows:Identifier>
      <Style isDefault="true">
        <ows:Identifier>default</ows:Identifier>
      </Style>
      <Format>image/png</Format>
      <TileMatrixSetLink>
        <TileMatrixSet>{TILE_MATRIX_SET}</TileMatrixSet>
        <TileMatrixSetLimits>
"#,
            title = escape(&format!("{} {layer}", w.title())),
        );
        for z in w.min_zoom()..=w.max_zoom() {
            let (x0, y0, x1, y1) = tile_range_for_bounds(z, (west, south, east, north));
            let _ = write!(
                x,
                r#"          <TileMatrixLimits>
            <TileMatrix>{z}</TileMatrix>
            <MinTileRow>{y0}</MinTileRow>
            <MaxTileRow>{y1}</MaxTileRow>
            <MinTileCol>{x0}</MinTileCol>
            <MaxTileCol>{x1}</MaxTileCol>
          </TileMatrixLimits>
"#
            );
        }
        let _ = write!(
            x,
            r#"        </TileMatrixSetLimits>
      </TileMatrixSetLink>
      <ResourceURL format="image/png" resourceType="tile" template="{tiles}{layer}/{{TileMatrix}}/{{TileCol}}/{{TileRow}}.png"/>
    </Layer>
"#
        );
    }
    let _ = write!(
        x,
        r#"    <TileMatrixSet>
      <ows:Identifier>{TILE_MATRIX_SET}</ows:Identifier>
      <ows:SupportedCRS>urn:ogc:def:crs:EPSG::3857</ows:SupportedCRS>
      <WellKnownScaleSet>urn:ogc:def:wkss:OGC:1.0:GoogleMapsCompatible</WellKnownScaleSet>
"#
    );
    for z in 0..=w.max_zoom() {
        let side = 1u64 << z;
        let scale = SCALE_DENOMINATOR_Z0 / side as f64;
        let _ = write!(
            x,
            r#"      <TileMatrix>
        <ows:Identifier>{z}</ows:Identifier>
        <ScaleDenominator>{scale}</ScaleDenominator>
        <TopLeftCorner>{left} {top}</TopLeftCorner>
        <TileWidth>256</TileWidth>
        <TileHeight>256</TileHeight>
        <MatrixWidth>{side}</MatrixWidth>
        <MatrixHeight>{side}</MatrixHeight>
      </TileMatrix>
"#,
            left = -HALF_WORLD_M,
            top = HALF_WORLD_M,
        );
    }
    let _ = write!(
        x,
        r#"    </TileMatrixSet>
  </Contents>
  <ServiceMetadataURL xlink:href="{here}"/>
</Capabilities>
"#
    );
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_five_xml_characters_are_escaped() {
        assert_eq!(
            escape(r#"A & B <c> "d" 'e' é"#),
            "A &amp; B &lt;c&gt; &quot;d&quot; &apos;e&apos; é"
        );
    }

    #[test]
    fn zoom_zero_is_one_tile_of_the_whole_mercator_square() {
        // 2π × 6 378 137 m over 256 pixels of 0.28 mm.
        let from_radius = 2.0 * std::f64::consts::PI * 6_378_137.0 / 256.0 / 0.000_28;
        assert!((SCALE_DENOMINATOR_Z0 - from_radius).abs() < 1e-3);
        assert!((HALF_WORLD_M - std::f64::consts::PI * 6_378_137.0).abs() < 1e-6);
    }
}
