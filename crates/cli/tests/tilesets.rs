//! 3D Tiles tilesets written by independent producers (py3dtiles, 3d-tiles-tools; see
//! testdata/README.md) drawn by `render` like their source LAS files, from the same camera:
//! the same pixels covered, and the same colours — exactly for pnts (8-bit sRGB as in the
//! source), within a few steps for GLB, whose producer stored colours as 8-bit linear values
//! (dark sRGB shades do not survive that round trip exactly). pnts and GLB content, REPLACE
//! and ADD refinement, nested transforms and an external tileset. Broken tilesets fail with a
//! message naming the tile.

mod common;
use common::*;
use std::path::Path;

const SIZE: [&str; 4] = ["--width", "320", "--height", "240"];

fn render(input: &Path, png: &Path, extra: &[&str]) -> Vec<u8> {
    let mut args = vec!["render", s(input), "-o", s(png)];
    args.extend(SIZE);
    args.extend(extra);
    ok(&args);
    png_rgba(png)
}

fn lit(rgba: &[u8]) -> Vec<bool> {
    rgba.chunks_exact(4).map(|p| p[..3] != [0, 0, 0]).collect()
}

#[test]
fn producers_tilesets_draw_like_their_source_files() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases: [(&str, &str, u8); 9] = [
        ("tiles/simple_pnts/tileset.json", "simple.las", 0),
        ("tiles/simple_pnts/tileset_add.json", "simple.las", 0),
        ("tiles/simple_pnts/tileset_rotated.json", "simple.las", 0),
        ("tiles/simple_pnts/tileset_external.json", "simple.las", 0),
        ("tiles/simple_glb/tileset.json", "simple.las", 4),
        ("tiles/simple_glb/tileset_add.json", "simple.las", 4),
        ("tiles/simple_glb/tileset_rotated.json", "simple.las", 4),
        ("tiles/autzen_pnts/tileset.json", "tiles/autzen_crop.laz", 0),
        ("tiles/autzen_glb/tileset.json", "tiles/autzen_crop.laz", 4),
    ];
    for view in [&["--view", "overview"][..], &["--view", "closeup"]] {
        for (tileset, source, tolerance) in cases {
            // --max-sse 0: every tile down to full detail, every point of each, one pixel each
            // as the source's.
            let full = [view, &["--max-sse", "0", "--point-size", "1"]].concat();
            let a = render(&data(tileset), &dir.path().join("tileset.png"), &full);
            let b = render(&data(source), &dir.path().join("source.png"), view);
            let (la, lb) = (lit(&a), lit(&b));
            let covered = lb.iter().filter(|l| **l).count();
            assert!(
                covered > 200,
                "{source} {view:?}: only {covered} pixels lit"
            );
            let differ = la.iter().zip(&lb).filter(|(x, y)| x != y).count();
            assert_eq!(
                differ, 0,
                "{tileset} {view:?}: {differ} pixels covered by one picture only"
            );
            let worst = a.iter().zip(&b).map(|(x, y)| x.abs_diff(*y)).max();
            assert!(
                worst <= Some(tolerance),
                "{tileset} {view:?}: colours differ by {worst:?} (allowed {tolerance})"
            );
        }
    }
}

#[test]
fn info_describes_a_tileset() {
    let out = ok(&["info", s(&data("tiles/autzen_glb/tileset.json"))]);
    assert!(out.contains("3D Tiles 1.1 tileset"), "{out}");
    assert!(out.contains("1872"), "{out}");
}

/// A copy of `simple_pnts` to break.
fn broken_copy(dir: &Path) -> std::path::PathBuf {
    let from = data("tiles/simple_pnts");
    let to = dir.join("simple_pnts");
    for sub in ["", "points", "external"] {
        std::fs::create_dir_all(to.join(sub)).expect("mkdir");
        for e in std::fs::read_dir(from.join(sub)).expect("read_dir") {
            let e = e.expect("entry");
            if e.path().is_file() {
                std::fs::copy(e.path(), to.join(sub).join(e.file_name())).expect("copy");
            }
        }
    }
    to
}

#[test]
fn broken_tilesets_name_the_tile() {
    let dir = tempfile::tempdir().expect("temp dir");
    let png = dir.path().join("out.png");

    let missing = broken_copy(&dir.path().join("missing"));
    std::fs::remove_file(missing.join("points/r0.pnts")).expect("remove tile");
    let tileset = missing.join("tileset.json");
    fails(
        &["render", s(&tileset), "-o", s(&png)],
        &["r0.pnts", "cannot read"],
    );
    assert!(!png.exists(), "a failed render left {}", png.display());

    let truncated = broken_copy(&dir.path().join("truncated"));
    let tile = truncated.join("points/r2.pnts");
    let bytes = std::fs::read(&tile).expect("tile");
    std::fs::write(&tile, &bytes[..bytes.len() / 2]).expect("truncate");
    fails(
        &["render", s(&truncated.join("tileset.json")), "-o", s(&png)],
        &["r2.pnts"],
    );

    let magic = broken_copy(&dir.path().join("magic"));
    let tile = magic.join("points/r4.pnts");
    let mut bytes = std::fs::read(&tile).expect("tile");
    bytes[..4].copy_from_slice(b"nope");
    std::fs::write(&tile, &bytes).expect("rewrite");
    fails(&["info", s(&magic.join("tileset.json"))], &["r4.pnts"]);

    let not_json = dir.path().join("tileset.json");
    std::fs::write(&not_json, "{ \"asset\": ").expect("write");
    fails(&["render", s(&not_json), "-o", s(&png)], &["tileset.json"]);
}

/// A loopback HTTP/1.1 server of a folder's files, one thread per connection, where some paths
/// answer 500 or stall.
struct FileServer {
    port: u16,
}

impl FileServer {
    fn start(root: std::path::PathBuf, fail: &'static str, stall: &'static str) -> FileServer {
        use std::io::{BufRead, BufReader, Write};
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind loopback");
        let port = listener.local_addr().expect("address").port();
        std::thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let root = root.clone();
                std::thread::spawn(move || {
                    let mut reader = BufReader::new(&stream);
                    let mut line = String::new();
                    if reader.read_line(&mut line).is_err() {
                        return;
                    }
                    // Headers up to the blank line; ranges are not needed for whole files.
                    let mut header = String::new();
                    while reader.read_line(&mut header).is_ok_and(|n| n > 2) {
                        header.clear();
                    }
                    let path = line.split_whitespace().nth(1).unwrap_or("/").to_string();
                    let mut out = &stream;
                    if path.ends_with(stall) {
                        std::thread::sleep(std::time::Duration::from_secs(120));
                        return;
                    }
                    let (status, body) = if path.ends_with(fail) {
                        ("500 Internal Server Error", b"boom".to_vec())
                    } else {
                        match std::fs::read(root.join(path.trim_start_matches('/'))) {
                            Ok(b) => ("200 OK", b),
                            Err(_) => ("404 Not Found", b"no such file".to_vec()),
                        }
                    };
                    let _ = write!(
                        out,
                        "HTTP/1.1 {status}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                        body.len()
                    );
                    let _ = out.write_all(&body);
                });
            }
        });
        FileServer { port }
    }

    fn url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}/{path}", self.port)
    }
}

/// `pointlet args` with a short network timeout, and how long it took.
fn pointlet_timed(args: &[&str]) -> (std::process::Output, std::time::Duration) {
    let start = std::time::Instant::now();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .env("POINTLET_REMOTE_TIMEOUT_MS", "500")
        .args(args)
        .output()
        .expect("running pointlet");
    (out, start.elapsed())
}

#[test]
fn tilesets_over_http_draw_like_local_ones_and_bad_servers_name_the_tile() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = FileServer::start(data("tiles"), "autzen_pnts/points/r3.pnts", "r6.pnts");
    let local = render(
        &data("tiles/simple_glb/tileset_external.json"),
        &dir.path().join("local.png"),
        &[],
    );
    let url = server.url("simple_glb/tileset_external.json");
    let remote = render(Path::new(&url), &dir.path().join("remote.png"), &[]);
    assert!(local == remote, "the tileset over HTTP draws differently");

    let png = dir.path().join("bad.png");
    let cases = [
        ("autzen_pnts/tileset.json", "r3.pnts"),
        ("simple_pnts/tileset.json", "r6.pnts"),
        ("no_such/tileset.json", "no_such/tileset.json"),
    ];
    for (tileset, named) in cases {
        let url = server.url(tileset);
        let (out, took) = pointlet_timed(&["render", &url, "-o", s(&png)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{tileset}:\n{err}");
        assert!(!err.contains("panicked"), "{tileset}:\n{err}");
        assert!(
            err.contains(named),
            "{tileset}: the message lacks {named}:\n{err}"
        );
        assert!(took.as_secs() < 60, "{tileset}: took {took:?}");
        assert!(!png.exists());
    }
}

#[test]
fn a_tileset_converts_to_a_store_of_its_points() {
    let dir = tempfile::tempdir().expect("temp dir");
    let from_tiles = dir.path().join("tiles.pointlet");
    let from_las = dir.path().join("las.pointlet");
    ok(&[
        "convert",
        s(&data("tiles/autzen_pnts/tileset.json")),
        "-o",
        s(&from_tiles),
    ]);
    ok(&[
        "convert",
        s(&data("tiles/autzen_crop.laz")),
        "-o",
        s(&from_las),
    ]);
    assert!(ok(&["info", s(&from_tiles)]).contains("1872"));
    let one = ["--point-size", "1"];
    let a = render(&from_tiles, &dir.path().join("a.png"), &one);
    let b = render(&from_las, &dir.path().join("b.png"), &one);
    assert!(
        a == b,
        "the store of the tileset draws differently from the LAS file's"
    );
}

/// The number before `what` in a `render` summary line ("… 12 tiles drawn, …").
fn count_before(text: &str, what: &str) -> u64 {
    let at = text
        .find(what)
        .unwrap_or_else(|| panic!("no '{what}' in:\n{text}"));
    text[..at]
        .trim_end()
        .rsplit(' ')
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count before '{what}' in:\n{text}"))
}

#[test]
fn our_export_streams_back_to_the_stores_picture_refining_with_the_view() {
    let dir = tempfile::tempdir().expect("temp dir");
    let store = dir.path().join("autzen.pointlet");
    ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&store)]);
    let one = ["--point-size", "1", "--width", "320", "--height", "240"];
    let png = dir.path().join("out.png");
    ok(&[&["render", s(&store), "-o", s(&png)][..], &one].concat());
    let expected = png_rgba(&png);
    for refine in ["add", "replace"] {
        let tiles = dir.path().join(refine);
        ok(&[
            "export-3dtiles",
            s(&store),
            "-o",
            s(&tiles),
            "--refine",
            refine,
            "--points-per-tile",
            "5K",
        ]);
        let tileset = tiles.join("tileset.json");
        // Full detail: every point, where the store puts it.
        let full = ok_stderr(
            &[
                &["render", s(&tileset), "-o", s(&png), "--max-sse", "0"][..],
                &one,
            ]
            .concat(),
        );
        assert_eq!(
            count_before(&full, "points tested"),
            110_000,
            "{refine}:\n{full}"
        );
        let got = png_rgba(&png);
        let (la, lb) = (lit(&got), lit(&expected));
        let differ = la.iter().zip(&lb).filter(|(x, y)| x != y).count();
        assert_eq!(
            differ, 0,
            "{refine}: {differ} pixels covered by one picture only"
        );
        // The default error draws the coarse tiles of the overview, more of them close up.
        let coarse = ok_stderr(&["render", s(&tileset), "-o", s(&png)]);
        let close = ok_stderr(&["render", s(&tileset), "-o", s(&png), "--view", "closeup"]);
        let (n_coarse, n_close) = (
            count_before(&coarse, "points tested"),
            count_before(&close, "points tested"),
        );
        assert!(
            n_coarse < 110_000 / 4,
            "{refine}: the overview at 16 px draws {n_coarse} points"
        );
        assert!(
            count_before(&full, "tiles drawn") > count_before(&coarse, "tiles drawn"),
            "{refine}: full detail draws no more tiles than the overview"
        );
        let _ = n_close;
    }
    // A budget too small for the view: tiles come and go, the GPU memory stays within it.
    let json = dir.path().join("bench.json");
    ok(&[
        "bench",
        s(&dir.path().join("add/tileset.json")),
        "--frames",
        "60",
        "--orbit-seconds",
        "3",
        "--width",
        "320",
        "--height",
        "240",
        "--max-sse",
        "0",
        "--vram-budget",
        "2560KiB",
        "--json",
        s(&json),
    ]);
    let text = std::fs::read_to_string(&json).expect("bench json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    let frames = v["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 60);
    let peak = frames
        .iter()
        .filter_map(|f| f["gpu_bytes"].as_u64())
        .max()
        .unwrap_or(0);
    let evicted: u64 = frames
        .iter()
        .filter_map(|f| f["evicted_tiles"].as_u64())
        .sum();
    let share = v["wanted_drawn"].as_f64().expect("share");
    assert!(peak <= 2560 << 10, "GPU {peak} bytes for a 2.5 MiB budget");
    assert!(evicted > 0, "nothing evicted under a budget below the data");
    assert!(share > 0.2 && share < 1.0, "share drawn {share}");
}

/// Lit pixels' bounding box: (min x, min y, max x, max y).
fn lit_box(rgba: &[u8], width: usize) -> [usize; 4] {
    let mut b = [usize::MAX, usize::MAX, 0, 0];
    for (i, _) in lit(rgba).iter().enumerate().filter(|(_, l)| **l) {
        let (x, y) = (i % width, i / width);
        b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
    }
    b
}

#[test]
fn a_globe_tileset_is_seen_from_its_local_vertical_as_its_store() {
    let dir = tempfile::tempdir().expect("temp dir");
    let store = dir.path().join("g.pointlet");
    // Generated scenes are in EPSG:32611: the export places them in ECEF.
    ok(&["generate", "--points", "100K", "-o", s(&store)]);
    let tiles = dir.path().join("ecef");
    let said = ok_stderr(&["export-3dtiles", s(&store), "-o", s(&tiles)]);
    assert!(said.contains("placed in ECEF"), "{said}");
    let one = ["--point-size", "1"];
    let png = dir.path().join("out.png");
    ok(&[&["render", s(&store), "-o", s(&png)][..], &SIZE, &one].concat());
    let from_store = lit_box(&png_rgba(&png), 320);
    let tileset = tiles.join("tileset.json");
    ok(&[
        &["render", s(&tileset), "-o", s(&png), "--max-sse", "0"][..],
        &SIZE,
        &one,
    ]
    .concat());
    let from_tiles = lit_box(&png_rgba(&png), 320);
    // The same framing: the overview of the local east-north-up frame, not of ECEF's axes.
    for k in 0..4 {
        assert!(
            from_store[k].abs_diff(from_tiles[k]) <= 6,
            "lit box {from_tiles:?} of the tileset against {from_store:?} of the store"
        );
    }
}
