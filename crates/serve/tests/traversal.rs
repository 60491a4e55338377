//! Nothing but the given stores (and the viewer folder's files) can be read: traversal in
//! every spelling, absolute paths, NUL, symlinks not given, symlinks inside a given folder,
//! a store replaced by a symlink while served, and no folder listings.

mod common;

use common::{build_store, get, request_bytes, serve};
use std::os::unix::fs::symlink;
use std::path::Path;

const SECRET: &str = "top secret: never served\n";

/// Whether an answer leaked the secret file or /etc/passwd.
fn leaked(r: &common::Raw) -> bool {
    let text = r.text();
    text.contains("top secret") || text.contains("root:")
}

fn targets(dir: &Path) -> Vec<String> {
    let abs = dir.join("secret.txt");
    let abs = abs.to_str().unwrap();
    let mut t: Vec<String> = [
        "/etc/passwd",
        "/../../../../etc/passwd",
        "/stores/../../../../etc/passwd",
        "/stores/../secret.txt",
        "/stores/..%2f..%2f..%2f..%2fetc%2fpasswd",
        "/stores/%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/stores/%2e%2e%2f%2e%2e%2f%2e%2e%2f%2e%2e%2fetc%2fpasswd",
        "/stores/%252e%252e%252f%252e%252e%252fetc%252fpasswd",
        "/stores/..%5c..%5c..%5cetc%5cpasswd",
        "/stores/..\\..\\..\\etc\\passwd",
        "/stores//etc/passwd",
        "/stores/%2fetc%2fpasswd",
        "/stores/secret.txt",
        "/stores/passwd.pointlet",
        "/stores/city.pointlet/../secret.txt",
        "/stores/city.pointlet%00",
        "/stores/city%00.pointlet",
        "/stores/city.pointlet/",
        "/stores/./city.pointlet/.",
        "/stores/",
        "/stores",
        "/secret.txt",
        "/%2e%2e/secret.txt",
        "/..%2fsecret.txt",
        "/....//secret.txt",
        "//etc/passwd",
        "http://localhost/etc/passwd",
        "/stores/http://localhost/etc/passwd",
        "/stores.json/../etc/passwd",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    t.push(abs.to_string());
    t.push(format!("/stores/{abs}"));
    t.push(format!("/stores/{}", abs.replace('/', "%2f")));
    t.push(format!(
        "/stores/{}",
        abs.replace('/', "%2F").replace('.', "%2E")
    ));
    t
}

/// A folder with a served store, a secret beside it and a symlink to /etc/passwd that was not
/// given; returns the store's path.
fn scene(dir: &Path) -> std::path::PathBuf {
    let store = dir.join("city.pointlet");
    build_store(&store, 2_000, 1);
    std::fs::write(dir.join("secret.txt"), SECRET).unwrap();
    symlink("/etc/passwd", dir.join("passwd.pointlet")).unwrap();
    symlink(dir.join("secret.txt"), dir.join("secret.pointlet")).unwrap();
    store
}

fn assert_refused(addr: std::net::SocketAddr, target: &str) {
    let r = get(addr, target, &[]);
    assert!(
        r.status == 404 || r.status == 400,
        "{target}: status {} ({})",
        r.status,
        r.text()
    );
    assert!(!leaked(&r), "{target} leaked: {}", r.text());
}

#[test]
fn traversal_in_every_spelling_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let store = scene(dir.path());
    let server = serve(&[store], None);
    let addr = server.local_addr();
    for target in targets(dir.path()) {
        assert_refused(addr, &target);
    }
    // The store itself is still served.
    assert_eq!(get(addr, "/stores/city.pointlet", &[]).status, 200);
    // A request line with a raw NUL or a backslash never reaches a file.
    for raw in [
        &b"GET /stores/city.pointlet\0/../../etc/passwd HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"[..],
        b"GET \\etc\\passwd HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
        b"GET ../../etc/passwd HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
    ] {
        let r = request_bytes(addr, raw, false);
        assert!(r.status == 400 || r.status == 404, "{:?}: {}", String::from_utf8_lossy(raw), r.status);
        assert!(!leaked(&r));
    }
    server.shutdown().unwrap();
}

#[test]
fn a_folder_serves_its_regular_stores_only() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    build_store(&dir.path().join("b.pointlet"), 2_000, 2);
    // A symlink to another store inside the folder is not followed either.
    symlink(
        dir.path().join("b.pointlet"),
        dir.path().join("alias.pointlet"),
    )
    .unwrap();
    let server = serve(&[dir.path().to_path_buf()], None);
    let names: Vec<&str> = server.stores().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["b", "city"]);
    let notes = server.notes().join("\n");
    for skipped in ["passwd.pointlet", "secret.pointlet", "alias.pointlet"] {
        assert!(notes.contains(skipped), "no note for {skipped}: {notes}");
    }
    let addr = server.local_addr();
    for target in targets(dir.path()) {
        assert_refused(addr, &target);
    }
    for target in ["/stores/secret.pointlet", "/stores/alias.pointlet"] {
        assert_refused(addr, target);
    }
    let list = get(addr, "/stores.json", &[]).text();
    assert!(!list.contains("passwd") && !list.contains("secret") && !list.contains("alias"));
    server.shutdown().unwrap();
}

#[test]
fn a_store_replaced_by_a_symlink_is_not_followed() {
    let dir = tempfile::tempdir().unwrap();
    let store = scene(dir.path());
    let server = serve(std::slice::from_ref(&store), None);
    let addr = server.local_addr();
    assert_eq!(get(addr, "/stores/city.pointlet", &[]).status, 200);
    std::fs::remove_file(&store).unwrap();
    symlink(dir.path().join("secret.txt"), &store).unwrap();
    let r = get(addr, "/stores/city.pointlet", &[]);
    assert_eq!(r.status, 404);
    assert!(!leaked(&r));
    let list = get(addr, "/stores.json", &[]);
    assert_eq!(list.status, 200);
    assert!(!leaked(&list));
    let list: serde_json::Value = serde_json::from_slice(&list.body).unwrap();
    assert!(list[0]["error"].is_string(), "{list}");
    std::fs::remove_file(&store).unwrap();
    assert_eq!(get(addr, "/stores/city.pointlet", &[]).status, 404);
    server.shutdown().unwrap();
}

#[test]
fn an_explicitly_given_symlink_is_served_under_its_own_name() {
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("data");
    std::fs::create_dir(&real).unwrap();
    build_store(&real.join("x.pointlet"), 2_000, 1);
    let link = dir.path().join("city.pointlet");
    symlink(real.join("x.pointlet"), &link).unwrap();
    let server = serve(&[link], None);
    let addr = server.local_addr();
    let r = get(addr, "/stores/city.pointlet", &[]);
    assert_eq!(r.status, 200);
    assert!(r.body == std::fs::read(real.join("x.pointlet")).unwrap());
    assert_eq!(get(addr, "/stores/x.pointlet", &[]).status, 404);
    server.shutdown().unwrap();
}

#[test]
fn the_viewer_folder_keeps_its_files_in() {
    let dir = tempfile::tempdir().unwrap();
    let store = scene(dir.path());
    let viewer = dir.path().join("viewer");
    std::fs::create_dir_all(viewer.join("pkg")).unwrap();
    std::fs::write(viewer.join("index.html"), "viewer").unwrap();
    std::fs::write(viewer.join("pkg/app.js"), "js").unwrap();
    std::fs::write(viewer.join(".hidden"), SECRET).unwrap();
    symlink("/etc/passwd", viewer.join("passwd")).unwrap();
    symlink(dir.path().join("secret.txt"), viewer.join("pkg/secret.js")).unwrap();
    symlink(dir.path(), viewer.join("up")).unwrap();
    let server = serve(&[store], Some(&viewer));
    let addr = server.local_addr();
    assert_eq!(get(addr, "/pkg/app.js", &[]).body, b"js");
    let mut all = targets(dir.path());
    all.extend(
        [
            "/passwd",
            "/pkg/secret.js",
            "/up/secret.txt",
            "/.hidden",
            "/pkg/../../secret.txt",
            "/pkg/%2e%2e/%2e%2e/secret.txt",
            "/pkg%2f..%2f..%2fsecret.txt",
            "/pkg/..%5c..%5csecret.txt",
            "/viewer/../secret.txt",
        ]
        .map(String::from),
    );
    for target in all {
        assert_refused(addr, &target);
    }
    // A folder is never listed.
    let pkg = get(addr, "/pkg/", &[]);
    assert_eq!(pkg.status, 404);
    assert!(!pkg.text().contains("app.js"));
    server.shutdown().unwrap();
}
