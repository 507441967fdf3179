//! GeoTIFFs in a projected CRS (UTM): the committed Carrizo Plain lidar (EPSG:26911) read as a
//! metric grid, used as an exemplar without a place on the globe, reprojected onto EPSG:4326
//! for world bases; writer round trip of projected grids; unsupported codes named.

use std::io::Cursor;

use ndarray::Array2;
use terrasynth_core::dictionary::build::Exemplar;
use terrasynth_core::dictionary::ExemplarOptions;
use terrasynth_core::raster::projection::Projection;
use terrasynth_core::raster::reproject::to_geographic;
use terrasynth_core::raster::{
    embedded, read_geotiff, write_geotiff, Crs, Georef, Grid, ReadLimits,
};

#[test]
fn utm_lidar_reads_as_a_metric_grid() {
    let g = embedded::carrizo().unwrap();
    assert_eq!(g.georef.crs, Crs::Projected(26911));
    assert_eq!((g.rows(), g.cols()), (900, 505));
    // The values of config/data/carrizo_lidar_2m.json.
    assert!((g.georef.west - 241_027.441).abs() < 1e-3);
    assert!((g.georef.north - 3_910_578.74).abs() < 1e-3);
    assert_eq!(g.georef.cell_size_m(0.0), (2.0, 2.0));
    assert_eq!(g.georef.cell_size_m(899.0), (2.0, 2.0));
    let (lo, hi) = g.min_max().unwrap();
    assert!(
        (lo - 628.918).abs() < 0.01 && (hi - 702.677).abs() < 0.01,
        "{lo} {hi}"
    );
    // As an exemplar: cells of 2 m, no place on the globe needed.
    let ex = Exemplar::from_grid(&g, ExemplarOptions::default(), |_, _| Vec::new()).unwrap();
    assert_eq!(ex.cell_m, 2.0);
}

#[test]
fn utm_lidar_reprojects_onto_the_globe_keeping_its_area_and_heights() {
    let g = embedded::carrizo().unwrap();
    let out = to_geographic(&g).unwrap();
    assert_eq!(out.georef.crs, Crs::Epsg4326);
    // Where the lidar lies: the Carrizo Plain, about 119.8°W 35.3°N.
    let p = Projection::new(26911).unwrap();
    let (lon, lat) = p
        .to_lonlat(241_027.441 + 505.0, 3_910_578.74 - 900.0)
        .unwrap();
    let (w, s, e, n) = out.georef.bounds(out.cols(), out.rows());
    assert!(w < lon && lon < e && s < lat && lat < n);
    assert!(
        (-120.0..-119.5).contains(&lon) && (35.0..35.5).contains(&lat),
        "{lon} {lat}"
    );
    // Valid area and mean height within a percent / 0.5 m of the source's.
    let area: f64 = (0..out.rows())
        .map(|r| {
            let row_valid = (0..out.cols()).filter(|&c| out.is_valid(r, c)).count();
            row_valid as f64 * out.georef.cell_sizes(out.rows()).area(r)
        })
        .sum();
    let src_area = 900.0 * 505.0 * 4.0;
    assert!((area / src_area - 1.0).abs() < 0.01, "{area} vs {src_area}");
    let mean = |gr: &Grid| {
        let v: Vec<f64> = gr
            .data
            .indexed_iter()
            .filter(|((r, c), _)| gr.is_valid(*r, *c))
            .map(|(_, v)| f64::from(*v))
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    assert!(
        (mean(&out) - mean(&g)).abs() < 0.5,
        "{} vs {}",
        mean(&out),
        mean(&g)
    );
}

#[test]
fn projected_grids_round_trip_through_geotiff() {
    let g = Grid::new(
        Array2::from_shape_fn((8, 6), |(r, c)| (r * 10 + c) as f32),
        Georef {
            crs: Crs::Projected(32733),
            west: 500_000.0,
            north: 9_000_000.0,
            pixel_width: 5.0,
            pixel_height: 5.0,
        },
    );
    let mut out = Cursor::new(Vec::new());
    write_geotiff(&g, &mut out).unwrap();
    let back = read_geotiff(&out.into_inner(), &ReadLimits::default()).unwrap();
    assert_eq!(back.georef, g.georef);
    assert_eq!(back.data, g.data);
    // The CRS is carried as "EPSG:32733" in JSON (store headers).
    assert_eq!(
        serde_json::to_string(&g.georef.crs).unwrap(),
        "\"EPSG:32733\""
    );
    let crs: Crs = serde_json::from_str("\"EPSG:26911\"").unwrap();
    assert_eq!(crs, Crs::Projected(26911));
    assert!(serde_json::from_str::<Crs>("\"EPSG:2154\"").is_err());
}

#[test]
fn unsupported_projected_codes_are_named() {
    let g = Grid::new(
        Array2::zeros((4, 4)),
        Georef {
            crs: Crs::Projected(32611),
            west: 0.0,
            north: 0.0,
            pixel_width: 1.0,
            pixel_height: 1.0,
        },
    );
    let mut out = Cursor::new(Vec::new());
    write_geotiff(&g, &mut out).unwrap();
    let mut bytes = out.into_inner();
    // Swap the EPSG code 32611 for 2154 (Lambert-93, not read) wherever the directory holds it.
    let needle = 32611u16.to_le_bytes();
    let at = bytes
        .windows(2)
        .rposition(|w| w == needle)
        .expect("the code in the GeoKeyDirectory");
    bytes[at..at + 2].copy_from_slice(&2154u16.to_le_bytes());
    let e = read_geotiff(&bytes, &ReadLimits::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("EPSG:2154"), "{e}");
}
