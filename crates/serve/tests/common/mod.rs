//! What the server's tests share: small stores from the synthetic scene, a server on a free
//! loopback port, and a raw HTTP/1.1 client that sends request targets exactly as written
//! (an HTTP client library would normalise `..` and percent-encodings away).

#![allow(dead_code)]

use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::PointReader;
use pointlet_serve::{RunningServer, ServeConfig, Server};
use pointlet_store::{BuildConfig, StoreBuilder};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Writes a store of the generated scene (`points` points, `seed`) at `path`, replacing any
/// file there the way `convert` does (a new file renamed into place).
pub fn build_store(path: &Path, points: u64, seed: u64) {
    let generator = SceneGenerator::new(SceneConfig { points, seed });
    let meta = generator.meta();
    let config = BuildConfig {
        target_pointlets: 64,
        seed,
        ..Default::default()
    };
    let mut builder =
        StoreBuilder::create(path, config, &meta, vec!["test".into()]).expect("builder");
    let mut reader = generator.reader();
    while let Some(b) = reader.read_batch(1 << 16).expect("generate") {
        builder.push(&b).expect("push");
    }
    builder.finish().expect("finish");
}

/// Serves `stores` (and `viewer`) on a free loopback port.
pub fn serve(stores: &[PathBuf], viewer: Option<&Path>) -> RunningServer {
    let mut config = ServeConfig::new(stores.to_vec());
    config.bind = "127.0.0.1:0".parse().unwrap();
    config.viewer_dir = viewer.map(Path::to_path_buf);
    Server::bind(config).expect("server starts")
}

/// A response as it came over the wire.
#[derive(Debug)]
pub struct Raw {
    pub status: u16,
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Raw {
    /// The value of header `name` (case-insensitive); panics when it appears more than once.
    pub fn header(&self, name: &str) -> Option<&str> {
        let mut found = self
            .headers
            .iter()
            .filter(|(k, _)| k.eq_ignore_ascii_case(name));
        let first = found.next().map(|(_, v)| v.as_str());
        assert!(found.next().is_none(), "header {name} appears twice");
        first
    }

    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// Sends `METHOD TARGET HTTP/1.1` with `headers` on a new connection and reads the answer to
/// the end (the request asks to close the connection).
pub fn request(addr: SocketAddr, method: &str, target: &str, headers: &[(&str, &str)]) -> Raw {
    let mut head = format!("{method} {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    request_bytes(addr, head.as_bytes(), method == "HEAD")
}

/// Sends `raw` bytes as the request and parses what comes back.
pub fn request_bytes(addr: SocketAddr, raw: &[u8], head: bool) -> Raw {
    let mut stream = TcpStream::connect(addr).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    stream.write_all(raw).expect("send");
    let mut all = Vec::new();
    stream.read_to_end(&mut all).expect("read the response");
    parse(&all, head)
}

pub fn get(addr: SocketAddr, target: &str, headers: &[(&str, &str)]) -> Raw {
    request(addr, "GET", target, headers)
}

fn parse(all: &[u8], head: bool) -> Raw {
    let end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no end of headers in {:?}", String::from_utf8_lossy(all)));
    let text = std::str::from_utf8(&all[..end]).expect("ASCII headers");
    let mut lines = text.split("\r\n");
    let status_line = lines.next().unwrap();
    let status: u16 = status_line
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("bad status line {status_line:?}"));
    let headers: Vec<(String, String)> = lines
        .map(|l| {
            let (k, v) = l.split_once(':').expect("header line");
            (k.trim().to_string(), v.trim().to_string())
        })
        .collect();
    let body = all[end + 4..].to_vec();
    let raw = Raw {
        status,
        headers,
        body,
    };
    if let Some(len) = raw.header("content-length") {
        let len: usize = len.parse().unwrap();
        let expected = if head || status == 304 { 0 } else { len };
        assert_eq!(raw.body.len(), expected, "body length vs Content-Length");
    }
    assert!(
        raw.header("transfer-encoding").is_none() || !head,
        "chunked answer to HEAD"
    );
    raw
}

/// Resident memory of this process, in bytes.
pub fn rss_bytes() -> u64 {
    status_kib("VmRSS:") * 1024
}

/// Peak resident memory of this process since the last [`reset_peak_rss`], in bytes.
pub fn peak_rss_bytes() -> u64 {
    status_kib("VmHWM:") * 1024
}

/// Resets the peak of resident memory; false where the kernel does not allow it.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

fn status_kib(field: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with(field))
        .expect("field");
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}
