//! PLY (ascii and both binaries) and text readers on small files written here; `open`'s
//! choice of reader; `list_inputs` and `open_inputs` on folders.

mod common;
use common::*;
use pointlet_core::PointBatch;
use std::path::Path;

fn read(path: &Path) -> (pointlet_core::SourceMeta, PointBatch) {
    let mut r = pointlet_io::open(path).unwrap_or_else(|e| panic!("{e}"));
    let meta = r.meta().clone();
    let b = read_all(r.as_mut(), 2);
    assert_eq!(b.len() as u64, meta.point_count);
    (meta, b)
}

fn bounds_of(b: &PointBatch) -> pointlet_core::Aabb {
    let mut a = pointlet_core::Aabb::EMPTY;
    b.xyz.iter().for_each(|p| a.grow(*p));
    a
}

#[test]
fn xyz_without_names_by_column_count() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("a.xyz");
    std::fs::write(&p, "# a comment\n\n1 2 3\r\n4.5\t5 -6\n").expect("write");
    let (m, b) = read(&p);
    assert_eq!(b.xyz, vec![[1.0, 2.0, 3.0], [4.5, 5.0, -6.0]]);
    assert!(!m.layout.rgb && m.las_point_format.is_none());
    assert_eq!(
        m.quantization.map(|q| q.scale),
        Some([0.1, 1.0, 1.0]),
        "decimals written"
    );
    assert_eq!(m.bounds, bounds_of(&b));
    assert_eq!(b.returns, vec![0x11, 0x11], "one return of one");
    assert_eq!(b.intensity, vec![0, 0]);

    let p = dir.path().join("b.txt");
    std::fs::write(&p, "1;2;3;100\n4;5;6;200\n").expect("write");
    let (_, b) = read(&p);
    assert_eq!(b.intensity, vec![100, 200]);

    let p = dir.path().join("c.xyz");
    std::fs::write(&p, "1 2 3 0 128 255\n4 5 6 10 20 30\n").expect("write");
    let (m, b) = read(&p);
    assert!(m.layout.rgb);
    assert_eq!(
        b.rgb,
        vec![[0, 128 * 257, 65535], [2570, 5140, 7710]],
        "8-bit ×257"
    );

    let p = dir.path().join("d.xyz");
    std::fs::write(&p, "1 2 3 0 128 1000\n4 5 6 20 30 40\n").expect("write");
    let (_, b) = read(&p);
    assert_eq!(
        b.rgb,
        vec![[0, 128, 1000], [20, 30, 40]],
        "kept: a value exceeds 255"
    );
}

#[test]
fn csv_with_named_columns_in_any_order() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("a.csv");
    std::fs::write(
        &p,
        "id, Z, Y, X, Intensity, red, green, blue\n1, 3, 2, 1, 0.5, 255, 0, 10\n2, 6, 5, 4, 1, 0, 255, 20\n",
    )
    .expect("write");
    let (m, b) = read(&p);
    assert_eq!(b.xyz, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(
        b.intensity,
        vec![32768, 65535],
        "fractions in 0–1 scale to 16 bits"
    );
    assert_eq!(b.rgb, vec![[65535, 0, 2570], [0, 65535, 5140]]);
    assert!(m.format.contains("comma"));
    let p = dir.path().join("b.csv");
    std::fs::write(&p, "a,b,c\n1,2,3\n").expect("write");
    let e = pointlet_io::open(&p).err().expect("no x/y/z").to_string();
    assert!(e.contains("b.csv") && e.contains("line 1"), "{e}");
}

#[test]
fn pts_with_count_line_and_signed_intensity() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("a.pts");
    std::fs::write(&p, "2\n1 2 3 -2048 10 20 30\n4 5 6 2047 40 50 60\n").expect("write");
    let (_, b) = read(&p);
    assert_eq!(b.len(), 2);
    assert_eq!(b.intensity, vec![0, 4095], "shifted to start at 0");
    assert_eq!(b.rgb[1], [40 * 257, 50 * 257, 60 * 257]);
}

/// The same three vertices in all three encodings, with elements before and after the
/// vertices (lists included) and properties to skip.
fn ply_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let head = |fmt: &str| {
        format!(
            "ply\nformat {fmt} 1.0\ncomment made by a test\nelement camera 1\nproperty float fov\nproperty list uchar int ids\nelement vertex 3\nproperty double x\nproperty float y\nproperty int z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float nx\nproperty float intensity\nproperty list uchar float extra\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    // x (double), y (float), z (int), colour, nx, intensity, list.
    type Vertex = (f64, f32, i32, [u8; 3], f32, f32, Vec<f32>);
    let verts: [Vertex; 3] = [
        (1.5, 2.0, -3, [255, 0, 1], 0.1, 0.25, vec![]),
        (4.0, -5.5, 6, [2, 128, 3], 0.2, 1.0, vec![9.0, 8.0]),
        (1e6, 0.0, 0, [0, 0, 0], 0.3, 0.0, vec![7.0]),
    ];
    let mut ascii = head("ascii");
    ascii += "0.7 3 1 2 3\n";
    for (x, y, z, c, nx, i, l) in &verts {
        ascii += &format!(
            "{x} {y} {z} {} {} {} {nx} {i} {}",
            c[0],
            c[1],
            c[2],
            l.len()
        );
        for v in l {
            ascii += &format!(" {v}");
        }
        ascii += "\n";
    }
    ascii += "3 0 1 2\n";
    let mut out = vec![dir.join("a.ply")];
    std::fs::write(&out[0], ascii).expect("write");
    for (name, le) in [("le.ply", true), ("be.ply", false)] {
        let mut bytes = head(if le {
            "binary_little_endian"
        } else {
            "binary_big_endian"
        })
        .into_bytes();
        macro_rules! put {
            ($v:expr) => {
                if le {
                    bytes.extend_from_slice(&$v.to_le_bytes())
                } else {
                    bytes.extend_from_slice(&$v.to_be_bytes())
                }
            };
        }
        put!(0.7f32);
        bytes.push(3);
        for i in 1..=3i32 {
            put!(i);
        }
        for (x, y, z, c, nx, i, l) in &verts {
            put!(*x);
            put!(*y);
            put!(*z);
            bytes.extend_from_slice(c);
            put!(*nx);
            put!(*i);
            bytes.push(l.len() as u8);
            for v in l {
                put!(*v);
            }
        }
        bytes.push(3);
        for i in 0..3i32 {
            put!(i);
        }
        let p = dir.join(name);
        std::fs::write(&p, bytes).expect("write");
        out.push(p);
    }
    out
}

#[test]
fn ply_in_all_encodings_reads_the_same_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let files = ply_files(dir.path());
    let (m0, b0) = read(&files[0]);
    assert!(m0.format.contains("ascii"));
    assert_eq!(
        b0.xyz,
        vec![[1.5, 2.0, -3.0], [4.0, -5.5, 6.0], [1e6, 0.0, 0.0]]
    );
    assert_eq!(
        b0.rgb,
        vec![[65535, 0, 257], [514, 128 * 257, 771], [0, 0, 0]]
    );
    assert_eq!(
        b0.intensity,
        vec![16384, 65535, 0],
        "float intensity within 0–1"
    );
    assert_eq!(m0.bounds, bounds_of(&b0));
    for f in &files[1..] {
        let (m, b) = read(f);
        assert!(b == b0, "{}", f.display());
        assert_eq!(m.bounds, m0.bounds);
        assert_eq!(m.point_count, 3);
    }
}

#[test]
fn ply_ushort_colour_is_kept() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("c.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty ushort red\nproperty ushort green\nproperty ushort blue\nproperty uchar intensity\nend_header\n1 2 3 1000 2000 65535 200\n",
    )
    .expect("write");
    let (_, b) = read(&p);
    assert_eq!(b.rgb, vec![[1000, 2000, 65535]]);
    assert_eq!(b.intensity, vec![200]);
}

#[test]
fn open_picks_the_reader_by_content_first() {
    let dir = tempfile::tempdir().expect("tempdir");
    let odd = dir.path().join("las-in-disguise.xyz");
    std::fs::copy(data("simple.las"), &odd).expect("copy");
    assert!(pointlet_io::open(&odd)
        .expect("open")
        .meta()
        .format
        .starts_with("LAS 1.2"));
    let noext = dir.path().join("cloud");
    std::fs::write(
        &noext,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
    )
    .expect("write");
    assert!(pointlet_io::open(&noext)
        .expect("open")
        .meta()
        .format
        .starts_with("PLY"));
    let upper = dir.path().join("UPPER.LAZ");
    std::fs::copy(data("simple.laz"), &upper).expect("copy");
    assert_eq!(
        pointlet_io::open(&upper).expect("open").meta().point_count,
        1065
    );
}

#[test]
fn folders_expand_recursively_and_sorted() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path();
    std::fs::create_dir_all(root.join("b/deeper")).expect("mkdir");
    std::fs::create_dir_all(root.join("a")).expect("mkdir");
    for f in [
        "z.las",
        "b/deeper/x.copc.laz",
        "b/y.PLY",
        "a/notes.md",
        "a/w.csv",
        "a/v.pts",
        "m.txt",
        "n.bin",
    ] {
        std::fs::write(root.join(f), b"").expect("write");
    }
    let explicit = root.join("n.bin");
    let (got, skipped) =
        pointlet_io::list_inputs(&[explicit.clone(), root.to_path_buf()]).expect("expand");
    let rel: Vec<String> = got
        .iter()
        .map(|f| {
            let p = &f.path;
            p.strip_prefix(root)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(
        rel,
        vec![
            "n.bin",
            "a/v.pts",
            "a/w.csv",
            "b/deeper/x.copc.laz",
            "b/y.PLY",
            "m.txt",
            "z.las"
        ],
        "explicit files as given, then the folder's supported files in path order"
    );
    assert!(!got[0].in_folder && got[1..].iter().all(|f| f.in_folder));
    let skipped: Vec<_> = skipped.iter().map(|s| s.path.clone()).collect();
    assert_eq!(
        skipped,
        vec![root.join("a/notes.md"), root.join("n.bin")],
        "the folder's other files"
    );
}

fn read_with(path: &Path, columns: &str) -> (pointlet_core::SourceMeta, PointBatch, Vec<String>) {
    let options = pointlet_io::ReadOptions {
        columns: Some(columns.split(',').map(String::from).collect()),
    };
    let mut r = pointlet_io::open_with(path, &options).unwrap_or_else(|e| panic!("{e}"));
    let meta = r.meta().clone();
    let notes = r.notes().to_vec();
    let b = read_all(r.as_mut(), 3);
    (meta, b, notes)
}

#[test]
fn named_columns_feed_every_attribute_they_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("a.csv");
    std::fs::write(
        &p,
        "X;Y;Z;Class;Return_Number;number of returns;GPS_Time;Point_Source_ID;user_data;\
         Scan_Angle;NIR;nx;scalar_Intensity;colour_index\n\
         1;2;3;2;1;2;100.25;7;9;-12.5;65535;0.1;300;5\n\
         4;5;6;6;2;2;100.5;8;0;3;0;0.2;400;6\n",
    )
    .expect("write");
    let mut r = pointlet_io::open(&p).unwrap_or_else(|e| panic!("{e}"));
    let notes = r.notes().to_vec();
    let m = r.meta().clone();
    let b = read_all(r.as_mut(), 2);
    assert_eq!(b.xyz, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(b.classification, vec![2, 6]);
    assert_eq!(b.returns, vec![0x21, 0x22], "return 1 of 2, return 2 of 2");
    assert!(m.layout.gps_time && m.layout.nir && !m.layout.rgb);
    assert_eq!(b.gps_time, vec![100.25, 100.5]);
    assert_eq!(b.point_source_id, vec![7, 8]);
    assert_eq!(b.user_data, vec![9, 0]);
    assert_eq!(b.scan_angle, vec![-12.5, 3.0]);
    assert_eq!(b.nir, vec![65535, 0]);
    assert_eq!(b.intensity, vec![300, 400]);
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(notes[0].contains("'nx'") && notes[1].contains("'colour_index'"));

    let p = dir.path().join("b.csv");
    std::fs::write(&p, "x,y,z,classification\n1,2,3,2.5\n").expect("write");
    let e = pointlet_io::open(&p)
        .err()
        .expect("fractional class")
        .to_string();
    assert!(e.contains("b.csv") && e.contains("line 2") && e.contains("classification"));
}

#[test]
fn seven_unnamed_columns_are_refused_and_columns_names_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("rgbi.xyz");
    // x y z r g b intensity: the old reading took 255 as intensity and 25700 as blue.
    std::fs::write(&p, "1 2 3 255 128 0 100\n4 5 6 0 10 20 30000\n").expect("write");
    let e = pointlet_io::open(&p).err().expect("ambiguous").to_string();
    assert!(
        e.contains("rgbi.xyz") && e.contains("7 unnamed columns") && e.contains("--columns"),
        "{e}"
    );
    let (m, b, notes) = read_with(&p, "x,y,z,r,g,b,intensity");
    assert!(m.layout.rgb && notes.is_empty());
    assert_eq!(b.rgb, vec![[65535, 128 * 257, 0], [0, 2570, 5140]]);
    assert_eq!(b.intensity, vec![100, 30000]);
    let (_, b, _) = read_with(&p, "X,Y,Z,_,_,Class,_");
    assert_eq!(b.classification, vec![0, 20], "_ skips a column");
    for bad in [
        "x,y,z,r,g,b",
        "x,y,z,r,g,b,intensity,class",
        "x,y,z,r,g,b,colour",
    ] {
        let options = pointlet_io::ReadOptions {
            columns: Some(bad.split(',').map(String::from).collect()),
        };
        let e = pointlet_io::open_with(&p, &options)
            .err()
            .unwrap_or_else(|| panic!("--columns {bad}"))
            .to_string();
        assert!(e.contains("rgbi.xyz"), "{e}");
    }
    // .pts defines its seven columns: x y z intensity r g b.
    let pts = dir.path().join("a.pts");
    std::fs::copy(&p, &pts).expect("copy");
    let (_, b) = read(&pts);
    assert_eq!(b.intensity, vec![255, 0]);
}

#[test]
fn cloudcompare_header_names_the_columns() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("cc.txt");
    std::fs::write(
        &p,
        "//X,Y,Z,Rf,Gf,Bf,Intensity\n1.5,2,3,1,0.5,0,200\n4,5,6,0,0,1,100\n",
    )
    .expect("write");
    let (m, b) = read(&p);
    assert!(m.layout.rgb);
    assert_eq!(b.xyz, vec![[1.5, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(
        b.rgb,
        vec![[65535, 32768, 0], [0, 0, 65535]],
        "rf gf bf are 0–1"
    );
    assert_eq!(b.intensity, vec![200, 100]);
}

#[test]
fn folders_skip_what_is_not_a_point_cloud() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path();
    std::fs::write(root.join("a.xyz"), "1 2 3\n4 5 6\n").expect("write");
    std::fs::write(root.join("readme.txt"), "Tiles of the 2024 survey.\n").expect("write");
    std::fs::write(root.join("empty.xyz"), "# no points here\n").expect("write");
    std::fs::write(root.join("notes.md"), "hello").expect("write");
    std::fs::write(
        root.join("empty.ply"),
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
    )
    .expect("write");
    // A LAS tile whose header says it holds no points (legacy count at byte 107, by return).
    let mut las = std::fs::read(data("simple.las")).expect("read");
    las[107..131].fill(0);
    std::fs::write(root.join("zero.las"), las).expect("write");
    let pointlet_io::Inputs { readers, skipped } =
        pointlet_io::open_inputs(&[root.to_path_buf()], &Default::default()).expect("open");
    assert_eq!(readers.len(), 1);
    assert_eq!(readers[0].path(), root.join("a.xyz"));
    let mut names: Vec<String> = skipped
        .iter()
        .map(|s| s.path.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        vec![
            "empty.ply",
            "empty.xyz",
            "notes.md",
            "readme.txt",
            "zero.las"
        ]
    );
    assert!(skipped.iter().all(|s| !s.reason.is_empty()));
    // Named on their own, the same files are errors.
    for f in ["readme.txt", "empty.xyz", "zero.las"] {
        let Err(e) = pointlet_io::open_inputs(&[root.join(f)], &Default::default()) else {
            panic!("{f} alone");
        };
        assert!(e.to_string().contains(f), "{e}");
    }
    // A broken point file in a folder still fails the merge.
    std::fs::write(root.join("b.xyz"), "1 2 3\n4 5 nan\n").expect("write");
    assert!(pointlet_io::open_inputs(&[root.to_path_buf()], &Default::default()).is_err());
}

/// Deterministic coordinates in [0, 0.005): a 5 mm object.
fn small_object(n: usize) -> Vec<[f64; 3]> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 0.005
    };
    (0..n).map(|_| [next(), next(), next()]).collect()
}

#[test]
fn scale_follows_the_precision_of_the_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let pts = small_object(100);
    let bin = |name: &str, ty: &str, put: &dyn Fn(&mut Vec<u8>, f64)| {
        let mut bytes = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\nend_header\n",
            pts.len()
        )
        .into_bytes();
        for p in &pts {
            p.iter().for_each(|c| put(&mut bytes, *c));
        }
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        read(&path).0.quantization.expect("quantization")
    };
    let q = bin("f.ply", "float", &|b, c| {
        b.extend_from_slice(&(c as f32).to_le_bytes())
    });
    assert_eq!(q.scale, [1e-10; 3], "f32 spacing near 0.005 is 4.7e-10");
    let q = bin("d.ply", "double", &|b, c| {
        b.extend_from_slice(&c.to_le_bytes())
    });
    assert_eq!(q.scale, [1e-11; 3], "the finest step 0.005 fits in 32 bits");
    let p = dir.path().join("a.xyz");
    std::fs::write(&p, "1.25 100.5 3\n1.125 -200.25 4.5e-3\n").expect("write");
    let q = read(&p).0.quantization.expect("quantization");
    assert_eq!(q.scale, [0.001, 0.01, 0.0001], "decimals written, per axis");
    for (i, v) in [1.25, 100.5, 3.0].iter().enumerate() {
        let raw = ((v - q.offset[i]) / q.scale[i]).round();
        assert!(
            (raw * q.scale[i] + q.offset[i] - v).abs() < 1e-9,
            "on the grid"
        );
    }
}
