//! PLY and text inputs through the commands: the scale chosen from the data (and `--scale`),
//! `--columns`, and folders holding files that are not point clouds.

mod common;
use common::*;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// Deterministic points in [0, 0.005)³: a 5 mm scanned object.
fn small_object(n: usize) -> Vec<[f64; 3]> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 0.005
    };
    (0..n).map(|_| [next(), next(), next()]).collect()
}

fn ply_header(format: &str, ty: &str, n: usize) -> String {
    format!(
        "ply\nformat {format} 1.0\nelement vertex {n}\nproperty {ty} x\nproperty {ty} y\n\
         property {ty} z\nend_header\n"
    )
}

/// The object as binary float and double PLY, ascii PLY and XYZ.
fn object_files(dir: &Path, pts: &[[f64; 3]]) -> Vec<PathBuf> {
    let mut f32s = ply_header("binary_little_endian", "float", pts.len()).into_bytes();
    let mut f64s = ply_header("binary_little_endian", "double", pts.len()).into_bytes();
    let mut ascii = ply_header("ascii", "double", pts.len());
    let mut xyz = String::new();
    for p in pts {
        for c in p {
            f32s.extend_from_slice(&(*c as f32).to_le_bytes());
            f64s.extend_from_slice(&c.to_le_bytes());
        }
        let line = format!("{:.7} {:.7} {:.7}\n", p[0], p[1], p[2]);
        ascii += &line;
        xyz += &line;
    }
    let files = [
        ("f32.ply", f32s),
        ("f64.ply", f64s),
        ("ascii.ply", ascii.into_bytes()),
        ("object.xyz", xyz.into_bytes()),
    ];
    files
        .into_iter()
        .map(|(name, bytes)| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).expect("write");
            p
        })
        .collect()
}

/// Distinct positions of a LAS/LAZ file.
fn distinct_positions(path: &Path) -> (usize, Vec<[f64; 3]>) {
    let mut r = pointlet_io::open(path).expect("open export");
    let mut all = Vec::new();
    while let Some(b) = r.read_batch(1 << 16).expect("read") {
        all.extend_from_slice(&b.xyz);
    }
    let set: HashSet<[u64; 3]> = all.iter().map(|p| p.map(f64::to_bits)).collect();
    (set.len(), all)
}

fn json(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&ok(args)).expect("json")
}

fn scale_of(v: &serde_json::Value) -> Vec<f64> {
    v["scale"]
        .as_array()
        .expect("scale")
        .iter()
        .map(|s| s.as_f64().expect("number"))
        .collect()
}

#[test]
fn a_small_object_keeps_its_positions_through_convert_and_export() {
    let dir = tempfile::tempdir().expect("tempdir");
    let pts = small_object(5000);
    for input in object_files(dir.path(), &pts) {
        let store = dir.path().join("s.pointlet");
        let out = dir.path().join("e.las");
        ok(&["convert", s(&input), "-o", s(&store)]);
        ok(&["export", s(&store), "-o", s(&out)]);
        let (distinct, got) = distinct_positions(&out);
        assert_eq!(distinct, 5000, "{}: distinct positions", input.display());
        // Each exported point is within the input's own precision of an input point.
        let tolerance = if input.ends_with("f32.ply") {
            1e-9
        } else {
            1e-7
        };
        let near = got.iter().filter(|h| {
            pts.iter()
                .any(|w| (0..3).all(|i| (w[i] - h[i]).abs() <= tolerance))
        });
        assert_eq!(near.count(), 5000, "{}", input.display());
        // info says which scale was chosen, for the file and for the store.
        let file_scale = scale_of(&json(&["info", s(&input), "--json"]));
        let store_scale = scale_of(&json(&["info", s(&store), "--json"]));
        assert_eq!(file_scale, store_scale);
        assert!(
            file_scale.iter().all(|s| *s <= 1e-7),
            "{}: {file_scale:?}",
            input.display()
        );
        std::fs::remove_file(&store).expect("rm");
        std::fs::remove_file(&out).expect("rm");
    }
}

#[test]
fn scale_flag_sets_the_store_grid() {
    let dir = tempfile::tempdir().expect("tempdir");
    let files = object_files(dir.path(), &small_object(5000));
    let store = dir.path().join("s.pointlet");
    let out = dir.path().join("e.las");
    ok(&[
        "convert",
        s(&files[3]),
        "-o",
        s(&store),
        "--scale",
        "0.0001",
    ]);
    assert_eq!(
        scale_of(&json(&["info", s(&store), "--json"])),
        vec![0.0001; 3]
    );
    ok(&["export", s(&store), "-o", s(&out)]);
    let (distinct, got) = distinct_positions(&out);
    assert!(distinct < 5000 && distinct > 4000, "{distinct}");
    for p in &got {
        for c in p {
            let steps = c / 0.0001;
            assert!(
                (steps - steps.round()).abs() < 1e-6,
                "{c} is off the 0.1 mm grid"
            );
        }
    }
    // A step too fine for the extent is refused, naming the flag.
    std::fs::remove_file(&store).expect("rm");
    fails(
        &[
            "convert",
            s(&data("autzen_trim.laz")),
            "-o",
            s(&store),
            "--scale",
            "1e-9",
        ],
        &["--scale"],
    );
    assert!(!store.exists());
    let e = pointlet(&["convert", s(&files[3]), "-o", s(&store), "--scale", "0"]);
    assert_eq!(e.status.code(), Some(2), "a usage error");
}

#[test]
fn columns_flag_names_text_columns_in_every_command_that_reads_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("rgbi.xyz");
    std::fs::write(&p, "1 2 3 255 128 0 100\n4 5 6 0 10 20 30000\n").expect("write");
    let store = dir.path().join("s.pointlet");
    fails(
        &["convert", s(&p), "-o", s(&store)],
        &["rgbi.xyz", "--columns"],
    );
    fails(&["info", s(&p)], &["rgbi.xyz", "--columns"]);
    let columns = ["--columns", "x,y,z,r,g,b,intensity"];
    let v = json(&["info", s(&p), "--json", columns[0], columns[1]]);
    assert!(v["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .any(|a| a == "rgb"));
    ok(&["convert", s(&p), "-o", s(&store), columns[0], columns[1]]);
    ok(&["metrics", s(&p), columns[0], columns[1], "--pointlets", "1"]);
    // A usage error (exit 2), like every flag that does not apply to its input.
    let png = dir.path().join("r.png");
    for args in [
        vec!["info", s(&store)],
        vec!["view", s(&store)],
        vec!["metrics", s(&store)],
        vec!["render", s(&store), "-o", s(&png)],
    ] {
        let args = [&args[..], &columns[..]].concat();
        let out = pointlet(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}:\n{err}");
        assert!(
            err.starts_with("error: --columns applies to point files only, not to a store"),
            "{args:?}:\n{err}"
        );
    }
    assert!(!png.exists());
    // A header line naming attributes without a column: each skipped with a note.
    let named = dir.path().join("named.csv");
    std::fs::write(
        &named,
        "x,y,z,nx,ny,nz,class\n1,2,3,0,0,1,2\n4,5,6,0,1,0,6\n",
    )
    .expect("write");
    let out = pointlet(&["convert", s(&named), "-o", s(&store)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("note: ").count(), 3, "{err}");
    assert!(err.contains("'nx'") && err.contains("named.csv"), "{err}");
}

#[test]
fn folders_skip_files_that_are_not_point_clouds_with_a_note() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tiles = dir.path().join("tiles");
    std::fs::create_dir(&tiles).expect("mkdir");
    std::fs::write(tiles.join("a.xyz"), "1 2 3\n4 5 6\n").expect("write");
    std::fs::write(tiles.join("b.csv"), "x,y,z\n7,8,9\n").expect("write");
    std::fs::write(tiles.join("readme.txt"), "Survey tiles, EPSG:2994.\n").expect("write");
    std::fs::write(tiles.join("empty.xyz"), "").expect("write");
    std::fs::write(tiles.join("index.html"), "<html>").expect("write");
    let store = dir.path().join("s.pointlet");
    let out = pointlet(&["convert", s(&tiles), "-o", s(&store)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let notes: Vec<&str> = err.lines().filter(|l| l.starts_with("note: ")).collect();
    assert_eq!(notes.len(), 3, "{err}");
    for f in ["readme.txt", "empty.xyz", "index.html"] {
        assert!(
            notes.iter().any(|n| n.contains(f)),
            "no note for {f}:\n{err}"
        );
    }
    assert_eq!(json(&["info", s(&store), "--json"])["points"], 3);
    // The same file named on its own is an error.
    fails(
        &[
            "convert",
            s(&tiles.join("readme.txt")),
            "-o",
            s(&dir.path().join("r.pointlet")),
        ],
        &["readme.txt", "not a point file"],
    );
}
