//! Tile content decoded into plain data: [`TilePoints`], and the choice of decoder by the
//! content's first bytes (3D Tiles 1.1 §"Tile format specifications": `pnts`, `glTF` (GLB),
//! a JSON glTF; `b3dm`, `i3dm` and `cmpt` are meshes, instances and composites, which this
//! crate does not read). Positions come out in world space, in f64, every transform applied.

use crate::transform::Transform;
use crate::{TileSource, TilesError};

/// The points of one tile content, in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TilePoints {
    /// The content's resolved URI.
    pub uri: String,
    /// World positions (the tile transform chain, RTC centers, quantization, glTF nodes and
    /// the glTF y-up → z-up rotation applied, all in f64).
    pub positions: Vec<[f64; 3]>,
    /// sRGB colours with alpha, one per point (white when the content has none). glTF's
    /// linear `COLOR_0` is converted to sRGB.
    pub colors: Vec<[u8; 4]>,
    /// Unit normals in world space, when the content has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Named per-point values: pnts batch table properties and `BATCH_ID`, glTF feature IDs
    /// and structural-metadata properties.
    pub attributes: Vec<PointAttribute>,
    /// What was skipped or assumed while decoding (one line each).
    pub notes: Vec<String>,
}

impl TilePoints {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The attribute with this name.
    pub fn attribute(&self, name: &str) -> Option<&PointAttribute> {
        self.attributes.iter().find(|a| a.name == name)
    }
}

/// One named per-point property: `components` values per point, point after point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointAttribute {
    pub name: String,
    pub components: usize,
    pub values: AttributeValues,
}

#[derive(Clone, Debug, PartialEq)]
pub enum AttributeValues {
    Int(Vec<i64>),
    Float(Vec<f64>),
}

impl AttributeValues {
    pub fn len(&self) -> usize {
        match self {
            AttributeValues::Int(v) => v.len(),
            AttributeValues::Float(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` as f64.
    pub fn get_f64(&self, i: usize) -> Option<f64> {
        match self {
            AttributeValues::Int(v) => v.get(i).map(|x| *x as f64),
            AttributeValues::Float(v) => v.get(i).copied(),
        }
    }
}

/// What a content decoder needs besides the bytes.
pub struct ContentContext<'a> {
    /// The content's resolved URI (named in errors; glTF buffers resolve against it).
    pub uri: &'a str,
    /// The tile's world transform.
    pub world: Transform,
    /// The up axis of glTF content (`asset.gltfUpAxis` of the tileset; Y by default).
    pub up_axis: UpAxis,
    /// Reads external glTF buffers; `None` refuses them.
    pub source: Option<&'a dyn TileSource>,
}

/// The up axis of glTF content (3D Tiles 1.0 `asset.gltfUpAxis`, Y unless stated).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    X,
    #[default]
    Y,
    Z,
}

impl UpAxis {
    /// The rotation from this up axis to the z-up frame of 3D Tiles.
    pub fn to_z_up(self) -> Transform {
        match self {
            UpAxis::X => Transform::X_UP_TO_Z_UP,
            UpAxis::Y => Transform::Y_UP_TO_Z_UP,
            UpAxis::Z => Transform::IDENTITY,
        }
    }
}

/// Decodes one tile content, picking the format by its first bytes.
pub fn decode(bytes: &[u8], context: &ContentContext) -> Result<TilePoints, TilesError> {
    let uri = context.uri;
    let magic = bytes.get(..4).unwrap_or(bytes);
    match magic {
        b"pnts" => crate::pnts::decode(bytes, context),
        b"glTF" => crate::gltf::decode_glb(bytes, context),
        b"b3dm" | b"i3dm" => Err(TilesError::unsupported(
            uri,
            format!(
                "{} content (meshes or instances) is not a point cloud",
                String::from_utf8_lossy(magic)
            ),
        )),
        b"cmpt" => Err(TilesError::unsupported(uri, "composite (cmpt) content")),
        _ if bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') => {
            crate::gltf::decode_gltf_json(bytes, context)
        }
        _ if bytes.len() < 4 => Err(TilesError::content(
            uri,
            format!(
                "truncated: {} bytes, too short for any tile format",
                bytes.len()
            ),
        )),
        _ => Err(TilesError::content(
            uri,
            format!(
                "unknown content format (magic {:?}); expected pnts, glTF or JSON glTF",
                String::from_utf8_lossy(magic)
            ),
        )),
    }
}

/// The points of several parts (glTF primitives) as one: positions and colours concatenated;
/// normals kept when every part has them; an attribute kept when every part has it with the
/// same shape (the others are dropped with a note).
pub(crate) fn merge_parts(uri: &str, parts: Vec<TilePoints>) -> TilePoints {
    let mut parts = parts.into_iter();
    let Some(mut out) = parts.next() else {
        return TilePoints {
            uri: uri.to_string(),
            ..TilePoints::default()
        };
    };
    for part in parts {
        out.normals = match (out.normals.take(), part.normals) {
            (Some(mut a), Some(b)) => {
                a.extend(b);
                Some(a)
            }
            _ => None,
        };
        out.positions.extend(part.positions);
        out.colors.extend(part.colors);
        out.notes.extend(part.notes);
        let mut kept = Vec::with_capacity(out.attributes.len());
        for mut attribute in std::mem::take(&mut out.attributes) {
            let other = part.attributes.iter().find(|b| {
                b.name == attribute.name
                    && b.components == attribute.components
                    && std::mem::discriminant(&b.values)
                        == std::mem::discriminant(&attribute.values)
            });
            match (other, &mut attribute.values) {
                (
                    Some(PointAttribute {
                        values: AttributeValues::Int(b),
                        ..
                    }),
                    AttributeValues::Int(a),
                ) => a.extend_from_slice(b),
                (
                    Some(PointAttribute {
                        values: AttributeValues::Float(b),
                        ..
                    }),
                    AttributeValues::Float(a),
                ) => a.extend_from_slice(b),
                _ => {
                    out.notes.push(format!(
                        "attribute '{}' is not in every primitive: dropped",
                        attribute.name
                    ));
                    continue;
                }
            }
            kept.push(attribute);
        }
        for b in &part.attributes {
            if !kept.iter().any(|a| a.name == b.name) {
                out.notes.push(format!(
                    "attribute '{}' is not in every primitive: dropped",
                    b.name
                ));
            }
        }
        out.attributes = kept;
    }
    out
}

/// sRGB 8-bit value of a linear intensity in [0, 1] (IEC 61966-2-1).
pub fn linear_to_srgb8(linear: f64) -> u8 {
    let l = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let s = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
}

/// Linear intensity of an sRGB 8-bit value.
pub fn srgb8_to_linear(srgb: u8) -> f64 {
    let s = srgb as f64 / 255.0;
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// A unit value in [0, 1] as 8 bits.
pub(crate) fn unit_to_u8(v: f64) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * 255.0).round() as u8
}

/// A direction mapped by a normal matrix (columns) and made unit length (zero stays zero).
pub(crate) fn transform_normal(n: &[[f64; 3]; 3], v: [f64; 3]) -> [f32; 3] {
    let w = [0, 1, 2].map(|r| n[0][r] * v[0] + n[1][r] * v[1] + n[2][r] * v[2]);
    let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    if len > 0.0 && len.is_finite() {
        w.map(|x| (x / len) as f32)
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(v)), v);
        }
    }

    #[test]
    fn unknown_and_short_content_are_named_errors() {
        let context = ContentContext {
            uri: "t/x.bin",
            world: Transform::IDENTITY,
            up_axis: UpAxis::Y,
            source: None,
        };
        let e = decode(b"ab", &context).unwrap_err().to_string();
        assert!(e.contains("t/x.bin") && e.contains("truncated"), "{e}");
        let e = decode(b"abcdefgh", &context).unwrap_err().to_string();
        assert!(e.contains("unknown content format"), "{e}");
        let e = decode(b"b3dm....", &context).unwrap_err();
        assert!(matches!(e, TilesError::Unsupported { .. }));
    }
}
