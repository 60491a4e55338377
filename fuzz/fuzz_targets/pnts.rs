//! Tile content decoding never panics, hangs or allocates far beyond its input: the bytes go
//! through the decoder the tileset reader uses (pnts and its batch table; an input starting
//! with `glTF` goes to the GLB decoder), with a tile transform that scales and translates.
#![no_main]
use libfuzzer_sys::fuzz_target;
use pointlet_tiles::{ContentContext, Transform, UpAxis};

fuzz_target!(|data: &[u8]| {
    let context = ContentContext {
        uri: "fuzz.pnts",
        world: Transform([
            2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1e6, 2e6, 3e3, 1.0,
        ]),
        up_axis: UpAxis::Y,
        source: None,
    };
    if let Ok(points) = pointlet_tiles::content::decode(data, &context) {
        assert_eq!(points.colors.len(), points.len());
        if let Some(normals) = &points.normals {
            assert_eq!(normals.len(), points.len());
        }
        for a in &points.attributes {
            assert_eq!(a.values.len(), a.components * points.len());
        }
    }
});
