//! One tile's points as a binary glTF (GLB) point primitive: positions quantized to u16 per tile
//! (KHR_mesh_quantization; the node matrix holds the tile's step, origin and the z-up → y-up turn
//! of glTF), sRGB colours as linear u16 `COLOR_0`, and every other column as per-point metadata
//! (EXT_structural_metadata): 8/16-bit integers and f32 as property attributes (vertex
//! attributes, which glTF limits to those types), wider numbers in a property table reached
//! through implicit feature IDs (EXT_mesh_features: the feature ID is the vertex index).

use super::layout::{ExportLayout, Storage, TileColumns};
use serde_json::{json, Map, Value};

const ARRAY_BUFFER: u32 = 34962;
const UNSIGNED_SHORT: u32 = 5123;
const GLB_JSON: u32 = 0x4E4F_534A;
const GLB_BIN: u32 = 0x004E_4942;

/// Where a tile's local frame starts and how big its quantization step is: local (metres, or
/// store units for a local tileset) = metres_per_unit × (raw × scale + offset − origin).
pub struct TileFrame {
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub origin: [f64; 3],
    pub metres_per_unit: [f64; 3],
}

/// The GLB of `columns`, and what its quantization may lose per axis (store units).
pub fn encode(
    columns: &TileColumns,
    layout: &ExportLayout,
    frame: &TileFrame,
) -> (Vec<u8>, [f64; 3]) {
    let n = columns.len();
    let positions = columns.positions();
    let mut min = [i64::MAX; 3];
    let mut max = [i64::MIN; 3];
    for p in &positions {
        for a in 0..3 {
            min[a] = min[a].min(p[a] as i64);
            max[a] = max[a].max(p[a] as i64);
        }
    }
    // The smallest integer step that fits the tile's extent into u16: 1 (lossless) for small tiles.
    let step: [i64; 3] =
        std::array::from_fn(|a| ((max[a] - min[a]) as u64).div_ceil(65535).max(1) as i64);
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = Map::new();

    let mut q_max = [0u16; 3];
    let mut q_min = [u16::MAX; 3];
    // Rounded to the nearest step but never past the tile's last point: quantized points stay
    // inside the tile's bounds.
    let top: [i64; 3] = std::array::from_fn(|a| (max[a] - min[a]) / step[a]);
    let start = begin_view(&mut bin);
    for p in &positions {
        for a in 0..3 {
            let q = ((p[a] as i64 - min[a] + step[a] / 2) / step[a]).min(top[a]) as u16;
            q_min[a] = q_min[a].min(q);
            q_max[a] = q_max[a].max(q);
            bin.extend_from_slice(&q.to_le_bytes());
        }
        bin.extend_from_slice(&[0, 0]);
    }
    push_vertex_view(&mut views, start, bin.len(), 8);
    accessors.push(json!({
        "bufferView": views.len() - 1, "componentType": UNSIGNED_SHORT, "count": n, "type": "VEC3",
        "min": q_min, "max": q_max,
    }));
    attributes.insert("POSITION".into(), json!(accessors.len() - 1));

    if let Some(rgb) = columns.rgb(layout) {
        let start = begin_view(&mut bin);
        for c in rgb {
            for v in c {
                bin.extend_from_slice(&layout.linear_color(v).to_le_bytes());
            }
            bin.extend_from_slice(&[0, 0]);
        }
        push_vertex_view(&mut views, start, bin.len(), 8);
        accessors.push(json!({
            "bufferView": views.len() - 1, "componentType": UNSIGNED_SHORT, "normalized": true,
            "count": n, "type": "VEC3",
        }));
        attributes.insert("COLOR_0".into(), json!(accessors.len() - 1));
    }

    let mut attribute_properties = Map::new();
    let mut table_properties = Map::new();
    for (index, property) in layout.properties.iter().enumerate() {
        let start = begin_view(&mut bin);
        match property.storage {
            Storage::Attribute => {
                // Vertex attribute elements start on 4-byte boundaries (glTF 2.0 §3.6.2.4).
                let stride = property.size.next_multiple_of(4);
                for i in 0..n {
                    columns.value(layout, index, i, &mut bin);
                    bin.resize(start + (i + 1) * stride, 0);
                }
                push_vertex_view(&mut views, start, bin.len(), stride);
                accessors.push(json!({
                    "bufferView": views.len() - 1, "componentType": property.gl_type(),
                    "count": n, "type": "SCALAR",
                }));
                attributes.insert(property.semantic(), json!(accessors.len() - 1));
                attribute_properties.insert(
                    property.name.clone(),
                    json!({ "attribute": property.semantic() }),
                );
            }
            Storage::Table => {
                for i in 0..n {
                    columns.value(layout, index, i, &mut bin);
                }
                views.push(
                    json!({ "buffer": 0, "byteOffset": start, "byteLength": bin.len() - start }),
                );
                table_properties
                    .insert(property.name.clone(), json!({ "values": views.len() - 1 }));
            }
        }
    }

    let mut primitive = json!({ "mode": 0, "attributes": attributes });
    let mut root_metadata = Map::new();
    if !layout.properties.is_empty() {
        root_metadata.insert("schema".into(), layout.schema());
    }
    let mut extensions_used = vec!["KHR_mesh_quantization"];
    if !attribute_properties.is_empty() {
        root_metadata.insert(
            "propertyAttributes".into(),
            json!([{ "class": super::layout::ATTRIBUTE_CLASS, "properties": attribute_properties }]),
        );
        primitive["extensions"]["EXT_structural_metadata"] = json!({ "propertyAttributes": [0] });
    }
    if !table_properties.is_empty() {
        root_metadata.insert(
            "propertyTables".into(),
            json!([{ "class": super::layout::TABLE_CLASS, "count": n, "properties": table_properties }]),
        );
        primitive["extensions"]["EXT_mesh_features"] = json!({ "featureIds": [{ "featureCount": n, "propertyTable": 0, "label": "point_index" }] });
        extensions_used.push("EXT_mesh_features");
    }
    if !root_metadata.is_empty() {
        extensions_used.push("EXT_structural_metadata");
    }

    // Local = m·((min + q·step)·scale + offset − origin); glTF is y-up: (x, y, z) → (x, z, −y).
    let s: [f64; 3] =
        std::array::from_fn(|a| frame.metres_per_unit[a] * step[a] as f64 * frame.scale[a]);
    let t: [f64; 3] = std::array::from_fn(|a| {
        frame.metres_per_unit[a]
            * (min[a] as f64 * frame.scale[a] + frame.offset[a] - frame.origin[a])
    });
    let matrix = [
        s[0], 0.0, 0.0, 0.0, //
        0.0, 0.0, -s[1], 0.0, //
        0.0, s[2], 0.0, 0.0, //
        t[0], t[2], -t[1], 1.0,
    ];

    let mut document = json!({
        "asset": { "version": "2.0", "generator": "pointlet export-3dtiles" },
        "extensionsUsed": extensions_used,
        "extensionsRequired": ["KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0, "matrix": matrix }],
        "meshes": [{ "primitives": [primitive] }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    if !root_metadata.is_empty() {
        document["extensions"] = json!({ "EXT_structural_metadata": root_metadata });
    }
    // Half a step from rounding; up to a step less one below the clamped top.
    let error: [f64; 3] = std::array::from_fn(|a| (step[a] - 1) as f64 * frame.scale[a]);
    (glb(&document, bin), error)
}

/// Pads the binary buffer to 8 bytes (f64 table values need it) and returns where a view starts.
fn begin_view(bin: &mut Vec<u8>) -> usize {
    bin.resize(bin.len().next_multiple_of(8), 0);
    bin.len()
}

fn push_vertex_view(views: &mut Vec<Value>, start: usize, end: usize, stride: usize) {
    views.push(json!({
        "buffer": 0, "byteOffset": start, "byteLength": end - start,
        "byteStride": stride, "target": ARRAY_BUFFER,
    }));
}

/// The GLB container: header, JSON chunk (space-padded), BIN chunk (zero-padded).
fn glb(document: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut text = document.to_string().into_bytes();
    text.resize(text.len().next_multiple_of(4), b' ');
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&GLB_JSON.to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&GLB_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    out
}
