//! Stores drawn through the virtualized scene at the edges: a handful of points (one pointlet),
//! buckets too small to share out, and HQS, which must converge like the other rasterizers.

mod common;

use common::{ok, pointlet, s, usage_fails};
use std::path::Path;

fn pixels(path: &Path) -> Vec<u8> {
    let file = std::fs::File::open(path).expect("opening the PNG");
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size().expect("PNG size")];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    buf.truncate(info.buffer_size());
    buf
}

/// Pixels that differ between two images of the same size.
fn differing(a: &Path, b: &Path) -> usize {
    let (a, b) = (pixels(a), pixels(b));
    assert_eq!(a.len(), b.len(), "image sizes");
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p != q)
        .count()
}

fn lit(path: &Path) -> usize {
    pixels(path)
        .chunks_exact(4)
        .filter(|p| p[..3] != [0, 0, 0])
        .count()
}

/// Renders `store` into `png` with `extra` arguments; returns stderr.
fn render(store: &Path, png: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "render",
        s(store),
        "-o",
        s(png),
        "--width",
        "160",
        "--height",
        "120",
    ];
    args.extend_from_slice(extra);
    let out = pointlet(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "pointlet {args:?} failed:\n{err}");
    err
}

#[test]
fn stores_of_a_few_points_draw_every_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 106 points (one pointlet, as any small LAS file gives), one point, a pointlet and a point.
    for points in ["106", "1", "257"] {
        let las = dir.path().join(format!("{points}.las"));
        let store = dir.path().join(format!("{points}.pointlet"));
        let png = dir.path().join(format!("{points}.png"));
        ok(&["generate", "--points", points, "-o", s(&las)]);
        ok(&["convert", s(&las), "-o", s(&store)]);
        let err = render(&store, &png, &["--max-frames", "100"]);
        assert!(
            err.contains(&format!(": {points} points drawn")),
            "{points} points: {err}"
        );
        assert!(!err.contains("not converged"), "{points} points: {err}");
        assert!(lit(&png) > 0, "{points} points: the image is black");
        // Loads arrive asynchronously: 20 frames (40 ms on lavapipe) sometimes end before the
        // second pointlet does.
        let bench = ok(&[
            "bench",
            s(&store),
            "--frames",
            "200",
            "--width",
            "160",
            "--height",
            "120",
        ]);
        assert!(
            bench.contains(&format!("; {points} points uploaded")),
            "{points} points: {bench}"
        );
    }
}

#[test]
fn a_tiny_bucket_draws_every_visible_pointlet_and_zero_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("scene.pointlet");
    ok(&[
        "generate",
        "--points",
        "100k",
        "--pointlets",
        "300",
        "-o",
        s(&store),
    ]);
    let full = dir.path().join("full.png");
    render(&store, &full, &[]);
    for bucket in ["1", "10"] {
        // Converged: the full-detail image, not a black one.
        let png = dir.path().join(format!("b{bucket}.png"));
        let err = render(&store, &png, &["--bucket", bucket, "--max-frames", "200"]);
        assert!(!err.contains("not converged"), "bucket {bucket}: {err}");
        assert_eq!(differing(&png, &full), 0, "bucket {bucket}");
        // The bucket's own image: a point of every pointlet in view.
        let err = render(&store, &png, &["--bucket", bucket, "--no-converge"]);
        assert!(!err.contains(": 0 points drawn"), "bucket {bucket}: {err}");
        assert!(lit(&png) > 0, "bucket {bucket}: the LoD image is black");
    }
    let png = dir.path().join("b0.png");
    usage_fails(
        &["render", s(&store), "-o", s(&png), "--bucket", "0"],
        &["bucket", "at least 1"],
    );
    assert!(!png.exists(), "no image for a refused bucket");
}

#[test]
fn hqs_on_a_store_converges_to_full_detail() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("scene.pointlet");
    ok(&[
        "generate",
        "--points",
        "100k",
        "--pointlets",
        "300",
        "-o",
        s(&store),
    ]);
    for raster in ["hqs", "hqs1r"] {
        // Full detail from the first frame, against a bucket of a fiftieth of the store that
        // must grow while the camera stands still.
        let full = dir.path().join(format!("{raster}-full.png"));
        render(&store, &full, &["--raster", raster, "--bucket", "1G"]);
        let grown = dir.path().join(format!("{raster}-grown.png"));
        let err = render(
            &store,
            &grown,
            &[
                "--raster",
                raster,
                "--bucket",
                "2000",
                "--max-frames",
                "100",
            ],
        );
        assert!(!err.contains("not converged"), "{raster}: {err}");
        assert!(err.contains(": 100000 points drawn"), "{raster}: {err}");
        assert_eq!(differing(&grown, &full), 0, "{raster}");
    }
    // The quality benchmark measures HQS too (it needs the converged image as ground truth).
    let out = ok(&[
        "bench",
        s(&store),
        "--quality",
        "--raster",
        "hqs",
        "--buckets",
        "5000",
        "--width",
        "160",
        "--height",
        "120",
    ]);
    assert!(out.contains("closeup   bucket         5000: PSNR"), "{out}");
}
