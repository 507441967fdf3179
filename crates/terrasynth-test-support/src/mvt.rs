//! A small Mapbox Vector Tile 2.1 reader written from the specification (protobuf wire format
//! and geometry commands by hand), independent of the `mvt` crate the server encodes with: the
//! tests read the served bytes as a client would.

/// A property value of a feature.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `string_value`.
    String(String),
    /// `float_value` or `double_value`.
    Number(f64),
    /// `int_value`, `uint_value` or `sint_value`.
    Int(i64),
    /// `bool_value`.
    Bool(bool),
}

/// A decoded feature.
#[derive(Clone, Debug, PartialEq)]
pub struct Feature {
    /// Geometry type: 1 point, 2 line string, 3 polygon.
    pub geom_type: u64,
    /// Parts (one per `MoveTo`), points in tile units.
    pub parts: Vec<Vec<(i64, i64)>>,
    /// Properties in tag order.
    pub properties: Vec<(String, Value)>,
}

impl Feature {
    /// The property `key`.
    pub fn get(&self, key: &str) -> Option<&Value> {
        self.properties
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v)
    }
}

/// A decoded layer.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Layer name.
    pub name: String,
    /// Extent (default 4096).
    pub extent: u64,
    /// Its features.
    pub features: Vec<Feature>,
}

fn varint(b: &[u8], i: &mut usize) -> u64 {
    let mut v = 0u64;
    let mut shift = 0;
    loop {
        let byte = b[*i];
        *i += 1;
        v |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return v;
        }
        shift += 7;
    }
}

/// The fields of a protobuf message: `(field number, wire type, varint value or bytes)`.
fn fields(b: &[u8]) -> Vec<(u64, u64, u64, &[u8])> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let key = varint(b, &mut i);
        let (field, wire) = (key >> 3, key & 7);
        match wire {
            0 => {
                let v = varint(b, &mut i);
                out.push((field, wire, v, &b[0..0]));
            }
            1 => {
                out.push((field, wire, 0, &b[i..i + 8]));
                i += 8;
            }
            2 => {
                let n = varint(b, &mut i) as usize;
                out.push((field, wire, 0, &b[i..i + n]));
                i += n;
            }
            5 => {
                out.push((field, wire, 0, &b[i..i + 4]));
                i += 4;
            }
            w => panic!("unexpected wire type {w}"),
        }
    }
    out
}

fn packed(b: &[u8]) -> Vec<u64> {
    let mut i = 0;
    let mut v = Vec::new();
    while i < b.len() {
        v.push(varint(b, &mut i));
    }
    v
}

fn zigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

fn value(b: &[u8]) -> Value {
    let (f, _, v, bytes) = fields(b)[0];
    match f {
        1 => Value::String(String::from_utf8(bytes.to_vec()).unwrap()),
        2 => Value::Number(f64::from(f32::from_le_bytes(bytes.try_into().unwrap()))),
        3 => Value::Number(f64::from_le_bytes(bytes.try_into().unwrap())),
        4 | 5 => Value::Int(v as i64),
        6 => Value::Int(zigzag(v)),
        7 => Value::Bool(v != 0),
        other => panic!("unknown value field {other}"),
    }
}

/// Geometry commands into parts (cursor carried across parts, as the specification says).
fn geometry(cmds: &[u64]) -> Vec<Vec<(i64, i64)>> {
    let (mut x, mut y) = (0i64, 0i64);
    let mut parts: Vec<Vec<(i64, i64)>> = Vec::new();
    let mut i = 0;
    while i < cmds.len() {
        let (id, count) = (cmds[i] & 7, cmds[i] >> 3);
        i += 1;
        match id {
            1 | 2 => {
                for _ in 0..count {
                    x += zigzag(cmds[i]);
                    y += zigzag(cmds[i + 1]);
                    i += 2;
                    if id == 1 {
                        parts.push(Vec::new());
                    }
                    parts.last_mut().expect("MoveTo first").push((x, y));
                }
            }
            7 => {}
            other => panic!("unknown command {other}"),
        }
    }
    parts
}

/// The layers of a tile.
pub fn decode(tile: &[u8]) -> Vec<Layer> {
    let mut layers = Vec::new();
    for (f, _, _, lb) in fields(tile) {
        if f != 3 {
            continue;
        }
        let mut name = String::new();
        let mut extent = 4096;
        let (mut keys, mut values, mut raw) = (Vec::new(), Vec::new(), Vec::new());
        for (lf, _, v, b) in fields(lb) {
            match lf {
                1 => name = String::from_utf8(b.to_vec()).unwrap(),
                2 => raw.push(b),
                3 => keys.push(String::from_utf8(b.to_vec()).unwrap()),
                4 => values.push(value(b)),
                5 => extent = v,
                _ => {}
            }
        }
        let features = raw
            .into_iter()
            .map(|fb| {
                let (mut tags, mut geom, mut geom_type) = (Vec::new(), Vec::new(), 0);
                for (ff, _, v, b) in fields(fb) {
                    match ff {
                        2 => tags = packed(b),
                        3 => geom_type = v,
                        4 => geom = packed(b),
                        _ => {}
                    }
                }
                Feature {
                    geom_type,
                    parts: geometry(&geom),
                    properties: tags
                        .chunks(2)
                        .map(|kv| (keys[kv[0] as usize].clone(), values[kv[1] as usize].clone()))
                        .collect(),
                }
            })
            .collect();
        layers.push(Layer {
            name,
            extent,
            features,
        });
    }
    layers
}
