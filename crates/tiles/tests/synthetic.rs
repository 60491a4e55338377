//! Format features no independent producer in testdata writes, on small files built here:
//! pnts quantized positions, RTC_CENTER, RGB565 / RGBA / CONSTANT_RGBA, NORMAL_OCT16P,
//! BATCH_ID with a per-batch table; GLB with KHR_mesh_quantization, a node hierarchy,
//! CESIUM_RTC, the y-up → z-up rotation, indices, EXT_meshopt_compression, EXT_mesh_features
//! and EXT_structural_metadata; a region bounding volume.

mod common;
use common::*;
use pointlet_tiles::{AttributeValues, ContentContext, Tileset, Transform, UpAxis};
use serde_json::json;

fn context(uri: &str) -> ContentContext<'_> {
    ContentContext {
        uri,
        world: Transform::IDENTITY,
        up_axis: UpAxis::Y,
        source: None,
    }
}

fn close(a: [f64; 3], b: [f64; 3], tolerance: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tolerance)
}

#[test]
fn pnts_quantized_positions_rtc_colours_normals_and_batches() {
    // Two points: quantized (0,0,0) and (65535, 32768, 65535) in a 10 m volume at (100,200,300),
    // RTC_CENTER (1000, 0, 0); RGB565 white and pure red; oct normals +z and −x; batches 1, 0.
    let mut bin = Vec::new();
    for q in [[0u16, 0, 0], [65535, 32768, 65535]] {
        for v in q {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let colour_offset = bin.len();
    for c in [0xFFFFu16, 0xF800] {
        bin.extend_from_slice(&c.to_le_bytes());
    }
    let normal_offset = bin.len();
    bin.extend_from_slice(&[128, 128, 0, 128]); // +z (center), then −x (x = −1)
    let batch_offset = bin.len();
    bin.extend_from_slice(&[1u8, 0u8]);
    let ft = json!({
        "POINTS_LENGTH": 2,
        "POSITION_QUANTIZED": {"byteOffset": 0},
        "QUANTIZED_VOLUME_OFFSET": [100, 200, 300],
        "QUANTIZED_VOLUME_SCALE": [10, 10, 10],
        "RTC_CENTER": [1000, 0, 0],
        "RGB565": {"byteOffset": colour_offset},
        "NORMAL_OCT16P": {"byteOffset": normal_offset},
        "BATCH_ID": {"byteOffset": batch_offset, "componentType": "UNSIGNED_BYTE"},
        "BATCH_LENGTH": 2
    });
    let bt = json!({"class": [5, 6], "height": {"byteOffset": 0, "componentType": "DOUBLE", "type": "SCALAR"}});
    let bt_bin: Vec<u8> = [1.5f64, 2.5].iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = pnts(&ft, &bin, Some(&bt), &bt_bin);
    let mut ctx = context("q.pnts");
    // A tile transform scaling by 2 about the origin and translating by (0, 0, 5).
    ctx.world = Transform([
        2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 5.0, 1.0,
    ]);
    let points = pointlet_tiles::content::decode(&bytes, &ctx).unwrap();
    assert!(
        close(points.positions[0], [2200.0, 400.0, 605.0], 1e-9),
        "{:?}",
        points.positions
    );
    let y = 200.0 + 32768.0 * 10.0 / 65535.0;
    assert!(
        close(points.positions[1], [2220.0, 2.0 * y, 625.0], 1e-9),
        "{:?}",
        points.positions
    );
    assert_eq!(points.colors, vec![[255, 255, 255, 255], [255, 0, 0, 255]]);
    let normals = points.normals.clone().unwrap();
    assert!(
        normals[0][2] > 0.999 && normals[1][0] < -0.999,
        "{normals:?}"
    );
    assert_eq!(
        points.attribute("BATCH_ID").unwrap().values,
        AttributeValues::Int(vec![1, 0])
    );
    assert_eq!(
        points.attribute("class").unwrap().values,
        AttributeValues::Int(vec![6, 5])
    );
    assert_eq!(
        points.attribute("height").unwrap().values,
        AttributeValues::Float(vec![2.5, 1.5])
    );
}

#[test]
fn pnts_rgba_over_rgb_and_constant_colour() {
    let positions = f32_bytes(&[0.0, 0.0, 0.0]);
    let mut bin = positions.clone();
    bin.extend_from_slice(&[1, 2, 3, 4, 9, 9, 9]);
    let ft = json!({"POINTS_LENGTH": 1, "POSITION": {"byteOffset": 0}, "RGBA": {"byteOffset": 12}, "RGB": {"byteOffset": 16}});
    let points =
        pointlet_tiles::content::decode(&pnts(&ft, &bin, None, &[]), &context("c.pnts")).unwrap();
    assert_eq!(points.colors, vec![[1, 2, 3, 4]]);
    let ft = json!({"POINTS_LENGTH": 1, "POSITION": {"byteOffset": 0}, "CONSTANT_RGBA": [10, 20, 30, 40]});
    let points =
        pointlet_tiles::content::decode(&pnts(&ft, &positions, None, &[]), &context("c.pnts"))
            .unwrap();
    assert_eq!(points.colors, vec![[10, 20, 30, 40]]);
    let ft = json!({"POINTS_LENGTH": 1, "POSITION": {"byteOffset": 0}});
    let points =
        pointlet_tiles::content::decode(&pnts(&ft, &positions, None, &[]), &context("c.pnts"))
            .unwrap();
    assert_eq!(points.colors, vec![[255; 4]]);
    assert!(points.normals.is_none());
}

/// A GLB with quantized int16 positions under a node hierarchy, CESIUM_RTC, linear float
/// colours, indices, a `_FEATURE_ID_0` attribute with a property table and a property attribute.
fn metadata_glb() -> Vec<u8> {
    let mut bin = Vec::new();
    // Positions: int16 normalized: (32767, 0, 0) and (0, 32767, -32767).
    for p in [[32767i16, 0, 0, 0], [0, 32767, -32767, 0]] {
        for v in p {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let colours = bin.len();
    bin.extend(f32_bytes(&[1.0, 0.0, 0.0, 0.21586, 0.21586, 0.21586]));
    let ids = bin.len();
    bin.extend_from_slice(&[1u8, 0, 0, 0]); // feature ids 1, 0 (uint8, padded)
    let intensity = bin.len();
    bin.extend_from_slice(&[10u8, 0, 20, 0]); // uint16 10, 20
    let table = bin.len();
    bin.extend(f32_bytes(&[7.5, 8.5]));
    let indices = bin.len();
    bin.extend_from_slice(&[1u8, 0, 1, 0]);
    let json = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization", "CESIUM_RTC", "EXT_mesh_features", "EXT_structural_metadata"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "extensions": {
            "CESIUM_RTC": {"center": [6378137.0, 0.0, 0.0]},
            "EXT_structural_metadata": {
                "schema": {"id": "s", "classes": {
                    "point": {"properties": {"intensity": {"type": "SCALAR", "componentType": "UINT16"}}},
                    "feature": {"properties": {"weight": {"type": "SCALAR", "componentType": "FLOAT32", "scale": 2.0}}}}},
                "propertyTables": [{"class": "feature", "count": 2, "properties": {"weight": {"values": 5}}}],
                "propertyAttributes": [{"class": "point", "properties": {"intensity": {"attribute": "_INTENSITY"}}}]
            }
        },
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 16, "byteStride": 8},
            {"buffer": 0, "byteOffset": colours, "byteLength": 24},
            {"buffer": 0, "byteOffset": ids, "byteLength": 2},
            {"buffer": 0, "byteOffset": intensity, "byteLength": 4},
            {"buffer": 0, "byteOffset": indices, "byteLength": 3},
            {"buffer": 0, "byteOffset": table, "byteLength": 8}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5122, "normalized": true, "count": 2, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5121, "count": 2, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5123, "count": 2, "type": "SCALAR"},
            {"bufferView": 4, "componentType": 5121, "count": 3, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "COLOR_0": 1, "_FEATURE_ID_0": 2, "_INTENSITY": 3}, "indices": 4, "mode": 0,
             "extensions": {
                "EXT_mesh_features": {"featureIds": [{"featureCount": 2, "attribute": 0, "propertyTable": 0, "label": "fid"}]},
                "EXT_structural_metadata": {"propertyAttributes": [0]}}},
            {"attributes": {"POSITION": 0}, "mode": 4}
        ]}],
        // Parent: translation (0, 0, 10) in glTF (y-up) space; child: dequantization scale 100.
        "nodes": [{"translation": [0, 0, 10], "children": [1]}, {"scale": [100, 100, 100], "mesh": 0}],
        "scene": 0,
        "scenes": [{"nodes": [0]}]
    });
    glb(&json, &bin)
}

#[test]
fn glb_quantization_nodes_rtc_y_up_indices_and_metadata() {
    let points = pointlet_tiles::content::decode(&metadata_glb(), &context("m.glb")).unwrap();
    // glTF (x, y, z) → z-up (x, −z, y), then + RTC center.
    // Vertex 1: node (0, 100, −100) + (0, 0, 10) = (0, 100, −90) → (0, 90, 100).
    // Vertex 0: (100, 0, 0) + (0, 0, 10) = (100, 0, 10) → (100, −10, 0).
    let a = 6378137.0;
    assert_eq!(points.len(), 3);
    assert!(
        close(points.positions[0], [a, 90.0, 100.0], 1e-9),
        "{:?}",
        points.positions
    );
    assert!(
        close(points.positions[1], [a + 100.0, -10.0, 0.0], 1e-9),
        "{:?}",
        points.positions
    );
    assert!(close(points.positions[2], points.positions[0], 0.0));
    // Linear 0.21586 is sRGB 128.
    assert_eq!(points.colors[1], [255, 0, 0, 255]);
    assert_eq!(points.colors[0], [128, 128, 128, 255]);
    assert_eq!(
        points.attribute("fid").unwrap().values,
        AttributeValues::Int(vec![0, 1, 0])
    );
    assert_eq!(
        points.attribute("intensity").unwrap().values,
        AttributeValues::Int(vec![20, 10, 20])
    );
    assert_eq!(attribute_f64(&points, "weight"), vec![15.0, 17.0, 15.0]);
    assert!(
        points
            .notes
            .iter()
            .any(|n| n.contains("Triangles") && n.contains("skipped")),
        "{:?}",
        points.notes
    );
}

#[test]
fn glb_with_meshopt_compressed_positions() {
    let vertices: Vec<[f32; 3]> = (0..50).map(|i| [i as f32, 2.0 * i as f32, 0.5]).collect();
    let encoded = meshopt::encode_vertex_buffer(&vertices).unwrap();
    let mut bin = encoded.clone();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let json = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["EXT_meshopt_compression"],
        "extensionsRequired": ["EXT_meshopt_compression"],
        "buffers": [{"byteLength": bin.len()}, {"byteLength": 600, "extensions": {"EXT_meshopt_compression": {"fallback": true}}}],
        "bufferViews": [{"buffer": 1, "byteLength": 600, "byteStride": 12, "extensions": {"EXT_meshopt_compression": {
            "buffer": 0, "byteOffset": 0, "byteLength": encoded.len(), "byteStride": 12, "count": 50, "mode": "ATTRIBUTES"}}}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 50, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}]
    });
    let mut ctx = context("mo.glb");
    ctx.up_axis = UpAxis::Z;
    let points = pointlet_tiles::content::decode(&glb(&json, &bin), &ctx).unwrap();
    assert_eq!(points.len(), 50);
    assert_eq!(points.positions[49], [49.0, 98.0, 0.5]);
}

#[test]
fn unsupported_gltf_extensions_are_named() {
    let json =
        json!({"asset": {"version": "2.0"}, "extensionsRequired": ["KHR_draco_mesh_compression"]});
    let e = pointlet_tiles::content::decode(&glb(&json, &[]), &context("d.glb")).unwrap_err();
    assert!(matches!(e, pointlet_tiles::TilesError::Unsupported { .. }));
    assert!(
        e.to_string().contains("KHR_draco_mesh_compression") && e.to_string().contains("d.glb"),
        "{e}"
    );
}

#[test]
fn region_volumes_and_gltf_up_axis_in_a_tileset() {
    let dir = tempfile::tempdir().unwrap();
    let tileset = json!({
        "asset": {"version": "1.0", "gltfUpAxis": "Z"},
        "geometricError": 100,
        "root": {
            "boundingVolume": {"region": [-0.001, 0.7, 0.001, 0.701, -10, 50]},
            "geometricError": 10,
            "refine": "add",
            "children": [{"boundingVolume": {"sphere": [0, 0, 0, 5]}, "geometricError": 0, "content": {"url": "x.glb"}}]
        }
    });
    std::fs::write(
        dir.path().join("tileset.json"),
        serde_json::to_vec(&tileset).unwrap(),
    )
    .unwrap();
    let (tileset, _) = Tileset::open(&dir.path().join("tileset.json")).unwrap();
    let root = tileset.root();
    assert_eq!(root.refine, pointlet_tiles::Refine::Add);
    let aabb = root.volume.aabb();
    let corner = pointlet_tiles::volume::geodetic_to_ecef(0.001, 0.701, 50.0);
    assert!((0..3).all(|i| corner[i] >= aabb.min[i] - 1e-6 && corner[i] <= aabb.max[i] + 1e-6));
    // 0.002 rad of longitude at latitude 0.7 (parallel radius ≈ 4.885e6 m): ≈ 9 770 m.
    assert!(
        aabb.extent()[1] > 9_700.0 && aabb.extent()[1] < 9_850.0,
        "{aabb:?}"
    );
    assert_eq!(tileset.files[0].up_axis, UpAxis::Z);
    assert_eq!(tileset.tiles[1].refine, pointlet_tiles::Refine::Add);
    assert_eq!(tileset.tiles[1].contents[0].uri, "x.glb");
}
