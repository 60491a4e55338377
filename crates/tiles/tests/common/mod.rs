//! Helpers of the integration tests: the source LAS points, point-set matching, and writers of
//! small synthetic pnts / GLB / tileset files.
#![allow(dead_code)]

use pointlet_tiles::{AttributeValues, LocalSource, TilePoints, Tileset};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(rel)
}

/// A source point: position, 8-bit colour and intensity.
#[derive(Clone, Debug)]
pub struct SourcePoint {
    pub xyz: [f64; 3],
    pub rgb: [u8; 3],
    pub intensity: u16,
}

/// The points of a LAS/LAZ file with its position quantization (scale, offset).
pub fn read_las(path: &Path) -> (Vec<SourcePoint>, [f64; 3], [f64; 3]) {
    let mut reader = pointlet_io::open(path).unwrap();
    let q = reader.meta().quantization.unwrap();
    let mut points = Vec::new();
    while let Some(batch) = reader.read_batch(100_000).unwrap() {
        let wide = batch.rgb.iter().any(|c| c.iter().any(|v| *v > 255));
        for i in 0..batch.len() {
            // Colours stored as 8-bit values in 16-bit fields stay as they are (py3dtiles'
            // --color_scale 256 keeps them); true 16-bit colours are shifted down.
            let c = batch.rgb[i];
            let rgb = if wide {
                c.map(|v| (v >> 8) as u8)
            } else {
                c.map(|v| v as u8)
            };
            points.push(SourcePoint {
                xyz: batch.xyz[i],
                rgb,
                intensity: batch.intensity[i],
            });
        }
    }
    (points, q.scale, q.offset)
}

/// A decoded point with what the comparisons look at.
#[derive(Clone, Debug)]
pub struct Decoded {
    pub xyz: [f64; 3],
    pub rgba: [u8; 4],
    pub intensity: Option<f64>,
}

pub fn decoded_points(parts: &[TilePoints]) -> Vec<Decoded> {
    let mut out = Vec::new();
    for p in parts {
        let intensity = p.attribute("intensity");
        for i in 0..p.len() {
            out.push(Decoded {
                xyz: p.positions[i],
                rgba: p.colors[i],
                intensity: intensity.and_then(|a| a.values.get_f64(i)),
            });
        }
    }
    out
}

/// Every content of the given tiles, decoded.
pub fn read_tiles(
    tileset: &Tileset,
    source: &LocalSource,
    tiles: impl Iterator<Item = usize>,
) -> Vec<TilePoints> {
    let mut out = Vec::new();
    for t in tiles {
        out.extend(tileset.read_tile(source, t).unwrap());
    }
    out
}

/// Colour and intensity of a source point, and of a decoded one.
type SourceValues = ([u8; 3], u16);
type DecodedValues = ([u8; 4], Option<f64>);

/// How colours are compared.
#[derive(Clone, Copy, Debug)]
pub enum ColourCheck {
    /// Equal bytes (pnts: the producer wrote the source's 8-bit values).
    Exact,
    /// Equal within one step of an 8-bit *linear* encoding (glTF COLOR_0 written as linear
    /// unorm8 by the producer): |lin(a) − lin(b)| ≤ 1.5/255.
    LinearStep,
}

/// Checks that `decoded` is the same point set as `source`: the same count, each decoded point
/// within `tolerance` metres of a grid position of the source quantization, and the multisets
/// of grid positions equal; colours (and intensities when `check_intensity`) of the points at
/// each position equal as multisets. Returns the largest position deviation.
pub fn assert_same_points(
    decoded: &[Decoded],
    source: &[SourcePoint],
    scale: [f64; 3],
    offset: [f64; 3],
    tolerance: f64,
    colours: ColourCheck,
    check_intensity: bool,
) -> f64 {
    assert_eq!(decoded.len(), source.len(), "point count");
    let key = |p: [f64; 3]| -> [i64; 3] {
        [0, 1, 2].map(|i| ((p[i] - offset[i]) / scale[i]).round() as i64)
    };
    let mut worst: f64 = 0.0;
    let mut by_key: BTreeMap<[i64; 3], (Vec<SourceValues>, Vec<DecodedValues>)> = BTreeMap::new();
    for s in source {
        by_key
            .entry(key(s.xyz))
            .or_default()
            .0
            .push((s.rgb, s.intensity));
    }
    for d in decoded {
        let k = key(d.xyz);
        for i in 0..3 {
            let grid = k[i] as f64 * scale[i] + offset[i];
            worst = worst.max((d.xyz[i] - grid).abs());
        }
        by_key.entry(k).or_default().1.push((d.rgba, d.intensity));
    }
    assert!(
        worst <= tolerance,
        "largest deviation from the source grid {worst} > {tolerance}"
    );
    for (k, (mut s, mut d)) in by_key {
        assert_eq!(s.len(), d.len(), "points at grid position {k:?}");
        s.sort_by_key(|(c, i)| (*c, *i));
        d.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.partial_cmp(&b.1).unwrap()));
        if s.len() > 1 {
            // Several points at one position: compare the colour multisets order-free by sorting both.
            d.sort_by_key(|(c, _)| *c);
        }
        for ((sc, si), (dc, di)) in s.iter().zip(&d) {
            match colours {
                ColourCheck::Exact => assert_eq!(&dc[..3], &sc[..], "colour at {k:?}"),
                ColourCheck::LinearStep => {
                    // The producer stored lin(source) as unorm8, within one step; the decoder
                    // rounds that to sRGB8, a monotonic map: so the decoded value lies between
                    // the sRGB8 values of lin(source) ∓ 1/255.
                    use pointlet_tiles::content::{linear_to_srgb8, srgb8_to_linear};
                    for c in 0..3 {
                        let lin = srgb8_to_linear(sc[c]);
                        let low = linear_to_srgb8(lin - 1.0 / 255.0);
                        let high = linear_to_srgb8(lin + 1.0 / 255.0);
                        assert!(
                            (low..=high).contains(&dc[c]),
                            "colour at {k:?}: {dc:?} vs {sc:?}"
                        );
                    }
                }
            }
            assert_eq!(dc[3], 255);
            if check_intensity {
                assert_eq!(*di, Some(*si as f64), "intensity at {k:?}");
            }
        }
    }
    worst
}

/// Every decoded point of every content lies in its tile's world bounding volume: within 1 mm
/// for leaves (geometric error 0), within the tile's geometric error for the others (the
/// producers' preview contents store coarser positions).
pub fn assert_points_in_volumes(tileset: &Tileset, source: &LocalSource) {
    for (t, tile) in tileset.tiles.iter().enumerate() {
        let tolerance = tile.geometric_error.max(1e-3);
        for part in tileset.read_tile(source, t).unwrap() {
            for p in &part.positions {
                assert!(
                    tile.volume.contains(*p, tolerance),
                    "point {p:?} of {} outside the volume of tile {}",
                    part.uri,
                    tile.path
                );
            }
        }
    }
}

/// A pnts file from its four parts (JSON parts padded with spaces to 8 bytes).
pub fn pnts(
    feature_json: &Value,
    feature_bin: &[u8],
    batch_json: Option<&Value>,
    batch_bin: &[u8],
) -> Vec<u8> {
    let pad = |mut v: Vec<u8>, with: u8| {
        while !(v.len() + 28).is_multiple_of(8) {
            v.push(with);
        }
        v
    };
    let ft_json = pad(serde_json::to_vec(feature_json).unwrap(), b' ');
    let bt_json = batch_json.map_or_else(Vec::new, |b| pad(serde_json::to_vec(b).unwrap(), b' '));
    let total = 28 + ft_json.len() + feature_bin.len() + bt_json.len() + batch_bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"pnts");
    for v in [
        1,
        total,
        ft_json.len(),
        feature_bin.len(),
        bt_json.len(),
        batch_bin.len(),
    ] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    out.extend_from_slice(&ft_json);
    out.extend_from_slice(feature_bin);
    out.extend_from_slice(&bt_json);
    out.extend_from_slice(batch_bin);
    out
}

/// A GLB from its JSON and binary chunk.
pub fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    if !b.is_empty() {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

/// A one-tile tileset JSON whose root has `content` and the given transform.
pub fn one_tile_tileset(content: &str, transform: Option<[f64; 16]>) -> Value {
    let mut root = serde_json::json!({
        "boundingVolume": {"sphere": [0, 0, 0, 1000]},
        "geometricError": 0,
        "refine": "ADD",
        "content": {"uri": content}
    });
    if let Some(t) = transform {
        root["transform"] = serde_json::json!(t);
    }
    serde_json::json!({"asset": {"version": "1.1"}, "geometricError": 10, "root": root})
}

pub fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

pub fn attribute_f64(points: &TilePoints, name: &str) -> Vec<f64> {
    match &points
        .attribute(name)
        .unwrap_or_else(|| panic!("no attribute {name}"))
        .values
    {
        AttributeValues::Float(v) => v.clone(),
        AttributeValues::Int(v) => v.iter().map(|x| *x as f64).collect(),
    }
}
