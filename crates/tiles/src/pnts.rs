//! The Point Cloud (`pnts`) tile format of 3D Tiles 1.0 (§"Point Cloud").
//!
//! Layout: a 28-byte header (magic `pnts`, version 1, byteLength, then the byte lengths of the
//! feature table JSON and binary and of the batch table JSON and binary), followed by those
//! four parts in that order. Every length is checked against the buffer before a part is cut
//! out, and every semantic's byte range against its binary part before it is read.
//!
//! Feature table semantics read here: the globals `POINTS_LENGTH`, `RTC_CENTER`,
//! `QUANTIZED_VOLUME_OFFSET`/`_SCALE`, `CONSTANT_RGBA`, `BATCH_LENGTH` (as JSON values or as
//! `byteOffset` references into the binary), and per point `POSITION` (float32×3),
//! `POSITION_QUANTIZED` (uint16×3: `offset + q × scale / 65535`), `RGBA`, `RGB`, `RGB565`,
//! `NORMAL`, `NORMAL_OCT16P` and `BATCH_ID` (uint8/16/32). Precedence follows the format:
//! `POSITION` over `POSITION_QUANTIZED`; `RGBA` over `RGB` over `RGB565` over `CONSTANT_RGBA`;
//! `NORMAL` over `NORMAL_OCT16P`. Positions are `RTC_CENTER + position` in the tile's frame,
//! then the tile's world transform (pnts is z-up: no axis rotation). The batch table is read by
//! [`crate::batch_table`]. Draco-compressed point clouds are reported as unsupported.

use crate::batch_table;
use crate::bytes::{read_f64s, ComponentType, Strided};
use crate::content::{transform_normal, ContentContext, TilePoints};
use crate::TilesError;
use serde_json::{Map, Value};

const HEADER_BYTES: usize = 28;
const DRACO: &str = "3DTILES_draco_point_compression";

/// Decodes a `pnts` tile into world-space points.
pub fn decode(bytes: &[u8], context: &ContentContext) -> Result<TilePoints, TilesError> {
    let uri = context.uri;
    let invalid = |message: String| TilesError::content(uri, message);
    if bytes.len() < HEADER_BYTES {
        return Err(invalid(format!(
            "truncated pnts: {} bytes, the header alone has {HEADER_BYTES}",
            bytes.len()
        )));
    }
    if &bytes[..4] != b"pnts" {
        return Err(invalid(format!(
            "wrong magic {:?}, expected \"pnts\"",
            String::from_utf8_lossy(&bytes[..4])
        )));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let version = word(4);
    if version != 1 {
        return Err(TilesError::unsupported(
            uri,
            format!("pnts version {version} (only version 1 exists)"),
        ));
    }
    let byte_length = word(8) as u64;
    if byte_length > bytes.len() as u64 {
        return Err(invalid(format!(
            "truncated pnts: the header says {byte_length} bytes, the file has {}",
            bytes.len()
        )));
    }
    let parts = [word(12), word(16), word(20), word(24)].map(u64::from);
    let total = HEADER_BYTES as u64 + parts.iter().sum::<u64>();
    if total > byte_length {
        return Err(invalid(format!(
            "pnts part lengths (feature table JSON {}, binary {}, batch table JSON {}, \
             binary {}) add up to {total} bytes with the header, beyond byteLength {byte_length}",
            parts[0], parts[1], parts[2], parts[3]
        )));
    }
    let mut cursor = HEADER_BYTES;
    let mut cut = |len: u64| {
        let start = cursor;
        cursor += len as usize;
        &bytes[start..cursor]
    };
    let ft_json = cut(parts[0]);
    let ft_bin = cut(parts[1]);
    let bt_json = cut(parts[2]);
    let bt_bin = cut(parts[3]);

    let ft = parse_json_object(ft_json).map_err(|e| invalid(format!("feature table JSON: {e}")))?;
    if let Some(Value::Object(ext)) = ft.get("extensions") {
        if ext.contains_key(DRACO) {
            return Err(TilesError::unsupported(
                uri,
                format!("Draco-compressed point cloud ({DRACO})"),
            ));
        }
    }
    let table = FeatureTable {
        json: &ft,
        binary: ft_bin,
    };
    let points = table
        .global("POINTS_LENGTH", ComponentType::U32, 1)
        .map_err(invalid)?
        .ok_or_else(|| invalid("feature table has no POINTS_LENGTH".into()))?[0];
    if !(points >= 0.0 && points.fract() == 0.0 && points <= u32::MAX as f64) {
        return Err(invalid(format!("POINTS_LENGTH {points} is not a count")));
    }
    let points = points as usize;

    let positions = read_positions(&table, points, context).map_err(invalid)?;
    let mut out = TilePoints {
        uri: uri.to_string(),
        positions,
        ..TilePoints::default()
    };
    out.colors = read_colors(&table, points).map_err(invalid)?;
    out.normals = read_normals(&table, points, context).map_err(invalid)?;

    let batch_ids = table
        .per_point("BATCH_ID", batch_id_type(&ft).map_err(invalid)?, 1, points)
        .map_err(invalid)?
        .map(|(view, ty)| {
            (0..view.len())
                .map(|i| ty.read_f64(view.element(i)) as u64)
                .collect::<Vec<u64>>()
        });
    let batch_length = table
        .global("BATCH_LENGTH", ComponentType::U32, 1)
        .map_err(invalid)?
        .map(|v| v[0] as usize);
    let feature_count = match (&batch_ids, batch_length) {
        (Some(_), Some(n)) => n,
        (Some(ids), None) => {
            let n = ids.iter().max().map_or(0, |m| *m as usize + 1);
            out.notes.push(format!(
                "BATCH_ID without BATCH_LENGTH: {n} batches assumed (the largest id + 1)"
            ));
            n
        }
        (None, _) => points,
    };
    if let Some(ids) = &batch_ids {
        if let Some(bad) = ids.iter().find(|id| **id as usize >= feature_count) {
            return Err(invalid(format!(
                "BATCH_ID {bad} is not below BATCH_LENGTH {feature_count}"
            )));
        }
        out.attributes.push(crate::content::PointAttribute {
            name: "BATCH_ID".into(),
            components: 1,
            values: crate::content::AttributeValues::Int(ids.iter().map(|v| *v as i64).collect()),
        });
    }
    if !bt_json.is_empty() {
        let bt =
            parse_json_object(bt_json).map_err(|e| invalid(format!("batch table JSON: {e}")))?;
        if let Some(Value::Object(ext)) = bt.get("extensions") {
            if ext.contains_key(DRACO) {
                return Err(TilesError::unsupported(
                    uri,
                    format!("Draco-compressed batch table ({DRACO})"),
                ));
            }
        }
        let (attributes, notes) =
            batch_table::read(&bt, bt_bin, feature_count, batch_ids.as_deref(), points)
                .map_err(|e| invalid(format!("batch table: {e}")))?;
        out.attributes.extend(attributes);
        out.notes.extend(notes);
    }
    Ok(out)
}

/// A JSON part: empty or padding-only means an empty object; anything else must be an object.
fn parse_json_object(bytes: &[u8]) -> Result<Map<String, Value>, String> {
    let trimmed: &[u8] = {
        let end = bytes
            .iter()
            .rposition(|b| !b.is_ascii_whitespace() && *b != 0)
            .map_or(0, |i| i + 1);
        &bytes[..end]
    };
    if trimmed.is_empty() {
        return Ok(Map::new());
    }
    match serde_json::from_slice::<Value>(trimmed) {
        Ok(Value::Object(map)) => Ok(map),
        Ok(_) => Err("not a JSON object".into()),
        Err(e) => Err(format!("invalid JSON: {e}")),
    }
}

/// A feature table: its JSON header and binary body.
struct FeatureTable<'a> {
    json: &'a Map<String, Value>,
    binary: &'a [u8],
}

fn byte_offset(value: &Value, name: &str) -> Result<Option<usize>, String> {
    match value.get("byteOffset") {
        None => Ok(None),
        Some(v) => match v.as_u64() {
            Some(o) => usize::try_from(o)
                .map(Some)
                .map_err(|_| format!("{name}.byteOffset {o} is too large")),
            None => Err(format!(
                "{name}.byteOffset {v} is not a non-negative integer"
            )),
        },
    }
}

impl<'a> FeatureTable<'a> {
    /// A global semantic of `count` values: a JSON number or array, or a binary reference.
    fn global(
        &self,
        name: &str,
        ty: ComponentType,
        count: usize,
    ) -> Result<Option<Vec<f64>>, String> {
        let Some(value) = self.json.get(name) else {
            return Ok(None);
        };
        let numbers: Vec<f64> = match value {
            Value::Number(n) => vec![n.as_f64().unwrap_or(f64::NAN)],
            Value::Array(items) => items
                .iter()
                .map(|v| {
                    v.as_f64()
                        .ok_or_else(|| format!("{name} holds a non-number {v}"))
                })
                .collect::<Result<_, _>>()?,
            Value::Object(_) => {
                let offset = byte_offset(value, name)?
                    .ok_or_else(|| format!("{name} is an object without byteOffset"))?;
                let size = ty.size() * count;
                let view = Strided::new(self.binary, offset, size, 1, size)
                    .map_err(|e| format!("{name} in the feature table binary: {e}"))?;
                read_f64s(&view, ty, count, false)
            }
            other => {
                return Err(format!(
                    "{name} is {other}, not a number, array or reference"
                ))
            }
        };
        if numbers.len() != count {
            return Err(format!(
                "{name} has {} values instead of {count}",
                numbers.len()
            ));
        }
        if let Some(bad) = numbers.iter().find(|v| !v.is_finite()) {
            return Err(format!("{name} holds a non-finite value {bad}"));
        }
        Ok(Some(numbers))
    }

    /// A per-point semantic: `points` elements of `components` values of `ty`.
    fn per_point(
        &self,
        name: &str,
        ty: ComponentType,
        components: usize,
        points: usize,
    ) -> Result<Option<(Strided<'a>, ComponentType)>, String> {
        let Some(value) = self.json.get(name) else {
            return Ok(None);
        };
        let offset = byte_offset(value, name)?
            .ok_or_else(|| format!("{name} must be an object with a byteOffset"))?;
        let size = ty.size() * components;
        let view = Strided::new(self.binary, offset, size, points, size)
            .map_err(|e| format!("{name} in the feature table binary: {e}"))?;
        Ok(Some((view, ty)))
    }
}

fn batch_id_type(ft: &Map<String, Value>) -> Result<ComponentType, String> {
    match ft.get("BATCH_ID").and_then(|v| v.get("componentType")) {
        None => Ok(ComponentType::U16),
        Some(Value::String(s)) => match ComponentType::from_tiles_name(s) {
            Some(t @ (ComponentType::U8 | ComponentType::U16 | ComponentType::U32)) => Ok(t),
            _ => Err(format!(
                "BATCH_ID componentType {s} is not UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT"
            )),
        },
        Some(other) => Err(format!("BATCH_ID componentType {other} is not a string")),
    }
}

fn read_positions(
    table: &FeatureTable,
    points: usize,
    context: &ContentContext,
) -> Result<Vec<[f64; 3]>, String> {
    let rtc = table.global("RTC_CENTER", ComponentType::F32, 3)?;
    let rtc = rtc.map_or([0.0; 3], |v| [v[0], v[1], v[2]]);
    let local: Vec<[f64; 3]> =
        if let Some((view, ty)) = table.per_point("POSITION", ComponentType::F32, 3, points)? {
            read_f64s(&view, ty, 3, false)
                .chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]])
                .collect()
        } else if let Some((view, ty)) =
            table.per_point("POSITION_QUANTIZED", ComponentType::U16, 3, points)?
        {
            let offset = table
                .global("QUANTIZED_VOLUME_OFFSET", ComponentType::F32, 3)?
                .ok_or("POSITION_QUANTIZED without QUANTIZED_VOLUME_OFFSET")?;
            let scale = table
                .global("QUANTIZED_VOLUME_SCALE", ComponentType::F32, 3)?
                .ok_or("POSITION_QUANTIZED without QUANTIZED_VOLUME_SCALE")?;
            read_f64s(&view, ty, 3, false)
                .chunks_exact(3)
                .map(|q| [0, 1, 2].map(|i| offset[i] + q[i] * scale[i] / 65535.0))
                .collect()
        } else {
            return Err("feature table has neither POSITION nor POSITION_QUANTIZED".into());
        };
    Ok(local
        .into_iter()
        .map(|p| {
            context
                .world
                .apply_point([p[0] + rtc[0], p[1] + rtc[1], p[2] + rtc[2]])
        })
        .collect())
}

fn read_colors(table: &FeatureTable, points: usize) -> Result<Vec<[u8; 4]>, String> {
    if let Some((view, _)) = table.per_point("RGBA", ComponentType::U8, 4, points)? {
        return Ok((0..points)
            .map(|i| {
                let e = view.element(i);
                [e[0], e[1], e[2], e[3]]
            })
            .collect());
    }
    if let Some((view, _)) = table.per_point("RGB", ComponentType::U8, 3, points)? {
        return Ok((0..points)
            .map(|i| {
                let e = view.element(i);
                [e[0], e[1], e[2], 255]
            })
            .collect());
    }
    if let Some((view, _)) = table.per_point("RGB565", ComponentType::U16, 1, points)? {
        let widen = |v: u16, max: u16| ((v as u32 * 255 + max as u32 / 2) / max as u32) as u8;
        return Ok((0..points)
            .map(|i| {
                let e = view.element(i);
                let c = u16::from_le_bytes([e[0], e[1]]);
                [
                    widen(c >> 11, 31),
                    widen((c >> 5) & 63, 63),
                    widen(c & 31, 31),
                    255,
                ]
            })
            .collect());
    }
    if let Some(c) = table.global("CONSTANT_RGBA", ComponentType::U8, 4)? {
        if let Some(bad) = c.iter().find(|v| !(0.0..=255.0).contains(*v)) {
            return Err(format!("CONSTANT_RGBA value {bad} is not a byte"));
        }
        let c = [c[0] as u8, c[1] as u8, c[2] as u8, c[3] as u8];
        return Ok(vec![c; points]);
    }
    Ok(vec![[255; 4]; points])
}

fn read_normals(
    table: &FeatureTable,
    points: usize,
    context: &ContentContext,
) -> Result<Option<Vec<[f32; 3]>>, String> {
    let normal_matrix = context.world.normal_matrix();
    if let Some((view, ty)) = table.per_point("NORMAL", ComponentType::F32, 3, points)? {
        let values = read_f64s(&view, ty, 3, false);
        return Ok(Some(
            values
                .chunks_exact(3)
                .map(|n| transform_normal(&normal_matrix, [n[0], n[1], n[2]]))
                .collect(),
        ));
    }
    if let Some((view, _)) = table.per_point("NORMAL_OCT16P", ComponentType::U8, 2, points)? {
        return Ok(Some(
            (0..points)
                .map(|i| {
                    let e = view.element(i);
                    transform_normal(&normal_matrix, oct_decode(e[0], e[1]))
                })
                .collect(),
        ));
    }
    Ok(None)
}

/// An octahedron-encoded unit vector (two bytes, each mapped to [−1, 1]).
pub fn oct_decode(x: u8, y: u8) -> [f64; 3] {
    let sign = |v: f64| if v < 0.0 { -1.0 } else { 1.0 };
    let mut v = [
        x as f64 / 255.0 * 2.0 - 1.0,
        y as f64 / 255.0 * 2.0 - 1.0,
        0.0,
    ];
    v[2] = 1.0 - v[0].abs() - v[1].abs();
    if v[2] < 0.0 {
        let (a, b) = (v[0], v[1]);
        v[0] = (1.0 - b.abs()) * sign(a);
        v[1] = (1.0 - a.abs()) * sign(b);
    }
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / len)
}
