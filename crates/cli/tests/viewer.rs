//! The viewer in a real window: an X server (Xvfb) started by the test, the viewer drawing N
//! frames on lavapipe and saving its image, compared with `pointlet render` of the same camera
//! and settings. No X server is a failure with instructions, never a skipped test.

mod common;

use common::{data, ok, s};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// An Xvfb server on a display number it picks itself (`-displayfd`), so parallel tests and
/// other X servers never collide. Killed when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1600x1200x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| {
                panic!(
                    "cannot start an X server for the viewer test (Xvfb: {e}); install it with \
                     `bash scripts/ensure-xvfb.sh` (apt-get install xvfb)"
                )
            });
        let mut line = String::new();
        let stdout = child.stdout.take().expect("Xvfb stdout");
        BufReader::new(stdout)
            .read_line(&mut line)
            .expect("reading Xvfb's display number");
        let number = line.trim();
        if number.is_empty() || number.parse::<u32>().is_err() {
            let _ = child.kill();
            panic!("Xvfb started but reported no display number (got '{number}'): it failed");
        }
        Xvfb {
            display: format!(":{number}"),
            child,
        }
    }

    /// `pointlet view` with `args` on this display; asserts success, returns stderr.
    fn view(&self, args: &[&str]) -> String {
        let out = Command::new(env!("CARGO_BIN_EXE_pointlet"))
            .arg("view")
            .args(args)
            .env("DISPLAY", &self.display)
            // X11 only: no Wayland probing (and its warnings) on a headless machine.
            .env_remove("WAYLAND_DISPLAY")
            .env("WGPU_BACKEND", "vulkan")
            .output()
            .expect("running pointlet view");
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(
            out.status.success(),
            "pointlet view {args:?} failed:\n{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        err
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn pixels(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).expect("opening the PNG");
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size().expect("PNG size")];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// Renders `input` with `extra` arguments both ways and asserts identical pixels.
fn assert_view_matches_render(x: &Xvfb, input: &Path, extra: &[&str]) {
    assert_view_matches_render_with(x, &[input], extra, &[], 0);
}

/// The demo scene both ways (no INPUT).
fn assert_view_matches_render_demo(x: &Xvfb, extra: &[&str]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let (viewed, rendered) = (dir.path().join("v.png"), dir.path().join("r.png"));
    let size = ["--width", "320", "--height", "240"];
    let mut view_args = vec!["--frames", "2", "--screenshot", s(&viewed)];
    view_args.extend_from_slice(&size);
    view_args.extend_from_slice(extra);
    x.view(&view_args);
    let mut render_args = vec!["render", "-o", s(&rendered)];
    render_args.extend_from_slice(&size);
    render_args.extend_from_slice(extra);
    ok(&render_args);
    assert_eq!(pixels(&viewed), pixels(&rendered), "demo scene {extra:?}");
}

/// Like [`assert_view_matches_render`], with `view_only` arguments that `render` lacks and at
/// most `tolerated` differing pixels.
fn assert_view_matches_render_with(
    x: &Xvfb,
    inputs: &[&Path],
    extra: &[&str],
    view_only: &[&str],
    tolerated: usize,
) {
    let dir = tempfile::tempdir().expect("tempdir");
    let viewed = dir.path().join("view.png");
    let rendered = dir.path().join("render.png");
    let size = ["--width", "480", "--height", "360"];
    let mut view_args: Vec<&str> = inputs.iter().map(|p| s(p)).collect();
    view_args.extend_from_slice(&["--frames", "3", "--screenshot", s(&viewed)]);
    view_args.extend_from_slice(&size);
    view_args.extend_from_slice(extra);
    view_args.extend_from_slice(view_only);
    let err = x.view(&view_args);
    assert!(err.contains("viewed"), "{err}");
    let mut render_args = vec!["render"];
    render_args.extend(inputs.iter().map(|p| s(p)));
    render_args.extend_from_slice(&["-o", s(&rendered)]);
    render_args.extend_from_slice(&size);
    render_args.extend_from_slice(extra);
    ok(&render_args);
    let (a, b) = (pixels(&viewed), pixels(&rendered));
    assert_eq!((a.0, a.1), (b.0, b.1), "image sizes");
    let differing =
        a.2.chunks_exact(4)
            .zip(b.2.chunks_exact(4))
            .filter(|(p, q)| p != q)
            .count();
    assert!(
        differing <= tolerated,
        "{extra:?}: {differing} of {} pixels differ between view and render",
        a.0 * a.1
    );
    let lit = a.2.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
    assert!(lit > 1000, "the image shows points ({lit} lit pixels)");
}

#[test]
fn viewer_window_matches_render_of_the_same_camera() {
    let x = Xvfb::start();
    let laz = data("autzen_trim.laz");
    assert_view_matches_render(&x, &laz, &[]);
    assert_view_matches_render(
        &x,
        &laz,
        &[
            "--view",
            "closeup",
            "--color",
            "elevation",
            "--edl",
            "--fill",
            "1",
        ],
    );
    assert_view_matches_render(
        &x,
        &data("plane.laz"),
        &["--color", "intensity", "--raster", "hqs"],
    );
    assert_view_matches_render(&x, &data("extrabytes.las"), &["--color", "extra:Time"]);
    // The hardware point baseline, and the demo scene (no INPUT).
    assert_view_matches_render(
        &x,
        &laz,
        &["--raster", "hw-points", "--color", "classification"],
    );
    assert_view_matches_render_demo(&x, &["--demo-points", "60000", "--view", "closeup"]);
    // Several inputs in one frame: a LAZ file with a store of another file.
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("simple.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    let inputs = [laz.as_path(), store.as_path()];
    assert_view_matches_render_with(&x, &inputs, &["--color", "classification"], &[], 0);
}

#[test]
fn viewer_window_screenshot_and_bad_input() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().expect("tempdir");
    let shot = dir.path().join("window.png");
    x.view(&[
        s(&data("simple.las")),
        "--frames",
        "2",
        "--width",
        "400",
        "--height",
        "300",
        "--window-screenshot",
        s(&shot),
    ]);
    let (w, h, rgba) = pixels(&shot);
    assert_eq!((w, h), (400, 300));
    assert!(
        rgba.chunks_exact(4).all(|p| p[3] == 255),
        "the window is opaque"
    );
    // Data without colours opens coloured by its intensity (the default for data without RGB).
    let err = x.view(&[
        s(&data("simple1_1.las")),
        "--frames",
        "1",
        "--width",
        "200",
        "--height",
        "150",
    ]);
    assert!(err.contains("colouring by intensity"), "{err}");
    // A missing or broken file and a wrong screenshot name fail cleanly, before any window
    // opens.
    let missing = dir.path().join("missing.laz");
    common::fails(&["view", s(&missing), "--frames", "1"], &["missing.laz"]);
    let broken = dir.path().join("broken.laz");
    std::fs::write(&broken, b"LASF but not really a point file").expect("write");
    common::fails(&["view", s(&broken), "--frames", "1"], &["broken.laz"]);
    common::fails(
        &[
            "view",
            "--frames",
            "1",
            "--screenshot",
            s(&dir.path().join("x.jpg")),
        ],
        &["png"],
    );
    // Without the keyboard data X11 needs (xkb-data), winit panics: the viewer says so instead.
    let out = Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .args(["view", s(&data("simple.las")), "--frames", "1"])
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("XKB_CONFIG_ROOT", dir.path().join("no-xkb"))
        .output()
        .expect("running pointlet view");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot connect to a display")
            && err.contains("XKB")
            && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn viewer_of_a_store_converges_to_the_render_of_it() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("autzen.pointlet");
    ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&store)]);
    // Small budgets: the store is streamed through the virtualized scene, not held whole.
    let budgets = ["--vram-budget", "96MiB", "--ram-budget", "16MiB"];
    assert_view_matches_render_with(&x, &[&store], &[], &budgets, 0);
    assert_view_matches_render_with(&x, &[&store], &["--color", "classification"], &budgets, 0);
    // HQS converges like the others (a still view redraws every point up to full detail). It
    // blends the points within 1 % of the closest depth, so last-bit rounding decides points at
    // that border: the virtualized scene's pages have other origins than `render`'s (positions
    // relative to them round differently in f32), and its camera is fitted to the store
    // header's bounds (637179.22) where `render` fits it to the dequantized points
    // (637179.2200000001). 1 pixel of 172 800 differs here; closest-point images are exact.
    assert_view_matches_render_with(&x, &[&store], &["--raster", "hqs"], &budgets, 20);
    // A store of one pointlet (fewer points than a page) converges too.
    let las = dir.path().join("few.las");
    let few = dir.path().join("few.pointlet");
    ok(&["generate", "--points", "106", "-o", s(&las)]);
    ok(&["convert", s(&las), "-o", s(&few)]);
    let shot = dir.path().join("few.png");
    let err = x.view(&[
        s(&few),
        "--frames",
        "3",
        "--screenshot",
        s(&shot),
        "--width",
        "160",
        "--height",
        "120",
    ]);
    assert!(!err.contains("did not converge"), "{err}");
    let lit = pixels(&shot)
        .2
        .chunks_exact(4)
        .filter(|p| p[..3] != [0, 0, 0])
        .count();
    assert!(lit > 0, "the 106 points are drawn");
}

#[test]
fn viewer_of_a_tileset_streams_it_to_the_render_of_it() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().expect("tempdir");
    let tileset = data("tiles/simple_pnts/tileset.json");
    let (viewed, rendered) = (dir.path().join("view.png"), dir.path().join("render.png"));
    let size = ["--width", "320", "--height", "240"];
    // Every tile down to full detail, every point one pixel, within budgets lavapipe allocates
    // quickly.
    let full = [
        "--max-sse",
        "0",
        "--point-size",
        "1",
        "--vram-budget",
        "64MiB",
        "--ram-budget",
        "64MiB",
    ];
    let mut view_args = vec![s(&tileset), "--frames", "2", "--screenshot", s(&viewed)];
    view_args.extend(size);
    view_args.extend(full);
    let err = x.view(&view_args);
    // Streamed, not read whole as a point file drawn while it loads.
    assert!(err.contains("streamed tiles"), "{err}");
    let mut render_args = vec!["render", s(&tileset), "-o", s(&rendered)];
    render_args.extend(size);
    render_args.extend(full);
    let out = common::ok_stderr(&render_args);
    assert!(out.contains("tiles drawn"), "render streamed it too: {out}");
    let (a, b) = (pixels(&viewed), pixels(&rendered));
    assert_eq!((a.0, a.1), (b.0, b.1), "image sizes");
    let lit =
        |rgba: &[u8]| -> Vec<bool> { rgba.chunks_exact(4).map(|p| p[..3] != [0, 0, 0]).collect() };
    let (la, lb) = (lit(&a.2), lit(&b.2));
    let covered = lb.iter().filter(|l| **l).count();
    assert!(
        covered > 200,
        "render shows the tileset ({covered} lit pixels)"
    );
    let differ = la.iter().zip(&lb).filter(|(p, q)| p != q).count();
    assert_eq!(differ, 0, "{differ} pixels lit in one picture only");
    assert_eq!(a.2, b.2, "the same colours");
}

#[test]
fn viewer_flags_of_tilesets_apply_to_tilesets_only() {
    let tileset = data("tiles/simple_pnts/tileset.json");
    common::usage_fails(
        &["view", s(&data("simple.las")), "--max-sse", "3"],
        &["--max-sse applies to a tileset only"],
    );
    common::usage_fails(&["view", "--no-clod"], &["--no-clod", "demo scene"]);
    common::usage_fails(
        &["view", s(&tileset), "--bucket", "3M"],
        &["--bucket", "not to a tileset"],
    );
    common::usage_fails(
        &["view", s(&tileset), "--target-fps", "30"],
        &["--target-fps", "not to a tileset"],
    );
    common::usage_fails(
        &["view", s(&tileset), "--raster", "hw-points"],
        &["hw-points", "tileset"],
    );
    common::fails(
        &["view", s(&tileset), "--color", "extra:Time"],
        &["tileset has no LAS extra-bytes attribute 'Time'"],
    );
}
