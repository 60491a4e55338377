//! What an export writes for each point of a store: the streams it reads, the colour
//! conversion, and one metadata property per attribute (LAS columns and documented extra-bytes
//! attributes), each with its component type and where glTF can hold it.

use pointlet_core::extra::{ExtraAttributes, ExtraType};
use pointlet_store::{StoreHeader, StreamKind};
use serde_json::{json, Map, Value};

/// The schema class of the properties held as vertex attributes.
pub const ATTRIBUTE_CLASS: &str = "point";
/// The schema class of the properties held in the property table (wider than glTF attributes).
pub const TABLE_CLASS: &str = "point_wide";

/// Where a property's values go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// A vertex attribute named by the property (EXT_structural_metadata property attribute).
    Attribute,
    /// A property-table column indexed by implicit feature IDs (one feature per point).
    Table,
}

/// How a property's bytes come out of a point's stream bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueSource {
    /// `size` bytes at `at` of stream `stream` (an index into [`ExportLayout::kinds`]).
    Bytes {
        stream: usize,
        at: usize,
    },
    LowNibble {
        stream: usize,
    },
    HighNibble {
        stream: usize,
    },
}

/// One per-point metadata property.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    pub name: String,
    /// EXT_structural_metadata componentType (`UINT16`, `FLOAT64`, ...).
    pub component: &'static str,
    pub size: usize,
    pub storage: Storage,
    pub source: ValueSource,
    pub no_data: Option<f64>,
    pub description: Option<String>,
}

impl Property {
    /// The vertex attribute's semantic: application-specific ones start with `_`.
    pub fn semantic(&self) -> String {
        format!("_{}", self.name.to_ascii_uppercase())
    }

    /// The glTF accessor componentType of an attribute property.
    pub fn gl_type(&self) -> u32 {
        match self.component {
            "INT8" => 5120,
            "UINT8" => 5121,
            "INT16" => 5122,
            "UINT16" => 5123,
            _ => 5126,
        }
    }
}

/// Everything per store that the tile writer needs.
#[derive(Clone, Debug)]
pub struct ExportLayout {
    /// Streams read for each point, position first.
    pub kinds: Vec<StreamKind>,
    pub bytes_per_point: Vec<usize>,
    /// Index of the RGB stream in `kinds`.
    pub rgb: Option<usize>,
    /// 16-bit linear value of each stored colour value.
    color_lut: Vec<u16>,
    pub eight_bit_color: bool,
    pub properties: Vec<Property>,
    /// What is not exported, one line each.
    pub notes: Vec<String>,
}

impl ExportLayout {
    /// The layout for a store with `header`; `eight_bit_color` when its colours are 8-bit
    /// values in LAS's 16-bit fields; without `metadata`, positions and colours only.
    pub fn new(header: &StoreHeader, eight_bit_color: bool, metadata: bool) -> ExportLayout {
        let mut kinds = vec![StreamKind::Position];
        let mut properties = Vec::new();
        let mut notes = Vec::new();
        let stream_of = |kind: StreamKind, kinds: &mut Vec<StreamKind>| {
            kinds.push(kind);
            kinds.len() - 1
        };
        let plain = |name: &str, component, size, storage, source| Property {
            name: name.to_string(),
            component,
            size,
            storage,
            source,
            no_data: None,
            description: None,
        };
        if !metadata {
            notes.push(
                "per-point metadata left out (--no-metadata): positions and colours only".into(),
            );
        }
        for (kind, _) in StreamKind::present(&header.layout) {
            use StreamKind::*;
            if !metadata && !matches!(kind, Position | Rgb) {
                continue;
            }
            let (component, size, storage) = match kind {
                Position | Rgb | Waveform | ExtraBytes | Returns => ("", 0, Storage::Attribute),
                Intensity | PointSourceId | Nir => ("UINT16", 2, Storage::Attribute),
                Flags | Classification | UserData => ("UINT8", 1, Storage::Attribute),
                ScanAngle => ("FLOAT32", 4, Storage::Attribute),
                GpsTime => ("FLOAT64", 8, Storage::Table),
            };
            match kind {
                Position => {}
                Rgb => {}
                Waveform => notes.push(
                    "waveform packet descriptors are not exported (no waveform data in 3D Tiles)"
                        .into(),
                ),
                Returns => {
                    let stream = stream_of(kind, &mut kinds);
                    properties.push(plain(
                        "return_number",
                        "UINT8",
                        1,
                        Storage::Attribute,
                        ValueSource::LowNibble { stream },
                    ));
                    properties.push(plain(
                        "number_of_returns",
                        "UINT8",
                        1,
                        Storage::Attribute,
                        ValueSource::HighNibble { stream },
                    ));
                }
                ExtraBytes => {
                    let extra = ExtraAttributes::from_vlrs(
                        &header.vlrs,
                        header.layout.extra_bytes as usize,
                    );
                    if extra.undocumented > 0 {
                        notes.push(format!(
                            "{} undocumented extra bytes per point are not exported",
                            extra.undocumented
                        ));
                    }
                    if let Some(problem) = &extra.problem {
                        notes.push(format!("extra bytes: {problem}"));
                    }
                    if extra.attributes.is_empty() {
                        continue;
                    }
                    let stream = stream_of(kind, &mut kinds);
                    for a in &extra.attributes {
                        let (component, storage) = match a.kind {
                            ExtraType::U8 => ("UINT8", Storage::Attribute),
                            ExtraType::I8 => ("INT8", Storage::Attribute),
                            ExtraType::U16 => ("UINT16", Storage::Attribute),
                            ExtraType::I16 => ("INT16", Storage::Attribute),
                            ExtraType::F32 => ("FLOAT32", Storage::Attribute),
                            ExtraType::U32 => ("UINT32", Storage::Table),
                            ExtraType::I32 => ("INT32", Storage::Table),
                            ExtraType::U64 => ("UINT64", Storage::Table),
                            ExtraType::I64 => ("INT64", Storage::Table),
                            ExtraType::F64 => ("FLOAT64", Storage::Table),
                        };
                        let mut description = a.description.clone();
                        if a.scale != 1.0 || a.offset != 0.0 {
                            // Class offset/scale apply only to floats and normalized integers:
                            // raw values stay exact, the scaling is stated instead.
                            description = format!(
                                "{description} (raw LAS extra-bytes value; value = raw × {} + {})",
                                a.scale, a.offset
                            )
                            .trim()
                            .to_string();
                        }
                        properties.push(Property {
                            name: a.name.clone(),
                            component,
                            size: a.kind.bytes(),
                            storage,
                            source: ValueSource::Bytes { stream, at: a.at },
                            no_data: a.no_data,
                            description: (!description.is_empty()).then_some(description),
                        });
                    }
                }
                _ => {
                    let stream = stream_of(kind, &mut kinds);
                    properties.push(plain(
                        kind.name(),
                        component,
                        size,
                        storage,
                        ValueSource::Bytes { stream, at: 0 },
                    ));
                }
            }
        }
        let rgb = header.layout.rgb.then(|| {
            kinds.push(StreamKind::Rgb);
            kinds.len() - 1
        });
        unique_names(&mut properties);
        let bytes_per_point = kinds
            .iter()
            .map(|k| k.bytes_per_point(&header.layout).unwrap_or(0))
            .collect();
        let max = if eight_bit_color { 255.0 } else { 65535.0 };
        let lut_len = if eight_bit_color { 256 } else { 65536 };
        let color_lut = (0..lut_len)
            .map(|v| (srgb_to_linear((v as f64 / max).min(1.0)) * 65535.0).round() as u16)
            .collect();
        ExportLayout {
            kinds,
            bytes_per_point,
            rgb,
            color_lut,
            eight_bit_color,
            properties,
            notes,
        }
    }

    /// The linear u16 of a stored colour value (values past 255 in an 8-bit store saturate).
    pub fn linear_color(&self, v: u16) -> u16 {
        self.color_lut[(v as usize).min(self.color_lut.len() - 1)]
    }

    /// The EXT_structural_metadata schema of the properties.
    pub fn schema(&self) -> Value {
        let mut classes = Map::new();
        for (class, storage) in [
            (ATTRIBUTE_CLASS, Storage::Attribute),
            (TABLE_CLASS, Storage::Table),
        ] {
            let mut properties = Map::new();
            for p in self.properties.iter().filter(|p| p.storage == storage) {
                let mut entry = json!({ "type": "SCALAR", "componentType": p.component });
                if let Some(no_data) = p.no_data {
                    entry["noData"] = json!(no_data);
                }
                if let Some(d) = &p.description {
                    entry["description"] = json!(d);
                }
                properties.insert(p.name.clone(), entry);
            }
            if !properties.is_empty() {
                classes.insert(class.into(), json!({ "properties": properties }));
            }
        }
        json!({ "id": "pointlet", "classes": classes })
    }
}

/// sRGB transfer function inverted (IEC 61966-2-1).
fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.04045 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// Property names as EXT_structural_metadata wants them (`[A-Za-z_][A-Za-z0-9_]*`), unique.
fn unique_names(properties: &mut [Property]) {
    let mut taken: Vec<String> = Vec::new();
    for p in properties.iter_mut() {
        let mut name: String = p
            .name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() {
                    c.to_ascii_lowercase()
                } else {
                    '_'
                }
            })
            .collect();
        if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit()) {
            name.insert(0, '_');
        }
        let base = name.clone();
        let mut k = 2;
        while taken.contains(&name) {
            name = format!("{base}_{k}");
            k += 1;
        }
        taken.push(name.clone());
        p.name = name;
    }
}

/// The points of one tile: the raw bytes of each stream of [`ExportLayout::kinds`].
#[derive(Clone, Debug, Default)]
pub struct TileColumns {
    pub streams: Vec<Vec<u8>>,
    pub count: usize,
}

impl TileColumns {
    pub fn new(layout: &ExportLayout) -> TileColumns {
        TileColumns {
            streams: vec![Vec::new(); layout.kinds.len()],
            count: 0,
        }
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Appends point `i` of `raw` (one byte vector per stream, as read).
    pub fn push_from(&mut self, layout: &ExportLayout, raw: &[Vec<u8>], i: usize) {
        for (s, bytes) in raw.iter().enumerate() {
            let b = layout.bytes_per_point[s];
            self.streams[s].extend_from_slice(&bytes[i * b..(i + 1) * b]);
        }
        self.count += 1;
    }

    pub fn positions(&self) -> Vec<[i32; 3]> {
        pointlet_store::decode_positions(&self.streams[0])
    }

    /// The stored colours, when the store has them.
    pub fn rgb<'a>(&'a self, layout: &ExportLayout) -> Option<impl Iterator<Item = [u16; 3]> + 'a> {
        let s = layout.rgb?;
        Some(self.streams[s].chunks_exact(6).map(|c| {
            [
                u16::from_le_bytes([c[0], c[1]]),
                u16::from_le_bytes([c[2], c[3]]),
                u16::from_le_bytes([c[4], c[5]]),
            ]
        }))
    }

    /// Appends the bytes of property `index` of point `i` to `out`.
    pub fn value(&self, layout: &ExportLayout, index: usize, i: usize, out: &mut Vec<u8>) {
        let p = &layout.properties[index];
        match p.source {
            ValueSource::Bytes { stream, at } => {
                let b = layout.bytes_per_point[stream];
                let start = i * b + at;
                out.extend_from_slice(&self.streams[stream][start..start + p.size]);
            }
            ValueSource::LowNibble { stream } => out.push(self.streams[stream][i] & 0x0f),
            ValueSource::HighNibble { stream } => out.push(self.streams[stream][i] >> 4),
        }
    }
}
