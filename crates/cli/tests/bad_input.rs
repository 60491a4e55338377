//! Every bad-input case gets a clear message naming the file, exit code 1, no panic, and no
//! output left behind.

mod common;
use common::*;
use std::path::Path;

/// Converting `input` must fail with `needles` and leave the output folder as it was.
fn convert_fails(input: &Path, needles: &[&str]) {
    let out_dir = tempfile::tempdir().expect("tempdir");
    let out = out_dir.path().join("out.pointlet");
    let mut all = vec![input.file_name().and_then(|n| n.to_str()).unwrap_or("")];
    all.extend_from_slice(needles);
    fails(&["convert", s(input), "-o", s(&out)], &all);
    assert!(
        listing(out_dir.path()).is_empty(),
        "left behind: {:?}",
        listing(out_dir.path())
    );
}

fn patched(name: &str, dir: &Path, f: impl FnOnce(&mut Vec<u8>)) -> std::path::PathBuf {
    let mut bytes = std::fs::read(data(name)).expect("read test data");
    f(&mut bytes);
    let p = dir.join(format!("bad-{name}"));
    std::fs::write(&p, bytes).expect("write");
    p
}

#[test]
fn missing_file() {
    convert_fails(Path::new("/nonexistent/none.las"), &["none.las"]);
}

#[test]
fn truncated_las_and_laz() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, keep) in [
        ("simple.las", 20_000usize),
        ("simple.laz", 9_000),
        ("simple.las", 100),
    ] {
        let p = patched(name, dir.path(), |b| b.truncate(keep));
        convert_fails(&p, &[]);
    }
}

#[test]
fn header_claims_more_points_than_the_file_holds() {
    let dir = tempfile::tempdir().expect("tempdir");
    // LAS 1.2: legacy point count at byte 107.
    let p = patched("simple.las", dir.path(), |b| {
        b[107..111].copy_from_slice(&5000u32.to_le_bytes());
    });
    convert_fails(&p, &["5000"]);
}

#[test]
fn zero_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = patched("simple.las", dir.path(), |b| {
        b[107..111].copy_from_slice(&0u32.to_le_bytes());
        let start = u32::from_le_bytes([b[96], b[97], b[98], b[99]]) as usize;
        b.truncate(start);
    });
    convert_fails(&p, &["no points"]);
}

#[test]
fn scale_zero() {
    let dir = tempfile::tempdir().expect("tempdir");
    // x scale factor at byte 131.
    let p = patched("simple.las", dir.path(), |b| {
        b[131..139].copy_from_slice(&0f64.to_le_bytes());
    });
    convert_fails(&p, &["scale"]);
}

#[test]
fn unknown_point_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = patched("simple.las", dir.path(), |b| b[104] = 42);
    convert_fails(&p, &["42"]);
}

#[test]
fn nan_and_inf_coordinates() {
    let dir = tempfile::tempdir().expect("tempdir");
    let nan = dir.path().join("nan.xyz");
    std::fs::write(&nan, "1 2 3\n4 NaN 6\n").expect("write");
    convert_fails(&nan, &[]);
    let inf = dir.path().join("inf.ply");
    std::fs::write(
        &inf,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 inf 6\n",
    )
    .expect("write");
    convert_fails(&inf, &[]);
}

#[test]
fn out_of_range_coordinates() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("huge.xyz");
    std::fs::write(&p, "0 0 0\n1e300 0 0\n").expect("write");
    convert_fails(&p, &[]);
}

#[test]
fn garbage_and_folders_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let g = dir.path().join("garbage.las");
    std::fs::write(&g, b"this is not a point cloud at all, just text").expect("write");
    convert_fails(&g, &[]);
    let empty = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("o.pointlet");
    fails(
        &["convert", s(empty.path()), "-o", s(&out)],
        &["no supported"],
    );
}

#[test]
fn unwritable_output() {
    fails(
        &[
            "convert",
            s(&data("simple.las")),
            "-o",
            "/nonexistent-dir/out.pointlet",
        ],
        &["out.pointlet"],
    );
    fails(
        &["export", "/nonexistent/x.pointlet", "-o", "/tmp/x.las"],
        &["x.pointlet"],
    );
}

#[test]
fn output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let copy = dir.path().join("in.las");
    std::fs::copy(data("simple.las"), &copy).expect("copy");
    let before = std::fs::read(&copy).expect("read");
    fails(&["convert", s(&copy), "-o", s(&copy)], &["in.las"]);
    assert_eq!(
        std::fs::read(&copy).expect("read"),
        before,
        "input modified"
    );
}

#[test]
fn full_disk_leaves_nothing_behind() {
    // A file-size limit makes writes fail like a full disk (EFBIG); SIGXFSZ is ignored so the
    // process sees the error instead of being killed.
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("full.pointlet");
    let cmd = format!(
        "ulimit -f 64; trap '' XFSZ; exec '{}' convert '{}' -o '{}'",
        env!("CARGO_BIN_EXE_pointlet"),
        s(&data("autzen_trim.laz")),
        s(&out)
    );
    let o = std::process::Command::new("bash")
        .arg("-c")
        .arg(&cmd)
        .output()
        .expect("bash");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: ") && !err.contains("panicked"),
        "{err}"
    );
    assert!(
        listing(dir.path()).is_empty(),
        "left behind: {:?}",
        listing(dir.path())
    );
}

#[test]
fn damaged_store_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("a.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    let bytes = std::fs::read(&store).expect("read");
    let cut = dir.path().join("cut.pointlet");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write");
    fails(&["info", s(&cut)], &["cut.pointlet"]);
    let mut flipped = bytes.clone();
    let at = bytes.len() - 100;
    flipped[at] ^= 0xff;
    let fl = dir.path().join("flip.pointlet");
    std::fs::write(&fl, &flipped).expect("write");
    fails(&["info", s(&fl), "--verify"], &["flip.pointlet"]);
    fails(
        &["export", s(&fl), "-o", s(&dir.path().join("x.las"))],
        &["flip.pointlet"],
    );
    assert!(!dir.path().join("x.las").exists());
}

#[test]
fn bad_arguments() {
    fails(
        &["generate", "--points", "0", "-o", "/tmp/x.las"],
        &["points"],
    );
    fails(
        &["generate", "--points", "10", "-o", "/tmp/x.txt"],
        &["unknown output"],
    );
    let out = pointlet(&[
        "convert",
        s(&data("simple.las")),
        "-o",
        "/tmp/x.pointlet",
        "--ram-budget",
        "lots",
    ]);
    assert_eq!(out.status.code(), Some(2), "usage errors exit with 2");
}

#[test]
fn error_chains_say_each_fact_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = dir.path().join("none.las");
    let missing_store = dir.path().join("none.pointlet");
    let folder = dir.path().join("folder.las");
    std::fs::create_dir(&folder).expect("mkdir");
    let garbage = dir.path().join("garbage.pointlet");
    std::fs::write(&garbage, b"not a store").expect("write");
    let png = dir.path().join("x.png");
    let out = dir.path().join("o.pointlet");
    let las = dir.path().join("o.las");
    for input in [&missing, &missing_store, &folder, &garbage] {
        let i = s(input);
        let name = input.file_name().and_then(|n| n.to_str()).expect("name");
        let commands: [&[&str]; 6] = [
            &["info", i],
            &["convert", i, "-o", s(&out)],
            &["render", i, "-o", s(&png)],
            &["metrics", i],
            &["export", i, "-o", s(&las)],
            &["bench-read", i],
        ];
        for args in commands {
            let err = fails(args, &[name]);
            let line = err.lines().next().unwrap_or("");
            assert_eq!(
                line.matches(name).count(),
                1,
                "{args:?}: the path once: {line}"
            );
            assert!(line.matches("(os error").count() <= 1, "{args:?}: {line}");
            for part in line.split(": ").filter(|p| p.len() > 8) {
                assert_eq!(
                    line.matches(part).count(),
                    1,
                    "{args:?}: '{part}' repeated: {line}"
                );
            }
        }
    }
    assert!(listing(dir.path())
        .iter()
        .all(|f| f != "x.png" && f != "o.las" && f != "o.pointlet"));
}

#[test]
fn a_bad_flag_value_is_named_once() {
    for (args, value) in [
        (
            &["export", "x.pointlet", "-o", "x.las", "--bbox", "1,2,3"][..],
            "1,2,3",
        ),
        (&["render", "-o", "x.png", "--eye", "1,2"][..], "1,2"),
        (&["render", "-o", "x.png", "--background", "zz"][..], "zz"),
        (&["render", "-o", "x.png", "--raster", "fast"][..], "fast"),
        (&["generate", "--points", "abc", "-o", "x.las"][..], "abc"),
        (
            &["convert", "x.las", "-o", "x.pointlet", "--scale", "0"][..],
            "'0'",
        ),
    ] {
        let out = pointlet(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}:\n{err}");
        assert_eq!(err.matches(value).count(), 1, "{args:?}:\n{err}");
    }
}

#[test]
fn an_image_too_large_is_refused_for_its_size_on_stores_and_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    let png = dir.path().join("x.png");
    for input in [s(&store), s(&data("simple.las"))] {
        fails(
            &[
                "render",
                input,
                "-o",
                s(&png),
                "--width",
                "100000",
                "--height",
                "100000",
                "--color",
                "rgb",
            ],
            &["image size 100000×100000", "pixels per side"],
        );
        assert!(!png.exists());
    }
}
