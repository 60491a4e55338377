//! Stores read over HTTP: the same points as the local file, transient faults retried, and a
//! replaced store, a missing or forbidden one and a stalled server ending in a clear error,
//! never a wrong read or a hang. The server is `common::range_server`, on loopback.

mod common;
use common::range_server::{Fault, RangeServer};
use common::*;
use pointlet_store::{BuildConfig, Store, StreamKind};
use std::path::Path;
use std::time::{Duration, Instant};

/// A generated store's bytes and the store opened locally.
fn store_bytes(dir: &Path) -> (Vec<u8>, Store) {
    let path = dir.join("s.pointlet");
    let batches = batches(RGB_GPS_EXTRA, 30_000, 7_000, 5);
    let config = BuildConfig {
        target_pointlets: 40,
        ..Default::default()
    };
    build(&path, config, &meta(RGB_GPS_EXTRA, 30_000), &batches);
    let bytes = std::fs::read(&path).expect("read");
    (bytes, Store::open(&path).expect("open"))
}

fn quick_timeouts() {
    // Every test of this binary sets the same value before its first request.
    std::env::set_var("POINTLET_REMOTE_TIMEOUT_MS", "700");
}

fn all_points(store: &Store) -> Vec<Vec<u64>> {
    let b = store
        .read_pointlets(0..store.pointlets().len())
        .expect("read");
    multiset([&b])
}

#[test]
fn a_store_over_http_reads_like_the_local_file() {
    quick_timeouts();
    let dir = tempfile::tempdir().expect("tempdir");
    let (bytes, local) = store_bytes(dir.path());
    let server = RangeServer::start(bytes);
    let url = server.url("stores/s.pointlet");
    let remote = Store::open(Path::new(&url)).expect("open over http");
    assert_eq!(remote.header(), local.header());
    assert_eq!(remote.pointlets(), local.pointlets());
    assert_eq!(all_points(&remote), all_points(&local));
    for i in 0..local.pointlets().len() {
        assert_eq!(
            remote.read_pointlet(i).expect("pointlet"),
            local.read_pointlet(i).expect("pointlet")
        );
    }
    remote.verify().expect("every byte checks out");
}

#[test]
fn transient_faults_are_retried() {
    quick_timeouts();
    let dir = tempfile::tempdir().expect("tempdir");
    let (bytes, local) = store_bytes(dir.path());
    let server = RangeServer::start(bytes);
    let remote = Store::open(Path::new(&server.url("s.pointlet"))).expect("open");
    for fault in [
        Fault::Status(503, 2),
        Fault::Status(500, 1),
        Fault::Reset(2),
        Fault::Short(1),
        Fault::Stall(Duration::from_millis(1500), 1),
    ] {
        server.inject(fault);
        assert_eq!(
            all_points(&remote),
            all_points(&local),
            "after {fault:?} the read is retried and right"
        );
    }
}

/// Prefixes and middles of every pointlet in every stream, as the loaders read them in batches.
fn batched_ranges(store: &Store) -> Vec<Vec<Vec<u8>>> {
    let requests: Vec<(usize, std::ops::Range<u32>)> = store
        .pointlets()
        .iter()
        .enumerate()
        .map(|(i, p)| (i, (i as u32 % 3) * p.count / 4..p.count - p.count / 5))
        .collect();
    let kinds: Vec<StreamKind> = store.header().streams.iter().map(|s| s.kind).collect();
    store
        .read_streams_raw_many(&requests, &kinds)
        .expect("batched read")
}

#[test]
fn batched_range_reads_survive_faults_and_match_the_local_file() {
    quick_timeouts();
    let dir = tempfile::tempdir().expect("tempdir");
    let (bytes, local) = store_bytes(dir.path());
    let server = RangeServer::start(bytes);
    let remote = Store::open(Path::new(&server.url("s.pointlet"))).expect("open");
    let expected = batched_ranges(&local);
    assert_eq!(batched_ranges(&remote), expected);
    for fault in [Fault::Status(503, 3), Fault::Reset(2), Fault::Short(2)] {
        server.inject(fault);
        assert_eq!(batched_ranges(&remote), expected, "after {fault:?}");
    }
}

#[test]
fn a_store_replaced_while_being_read_is_an_error() {
    quick_timeouts();
    let dir = tempfile::tempdir().expect("tempdir");
    let (bytes, _) = store_bytes(dir.path());
    let server = RangeServer::start(bytes.clone());
    let remote = Store::open(Path::new(&server.url("s.pointlet"))).expect("open");
    let mut other = bytes;
    let last = other.len() - 1;
    other[last] ^= 1;
    server.replace(other);
    let err = remote.read_pointlet(0).expect_err("the store changed");
    assert!(
        err.to_string().contains("changed while being read"),
        "{err}"
    );
}

#[test]
fn missing_forbidden_and_stalled_stores_are_clear_errors() {
    quick_timeouts();
    let dir = tempfile::tempdir().expect("tempdir");
    let (bytes, _) = store_bytes(dir.path());
    let server = RangeServer::start(bytes);
    for (code, needle) in [(404, "not found"), (403, "access denied")] {
        server.inject(Fault::Status(code, 1000));
        let url = server.url("s.pointlet");
        let err = Store::open(Path::new(&url)).expect_err("refused");
        let msg = err.to_string();
        assert!(msg.contains(needle) && msg.contains(&url), "{msg}");
        server.replace_faults();
    }
    // A server that never answers: the retries give up in bounded time.
    server.inject(Fault::Stall(Duration::from_secs(3600), 1000));
    let started = Instant::now();
    let err = Store::open(Path::new(&server.url("s.pointlet"))).expect_err("stalled");
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "gave up after {:?}",
        started.elapsed()
    );
    assert!(!err.to_string().is_empty());
}
