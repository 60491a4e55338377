//! Progressive loading of point files: every point lands in the shuffled buffer where the CPU
//! permutation puts it, progress reaches the header's count, a file cut while loading keeps
//! what was read before the cut and reports the error once, and the queue bound holds. A
//! store's positions go to the GPU as stored and land, its pointlets interleaved, within an
//! ulp of the CPU's encoding.

mod common;
use common::context;

use pointlet_core::color::{point_color, ColorMode};
use pointlet_core::progressive::{GroupRows, Reservoir, SlotOrder};
use pointlet_engine::progressive::{
    LoadConfig, LoadProgress, LoadState, ProgressiveLoad, Uploaded,
};
use pointlet_engine::EngineError;
use pointlet_gpu::shuffle::{ShufflePass, ShuffledBuffer, ShuffledContents};
use pointlet_gpu::{encode_point, GpuContext, PointEncoding};
use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use pointlet_io::PointReader;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// LAS parts of generated files hold this many points (32 768 records of 34 bytes fit 4 MiB).
const LAS_PART: u64 = 32_768;

fn testdata(name: &str) -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata")).join(name);
    assert!(p.exists(), "test data {} is missing", p.display());
    p
}

/// The generated scene of `points` points written as LAS into `dir`.
fn generated_las(dir: &Path, points: u64) -> PathBuf {
    let scene = SceneGenerator::new(SceneConfig { points, seed: 5 });
    let meta = scene.meta();
    let path = dir.join("scene.las");
    let mut w = LasWriter::create(
        &path,
        LasWriterConfig {
            quantization: meta.quantization.unwrap(),
            point_format: meta.las_point_format.unwrap(),
            layout: meta.layout,
            vlrs: meta.vlrs.clone(),
            fields: meta.las.clone().unwrap_or_default(),
            compress: false,
        },
    )
    .unwrap();
    let mut r = scene.reader();
    while let Some(b) = r.read_batch(50_000).unwrap() {
        w.write_batch(&b).unwrap();
    }
    w.finish().unwrap();
    let r = pointlet_io::open(&path).unwrap();
    assert_eq!(r.parted().unwrap().part_sizes()[0], LAS_PART);
    path
}

/// A binary PLY of `n` points with colours.
fn ply(dir: &Path, n: u32) -> PathBuf {
    let path = dir.join("cloud.ply");
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
         property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
         property uchar blue\nend_header\n"
    )
    .into_bytes();
    for i in 0..n {
        for v in [i as f32 * 0.25, (i % 97) as f32, (i % 13) as f32 * 2.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&[(i % 256) as u8, (i * 7 % 256) as u8, 200]);
    }
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A text file of `n` points, x y z only.
fn xyz(dir: &Path, n: u32) -> PathBuf {
    let path = dir.join("cloud.xyz");
    let text: String = (0..n)
        .map(|i| format!("{}.5 {} {}.25\n", 1000 + i, i % 31, i % 7))
        .collect();
    std::fs::write(&path, text).unwrap();
    path
}

struct Gpu {
    ctx: GpuContext,
    pass: ShufflePass,
}

impl Gpu {
    fn new() -> Self {
        let ctx = context();
        let pass = ShufflePass::new(&ctx).unwrap();
        Self { ctx, pass }
    }

    fn buffer(&self, load: &ProgressiveLoad) -> ShuffledBuffer {
        let mut b =
            ShuffledBuffer::new(&self.ctx, PointEncoding::Full16, load.slots() as u32).unwrap();
        b.set_order(load.order()).unwrap();
        b
    }

    fn upload(&mut self, load: &mut ProgressiveLoad, dst: &ShuffledBuffer) -> Uploaded {
        load.upload_ready(&self.ctx, &mut self.pass, dst, 2)
            .unwrap()
    }

    /// Uploads until loading ends; the failures reported on the way.
    fn upload_all(&mut self, load: &mut ProgressiveLoad, dst: &ShuffledBuffer) -> Vec<EngineError> {
        let give_up = Instant::now() + Duration::from_secs(60);
        let mut failures = Vec::new();
        while !load.progress().is_finished() {
            let up = self.upload(load, dst);
            failures.extend(up.failure);
            if up.batches == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
            assert!(Instant::now() < give_up, "loading never finished");
        }
        // Once ended, nothing more arrives and the error is not repeated.
        let after = self.upload(load, dst);
        assert_eq!(after.batches, 0);
        assert!(after.failure.is_none(), "{:?}", after.failure);
        failures
    }
}

/// The first `points` points of `source` (the load's file as it was), encoded with the load's
/// origin and colouring, in the slots the CPU reservoir of the load's buffer (seeded with
/// `seed`) gives them: the permutation's within the capacity, a later point replacing an
/// earlier one past it (every other slot zero).
fn cpu_placement(
    load: &ProgressiveLoad,
    source: &Path,
    points: u64,
    seed: u64,
) -> ShuffledContents {
    let scale = load.color().expect("the colouring is chosen").scale;
    let reservoir = Reservoir::new(load.slots(), seed).unwrap();
    let n = load.slots() as usize;
    let mut out = ShuffledContents {
        positions: vec![0; n * 3],
        fine: Vec::new(),
        colors: vec![0; n],
    };
    let mut r = pointlet_io::open(source).unwrap();
    let mut i = 0u64;
    while let Some(b) = r.read_batch(7_000).unwrap() {
        for k in 0..b.len() {
            if i == points {
                return out;
            }
            if let Some(t) = reservoir.slot(i) {
                let t = t as usize;
                let words = encode_point(b.xyz[k], load.origin(), [1.0; 3], PointEncoding::Full16);
                out.positions[t * 3..t * 3 + 3].copy_from_slice(&words);
                out.colors[t] = point_color(&b, k, &scale);
            }
            i += 1;
        }
    }
    assert_eq!(i, points, "{} holds fewer points", source.display());
    out
}

fn assert_complete(p: &LoadProgress) {
    assert_eq!(p.state, LoadState::Loaded);
    assert_eq!(p.loaded, p.total);
    assert_eq!(p.uploaded, p.total);
    assert!(p.points_per_s() > 0.0 && p.mb_per_s() > 0.0, "{p:?}");
}

/// Loads `path` completely and checks the buffer against the CPU placement.
fn load_and_check(gpu: &mut Gpu, path: &Path, config: LoadConfig) -> ProgressiveLoad {
    let seed = config.seed;
    let mut load = ProgressiveLoad::start(path, config).unwrap();
    let dst = gpu.buffer(&load);
    let failures = gpu.upload_all(&mut load, &dst);
    assert!(failures.is_empty(), "{}: {failures:?}", path.display());
    assert_complete(&load.progress());
    let got = dst.read(&gpu.ctx).unwrap();
    let want = cpu_placement(&load, path, load.total(), seed);
    assert!(
        got == want,
        "{}: the shuffled buffer differs",
        path.display()
    );
    load
}

#[test]
fn a_generated_las_lands_where_the_cpu_permutation_puts_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = generated_las(dir.path(), 300_000);
    let mut gpu = Gpu::new();
    let config = LoadConfig {
        batch_points: 100_000,
        ..Default::default()
    };
    let load = load_and_check(&mut gpu, &path, config);
    assert_eq!(load.total(), 300_000);
    let color = load.color().unwrap();
    assert_eq!(color.default.map(|d| d.mode), Some(ColorMode::Rgb));
}

#[test]
fn a_file_beyond_the_slots_keeps_the_reservoirs_points_the_later_winning() {
    let dir = tempfile::tempdir().unwrap();
    let path = generated_las(dir.path(), 300_000);
    let mut gpu = Gpu::new();
    let config = LoadConfig {
        batch_points: 100_000,
        max_slots: 50_000,
        ..Default::default()
    };
    // About 90 000 picks of 50 000 slots past the first fill: slots picked twice within one
    // batch abound, and the buffer must hold the later point of each.
    let reservoir = Reservoir::new(50_000, config.seed).unwrap();
    let picks = (50_000..300_000)
        .filter(|&i| reservoir.slot(i).is_some())
        .count();
    assert!(picks > 60_000, "{picks} picks past the capacity");
    let load = load_and_check(&mut gpu, &path, config);
    assert_eq!((load.slots(), load.total()), (50_000, 300_000));
}

/// Distance between two floats in f32 steps at the larger of their magnitudes and `at`.
fn ulps(a: f32, b: f32, at: f32) -> f64 {
    let x = a.abs().max(b.abs()).max(at);
    let step = f32::from_bits(x.to_bits() + 1) - x;
    (a as f64 - b as f64).abs() / step as f64
}

#[test]
fn a_store_lands_in_interleaved_pointlets_dequantized_on_the_gpu() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.pointlet");
    common::build_store(&path, 120_000, 5, 300);
    check_store_load(&path, u64::from(u32::MAX), None, None);
    // A budget of fewer slots keeps the first points of every pointlet.
    check_store_load(&path, 50_000, None, None);
    // Colours from the stream bytes: RGB above (the default), classes here.
    check_store_load(
        &path,
        u64::from(u32::MAX),
        Some(ColorMode::Classification),
        None,
    );
    // In chunks of whole pointlets, each leaving slots unused at its end.
    check_store_load(&path, u64::from(u32::MAX), None, Some(5_220));
    check_store_load(&path, 50_000, None, Some(5_220));
}

/// Loads the store at `path` into at most `max_slots` slots (in buffers of `chunk_slots`, else
/// one), coloured by `color` (or the default), and checks every slot against the CPU's
/// encoding of the point the store's interleave puts there.
fn check_store_load(
    path: &Path,
    max_slots: u64,
    color: Option<ColorMode>,
    chunk_slots: Option<u64>,
) {
    let mut gpu = Gpu::new();
    // Batches of two parts (of ~1 875 points), one waiting and one decoding at a time: the
    // few decoded before the first upload tells the loader the GPU go encoded on the CPU,
    // the others as stored.
    let config = LoadConfig {
        batch_points: 3_000,
        parallel_parts: 1,
        queue_batches: 1,
        batches_decoding: 1,
        max_slots,
        color,
        ..Default::default()
    };
    let mut load = ProgressiveLoad::start(path, config).unwrap();
    let store = pointlet_store::Store::open(path).unwrap();
    let h = store.header();
    let rows = GroupRows::new(h.points, h.pointlet_size, max_slots).unwrap();
    assert_eq!(load.order(), SlotOrder::Interleaved(rows));
    assert_eq!(load.slots(), rows.placed());
    assert!(rows.placed() <= max_slots.min(h.points));
    let (order, dst) = match chunk_slots {
        None => (SlotOrder::Interleaved(rows), gpu.buffer(&load)),
        Some(cs) => {
            let chunked = rows.chunked(cs).unwrap();
            assert!(chunked.chunks() > 2);
            let order = SlotOrder::Interleaved(chunked);
            let slots = order.physical_slots() as u32;
            let mut b =
                ShuffledBuffer::with_chunk_slots(&gpu.ctx, PointEncoding::Full16, slots, cs as u32)
                    .unwrap();
            b.set_order(order).unwrap();
            assert_eq!(b.chunk_count() as u64, chunked.chunks());
            (order, b)
        }
    };
    let give_up = Instant::now() + Duration::from_secs(60);
    let (mut stored, mut points) = (0, 0);
    while !load.progress().is_finished() {
        let up = gpu.upload(&mut load, &dst);
        assert!(up.failure.is_none(), "{:?}", up.failure);
        (stored, points) = (stored + up.stored, points + up.points);
        if up.batches == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(Instant::now() < give_up, "loading never finished");
    }
    assert_complete(&load.progress());
    assert_eq!(points, 120_000);
    assert!(
        stored >= 60_000,
        "only {stored} of the points went to the GPU as stored"
    );
    let got = dst.read(&gpu.ctx).unwrap();
    let scale = load.color().unwrap().scale;
    assert_eq!(scale.mode, color.unwrap_or(ColorMode::Rgb));
    let step = h.quantization.scale;
    let mut r = pointlet_engine::open_points(path, &Default::default()).unwrap();
    let (mut i, mut kept) = (0u64, 0u64);
    while let Some(b) = r.read_batch(7_000).unwrap() {
        for k in 0..b.len() {
            let Some(t) = order.target(i).map(|t| t as usize) else {
                i += 1;
                continue;
            };
            kept += 1;
            let want = encode_point(b.xyz[k], load.origin(), [1.0; 3], PointEncoding::Full16);
            for a in 0..3 {
                let (g, w) = (
                    f32::from_bits(got.positions[t * 3 + a]),
                    f32::from_bits(want[a]),
                );
                assert!(
                    ulps(g, w, step[a] as f32) <= 2.0,
                    "point {i} axis {a}: {g} on the GPU, {w} encoded on the CPU"
                );
            }
            assert_eq!(got.colors[t], point_color(&b, k, &scale), "point {i}");
            i += 1;
        }
    }
    assert_eq!((i, kept), (120_000, load.slots()));
}

#[test]
fn laz_ply_and_xyz_files_load_completely() {
    let dir = tempfile::tempdir().unwrap();
    let mut gpu = Gpu::new();
    let cases = [
        (testdata("autzen_trim.laz"), 60_000, None),
        (testdata("plane.laz"), BATCH_ALL, None),
        (ply(dir.path(), 5_000), 1_000, None),
        (xyz(dir.path(), 3_000), 700, Some(ColorMode::Classification)),
    ];
    for (path, batch_points, color) in cases {
        let config = LoadConfig {
            batch_points,
            color,
            ..Default::default()
        };
        let load = load_and_check(&mut gpu, &path, config);
        let chosen = load.color().unwrap();
        match color {
            Some(mode) => assert_eq!((chosen.scale.mode, chosen.default), (mode, None)),
            None => assert!(chosen.default.is_some(), "{}", path.display()),
        }
    }
}

/// Larger than any test file: one batch.
const BATCH_ALL: usize = 1 << 30;

#[test]
fn a_las_cut_while_loading_keeps_the_points_before_the_cut_and_reports_once() {
    let dir = tempfile::tempdir().unwrap();
    let whole = generated_las(dir.path(), 300_000);
    let bytes = std::fs::read(&whole).unwrap();
    let data_start = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as u64;
    let record = u16::from_le_bytes(bytes[105..107].try_into().unwrap()) as u64;
    drop(bytes);
    let path = dir.path().join("cut.las");
    let mut gpu = Gpu::new();
    // One batch decoding and one queued: before any upload the load thread has read at most
    // two batches, all before the cut. With two parts per batch the cut falls in a batch's second
    // part, whose first part must still arrive.
    for (parts_per_batch, cut) in [(1, 100_000), (2, 250_000)] {
        std::fs::copy(&whole, &path).unwrap();
        let config = LoadConfig {
            batch_points: (parts_per_batch * LAS_PART) as usize,
            queue_batches: 1,
            parallel_parts: 1,
            batches_decoding: 1,
            ..Default::default()
        };
        let mut load = ProgressiveLoad::start(&path, config).unwrap();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(data_start + cut * record)
            .unwrap();
        let dst = gpu.buffer(&load);
        let failures = gpu.upload_all(&mut load, &dst);
        assert_eq!(failures.len(), 1, "{failures:?}");
        let message = failures[0].to_string();
        assert!(message.contains(&path.display().to_string()), "{message}");
        let offset = format!("byte {}", data_start + cut * record);
        assert!(
            message.contains("ends early") && message.contains(&offset),
            "{message}"
        );
        let p = load.progress();
        let before_cut = cut / LAS_PART * LAS_PART;
        assert_eq!(p.state, LoadState::Failed);
        assert_eq!(
            (p.loaded, p.uploaded, p.total),
            (before_cut, before_cut, 300_000)
        );
        let got = dst.read(&gpu.ctx).unwrap();
        assert!(
            got == cpu_placement(&load, &whole, before_cut, LoadConfig::default().seed),
            "{parts_per_batch} parts per batch: the points before the cut differ"
        );
    }
}

#[test]
fn a_las_cut_before_loading_fails_at_start_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.las");
    let bytes = std::fs::read(testdata("simple.las")).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 500]).unwrap();
    let e = ProgressiveLoad::start(&path, LoadConfig::default())
        .err()
        .expect("a truncated LAS is refused");
    assert!(e.to_string().contains(&path.display().to_string()), "{e}");
}

#[test]
fn the_load_thread_runs_no_further_ahead_than_the_queue_bound() {
    let dir = tempfile::tempdir().unwrap();
    let path = generated_las(dir.path(), 300_000);
    let mut gpu = Gpu::new();
    let queue_batches = 2;
    let config = LoadConfig {
        batch_points: LAS_PART as usize,
        queue_batches,
        parallel_parts: 1,
        ..Default::default()
    };
    let mut load = ProgressiveLoad::start(&path, config).unwrap();
    // The queue's batches plus the one the load thread holds while it waits.
    let bound = (queue_batches as u64 + 1) * LAS_PART;
    let give_up = Instant::now() + Duration::from_secs(60);
    while load.progress().loaded < bound {
        assert!(
            Instant::now() < give_up,
            "the load thread never filled the queue"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    // Give a load thread that ignores the bound time to run past it.
    std::thread::sleep(Duration::from_millis(200));
    let p = load.progress();
    assert_eq!((p.loaded, p.uploaded), (bound, 0), "{p:?}");
    assert_eq!(p.state, LoadState::Loading);
    let dst = gpu.buffer(&load);
    let up = gpu.upload(&mut load, &dst);
    assert_eq!((up.batches, up.points), (2, 2 * LAS_PART));
    let failures = gpu.upload_all(&mut load, &dst);
    assert!(failures.is_empty(), "{failures:?}");
    assert_complete(&load.progress());
}

#[test]
fn a_buffer_of_another_size_or_encoding_is_refused() {
    let gpu = Gpu::new();
    let mut pass = ShufflePass::new(&gpu.ctx).unwrap();
    let mut load = ProgressiveLoad::start(&testdata("simple.las"), LoadConfig::default()).unwrap();
    for (encoding, n) in [
        (PointEncoding::Full16, load.total() as u32 - 1),
        (PointEncoding::Compact8, load.total() as u32),
    ] {
        let dst = ShuffledBuffer::new(&gpu.ctx, encoding, n).unwrap();
        let e = load
            .upload_ready(&gpu.ctx, &mut pass, &dst, 4)
            .expect_err("refused");
        assert!(matches!(e, EngineError::Config(_)), "{e}");
    }
}

#[test]
fn dropping_a_load_while_its_thread_waits_on_the_queue_stops_the_thread() {
    let dir = tempfile::tempdir().unwrap();
    let path = generated_las(dir.path(), 300_000);
    let config = LoadConfig {
        batch_points: LAS_PART as usize,
        queue_batches: 1,
        parallel_parts: 1,
        ..Default::default()
    };
    let load = ProgressiveLoad::start(&path, config).unwrap();
    let give_up = Instant::now() + Duration::from_secs(60);
    while load.progress().loaded < 2 * LAS_PART {
        assert!(
            Instant::now() < give_up,
            "the load thread never filled the queue"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    // The drop joins the load thread, which waits on the full queue: it must wake and end.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        drop(load);
        tx.send(()).unwrap();
    });
    rx.recv_timeout(Duration::from_secs(60))
        .expect("dropping the load hangs");
}
