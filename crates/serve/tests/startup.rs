//! What the server is given and where it listens: clear errors for what cannot be served
//! (missing paths, files that are not stores, damaged stores, empty folders, duplicate
//! names, a port in use), and a clean stop.

mod common;

use common::{build_store, get};
use pointlet_serve::{ServeConfig, ServeError, Server};
use std::path::PathBuf;

fn bind(stores: Vec<PathBuf>) -> Result<pointlet_serve::RunningServer, ServeError> {
    let mut config = ServeConfig::new(stores);
    config.bind = "127.0.0.1:0".parse().unwrap();
    Server::bind(config)
}

fn error(stores: Vec<PathBuf>) -> String {
    match bind(stores) {
        Ok(_) => panic!("should not start"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn what_cannot_be_served_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    build_store(&d.join("good.pointlet"), 2_000, 1);

    let e = error(vec![]);
    assert!(e.contains("no stores"), "{e}");

    let e = error(vec![d.join("missing.pointlet")]);
    assert!(
        e.contains("missing.pointlet") && e.contains("No such file"),
        "{e}"
    );

    std::fs::write(d.join("notes.txt"), "hello").unwrap();
    let e = error(vec![d.join("notes.txt")]);
    assert!(e.contains("notes.txt") && e.contains("not a store"), "{e}");

    std::fs::write(d.join("fake.pointlet"), "this is not a store at all").unwrap();
    let e = error(vec![d.join("good.pointlet"), d.join("fake.pointlet")]);
    assert!(
        e.contains("fake.pointlet") && e.contains("not a valid store"),
        "{e}"
    );

    // A damaged store inside a folder is refused too: everything listed must be servable.
    let mixed = d.join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    build_store(&mixed.join("ok.pointlet"), 2_000, 1);
    let mut cut = std::fs::read(mixed.join("ok.pointlet")).unwrap();
    cut.truncate(cut.len() / 2);
    std::fs::write(mixed.join("cut.pointlet"), cut).unwrap();
    let e = error(vec![mixed.clone()]);
    assert!(e.contains("cut.pointlet"), "{e}");

    let empty = d.join("empty");
    std::fs::create_dir(&empty).unwrap();
    std::fs::write(empty.join("readme.txt"), "no stores here").unwrap();
    let e = error(vec![d.join("good.pointlet"), empty.clone()]);
    assert!(
        e.contains("empty") && e.contains("holds no .pointlet stores"),
        "{e}"
    );

    let other = d.join("other");
    std::fs::create_dir(&other).unwrap();
    build_store(&other.join("good.pointlet"), 2_000, 2);
    let e = error(vec![d.join("good.pointlet"), other.clone()]);
    assert!(
        e.contains("two stores would be served as good.pointlet"),
        "{e}"
    );
}

#[test]
fn the_same_store_given_twice_is_served_once() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("good.pointlet");
    build_store(&store, 2_000, 1);
    let server = bind(vec![store.clone(), dir.path().to_path_buf(), store]).unwrap();
    assert_eq!(server.stores().len(), 1);
    let list: serde_json::Value =
        serde_json::from_slice(&get(server.local_addr(), "/stores.json", &[]).body).unwrap();
    assert_eq!(list.as_array().unwrap().len(), 1);
    server.shutdown().unwrap();
}

#[test]
fn a_port_in_use_is_a_clear_error_and_shutdown_frees_it() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("good.pointlet");
    build_store(&store, 2_000, 1);
    let first = bind(vec![store.clone()]).unwrap();
    let addr = first.local_addr();
    assert_ne!(addr.port(), 0);
    let mut config = ServeConfig::new(vec![store.clone()]);
    config.bind = addr;
    let e = match Server::bind(config.clone()) {
        Ok(_) => panic!("bound a port in use"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains(&format!("cannot listen on {addr}")), "{e}");
    // A handle from another thread stops it; then the port is free again.
    let handle = first.shutdown_handle();
    std::thread::spawn(move || handle.shutdown());
    first.wait().unwrap();
    let again = Server::bind(config).expect("the port is free after shutdown");
    assert_eq!(get(again.local_addr(), "/stores.json", &[]).status, 200);
    again.shutdown().unwrap();
}
