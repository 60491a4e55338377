//! Damaged stores are refused with a message naming the file, never a panic; failed builds
//! leave nothing behind.

mod common;
use common::*;
use pointlet_core::PointLayout;
use pointlet_store::{BuildConfig, Store, StoreBuilder};
use std::path::Path;

fn small_store(dir: &Path) -> Vec<u8> {
    let out = dir.join("good.pointlet");
    let n = 3000;
    let c = BuildConfig {
        target_pointlets: 12,
        ..Default::default()
    };
    build(
        &out,
        c,
        &meta(RGB_GPS_EXTRA, n as u64),
        &batches(RGB_GPS_EXTRA, n, 1000, 11),
    );
    std::fs::read(&out).unwrap()
}

/// Whether the store at `path` is refused by `open`, `verify` or a pointlet read; panics (and
/// so fails the test) only if the reader panics.
fn refused(path: &Path) -> bool {
    let name = path.file_name().unwrap().to_str().unwrap();
    let named = |e: pointlet_store::StoreError| {
        let m = e.to_string();
        assert!(m.contains(name), "message does not name the file: {m}");
    };
    let store = match Store::open(path) {
        Ok(s) => s,
        Err(e) => {
            named(e);
            return true;
        }
    };
    let mut failed = false;
    for i in 0..store.pointlets().len() {
        if let Err(e) = store.read_pointlet(i) {
            named(e);
            failed = true;
        }
    }
    if let Err(e) = store.verify() {
        named(e);
        failed = true;
    }
    failed
}

#[test]
fn the_good_store_passes() {
    let dir = tempfile::tempdir().unwrap();
    small_store(dir.path());
    assert!(!refused(&dir.path().join("good.pointlet")));
}

#[test]
fn truncated_or_extended_stores_are_refused_at_open() {
    let dir = tempfile::tempdir().unwrap();
    let good = small_store(dir.path());
    let p = dir.path().join("cut.pointlet");
    let len = good.len();
    for keep in [
        0,
        1,
        8,
        100,
        127,
        128,
        129,
        500,
        4096,
        len / 3,
        len / 2,
        len - 4097,
        len - 1,
    ] {
        std::fs::write(&p, &good[..keep]).unwrap();
        let e = Store::open(&p).unwrap_err().to_string();
        assert!(e.contains("cut.pointlet"), "{e}");
    }
    let mut longer = good.clone();
    longer.extend_from_slice(&[0; 10]);
    std::fs::write(&p, &longer).unwrap();
    assert!(Store::open(&p)
        .unwrap_err()
        .to_string()
        .contains("appended"));
}

#[test]
fn every_flipped_byte_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    let good = small_store(dir.path());
    let p = dir.path().join("flip.pointlet");
    // Every byte of the metadata (preamble, header, tables) and a deterministic spread over
    // the padding and streams.
    let store = Store::open(&dir.path().join("good.pointlet")).unwrap();
    let data_start = store.header().streams[0].offset as usize;
    drop(store);
    let mut offsets: Vec<usize> = (0..data_start).step_by(7).collect();
    offsets.extend((data_start..good.len()).step_by(good.len() / 250));
    offsets.push(good.len() - 1);
    assert!(offsets.len() > 300);
    let mut rng = pointlet_core::shuffle::SplitMix64::new(5);
    for at in offsets {
        let mut bad = good.clone();
        bad[at] ^= 1 << rng.below(8);
        std::fs::write(&p, &bad).unwrap();
        assert!(refused(&p), "flipping byte {at} went unnoticed");
    }
}

/// Rewrites the JSON header (and every checksum that covers it), as a buggy or hostile writer
/// would, and returns the new file.
fn with_header(good: &[u8], edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
    let u64_at = |o: usize| u64::from_le_bytes(good[o..o + 8].try_into().unwrap());
    let (h_off, h_len) = (u64_at(24) as usize, u64_at(32) as usize);
    let mut v: serde_json::Value = serde_json::from_slice(&good[h_off..h_off + h_len]).unwrap();
    edit(&mut v);
    let json = serde_json::to_vec(&v).unwrap();
    // Keep the length so the rest of the layout stays put: pad with spaces, or cut.
    let mut hb = json.clone();
    hb.resize(h_len, b' ');
    let mut out = good.to_vec();
    out[h_off..h_off + h_len].copy_from_slice(&hb);
    out[80..84].copy_from_slice(&crc32fast::hash(&hb).to_le_bytes());
    let crc = crc32fast::hash(&out[0..124]);
    out[124..128].copy_from_slice(&crc.to_le_bytes());
    out
}

#[test]
fn lying_headers_with_valid_checksums_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = small_store(dir.path());
    let p = dir.path().join("lie.pointlet");
    let edits: Vec<fn(&mut serde_json::Value)> = vec![
        |v| v["points"] = serde_json::json!(1_000_000_000_000_000u64),
        |v| v["points"] = serde_json::json!(0),
        |v| v["pointlets"] = serde_json::json!(u64::MAX),
        |v| v["pointlet_size"] = serde_json::json!(3),
        |v| v["pointlet_size"] = serde_json::json!(1u64 << 40),
        |v| v["quantization"]["scale"][0] = serde_json::json!(0.0),
        |v| v["bounds"]["min"][0] = serde_json::json!(1e300),
        |v| v["layout"]["rgb"] = serde_json::json!(false),
        |v| v["layout"]["extra_bytes"] = serde_json::json!(60000),
        |v| v["streams"][0]["offset"] = serde_json::json!(8192),
        |v| v["streams"][2]["name"] = serde_json::json!("intensity"),
        |v| v["vlrs"][0]["data_hex"] = serde_json::json!("xyz"),
        |v| v["las_point_format"] = serde_json::json!(200),
        |v| v["version"] = serde_json::json!(1),
        |v| v["version"] = serde_json::json!(3),
        |v| v["las"]["project_id_hex"] = serde_json::json!("00"),
        |v| {
            v.as_object_mut().unwrap().remove("las");
        },
        |v| v["surprise"] = serde_json::json!(1),
        |v| *v = serde_json::json!([1, 2, 3]),
    ];
    for (i, edit) in edits.iter().enumerate() {
        std::fs::write(&p, with_header(&good, edit)).unwrap();
        let e = Store::open(&p).map(|_| ()).unwrap_err().to_string();
        assert!(e.contains("lie.pointlet"), "edit {i}: {e}");
    }
    // The same edit machinery leaves a good header good.
    std::fs::write(&p, with_header(&good, |_| {})).unwrap();
    assert!(!refused(&p));
}

/// `good` with the format version of its preamble set to `version`.
fn with_version(good: &[u8], version: u32) -> Vec<u8> {
    let mut out = good.to_vec();
    out[8..12].copy_from_slice(&version.to_le_bytes());
    let crc = crc32fast::hash(&out[0..124]);
    out[124..128].copy_from_slice(&crc.to_le_bytes());
    out
}

#[test]
fn version_1_stores_are_read_and_later_versions_refused_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let good = small_store(dir.path());
    let p = dir.path().join("old.pointlet");
    let v1 = with_header(&good, |v| {
        v["version"] = serde_json::json!(1);
        v.as_object_mut().unwrap().remove("las");
    });
    std::fs::write(&p, with_version(&v1, 1)).unwrap();
    let store = Store::open(&p).unwrap();
    assert_eq!((store.header().version, &store.header().las), (1, &None));
    store.verify().unwrap();
    std::fs::write(&p, with_version(&good, 3)).unwrap();
    let e = Store::open(&p).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("version 3 is not supported"), "{e}");
}

#[test]
fn not_a_store_and_missing_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("text.pointlet");
    std::fs::write(&p, vec![b'x'; 4096]).unwrap();
    assert!(Store::open(&p).unwrap_err().to_string().contains("magic"));
    let e = Store::open(&dir.path().join("none.pointlet"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.pointlet"), "{e}");
}

fn builder(out: &Path, config: BuildConfig, n: usize) -> StoreBuilder {
    StoreBuilder::create(out, config, &meta(RGB_GPS_EXTRA, n as u64), vec![]).unwrap()
}

#[test]
fn failed_or_abandoned_builds_leave_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.pointlet");
    let tiny = BuildConfig {
        ram_budget: 0,
        ..Default::default()
    };
    let input = batches(RGB_GPS_EXTRA, 30_000, 5000, 12);

    // A non-finite coordinate after runs were spilled.
    let mut b = builder(&out, tiny.clone(), 30_000);
    for batch in &input[..3] {
        b.push(batch).unwrap();
    }
    let mut bad = input[3].clone();
    bad.xyz[17][1] = f64::NAN;
    let e = b.push(&bad).unwrap_err().to_string();
    assert!(
        e.contains("s.pointlet") && e.contains("point 15017") && e.contains("axis 1"),
        "{e}"
    );
    assert!(
        b.push(&input[4]).is_err(),
        "a failed builder refuses more points"
    );
    assert!(
        !listing(dir.path()).is_empty(),
        "runs and the temporary output exist mid-build"
    );
    drop(b);
    assert!(
        listing(dir.path()).is_empty(),
        "left behind: {:?}",
        listing(dir.path())
    );

    // A coordinate that does not fit 32-bit integers names the coordinate.
    let mut b = builder(&out, tiny.clone(), 30_000);
    let mut far = input[0].clone();
    far.xyz[3][0] = 1e12;
    let e = b.push(&far).unwrap_err().to_string();
    assert!(e.contains("point 3") && e.contains("1000000000000"), "{e}");
    drop(b);
    assert!(listing(dir.path()).is_empty());

    // The run folder disappears mid-build.
    let runs = tempfile::tempdir().unwrap();
    let run_path = runs.path().to_path_buf();
    let mut c = tiny.clone();
    c.tmp_dir = Some(run_path.clone());
    let mut b = builder(&out, c, 30_000);
    drop(runs);
    // Runs spill in the background: the error comes from a later push or from finish.
    let pushed: Result<(), _> = input.iter().try_for_each(|batch| b.push(batch));
    let e = match pushed {
        Err(e) => {
            drop(b);
            e
        }
        Ok(()) => b.finish().unwrap_err(),
    };
    let e = e.to_string();
    assert!(e.contains(run_path.to_str().unwrap()), "{e}");
    assert!(listing(dir.path()).is_empty());

    // Abandoned without finish, in memory and out of core.
    for c in [BuildConfig::default(), tiny.clone()] {
        let mut b = builder(&out, c, 30_000);
        for batch in &input {
            b.push(batch).unwrap();
        }
        drop(b);
        assert!(listing(dir.path()).is_empty());
    }

    // No points at all.
    let e = builder(&out, tiny.clone(), 0)
        .finish()
        .unwrap_err()
        .to_string();
    assert!(e.contains("no points") && e.contains("s.pointlet"), "{e}");
    assert!(listing(dir.path()).is_empty());

    // An output folder that does not exist, and a tmp dir that is not a folder.
    let nowhere = dir.path().join("missing").join("x.pointlet");
    let e = StoreBuilder::create(
        &nowhere,
        tiny.clone(),
        &meta(PointLayout::default(), 1),
        vec![],
    )
    .map(|_| ())
    .unwrap_err()
    .to_string();
    assert!(e.contains("x.pointlet"), "{e}");
    let mut c = tiny;
    c.tmp_dir = Some(dir.path().join("nope"));
    assert!(StoreBuilder::create(&out, c, &meta(PointLayout::default(), 1), vec![]).is_err());
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn a_finished_store_replaces_an_older_one_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.pointlet");
    std::fs::write(&out, b"old contents").unwrap();
    let layout = PointLayout::default();
    let mut b =
        StoreBuilder::create(&out, BuildConfig::default(), &meta(layout, 100), vec![]).unwrap();
    b.push(&batches(layout, 100, 100, 1)[0]).unwrap();
    // Until finish the old file is untouched.
    assert_eq!(std::fs::read(&out).unwrap(), b"old contents");
    b.finish().unwrap();
    assert_eq!(Store::open(&out).unwrap().header().points, 100);
    assert_eq!(listing(dir.path()), vec![out]);
}
