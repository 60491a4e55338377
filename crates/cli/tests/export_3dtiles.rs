//! `pointlet export-3dtiles` end to end: bad inputs and outputs fail cleanly, and an exported
//! tileset loads in CesiumJS (headless Chromium, WebGL on SwiftShader) and shows the points
//! where `pointlet render` of the store puts them from the same camera.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn autzen_store(dir: &Path) -> PathBuf {
    let store = dir.join("autzen.pointlet");
    ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&store)]);
    store
}

#[test]
fn exports_a_store_and_says_the_tileset_is_local() {
    let dir = tempfile::tempdir().unwrap();
    let store = autzen_store(dir.path());
    let out = dir.path().join("tiles");
    let err = ok_stderr(&[
        "export-3dtiles",
        s(&store),
        "-o",
        s(&out),
        "--points-per-tile",
        "10K",
    ]);
    // autzen_trim.laz names its CRS by parameters only (user-defined GeoTIFF codes).
    assert!(err.contains("the tileset is local"), "{err}");
    assert!(err.contains("exported 110000 points"), "{err}");
    assert!(out.join("tileset.json").is_file());
    assert_eq!(listing(dir.path()), ["autzen.pointlet", "tiles"]);
}

#[test]
fn refuses_a_file_that_is_not_a_store() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("fake.pointlet");
    std::fs::write(&fake, b"this is not a store at all, only some text").unwrap();
    let out = dir.path().join("tiles");
    fails(
        &["export-3dtiles", s(&fake), "-o", s(&out)],
        &["not a pointlet store"],
    );
    assert!(!out.exists());
    fails(
        &["export-3dtiles", s(&data("simple.las")), "-o", s(&out)],
        &["reads a pointlet store"],
    );
    assert_eq!(listing(dir.path()), ["fake.pointlet"]);
}

#[test]
fn refuses_a_truncated_store() {
    let dir = tempfile::tempdir().unwrap();
    let store = autzen_store(dir.path());
    let len = std::fs::metadata(&store).unwrap().len();
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&store)
        .unwrap();
    f.set_len(len - 5000).unwrap();
    let out = dir.path().join("tiles");
    fails(
        &["export-3dtiles", s(&store), "-o", s(&out)],
        &["truncated"],
    );
    assert_eq!(listing(dir.path()), ["autzen.pointlet"]);
}

#[test]
fn refuses_a_non_empty_output_unless_forced_and_an_unwritable_one() {
    let dir = tempfile::tempdir().unwrap();
    let store = autzen_store(dir.path());
    let out = dir.path().join("tiles");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("mine.txt"), "keep").unwrap();
    fails(
        &["export-3dtiles", s(&store), "-o", s(&out)],
        &["not empty", "--force"],
    );
    assert!(out.join("mine.txt").exists());
    ok(&["export-3dtiles", s(&store), "-o", s(&out), "--force"]);
    assert!(out.join("tileset.json").exists() && !out.join("mine.txt").exists());
    // An output under a file cannot be written (root ignores permission bits, so a file it is).
    let file = dir.path().join("plain");
    std::fs::write(&file, "x").unwrap();
    fails(
        &["export-3dtiles", s(&store), "-o", s(&file.join("tiles"))],
        &["plain"],
    );
    // An output that is a file is not replaced, forced or not.
    fails(
        &["export-3dtiles", s(&store), "-o", s(&file), "--force"],
        &["not a folder"],
    );
    assert_eq!(listing(dir.path()), ["autzen.pointlet", "plain", "tiles"]);
}

/// Lit pixels of an RGB(A) PNG: count, centroid and bounding box, in fractions of the image.
struct Silhouette {
    coverage: f64,
    centroid: [f64; 2],
    bbox: [f64; 4],
}

fn silhouette(path: &Path) -> Silhouette {
    let mut decoder =
        png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let (w, h) = (info.width as usize, info.height as usize);
    let (mut n, mut sx, mut sy) = (0usize, 0f64, 0f64);
    let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for y in 0..h {
        for x in 0..w {
            let p = &buf[(y * w + x) * channels..][..3];
            if p.iter().map(|v| *v as u32).sum::<u32>() > 24 {
                n += 1;
                sx += x as f64;
                sy += y as f64;
                bbox = [
                    bbox[0].min(x as f64),
                    bbox[1].min(y as f64),
                    bbox[2].max(x as f64),
                    bbox[3].max(y as f64),
                ];
            }
        }
    }
    assert!(n > 0, "{}: no lit pixels", path.display());
    Silhouette {
        coverage: n as f64 / (w * h) as f64,
        centroid: [sx / n as f64 / w as f64, sy / n as f64 / h as f64],
        bbox: [
            bbox[0] / w as f64,
            bbox[1] / h as f64,
            bbox[2] / w as f64,
            bbox[3] / h as f64,
        ],
    }
}

/// The tileset's root frame: store coordinates → tileset world (ECEF, or the store's own).
struct Frame {
    matrix: Vec<f64>,
    origin: [f64; 3],
    metres_per_unit: [f64; 3],
}

impl Frame {
    fn of(tiles: &Path) -> Frame {
        let tileset: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tiles.join("tileset.json")).unwrap()).unwrap();
        let extras = &tileset["asset"]["extras"]["pointlet"];
        let v3 =
            |v: &serde_json::Value| -> [f64; 3] { std::array::from_fn(|i| v[i].as_f64().unwrap()) };
        Frame {
            matrix: (0..16)
                .map(|i| tileset["root"]["transform"][i].as_f64().unwrap())
                .collect(),
            origin: v3(&extras["origin"]),
            metres_per_unit: v3(&extras["metresPerUnit"]),
        }
    }

    fn world(&self, store: [f64; 3]) -> [f64; 3] {
        let local: [f64; 3] =
            std::array::from_fn(|a| (store[a] - self.origin[a]) * self.metres_per_unit[a]);
        std::array::from_fn(|r| {
            (0..3)
                .map(|c| self.matrix[c * 4 + r] * local[c])
                .sum::<f64>()
                + self.matrix[12 + r]
        })
    }

    /// The world direction of the store's z axis.
    fn up(&self) -> [f64; 3] {
        [self.matrix[8], self.matrix[9], self.matrix[10]]
    }
}

/// Renders `store` with `pointlet render` and its tileset `tiles` in CesiumJS from the same
/// camera (given in store coordinates) and compares where the points are.
fn compare_with_cesium(store: &Path, tiles: &Path, eye: [f64; 3], target: [f64; 3], dir: &Path) {
    let started = std::time::Instant::now();
    let frame = Frame::of(tiles);
    let size = 400;
    let v = |p: [f64; 3]| format!("{},{},{}", p[0], p[1], p[2]);
    let ours = dir.join("pointlet.png");
    ok(&[
        "render",
        s(store),
        "-o",
        s(&ours),
        "--width",
        &size.to_string(),
        "--height",
        &size.to_string(),
        "--eye",
        &v(eye),
        "--target",
        &v(target),
        "--up",
        "0,0,1",
        "--fov",
        "50",
        "--point-size",
        "1",
    ]);
    let cesium = dir.join("cesium.png");
    let tools = repo().join("target/node-tools/cesium");
    let run = Command::new("node")
        .arg(repo().join("crates/cli/tests/cesium/load_tileset.cjs"))
        .args([
            s(&tools),
            s(tiles),
            s(&cesium),
            &v(frame.world(eye)),
            &v(frame.world(target)),
            &v(frame.up()),
            "50",
            &size.to_string(),
        ])
        .output()
        .expect("running node");
    assert!(
        run.status.success(),
        "Cesium did not load the tileset:\n{}\n{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    if let Some(keep) = std::env::var_os("POINTLET_KEEP_CESIUM_PNG").map(PathBuf::from) {
        let name = tiles.file_name().unwrap().to_string_lossy().into_owned();
        std::fs::copy(&ours, keep.join(format!("{name}-pointlet.png"))).unwrap();
        std::fs::copy(&cesium, keep.join(format!("{name}-cesium.png"))).unwrap();
    }
    let a = silhouette(&ours);
    let b = silhouette(&cesium);
    eprintln!(
        "{}: cesium {} | ours coverage {:.3} centroid {:?} bbox {:?} | cesium coverage {:.3} centroid {:?} bbox {:?} | {:.1} s",
        tiles.display(),
        String::from_utf8_lossy(&run.stdout).trim(),
        a.coverage, a.centroid, a.bbox, b.coverage, b.centroid, b.bbox,
        started.elapsed().as_secs_f64()
    );
    for i in 0..2 {
        assert!(
            (a.centroid[i] - b.centroid[i]).abs() < 0.03,
            "centroids differ: {:?} vs {:?}",
            a.centroid,
            b.centroid
        );
    }
    for i in 0..4 {
        assert!(
            (a.bbox[i] - b.bbox[i]).abs() < 0.03,
            "bounding boxes differ: {:?} vs {:?}",
            a.bbox,
            b.bbox
        );
    }
    // One-pixel points of the same cloud cover the same share of the image, within 15 %.
    let ratio = b.coverage / a.coverage;
    assert!(
        (0.85..1.18).contains(&ratio),
        "coverage {:.3} (Cesium) vs {:.3} (pointlet)",
        b.coverage,
        a.coverage
    );
}

fn ensure_cesium() {
    let status = Command::new("bash")
        .arg(repo().join("scripts/ensure-cesium.sh"))
        .status()
        .expect("running scripts/ensure-cesium.sh");
    assert!(status.success(), "scripts/ensure-cesium.sh failed");
}

#[test]
fn a_local_tileset_loads_in_cesium_where_pointlet_renders_the_store() {
    ensure_cesium();
    let dir = tempfile::tempdir().unwrap();
    let store = autzen_store(dir.path());
    let out = dir.path().join("autzen-tiles");
    ok(&[
        "export-3dtiles",
        s(&store),
        "-o",
        s(&out),
        "--points-per-tile",
        "20K",
    ]);
    // A local tileset: its root transform is a translation, world coordinates are the store's.
    let frame = Frame::of(&out);
    assert_eq!(frame.metres_per_unit, [1.0; 3]);
    let o = frame.origin;
    compare_with_cesium(
        &store,
        &out,
        [o[0] - 400.0, o[1] - 1300.0, o[2] + 900.0],
        o,
        dir.path(),
    );
}

#[test]
fn an_ecef_tileset_loads_in_cesium_where_pointlet_renders_the_store() {
    ensure_cesium();
    let dir = tempfile::tempdir().unwrap();
    // Generated scenes are in UTM zone 11N (EPSG:32611): the tileset is placed in ECEF.
    let store = dir.path().join("scene.pointlet");
    ok(&["generate", "--points", "300K", "-o", s(&store)]);
    let out = dir.path().join("scene-tiles");
    let err = ok_stderr(&[
        "export-3dtiles",
        s(&store),
        "-o",
        s(&out),
        "--points-per-tile",
        "20K",
    ]);
    assert!(err.contains("placed in ECEF from EPSG:32611"), "{err}");
    let frame = Frame::of(&out);
    let radius = (0..3)
        .map(|i| frame.matrix[12 + i].powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        (6.35e6..6.40e6).contains(&radius),
        "root frame {radius} m from the Earth's centre"
    );
    let o = frame.origin;
    compare_with_cesium(
        &store,
        &out,
        [o[0] - 60.0, o[1] - 200.0, o[2] + 180.0],
        o,
        dir.path(),
    );
}

/// Large pointlets and small tiles: the root's rate takes under one point of each pointlet,
/// which once left the root empty, every child estimated at zero points and made leaves of
/// whole octants (a 1 G-point store became 4 tiles of 250 M points).
#[test]
fn small_rates_of_large_pointlets_still_build_a_deep_tree() {
    let dir = tempfile::tempdir().expect("temp dir");
    let store = dir.path().join("g.pointlet");
    ok(&[
        "generate",
        "--points",
        "100K",
        "--pointlets",
        "300",
        "-o",
        store.to_str().expect("utf-8"),
    ]);
    let out = dir.path().join("tiles");
    let said = ok_stderr(&[
        "export-3dtiles",
        store.to_str().expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
        "--points-per-tile",
        "100",
    ]);
    let tiles: u64 = said
        .split("into ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no tile count in:\n{said}"));
    assert!(
        tiles > 300,
        "{tiles} tiles for 100 K points at 100 a tile:\n{said}"
    );
}
