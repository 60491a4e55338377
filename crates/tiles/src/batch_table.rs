//! The batch table of a `pnts` tile (3D Tiles 1.0 §"Batch Table"): per-feature properties,
//! where a feature is a point (no `BATCH_ID`) or a batch of points (with `BATCH_ID`, and then
//! the batch's value is given to each of its points).
//!
//! A property is either a JSON array with one entry per feature (numbers, booleans as 0/1, or
//! arrays of numbers of one length), or a reference into the binary part: `byteOffset`,
//! `componentType` (`BYTE` … `DOUBLE`) and `type` (`SCALAR`, `VEC2`, `VEC3`, `VEC4`). Integer
//! types come out as integers, floats as f64. Properties that are not numeric (strings,
//! objects, nulls) are skipped with a note; `extensions` and `extras` are not properties.

use crate::bytes::{read_f64s, read_i64s, ComponentType, Strided};
use crate::content::{AttributeValues, PointAttribute};
use serde_json::{Map, Value};

/// The numeric properties as per-point attributes, and notes about what was skipped.
pub fn read(
    json: &Map<String, Value>,
    binary: &[u8],
    features: usize,
    batch_ids: Option<&[u64]>,
    points: usize,
) -> Result<(Vec<PointAttribute>, Vec<String>), String> {
    let mut attributes = Vec::new();
    let mut notes = Vec::new();
    for (name, value) in json {
        if name == "extensions" || name == "extras" {
            continue;
        }
        let per_feature = match value {
            Value::Array(items) => {
                if items.len() != features {
                    return Err(format!(
                        "property '{name}' has {} values for {features} features",
                        items.len()
                    ));
                }
                match json_values(items) {
                    Some(v) => v,
                    None => {
                        notes.push(format!(
                            "batch table property '{name}' is not numeric: skipped"
                        ));
                        continue;
                    }
                }
            }
            Value::Object(_) if value.get("byteOffset").is_some() => {
                binary_values(name, value, binary, features)?
            }
            _ => {
                notes.push(format!(
                    "batch table property '{name}' is neither an array nor a binary reference: skipped"
                ));
                continue;
            }
        };
        let (components, values) = per_feature;
        let values = match batch_ids {
            None => values,
            Some(ids) => expand(&values, components, ids),
        };
        debug_assert_eq!(values.len(), points * components);
        attributes.push(PointAttribute {
            name: name.clone(),
            components,
            values,
        });
    }
    Ok((attributes, notes))
}

/// Per-batch values given to each point by its batch id (ids were checked to be in range).
fn expand(values: &AttributeValues, components: usize, ids: &[u64]) -> AttributeValues {
    fn pick<T: Copy>(v: &[T], components: usize, ids: &[u64]) -> Vec<T> {
        let mut out = Vec::with_capacity(ids.len() * components);
        for id in ids {
            let start = *id as usize * components;
            out.extend_from_slice(&v[start..start + components]);
        }
        out
    }
    match values {
        AttributeValues::Int(v) => AttributeValues::Int(pick(v, components, ids)),
        AttributeValues::Float(v) => AttributeValues::Float(pick(v, components, ids)),
    }
}

/// Numbers, booleans or equal-length arrays of numbers; `None` for anything else.
fn json_values(items: &[Value]) -> Option<(usize, AttributeValues)> {
    let components = match items.first() {
        Some(Value::Array(first)) => first.len(),
        _ => 1,
    };
    if components == 0 || components > 16 {
        return None;
    }
    let arrays = matches!(items.first(), Some(Value::Array(_)));
    let mut flat: Vec<&Value> = Vec::with_capacity(items.len() * components);
    for item in items {
        match (arrays, item) {
            (true, Value::Array(inner)) if inner.len() == components => flat.extend(inner.iter()),
            (false, scalar) if !scalar.is_array() => flat.push(scalar),
            _ => return None,
        }
    }
    if flat.iter().all(|v| v.as_i64().is_some() || v.is_boolean()) {
        return Some((
            components,
            AttributeValues::Int(
                flat.iter()
                    .map(|v| {
                        v.as_i64()
                            .unwrap_or_else(|| i64::from(v.as_bool() == Some(true)))
                    })
                    .collect(),
            ),
        ));
    }
    if flat.iter().all(|v| v.is_number()) {
        return Some((
            components,
            AttributeValues::Float(flat.iter().filter_map(|v| v.as_f64()).collect()),
        ));
    }
    None
}

fn binary_values(
    name: &str,
    value: &Value,
    binary: &[u8],
    features: usize,
) -> Result<(usize, AttributeValues), String> {
    let offset = value
        .get("byteOffset")
        .and_then(Value::as_u64)
        .and_then(|o| usize::try_from(o).ok())
        .ok_or_else(|| format!("property '{name}': byteOffset is not a non-negative integer"))?;
    let ty_name = value
        .get("componentType")
        .and_then(Value::as_str)
        .unwrap_or("");
    let ty = ComponentType::from_tiles_name(ty_name)
        .ok_or_else(|| format!("property '{name}': unknown componentType '{ty_name}'"))?;
    let shape = value.get("type").and_then(Value::as_str).unwrap_or("");
    let components = match shape {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        _ => return Err(format!("property '{name}': unknown type '{shape}'")),
    };
    let size = ty.size() * components;
    let view = Strided::new(binary, offset, size, features, size)
        .map_err(|e| format!("property '{name}' in the batch table binary: {e}"))?;
    let values = if ty.is_float() {
        AttributeValues::Float(read_f64s(&view, ty, components, false))
    } else {
        // Batch table integers are at most 32 bits: they always fit i64.
        AttributeValues::Int(read_i64s(&view, ty, components).unwrap_or_default())
    };
    Ok((components, values))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn json_and_binary_properties_per_point_and_per_batch() {
        let table = json!({
            "name": ["a", "b"],
            "height": [1.5, 2],
            "class": [3, 4],
            "dir": [[1, 0], [0, 1]],
            "flag": [true, false],
            "weight": {"byteOffset": 0, "componentType": "UNSIGNED_SHORT", "type": "SCALAR"},
            "extras": {"x": 1}
        });
        let binary = [7u8, 0, 9, 0];
        let (attributes, notes) =
            read(table.as_object().unwrap(), &binary, 2, Some(&[1, 1, 0]), 3).unwrap();
        let get = |n: &str| attributes.iter().find(|a| a.name == n).unwrap();
        assert_eq!(
            get("height").values,
            AttributeValues::Float(vec![2.0, 2.0, 1.5])
        );
        assert_eq!(get("class").values, AttributeValues::Int(vec![4, 4, 3]));
        assert_eq!(get("dir").components, 2);
        assert_eq!(
            get("dir").values,
            AttributeValues::Int(vec![0, 1, 0, 1, 1, 0])
        );
        assert_eq!(get("flag").values, AttributeValues::Int(vec![0, 0, 1]));
        assert_eq!(get("weight").values, AttributeValues::Int(vec![9, 9, 7]));
        assert_eq!(notes.len(), 1);
        assert!(notes[0].contains("'name'"));

        let short =
            json!({"weight": {"byteOffset": 2, "componentType": "UNSIGNED_SHORT", "type": "VEC2"}});
        let e = read(short.as_object().unwrap(), &binary, 2, None, 2).unwrap_err();
        assert!(e.contains("'weight'") && e.contains("need"), "{e}");
        let wrong_count = json!({"h": [1, 2, 3]});
        assert!(read(wrong_count.as_object().unwrap(), &[], 2, None, 2).is_err());
    }
}
