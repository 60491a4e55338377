//! Many clients at once: 10 000 range requests, 200 in flight, all with the right bytes and
//! without the process's memory growing past a bound; clients that hang up mid-body or
//! mid-request leave the server serving.

mod common;

use common::{build_store, get, serve};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Arc;

/// A deterministic generator of request ranges (splitmix64).
struct Mix(u64);

impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

const REQUESTS: usize = 10_000;
const IN_FLIGHT: usize = 200;
/// The bound on the process's memory growth while the requests run.
const MAX_GROWTH: u64 = 64 << 20;

#[test]
fn ten_thousand_concurrent_range_requests() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("load.pointlet");
    build_store(&path, 20_000, 7);
    let bytes = Arc::new(std::fs::read(&path).unwrap());
    let len = bytes.len() as u64;
    let server = serve(&[path], None);
    let url = format!("http://{}/stores/load.pointlet", server.local_addr());

    // Ranges of every form, up to a little over two read chunks.
    let mut mix = Mix(42);
    let max_len = 2 * pointlet_serve::config::CHUNK_BYTES as u64 + 100;
    let ranges: Vec<(String, u64, u64)> = (0..REQUESTS)
        .map(|i| {
            let a = mix.next() % len;
            let n = 1 + mix.next() % max_len;
            match i % 4 {
                0 | 1 => {
                    let last = (a + n - 1).min(len - 1);
                    (format!("bytes={a}-{}", a + n - 1), a, last)
                }
                2 => (
                    format!("bytes={}-", len - n.min(len)),
                    len - n.min(len),
                    len - 1,
                ),
                _ => (format!("bytes=-{n}"), len.saturating_sub(n), len - 1),
            }
        })
        .collect();

    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let client = reqwest::Client::builder()
        .no_proxy()
        .pool_max_idle_per_host(IN_FLIGHT)
        .build()
        .unwrap();

    let run = |ranges: Vec<(String, u64, u64)>| {
        let client = client.clone();
        let url = url.clone();
        let bytes = Arc::clone(&bytes);
        runtime.block_on(async move {
            let semaphore = Arc::new(tokio::sync::Semaphore::new(IN_FLIGHT));
            let mut tasks = tokio::task::JoinSet::new();
            for (range, first, last) in ranges {
                let permit = Arc::clone(&semaphore).acquire_owned().await.unwrap();
                let (client, url, bytes) = (client.clone(), url.clone(), Arc::clone(&bytes));
                tasks.spawn(async move {
                    let response = client
                        .get(&url)
                        .header("Range", &range)
                        .send()
                        .await
                        .unwrap_or_else(|e| panic!("{range}: {e}"));
                    assert_eq!(response.status().as_u16(), 206, "{range}");
                    let expected = format!("bytes {first}-{last}/{}", bytes.len());
                    assert_eq!(
                        response.headers()["content-range"].to_str().unwrap(),
                        expected
                    );
                    let body = response.bytes().await.unwrap();
                    assert!(
                        body[..] == bytes[first as usize..=last as usize],
                        "{range}: wrong bytes"
                    );
                    drop(permit);
                });
                while let Some(done) = tasks.try_join_next() {
                    done.unwrap();
                }
            }
            let mut count = 0;
            while let Some(done) = tasks.join_next().await {
                done.unwrap();
                count += 1;
            }
            count
        })
    };

    // Warm up (pools, runtime threads, allocator arenas), then measure.
    run(ranges[..2 * IN_FLIGHT].to_vec());
    let peak_known = common::reset_peak_rss();
    let before = common::rss_bytes();
    run(ranges);
    let after = common::rss_bytes();
    let growth = after.saturating_sub(before);
    assert!(
        growth < MAX_GROWTH,
        "resident memory grew by {} MiB",
        growth >> 20
    );
    if peak_known {
        let peak = common::peak_rss_bytes().saturating_sub(before);
        assert!(peak < MAX_GROWTH, "peak memory rose by {} MiB", peak >> 20);
    }
    // Still serving.
    assert_eq!(
        get(server.local_addr(), "/stores/load.pointlet", &[]).status,
        200
    );
    server.shutdown().unwrap();
}

#[test]
fn clients_hanging_up_do_not_stop_the_server() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.pointlet");
    build_store(&path, 20_000, 3);
    let bytes = std::fs::read(&path).unwrap();
    let server = serve(&[path], None);
    let addr = server.local_addr();
    for i in 0..100 {
        let mut stream = TcpStream::connect(addr).unwrap();
        if i % 3 == 0 {
            // Half a request line, then gone.
            stream.write_all(b"GET /stores/s.poin").unwrap();
        } else {
            // The whole file asked for, a few bytes read, then gone.
            stream
                .write_all(b"GET /stores/s.pointlet HTTP/1.1\r\nHost: x\r\n\r\n")
                .unwrap();
            let mut some = [0u8; 1000];
            stream.read_exact(&mut some).unwrap();
        }
        drop(stream);
    }
    for _ in 0..10 {
        let r = get(addr, "/stores/s.pointlet", &[("Range", "bytes=100-")]);
        assert_eq!(r.status, 206);
        assert!(r.body == bytes[100..]);
    }
    server.shutdown().unwrap();
}
