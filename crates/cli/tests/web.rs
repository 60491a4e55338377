//! The browser viewer end to end: scripts/ensure-browser.sh provides chromium, playwright-core
//! and a fresh target/web/; a loopback HTTP server (range requests, as `pointlet serve` or any
//! static host answers them) serves the viewer and a store; headless chromium draws the shared
//! view on WebGPU (SwiftShader) until the page says `converged`, and the image must match
//! `pointlet render` of the same view (the same store, camera, rasterizer and point size).
//! Without chromium or WebGPU the test fails with the reason — it never skips.

mod common;
use common::*;
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Command;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// What the server answers for a path: a file and its content type.
fn resolve(web: &Path, stores: &Path, path: &str) -> Option<(PathBuf, &'static str)> {
    let path = path.split('?').next().unwrap_or("");
    if let Some(name) = path.strip_prefix("/stores/") {
        let name = name.strip_suffix(".pointlet")?;
        if name.contains('/') || name.contains("..") {
            return None;
        }
        return Some((
            stores.join(format!("{name}.pointlet")),
            "application/octet-stream",
        ));
    }
    let file = match path {
        "/" | "" => "index.html",
        p => p.trim_start_matches('/'),
    };
    if file.contains("..") || file.contains('/') {
        return None;
    }
    let kind = match file.rsplit('.').next() {
        Some("html") => "text/html",
        Some("js") => "text/javascript",
        Some("wasm") => "application/wasm",
        Some("json") => "application/json",
        _ => "application/octet-stream",
    };
    Some((web.join(file), kind))
}

/// `bytes=a-b` (or `a-`) within a file of `len` bytes.
fn parse_range(value: &str, len: u64) -> Option<(u64, u64)> {
    let (a, b) = value.trim().strip_prefix("bytes=")?.split_once('-')?;
    let start: u64 = a.parse().ok()?;
    let end = if b.is_empty() {
        len.checked_sub(1)?
    } else {
        b.parse::<u64>().ok()?.min(len.checked_sub(1)?)
    };
    (start <= end).then_some((start, end))
}

/// One connection: requests until the client closes it (keep-alive, as browsers expect).
fn serve_connection(stream: TcpStream, web: &Path, stores: &Path) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut out = stream;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 {
            return Ok(());
        }
        let path = line.split_whitespace().nth(1).unwrap_or("/").to_string();
        let mut range = None;
        loop {
            let mut h = String::new();
            if reader.read_line(&mut h)? == 0 || h.trim().is_empty() {
                break;
            }
            if let Some((k, v)) = h.split_once(':') {
                if k.eq_ignore_ascii_case("range") {
                    range = Some(v.trim().to_string());
                }
            }
        }
        let found = resolve(web, stores, &path).and_then(|(p, kind)| {
            if path == "/stores.json" {
                let list = std::fs::read_dir(stores).ok()?;
                let names: Vec<String> = list
                    .filter_map(|e| e.ok())
                    .filter_map(|e| {
                        let n = e.file_name().to_string_lossy().into_owned();
                        let size = e.metadata().ok()?.len();
                        let name = n.strip_suffix(".pointlet")?.to_string();
                        Some(format!(
                            "{{\"name\":\"{name}\",\"url\":\"stores/{name}.pointlet\",\"size\":{size}}}"
                        ))
                    })
                    .collect();
                return Some((format!("[{}]", names.join(",")).into_bytes(), kind));
            }
            std::fs::read(p).ok().map(|b| (b, kind))
        });
        let Some((body, kind)) = found else {
            out.write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n")?;
            continue;
        };
        let len = body.len() as u64;
        match range.as_deref().map(|r| parse_range(r, len)) {
            Some(Some((a, b))) => {
                write!(
                    out,
                    "HTTP/1.1 206 Partial Content\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nContent-Range: bytes {a}-{b}/{len}\r\nAccept-Ranges: bytes\r\n\r\n",
                    b - a + 1
                )?;
                out.write_all(&body[a as usize..=b as usize])?;
            }
            Some(None) => {
                write!(
                    out,
                    "HTTP/1.1 416 Range Not Satisfiable\r\nContent-Range: bytes */{len}\r\nContent-Length: 0\r\n\r\n"
                )?;
            }
            None => {
                write!(
                    out,
                    "HTTP/1.1 200 OK\r\nContent-Type: {kind}\r\nContent-Length: {len}\r\nAccept-Ranges: bytes\r\n\r\n"
                )?;
                out.write_all(&body)?;
            }
        }
        out.flush()?;
    }
}

/// Serves `web` at `/` and `stores/NAME.pointlet` at `/stores/NAME.pointlet` on loopback;
/// returns the base URL. The server lives as long as the test process.
fn serve(web: PathBuf, stores: PathBuf) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("binding a loopback port");
    let addr = listener.local_addr().expect("the server's address");
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let (web, stores) = (web.clone(), stores.clone());
            std::thread::spawn(move || {
                let _ = serve_connection(stream, &web, &stores);
            });
        }
    });
    format!("http://{addr}")
}

#[test]
fn the_browser_draws_the_shared_view_as_render_does() {
    let root = repo();
    let ensure = Command::new("bash")
        .arg(root.join("scripts/ensure-browser.sh"))
        .status()
        .expect("running scripts/ensure-browser.sh");
    assert!(
        ensure.success(),
        "scripts/ensure-browser.sh failed: the web viewer test needs chromium, node with \
         playwright-core and a built target/web/"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let stores = dir.path().join("stores");
    std::fs::create_dir(&stores).expect("stores dir");
    let store = stores.join("scene.pointlet");
    ok(&[
        "generate",
        "--points",
        "200k",
        "--pointlets",
        "200",
        "-o",
        s(&store),
    ]);
    // A view from the south-west, above the data (coordinates of the generated scene).
    let info = ok(&["info", s(&store), "--json"]);
    let json: serde_json::Value = serde_json::from_str(&info).expect("info --json");
    let b = &json["bounds"];
    let v = |k: &str, i: usize| b[k][i].as_f64().expect("a bound");
    let (min, max) = (
        [v("min", 0), v("min", 1), v("min", 2)],
        [v("max", 0), v("max", 1), v("max", 2)],
    );
    let c = [0, 1, 2].map(|i| 0.5 * (min[i] + max[i]));
    let span = (max[0] - min[0]).max(max[1] - min[1]);
    let eye = [c[0] - 0.6 * span, c[1] - 0.8 * span, c[2] + 0.5 * span];
    let fmt = |p: [f64; 3]| format!("{},{},{}", p[0], p[1], p[2]);
    let (eye, target, fov) = (fmt(eye), fmt(c), "50");

    let png = dir.path().join("render.png");
    ok(&[
        "render",
        s(&store),
        "-o",
        s(&png),
        "--eye",
        &eye,
        "--target",
        &target,
        "--fov",
        fov,
        "--raster",
        "atomic-min-32",
        "--point-size",
        "1",
        "--width",
        &WIDTH.to_string(),
        "--height",
        &HEIGHT.to_string(),
    ]);
    let want = png_rgba(&png);

    let base = serve(root.join("target/web"), stores.clone());
    let query = format!("?store=scene&eye={eye}&target={target}&fov={fov}&ui=off");
    let (w, h) = (WIDTH.to_string(), HEIGHT.to_string());
    let driver_args: [&str; 5] = [&base, &query, &w, &h, s(dir.path())];
    let out = Command::new("node")
        .arg(root.join("crates/cli/tests/web/driver.mjs"))
        .args(driver_args)
        .env(
            "PLAYWRIGHT_MODULES",
            root.join("target/node-tools/node_modules"),
        )
        .output()
        .expect("running node (scripts/ensure-browser.sh checks it is installed)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "the browser run failed:\n{stderr}\n{stdout}"
    );
    eprintln!("browser: {stdout}");
    let found: serde_json::Value =
        serde_json::from_str(stdout.lines().last().unwrap_or("")).expect("the driver's JSON line");

    // The image: the same size, and every pixel equal to render's but for a few where two
    // points at one pixel tie in depth after f32 rounding (the chosen one may differ).
    let got = std::fs::read(dir.path().join("pixels.rgba")).expect("the browser's pixels");
    assert_eq!(
        (found["width"].as_u64(), found["height"].as_u64()),
        (Some(WIDTH as u64), Some(HEIGHT as u64))
    );
    assert_eq!(got.len(), want.len());
    let pixels = want.len() / 4;
    let differ = (0..pixels)
        .filter(|i| got[4 * i..4 * i + 4] != want[4 * i..4 * i + 4])
        .count();
    let lit = (0..pixels)
        .filter(|i| want[4 * i..4 * i + 3].iter().any(|v| *v > 0))
        .count();
    assert!(
        lit > pixels / 20,
        "render's image is nearly empty ({lit} lit pixels)"
    );
    assert!(
        differ * 1000 <= pixels,
        "{differ} of {pixels} pixels differ from pointlet render's (at most 0.1 % may)"
    );
    assert_eq!(found["overlays_visible"], 0, "ui=off hides every overlay");

    // The page: colouring by classification shows the legend and goes into the URL; two
    // clicks measure a distance; the screenshot button makes a PNG.
    assert_eq!(found["color"], "classification");
    assert!(found["legend_entries"].as_u64().unwrap_or(0) > 0, "{found}");
    assert!(
        found["url_after_color"]
            .as_str()
            .is_some_and(|u| u.contains("color=classification") && u.contains("eye=")),
        "{found}"
    );
    assert!(
        found["measurement"].as_f64().is_some_and(|d| d > 0.0),
        "measuring: {found}"
    );
    assert!(
        found["screenshot_bytes"].as_u64().unwrap_or(0) > 100,
        "{found}"
    );
    let bare = &found["without_webgpu"];
    assert_eq!(bare[0], "no-webgpu", "{found}");
    assert!(
        bare[1].as_str().is_some_and(|m| m.contains("no WebGPU")),
        "{found}"
    );
}

#[test]
fn the_test_server_answers_ranges() {
    assert_eq!(parse_range("bytes=0-9", 100), Some((0, 9)));
    assert_eq!(parse_range("bytes=90-", 100), Some((90, 99)));
    assert_eq!(parse_range("bytes=90-200", 100), Some((90, 99)));
    assert_eq!(parse_range("bytes=100-", 100), None);
    assert!(resolve(Path::new("w"), Path::new("s"), "/stores/../x.pointlet").is_none());
    assert_eq!(
        resolve(Path::new("w"), Path::new("s"), "/?store=a").map(|r| r.1),
        Some("text/html")
    );
}
