//! Bad tilesets and bad content give typed errors that name the tile (its path in the tree
//! and/or its content URI), never panics.

mod common;
use common::*;
use pointlet_tiles::{LoadLimits, LocalSource, TilesError, Tileset};
use serde_json::json;
use std::path::Path;

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    let path = dir.join(name);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

fn write_json(dir: &Path, name: &str, value: &serde_json::Value) {
    write(dir, name, &serde_json::to_vec(value).unwrap());
}

/// A copy of the py3dtiles simple tileset in a temporary folder, to damage.
fn simple_copy() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let from = testdata("tiles/simple_pnts");
    for rel in [
        "tileset.json",
        "preview.pnts",
        "points/r.pnts",
        "points/r0.pnts",
        "points/r2.pnts",
        "points/r4.pnts",
        "points/r6.pnts",
        "points/r7.pnts",
    ] {
        write(dir.path(), rel, &std::fs::read(from.join(rel)).unwrap());
    }
    dir
}

/// Reads every content of every tile; the first error.
fn read_all(dir: &Path) -> Result<usize, TilesError> {
    let (tileset, source) = Tileset::open(&dir.join("tileset.json"))?;
    let mut n = 0;
    for t in 0..tileset.tiles.len() {
        for part in tileset.read_tile(&source, t)? {
            n += part.len();
        }
    }
    Ok(n)
}

#[test]
fn a_missing_tile_file_names_the_tile_and_its_uri() {
    let dir = simple_copy();
    std::fs::remove_file(dir.path().join("points/r4.pnts")).unwrap();
    let e = read_all(dir.path()).unwrap_err();
    let message = e.to_string();
    assert!(matches!(e.root_cause(), TilesError::Read { .. }), "{e:?}");
    assert!(
        message.contains("root.children[0].children[2]") && message.contains("points/r4.pnts"),
        "{message}"
    );
}

#[test]
fn truncated_content_is_an_error_naming_the_tile() {
    let dir = simple_copy();
    let bytes = std::fs::read(dir.path().join("points/r0.pnts")).unwrap();
    for cut in [0, 3, 20, 27, 28, 100, bytes.len() - 1] {
        write(dir.path(), "points/r0.pnts", &bytes[..cut]);
        let e = read_all(dir.path()).unwrap_err();
        assert!(
            matches!(e.root_cause(), TilesError::InvalidContent { .. }),
            "{cut}: {e:?}"
        );
        let message = e.to_string();
        assert!(
            message.contains("points/r0.pnts") && message.contains("root.children[0].children[0]"),
            "{message}"
        );
    }
}

#[test]
fn wrong_magic_is_an_error() {
    let dir = simple_copy();
    let mut bytes = std::fs::read(dir.path().join("points/r2.pnts")).unwrap();
    bytes[..4].copy_from_slice(b"pnxs");
    write(dir.path(), "points/r2.pnts", &bytes);
    let message = read_all(dir.path()).unwrap_err().to_string();
    assert!(
        message.contains("points/r2.pnts") && message.contains("magic"),
        "{message}"
    );
    // A GLB with a damaged magic reads as an unknown format, also named.
    let dir = tempfile::tempdir().unwrap();
    let mut glb = std::fs::read(testdata("tiles/simple_glb/points/r0.glb")).unwrap();
    glb[1] = b'X';
    write(dir.path(), "x.glb", &glb);
    write_json(dir.path(), "tileset.json", &one_tile_tileset("x.glb", None));
    let message = read_all(dir.path()).unwrap_err().to_string();
    assert!(
        message.contains("x.glb") && message.contains("unknown content format"),
        "{message}"
    );
}

#[test]
fn byte_lengths_that_lie_are_errors() {
    let dir = simple_copy();
    let original = std::fs::read(dir.path().join("points/r6.pnts")).unwrap();
    // byteLength, then each part's length, claiming more than there is.
    for field in [8usize, 12, 16, 20, 24] {
        let mut bytes = original.clone();
        bytes[field..field + 4].copy_from_slice(&0xFFFF_FF00u32.to_le_bytes());
        write(dir.path(), "points/r6.pnts", &bytes);
        let e = read_all(dir.path()).unwrap_err();
        assert!(
            matches!(e.root_cause(), TilesError::InvalidContent { .. }),
            "field {field}: {e:?}"
        );
        assert!(e.to_string().contains("points/r6.pnts"));
    }
    // POINTS_LENGTH larger than the binary holds.
    let ft = json!({"POINTS_LENGTH": 1000, "POSITION": {"byteOffset": 0}});
    write(
        dir.path(),
        "points/r6.pnts",
        &pnts(&ft, &[0u8; 24], None, &[]),
    );
    let message = read_all(dir.path()).unwrap_err().to_string();
    assert!(
        message.contains("POSITION") && message.contains("need 12000 bytes"),
        "{message}"
    );
    // A GLB whose length field and chunk lengths lie.
    let glb = std::fs::read(testdata("tiles/simple_glb/points/r0.glb")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    write_json(tmp.path(), "tileset.json", &one_tile_tileset("x.glb", None));
    for field in [8usize, 12] {
        let mut bytes = glb.clone();
        bytes[field..field + 4].copy_from_slice(&0x7FFF_FFF0u32.to_le_bytes());
        write(tmp.path(), "x.glb", &bytes);
        let e = read_all(tmp.path()).unwrap_err();
        assert!(
            matches!(e.root_cause(), TilesError::InvalidContent { .. }),
            "field {field}: {e:?}"
        );
    }
    // A buffer view reaching past the binary chunk.
    let json = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 12}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 1200}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 100, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]
    });
    write(tmp.path(), "x.glb", &glb_file(&json, &[0u8; 12]));
    let message = read_all(tmp.path()).unwrap_err().to_string();
    assert!(
        message.contains("x.glb") && message.contains("buffer view 0"),
        "{message}"
    );
}

fn glb_file(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    common::glb(json, bin)
}

#[test]
fn invalid_json_is_an_error_naming_the_file() {
    let dir = simple_copy();
    write(
        dir.path(),
        "tileset.json",
        b"{\"asset\": {\"version\": \"1.0\"}, \"root\": [",
    );
    let e = read_all(dir.path()).unwrap_err();
    assert!(matches!(e, TilesError::Json { .. }), "{e:?}");
    assert!(
        e.to_string()
            .starts_with("tileset.json: invalid tileset JSON"),
        "{e}"
    );
    // Valid JSON, invalid tile: named by its path.
    write_json(
        dir.path(),
        "tileset.json",
        &json!({
            "asset": {"version": "1.0"}, "geometricError": 1,
            "root": {"boundingVolume": {"box": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]}, "geometricError": 1,
                     "children": [{"boundingVolume": {"box": [1, 2, 3]}, "geometricError": 0}]}
        }),
    );
    let message = read_all(dir.path()).unwrap_err().to_string();
    assert!(
        message.contains("root.children[0]") && message.contains("box has 3 numbers"),
        "{message}"
    );
    // A pnts feature table that is not JSON.
    let mut bytes = pnts(&json!({"POINTS_LENGTH": 0}), &[], None, &[]);
    bytes[28] = b'[';
    write(dir.path(), "x.pnts", &bytes);
    write_json(
        dir.path(),
        "tileset.json",
        &one_tile_tileset("x.pnts", None),
    );
    let message = read_all(dir.path()).unwrap_err().to_string();
    assert!(
        message.contains("x.pnts") && message.contains("feature table JSON"),
        "{message}"
    );
}

#[test]
fn cycles_of_external_tilesets_are_refused_with_the_chain() {
    let dir = tempfile::tempdir().unwrap();
    let tile = |content: &str| {
        json!({
            "asset": {"version": "1.0"}, "geometricError": 1,
            "root": {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 1, "content": {"uri": content}}
        })
    };
    write_json(dir.path(), "tileset.json", &tile("a/one.json"));
    write_json(dir.path(), "a/one.json", &tile("../b/two.json"));
    write_json(dir.path(), "b/two.json", &tile("../a/one.json"));
    let e = read_all(dir.path()).unwrap_err();
    let TilesError::Cycle { chain } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(
        chain,
        &["tileset.json", "a/one.json", "b/two.json", "a/one.json"]
    );
    assert!(
        e.to_string()
            .contains("a/one.json -> b/two.json -> a/one.json"),
        "{e}"
    );
    // A tileset naming itself.
    write_json(dir.path(), "tileset.json", &tile("tileset.json"));
    assert!(matches!(
        read_all(dir.path()).unwrap_err(),
        TilesError::Cycle { .. }
    ));
    // The same external tileset under two tiles is not a cycle.
    let two = json!({
        "asset": {"version": "1.0"}, "geometricError": 1,
        "root": {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 1, "children": [
            {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 1, "content": {"uri": "leaf.json"}},
            {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 1, "content": {"uri": "leaf.json"}}]}
    });
    write_json(dir.path(), "tileset.json", &two);
    write_json(
        dir.path(),
        "leaf.json",
        &json!({"asset": {"version": "1.0"}, "geometricError": 0,
        "root": {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 0}}),
    );
    let (tileset, _) = Tileset::open(&dir.path().join("tileset.json")).unwrap();
    assert_eq!(tileset.tiles.len(), 5);
    assert_eq!(tileset.files.len(), 3);
}

#[test]
fn absurd_transforms_are_refused_naming_the_tile() {
    let dir = tempfile::tempdir().unwrap();
    let with_child_transform = |t: serde_json::Value| {
        json!({
            "asset": {"version": "1.0"}, "geometricError": 1,
            "root": {"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 1,
                     "transform": [1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1],
                     "children": [{"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 0, "transform": t}]}
        })
    };
    let cases = [
        // Overflows to infinity (and NaN) once accumulated with the root's 1e300 scale.
        (
            json!([1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1]),
            "non-finite",
        ),
        // Zero scale.
        (
            json!([0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
            "zero length",
        ),
        (
            json!([1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1]),
            "coplanar",
        ),
        (
            json!([1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
            "not affine",
        ),
        (json!([1, 0, 0]), "16"),
    ];
    for (transform, expected) in cases {
        write_json(dir.path(), "tileset.json", &with_child_transform(transform));
        let e = read_all(dir.path()).unwrap_err();
        let TilesError::BadTransform { tile, .. } = &e else {
            panic!("{e:?}")
        };
        assert_eq!(tile, "root.children[0]");
        assert!(e.to_string().contains(expected), "{e}");
    }
    // JSON has no NaN: a NaN written into the file is invalid JSON, refused as such.
    write(
        dir.path(),
        "tileset.json",
        br#"{"asset": {"version": "1.0"}, "root": {"transform": [NaN]}}"#,
    );
    assert!(matches!(
        read_all(dir.path()).unwrap_err(),
        TilesError::Json { .. }
    ));
}

#[test]
fn limits_refuse_deep_and_large_tilesets() {
    let dir = tempfile::tempdir().unwrap();
    let mut tile = json!({"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 0});
    for _ in 0..20 {
        tile = json!({"boundingVolume": {"sphere": [0, 0, 0, 1]}, "geometricError": 0, "children": [tile]});
    }
    write_json(
        dir.path(),
        "tileset.json",
        &json!({"asset": {"version": "1.0"}, "geometricError": 0, "root": tile}),
    );
    let source = LocalSource::new(dir.path());
    let limits = LoadLimits {
        max_depth: 10,
        ..LoadLimits::default()
    };
    let e = Tileset::load_with(&source, "tileset.json", &limits).unwrap_err();
    assert!(
        matches!(e, TilesError::Limit { .. }) && e.to_string().contains("levels deep"),
        "{e}"
    );
    let limits = LoadLimits {
        max_tiles: 5,
        ..LoadLimits::default()
    };
    let e = Tileset::load_with(&source, "tileset.json", &limits).unwrap_err();
    assert!(e.to_string().contains("more than 5 tiles"), "{e}");
    // JSON nested beyond serde_json's recursion limit is refused, not a stack overflow.
    let deep = "[".repeat(100_000);
    write(dir.path(), "tileset.json", deep.as_bytes());
    assert!(matches!(
        read_all(dir.path()).unwrap_err(),
        TilesError::Json { .. }
    ));
    // A file over the source's size limit.
    let small = LocalSource::new(dir.path()).with_max_bytes(1000);
    assert!(matches!(
        Tileset::load(&small, "tileset.json").unwrap_err(),
        TilesError::Limit { .. }
    ));
}

#[test]
fn draco_pnts_is_reported_as_unsupported_naming_the_tile() {
    let dir = tempfile::tempdir().unwrap();
    let ft = json!({"POINTS_LENGTH": 10, "extensions": {"3DTILES_draco_point_compression": {
        "properties": {"POSITION": 0}, "byteOffset": 0, "byteLength": 4}}});
    write(dir.path(), "d.pnts", &pnts(&ft, &[0u8; 8], None, &[]));
    write_json(
        dir.path(),
        "tileset.json",
        &one_tile_tileset("d.pnts", None),
    );
    let e = read_all(dir.path()).unwrap_err();
    assert!(
        matches!(e.root_cause(), TilesError::Unsupported { .. }),
        "{e:?}"
    );
    let message = e.to_string();
    assert!(
        message.contains("d.pnts") && message.contains("tile root") && message.contains("Draco"),
        "{message}"
    );
}

#[test]
fn every_truncation_and_byte_flip_of_real_content_is_an_error_or_points() {
    // A deterministic mutation sweep over a producer's pnts and GLB: no panic, and a decoded
    // result never holds more points than the header claims.
    for rel in [
        "tiles/autzen_pnts/points/r3.pnts",
        "tiles/autzen_glb/points/r3.glb",
    ] {
        let bytes = std::fs::read(testdata(rel)).unwrap();
        let context = pointlet_tiles::ContentContext {
            uri: rel,
            world: pointlet_tiles::Transform::IDENTITY,
            up_axis: pointlet_tiles::UpAxis::Y,
            source: None,
        };
        let full = pointlet_tiles::content::decode(&bytes, &context)
            .unwrap()
            .len();
        for cut in 0..bytes.len() {
            let _ = pointlet_tiles::content::decode(&bytes[..cut], &context);
        }
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..3000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut damaged = bytes.clone();
            let at = (state as usize) % damaged.len();
            damaged[at] ^= (state >> 32) as u8 | 1;
            if let Ok(points) = pointlet_tiles::content::decode(&damaged, &context) {
                assert!(
                    points.len() <= full.max(1) * 64,
                    "{rel}: {} points",
                    points.len()
                );
                assert_eq!(points.colors.len(), points.len());
            }
        }
    }
}
