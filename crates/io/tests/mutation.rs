//! Deterministic damage over the real files: truncations and byte flips. Every case must end
//! in Ok or Err: no panic, no hang (each case runs under a watchdog).

mod common;
use common::*;
use pointlet_core::shuffle::SplitMix64;
use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

/// Far above what any case needs; only a hang gets near it.
const WATCHDOG: Duration = Duration::from_secs(120);

/// Opens and reads everything, in odd-sized batches.
fn exercise(path: &Path) -> Result<u64, String> {
    let mut r = pointlet_io::open(path).map_err(|e| e.to_string())?;
    let claimed = r.meta().point_count;
    let mut n = 0u64;
    while let Some(b) = r.read_batch(3_001).map_err(|e| e.to_string())? {
        b.check_shape().map_err(|e| e.to_string())?;
        n += b.len() as u64;
        assert!(
            n <= claimed,
            "{}: more points than the header claims",
            path.display()
        );
    }
    assert_eq!(
        n,
        claimed,
        "{}: Ok(None) before every point",
        path.display()
    );
    Ok(n)
}

fn run_case(path: std::path::PathBuf, what: String) {
    let (tx, rx) = mpsc::channel();
    let worker = std::thread::spawn(move || {
        let _ = pointlet_io::las::parse_header(&std::fs::read(&path).expect("read case"));
        let r = exercise(&path);
        let _ = tx.send(());
        r
    });
    match rx.recv_timeout(WATCHDOG) {
        Ok(()) => {}
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("{what}: still running after {WATCHDOG:?}"),
        Err(mpsc::RecvTimeoutError::Disconnected) => {}
    }
    if worker.join().is_err() {
        panic!("{what}: panicked");
    }
}

#[test]
fn truncations_and_byte_flips_never_panic_or_hang() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = SplitMix64::new(0x5EED);
    let mut cases = 0;
    for path in shared_files() {
        let original = std::fs::read(&path).expect("read");
        let len = original.len() as u64;
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .expect("name")
            .to_string();
        let case_path = dir.path().join(&name);
        for k in 0..12 {
            let keep = if k < 4 {
                rng.below(2_048.min(len))
            } else {
                rng.below(len)
            };
            std::fs::write(&case_path, &original[..keep as usize]).expect("write");
            run_case(case_path.clone(), format!("{name} cut to {keep} bytes"));
            cases += 1;
        }
        for k in 0..24 {
            let mut bytes = original.clone();
            // Half the flips hit the header and records before the points, half anywhere.
            let span = if k % 2 == 0 { 2_048.min(len) } else { len };
            let flips = 1 + rng.below(4);
            let mut what = format!("{name} with bytes changed at");
            for _ in 0..flips {
                let at = rng.below(span) as usize;
                bytes[at] ^= 1 + rng.below(255) as u8;
                what += &format!(" {at}");
            }
            std::fs::write(&case_path, &bytes).expect("write");
            run_case(case_path.clone(), what);
            cases += 1;
        }
    }
    assert!(cases >= 300, "{cases} cases");
}

/// The header parser on random bytes behind a real signature and version: Ok or Err only.
#[test]
fn parse_header_survives_random_headers() {
    let mut rng = SplitMix64::new(42);
    let real = std::fs::read(data("simple1_4.las")).expect("read");
    for case in 0..5_000 {
        let len = rng.below(1_200) as usize;
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
        if case % 2 == 0 {
            // Half start from a real 1.4 header so the parse gets past the first checks.
            let keep = len.min(real.len());
            bytes[..keep].copy_from_slice(&real[..keep]);
            for _ in 0..1 + rng.below(6) {
                if len > 0 {
                    let at = rng.below(len.min(400) as u64) as usize;
                    bytes[at] = rng.next_u64() as u8;
                }
            }
        } else if len >= 4 {
            bytes[..4].copy_from_slice(b"LASF");
        }
        let _ = pointlet_io::las::parse_header(&bytes);
    }
}
