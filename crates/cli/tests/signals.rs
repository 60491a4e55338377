//! Ctrl-C (SIGINT) and SIGTERM in the middle of `convert`, `export` and `generate`: no
//! temporary output or run file remains, no output appears, and the exit status is 128 + signal.
#![cfg(unix)]

mod common;
use common::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Points in the generated input: enough that each command runs for seconds.
const POINTS: &str = "5M";

/// Hidden temporary files (`.NAME.PID.N.tmp` outputs, `.run` files) in `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    listing(dir)
        .into_iter()
        .filter(|n| n.starts_with('.'))
        .collect()
}

/// Starts `pointlet args`, waits until a temporary file whose name ends in `suffix` shows up in
/// `dir`, sends `signal`, and checks the exit status and that nothing but `keep` remains.
fn interrupt(args: &[&str], dir: &Path, suffix: &str, signal: &str, code: i32, keep: &[&str]) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting pointlet");
    let started = Instant::now();
    while !temporaries(dir).iter().any(|n| n.ends_with(suffix)) {
        if let Some(status) = child.try_wait().expect("try_wait") {
            panic!("pointlet {args:?} ended ({status}) before a {suffix} file appeared");
        }
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no {suffix} file"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let pid = child.id().to_string();
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &pid])
        .status()
        .expect("kill");
    assert!(sent.success());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(code),
        "pointlet {args:?} after SIG{signal}:\n{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        listing(dir),
        keep.iter().map(|s| s.to_string()).collect::<Vec<_>>(),
        "left behind after SIG{signal} to {args:?}"
    );
}

#[test]
fn signals_remove_temporary_files_and_runs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let las = d.join("g.las");
    let store = d.join("s.pointlet");
    let (las_s, store_s) = (s(&las), s(&store));
    // generate writes a hidden temporary LAZ, renamed at the end.
    let laz = d.join("g.laz");
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let args = ["generate", "--points", POINTS, "-o", s(&laz)];
        interrupt(&args, d, ".tmp", signal, code, &[]);
    }
    ok(&["generate", "--points", POINTS, "-o", las_s]);
    // A small budget makes convert spill runs beside the output: wait for one.
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let args = ["convert", las_s, "-o", store_s, "--ram-budget", "64MiB"];
        interrupt(&args, d, ".run", signal, code, &["g.las"]);
    }
    ok(&["convert", las_s, "-o", store_s]);
    let out = d.join("e.laz");
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let args = ["export", store_s, "-o", s(&out)];
        interrupt(&args, d, ".tmp", signal, code, &["g.las", "s.pointlet"]);
    }
}
