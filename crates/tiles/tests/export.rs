//! The tileset writer against the reader: stores built here from the repository's LAS files,
//! exported with ADD and REPLACE, read back by `Tileset`; points, colours and every attribute
//! compared with the store's, and the tree's invariants checked.

use pointlet_store::{BuildConfig, Store, StoreBuilder};
use pointlet_tiles::write::{export, ExportConfig, ExportError, ExportSummary, Projection};
use pointlet_tiles::{AttributeValues, Refine, TilePoints, Tileset, Transform};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(rel)
}

/// A store of `input` with small pointlets (so tiles cut through many of them).
fn build_store(input: &Path, out: &Path) -> Store {
    build_store_with_crs(input, out, None)
}

/// Like `build_store`, with the CRS records replaced by GeoTIFF keys naming EPSG `epsg`.
fn build_store_with_crs(input: &Path, out: &Path, epsg: Option<u16>) -> Store {
    let mut reader = pointlet_io::open(input).unwrap();
    let mut meta = reader.meta().clone();
    if let Some(code) = epsg {
        meta.vlrs.retain(|v| !v.is_crs());
        // Key directory 1.1.0 with 2 keys: model type projected, projected CRS `code`.
        let keys: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, code];
        meta.vlrs.push(pointlet_core::Vlr {
            user_id: "LASF_Projection".into(),
            record_id: 34735,
            description: "GeoTIFF GeoKeyDirectoryTag".into(),
            data: keys.iter().flat_map(|k| k.to_le_bytes()).collect(),
            extended: false,
        });
    }
    let config = BuildConfig {
        target_pointlets: (meta.point_count / 300).max(1),
        seed: 7,
        ..Default::default()
    };
    let mut b =
        StoreBuilder::create(out, config, &meta, vec![input.display().to_string()]).unwrap();
    while let Some(batch) = reader.read_batch(50_000).unwrap() {
        b.push(&batch).unwrap();
    }
    b.finish().unwrap();
    Store::open(out).unwrap()
}

/// One store point: raw position and every exported value, as the reader names them.
struct StorePoint {
    raw: [i64; 3],
    rgb8: Option<[u8; 3]>,
    values: Vec<(String, f64)>,
}

fn store_points(store: &Store, eight_bit: bool) -> Vec<StorePoint> {
    let h = store.header();
    let q = h.quantization;
    let extra =
        pointlet_core::extra::ExtraAttributes::from_vlrs(&h.vlrs, h.layout.extra_bytes as usize);
    let mut out = Vec::new();
    for i in 0..store.pointlets().len() {
        let b = store.read_pointlet(i).unwrap();
        for k in 0..b.len() {
            let raw =
                std::array::from_fn(|a| ((b.xyz[k][a] - q.offset[a]) / q.scale[a]).round() as i64);
            let mut values = vec![
                ("intensity".to_string(), b.intensity[k] as f64),
                ("return_number".into(), (b.returns[k] & 15) as f64),
                ("number_of_returns".into(), (b.returns[k] >> 4) as f64),
                ("flags".into(), b.flags[k] as f64),
                ("classification".into(), b.classification[k] as f64),
                ("scan_angle".into(), b.scan_angle[k] as f64),
                ("user_data".into(), b.user_data[k] as f64),
                ("point_source_id".into(), b.point_source_id[k] as f64),
            ];
            if h.layout.gps_time {
                values.push(("gps_time".into(), b.gps_time[k]));
            }
            let per = h.layout.extra_bytes as usize;
            for a in &extra.attributes {
                let bytes = &b.extra_bytes[k * per..(k + 1) * per];
                let mut raw_only = a.clone();
                raw_only.scale = 1.0;
                raw_only.offset = 0.0;
                raw_only.no_data = None;
                let name: String = a
                    .name
                    .chars()
                    .map(|c| {
                        if c.is_ascii_alphanumeric() {
                            c.to_ascii_lowercase()
                        } else {
                            '_'
                        }
                    })
                    .collect();
                values.push((name, raw_only.value(bytes).unwrap()));
            }
            let rgb8 = h.layout.rgb.then(|| {
                b.rgb[k].map(|v| {
                    if eight_bit {
                        v.min(255) as u8
                    } else {
                        (v as f64 / 257.0).round() as u8
                    }
                })
            });
            out.push(StorePoint { raw, rgb8, values });
        }
    }
    out
}

/// World → store raw coordinates through the inverse of the tileset's root frame.
struct Inverse {
    m: [[f64; 3]; 3],
    t: [f64; 3],
    origin: [f64; 3],
    metres_per_unit: [f64; 3],
    scale: [f64; 3],
    offset: [f64; 3],
}

impl Inverse {
    fn new(root: &Transform, json: &serde_json::Value, store: &Store) -> Inverse {
        let a = |r: usize, c: usize| root.0[c * 4 + r];
        let det = root.determinant3();
        // Adjugate / determinant of the 3×3 part.
        let m = [
            [
                (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) / det,
                (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) / det,
                (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) / det,
            ],
            [
                (a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2)) / det,
                (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) / det,
                (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) / det,
            ],
            [
                (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0)) / det,
                (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) / det,
                (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) / det,
            ],
        ];
        let extras = &json["asset"]["extras"]["pointlet"];
        let v3 =
            |v: &serde_json::Value| -> [f64; 3] { std::array::from_fn(|i| v[i].as_f64().unwrap()) };
        let q = store.header().quantization;
        Inverse {
            m,
            t: [root.0[12], root.0[13], root.0[14]],
            origin: v3(&extras["origin"]),
            metres_per_unit: v3(&extras["metresPerUnit"]),
            scale: q.scale,
            offset: q.offset,
        }
    }

    /// Store raw coordinates (fractional) of a world position.
    fn raw(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [p[0] - self.t[0], p[1] - self.t[1], p[2] - self.t[2]];
        std::array::from_fn(|r| {
            let local = self.m[r][0] * d[0] + self.m[r][1] * d[1] + self.m[r][2] * d[2];
            let store = local / self.metres_per_unit[r] + self.origin[r];
            (store - self.offset[r]) / self.scale[r]
        })
    }
}

/// Values of point `i` of a tile, by attribute name.
fn tile_value(points: &TilePoints, name: &str, i: usize) -> f64 {
    let a = points.attribute(name).unwrap_or_else(|| {
        panic!(
            "{}: no attribute {name}; has {:?}",
            points.uri,
            points
                .attributes
                .iter()
                .map(|a| &a.name)
                .collect::<Vec<_>>()
        )
    });
    match &a.values {
        AttributeValues::Int(v) => v[i] as f64,
        AttributeValues::Float(v) => v[i],
    }
}

/// Matches every point of `tiles` to a distinct store point with the same colour and values
/// and a position within `tolerance` raw steps; returns how many store points each matched.
fn match_points(
    store: &[StorePoint],
    tiles: &[TilePoints],
    inverse: &Inverse,
    tolerance: [f64; 3],
) -> Vec<u32> {
    // Keyed by everything but position, then searched by position.
    let key_of = |rgb: Option<[u8; 3]>, values: &[(String, f64)]| -> Vec<u64> {
        let mut k: Vec<u64> = values.iter().map(|(_, v)| v.to_bits()).collect();
        if let Some(c) = rgb {
            k.extend(c.iter().map(|v| *v as u64));
        }
        k
    };
    let mut by_key: HashMap<Vec<u64>, Vec<usize>> = HashMap::new();
    for (i, p) in store.iter().enumerate() {
        by_key.entry(key_of(p.rgb8, &p.values)).or_default().push(i);
    }
    let mut used = vec![0u32; store.len()];
    let names: Vec<String> = store[0].values.iter().map(|(n, _)| n.clone()).collect();
    for tile in tiles {
        for i in 0..tile.len() {
            let values: Vec<(String, f64)> = names
                .iter()
                .map(|n| (n.clone(), tile_value(tile, n, i)))
                .collect();
            let rgb = store[0].rgb8.map(|_| {
                let c = tile.colors[i];
                [c[0], c[1], c[2]]
            });
            let raw = inverse.raw(tile.positions[i]);
            let candidates = by_key.get(&key_of(rgb, &values)).unwrap_or_else(|| {
                panic!(
                    "{}: point {i} matches no store point's colour and values: {values:?} {rgb:?}",
                    tile.uri
                )
            });
            let found = candidates.iter().copied().find(|&c| {
                used[c] == 0
                    && (0..3).all(|a| (store[c].raw[a] as f64 - raw[a]).abs() <= tolerance[a])
            });
            let c = found.unwrap_or_else(|| {
                panic!(
                    "{}: point {i} at raw {raw:?} is no unused store point within {tolerance:?}",
                    tile.uri
                )
            });
            used[c] += 1;
        }
    }
    used
}

fn read_all(
    tileset: &Tileset,
    source: &pointlet_tiles::LocalSource,
    tiles: impl Iterator<Item = usize>,
) -> Vec<TilePoints> {
    tiles
        .flat_map(|t| tileset.read_tile(source, t).unwrap())
        .collect()
}

/// Structure of the written tree: refine at the root, errors not growing with depth, leaves 0,
/// children's boxes inside their parent's, every content inside its tile's box.
fn check_tree(tileset: &Tileset, contents: &[(usize, TilePoints)], refine: Refine) {
    let root = tileset.root();
    assert_eq!(root.refine, refine);
    for (i, t) in tileset.tiles.iter().enumerate() {
        assert_eq!(t.refine, refine, "tile {}", t.path);
        if t.children.is_empty() {
            assert_eq!(t.geometric_error, 0.0, "leaf {}", t.path);
        } else {
            assert!(t.geometric_error > 0.0, "inner tile {} has error 0", t.path);
        }
        if let Some(p) = t.parent {
            let parent = &tileset.tiles[p];
            assert!(
                t.geometric_error <= parent.geometric_error,
                "tile {} error above its parent's",
                t.path
            );
            let (c, pb) = (t.volume.aabb(), parent.volume.aabb());
            let slack = 1e-3 + 1e-9 * pb.diagonal();
            for a in 0..3 {
                assert!(
                    c.min[a] >= pb.min[a] - slack && c.max[a] <= pb.max[a] + slack,
                    "tile {} box outside its parent's",
                    t.path
                );
            }
        }
        for (_, points) in contents.iter().filter(|(tile, _)| *tile == i) {
            for p in &points.positions {
                assert!(
                    t.volume.contains(*p, 1e-3),
                    "{}: point {p:?} outside its tile box",
                    points.uri
                );
            }
        }
    }
    assert!(tileset.files[0].geometric_error >= root.geometric_error);
}

fn export_to(store: &Store, out: &Path, refine: Refine, points_per_tile: u64) -> ExportSummary {
    let config = ExportConfig {
        refine,
        points_per_tile,
        ram_budget: 4 << 20,
        force: false,
        ..Default::default()
    };
    export(store, out, &config, &|_| {}).unwrap()
}

fn round_trip(input: &str, refine: Refine) {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store(&testdata(input), &dir.path().join("s.pointlet"));
    let out = dir.path().join("tiles");
    let per_tile = (store.header().points / 40).max(100);
    let summary = export_to(&store, &out, refine, per_tile);
    assert!(
        summary.depth >= 2,
        "{input}: a tree of depth {} is too shallow to test",
        summary.depth
    );
    let (tileset, source) = Tileset::open(&out.join("tileset.json")).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    assert_eq!(json["asset"]["version"], "1.1");
    let inverse = Inverse::new(&tileset.root().transform, &json, &store);
    let points = store_points(&store, summary.eight_bit_color);

    let contents: Vec<(usize, TilePoints)> = (0..tileset.tiles.len())
        .flat_map(|t| {
            tileset
                .read_tile(&source, t)
                .unwrap()
                .into_iter()
                .map(move |p| (t, p))
        })
        .collect();
    for (_, c) in &contents {
        assert!(c.notes.is_empty(), "{}: {:?}", c.uri, c.notes);
    }
    check_tree(&tileset, &contents, refine);
    // The matrix chain in f64 adds far less than a thousandth of a step.
    let tol = |e: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|a| e[a] / store.header().quantization.scale[a] + 1e-3)
    };
    match refine {
        Refine::Add => {
            // Every point in exactly one tile.
            let all: Vec<TilePoints> = contents.into_iter().map(|(_, p)| p).collect();
            let used = match_points(&points, &all, &inverse, tol(summary.quantization_error));
            assert!(
                used.iter().all(|u| *u == 1),
                "{input}: some store points are in no tile"
            );
            assert_eq!(summary.content_points, points.len() as u64);
        }
        Refine::Replace => {
            // The leaves hold every point once; each other tile, a subset of its cell.
            let leaves = read_all(&tileset, &source, tileset.leaves());
            let used = match_points(
                &points,
                &leaves,
                &inverse,
                tol(summary.leaf_quantization_error),
            );
            assert!(
                used.iter().all(|u| *u == 1),
                "{input}: the leaves miss store points"
            );
            for (t, tile) in &contents {
                if !tileset.tiles[*t].children.is_empty() {
                    match_points(
                        &points,
                        std::slice::from_ref(tile),
                        &inverse,
                        tol(summary.quantization_error),
                    );
                }
            }
            assert!(summary.content_points > points.len() as u64);
        }
    }
}

#[test]
fn autzen_round_trips_with_add() {
    round_trip("autzen_trim.laz", Refine::Add);
}

#[test]
fn autzen_round_trips_with_replace() {
    round_trip("autzen_trim.laz", Refine::Replace);
}

#[test]
fn extra_bytes_round_trip_with_add() {
    round_trip("extrabytes.las", Refine::Add);
}

#[test]
fn wide_colours_and_waveforms_round_trip_with_replace() {
    round_trip("simple1_4.las", Refine::Replace);
}

#[test]
fn output_is_the_same_for_any_thread_count_and_ram_budget() {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store(&testdata("autzen_trim.laz"), &dir.path().join("s.pointlet"));
    // Threads and RAM budget (1 byte: one tile per batch) change nothing in the output.
    let files = |threads: usize, ram_budget: u64| {
        let out = dir.path().join(format!("t{threads}-{ram_budget}"));
        let config = ExportConfig {
            refine: Refine::Add,
            points_per_tile: 3_000,
            ram_budget,
            force: false,
            ..Default::default()
        };
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| export(&store, &out, &config, &|_| {}))
            .unwrap();
        let mut all = Vec::new();
        for entry in walk(&out) {
            let rel = entry.strip_prefix(&out).unwrap().to_path_buf();
            all.push((rel, std::fs::read(&entry).unwrap()));
        }
        all.sort();
        all
    };
    let one = files(1, 1 << 30);
    for other in [files(3, 1 << 30), files(2, 1)] {
        assert_eq!(one.len(), other.len());
        assert!(one.len() > 10, "only {} files", one.len());
        for ((a, x), (b, y)) in one.iter().zip(&other) {
            assert_eq!(a, b);
            // The tileset names the store by path, which is the same here.
            assert!(
                x == y,
                "{} differs with other threads or budget",
                a.display()
            );
        }
    }
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn autzen_is_placed_in_ecef_from_its_epsg_code() {
    let dir = tempfile::tempdir().unwrap();
    // autzen_trim.laz names its CRS by parameters (user-defined); these are its EPSG:2994 keys.
    let store = build_store_with_crs(
        &testdata("autzen_trim.laz"),
        &dir.path().join("s.pointlet"),
        Some(2994),
    );
    let out = dir.path().join("tiles");
    let summary = export_to(&store, &out, Refine::Add, 5_000);
    let g = &summary.georeference;
    assert_eq!(g.epsg, Some(2994), "{}", g.note);
    // EPSG:2994 is in international feet.
    assert!((g.metres_per_unit[0] - 0.3048).abs() < 1e-9);
    let projection = Projection::from_epsg(2994).unwrap();
    // Autzen Stadium, Eugene, Oregon: about 44.058° N, 123.069° W.
    let (lon, lat) = projection.to_lon_lat(g.origin[0], g.origin[1]).unwrap();
    assert!(
        (lon.to_degrees() + 123.07).abs() < 0.02 && (lat.to_degrees() - 44.06).abs() < 0.02,
        "{lon} {lat}"
    );

    // Each tile point in ECEF against the projection of its store point: the linear frame's
    // error grows as d²/2R (plus the projection's own curvature), centimetres over this extent.
    let (tileset, source) = Tileset::open(&out.join("tileset.json")).unwrap();
    let root = tileset.root().transform;
    let b = store.read_pointlet(0).unwrap();
    let extent = store.header().bounds.diagonal() * 0.3048;
    let allowed = extent * extent / (2.0 * 6.37e6) * 4.0 + 1e-3;
    for k in (0..b.len()).step_by(17) {
        let p = b.xyz[k];
        let exact = projection.to_ecef(p[0], p[1], p[2] * 0.3048).unwrap();
        let local: [f64; 3] = std::array::from_fn(|a| (p[a] - g.origin[a]) * g.metres_per_unit[a]);
        let framed = root.apply_point(local);
        let d = (0..3)
            .map(|a| (exact[a] - framed[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            d < allowed,
            "point {k}: {d} m from its projection (allowed {allowed})"
        );
    }
    // And the content read back sits at those ECEF positions.
    let leaf = tileset.leaves().next().unwrap();
    let points = &tileset.read_tile(&source, leaf).unwrap()[0];
    let r = (points.positions[0][0].powi(2)
        + points.positions[0][1].powi(2)
        + points.positions[0][2].powi(2))
    .sqrt();
    assert!((6.36e6..6.38e6).contains(&r), "ECEF radius {r}");
}

#[test]
fn a_store_without_crs_is_local_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store(&testdata("simple1_4.las"), &dir.path().join("s.pointlet"));
    let out = dir.path().join("tiles");
    let summary = export_to(&store, &out, Refine::Add, 5_000);
    assert_eq!(summary.georeference.epsg, None);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    let extras = &json["asset"]["extras"]["pointlet"];
    assert_eq!(extras["georeferenced"], false);
    assert!(
        extras["placement"].as_str().unwrap().contains("local"),
        "{extras}"
    );
}

#[test]
fn local_placement_and_no_metadata_keep_store_coordinates_and_colours_only() {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store_with_crs(
        &testdata("autzen_trim.laz"),
        &dir.path().join("s.pointlet"),
        Some(2994),
    );
    let out = dir.path().join("tiles");
    let config = ExportConfig {
        points_per_tile: 5_000,
        ram_budget: 4 << 20,
        local: true,
        metadata: false,
        ..Default::default()
    };
    let summary = export(&store, &out, &config, &|_| {}).unwrap();
    assert_eq!(summary.georeference.epsg, None, "asked to stay local");
    assert!(summary.georeference.note.contains("--local"));
    let (tileset, source) = Tileset::open(&out.join("tileset.json")).unwrap();
    let mut points = 0;
    let bounds = store.header().bounds;
    for t in 0..tileset.tiles.len() {
        for c in tileset.read_tile(&source, t).unwrap() {
            assert!(
                c.attributes.is_empty(),
                "metadata in {}: {:?}",
                c.uri,
                c.attributes.len()
            );
            assert!(
                c.colors.iter().any(|rgba| rgba[..3] != [255, 255, 255]),
                "colours kept"
            );
            for p in &c.positions {
                // Store coordinates (feet), within the u16 quantization of a leaf.
                assert!((0..3).all(|a| p[a] >= bounds.min[a] - 1.0 && p[a] <= bounds.max[a] + 1.0));
            }
            points += c.len();
        }
    }
    assert_eq!(points as u64, store.header().points);
}

#[test]
fn a_non_empty_output_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store(&testdata("simple.las"), &dir.path().join("s.pointlet"));
    let out = dir.path().join("tiles");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "x").unwrap();
    let mut config = ExportConfig::default();
    let err = export(&store, &out, &config, &|_| {}).unwrap_err();
    assert!(matches!(err, ExportError::NotEmpty(_)), "{err}");
    assert!(out.join("keep.txt").exists());
    config.force = true;
    export(&store, &out, &config, &|_| {}).unwrap();
    assert!(!out.join("keep.txt").exists() && out.join("tileset.json").exists());
    // Nothing of the export is left beside the output.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

/// Every point a reader gives, batch by batch or part by part, as comparable rows.
fn reader_rows(reader: &mut pointlet_tiles::points::TilesetPoints, by_parts: bool) -> Vec<String> {
    use pointlet_io::PointReader;
    let row = |b: &pointlet_core::PointBatch, k: usize| {
        format!(
            "{:?} {:?} {} {}",
            b.xyz[k],
            b.rgb.get(k),
            b.intensity[k],
            b.classification[k]
        )
    };
    let mut rows = Vec::new();
    if by_parts {
        let parts = reader.parted().expect("tiles are parts");
        let (mut batch, mut scratch) = (pointlet_core::PointBatch::default(), Vec::new());
        for i in 0..parts.part_sizes().len() {
            parts.decode_part(i, &mut batch, &mut scratch).unwrap();
            rows.extend((0..batch.len()).map(|k| row(&batch, k)));
        }
    } else {
        while let Some(b) = reader.read_batch(3_000).unwrap() {
            rows.extend((0..b.len()).map(|k| row(&b, k)));
        }
    }
    rows
}

#[test]
fn a_tileset_reads_the_same_from_the_opening_cache_by_parts_and_decoded_again() {
    let dir = tempfile::tempdir().unwrap();
    let store = build_store(&testdata("autzen_trim.laz"), &dir.path().join("s.pointlet"));
    let out = dir.path().join("tiles");
    export_to(&store, &out, Refine::Replace, 5_000);
    let json = out.join("tileset.json");
    let open = |cache: u64| {
        let (source, uri) = pointlet_tiles::LocalSource::for_file(&json);
        let tileset = Tileset::load(&source, &uri).unwrap();
        pointlet_tiles::points::TilesetPoints::with_cache(&json, tileset, Box::new(source), cache)
            .unwrap()
    };
    let cached = reader_rows(&mut open(pointlet_tiles::points::CACHE_BYTES), false);
    assert_eq!(cached.len() as u64, store.header().points);
    assert_eq!(reader_rows(&mut open(0), false), cached, "decoded again");
    assert_eq!(reader_rows(&mut open(0), true), cached, "by parts");
    assert_eq!(
        reader_rows(&mut open(1 << 20), true),
        cached,
        "partly cached"
    );
}
