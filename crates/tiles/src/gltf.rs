//! glTF 2.0 tile content (3D Tiles 1.1 §"glTF"): GLB or JSON glTF whose mesh primitives of
//! mode POINTS (0) are point clouds.
//!
//! The GLB container and the glTF JSON are parsed by the `gltf` crate (`gltf::Glb`,
//! `gltf::json::Root`); every index the document holds is looked up with `Root::get` and every
//! byte range is checked, so malformed documents give errors, never panics. Node transforms and
//! the `CESIUM_RTC` center are read from the raw JSON in f64 (the crate stores them in f32).
//!
//! A point's world position is `tile world × translate(CESIUM_RTC) × up-axis rotation ×
//! node transforms (root → leaf) × POSITION`, where the up-axis rotation takes glTF's y-up to
//! the z-up frame of 3D Tiles (3D Tiles 1.1 §"glTF transforms"; `asset.gltfUpAxis` may name
//! X or Z instead). POSITION is float, or an 8/16-bit integer, normalized or not
//! (KHR_mesh_quantization: the node transform dequantizes). COLOR_0 (float, unorm8, unorm16;
//! VEC3 or VEC4) is linear and comes out as sRGB 8-bit; NORMAL (float or normalized
//! 8/16-bit) is mapped by the inverse transpose. Buffer views compressed with
//! EXT_meshopt_compression are decoded by [`crate::meshopt`]; per-point metadata
//! (EXT_mesh_features, EXT_structural_metadata) is read by [`crate::metadata`]. Primitives of
//! other modes are skipped with a note. Sparse accessors and Draco (KHR_draco_mesh_compression)
//! are reported as unsupported.

use crate::bytes::{read_f64s, ComponentType, Strided};
use crate::content::{
    linear_to_srgb8, transform_normal, unit_to_u8, AttributeValues, ContentContext, PointAttribute,
    TilePoints,
};
use crate::transform::Transform;
use crate::{resolve_uri, TilesError};
use gltf::json::validation::Checked;
use gltf::json::{self as gj, Root};
use serde::Deserialize;
use serde_json::Value;
use std::borrow::Cow;

/// Extensions that may be required: the decoder handles them (or their absence is harmless
/// for points).
const HANDLED_REQUIRED: &[&str] = &[
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_materials_unlit",
    "CESIUM_RTC",
    "EXT_mesh_features",
    "EXT_structural_metadata",
    "KHR_texture_transform",
];

/// Decodes a GLB (binary glTF) tile.
pub fn decode_glb(bytes: &[u8], context: &ContentContext) -> Result<TilePoints, TilesError> {
    let uri = context.uri;
    if bytes.len() < 12 {
        return Err(TilesError::content(
            uri,
            format!(
                "truncated GLB: {} bytes, the header alone has 12",
                bytes.len()
            ),
        ));
    }
    if &bytes[..4] != b"glTF" {
        return Err(TilesError::content(
            uri,
            format!(
                "wrong magic {:?}, expected \"glTF\"",
                String::from_utf8_lossy(&bytes[..4])
            ),
        ));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let version = word(4);
    if version != 2 {
        return Err(TilesError::unsupported(
            uri,
            format!("GLB version {version} (only glTF 2)"),
        ));
    }
    let length = word(8) as usize;
    if length < 20 || length > bytes.len() {
        return Err(TilesError::content(
            uri,
            format!(
                "GLB length {length} does not fit the file of {} bytes (at least 20 needed)",
                bytes.len()
            ),
        ));
    }
    // The length was checked above: `gltf::Glb` subtracts the header from it unchecked.
    let glb = gltf::Glb::from_slice(&bytes[..length])
        .map_err(|e| TilesError::content(uri, format!("GLB: {e}")))?;
    decode_document(&glb.json, glb.bin.as_deref(), context)
}

/// Decodes a JSON glTF tile (buffers from data URIs or files next to it).
pub fn decode_gltf_json(bytes: &[u8], context: &ContentContext) -> Result<TilePoints, TilesError> {
    decode_document(bytes, None, context)
}

fn decode_document(
    json: &[u8],
    bin: Option<&[u8]>,
    context: &ContentContext,
) -> Result<TilePoints, TilesError> {
    let uri = context.uri;
    let invalid = |m: String| TilesError::content(uri, m);
    let raw: Value =
        serde_json::from_slice(json).map_err(|e| invalid(format!("glTF JSON: {e}")))?;
    let root = Root::deserialize(&raw).map_err(|e| invalid(format!("glTF: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(TilesError::unsupported(
            uri,
            format!("glTF version {} (only 2.x)", root.asset.version),
        ));
    }
    let unhandled: Vec<&String> = root
        .extensions_required
        .iter()
        .filter(|e| !HANDLED_REQUIRED.contains(&e.as_str()))
        .collect();
    if !unhandled.is_empty() {
        return Err(TilesError::unsupported(
            uri,
            format!("glTF requires extensions {unhandled:?}"),
        ));
    }
    let buffers = load_buffers(&root, bin, context)?;
    let document = Document {
        root: &root,
        raw: &raw,
        buffers,
    };
    let rtc = match raw.pointer("/extensions/CESIUM_RTC/center") {
        None => Transform::IDENTITY,
        Some(center) => Transform::from_translation(
            numbers::<3>(center)
                .ok_or_else(|| invalid("CESIUM_RTC center is not 3 finite numbers".into()))?,
        ),
    };
    let base = context.world.mul(&rtc).mul(&context.up_axis.to_z_up());
    let mut parts = Vec::new();
    let mut notes = Vec::new();
    for (node, global) in document.mesh_nodes(&base).map_err(invalid)? {
        let Some(mesh_index) = node.mesh else {
            continue;
        };
        let mesh = root
            .get(mesh_index)
            .ok_or_else(|| invalid(format!("mesh {} does not exist", mesh_index.value())))?;
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let at = format!("mesh {} primitive {p}", mesh_index.value());
            match primitive.mode {
                Checked::Valid(gj::mesh::Mode::Points) => {}
                Checked::Valid(mode) => {
                    notes.push(format!("{at}: mode {mode:?} is not points: skipped"));
                    continue;
                }
                Checked::Invalid => return Err(invalid(format!("{at}: invalid mode"))),
            }
            if primitive
                .extensions
                .as_ref()
                .is_some_and(|e| e.others.contains_key("KHR_draco_mesh_compression"))
            {
                return Err(TilesError::unsupported(
                    uri,
                    format!("{at}: Draco-compressed primitive (KHR_draco_mesh_compression)"),
                ));
            }
            let raw_primitive = raw
                .pointer(&format!("/meshes/{}/primitives/{p}", mesh_index.value()))
                .unwrap_or(&Value::Null);
            let part = document
                .primitive(primitive, raw_primitive, &global, &at, uri)
                .map_err(|e| match e {
                    PrimitiveError::Invalid(m) => invalid(format!("{at}: {m}")),
                    PrimitiveError::Unsupported(m) => {
                        TilesError::unsupported(uri, format!("{at}: {m}"))
                    }
                })?;
            parts.push(part);
        }
    }
    let mut out = crate::content::merge_parts(uri, parts);
    notes.append(&mut out.notes);
    out.notes = notes;
    Ok(out)
}

/// `N` finite numbers of a JSON array.
pub(crate) fn numbers<const N: usize>(value: &Value) -> Option<[f64; N]> {
    let items = value.as_array()?;
    if items.len() != N {
        return None;
    }
    let mut out = [0.0; N];
    for (o, v) in out.iter_mut().zip(items) {
        *o = v.as_f64().filter(|x| x.is_finite())?;
    }
    Some(out)
}

fn load_buffers<'a>(
    root: &Root,
    bin: Option<&'a [u8]>,
    context: &ContentContext,
) -> Result<Vec<Option<Cow<'a, [u8]>>>, TilesError> {
    let uri = context.uri;
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buffer) in root.buffers.iter().enumerate() {
        let data: Option<Cow<[u8]>> = match &buffer.uri {
            None if i == 0 => bin.map(Cow::Borrowed),
            None => None,
            Some(u) if u.starts_with("data:") => {
                Some(Cow::Owned(decode_data_uri(u).ok_or_else(|| {
                    TilesError::content(uri, format!("buffer {i}: invalid data URI"))
                })?))
            }
            Some(u) => {
                let source = context.source.ok_or_else(|| {
                    TilesError::unsupported(
                        uri,
                        format!("buffer {i}: external buffer {u} without a source"),
                    )
                })?;
                Some(Cow::Owned(source.read(&resolve_uri(uri, u))?))
            }
        };
        let declared = buffer.byte_length.0;
        if let Some(d) = &data {
            if (d.len() as u64) < declared {
                return Err(TilesError::content(
                    uri,
                    format!(
                        "buffer {i} has {} bytes, its byteLength says {declared}",
                        d.len()
                    ),
                ));
            }
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes of a base64 `data:` URI.
fn decode_data_uri(uri: &str) -> Option<Vec<u8>> {
    let (header, payload) = uri.split_once(',')?;
    if !header.ends_with(";base64") {
        return Some(crate::source::percent_decode(payload).into_bytes());
    }
    let mut out = Vec::with_capacity(payload.len() / 4 * 3);
    let mut acc: u32 = 0;
    let mut bits = 0;
    for c in payload.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

pub(crate) enum PrimitiveError {
    Invalid(String),
    Unsupported(String),
}

impl From<String> for PrimitiveError {
    fn from(m: String) -> Self {
        PrimitiveError::Invalid(m)
    }
}

impl From<&str> for PrimitiveError {
    fn from(m: &str) -> Self {
        PrimitiveError::Invalid(m.to_string())
    }
}

/// A parsed glTF with its buffers.
pub(crate) struct Document<'a> {
    pub root: &'a Root,
    pub raw: &'a Value,
    pub buffers: Vec<Option<Cow<'a, [u8]>>>,
}

/// An accessor's elements: `components` values of `ty` per element.
pub(crate) struct AccessorData<'a> {
    pub bytes: Cow<'a, [u8]>,
    pub offset: usize,
    pub stride: usize,
    pub count: usize,
    pub ty: ComponentType,
    pub components: usize,
    pub normalized: bool,
}

impl AccessorData<'_> {
    pub fn view(&self) -> Result<Strided<'_>, String> {
        Strided::new(
            &self.bytes,
            self.offset,
            self.stride,
            self.count,
            self.ty.size() * self.components,
        )
    }

    /// Every value as f64, normalized integers mapped when the accessor says so.
    pub fn f64s(&self) -> Result<Vec<f64>, String> {
        Ok(read_f64s(
            &self.view()?,
            self.ty,
            self.components,
            self.normalized,
        ))
    }
}

impl<'a> Document<'a> {
    /// The nodes of the scene with their global transforms (`base` × root → node).
    fn mesh_nodes(&self, base: &Transform) -> Result<Vec<(&'a gj::Node, Transform)>, String> {
        let root = self.root;
        let scene = match root.scene {
            Some(s) => Some(
                root.get(s)
                    .ok_or_else(|| format!("scene {} does not exist", s.value()))?,
            ),
            None => root.scenes.first(),
        };
        let starts: Vec<usize> = match scene {
            Some(scene) => scene.nodes.iter().map(|n| n.value()).collect(),
            None => {
                // No scene: every node that is nobody's child.
                let mut is_child = vec![false; root.nodes.len()];
                for node in &root.nodes {
                    for c in node.children.iter().flatten() {
                        if let Some(flag) = is_child.get_mut(c.value()) {
                            *flag = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|i| !is_child[*i]).collect()
            }
        };
        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, Transform)> =
            starts.into_iter().rev().map(|n| (n, *base)).collect();
        let mut out = Vec::new();
        while let Some((index, parent)) = stack.pop() {
            let node = root
                .nodes
                .get(index)
                .ok_or_else(|| format!("node {index} does not exist"))?;
            if std::mem::replace(&mut visited[index], true) {
                return Err(format!(
                    "node {index} is reached twice: the node hierarchy is not a tree"
                ));
            }
            let global = parent.mul(&self.node_matrix(index)?);
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), global));
            }
            if node.mesh.is_some() {
                out.push((node, global));
            }
        }
        Ok(out)
    }

    /// A node's local transform from the raw JSON, in f64.
    fn node_matrix(&self, index: usize) -> Result<Transform, String> {
        let node = self
            .raw
            .pointer(&format!("/nodes/{index}"))
            .unwrap_or(&Value::Null);
        let bad = || format!("node {index} has a malformed or non-finite transform");
        let m = if let Some(m) = node.get("matrix") {
            Transform(numbers::<16>(m).ok_or_else(bad)?)
        } else {
            let t = match node.get("translation") {
                Some(v) => numbers::<3>(v).ok_or_else(bad)?,
                None => [0.0; 3],
            };
            let r = match node.get("rotation") {
                Some(v) => numbers::<4>(v).ok_or_else(bad)?,
                None => [0.0, 0.0, 0.0, 1.0],
            };
            let s = match node.get("scale") {
                Some(v) => numbers::<3>(v).ok_or_else(bad)?,
                None => [1.0; 3],
            };
            Transform::from_trs(t, r, s)
        };
        Ok(m)
    }

    /// The bytes of a buffer view (decompressed when EXT_meshopt_compression applies) and its
    /// stride.
    pub(crate) fn view(
        &self,
        index: usize,
    ) -> Result<(Cow<'_, [u8]>, Option<usize>), PrimitiveError> {
        let view = self
            .root
            .buffer_views
            .get(index)
            .ok_or_else(|| format!("buffer view {index} does not exist"))?;
        let stride = view.byte_stride.map(|s| s.0);
        if let Some(ext) = view.extensions.as_ref().and_then(|e| {
            e.others
                .get("EXT_meshopt_compression")
                .or_else(|| e.others.get("KHR_meshopt_compression"))
        }) {
            let decoded = crate::meshopt::decode_view(ext, &self.buffers)
                .map_err(|m| PrimitiveError::Invalid(format!("buffer view {index}: {m}")))?;
            let stride = stride.or_else(|| {
                ext.get("byteStride")
                    .and_then(Value::as_u64)
                    .map(|s| s as usize)
            });
            return Ok((Cow::Owned(decoded), stride));
        }
        let buffer = self
            .buffers
            .get(view.buffer.value())
            .ok_or_else(|| {
                format!(
                    "buffer view {index}: buffer {} does not exist",
                    view.buffer.value()
                )
            })?
            .as_ref()
            .ok_or_else(|| {
                format!(
                    "buffer view {index}: buffer {} has no data",
                    view.buffer.value()
                )
            })?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        match end {
            Some(end) if end <= buffer.len() as u64 => {
                Ok((Cow::Borrowed(&buffer[start as usize..end as usize]), stride))
            }
            _ => Err(format!(
                "buffer view {index} ({} bytes at {start}) reaches past its buffer of {} bytes",
                view.byte_length.0,
                buffer.len()
            )
            .into()),
        }
    }

    /// An accessor's data; `max_count` bounds accessors without a buffer view (all zeros).
    pub fn accessor(
        &self,
        index: usize,
        max_count: usize,
    ) -> Result<AccessorData<'_>, PrimitiveError> {
        let accessor = self
            .root
            .accessors
            .get(index)
            .ok_or_else(|| format!("accessor {index} does not exist"))?;
        if accessor.sparse.is_some() {
            return Err(PrimitiveError::Unsupported(format!(
                "accessor {index} is sparse"
            )));
        }
        let ty = match accessor.component_type {
            Checked::Valid(t) => ComponentType::from_gl(t.0.as_gl_enum()),
            Checked::Invalid => None,
        }
        .ok_or_else(|| format!("accessor {index} has an invalid componentType"))?;
        let components = match accessor.type_ {
            Checked::Valid(t) => t.multiplicity(),
            Checked::Invalid => return Err(format!("accessor {index} has an invalid type").into()),
        };
        let count = usize::try_from(accessor.count.0)
            .map_err(|_| format!("accessor {index} count {} is too large", accessor.count.0))?;
        let element = ty.size() * components;
        let offset = accessor.byte_offset.map_or(0, |o| o.0) as usize;
        let Some(view_index) = accessor.buffer_view else {
            if count > max_count {
                return Err(format!(
                    "accessor {index} without a buffer view has {count} elements, more than the {max_count} expected"
                )
                .into());
            }
            return Ok(AccessorData {
                bytes: Cow::Owned(vec![0; count * element]),
                offset: 0,
                stride: element,
                count,
                ty,
                components,
                normalized: accessor.normalized,
            });
        };
        let (bytes, stride) = self.view(view_index.value())?;
        let data = AccessorData {
            bytes,
            offset,
            stride: stride.unwrap_or(element),
            count,
            ty,
            components,
            normalized: accessor.normalized,
        };
        data.view().map_err(|e| format!("accessor {index}: {e}"))?;
        Ok(data)
    }

    /// The accessor of a named attribute of a primitive.
    pub fn attribute_accessor(raw_primitive: &Value, name: &str) -> Option<usize> {
        raw_primitive
            .get("attributes")?
            .get(name)?
            .as_u64()
            .map(|v| v as usize)
    }

    fn primitive(
        &self,
        primitive: &gj::mesh::Primitive,
        raw_primitive: &Value,
        global: &Transform,
        at: &str,
        uri: &str,
    ) -> Result<TilePoints, PrimitiveError> {
        let position_index = Self::attribute_accessor(raw_primitive, "POSITION")
            .ok_or_else(|| "has no POSITION".to_string())?;
        if self
            .root
            .accessors
            .get(position_index)
            .is_some_and(|a| a.buffer_view.is_none())
        {
            return Err("POSITION accessor has no buffer view".to_string().into());
        }
        let positions = self.accessor(position_index, 0)?;
        if positions.components != 3 {
            return Err(format!("POSITION has {} components, not 3", positions.components).into());
        }
        let vertex_count = positions.count;
        let position_values = positions.f64s()?;
        drop(positions);

        let order: Option<Vec<usize>> = match primitive.indices {
            None => None,
            Some(i) => {
                let data = self.accessor(i.value(), 0)?;
                if data.components != 1
                    || !matches!(
                        data.ty,
                        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                    )
                {
                    return Err("indices are not unsigned integer scalars"
                        .to_string()
                        .into());
                }
                let view = data.view()?;
                let mut order = Vec::with_capacity(view.len());
                for k in 0..view.len() {
                    let v = data.ty.read_f64(view.element(k)) as usize;
                    if v >= vertex_count {
                        return Err(
                            format!("index {v} is beyond the {vertex_count} vertices").into()
                        );
                    }
                    order.push(v);
                }
                Some(order)
            }
        };
        let gather = |v: usize| -> usize { order.as_ref().map_or(v, |o| o[v]) };
        let point_count = order.as_ref().map_or(vertex_count, Vec::len);

        let mut out = TilePoints {
            uri: uri.to_string(),
            ..TilePoints::default()
        };
        out.positions = (0..point_count)
            .map(|k| {
                let v = gather(k) * 3;
                global.apply_point([
                    position_values[v],
                    position_values[v + 1],
                    position_values[v + 2],
                ])
            })
            .collect();

        // COLOR_0: linear, to sRGB.
        out.colors = match Self::attribute_accessor(raw_primitive, "COLOR_0") {
            None => vec![[255; 4]; point_count],
            Some(i) => {
                let mut data = self.accessor(i, vertex_count)?;
                self.check_count(&data, vertex_count, "COLOR_0")?;
                if !(data.components == 3 || data.components == 4) {
                    return Err(format!("COLOR_0 has {} components", data.components).into());
                }
                // Integer colours are normalized by definition (some writers omit the flag).
                data.normalized = true;
                let values = data.f64s()?;
                let c = data.components;
                (0..point_count)
                    .map(|k| {
                        let v = &values[gather(k) * c..gather(k) * c + c];
                        let alpha = if c == 4 { unit_to_u8(v[3]) } else { 255 };
                        [
                            linear_to_srgb8(v[0]),
                            linear_to_srgb8(v[1]),
                            linear_to_srgb8(v[2]),
                            alpha,
                        ]
                    })
                    .collect()
            }
        };

        if let Some(i) = Self::attribute_accessor(raw_primitive, "NORMAL") {
            let data = self.accessor(i, vertex_count)?;
            self.check_count(&data, vertex_count, "NORMAL")?;
            if data.components != 3 {
                return Err(format!("NORMAL has {} components", data.components).into());
            }
            let values = data.f64s()?;
            let n = global.normal_matrix();
            out.normals = Some(
                (0..point_count)
                    .map(|k| {
                        let v = gather(k) * 3;
                        transform_normal(&n, [values[v], values[v + 1], values[v + 2]])
                    })
                    .collect(),
            );
        }

        let (attributes, notes) = crate::metadata::read(self, raw_primitive, vertex_count)?;
        for attribute in attributes {
            out.attributes
                .push(gather_attribute(attribute, point_count, &gather));
        }
        out.notes
            .extend(notes.into_iter().map(|n| format!("{at}: {n}")));
        Ok(out)
    }

    pub fn check_count(
        &self,
        data: &AccessorData,
        vertex_count: usize,
        name: &str,
    ) -> Result<(), String> {
        if data.count != vertex_count {
            return Err(format!(
                "{name} has {} elements for {vertex_count} vertices",
                data.count
            ));
        }
        Ok(())
    }
}

/// A per-vertex attribute as a per-point one (through the index list, if any).
fn gather_attribute(
    attribute: PointAttribute,
    point_count: usize,
    gather: &dyn Fn(usize) -> usize,
) -> PointAttribute {
    let c = attribute.components;
    let values = match attribute.values {
        AttributeValues::Int(v) => AttributeValues::Int(
            (0..point_count)
                .flat_map(|k| v[gather(k) * c..gather(k) * c + c].to_vec())
                .collect(),
        ),
        AttributeValues::Float(v) => AttributeValues::Float(
            (0..point_count)
                .flat_map(|k| v[gather(k) * c..gather(k) * c + c].to_vec())
                .collect(),
        ),
    };
    PointAttribute {
        name: attribute.name,
        components: c,
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_decode() {
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAECAw==").unwrap(),
            vec![0, 1, 2, 3]
        );
        assert_eq!(decode_data_uri("data:,hi%21").unwrap(), b"hi!".to_vec());
        assert!(decode_data_uri("data:;base64,A*").is_none());
    }
}
