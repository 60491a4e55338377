//! Per-point metadata of glTF point primitives: EXT_mesh_features (feature IDs) and
//! EXT_structural_metadata (property attributes, and property tables reached through a feature
//! ID), as 3D Tiles 1.1 uses them in place of the pnts batch table.
//!
//! - Feature IDs: from a vertex attribute `_FEATURE_ID_n`, or implicit (the vertex index); an
//!   integer attribute named by the feature ID's `label` or `feature_id_<i>`. Feature IDs in
//!   textures are skipped with a note.
//! - Property attributes: each property names a vertex attribute; its class property gives the
//!   type, `normalized`, `offset` and `scale` (the property attribute's own `offset`/`scale`
//!   win). Integers stay integers unless normalized, offset or scaled; then, and for floats,
//!   values are f64.
//! - Property tables: numeric properties (SCALAR, VECn, MATn, ENUM, fixed-length arrays of
//!   them) read from their `values` buffer view, then given to each point through its feature
//!   ID as f64 (NaN where the ID is the null feature ID or beyond the table).
//!
//! Strings, booleans and variable-length arrays are skipped with a note, as are schemas given
//! by `schemaUri`.

use crate::bytes::{read_f64s, read_i64s, ComponentType, Strided};
use crate::content::{AttributeValues, PointAttribute};
use crate::gltf::{Document, PrimitiveError};
use serde_json::{Map, Value};

type Attributes = (Vec<PointAttribute>, Vec<String>);

/// The metadata of one primitive as per-vertex attributes, with notes on what was skipped.
pub(crate) fn read(
    doc: &Document,
    raw_primitive: &Value,
    vertex_count: usize,
) -> Result<Attributes, PrimitiveError> {
    let mut attributes: Vec<PointAttribute> = Vec::new();
    let mut notes = Vec::new();
    let root_metadata = doc.raw.pointer("/extensions/EXT_structural_metadata");
    let schema = match root_metadata {
        Some(m) if m.get("schema").is_some() => m.get("schema"),
        Some(m) if m.get("schemaUri").is_some() => {
            notes.push(
                "EXT_structural_metadata schemaUri (external schema) is not read: metadata skipped"
                    .into(),
            );
            None
        }
        _ => None,
    };

    if let Some(ids) = raw_primitive.pointer("/extensions/EXT_mesh_features/featureIds") {
        let ids = ids
            .as_array()
            .ok_or("EXT_mesh_features featureIds is not an array")?;
        for (i, feature) in ids.iter().enumerate() {
            let name = feature
                .get("label")
                .and_then(Value::as_str)
                .map_or_else(|| format!("feature_id_{i}"), str::to_string);
            let values: Vec<i64> = if let Some(n) = feature.get("attribute") {
                let n = n.as_u64().ok_or("feature ID attribute is not an integer")?;
                let semantic = format!("_FEATURE_ID_{n}");
                let index =
                    Document::attribute_accessor(raw_primitive, &semantic).ok_or_else(|| {
                        format!("feature ID {i} names {semantic}, which the primitive lacks")
                    })?;
                let data = doc.accessor(index, vertex_count)?;
                doc.check_count(&data, vertex_count, &semantic)?;
                let mut plain = data;
                plain.normalized = false;
                plain
                    .f64s()?
                    .into_iter()
                    .map(|v| v.round() as i64)
                    .collect()
            } else if feature.get("texture").is_some() {
                notes.push(format!(
                    "feature ID {i} ({name}) is stored in a texture: skipped"
                ));
                continue;
            } else {
                (0..vertex_count as i64).collect()
            };
            if let (Some(table), Some(schema)) =
                (feature.get("propertyTable").and_then(Value::as_u64), schema)
            {
                let null_id = feature.get("nullFeatureId").and_then(Value::as_i64);
                let (mut table_attributes, mut table_notes) =
                    property_table(doc, schema, root_metadata, table as usize, &values, null_id)?;
                for a in table_attributes.drain(..) {
                    push_unique(&mut attributes, a);
                }
                notes.append(&mut table_notes);
            }
            push_unique(
                &mut attributes,
                PointAttribute {
                    name,
                    components: 1,
                    values: AttributeValues::Int(values),
                },
            );
        }
    }

    if let (Some(list), Some(schema), Some(root_metadata)) = (
        raw_primitive.pointer("/extensions/EXT_structural_metadata/propertyAttributes"),
        schema,
        root_metadata,
    ) {
        let list = list
            .as_array()
            .ok_or("propertyAttributes is not an array")?;
        for index in list {
            let index = index
                .as_u64()
                .ok_or("propertyAttributes holds a non-integer")? as usize;
            let property_attribute = root_metadata
                .get("propertyAttributes")
                .and_then(|p| p.get(index))
                .ok_or_else(|| format!("property attribute {index} does not exist"))?;
            let class_name = property_attribute
                .get("class")
                .and_then(Value::as_str)
                .unwrap_or("");
            let class = class_properties(schema, class_name).ok_or_else(|| {
                format!("property attribute {index}: class '{class_name}' is not in the schema")
            })?;
            let Some(properties) = property_attribute
                .get("properties")
                .and_then(Value::as_object)
            else {
                continue;
            };
            for (name, property) in properties {
                let class_property = class.get(name).unwrap_or(&Value::Null);
                let kind = class_property
                    .get("type")
                    .and_then(Value::as_str)
                    .unwrap_or("SCALAR");
                if matches!(kind, "STRING" | "BOOLEAN") {
                    notes.push(format!("property '{name}' of type {kind}: skipped"));
                    continue;
                }
                let semantic = property
                    .get("attribute")
                    .and_then(Value::as_str)
                    .unwrap_or("");
                let accessor = Document::attribute_accessor(raw_primitive, semantic).ok_or_else(|| {
                    format!("property '{name}' names attribute '{semantic}', which the primitive lacks")
                })?;
                let mut data = doc.accessor(accessor, vertex_count)?;
                doc.check_count(&data, vertex_count, semantic)?;
                let scaling = Scaling::of(class_property, property, data.components);
                data.normalized = scaling.normalized;
                let values = if data.ty.is_float() || scaling.changes_values() {
                    AttributeValues::Float(scaling.apply(data.f64s()?, data.components))
                } else {
                    match read_i64s(&data.view()?, data.ty, data.components) {
                        Some(v) => AttributeValues::Int(v),
                        None => AttributeValues::Float(data.f64s()?),
                    }
                };
                push_unique(
                    &mut attributes,
                    PointAttribute {
                        name: name.clone(),
                        components: data.components,
                        values,
                    },
                );
            }
        }
    }
    Ok((attributes, notes))
}

fn class_properties<'v>(schema: &'v Value, class: &str) -> Option<&'v Map<String, Value>> {
    schema
        .get("classes")?
        .get(class)?
        .get("properties")?
        .as_object()
}

/// Adds an attribute, renaming it `name_2`, `name_3`, … when the name is taken.
fn push_unique(attributes: &mut Vec<PointAttribute>, mut attribute: PointAttribute) {
    let base = attribute.name.clone();
    let mut k = 2;
    while attributes.iter().any(|a| a.name == attribute.name) {
        attribute.name = format!("{base}_{k}");
        k += 1;
    }
    attributes.push(attribute);
}

/// `normalized`, `offset` and `scale` of a property (the instance's own offset/scale win).
struct Scaling {
    normalized: bool,
    offset: Option<Vec<f64>>,
    scale: Option<Vec<f64>>,
}

impl Scaling {
    fn of(class_property: &Value, property: &Value, components: usize) -> Scaling {
        let per_component = |v: &Value| -> Option<Vec<f64>> {
            match v {
                Value::Number(n) => Some(vec![n.as_f64()?; components]),
                Value::Array(items) if items.len() == components => {
                    items.iter().map(Value::as_f64).collect()
                }
                _ => None,
            }
        };
        let pick = |key: &str| {
            property
                .get(key)
                .or_else(|| class_property.get(key))
                .and_then(per_component)
        };
        Scaling {
            normalized: class_property
                .get("normalized")
                .and_then(Value::as_bool)
                .unwrap_or(false),
            offset: pick("offset"),
            scale: pick("scale"),
        }
    }

    fn changes_values(&self) -> bool {
        self.normalized || self.offset.is_some() || self.scale.is_some()
    }

    fn apply(&self, mut values: Vec<f64>, components: usize) -> Vec<f64> {
        for (i, v) in values.iter_mut().enumerate() {
            let c = i % components.max(1);
            if let Some(s) = &self.scale {
                *v *= s[c];
            }
            if let Some(o) = &self.offset {
                *v += o[c];
            }
        }
        values
    }
}

/// The numeric properties of a property table given to each vertex through its feature ID.
fn property_table(
    doc: &Document,
    schema: &Value,
    root_metadata: Option<&Value>,
    table_index: usize,
    feature_ids: &[i64],
    null_id: Option<i64>,
) -> Result<Attributes, PrimitiveError> {
    let mut attributes = Vec::new();
    let mut notes = Vec::new();
    let table = root_metadata
        .and_then(|m| m.get("propertyTables"))
        .and_then(|t| t.get(table_index))
        .ok_or_else(|| format!("property table {table_index} does not exist"))?;
    let class_name = table.get("class").and_then(Value::as_str).unwrap_or("");
    let class = class_properties(schema, class_name).ok_or_else(|| {
        format!("property table {table_index}: class '{class_name}' is not in the schema")
    })?;
    let rows = table
        .get("count")
        .and_then(Value::as_u64)
        .ok_or_else(|| format!("property table {table_index} has no count"))?
        as usize;
    let Some(properties) = table.get("properties").and_then(Value::as_object) else {
        return Ok((attributes, notes));
    };
    for (name, property) in properties {
        let class_property = class.get(name).unwrap_or(&Value::Null);
        let kind = class_property
            .get("type")
            .and_then(Value::as_str)
            .unwrap_or("");
        let is_array = class_property
            .get("array")
            .and_then(Value::as_bool)
            .unwrap_or(false);
        let fixed_count = class_property.get("count").and_then(Value::as_u64);
        let per_element = match kind {
            "SCALAR" | "ENUM" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT2" => 4,
            "MAT3" => 9,
            "MAT4" => 16,
            _ => {
                notes.push(format!(
                    "property table property '{name}' of type {kind}: skipped"
                ));
                continue;
            }
        };
        if is_array && fixed_count.is_none() {
            notes.push(format!(
                "property table property '{name}' is a variable-length array: skipped"
            ));
            continue;
        }
        let components = per_element * fixed_count.filter(|_| is_array).unwrap_or(1) as usize;
        if components == 0 || components > 64 {
            notes.push(format!(
                "property table property '{name}' has {components} components: skipped"
            ));
            continue;
        }
        let ty_name = if kind == "ENUM" {
            let enum_type = class_property
                .get("enumType")
                .and_then(Value::as_str)
                .unwrap_or("");
            schema
                .get("enums")
                .and_then(|e| e.get(enum_type))
                .and_then(|e| e.get("valueType"))
                .and_then(Value::as_str)
                .unwrap_or("UINT16")
        } else {
            class_property
                .get("componentType")
                .and_then(Value::as_str)
                .unwrap_or("")
        };
        let ty = ComponentType::from_metadata_name(ty_name).ok_or_else(|| {
            format!("property table property '{name}': unknown componentType '{ty_name}'")
        })?;
        let view_index = property
            .get("values")
            .and_then(Value::as_u64)
            .ok_or_else(|| format!("property table property '{name}' has no values buffer view"))?;
        let (bytes, _) = doc.view(view_index as usize)?;
        let size = ty.size() * components;
        let view = Strided::new(&bytes, 0, size, rows, size)
            .map_err(|e| format!("property table property '{name}': {e}"))?;
        let scaling = Scaling::of(class_property, property, components);
        let table_values = scaling.apply(
            read_f64s(&view, ty, components, scaling.normalized),
            components,
        );
        let mut values = Vec::with_capacity(feature_ids.len() * components);
        for id in feature_ids {
            let row = usize::try_from(*id)
                .ok()
                .filter(|r| *r < rows && Some(*id) != null_id);
            match row {
                Some(r) => {
                    values.extend_from_slice(&table_values[r * components..(r + 1) * components])
                }
                None => values.extend(std::iter::repeat_n(f64::NAN, components)),
            }
        }
        attributes.push(PointAttribute {
            name: name.clone(),
            components,
            values: AttributeValues::Float(values),
        });
    }
    Ok((attributes, notes))
}
