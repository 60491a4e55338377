//! Helpers shared by the CLI integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata")
}

pub fn data(name: &str) -> PathBuf {
    let p = data_dir().join(name);
    assert!(
        p.exists(),
        "test data {} is missing (testdata/ in the repository)",
        p.display()
    );
    p
}

pub fn pointlet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .args(args)
        .output()
        .expect("running the pointlet binary")
}

/// Runs and asserts success, returning stdout.
pub fn ok(args: &[&str]) -> String {
    let out = pointlet(args);
    assert!(
        out.status.success(),
        "pointlet {:?} failed:\n{}",
        args,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs and asserts a clean failure: exit code 1, an `error:` line containing every `needles`,
/// and no panic.
pub fn fails(args: &[&str], needles: &[&str]) -> String {
    let out = pointlet(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(1),
        "pointlet {args:?} should fail cleanly:\n{err}"
    );
    assert!(
        !err.contains("panicked"),
        "pointlet {args:?} panicked:\n{err}"
    );
    assert!(err.starts_with("error: "), "no error line:\n{err}");
    for n in needles {
        assert!(
            err.to_lowercase().contains(&n.to_lowercase()),
            "pointlet {args:?}: message lacks '{n}':\n{err}"
        );
    }
    err
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Files in `dir` (to prove nothing was left behind).
pub fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("listing")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs and asserts a usage error: exit code 2 (as clap's own), an `error:` line containing
/// every `needles`.
pub fn usage_fails(args: &[&str], needles: &[&str]) {
    let out = pointlet(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "pointlet {args:?}:\n{err}");
    assert!(err.starts_with("error: "), "no error line:\n{err}");
    for n in needles {
        assert!(
            err.contains(n),
            "pointlet {args:?}: message lacks '{n}':\n{err}"
        );
    }
}

/// Runs and asserts success, returning stderr.
pub fn ok_stderr(args: &[&str]) -> String {
    let out = pointlet(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "pointlet {args:?} failed:\n{err}");
    err
}

/// The RGBA pixels of a PNG the binary wrote.
pub fn png_rgba(path: &Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).expect("open png"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("png size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    buf.truncate(info.buffer_size());
    buf
}
