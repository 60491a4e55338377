//! Point files drawn while they load (issue 11) through the commands: `render` writes the
//! converged image for LAS, LAZ, PLY and XYZ (the same picture as reading the file whole),
//! `bench` reports the loading figures, a file past the VRAM budget shows a subset and says
//! so, and flags that cannot apply are refused.

mod common;
use common::*;
use std::path::Path;

fn lit(rgba: &[u8]) -> usize {
    rgba.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

/// The points of simple.las written as ASCII PLY and XYZ (two decimals more than LAS's 0.01
/// grid, so positions are the same).
fn text_copies(dir: &Path) -> Vec<std::path::PathBuf> {
    let out = dir.join("simple.xyz");
    let mut reader = pointlet_io::open(&data("simple.las")).expect("open");
    let mut xyz = String::new();
    let mut n = 0;
    while let Some(b) = reader.read_batch(10_000).expect("read") {
        for p in &b.xyz {
            xyz += &format!("{:.4} {:.4} {:.4}\n", p[0], p[1], p[2]);
            n += 1;
        }
    }
    std::fs::write(&out, &xyz).expect("write xyz");
    let ply = dir.join("simple.ply");
    let header = format!(
        "ply\nformat ascii 1.0\nelement vertex {n}\nproperty double x\nproperty double y\n\
         property double z\nend_header\n"
    );
    std::fs::write(&ply, header + &xyz).expect("write ply");
    vec![out, ply]
}

#[test]
fn render_draws_every_kind_of_point_file_while_it_loads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut inputs = vec![
        data("simple.las"),
        data("simple.laz"),
        data("autzen_trim.laz"),
        data("simple.copc.laz"),
    ];
    inputs.extend(text_copies(dir.path()));
    for input in &inputs {
        let png = dir.path().join("p.png");
        let args = [
            "render",
            s(input),
            "-o",
            s(&png),
            "--width",
            "200",
            "--height",
            "120",
            "--color",
            "elevation",
        ];
        let err = ok_stderr(&args);
        assert!(err.contains("loaded in"), "{}: {err}", input.display());
        let progressive = png_rgba(&png);
        assert!(
            lit(&progressive) > 100,
            "{}: nothing drawn",
            input.display()
        );
        // The same view read whole and drawn at once (the blending-free 32-bit path is the
        // in-memory one; HQS would blend): the same pixels lit.
        let whole = dir.path().join("w.png");
        let mut whole_args = args.to_vec();
        whole_args[3] = s(&whole);
        whole_args.extend(["--raster", "atomic-min-32"]);
        ok(&whole_args);
        let whole = png_rgba(&whole);
        let lit_both = progressive
            .chunks_exact(4)
            .zip(whole.chunks_exact(4))
            .filter(|(a, b)| (a[..3] != [0; 3]) == (b[..3] != [0; 3]))
            .count();
        assert!(
            lit_both * 1000 >= 999 * 200 * 120,
            "{}: lit pixels differ from drawing the whole file",
            input.display()
        );
    }
}

#[test]
fn a_file_past_the_vram_budget_shows_a_subset_and_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("p.png");
    // autzen_trim.laz holds 110 000 points; 800 KiB holds 51 200 of them.
    let err = ok_stderr(&[
        "render",
        s(&data("autzen_trim.laz")),
        "-o",
        s(&png),
        "--width",
        "160",
        "--height",
        "100",
        "--vram-budget",
        "800KiB",
    ]);
    assert!(
        err.contains("showing a uniform subset of 51.2 k of its 110 k points")
            && err.contains("pointlet convert"),
        "{err}"
    );
    assert!(lit(&png_rgba(&png)) > 1000);
}

#[test]
fn bench_of_a_point_file_reports_loading_and_convergence() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json = dir.path().join("b.json");
    let out = ok(&[
        "bench",
        s(&data("autzen_trim.laz")),
        "--frames",
        "8",
        "--width",
        "160",
        "--height",
        "100",
        "--json",
        s(&json),
    ]);
    for needle in [
        "first frame after",
        "fully loaded after",
        "converged",
        "points/s",
        "after the first frame",
        "opening: passes",
        "GPU buffers",
        "waited",
    ] {
        assert!(out.contains(needle), "no '{needle}' in:\n{out}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    for key in [
        "first_frame_s",
        "loaded_s",
        "load_points_per_s",
        "load_mb_per_s",
        "converge_s",
        "share_drawn",
        "open_passes_s",
        "open_buffers_s",
        "staging_s",
        "queue_waited_s",
    ] {
        let x = v[key].as_f64().unwrap_or(-1.0);
        assert!(x.is_finite() && x >= 0.0, "{key} = {}", v[key]);
    }
    assert!(v["first_frame_s"].as_f64() <= v["loaded_s"].as_f64());
    // Opening is part of the time to the first frame; the buffer holds every point.
    let open = v["open_passes_s"].as_f64().unwrap_or(f64::NAN)
        + v["open_buffers_s"].as_f64().unwrap_or(f64::NAN);
    assert!(
        open > 0.0 && open <= v["first_frame_s"].as_f64().unwrap_or(0.0),
        "{open}"
    );
    assert!(
        v["gpu_bytes"].as_u64() >= Some(110_000 * 16),
        "{}",
        v["gpu_bytes"]
    );
    assert_eq!(v["points"], 110_000);
    assert_eq!(v["frames"].as_array().map(Vec::len), Some(8));
}

#[test]
fn flags_that_cannot_apply_to_a_loading_point_file_are_refused() {
    let las = data("simple.las");
    let las = s(&las);
    usage_fails(
        &["render", las, "-o", "x.png", "--order", "morton"],
        &["--order", "point file drawn while it loads"],
    );
    usage_fails(
        &["render", las, "-o", "x.png", "--encoding", "compact8"],
        &["--encoding"],
    );
    usage_fails(
        &["render", las, "-o", "x.png", "--bucket", "1M"],
        &["--bucket", "stores"],
    );
    usage_fails(
        &[
            "render",
            las,
            "-o",
            "x.png",
            "--raster",
            "hqs",
            "--vram-budget",
            "1GiB",
        ],
        &["--vram-budget"],
    );
    usage_fails(&["bench", las, "--quality"], &["--quality"]);
    usage_fails(&["bench", las, "--ram-budget", "1GiB"], &["--ram-budget"]);
    usage_fails(
        &["view", las, "--raster", "hqs", "--target-fps", "30"],
        &["--target-fps"],
    );
    fails(
        &["bench", las, "--raster", "hqs1r", "--frames", "2"],
        &["closest-point --raster", "pointlet convert"],
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("g.pointlet");
    ok(&["generate", "--points", "5000", "-o", s(&store)]);
    usage_fails(
        &["bench", s(&store), "--target-fps", "30"],
        &["--target-fps"],
    );
    usage_fails(&["bench", s(&store), "--columns", "x,y,z"], &["--columns"]);
}

#[test]
fn a_store_with_progressive_is_drawn_as_its_point_file_is() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = data("simple.las");
    let store = dir.path().join("simple.pointlet");
    ok(&["convert", s(&las), "-o", s(&store)]);
    let draw = |input: &Path, png: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(input),
            "-o",
            s(png),
            "--width",
            "200",
            "--height",
            "120",
            "--color",
            "intensity",
        ];
        args.extend_from_slice(extra);
        let err = ok_stderr(&args);
        assert!(err.contains("loaded in"), "{}: {err}", input.display());
        png_rgba(png)
    };
    let from_store = draw(&store, &dir.path().join("s.png"), &["--progressive"]);
    let from_file = draw(&las, &dir.path().join("f.png"), &[]);
    assert!(lit(&from_store) > 500, "nothing drawn");
    // The same points (the store keeps LAS's quantization); positions relative to the store's
    // bounds instead of the header's may round differently in f32 at a few pixels.
    let same = from_store
        .chunks_exact(4)
        .zip(from_file.chunks_exact(4))
        .filter(|(a, b)| a == b)
        .count();
    assert!(
        same * 1000 >= 998 * 200 * 120,
        "{same} of {} pixels equal",
        200 * 120
    );
    let out = ok(&[
        "bench",
        s(&store),
        "--progressive",
        "--frames",
        "4",
        "--width",
        "160",
        "--height",
        "100",
    ]);
    assert!(out.contains("fully loaded after"), "{out}");
    for extra in [
        &[][..],
        &["--color-only", "rgb"][..],
        &["--staged"][..],
        &["--staged", "--color-only", "intensity"][..],
    ] {
        let mut args = vec!["bench-read", s(&store)];
        args.extend_from_slice(extra);
        let out = ok(&args);
        assert!(out.contains("decoded 1065 points"), "{out}");
        let staged = extra.contains(&"--staged");
        assert_eq!(out.contains("GB/s of 16-byte points"), staged, "{out}");
    }
    usage_fails(
        &["bench-read", s(&las), "--staged"],
        &["--staged", "stores only"],
    );
    usage_fails(
        &[
            "bench-read",
            s(&store),
            "--staged",
            "--color-only",
            "elevation",
        ],
        &["--staged", "elevation"],
    );
    usage_fails(
        &["render", s(&las), "-o", "x.png", "--progressive"],
        &["--progressive", "stores only"],
    );
    usage_fails(
        &[
            "render",
            s(&store),
            "-o",
            "x.png",
            "--progressive",
            "--raster",
            "hqs",
        ],
        &["--progressive", "closest-point"],
    );
    usage_fails(
        &["bench", s(&store), "--progressive", "--columns", "x,y,z"],
        &["--columns"],
    );
    usage_fails(
        &["bench", s(&store), "--progressive", "--bucket", "1M"],
        &["--bucket"],
    );
}

#[test]
fn several_inputs_render_together_as_their_merged_store_does() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (las, laz) = (data("simple.las"), data("autzen_trim.laz"));
    let merged = dir.path().join("merged.pointlet");
    ok(&["convert", s(&las), s(&laz), "-o", s(&merged)]);
    let draw = |inputs: &[&Path], png: &Path, extra: &[&str]| {
        let mut args = vec!["render"];
        args.extend(inputs.iter().map(|p| s(p)));
        args.extend_from_slice(&["-o", s(png), "--width", "240", "--height", "160"]);
        args.extend_from_slice(&["--color", "classification"]);
        args.extend_from_slice(extra);
        let err = ok_stderr(&args);
        assert!(err.contains("rendered"), "{inputs:?}: {err}");
        png_rgba(png)
    };
    let together = draw(&[&las, &laz], &dir.path().join("t.png"), &[]);
    let from_store = draw(&[&merged], &dir.path().join("m.png"), &["--progressive"]);
    // simple.las's bounds hold autzen_trim's: the default camera frames both the same way.
    let alone = draw(&[&las], &dir.path().join("a.png"), &[]);
    assert!(lit(&together) > lit(&alone), "both inputs are drawn");
    let same = together
        .chunks_exact(4)
        .zip(from_store.chunks_exact(4))
        .filter(|(a, b)| a == b)
        .count();
    assert!(
        same * 1000 >= 998 * 240 * 160,
        "{same} of {} pixels equal",
        240 * 160
    );
    // A store among several inputs is read as a point file; in-core rasterizers take them too.
    let hqs = draw(
        &[&las, &merged],
        &dir.path().join("h.png"),
        &["--raster", "hqs"],
    );
    assert!(lit(&hqs) > 500);
    usage_fails(
        &[
            "render",
            s(&las),
            s(&merged),
            "-o",
            "x.png",
            "--bucket",
            "1M",
        ],
        &["--bucket", "several inputs"],
    );
}
