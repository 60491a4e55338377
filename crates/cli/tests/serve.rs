//! `pointlet serve`: a store served on a free loopback port, its list fetched, the server
//! stopped by Ctrl-C (SIGINT); bad arguments and a port in use end with a message.

mod common;

use common::{fails, ok, s, usage_fails};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Kills the server if a test fails before stopping it.
struct Guard(Option<Child>);

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some(child) = self.0.as_mut() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// GET `target` from `addr` over a fresh connection: (status line, body).
fn fetch(addr: &str, target: &str) -> (String, String) {
    let mut stream = TcpStream::connect(addr).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    write!(
        stream,
        "GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut all = String::new();
    stream.read_to_string(&mut all).expect("response");
    let (head, body) = all.split_once("\r\n\r\n").expect("headers");
    (head.lines().next().unwrap().to_string(), body.to_string())
}

#[test]
fn serve_lists_the_store_and_stops_on_ctrl_c() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("city.pointlet");
    ok(&["generate", "--points", "20k", "-o", s(&store)]);
    let child = Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .args(["serve", s(&store), "--bind", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting pointlet serve");
    let mut guard = Guard(Some(child));
    let child = guard.0.as_mut().unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut banner = Vec::new();
    loop {
        let mut line = String::new();
        let n = stdout.read_line(&mut line).expect("banner");
        assert!(n > 0, "the server ended early: {banner:?}");
        let done = line.starts_with("press Ctrl-C");
        banner.push(line);
        if done {
            break;
        }
    }
    let first = &banner[0];
    assert!(
        first.starts_with("serving 1 store on http://127.0.0.1:"),
        "{banner:?}"
    );
    let addr = first
        .trim()
        .trim_start_matches("serving 1 store on http://")
        .trim_end_matches('/')
        .to_string();
    let text = banner.concat();
    assert!(
        text.contains(&format!("http://{addr}/stores.json")),
        "{text}"
    );
    assert!(
        text.contains(&format!("http://{addr}/stores/city.pointlet")),
        "{text}"
    );

    let (status, body) = fetch(&addr, "/stores.json");
    assert!(status.contains(" 200 "), "{status}");
    let list: serde_json::Value = serde_json::from_str(&body).expect("JSON");
    assert_eq!(list[0]["name"], "city");
    assert_eq!(list[0]["points"], 20_000);
    assert_eq!(list[0]["url"], "/stores/city.pointlet");
    let (status, _) = fetch(&addr, "/stores/city.pointlet");
    assert!(status.contains(" 200 "), "{status}");

    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(sent.success());
    let mut child = guard.0.take().unwrap();
    let status = child.wait().expect("wait");
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(0), "after Ctrl-C:\n{err}");
    assert!(
        err.contains("stopped") && !err.contains("panicked"),
        "{err}"
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
    std::fs::write(&text, "hello").unwrap();
    fails(&["serve", s(&text)], &["notes.txt", "not a store"]);
    fails(&["serve", s(d)], &["holds no .pointlet stores"]);
    usage_fails(&["serve"], &["STORE_OR_DIR"]);
    usage_fails(&["serve", s(&text), "--bind", "nowhere"], &["--bind"]);

    let store = d.join("a.pointlet");
    ok(&["generate", "--points", "5k", "-o", s(&store)]);
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    fails(
        &["serve", s(&store), "--bind", &addr],
        &["cannot listen on", &addr],
    );
}
