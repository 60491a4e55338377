//! Bad input: every case is a clear error naming the file, never a panic or a hang.

mod common;
use common::*;
use pointlet_io::IoError;
use std::path::{Path, PathBuf};

/// Opens and reads everything; the first error, if any.
fn read_fully(path: &Path) -> Result<u64, IoError> {
    let mut r = pointlet_io::open(path)?;
    let mut n = 0;
    while let Some(b) = r.read_batch(100_000)? {
        n += b.len() as u64;
    }
    Ok(n)
}

/// `path` must fail with a message naming the file and containing every needle.
fn fails(path: &Path, needles: &[&str]) -> String {
    let e = read_fully(path)
        .expect_err("bad input must be an error")
        .to_string();
    let file = path.file_name().and_then(|n| n.to_str()).expect("name");
    assert!(e.contains(file), "message lacks the file name: {e}");
    for n in needles {
        assert!(
            e.to_lowercase().contains(&n.to_lowercase()),
            "message lacks '{n}': {e}"
        );
    }
    e
}

fn patched(name: &str, dir: &Path, tag: &str, f: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(data(name)).expect("read test data");
    f(&mut bytes);
    let p = dir.join(format!("{tag}-{name}"));
    std::fs::write(&p, bytes).expect("write");
    p
}

#[test]
fn missing_file() {
    let e = fails(Path::new("/nonexistent/none.las"), &[]);
    assert!(e.contains("/nonexistent/none.las"), "{e}");
}

#[test]
fn truncated_las_at_many_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let len = std::fs::metadata(data("simple.las")).expect("meta").len() as usize;
    for keep in [
        0,
        3,
        4,
        100,
        226,
        227,
        228,
        5_000,
        20_000,
        len - 34,
        len - 1,
    ] {
        let p = patched("simple.las", dir.path(), &format!("cut{keep}"), |b| {
            b.truncate(keep)
        });
        fails(&p, &[]);
    }
    // LAS 1.4 with an EVLR after the points, cut inside the EVLR.
    let len = std::fs::metadata(data("simple1_4.las"))
        .expect("meta")
        .len() as usize;
    let p = patched("simple1_4.las", dir.path(), "cut", |b| b.truncate(len - 10));
    fails(&p, &["EVLR"]);
}

#[test]
fn truncated_laz_and_copc() {
    let dir = tempfile::tempdir().expect("tempdir");
    for name in [
        "simple.laz",
        "autzen_trim.laz",
        "simple.copc.laz",
        "plane.laz",
    ] {
        let len = std::fs::metadata(data(name)).expect("meta").len() as usize;
        for keep in [400, 2_500, 9_000, len / 2, len - 9, len - 1] {
            if keep >= len {
                continue;
            }
            let p = patched(name, dir.path(), &format!("cut{keep}"), |b| {
                b.truncate(keep)
            });
            fails(&p, &[]);
        }
    }
}

#[test]
fn header_claims_more_points_than_the_file_holds() {
    let dir = tempfile::tempdir().expect("tempdir");
    // LAS 1.2: legacy point count at byte 107.
    let p = patched("simple.las", dir.path(), "lying", |b| {
        b[107..111].copy_from_slice(&5000u32.to_le_bytes());
    });
    let e = fails(&p, &["5000", "1065"]);
    assert!(
        e.contains("header claims 5000 points but the file holds 1065"),
        "{e}"
    );
    // LAS 1.4: the 64-bit count at byte 247, claiming far more than memory could hold.
    let p = patched("test1_4.las", dir.path(), "lying", |b| {
        b[247..255].copy_from_slice(&1_000_000_000_000u64.to_le_bytes());
    });
    fails(&p, &["1000000000000"]);
    // LAZ: more points than the chunks hold, with one chunk (decompression runs dry) and
    // beyond what the chunk table allows.
    for claimed in [5_000u32, 2_000_000] {
        let p = patched("simple.laz", dir.path(), &format!("lying{claimed}"), |b| {
            b[107..111].copy_from_slice(&claimed.to_le_bytes());
        });
        fails(&p, &[&claimed.to_string()]);
    }
    // COPC: variable chunks list their point counts.
    let p = patched("simple.copc.laz", dir.path(), "lying", |b| {
        b[247..255].copy_from_slice(&5000u64.to_le_bytes());
    });
    fails(&p, &["5000", "1065"]);
}

#[test]
fn zero_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = patched("simple.las", dir.path(), "zero", |b| {
        b[107..111].copy_from_slice(&0u32.to_le_bytes());
        let start = u32::from_le_bytes([b[96], b[97], b[98], b[99]]) as usize;
        b.truncate(start);
    });
    fails(&p, &["no points"]);
}

#[test]
fn bad_scales_offsets_and_bounds() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (tag, at, v) in [
        ("scale0", 131, 0.0),
        ("scaleneg", 139, -0.01),
        ("scalenan", 147, f64::NAN),
        ("scaleinf", 131, f64::INFINITY),
    ] {
        let p = patched("simple.las", dir.path(), tag, |b| {
            b[at..at + 8].copy_from_slice(&v.to_le_bytes());
        });
        fails(&p, &["scale"]);
    }
    let p = patched("simple.las", dir.path(), "offset", |b| {
        b[163..171].copy_from_slice(&f64::NAN.to_le_bytes());
    });
    fails(&p, &["offset"]);
    let p = patched("simple.las", dir.path(), "bounds", |b| {
        b[179..187].copy_from_slice(&f64::INFINITY.to_le_bytes());
    });
    fails(&p, &["bounds"]);
}

#[test]
fn bad_formats_lengths_and_offsets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = patched("simple.las", dir.path(), "f42", |b| b[104] = 42);
    fails(&p, &["42"]);
    let p = patched("simple.las", dir.path(), "reclen", |b| {
        b[105..107].copy_from_slice(&20u16.to_le_bytes());
    });
    fails(&p, &["record length 20"]);
    let p = patched("simple.las", dir.path(), "offset", |b| {
        b[96..100].copy_from_slice(&1_000_000u32.to_le_bytes());
    });
    fails(&p, &["offset to point data"]);
    let p = patched("simple.las", dir.path(), "hsize", |b| {
        b[94..96].copy_from_slice(&100u16.to_le_bytes());
    });
    fails(&p, &["header size"]);
    let p = patched("simple.las", dir.path(), "version", |b| b[24] = 2);
    fails(&p, &["version"]);
    // A VLR count the space before the points cannot hold.
    let p = patched("extrabytes.las", dir.path(), "vlrs", |b| {
        b[100..104].copy_from_slice(&7u32.to_le_bytes());
    });
    fails(&p, &["VLR"]);
}

#[test]
fn garbage_and_unknown_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let g = dir.path().join("garbage.las");
    std::fs::write(&g, b"this is not a point cloud at all, just text").expect("write");
    fails(&g, &["LASF"]);
    let u = dir.path().join("points.bin");
    std::fs::write(&u, [0u8; 64]).expect("write");
    fails(&u, &["unknown"]);
    let empty = dir.path().join("empty.laz");
    std::fs::write(&empty, b"").expect("write");
    fails(&empty, &[]);
    fails(dir.path(), &["folder"]);
    // A FIFO would block the reader forever: refused before opening.
    let fifo = dir.path().join("pipe.xyz");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(made.success());
    fails(&fifo, &["regular file"]);
}

#[test]
fn damaged_laz_items_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let laszip_at = |b: &[u8]| {
        // simple.laz: the LASzip VLR is the only VLR, right after the 227-byte header.
        assert_eq!(&b[227 + 2..227 + 16], b"laszip encoded");
        227 + 54
    };
    // Item 0 (Point10) declared with a wrong size.
    let p = patched("simple.laz", dir.path(), "itemsize", |b| {
        let at = laszip_at(b) + 34 + 2;
        b[at..at + 2].copy_from_slice(&5u16.to_le_bytes());
    });
    fails(&p, &["LASzip"]);
    // The header's point format no longer matches the items.
    let p = patched("simple.laz", dir.path(), "itemfmt", |b| b[104] = 0x80 | 1);
    fails(&p, &["LASzip"]);
}

#[test]
fn nan_in_text_and_ply() {
    let dir = tempfile::tempdir().expect("tempdir");
    let nan = dir.path().join("nan.xyz");
    std::fs::write(&nan, "1 2 3\n4 NaN 6\n").expect("write");
    fails(&nan, &["line 2"]);
    let inf = dir.path().join("inf.csv");
    std::fs::write(&inf, "x,y,z\n1,2,3\n4,5,inf\n").expect("write");
    fails(&inf, &["line 3"]);
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "1 2 3\n4 5 six\n").expect("write");
    fails(&bad, &["line 2", "six"]);
    let short = dir.path().join("short.xyz");
    std::fs::write(&short, "1 2 3\n4 5\n").expect("write");
    fails(&short, &["line 2"]);
    let ply = dir.path().join("inf.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 inf 6\n",
    )
    .expect("write");
    fails(&ply, &["vertex 1"]);
    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n".to_vec();
    for v in [1.0f64, 2.0, 3.0, 4.0, 5.0, f64::NAN] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    let binp = dir.path().join("nan.ply");
    std::fs::write(&binp, &bin).expect("write");
    fails(&binp, &["vertex 1", "z"]);
}

#[test]
fn ply_header_lies_and_damage() {
    let dir = tempfile::tempdir().expect("tempdir");
    let head = "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    let mut bin = head.as_bytes().to_vec();
    bin.extend_from_slice(&[0u8; 12 * 10]);
    let p = dir.path().join("short.ply");
    std::fs::write(&p, &bin).expect("write");
    fails(&p, &["1000"]);
    let ascii = dir.path().join("short_ascii.ply");
    std::fs::write(
        &ascii,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
    )
    .expect("write");
    fails(&ascii, &["3"]);
    let noend = dir.path().join("noend.ply");
    std::fs::write(&noend, "ply\nformat ascii 1.0\nelement vertex 3\n").expect("write");
    fails(&noend, &["end_header"]);
    let noxyz = dir.path().join("noxyz.ply");
    std::fs::write(
        &noxyz,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
    )
    .expect("write");
    fails(&noxyz, &["x, y or z"]);
    let notply = dir.path().join("notply.ply");
    std::fs::write(&notply, "hello\n").expect("write");
    fails(&notply, &["PLY"]);
    // A face list claiming an absurd length before the vertices.
    let mut lists = b"ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint int vertex_indices\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    lists.extend_from_slice(&u32::MAX.to_le_bytes());
    let lp = dir.path().join("list.ply");
    std::fs::write(&lp, &lists).expect("write");
    fails(&lp, &["list"]);
}

#[test]
fn empty_text_file_and_empty_folder() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = dir.path().join("empty.xyz");
    std::fs::write(&t, "# only a comment\n\n").expect("write");
    fails(&t, &["no points"]);
    let empty = tempfile::tempdir().expect("tempdir");
    let (files, _) = pointlet_io::list_inputs(&[empty.path().to_path_buf()]).expect("expand");
    assert!(files.is_empty());
    let e = pointlet_io::list_inputs(&[PathBuf::from("/nonexistent/in.laz")])
        .expect_err("missing")
        .to_string();
    assert!(e.contains("in.laz"), "{e}");
}

/// Readers never hand out more than asked (nor more than their bounded maximum); asking for
/// none is not the end.
#[test]
fn batches_are_bounded() {
    let mut r = pointlet_io::open(&data("autzen_trim.laz")).expect("open");
    let b = r.read_batch(usize::MAX).expect("read").expect("batch");
    assert!(b.len() <= 110_000 && !b.is_empty());
    let mut r = pointlet_io::open(&data("simple.las")).expect("open");
    assert_eq!(r.read_batch(1).expect("read").expect("batch").len(), 1);
    assert!(r
        .read_batch(0)
        .expect("read")
        .expect("not the end")
        .is_empty());
}
