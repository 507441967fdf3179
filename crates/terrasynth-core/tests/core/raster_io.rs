//! Integration tests of the raster file formats: GeoTIFF decoding over every sample type,
//! compression, predictor and layout (fixtures built byte by byte by a test-only TIFF writer),
//! georeference and nodata handling, hostile input, round-trips of the writers, and a fuzz-style
//! property test that the readers never panic.

use std::io::{Cursor, Write};

use ndarray::Array2;
use proptest::prelude::*;
use terrasynth_core::raster::{
    read_exr, read_geotiff, read_geotiff_file, read_png16, read_raster_file, sniff, write_exr,
    write_geotiff, write_geotiff_file, write_png16, write_raster_file, Crs, Georef, Grid,
    LayeredRaster, RasterError, RasterFormat, ReadLimits, ELEVATION,
};

// ---------------------------------------------------------------------------------------------
// Test-only little-endian TIFF builder.
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq)]
enum Sample {
    U8,
    I16,
    U16,
    I32,
    F32,
    F64,
}

impl Sample {
    fn bytes(self) -> usize {
        match self {
            Sample::U8 => 1,
            Sample::I16 | Sample::U16 => 2,
            Sample::I32 | Sample::F32 => 4,
            Sample::F64 => 8,
        }
    }
    fn format(self) -> u16 {
        match self {
            Sample::U8 | Sample::U16 => 1,
            Sample::I16 | Sample::I32 => 2,
            Sample::F32 | Sample::F64 => 3,
        }
    }
    fn is_float(self) -> bool {
        self.format() == 3
    }
    /// Little-endian bytes of `v` in this type (`v` must be representable).
    fn encode(self, v: f64) -> Vec<u8> {
        match self {
            Sample::U8 => vec![v as u8],
            Sample::I16 => (v as i16).to_le_bytes().to_vec(),
            Sample::U16 => (v as u16).to_le_bytes().to_vec(),
            Sample::I32 => (v as i32).to_le_bytes().to_vec(),
            Sample::F32 => (v as f32).to_le_bytes().to_vec(),
            Sample::F64 => v.to_le_bytes().to_vec(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Comp {
    None,
    Deflate,
    OldDeflate,
    Lzw,
    PackBits,
}

impl Comp {
    fn code(self) -> u16 {
        match self {
            Comp::None => 1,
            Comp::Deflate => 8,
            Comp::OldDeflate => 32946,
            Comp::Lzw => 5,
            Comp::PackBits => 32773,
        }
    }
    fn compress(self, raw: &[u8]) -> Vec<u8> {
        match self {
            Comp::None => raw.to_vec(),
            Comp::Deflate | Comp::OldDeflate => {
                let mut e =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                e.write_all(raw).unwrap();
                e.finish().unwrap()
            }
            Comp::Lzw => weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
                .encode(raw)
                .unwrap(),
            Comp::PackBits => {
                // Literal runs only: a header byte n-1 then n bytes, n <= 128.
                let mut out = Vec::new();
                for run in raw.chunks(128) {
                    out.push((run.len() - 1) as u8);
                    out.extend_from_slice(run);
                }
                out
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    Strips(u32),
    Tiles(u32, u32),
}

#[derive(Clone, Debug)]
enum Transform {
    None,
    ScaleTie([f64; 3], [f64; 6]),
    Matrix([f64; 16]),
}

/// Everything the builder needs; `values` is row-major, `height × width`.
#[derive(Clone, Debug)]
struct Spec {
    width: u32,
    height: u32,
    values: Vec<f64>,
    sample: Sample,
    comp: Comp,
    predictor: u16,
    layout: Layout,
    transform: Transform,
    geokeys: Option<Vec<u16>>,
    nodata: Option<String>,
    samples_per_pixel: u16,
    /// Written as the Compression tag instead of `comp.code()` (data still compressed by `comp`).
    compression_tag: Option<u16>,
}

const GEOKEYS_4326: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326];
const GEOKEYS_3857: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 3857];

impl Spec {
    fn new(width: u32, height: u32, sample: Sample, f: impl Fn(usize, usize) -> f64) -> Spec {
        let mut values = Vec::new();
        for r in 0..height as usize {
            for c in 0..width as usize {
                values.push(f(r, c));
            }
        }
        Spec {
            width,
            height,
            values,
            sample,
            comp: Comp::None,
            predictor: 1,
            layout: Layout::Strips(height),
            transform: Transform::ScaleTie([0.5, 0.25, 0.0], [0.0, 0.0, 0.0, 10.0, 50.0, 0.0]),
            geokeys: Some(GEOKEYS_4326.to_vec()),
            nodata: None,
            samples_per_pixel: 1,
            compression_tag: None,
        }
    }

    /// Uncompressed, unpredicted bytes of one chunk: `cw × ch` samples whose top-left is
    /// `(r0, c0)`, zero-padded outside the image, then the predictor applied row by row.
    fn chunk_bytes(&self, r0: usize, c0: usize, cw: usize, ch: usize) -> Vec<u8> {
        let n = self.sample.bytes();
        let spp = self.samples_per_pixel as usize;
        let mut out = Vec::new();
        for r in r0..r0 + ch {
            let mut row = Vec::new();
            for c in c0..c0 + cw {
                let v = if r < self.height as usize && c < self.width as usize {
                    self.values[r * self.width as usize + c]
                } else {
                    0.0
                };
                for _ in 0..spp {
                    row.extend(self.sample.encode(v));
                }
            }
            match self.predictor {
                1 => {}
                2 => horizontal_difference(&mut row, n),
                3 => row = float_predict(&row, n),
                p => panic!("builder has no predictor {p}"),
            }
            out.extend(row);
        }
        out
    }

    fn build(&self) -> Vec<u8> {
        let mut file = b"II*\0\0\0\0\0".to_vec();
        let (w, h) = (self.width as usize, self.height as usize);
        let mut offsets = Vec::new();
        let mut counts = Vec::new();
        let mut push_chunk = |file: &mut Vec<u8>, raw: Vec<u8>| {
            let data = self.comp.compress(&raw);
            offsets.push(file.len() as u32);
            counts.push(data.len() as u32);
            file.extend(data);
        };
        match self.layout {
            Layout::Strips(rps) => {
                let mut r0 = 0;
                while r0 < h {
                    let rows = (rps as usize).min(h - r0);
                    let raw = self.chunk_bytes(r0, 0, w, rows);
                    push_chunk(&mut file, raw);
                    r0 += rps as usize;
                }
            }
            Layout::Tiles(tw, th) => {
                for r0 in (0..h).step_by(th as usize) {
                    for c0 in (0..w).step_by(tw as usize) {
                        let raw = self.chunk_bytes(r0, c0, tw as usize, th as usize);
                        push_chunk(&mut file, raw);
                    }
                }
            }
        }
        let spp = self.samples_per_pixel;
        let mut tags = TagList::default();
        tags.long(256, &[self.width]);
        tags.long(257, &[self.height]);
        tags.short(258, &vec![(self.sample.bytes() * 8) as u16; spp as usize]);
        tags.short(259, &[self.compression_tag.unwrap_or(self.comp.code())]);
        tags.short(262, &[1]);
        tags.short(277, &[spp]);
        tags.short(317, &[self.predictor]);
        tags.short(339, &vec![self.sample.format(); spp as usize]);
        match self.layout {
            Layout::Strips(rps) => {
                tags.long(273, &offsets);
                tags.long(278, &[rps]);
                tags.long(279, &counts);
            }
            Layout::Tiles(tw, th) => {
                tags.long(322, &[tw]);
                tags.long(323, &[th]);
                tags.long(324, &offsets);
                tags.long(325, &counts);
            }
        }
        match &self.transform {
            Transform::None => {}
            Transform::ScaleTie(s, t) => {
                tags.double(33550, s);
                tags.double(33922, t);
            }
            Transform::Matrix(m) => tags.double(34264, m),
        }
        if let Some(k) = &self.geokeys {
            tags.short(34735, k);
        }
        if let Some(nd) = &self.nodata {
            let mut b = nd.as_bytes().to_vec();
            b.push(0);
            tags.raw(42113, 2, b.len() as u32, b);
        }
        tags.write(&mut file);
        file
    }
}

/// Horizontal differencing of one row of `n`-byte little-endian samples, on their bit patterns
/// (as libtiff does, also for floats).
fn horizontal_difference(row: &mut [u8], n: usize) {
    let get = |row: &[u8], i: usize| -> u64 {
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&row[i * n..(i + 1) * n]);
        u64::from_le_bytes(b)
    };
    let count = row.len() / n;
    for i in (1..count).rev() {
        let d = get(row, i).wrapping_sub(get(row, i - 1));
        row[i * n..(i + 1) * n].copy_from_slice(&d.to_le_bytes()[..n]);
    }
}

/// The floating-point predictor (TIFF Technical Note 3): split each sample into big-endian byte
/// planes across the row, then difference the bytes.
fn float_predict(row: &[u8], n: usize) -> Vec<u8> {
    let count = row.len() / n;
    let mut out = vec![0u8; row.len()];
    for i in 0..count {
        for k in 0..n {
            // Little-endian input: big-endian byte k is little-endian byte n-1-k.
            out[k * count + i] = row[i * n + (n - 1 - k)];
        }
    }
    for i in (1..out.len()).rev() {
        out[i] = out[i].wrapping_sub(out[i - 1]);
    }
    out
}

#[derive(Default)]
struct TagList {
    entries: Vec<(u16, u16, u32, Vec<u8>)>,
}

impl TagList {
    fn raw(&mut self, tag: u16, ty: u16, count: u32, data: Vec<u8>) {
        self.entries.push((tag, ty, count, data));
    }
    fn short(&mut self, tag: u16, v: &[u16]) {
        let data = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.raw(tag, 3, v.len() as u32, data);
    }
    fn long(&mut self, tag: u16, v: &[u32]) {
        let data = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.raw(tag, 4, v.len() as u32, data);
    }
    fn double(&mut self, tag: u16, v: &[f64]) {
        let data = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.raw(tag, 12, v.len() as u32, data);
    }
    /// Appends out-of-line values, then the IFD, and points the header at it.
    fn write(mut self, file: &mut Vec<u8>) {
        self.entries.sort_by_key(|e| e.0);
        let mut fields = Vec::new();
        for (tag, ty, count, data) in &self.entries {
            let value = if data.len() <= 4 {
                let mut v = data.clone();
                v.resize(4, 0);
                v
            } else {
                if file.len() % 2 == 1 {
                    file.push(0);
                }
                let off = file.len() as u32;
                file.extend_from_slice(data);
                off.to_le_bytes().to_vec()
            };
            fields.push((*tag, *ty, *count, value));
        }
        if file.len() % 2 == 1 {
            file.push(0);
        }
        let ifd = file.len() as u32;
        file[4..8].copy_from_slice(&ifd.to_le_bytes());
        file.extend_from_slice(&(fields.len() as u16).to_le_bytes());
        for (tag, ty, count, value) in fields {
            file.extend_from_slice(&tag.to_le_bytes());
            file.extend_from_slice(&ty.to_le_bytes());
            file.extend_from_slice(&count.to_le_bytes());
            file.extend_from_slice(&value);
        }
        file.extend_from_slice(&0u32.to_le_bytes());
    }
}

/// The known value of cell `(r, c)` for each sample type: integers (negative for signed types)
/// and quarter-metre fractions for floats, all exact in every type used.
fn known_value(sample: Sample, r: usize, c: usize) -> f64 {
    let base = (r * 7) as f64 - (c * 3) as f64 + 100.0;
    match sample {
        Sample::U8 | Sample::U16 => base,
        Sample::I16 | Sample::I32 => base - 150.0,
        Sample::F32 | Sample::F64 => base * 0.25 - 10.5,
    }
}

fn limits() -> ReadLimits {
    ReadLimits::default()
}

fn small_spec() -> Spec {
    let mut s = Spec::new(19, 13, Sample::F32, |r, c| known_value(Sample::F32, r, c));
    s.comp = Comp::Deflate;
    s.layout = Layout::Strips(5);
    s
}

fn geo_4326() -> Georef {
    Georef {
        crs: Crs::Epsg4326,
        west: 10.0,
        north: 50.0,
        pixel_width: 0.5,
        pixel_height: 0.25,
    }
}

// ---------------------------------------------------------------------------------------------
// Decoding matrix: every sample type × compression × predictor × layout gives the exact values.
// ---------------------------------------------------------------------------------------------

#[test]
fn geotiff_decodes_every_type_compression_predictor_and_layout() {
    let samples = [
        Sample::U8,
        Sample::I16,
        Sample::U16,
        Sample::I32,
        Sample::F32,
        Sample::F64,
    ];
    let comps = [
        Comp::None,
        Comp::Deflate,
        Comp::OldDeflate,
        Comp::Lzw,
        Comp::PackBits,
    ];
    let layouts = [Layout::Strips(5), Layout::Strips(13), Layout::Tiles(16, 16)];
    let mut cases = 0;
    for &sample in &samples {
        let predictors: &[u16] = if sample.is_float() {
            &[1, 2, 3]
        } else {
            &[1, 2]
        };
        for &comp in &comps {
            for &predictor in predictors {
                for &layout in &layouts {
                    let mut spec = Spec::new(19, 13, sample, |r, c| known_value(sample, r, c));
                    spec.comp = comp;
                    spec.predictor = predictor;
                    spec.layout = layout;
                    let label = format!("{sample:?} {comp:?} predictor {predictor} {layout:?}");
                    let grid = read_geotiff(&spec.build(), &limits())
                        .unwrap_or_else(|e| panic!("{label}: {e}"));
                    assert_eq!(grid.data.dim(), (13, 19), "{label}");
                    for r in 0..13 {
                        for c in 0..19 {
                            assert_eq!(
                                grid.data[[r, c]] as f64,
                                known_value(sample, r, c),
                                "{label} at ({r}, {c})"
                            );
                        }
                    }
                    assert_eq!(grid.georef, geo_4326(), "{label}");
                    assert!(grid.valid.is_none(), "{label}");
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, 4 * 5 * 2 * 3 + 2 * 5 * 3 * 3);
}

#[test]
fn geotiff_float_predictor_round_trips_extreme_floats() {
    // Values whose byte planes differ a lot: signs, tiny and huge magnitudes.
    let vals = [
        -1.0e30, 3.5e-20, -0.0, 8848.86, -430.5, 1.0e-3, 65504.0, -7.25,
    ];
    for sample in [Sample::F32, Sample::F64] {
        let mut spec = Spec::new(8, 3, sample, |r, c| vals[(r * 3 + c) % 8]);
        spec.predictor = 3;
        spec.comp = Comp::Lzw;
        let grid = read_geotiff(&spec.build(), &limits()).unwrap();
        for r in 0..3 {
            for c in 0..8 {
                assert_eq!(
                    grid.data[[r, c]],
                    vals[(r * 3 + c) % 8] as f32,
                    "{sample:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Georeference: tiepoints, PixelIsPoint, ModelTransformation, Web Mercator, and bad georefs.
// ---------------------------------------------------------------------------------------------

#[test]
fn geotiff_tiepoint_at_a_non_origin_pixel_is_moved_to_the_corner() {
    let mut spec = small_spec();
    // Raster point (2, 3) is at (11, 49): the corner is 2 pixels west and 3 pixels north.
    spec.transform = Transform::ScaleTie([0.5, 0.25, 0.0], [2.0, 3.0, 0.0, 11.0, 49.0, 0.0]);
    let g = read_geotiff(&spec.build(), &limits()).unwrap().georef;
    assert_eq!(
        g,
        Georef {
            west: 10.0,
            north: 49.75,
            ..geo_4326()
        }
    );
}

#[test]
fn geotiff_pixel_is_point_shifts_by_half_a_pixel() {
    let mut spec = small_spec();
    let mut keys = GEOKEYS_4326.to_vec();
    keys[11] = 2; // GTRasterTypeGeoKey = PixelIsPoint
    spec.geokeys = Some(keys);
    let g = read_geotiff(&spec.build(), &limits()).unwrap().georef;
    assert_eq!(
        g,
        Georef {
            west: 9.75,
            north: 50.125,
            ..geo_4326()
        }
    );
}

#[test]
fn geotiff_north_up_model_transformation_is_read() {
    let mut spec = small_spec();
    spec.geokeys = Some(GEOKEYS_3857.to_vec());
    #[rustfmt::skip]
    let m = [
        30.0, 0.0, 0.0, -20_000.0,
        0.0, -40.0, 0.0, 600_000.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    spec.transform = Transform::Matrix(m);
    let g = read_geotiff(&spec.build(), &limits()).unwrap().georef;
    assert_eq!(
        g,
        Georef {
            crs: Crs::Epsg3857,
            west: -20_000.0,
            north: 600_000.0,
            pixel_width: 30.0,
            pixel_height: 40.0,
        }
    );
}

#[test]
fn geotiff_old_web_mercator_code_3785_maps_to_3857() {
    let mut spec = small_spec();
    let mut keys = GEOKEYS_3857.to_vec();
    keys[15] = 3785;
    spec.geokeys = Some(keys);
    spec.transform = Transform::ScaleTie([10.0, 10.0, 0.0], [0.0, 0.0, 0.0, 1000.0, 2000.0, 0.0]);
    let g = read_geotiff(&spec.build(), &limits()).unwrap().georef;
    assert_eq!(g.crs, Crs::Epsg3857);
    assert_eq!((g.west, g.north), (1000.0, 2000.0));
}

#[test]
fn geotiff_rotated_transformation_is_unsupported() {
    let mut spec = small_spec();
    #[rustfmt::skip]
    let m = [
        0.5, 0.1, 0.0, 10.0,
        0.0, -0.25, 0.0, 50.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    spec.transform = Transform::Matrix(m);
    let err = read_geotiff(&spec.build(), &limits()).unwrap_err();
    assert!(matches!(err, RasterError::Unsupported { .. }), "{err:?}");
}

#[test]
fn geotiff_missing_or_insane_georeference_is_rejected() {
    let bad = |spec: Spec, what: &str| {
        let err = read_geotiff(&spec.build(), &limits()).unwrap_err();
        assert!(
            matches!(err, RasterError::BadGeoreference(_)),
            "{what}: {err:?}"
        );
    };
    let mut s = small_spec();
    s.transform = Transform::None;
    s.geokeys = None;
    bad(s, "no geotags at all");
    let mut s = small_spec();
    s.transform = Transform::None;
    bad(s, "geokeys without a transform");
    let mut s = small_spec();
    s.geokeys = None;
    bad(s, "transform without geokeys");
    let mut s = small_spec();
    s.geokeys = Some(vec![1, 1, 0, 1, 1025, 0, 1, 1]);
    bad(s, "geokeys without a CRS");
    for (scale, what) in [
        ([0.0, 0.25, 0.0], "zero pixel width"),
        ([0.5, -0.25, 0.0], "negative pixel height"),
        ([f64::NAN, 0.25, 0.0], "NaN pixel width"),
        ([f64::INFINITY, 0.25, 0.0], "infinite pixel width"),
    ] {
        let mut s = small_spec();
        s.transform = Transform::ScaleTie(scale, [0.0, 0.0, 0.0, 10.0, 50.0, 0.0]);
        bad(s, what);
    }
    let mut s = small_spec();
    s.transform = Transform::ScaleTie([0.5, 0.25, 0.0], [0.0, 0.0, 0.0, 10.0, 95.0, 0.0]);
    bad(s, "north of the pole");
    let mut s = small_spec();
    s.transform = Transform::ScaleTie([0.5, 0.25, 0.0], [0.0, 0.0, 0.0, 355.0, 50.0, 0.0]);
    bad(s, "east beyond 360°");
}

#[test]
fn geotiff_other_crs_is_unsupported() {
    let mut spec = small_spec();
    let mut keys = GEOKEYS_4326.to_vec();
    keys[15] = 4269; // NAD83
    spec.geokeys = Some(keys);
    let err = read_geotiff(&spec.build(), &limits()).unwrap_err();
    assert!(
        matches!(&err, RasterError::Unsupported { detail, .. } if detail.contains("4269")),
        "{err:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Nodata: GDAL_NODATA cells and NaN cells become invalid; all-invalid rasters are errors.
// ---------------------------------------------------------------------------------------------

#[test]
fn geotiff_gdal_nodata_and_nan_mark_cells_invalid() {
    // Integer nodata.
    let mut spec = Spec::new(6, 4, Sample::I16, |r, c| {
        if (r + c) % 3 == 0 {
            -32768.0
        } else {
            (r * 10 + c) as f64
        }
    });
    spec.nodata = Some("-32768".to_string());
    spec.comp = Comp::Lzw;
    spec.predictor = 2;
    let g = read_geotiff(&spec.build(), &limits()).unwrap();
    let mask = g.valid.as_ref().expect("mask expected");
    for r in 0..4 {
        for c in 0..6 {
            let nodata = (r + c) % 3 == 0;
            assert_eq!(mask[[r, c]], !nodata, "({r}, {c})");
            assert_eq!(g.is_valid(r, c), !nodata);
            if !nodata {
                assert_eq!(g.data[[r, c]], (r * 10 + c) as f32);
            }
        }
    }
    assert_eq!(g.valid_count(), 24 - 8);

    // Float data: NaN always invalid; "nan" nodata adds nothing else; -9999 is a value then.
    let mut spec = Spec::new(3, 2, Sample::F32, |r, c| match (r, c) {
        (0, 1) => f64::NAN,
        (1, 2) => -9999.0,
        _ => 1.5,
    });
    spec.nodata = Some("nan".to_string());
    let g = read_geotiff(&spec.build(), &limits()).unwrap();
    let mask = g.valid.unwrap();
    assert_eq!(
        mask,
        Array2::from_shape_vec((2, 3), vec![true, false, true, true, true, true]).unwrap()
    );
    assert_eq!(g.data[[1, 2]], -9999.0);

    // NaN without any nodata tag is still invalid.
    let mut spec = Spec::new(
        2,
        1,
        Sample::F64,
        |_, c| if c == 0 { f64::NAN } else { 2.0 },
    );
    spec.nodata = None;
    let g = read_geotiff(&spec.build(), &limits()).unwrap();
    assert_eq!(g.valid.unwrap().as_slice().unwrap(), &[false, true]);
}

#[test]
fn geotiff_all_invalid_is_no_valid_data() {
    let spec = Spec::new(4, 3, Sample::F32, |_, _| f64::NAN);
    assert!(matches!(
        read_geotiff(&spec.build(), &limits()),
        Err(RasterError::NoValidData)
    ));
    let mut spec = Spec::new(4, 3, Sample::I16, |_, _| -32768.0);
    spec.nodata = Some("-32768".to_string());
    assert!(matches!(
        read_geotiff(&spec.build(), &limits()),
        Err(RasterError::NoValidData)
    ));
}

#[test]
fn geotiff_unparseable_nodata_is_malformed() {
    let mut spec = small_spec();
    spec.nodata = Some("missing".to_string());
    assert!(matches!(
        read_geotiff(&spec.build(), &limits()),
        Err(RasterError::Malformed { .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// Hostile or unsupported input: magic, truncation, huge headers, compression, bands.
// ---------------------------------------------------------------------------------------------

#[test]
fn geotiff_wrong_magic_is_unknown_format() {
    for bytes in [&b"GIF89a\0\0\0\0\0\0"[..], b"", b"II", b"II\x2a"] {
        let err = read_geotiff(bytes, &limits()).unwrap_err();
        assert!(
            matches!(
                err,
                RasterError::UnknownFormat(_) | RasterError::Malformed { .. }
            ),
            "{bytes:?}: {err:?}"
        );
    }
    assert!(matches!(
        read_geotiff(b"PK\x03\x04zipzipzip", &limits()),
        Err(RasterError::UnknownFormat(_))
    ));
}

#[test]
fn geotiff_every_truncation_is_an_error() {
    let full = small_spec().build();
    assert!(read_geotiff(&full, &limits()).is_ok());
    // The IFD (with its 4-byte next-IFD link) is at the end, so every truncation loses part of it.
    for len in 0..full.len() {
        assert!(
            read_geotiff(&full[..len], &limits()).is_err(),
            "truncated to {len} of {} bytes",
            full.len()
        );
    }
}

#[test]
fn geotiff_huge_headers_are_too_large_before_allocating() {
    for (w, h) in [(40_000u32, 40_000u32), (1_000_000, 1_000)] {
        // A header claiming a huge single-strip image over a few bytes of data.
        let mut spec = Spec::new(2, 2, Sample::F32, |_, _| 1.0);
        spec.width = w;
        spec.height = h;
        spec.layout = Layout::Strips(h);
        spec.values = vec![1.0; 4];
        let mut tags = TagList::default();
        let mut file = b"II*\0\0\0\0\0".to_vec();
        file.extend_from_slice(&[0u8; 16]);
        tags.long(256, &[w]);
        tags.long(257, &[h]);
        tags.short(258, &[32]);
        tags.short(259, &[1]);
        tags.short(262, &[1]);
        tags.long(273, &[8]);
        tags.short(277, &[1]);
        tags.long(278, &[h]);
        tags.long(279, &[16]);
        tags.short(339, &[3]);
        tags.double(33550, &[1e-6, 1e-6, 0.0]);
        tags.double(33922, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        tags.short(34735, &GEOKEYS_4326);
        tags.write(&mut file);
        let err = read_geotiff(&file, &limits()).unwrap_err();
        assert!(
            matches!(err, RasterError::TooLarge { width, height, limit }
                if width == u64::from(w) && height == u64::from(h) && limit == 1 << 28),
            "{w}×{h}: {err:?}"
        );
    }
    // A custom limit applies too.
    let tight = ReadLimits {
        max_pixels: 200,
        max_layers: 1,
    };
    assert!(matches!(
        read_geotiff(&small_spec().build(), &tight),
        Err(RasterError::TooLarge {
            width: 19,
            height: 13,
            limit: 200
        })
    ));
}

#[test]
fn geotiff_unsupported_compressions_are_unsupported() {
    for code in [7u16, 6, 2, 34712, 50000, 65000] {
        let mut spec = small_spec();
        spec.comp = Comp::None;
        spec.compression_tag = Some(code);
        let err = read_geotiff(&spec.build(), &limits()).unwrap_err();
        assert!(
            matches!(&err, RasterError::Unsupported { detail, .. } if detail.contains(&code.to_string())),
            "compression {code}: {err:?}"
        );
    }
}

#[test]
fn geotiff_several_bands_are_unsupported() {
    let mut spec = small_spec();
    spec.samples_per_pixel = 2;
    spec.comp = Comp::None;
    let err = read_geotiff(&spec.build(), &limits()).unwrap_err();
    assert!(matches!(err, RasterError::Unsupported { .. }), "{err:?}");
}

#[test]
fn geotiff_corrupt_deflate_stream_is_an_error() {
    let mut spec = small_spec();
    spec.comp = Comp::None;
    spec.compression_tag = Some(8); // raw floats are not a zlib stream
    assert!(read_geotiff(&spec.build(), &limits()).is_err());
}

// ---------------------------------------------------------------------------------------------
// GeoTIFF writer round-trips (values, georef, mask) in memory and through files.
// ---------------------------------------------------------------------------------------------

fn masked_grid(georef: Georef) -> Grid {
    let data = Array2::from_shape_fn((9, 14), |(r, c)| (r as f32) * 1.5 - (c as f32) * 0.125);
    let valid = Array2::from_shape_fn((9, 14), |(r, c)| (r * 14 + c) % 5 != 2);
    Grid {
        data,
        georef,
        valid: Some(valid),
    }
}

fn assert_same_valid_cells(a: &Grid, b: &Grid) {
    assert_eq!(a.data.dim(), b.data.dim());
    assert_eq!(a.georef, b.georef);
    for r in 0..a.rows() {
        for c in 0..a.cols() {
            assert_eq!(a.is_valid(r, c), b.is_valid(r, c), "({r}, {c})");
            if a.is_valid(r, c) {
                assert_eq!(a.data[[r, c]], b.data[[r, c]], "({r}, {c})");
            }
        }
    }
}

#[test]
fn geotiff_write_read_round_trip_keeps_values_georef_and_mask() {
    let mercator = Georef {
        crs: Crs::Epsg3857,
        west: -1_234_567.5,
        north: 4_500_000.25,
        pixel_width: 30.0,
        pixel_height: 30.0,
    };
    for georef in [geo_4326(), mercator] {
        let grid = masked_grid(georef);
        let mut buf = Cursor::new(Vec::new());
        write_geotiff(&grid, &mut buf).unwrap();
        let bytes = buf.into_inner();
        assert_eq!(sniff(&bytes), Some(RasterFormat::GeoTiff));
        let back = read_geotiff(&bytes, &limits()).unwrap();
        assert_same_valid_cells(&grid, &back);
        assert_eq!(back.valid, grid.valid);
        assert_eq!(back.valid_count(), grid.valid_count());
    }
    // Without a mask, no mask comes back and every value is identical.
    let grid = Grid::new(masked_grid(geo_4326()).data, geo_4326());
    let mut buf = Cursor::new(Vec::new());
    write_geotiff(&grid, &mut buf).unwrap();
    let back = read_geotiff(buf.get_ref(), &limits()).unwrap();
    assert_eq!(back, grid);
}

#[test]
fn geotiff_writer_rejects_insane_georef() {
    let mut grid = masked_grid(geo_4326());
    grid.georef.pixel_width = -1.0;
    let err = write_geotiff(&grid, Cursor::new(Vec::new())).unwrap_err();
    assert!(matches!(err, RasterError::BadGeoreference(_)), "{err:?}");
}

#[test]
fn raster_files_round_trip_through_disk_by_extension_and_magic() {
    let dir = tempfile::tempdir().unwrap();
    let grid = masked_grid(geo_4326());

    let tif = dir.path().join("dem.TIF");
    write_raster_file(&grid, &tif).unwrap();
    assert_same_valid_cells(&grid, &read_geotiff_file(&tif, &limits()).unwrap());
    let layered = read_raster_file(&tif, None, &limits()).unwrap();
    assert_same_valid_cells(&grid, &layered.elevation().unwrap());

    let tif2 = dir.path().join("dem2.tiff");
    write_geotiff_file(&grid, &tif2).unwrap();
    assert_eq!(std::fs::read(&tif).unwrap(), std::fs::read(&tif2).unwrap());

    let exr_path = dir.path().join("dem.exr");
    write_raster_file(&grid, &exr_path).unwrap();
    let err = read_raster_file(&exr_path, None, &limits()).unwrap_err();
    assert!(
        matches!(&err, RasterError::BadGeoreference(m) if m.contains("OpenEXR")),
        "{err:?}"
    );
    let layered = read_raster_file(&exr_path, Some(geo_4326()), &limits()).unwrap();
    assert_eq!(layered.layers.len(), 1);
    assert_same_valid_cells(&grid, &layered.elevation().unwrap());

    let png_path = dir.path().join("dem.png");
    let ints = Grid::new(
        Array2::from_shape_fn((4, 5), |(r, c)| (r * 5 + c) as f32),
        geo_4326(),
    );
    std::fs::write(&png_path, write_png16(&ints).unwrap()).unwrap();
    let err = read_raster_file(&png_path, None, &limits()).unwrap_err();
    assert!(
        matches!(&err, RasterError::BadGeoreference(m) if m.contains("PNG")),
        "{err:?}"
    );
    let layered = read_raster_file(&png_path, Some(geo_4326()), &limits()).unwrap();
    assert_eq!(layered.elevation().unwrap(), ints);

    let err = write_raster_file(&grid, &dir.path().join("dem.png")).unwrap_err();
    assert!(matches!(err, RasterError::Unsupported { .. }), "{err:?}");
    assert!(write_raster_file(&grid, &dir.path().join("dem")).is_err());

    let junk = dir.path().join("junk.bin");
    std::fs::write(&junk, b"hello world").unwrap();
    assert!(matches!(
        read_raster_file(&junk, Some(geo_4326()), &limits()),
        Err(RasterError::UnknownFormat(_))
    ));
    assert!(matches!(
        read_raster_file(&dir.path().join("absent.tif"), None, &limits()),
        Err(RasterError::Io(_))
    ));
}

// ---------------------------------------------------------------------------------------------
// OpenEXR: multi-layer round-trip, channel naming, sample type conversion, limits.
// ---------------------------------------------------------------------------------------------

fn three_layers() -> LayeredRaster {
    let mut r = LayeredRaster {
        georef: geo_4326(),
        layers: Vec::new(),
        valid: None,
    };
    r.push_layer(
        ELEVATION,
        Array2::from_shape_fn((7, 5), |(r, c)| 1000.0 + r as f32 * 3.25 - c as f32),
    )
    .unwrap();
    r.push_layer(
        "slope",
        Array2::from_shape_fn((7, 5), |(r, c)| (r * c) as f32 * 0.01),
    )
    .unwrap();
    r.push_layer(
        "Y",
        Array2::from_shape_fn((7, 5), |(r, c)| -(r as f32) - c as f32),
    )
    .unwrap();
    r
}

#[test]
fn exr_multi_layer_round_trip_keeps_names_values_and_mask() {
    let mut raster = three_layers();
    let mask = Array2::from_shape_fn((7, 5), |(r, c)| !(r == 3 && c == 1));
    raster.valid = Some(mask.clone());
    let bytes = write_exr(&raster).unwrap();
    assert_eq!(sniff(&bytes), Some(RasterFormat::Exr));
    let back = read_exr(&bytes, geo_4326(), &limits()).unwrap();
    assert_eq!(back.georef, geo_4326());
    assert_eq!(back.layers.len(), 3);
    assert_eq!(back.layers[0].0, ELEVATION, "elevation comes first");
    for (name, data) in &raster.layers {
        let got = back.layer(name).unwrap_or_else(|| panic!("layer {name}"));
        for ((r, c), v) in data.indexed_iter() {
            if mask[[r, c]] {
                assert_eq!(got[[r, c]], *v, "{name} ({r}, {c})");
            } else {
                assert!(got[[r, c]].is_nan());
            }
        }
    }
    assert_eq!(back.valid, Some(mask));
}

#[test]
fn exr_single_channel_becomes_elevation_and_types_convert() {
    use exr::prelude::*;
    let f16_vals: Vec<f16> = (0..12).map(|i| f16::from_f32(i as f32 * 0.5)).collect();
    let write = |channels: SmallVec<[AnyChannel<FlatSamples>; 4]>| {
        let layer = Layer::new(
            (4, 3),
            LayerAttributes::default(),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(channels),
        );
        let mut out = Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut out)
            .unwrap();
        out.into_inner()
    };
    let one = write(SmallVec::from_vec(vec![AnyChannel::new(
        "Y",
        FlatSamples::F16(f16_vals.clone()),
    )]));
    let r = read_exr(&one, geo_4326(), &limits()).unwrap();
    assert_eq!(r.layers.len(), 1);
    assert_eq!(r.layers[0].0, ELEVATION);
    assert_eq!(r.layers[0].1[[2, 3]], 5.5);
    assert!(r.valid.is_none());

    let two = write(SmallVec::from_vec(vec![
        AnyChannel::new("Y", FlatSamples::F16(f16_vals)),
        AnyChannel::new(
            "count",
            FlatSamples::U32((0..12).map(|i| i * 1000).collect()),
        ),
    ]));
    let r = read_exr(&two, geo_4326(), &limits()).unwrap();
    let names: Vec<&str> = r.layers.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["Y", "count"]);
    assert_eq!(r.layer("count").unwrap()[[1, 2]], 6000.0);
    assert_eq!(r.layer("Y").unwrap()[[1, 0]], 2.0);
    assert!(r.elevation().is_none());
}

#[test]
fn exr_limits_and_georef_are_checked() {
    let bytes = write_exr(&three_layers()).unwrap();
    let tight = ReadLimits {
        max_pixels: 34,
        max_layers: 16,
    };
    assert!(matches!(
        read_exr(&bytes, geo_4326(), &tight),
        Err(RasterError::TooLarge {
            width: 5,
            height: 7,
            limit: 34
        })
    ));
    let few_layers = ReadLimits {
        max_pixels: 1 << 20,
        max_layers: 2,
    };
    assert!(matches!(
        read_exr(&bytes, geo_4326(), &few_layers),
        Err(RasterError::Unsupported { .. })
    ));
    let bad = Georef {
        pixel_height: 0.0,
        ..geo_4326()
    };
    assert!(matches!(
        read_exr(&bytes, bad, &limits()),
        Err(RasterError::BadGeoreference(_))
    ));
    assert!(matches!(
        read_exr(b"not an exr", geo_4326(), &limits()),
        Err(RasterError::UnknownFormat(_))
    ));
    let mut all_nan = three_layers();
    all_nan.valid = Some(Array2::from_elem((7, 5), false));
    let bytes = write_exr(&all_nan).unwrap();
    assert!(matches!(
        read_exr(&bytes, geo_4326(), &limits()),
        Err(RasterError::NoValidData)
    ));
    for len in [0, 4, 20, bytes.len() / 2, bytes.len() - 1] {
        assert!(
            read_exr(&bytes[..len], geo_4326(), &limits()).is_err(),
            "len {len}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// 16-bit PNG: rounding/clamping writer, reader, unsupported variants, limits.
// ---------------------------------------------------------------------------------------------

#[test]
fn png16_round_trip_rounds_and_clamps() {
    let input = [
        -5.0f32,
        0.4,
        0.6,
        70_000.0,
        1234.5,
        8848.0,
        f32::NAN,
        65535.0,
    ];
    let grid = Grid::new(
        Array2::from_shape_vec((2, 4), input.to_vec()).unwrap(),
        geo_4326(),
    );
    let bytes = write_png16(&grid).unwrap();
    assert_eq!(sniff(&bytes), Some(RasterFormat::Png));
    let back = read_png16(&bytes, geo_4326(), &limits()).unwrap();
    let expected = [0.0f32, 0.0, 1.0, 65535.0, 1235.0, 8848.0, 0.0, 65535.0];
    assert_eq!(back.data.as_slice().unwrap(), &expected);
    assert_eq!(back.georef, geo_4326());
    assert!(back.valid.is_none());
}

fn png_bytes(color: png::ColorType, depth: png::BitDepth, w: u32, h: u32, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut writer = enc.write_header().unwrap();
        writer.write_image_data(data).unwrap();
    }
    out
}

#[test]
fn png16_reads_big_endian_samples_and_rejects_other_formats() {
    let raw = [0x01, 0x02, 0xff, 0xfe, 0x00, 0x07];
    let bytes = png_bytes(
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        3,
        1,
        &raw,
    );
    let g = read_png16(&bytes, geo_4326(), &limits()).unwrap();
    assert_eq!(g.data.as_slice().unwrap(), &[258.0, 65534.0, 7.0]);

    let gray8 = png_bytes(
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        2,
        2,
        &[1, 2, 3, 4],
    );
    let rgb16 = png_bytes(png::ColorType::Rgb, png::BitDepth::Sixteen, 1, 1, &[0; 6]);
    for bytes in [gray8, rgb16] {
        let err = read_png16(&bytes, geo_4326(), &limits()).unwrap_err();
        assert!(matches!(err, RasterError::Unsupported { .. }), "{err:?}");
    }
    let tight = ReadLimits {
        max_pixels: 2,
        max_layers: 1,
    };
    assert!(matches!(
        read_png16(&bytes, geo_4326(), &tight),
        Err(RasterError::TooLarge {
            width: 3,
            height: 1,
            limit: 2
        })
    ));
    let bad = Georef {
        north: 91.0,
        ..geo_4326()
    };
    assert!(matches!(
        read_png16(&bytes, bad, &limits()),
        Err(RasterError::BadGeoreference(_))
    ));
    // Cutting into the image data is an error; cutting only the trailing 12-byte IEND chunk
    // may still decode, but then to exactly the right values.
    let iend_start = bytes.len() - 12;
    for len in 0..bytes.len() {
        match read_png16(&bytes[..len], geo_4326(), &limits()) {
            Err(_) => {}
            Ok(g) => {
                assert!(len >= iend_start, "len {len} decoded");
                assert_eq!(g.data.as_slice().unwrap(), &[258.0, 65534.0, 7.0]);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Fuzz-style property: bit flips and truncations of valid files never panic any reader.
// ---------------------------------------------------------------------------------------------

fn mutate(bytes: &[u8], flips: &[(usize, u8)], cut: Option<usize>) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for &(i, x) in flips {
        let n = b.len();
        if n > 0 {
            b[i % n] ^= x;
        }
    }
    if let Some(cut) = cut {
        let n = b.len();
        b.truncate(cut % (n + 1));
    }
    b
}

fn fuzz_inputs() -> (Vec<u8>, Vec<u8>, Vec<u8>, Vec<u8>) {
    let mut tiled = small_spec();
    tiled.layout = Layout::Tiles(16, 16);
    tiled.comp = Comp::Lzw;
    tiled.predictor = 3;
    let png = write_png16(&Grid::new(
        Array2::from_shape_fn((6, 5), |(r, c)| (r * 100 + c) as f32),
        geo_4326(),
    ))
    .unwrap();
    (
        small_spec().build(),
        tiled.build(),
        png,
        write_exr(&three_layers()).unwrap(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn readers_never_panic_on_corrupted_files(
        flips in proptest::collection::vec((any::<usize>(), 1u8..=255), 0..6),
        cut in proptest::option::of(any::<usize>()),
    ) {
        let (tiff_strips, tiff_tiles, png, exr) = fuzz_inputs();
        let small = ReadLimits { max_pixels: 1 << 16, max_layers: 8 };
        for tiff in [&tiff_strips, &tiff_tiles] {
            let _ = read_geotiff(&mutate(tiff, &flips, cut), &small);
        }
        let _ = read_png16(&mutate(&png, &flips, cut), geo_4326(), &small);
        let _ = read_exr(&mutate(&exr, &flips, cut), geo_4326(), &small);
    }
}
