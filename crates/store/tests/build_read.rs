//! Building stores from synthetic batches and reading them back.

mod common;
use common::*;
use pointlet_core::codes::KeyGrid;
use pointlet_core::shuffle::{mix_seed, permutation};
use pointlet_core::PointLayout;
use pointlet_store::{BuildConfig, BuildPhase, BuildProgress, Store, StoreBuilder, StreamKind};
use std::sync::{Arc, Mutex};

fn config(budget: u64, m: u64, seed: u64) -> BuildConfig {
    BuildConfig {
        ram_budget: budget,
        target_pointlets: m,
        seed,
        ..Default::default()
    }
}

fn read_all(store: &Store) -> Vec<pointlet_core::PointBatch> {
    (0..store.pointlets().len())
        .map(|i| store.read_pointlet(i).expect("read_pointlet"))
        .collect()
}

#[test]
fn in_memory_and_out_of_core_builds_are_byte_identical_and_clean() {
    let dir = tempfile::tempdir().unwrap();
    let runs_dir = tempfile::tempdir().unwrap();
    let n = 60_000;
    let batches = batches(RGB_GPS_EXTRA, n, 7_001, 1);
    let m = meta(RGB_GPS_EXTRA, n as u64);
    let mem = dir.path().join("mem.pointlet");
    let ooc = dir.path().join("ooc.pointlet");
    let beside = dir.path().join("beside.pointlet");
    let s_mem = build(&mem, config(1 << 30, 100, 9), &m, &batches);
    assert_eq!(s_mem.runs, 0);
    // A zero budget still sorts, in runs of the smallest size.
    let mut tiny = config(0, 100, 9);
    tiny.tmp_dir = Some(runs_dir.path().to_path_buf());
    let s_ooc = build(&ooc, tiny, &m, &batches);
    assert!(s_ooc.runs > 5, "expected several runs, got {}", s_ooc.runs);
    let s_beside = build(&beside, config(1 << 20, 100, 9), &m, &batches);
    assert!(s_beside.runs > 1);
    // A source that claims no points gets one whole-budget run, spilled when full.
    let unclaimed = dir.path().join("unclaimed.pointlet");
    let s_unclaimed = build(
        &unclaimed,
        config(1 << 20, 100, 9),
        &meta(RGB_GPS_EXTRA, 0),
        &batches,
    );
    assert!(s_unclaimed.runs > 1);
    // Only builds that spilled account for their spilling threads, which bucketed and wrote.
    assert_eq!(s_mem.timings.spills, None);
    for s in [&s_ooc, &s_beside, &s_unclaimed] {
        let spills = s.timings.spills.expect("spill timings");
        assert!(
            !spills.bucketing.is_zero() && !spills.writing.is_zero(),
            "{spills:?}"
        );
    }
    let a = std::fs::read(&mem).unwrap();
    assert!(
        a == std::fs::read(&ooc).unwrap(),
        "out of core differs from in memory"
    );
    assert!(
        a == std::fs::read(&beside).unwrap(),
        "1 MiB budget differs from in memory"
    );
    assert!(
        a == std::fs::read(&unclaimed).unwrap(),
        "unclaimed count differs from in memory"
    );
    assert_eq!(s_mem.bytes, a.len() as u64);
    let expected = vec![beside, mem, ooc, unclaimed];
    assert_eq!(listing(dir.path()), expected, "temporary files left");
    assert!(listing(runs_dir.path()).is_empty(), "run files left");
}

#[test]
fn many_runs_give_the_same_store() {
    let dir = tempfile::tempdir().unwrap();
    // 4096-point runs, and groups of 4096 points read from 130 runs at a time.
    let n = 4096 * 130 + 17;
    let layout = PointLayout::default();
    let batches = batches(layout, n, 100_000, 2);
    let m = meta(layout, n as u64);
    let mem = dir.path().join("a.pointlet");
    let ooc = dir.path().join("b.pointlet");
    build(&mem, config(1 << 30, 1000, 0), &m, &batches);
    let s = build(&ooc, config(0, 1000, 0), &m, &batches);
    assert!(s.runs > 128, "{} runs", s.runs);
    assert!(std::fs::read(&mem).unwrap() == std::fs::read(&ooc).unwrap());
    assert_eq!(listing(dir.path()).len(), 2);
}

#[test]
fn reading_back_gives_every_point_and_attribute() {
    let dir = tempfile::tempdir().unwrap();
    for (layout, n) in [
        (FULL, 5_000),
        (RGB_GPS_EXTRA, 1),
        (PointLayout::default(), 3_333),
    ] {
        let batches = batches(layout, n, 1000, 3);
        let m = meta(layout, n as u64);
        let out = dir.path().join("s.pointlet");
        let summary = build(&out, config(1 << 26, 7, 5), &m, &batches);
        let store = Store::open(&out).unwrap();
        store.verify().unwrap();
        let h = store.header();
        assert_eq!(h.points, n as u64);
        assert_eq!(summary.points, n as u64);
        assert_eq!(h.layout, layout);
        assert_eq!(h.quantization, Q);
        assert_eq!(h.vlrs, m.vlrs);
        assert_eq!(h.las, m.las);
        assert_eq!(h.sources, vec!["synthetic".to_string()]);
        assert_eq!(h.seed, 5);
        assert_eq!(h.las_point_format, layout.las_point_format());
        assert_eq!(h.pointlet_size, pointlet_store::pointlet_size(n as u64, 7));
        let back = read_all(&store);
        assert!(multiset(&back) == multiset(&batches), "layout {layout:?}");
        // The bounds are those of the points, not the claimed ones.
        let mut bounds = pointlet_core::Aabb::EMPTY;
        batches
            .iter()
            .flat_map(|b| b.xyz.iter())
            .for_each(|p| bounds.grow(*p));
        assert_eq!(h.bounds, bounds);
        for (e, b) in store.pointlets().iter().zip(&back) {
            let mut pb = pointlet_core::Aabb::EMPTY;
            b.xyz.iter().for_each(|p| pb.grow(*p));
            assert_eq!(e.aabb, pb);
            assert_eq!(e.count as usize, b.len());
        }
    }
}

#[test]
fn pointlets_are_hilbert_ranges_shuffled_by_their_seed() {
    let dir = tempfile::tempdir().unwrap();
    let n = 20_000;
    let seed = 77;
    let batches = batches(RGB_GPS_EXTRA, n, 3000, 4);
    let m = meta(RGB_GPS_EXTRA, n as u64);
    let out = dir.path().join("s.pointlet");
    build(&out, config(1 << 16, 50, seed), &m, &batches);
    let store = Store::open(&out).unwrap();
    // Reference order: Hilbert key of the dequantized position over the points' bounds (not
    // the claimed ones), ties by input order. gps_time holds the input index.
    assert_ne!(
        store.header().bounds,
        m.bounds,
        "the claim is not the points' bounds"
    );
    assert_eq!(store.header().key_bounds, store.header().bounds);
    let grid = KeyGrid::new(&store.header().bounds);
    let mut sorted: Vec<(u64, u64)> = batches
        .iter()
        .flat_map(|b| b.xyz.iter().zip(&b.gps_time))
        .map(|(p, id)| {
            (
                grid.hilbert(Q.dequantize(Q.quantize(*p).unwrap())),
                *id as u64,
            )
        })
        .collect();
    sorted.sort();
    assert!(store.pointlets().len() > 10);
    for (i, e) in store.pointlets().iter().enumerate() {
        let b = store.read_pointlet(i).unwrap();
        let perm = permutation(e.count as usize, mix_seed(seed, i as u64));
        for (j, id) in b.gps_time.iter().enumerate() {
            let expected = sorted[e.first as usize + perm[j] as usize].1;
            assert_eq!(*id as u64, expected, "pointlet {i}, slot {j}");
        }
    }
}

#[test]
fn prefix_and_range_reads_match_whole_pointlets() {
    let dir = tempfile::tempdir().unwrap();
    let n = 9_000;
    let batches = batches(FULL, n, 4000, 5);
    let out = dir.path().join("s.pointlet");
    build(
        &out,
        config(1 << 26, 10, 1),
        &meta(FULL, n as u64),
        &batches,
    );
    let store = Store::open(&out).unwrap();
    let q = store.header().quantization;
    for (i, e) in store.pointlets().iter().enumerate() {
        let whole = store.read_pointlet(i).unwrap();
        for len in [0, 1, 37, e.count / 2, e.count] {
            let pos = store.read_positions(i, 0..len).unwrap();
            let deq: Vec<[f64; 3]> = pos.iter().map(|r| q.dequantize(*r)).collect();
            assert_eq!(deq[..], whole.xyz[..len as usize]);
            assert_eq!(
                store.read_rgb(i, 0..len).unwrap()[..],
                whole.rgb[..len as usize]
            );
            assert_eq!(
                store.read_intensity(i, 0..len).unwrap()[..],
                whole.intensity[..len as usize]
            );
            assert_eq!(
                store.read_classification(i, 0..len).unwrap()[..],
                whole.classification[..len as usize]
            );
        }
        // A middle range of every stream, appended to what the buffer held.
        let r = e.count / 3..e.count / 2;
        for kind in StreamKind::ALL {
            let mut raw = vec![0xAB];
            store.read_stream_raw(kind, i, r.clone(), &mut raw).unwrap();
            let bpp = kind.bytes_per_point(&FULL).unwrap();
            assert_eq!(raw.len(), 1 + r.len() * bpp);
            let mut full = Vec::new();
            store
                .read_stream_raw(kind, i, 0..e.count, &mut full)
                .unwrap();
            assert_eq!(raw[1..], full[r.start as usize * bpp..r.end as usize * bpp]);
        }
    }
    // Out-of-range requests are errors that name the file.
    let last = store.pointlets().len();
    let e = store.read_pointlet(last).unwrap_err().to_string();
    assert!(
        e.contains("s.pointlet") && e.contains("does not exist"),
        "{e}"
    );
    let count = store.pointlets()[0].count;
    assert!(store.read_positions(0, 0..count + 1).is_err());
    #[allow(clippy::reversed_empty_ranges)]
    let backwards = 5..2;
    assert!(store.read_positions(0, backwards).is_err());
}

#[test]
fn absent_streams_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let layout = PointLayout::default();
    let out = dir.path().join("s.pointlet");
    build(
        &out,
        config(1 << 26, 10, 1),
        &meta(layout, 500),
        &batches(layout, 500, 500, 6),
    );
    let store = Store::open(&out).unwrap();
    let e = store.read_rgb(0, 0..1).unwrap_err().to_string();
    assert!(e.contains("no rgb stream"), "{e}");
    let b = store.read_pointlet(0).unwrap();
    assert!(b.rgb.is_empty() && b.gps_time.is_empty());
    b.check_shape().unwrap();
}

#[test]
fn store_is_shared_between_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Store>();
    let dir = tempfile::tempdir().unwrap();
    let n = 30_000;
    let out = dir.path().join("s.pointlet");
    build(
        &out,
        config(1 << 26, 40, 1),
        &meta(RGB_GPS_EXTRA, n as u64),
        &batches(RGB_GPS_EXTRA, n, 5000, 7),
    );
    let store = Store::open(&out).unwrap();
    let sequential = read_all(&store);
    let p = store.pointlets().len();
    std::thread::scope(|s| {
        for t in 0..4 {
            let (store, sequential) = (&store, &sequential);
            s.spawn(move || {
                for i in (t..p).step_by(4) {
                    assert_eq!(store.read_pointlet(i).unwrap(), sequential[i]);
                    let c = store.pointlets()[i].count;
                    assert_eq!(
                        store.read_positions(i, 0..c / 2).unwrap().len(),
                        (c / 2) as usize
                    );
                }
            });
        }
    });
}

#[test]
fn narrower_batches_are_widened_with_zeros() {
    let dir = tempfile::tempdir().unwrap();
    let narrow = PointLayout {
        gps_time: true,
        extra_bytes: 2,
        ..Default::default()
    };
    let input = batches(narrow, 1000, 1000, 8);
    let out = dir.path().join("s.pointlet");
    build(
        &out,
        config(1 << 26, 4, 0),
        &meta(RGB_GPS_EXTRA, 1000),
        &input,
    );
    let store = Store::open(&out).unwrap();
    let mut widened = input.clone();
    widened.iter_mut().for_each(|b| b.widen(RGB_GPS_EXTRA));
    assert!(multiset(&read_all(&store)) == multiset(&widened));
    // A batch wider than the store is refused.
    let mut b = StoreBuilder::create(
        &dir.path().join("t.pointlet"),
        config(1 << 26, 4, 0),
        &meta(narrow, 10),
        vec![],
    )
    .unwrap();
    let e = b
        .push(&batches(FULL, 10, 10, 1)[0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("t.pointlet") && e.contains("attributes"), "{e}");
}

#[test]
fn progress_reports_every_phase_up_to_completion() {
    let dir = tempfile::tempdir().unwrap();
    let seen: Arc<Mutex<Vec<BuildProgress>>> = Arc::default();
    let log = seen.clone();
    let mut c = config(0, 10, 0);
    c.progress = Some(Arc::new(move |p| log.lock().unwrap().push(p)));
    let n = 20_000;
    build(
        &dir.path().join("s.pointlet"),
        c,
        &meta(FULL, n as u64),
        &batches(FULL, n, 3000, 9),
    );
    let seen = seen.lock().unwrap();
    for phase in [
        BuildPhase::Reading,
        BuildPhase::Sorting,
        BuildPhase::Writing,
    ] {
        assert!(seen.iter().any(|p| p.phase == phase), "{phase:?} missing");
    }
    let last = seen.last().unwrap();
    assert_eq!(
        (last.phase, last.done, last.total),
        (BuildPhase::Writing, n as u64, n as u64)
    );
    assert!(seen.iter().all(|p| p.done <= p.total));
}

#[test]
fn unquantized_sources_get_a_quantization() {
    let dir = tempfile::tempdir().unwrap();
    let layout = PointLayout::default();
    let mut m = meta(layout, 100);
    m.quantization = None;
    let input = batches(layout, 100, 100, 10);
    let out = dir.path().join("s.pointlet");
    build(&out, config(1 << 26, 4, 0), &m, &input);
    let store = Store::open(&out).unwrap();
    assert_eq!(store.header().quantization.scale, [0.001; 3]);
    assert_eq!(store.header().points, 100);
}

/// Header bounds that are zero, scaled or shifted give the store that true bounds give: keys
/// are computed over the points' own bounds, in memory and through spilled runs alike.
#[test]
fn wrong_header_bounds_give_the_same_store() {
    let dir = tempfile::tempdir().unwrap();
    let n = 30_000;
    let batches = batches(RGB_GPS_EXTRA, n, 4000, 9);
    let mut truth = pointlet_core::Aabb::EMPTY;
    batches
        .iter()
        .flat_map(|b| b.xyz.iter())
        .for_each(|p| truth.grow(*p));
    let with_bounds = |bounds: pointlet_core::Aabb| pointlet_core::SourceMeta {
        bounds,
        ..meta(RGB_GPS_EXTRA, n as u64)
    };
    let zero = pointlet_core::Aabb {
        min: [0.0; 3],
        max: [0.0; 3],
    };
    let scaled = pointlet_core::Aabb {
        min: truth.min.map(|v| v * 1000.0),
        max: truth.max.map(|v| v * 1000.0),
    };
    let reference = dir.path().join("true.pointlet");
    build(
        &reference,
        config(1 << 30, 100, 3),
        &with_bounds(truth),
        &batches,
    );
    let want = std::fs::read(&reference).unwrap();
    for (name, bounds) in [
        ("zero", zero),
        ("scaled", scaled),
        ("claimed", claimed_bounds()),
    ] {
        for budget in [1u64 << 30, 1 << 18] {
            let out = dir.path().join(format!("{name}-{budget}.pointlet"));
            let s = build(&out, config(budget, 100, 3), &with_bounds(bounds), &batches);
            assert_eq!(s.runs > 0, budget < 1 << 20, "{name}: spilled as meant");
            let got = std::fs::read(&out).unwrap();
            assert!(got == want, "{name} bounds, budget {budget}: another store");
        }
    }
}

/// Batches served as parts, decoded from whatever thread asks.
struct Parts(Vec<pointlet_core::PointBatch>, Vec<u64>);

impl pointlet_core::PartedSource for Parts {
    fn part_sizes(&self) -> &[u64] {
        &self.1
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut pointlet_core::PointBatch,
        _scratch: &mut Vec<u8>,
    ) -> Result<(), pointlet_core::PartError> {
        if self.0[i].xyz.iter().any(|p| p[0] < -1e300) {
            return Err(format!("part {i} is damaged").into());
        }
        *out = self.0[i].clone();
        Ok(())
    }
}

/// [`Parts`] that also decode straight into rows, positions as integers of `Q`, as LAS and LAZ
/// files do, handing them over `stretch` rows at a time; `drop_last` leaves a part's last
/// stretch out (a broken source).
struct StoredParts {
    parts: Parts,
    stretch: usize,
    drop_last: bool,
}

impl pointlet_core::PartedSource for StoredParts {
    fn part_sizes(&self) -> &[u64] {
        self.parts.part_sizes()
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut pointlet_core::PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), pointlet_core::PartError> {
        self.parts.decode_part(i, out, scratch)
    }

    fn decode_part_rows(
        &self,
        i: usize,
        q: &pointlet_core::Quantization,
        row: &pointlet_core::rows::RowLayout,
        rows: &mut [u8],
        scratch: &mut Vec<u8>,
        done: &mut dyn FnMut(usize, &[u8]),
    ) -> Result<bool, pointlet_core::PartError> {
        if *q != Q {
            return Ok(false);
        }
        let mut batch = pointlet_core::PointBatch::default();
        self.parts.decode_part(i, &mut batch, scratch)?;
        let mut positions = Vec::new();
        for p in &batch.xyz {
            positions.push(q.quantize(*p)?);
        }
        row.pack(&batch, 0, &positions, rows);
        let stretches = rows.chunks(self.stretch * row.len).collect::<Vec<_>>();
        let handed = stretches.len() - usize::from(self.drop_last);
        for (k, r) in stretches.into_iter().take(handed).enumerate() {
            done(k * self.stretch, r);
        }
        Ok(true)
    }
}

fn build_parts(
    out: &std::path::Path,
    c: BuildConfig,
    parts: &dyn pointlet_core::PartedSource,
    n: usize,
) -> u64 {
    let m = meta(RGB_GPS_EXTRA, n as u64);
    let mut b = StoreBuilder::create(out, c, &m, vec!["synthetic".into()]).unwrap();
    b.push_parts(parts).unwrap();
    b.finish().unwrap().runs as u64
}

#[test]
fn parts_and_thread_counts_give_the_same_store_in_memory_and_out_of_core() {
    let dir = tempfile::tempdir().unwrap();
    // Enough points for the radix pass of the in-memory sort and for several stretches of
    // buckets sorted while the previous is written; parts of uneven sizes.
    let n = 150_000;
    let input = batches(RGB_GPS_EXTRA, n, 9_973, 4);
    let parts = Parts(
        input.clone(),
        input.iter().map(|b| b.len() as u64).collect(),
    );
    let reference = dir.path().join("ref.pointlet");
    build(
        &reference,
        config(1 << 30, 300, 5),
        &meta(RGB_GPS_EXTRA, n as u64),
        &input,
    );
    let want = std::fs::read(&reference).unwrap();
    // Parts decoded straight into rows (positions as stored integers) give the same store,
    // whether the rows are handed over whole or in stretches.
    for stretch in [n, 777] {
        let stored = StoredParts {
            parts: Parts(parts.0.clone(), parts.1.clone()),
            stretch,
            drop_last: false,
        };
        for budget in [1u64 << 30, 2 << 20] {
            let out = dir.path().join(format!("stored-{budget}.pointlet"));
            build_parts(&out, config(budget, 300, 5), &stored, n);
            assert!(
                std::fs::read(&out).unwrap() == want,
                "parts as rows in stretches of {stretch}, budget {budget}: the store differs"
            );
        }
    }
    // A source that leaves rows out fails the build: no store made of rows never keyed.
    let broken = StoredParts {
        parts: Parts(parts.0.clone(), parts.1.clone()),
        stretch: 777,
        drop_last: true,
    };
    let out = dir.path().join("broken.pointlet");
    let m = meta(RGB_GPS_EXTRA, n as u64);
    let mut b = StoreBuilder::create(&out, config(1 << 30, 300, 5), &m, vec!["x".into()]).unwrap();
    let e = b.push_parts(&broken).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("internal error") && e.contains("rows"), "{e}");
    drop(b);
    assert!(!out.exists(), "a failed build left {}", out.display());
    for threads in [1, 3, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        // 16 MiB holds the run in memory but gives small blocks, with buckets across them.
        for budget in [1u64 << 30, 16 << 20, 2 << 20, 0] {
            let out = dir.path().join(format!("t{threads}-{budget}.pointlet"));
            let runs = pool.install(|| build_parts(&out, config(budget, 300, 5), &parts, n));
            assert_eq!(
                runs > 0,
                budget <= 2 << 20,
                "{threads} threads, budget {budget}"
            );
            assert!(
                std::fs::read(&out).unwrap() == want,
                "{threads} threads, budget {budget}: the store differs"
            );
        }
    }
}

#[test]
fn a_damaged_part_fails_the_build_with_the_readers_message_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let n = 40_000;
    let mut input = batches(RGB_GPS_EXTRA, n, 5_000, 2);
    input[5].xyz[7][0] = -1e301;
    let parts = Parts(
        input.clone(),
        input.iter().map(|b| b.len() as u64).collect(),
    );
    let out = dir.path().join("bad.pointlet");
    let m = meta(RGB_GPS_EXTRA, n as u64);
    let mut b = StoreBuilder::create(&out, config(1 << 30, 100, 0), &m, vec![]).unwrap();
    let e = b.push_parts(&parts).unwrap_err().to_string();
    assert_eq!(e, "part 5 is damaged");
    drop(b);
    assert!(listing(dir.path()).is_empty(), "files left behind");
}

/// Points crowded into one bucket of the spilled runs (a dense cluster, and thousands of copies
/// of one point) are spilled again by finer buckets, down to single keys, and give the store
/// the in-memory build gives, whatever the pointlet size.
#[test]
fn crowded_and_repeated_points_give_the_same_store_out_of_core() {
    let dir = tempfile::tempdir().unwrap();
    let n = 30_000;
    let mut input = batches(RGB_GPS_EXTRA, n, 3_000, 11);
    let mut rng = pointlet_core::shuffle::SplitMix64::new(5);
    for (i, p) in input.iter_mut().flat_map(|b| b.xyz.iter_mut()).enumerate() {
        if i % 3 == 0 {
            *p = [1234.5, -1800.25, 17.0];
        } else if i % 3 == 1 && i % 4 != 1 {
            // A box of 0.2 m: one bucket of the first bucketing, several of the finer ones.
            *p = [
                1100.0 + rng.unit_f64() * 0.2,
                -1900.0 + rng.unit_f64() * 0.2,
                5.0 + rng.unit_f64() * 0.2,
            ];
        }
    }
    let m = meta(RGB_GPS_EXTRA, n as u64);
    for pointlets in [100, 1] {
        let mem = dir.path().join(format!("mem-{pointlets}.pointlet"));
        let ooc = dir.path().join(format!("ooc-{pointlets}.pointlet"));
        build(&mem, config(1 << 30, pointlets, 4), &m, &input);
        let s = build(&ooc, config(0, pointlets, 4), &m, &input);
        assert!(s.runs > 5, "{} runs", s.runs);
        assert!(
            std::fs::read(&mem).unwrap() == std::fs::read(&ooc).unwrap(),
            "{pointlets} pointlets: out of core differs from in memory"
        );
    }
    assert_eq!(listing(dir.path()).len(), 4, "temporary files left");
}
