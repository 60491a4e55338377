//! The store route over real HTTP: whole files, every form of byte range, refused ranges,
//! HEAD, validators and conditional requests, a store replaced while served, CORS, content
//! types and `stores.json`.

mod common;

use common::{build_store, get, request, serve};
use std::path::PathBuf;

/// A served store of a few hundred kilobytes (several read chunks) and its bytes.
fn served() -> (
    tempfile::TempDir,
    PathBuf,
    Vec<u8>,
    pointlet_serve::RunningServer,
) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.pointlet");
    build_store(&path, 20_000, 1);
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() > 3 * pointlet_serve::config::CHUNK_BYTES);
    let server = serve(std::slice::from_ref(&path), None);
    (dir, path, bytes, server)
}

const STORE: &str = "/stores/city.pointlet";

#[test]
fn whole_file_and_its_headers() {
    let (_dir, _path, bytes, server) = served();
    let r = get(server.local_addr(), STORE, &[]);
    assert_eq!(r.status, 200);
    assert!(r.body == bytes, "the body is the file");
    assert_eq!(
        r.header("content-length"),
        Some(bytes.len().to_string().as_str())
    );
    assert_eq!(r.header("content-type"), Some("application/octet-stream"));
    assert_eq!(r.header("accept-ranges"), Some("bytes"));
    assert_eq!(r.header("cache-control"), Some("no-cache"));
    assert!(r.header("content-range").is_none());
    let etag = r.header("etag").unwrap();
    assert!(
        etag.starts_with('"') && etag.ends_with('"') && etag.len() > 2,
        "strong: {etag}"
    );
    assert!(r.header("last-modified").unwrap().ends_with(" GMT"));
    assert_eq!(r.header("x-content-type-options"), Some("nosniff"));
    server.shutdown().unwrap();
}

#[test]
fn every_range_form_gives_exactly_its_bytes() {
    let (_dir, _path, bytes, server) = served();
    let len = bytes.len() as u64;
    let chunk = pointlet_serve::config::CHUNK_BYTES as u64;
    // (Range header, first byte, last byte) of what must come back.
    let cases = [
        ("bytes=0-0".to_string(), 0, 0),
        ("bytes=0-99".to_string(), 0, 99),
        ("bytes=10-".to_string(), 10, len - 1),
        ("bytes=-1".to_string(), len - 1, len - 1),
        ("bytes=-500".to_string(), len - 500, len - 1),
        (format!("bytes=-{}", len + 1000), 0, len - 1),
        (
            format!("bytes={}-{}", len - 5, len + 1_000_000),
            len - 5,
            len - 1,
        ),
        (format!("bytes=0-{}", u64::MAX), 0, len - 1),
        ("bytes=0-99999999999999999999999999".to_string(), 0, len - 1),
        (format!("bytes={}-{}", chunk - 1, chunk), chunk - 1, chunk),
        (
            format!("bytes={}-{}", chunk - 7, 2 * chunk + 7),
            chunk - 7,
            2 * chunk + 7,
        ),
        (format!("bytes={}-", len - 1), len - 1, len - 1),
        ("Bytes=3-4".to_string(), 3, 4),
        ("bytes=3-4,".to_string(), 3, 4),
    ];
    for (range, first, last) in cases {
        let r = get(server.local_addr(), STORE, &[("Range", &range)]);
        assert_eq!(r.status, 206, "{range}: {}", r.text());
        assert!(
            r.body == bytes[first as usize..=last as usize],
            "{range}: wrong bytes"
        );
        assert_eq!(
            r.header("content-range"),
            Some(format!("bytes {first}-{last}/{len}").as_str()),
            "{range}"
        );
        assert_eq!(
            r.header("content-length"),
            Some((last - first + 1).to_string().as_str())
        );
        assert_eq!(r.header("content-type"), Some("application/octet-stream"));
        assert!(r.header("etag").is_some() && r.header("last-modified").is_some());
    }
    server.shutdown().unwrap();
}

#[test]
fn refused_ranges_get_416_with_the_size_and_other_units_are_ignored() {
    let (_dir, _path, bytes, server) = served();
    let len = bytes.len();
    let past = format!("bytes={len}-");
    let far = format!("bytes={}-{}", len + 10, len + 20);
    for range in [
        "bytes=5-2",
        "bytes=abc",
        "bytes=-0",
        "bytes=",
        "bytes=-",
        "bytes=1-2-3",
        "bytes=+1-2",
        "bytes=0x10-0x20",
        "bytes 0-1",
        "bytes=0-1,5-6",
        "bytes=0-1, 100-200",
        past.as_str(),
        far.as_str(),
    ] {
        let r = get(server.local_addr(), STORE, &[("Range", range)]);
        assert_eq!(r.status, 416, "{range}");
        assert_eq!(
            r.header("content-range"),
            Some(format!("bytes */{len}").as_str()),
            "{range}"
        );
        assert!(r.header("content-type").unwrap().starts_with("text/plain"));
        assert!(
            r.body.len() < 1000 && !r.body.is_empty(),
            "{range}: a short reason"
        );
    }
    // A range in another unit is ignored, as RFC 9110 §14.2 requires: the whole file.
    let other_unit = get(server.local_addr(), STORE, &[("Range", "items=0-1")]);
    assert_eq!(other_unit.status, 200);
    assert!(other_unit.body == bytes);
    let multi = get(server.local_addr(), STORE, &[("Range", "bytes=0-1,5-6")]);
    assert!(
        multi.text().contains("one range per request"),
        "{}",
        multi.text()
    );
    let malformed = get(server.local_addr(), STORE, &[("Range", "bytes=5-2")]);
    assert!(
        malformed.text().contains("malformed"),
        "{}",
        malformed.text()
    );
    server.shutdown().unwrap();
}

#[test]
fn head_has_the_headers_of_get_and_no_body() {
    let (_dir, _path, bytes, server) = served();
    let addr = server.local_addr();
    let get_r = get(addr, STORE, &[]);
    let head = request(addr, "HEAD", STORE, &[]);
    assert_eq!(head.status, 200);
    assert!(head.body.is_empty());
    for name in [
        "content-length",
        "content-type",
        "etag",
        "last-modified",
        "accept-ranges",
        "cache-control",
    ] {
        assert_eq!(head.header(name), get_r.header(name), "{name}");
    }
    assert_eq!(
        head.header("content-length"),
        Some(bytes.len().to_string().as_str())
    );
    // Range is defined for GET only (RFC 9110 §14.2): HEAD answers as for the whole file.
    let ranged = request(addr, "HEAD", STORE, &[("Range", "bytes=0-9")]);
    assert_eq!(ranged.status, 200);
    assert_eq!(
        ranged.header("content-length"),
        get_r.header("content-length")
    );
    let listed = request(addr, "HEAD", "/stores.json", &[]);
    assert_eq!(listed.status, 200);
    assert!(listed.body.is_empty());
    server.shutdown().unwrap();
}

#[test]
fn conditional_requests_follow_the_etag() {
    let (_dir, path, bytes, server) = served();
    let addr = server.local_addr();
    let first = get(addr, STORE, &[]);
    let etag = first.header("etag").unwrap().to_string();
    let last_modified = first.header("last-modified").unwrap().to_string();

    let not_modified = get(addr, STORE, &[("If-None-Match", &etag)]);
    assert_eq!(not_modified.status, 304);
    assert!(not_modified.body.is_empty());
    assert_eq!(not_modified.header("etag"), Some(etag.as_str()));
    let length = not_modified.header("content-length");
    assert!(
        length.is_none() || length == Some(bytes.len().to_string().as_str()),
        "a 304's Content-Length is the 200's or none: {length:?}"
    );
    let weak = format!("\"nope\", W/{etag}");
    assert_eq!(get(addr, STORE, &[("If-None-Match", &weak)]).status, 304);
    assert_eq!(
        request(addr, "HEAD", STORE, &[("If-None-Match", &etag)]).status,
        304
    );
    assert_eq!(
        get(addr, STORE, &[("If-None-Match", "\"other\"")]).status,
        200
    );
    assert_eq!(
        get(addr, STORE, &[("If-Modified-Since", &last_modified)]).status,
        304
    );
    assert_eq!(get(addr, STORE, &[("If-Match", "\"other\"")]).status, 412);
    assert_eq!(get(addr, STORE, &[("If-Match", &etag)]).status, 200);

    // If-Range: the current ETag keeps the range, another one gets the whole file.
    let kept = get(addr, STORE, &[("Range", "bytes=0-9"), ("If-Range", &etag)]);
    assert_eq!(kept.status, 206);
    assert!(kept.body == bytes[..10]);
    let stale = get(
        addr,
        STORE,
        &[("Range", "bytes=0-9"), ("If-Range", "\"old\"")],
    );
    assert_eq!(stale.status, 200);
    assert!(stale.body == bytes);
    let by_date = get(
        addr,
        STORE,
        &[("Range", "bytes=0-9"), ("If-Range", &last_modified)],
    );
    assert_eq!(by_date.status, 206);

    // A new store written to the same path: new ETag, new bytes, the old tags no longer hold.
    build_store(&path, 30_000, 2);
    let new_bytes = std::fs::read(&path).unwrap();
    let second = get(addr, STORE, &[]);
    assert_eq!(second.status, 200);
    assert!(second.body == new_bytes);
    let new_etag = second.header("etag").unwrap().to_string();
    assert_ne!(new_etag, etag, "replacing the file changes the ETag");
    assert_eq!(get(addr, STORE, &[("If-None-Match", &etag)]).status, 200);
    assert_eq!(
        get(addr, STORE, &[("If-None-Match", &new_etag)]).status,
        304
    );
    let stale = get(addr, STORE, &[("Range", "bytes=0-9"), ("If-Range", &etag)]);
    assert_eq!(
        stale.status, 200,
        "a range of the old file is not mixed into the new"
    );
    assert!(stale.body == new_bytes);
    let listed: serde_json::Value =
        serde_json::from_slice(&get(addr, "/stores.json", &[]).body).unwrap();
    assert_eq!(listed[0]["etag"], new_etag.as_str());
    assert_eq!(listed[0]["points"], 30_000);
    assert_eq!(listed[0]["size"], new_bytes.len() as u64);
    server.shutdown().unwrap();
}

#[test]
fn cors_for_any_origin_and_preflights() {
    let (_dir, _path, _bytes, server) = served();
    let addr = server.local_addr();
    let r = get(
        addr,
        STORE,
        &[("Origin", "http://example.test"), ("Range", "bytes=0-3")],
    );
    assert_eq!(r.status, 206);
    assert_eq!(r.header("access-control-allow-origin"), Some("*"));
    let exposed = r
        .header("access-control-expose-headers")
        .unwrap()
        .to_lowercase();
    for h in ["content-range", "etag", "accept-ranges", "content-length"] {
        assert!(exposed.contains(h), "{h} not exposed: {exposed}");
    }
    let preflight = request(
        addr,
        "OPTIONS",
        STORE,
        &[
            ("Origin", "http://example.test"),
            ("Access-Control-Request-Method", "GET"),
            ("Access-Control-Request-Headers", "range, if-none-match"),
        ],
    );
    assert!(
        preflight.status == 200 || preflight.status == 204,
        "{preflight:?}"
    );
    assert_eq!(preflight.header("access-control-allow-origin"), Some("*"));
    let methods = preflight.header("access-control-allow-methods").unwrap();
    assert!(
        methods.contains("GET") && methods.contains("HEAD"),
        "{methods}"
    );
    let allowed = preflight
        .header("access-control-allow-headers")
        .unwrap()
        .to_lowercase();
    assert!(allowed.contains("range") || allowed == "*", "{allowed}");
    // Errors carry CORS too, so a page can read why.
    let missing = get(
        addr,
        "/stores/none.pointlet",
        &[("Origin", "http://example.test")],
    );
    assert_eq!(missing.status, 404);
    assert_eq!(missing.header("access-control-allow-origin"), Some("*"));
    // Only GET and HEAD.
    assert_eq!(
        request(addr, "POST", STORE, &[("Content-Length", "0")]).status,
        405
    );
    assert_eq!(request(addr, "DELETE", "/anything", &[]).status, 405);
    server.shutdown().unwrap();
}

#[test]
fn stores_json_lists_exactly_the_given_stores() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("folder");
    std::fs::create_dir(&folder).unwrap();
    build_store(&folder.join("a.pointlet"), 3_000, 1);
    build_store(&folder.join("b b.pointlet"), 4_000, 2);
    build_store(&dir.path().join("c.pointlet"), 5_000, 3);
    build_store(&dir.path().join("not-given.pointlet"), 3_000, 4);
    std::fs::write(folder.join("readme.txt"), "not a store").unwrap();
    std::fs::create_dir(folder.join("nested")).unwrap();
    build_store(&folder.join("nested/deep.pointlet"), 3_000, 5);
    let server = serve(&[folder.clone(), dir.path().join("c.pointlet")], None);
    let addr = server.local_addr();
    let r = get(addr, "/stores.json", &[]);
    assert_eq!(r.status, 200);
    assert_eq!(r.header("content-type"), Some("application/json"));
    assert_eq!(r.header("cache-control"), Some("no-cache"));
    let list: serde_json::Value = serde_json::from_slice(&r.body).unwrap();
    let list = list.as_array().unwrap();
    let names: Vec<&str> = list.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["a", "b b", "c"]);
    for (entry, (file, points)) in list.iter().zip([
        (folder.join("a.pointlet"), 3_000),
        (folder.join("b b.pointlet"), 4_000),
        (dir.path().join("c.pointlet"), 5_000),
    ]) {
        let bytes = std::fs::read(&file).unwrap();
        assert_eq!(entry["points"], points);
        assert_eq!(entry["size"], bytes.len() as u64);
        let store = pointlet_store::Store::open(&file).unwrap();
        let b = store.header().bounds;
        assert_eq!(entry["bounds"]["min"][0].as_f64().unwrap(), b.min[0]);
        assert_eq!(entry["bounds"]["max"][2].as_f64().unwrap(), b.max[2]);
        assert!(entry["pointlets"].as_u64().unwrap() >= 1);
        // Each listed URL serves the store, with the listed ETag.
        let url = entry["url"].as_str().unwrap();
        let served = get(addr, url, &[]);
        assert_eq!(served.status, 200, "{url}");
        assert!(served.body == bytes);
        assert_eq!(served.header("etag"), entry["etag"].as_str());
    }
    assert_eq!(list[1]["url"], "/stores/b%20b.pointlet");
    for hidden in [
        "/stores/not-given.pointlet",
        "/stores/deep.pointlet",
        "/stores/readme.txt",
    ] {
        assert_eq!(get(addr, hidden, &[]).status, 404, "{hidden}");
    }
    // The placeholder page links to the list.
    let index = get(addr, "/", &[]);
    assert_eq!(index.status, 200);
    assert_eq!(
        index.header("content-type"),
        Some("text/html; charset=utf-8")
    );
    let page = index.text();
    assert!(
        page.contains("/stores.json") && page.contains("not built yet"),
        "{page}"
    );
    assert!(page.contains("bash scripts/build-web.sh"), "{page}");
    assert!(page.contains("/stores/b%20b.pointlet"), "{page}");
    assert_eq!(server.stores().len(), 3);
    server.shutdown().unwrap();
}

#[test]
fn viewer_files_get_their_content_types() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("s.pointlet");
    build_store(&store, 2_000, 1);
    let viewer = dir.path().join("viewer");
    std::fs::create_dir_all(viewer.join("pkg")).unwrap();
    std::fs::write(viewer.join("index.html"), "<!doctype html><p>viewer").unwrap();
    std::fs::write(viewer.join("pkg/viewer.js"), "export {}").unwrap();
    std::fs::write(viewer.join("pkg/viewer_bg.wasm"), b"\0asm\x01\0\0\0").unwrap();
    std::fs::write(viewer.join("style.css"), "p{}").unwrap();
    let server = serve(&[store], Some(&viewer));
    let addr = server.local_addr();
    for (target, ty, body) in [
        (
            "/",
            "text/html; charset=utf-8",
            &b"<!doctype html><p>viewer"[..],
        ),
        (
            "/index.html",
            "text/html; charset=utf-8",
            b"<!doctype html><p>viewer",
        ),
        (
            "/pkg/viewer.js",
            "text/javascript; charset=utf-8",
            b"export {}",
        ),
        (
            "/pkg/viewer_bg.wasm",
            "application/wasm",
            b"\0asm\x01\0\0\0",
        ),
        (
            "/pkg/%76iewer.js",
            "text/javascript; charset=utf-8",
            b"export {}",
        ),
        ("/style.css", "text/css; charset=utf-8", b"p{}"),
    ] {
        let r = get(addr, target, &[]);
        assert_eq!(r.status, 200, "{target}");
        assert_eq!(r.header("content-type"), Some(ty), "{target}");
        assert_eq!(r.body, body, "{target}");
        assert!(r.header("etag").is_some());
    }
    let ranged = get(addr, "/pkg/viewer_bg.wasm", &[("Range", "bytes=0-3")]);
    assert_eq!(ranged.status, 206);
    assert_eq!(ranged.body, b"\0asm");
    for missing in ["/pkg/", "/pkg", "/nope.js", "/stores/"] {
        assert_eq!(get(addr, missing, &[]).status, 404, "{missing}");
    }
    server.shutdown().unwrap();
}
