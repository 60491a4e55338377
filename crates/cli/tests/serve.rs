//! `pointlet serve`: the real binary on a free loopback port (`--bind 127.0.0.1:0`, the address
//! read from its first line), read by the other commands as a remote store: `info`, `render`
//! and `export` of the URL give what they give of the local file, pixel for pixel and byte for
//! byte, also through a proxy that drops and refuses some requests. Ctrl-C and SIGTERM stop
//! it; bad arguments, a port in use and a missing viewer folder end with a message.

mod common;

use common::{data, fails, ok, png_rgba, s, usage_fails};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// A running `pointlet serve`, killed if a test fails before stopping it.
struct Served {
    child: Option<Child>,
    /// `127.0.0.1:PORT`, from the first line.
    addr: String,
    /// Every line printed before `press Ctrl-C to stop`.
    banner: String,
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(child) = self.child.as_mut() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Served {
    /// Starts `pointlet serve ARGS --bind 127.0.0.1:0` and reads its banner.
    fn start(args: &[&str], env: &[(&str, &Path)]) -> Served {
        let mut command = Command::new(env!("CARGO_BIN_EXE_pointlet"));
        command
            .arg("serve")
            .args(args)
            .args(["--bind", "127.0.0.1:0"])
            .env_remove("POINTLET_WEB_DIR")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for (k, v) in env {
            command.env(k, v);
        }
        let mut child = command.spawn().expect("starting pointlet serve");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut served = Served {
            child: Some(child),
            addr: String::new(),
            banner: String::new(),
        };
        loop {
            let mut line = String::new();
            let n = stdout.read_line(&mut line).expect("reading the banner");
            assert!(n > 0, "the server ended early:\n{}", served.banner);
            served.banner.push_str(&line);
            if line.starts_with("press Ctrl-C") {
                break;
            }
        }
        let first = served.banner.lines().next().expect("a first line");
        let (count, url) = first
            .strip_prefix("serving ")
            .and_then(|rest| rest.split_once(" stores at "))
            .unwrap_or_else(|| panic!("first line is not `serving N stores at URL`: {first}"));
        assert!(count.parse::<usize>().is_ok(), "{first}");
        served.addr = url
            .strip_prefix("http://")
            .and_then(|a| a.strip_suffix('/'))
            .unwrap_or_else(|| panic!("not http://ADDR/: {url}"))
            .to_string();
        assert!(served.addr.starts_with("127.0.0.1:"), "{first}");
        assert!(
            !served.addr.ends_with(":0"),
            "the real port is printed: {first}"
        );
        served
    }

    fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    /// Sends `signal` and waits: the exit status code and stderr.
    fn stop(mut self, signal: &str) -> (Option<i32>, String) {
        let mut child = self.child.take().expect("running");
        let sent = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .expect("kill");
        assert!(sent.success());
        let status = child.wait().expect("wait");
        let mut err = String::new();
        child
            .stderr
            .take()
            .expect("stderr")
            .read_to_string(&mut err)
            .expect("reading stderr");
        (status.code(), err)
    }
}

/// GET `target` from `addr` over a fresh connection: (status line, body).
fn fetch(addr: &str, target: &str) -> (String, Vec<u8>) {
    let mut stream = TcpStream::connect(addr).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("timeout");
    write!(
        stream,
        "GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("send");
    let mut all = Vec::new();
    stream.read_to_end(&mut all).expect("response");
    let end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("end of headers");
    let head = String::from_utf8_lossy(&all[..end]);
    let status = head.lines().next().expect("status line").to_string();
    (status, all[end + 4..].to_vec())
}

#[test]
fn serve_lists_the_store_and_stops_on_ctrl_c_and_sigterm() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("city.pointlet");
    ok(&["generate", "--points", "20k", "-o", s(&store)]);
    for signal in ["-INT", "-TERM"] {
        let served = Served::start(&[s(&store)], &[]);
        assert!(served
            .banner
            .starts_with("serving 1 stores at http://127.0.0.1:"));
        let text = &served.banner;
        assert!(text.contains(&served.url("/stores.json")), "{text}");
        assert!(
            text.contains(&served.url("/stores/city.pointlet")),
            "{text}"
        );

        let (status, body) = fetch(&served.addr, "/stores.json");
        assert!(status.contains(" 200 "), "{status}");
        let list: serde_json::Value = serde_json::from_slice(&body).expect("JSON");
        assert_eq!(list[0]["name"], "city");
        assert_eq!(list[0]["points"], 20_000);
        assert_eq!(list[0]["url"], "/stores/city.pointlet");
        assert_eq!(
            list[0]["size"],
            std::fs::metadata(&store).expect("size").len()
        );
        let (status, body) = fetch(&served.addr, "/stores/city.pointlet");
        assert!(status.contains(" 200 "), "{status}");
        assert!(
            body == std::fs::read(&store).expect("the store"),
            "the body is the store"
        );

        let (code, err) = served.stop(signal);
        assert_eq!(code, Some(0), "after kill {signal}:\n{err}");
        assert!(
            err.contains("stopped") && !err.contains("panicked"),
            "{err}"
        );
    }
}

/// `pointlet info --json` of `input`.
fn info(input: &str) -> serde_json::Value {
    serde_json::from_str(&ok(&["info", input, "--json", "--verify"])).expect("info JSON")
}

/// The pixels of `pointlet render INPUT` with fixed size and camera.
fn render(input: &str, png: &Path) -> Vec<u8> {
    ok(&[
        "render",
        input,
        "-o",
        s(png),
        "--width",
        "160",
        "--height",
        "120",
    ]);
    png_rgba(png)
}

#[test]
fn commands_read_the_served_store_as_they_read_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let store = d.join("autzen.pointlet");
    ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&store)]);
    let served = Served::start(&[s(d)], &[]);
    assert!(
        served.banner.starts_with("serving 1 stores at "),
        "{}",
        served.banner
    );
    let url = served.url("/stores/autzen.pointlet");

    let local = info(s(&store));
    assert_eq!(info(&url), local, "info of the URL and of the file");
    assert!(local["points"].as_u64().expect("points") > 1000);

    let expected = render(s(&store), &d.join("local.png"));
    assert!(
        expected.chunks(4).any(|p| p[..3] != [0, 0, 0]),
        "drawn black"
    );
    assert!(
        render(&url, &d.join("remote.png")) == expected,
        "rendering the URL differs from rendering the file"
    );

    ok(&["export", s(&store), "-o", s(&d.join("local.las"))]);
    ok(&["export", &url, "-o", s(&d.join("remote.las"))]);
    let read = |name: &str| std::fs::read(d.join(name)).expect("exported file");
    assert!(
        read("local.las") == read("remote.las"),
        "export of the URL differs"
    );

    // Through a proxy that resets some connections and answers 503 to others, the reader's
    // retries still give the same picture.
    let proxy = FaultyProxy::start(&served.addr, 5);
    let proxied = format!("http://{}/stores/autzen.pointlet", proxy.addr);
    assert!(
        render(&proxied, &d.join("proxied.png")) == expected,
        "rendering through the faulty proxy differs"
    );
    assert!(
        proxy.faults.load(Ordering::Relaxed) > 0,
        "the proxy injected no fault"
    );

    let missing = served.url("/stores/none.pointlet");
    fails(&["info", &missing], &["none.pointlet"]);
    let (code, err) = served.stop("-TERM");
    assert_eq!(code, Some(0), "{err}");
}

/// A loopback proxy in front of `upstream` that breaks every `every`-th request: it closes the
/// connection without an answer, or answers 503 (in turn); the others are passed on whole.
struct FaultyProxy {
    addr: String,
    faults: Arc<AtomicUsize>,
}

impl FaultyProxy {
    fn start(upstream: &str, every: usize) -> FaultyProxy {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind the proxy");
        let addr = listener.local_addr().expect("proxy address").to_string();
        let faults = Arc::new(AtomicUsize::new(0));
        let (upstream, counted) = (upstream.to_string(), Arc::clone(&faults));
        std::thread::spawn(move || {
            let requests = Arc::new(AtomicUsize::new(0));
            for conn in listener.incoming() {
                let Ok(conn) = conn else { continue };
                let (upstream, requests, counted) = (
                    upstream.clone(),
                    Arc::clone(&requests),
                    Arc::clone(&counted),
                );
                std::thread::spawn(move || {
                    let _ = relay(conn, &upstream, &requests, &counted, every);
                });
            }
        });
        FaultyProxy { addr, faults }
    }
}

/// Serves one client connection, a request at a time, each over a fresh upstream connection.
fn relay(
    client: TcpStream,
    upstream: &str,
    requests: &AtomicUsize,
    faults: &AtomicUsize,
    every: usize,
) -> std::io::Result<()> {
    let mut reader = BufReader::new(client.try_clone()?);
    let mut client = client;
    loop {
        let mut head = Vec::new();
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line)? == 0 {
                return Ok(());
            }
            let end = line == "\r\n";
            // Each request goes upstream on its own connection, which closes after it.
            if !line.to_ascii_lowercase().starts_with("connection:") {
                head.extend_from_slice(line.as_bytes());
            }
            if end {
                break;
            }
        }
        let n = requests.fetch_add(1, Ordering::Relaxed) + 1;
        if n.is_multiple_of(every) {
            let k = faults.fetch_add(1, Ordering::Relaxed);
            if k.is_multiple_of(2) {
                return Ok(());
            }
            let busy = "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n\r\n";
            client.write_all(busy.as_bytes())?;
            continue;
        }
        let end = head.len() - 2;
        head.truncate(end);
        head.extend_from_slice(b"Connection: close\r\n\r\n");
        let mut up = TcpStream::connect(upstream)?;
        up.write_all(&head)?;
        let mut answer = Vec::new();
        up.read_to_end(&mut answer)?;
        // The answer's own length frames it on the kept-alive client connection.
        client.write_all(&answer)?;
    }
}

#[test]
fn serve_finds_the_web_viewer_and_says_when_it_is_missing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let store = d.join("a.pointlet");
    ok(&["generate", "--points", "5k", "-o", s(&store)]);
    let web = d.join("web");
    std::fs::create_dir_all(web.join("pkg")).expect("mkdir");
    std::fs::write(web.join("index.html"), "<!doctype html><p>the viewer").expect("write");
    std::fs::write(web.join("pkg/app.wasm"), b"\0asm\x01\0\0\0").expect("write");

    let by_flag = Served::start(&[s(&store), "--web-dir", s(&web)], &[]);
    let (status, body) = fetch(&by_flag.addr, "/");
    assert!(
        status.contains(" 200 ") && String::from_utf8_lossy(&body).contains("the viewer"),
        "{status}"
    );
    let (status, _) = fetch(&by_flag.addr, "/pkg/app.wasm");
    assert!(status.contains(" 200 "), "{status}");
    drop(by_flag);

    let by_env = Served::start(&[s(&store)], &[("POINTLET_WEB_DIR", &web)]);
    let (status, body) = fetch(&by_env.addr, "/");
    assert!(
        status.contains(" 200 ") && String::from_utf8_lossy(&body).contains("the viewer"),
        "{status}"
    );
    drop(by_env);

    fails(
        &["serve", s(&store), "--web-dir", s(&d.join("nowhere"))],
        &["viewer folder", "nowhere"],
    );
}

#[test]
fn serve_refuses_what_it_cannot_serve() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    fails(
        &["serve", s(&d.join("missing.pointlet"))],
        &["missing.pointlet"],
    );
    let text = d.join("notes.txt");
    std::fs::write(&text, "hello").expect("write");
    fails(&["serve", s(&text)], &["notes.txt", "not a store"]);
    fails(&["serve", s(d)], &["holds no .pointlet stores"]);
    usage_fails(&["serve"], &["STORE_OR_DIR"]);
    usage_fails(&["serve", s(&text), "--bind", "nowhere"], &["--bind"]);

    let store = d.join("a.pointlet");
    ok(&["generate", "--points", "5k", "-o", s(&store)]);
    let taken = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = taken.local_addr().expect("addr").to_string();
    fails(
        &["serve", s(&store), "--bind", &addr],
        &["cannot listen on", &addr],
    );
}
