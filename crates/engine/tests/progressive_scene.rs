//! A point file drawn while it loads (`ProgressiveScene`), on lavapipe:
//! - a still camera converges to exactly the image of drawing every point at once (the static
//!   `GpuCloud` path), for LAS, LAZ, PLY, XYZ and a store read as a point file, also after
//!   moving while loading;
//! - a file larger than the VRAM budget keeps a uniform subset of all its points (χ² tests on
//!   the file order and on a spatial histogram, α = 0.001), every slot filled;
//! - a damaged file keeps what was read before the damage and reports the error once.
//!
//! Positions lie on a 1/256 grid within 64 units and the cameras' eyes on integers, so every
//! difference from an origin is exact in f32 and both paths compute identical clip positions.

mod common;
use common::context;

use pointlet_core::color::{point_color, ColorMode};
use pointlet_core::shuffle::SplitMix64;
use pointlet_core::{Camera, PointBatch, PointLayout, Quantization};
use pointlet_engine::progressive::LoadConfig;
use pointlet_engine::{FillBudget, ProgressiveConfig, ProgressiveReport, ProgressiveScene};
use pointlet_gpu::progressive::ProgressiveTiming;
use pointlet_gpu::{
    GpuCloud, GpuContext, PointEncoding, PointSet, PointSize, RasterVariant, RenderSettings,
    RenderTarget, Renderer, SplatSettings, SplatShape,
};
use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use pointlet_io::PointReader;
use pointlet_store::{BuildConfig, StoreBuilder};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const W: u32 = 160;
const H: u32 = 100;
const N: usize = 40_000;
const GRID: f64 = 256.0;

fn camera() -> Camera {
    Camera {
        eye: [8.0, 4.0, 30.0],
        target: [32.0, 32.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y_deg: 60.0,
        near: 0.5,
        far: 500.0,
    }
}

fn moved() -> Camera {
    Camera {
        eye: [60.0, 10.0, 20.0],
        target: [30.0, 40.0, 0.0],
        ..camera()
    }
}

/// A wavy terrain with pillars over 64 × 64 units, on the 1/256 grid, unique positions, RGB
/// colours from the position.
fn terrain() -> PointBatch {
    let layout = PointLayout {
        rgb: true,
        ..Default::default()
    };
    let mut b = PointBatch::with_capacity(layout, N);
    let mut rng = SplitMix64::new(21);
    let mut seen = HashSet::new();
    while b.len() < N {
        let (gx, gy) = (rng.below(64 * 256), rng.below(64 * 256));
        if !seen.insert((gx, gy)) {
            continue;
        }
        let (x, y) = (gx as f64 / GRID, gy as f64 / GRID);
        let mut z = 4.0 * (x / 6.0).sin() * (y / 5.0).cos() + 8.0;
        if (x % 16.0) < 2.0 && (y % 16.0) < 2.0 {
            z += 12.0 * rng.unit_f64();
        }
        b.xyz.push([x, y, (z * GRID).round() / GRID]);
        b.rgb
            .push([(gx * 4) as u16, (gy * 4) as u16, ((z * 2000.0) as u16)]);
        b.intensity.push(0);
        b.returns.push(0x11);
        b.flags.push(0);
        b.classification.push(2);
        b.scan_angle.push(0.0);
        b.user_data.push(0);
        b.point_source_id.push(0);
    }
    b
}

fn write_las(path: &Path, batch: &PointBatch, compress: bool) {
    let mut w = LasWriter::create(
        path,
        LasWriterConfig {
            quantization: Quantization {
                scale: [1.0 / GRID; 3],
                offset: [0.0; 3],
            },
            point_format: 2,
            layout: batch.layout,
            vlrs: Vec::new(),
            fields: Default::default(),
            compress,
        },
    )
    .unwrap();
    w.write_batch(batch).unwrap();
    w.finish().unwrap();
}

fn write_ply(path: &Path, batch: &PointBatch) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
         property uchar blue\nend_header\n",
        batch.len()
    )
    .into_bytes();
    for (p, c) in batch.xyz.iter().zip(&batch.rgb) {
        for v in p {
            bytes.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        bytes.extend_from_slice(&[(c[0] >> 8) as u8, (c[1] >> 8) as u8, (c[2] >> 8) as u8]);
    }
    std::fs::write(path, bytes).unwrap();
}

fn write_xyz(path: &Path, batch: &PointBatch) {
    let text: String = batch
        .xyz
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    std::fs::write(path, text).unwrap();
}

/// The four kinds of point file, each holding `terrain()`.
fn files(dir: &Path) -> Vec<PathBuf> {
    let batch = terrain();
    let las = dir.join("t.las");
    write_las(&las, &batch, false);
    let laz = dir.join("t.laz");
    write_las(&laz, &batch, true);
    let ply = dir.join("t.ply");
    write_ply(&ply, &batch);
    let xyz = dir.join("t.xyz");
    write_xyz(&xyz, &batch);
    let store = dir.join("t.pointlet");
    write_store(&store, &las);
    vec![las, laz, ply, xyz, store]
}

/// The store of `las`'s points, in small pointlets (several per part of the store's reader).
fn write_store(path: &Path, las: &Path) {
    let mut reader = pointlet_io::open(las).unwrap();
    let config = BuildConfig {
        target_pointlets: 400,
        ..Default::default()
    };
    let mut builder =
        StoreBuilder::create(path, config, reader.meta(), vec!["t.las".into()]).unwrap();
    while let Some(b) = reader.read_batch(10_000).unwrap() {
        builder.push(&b).unwrap();
    }
    builder.finish().unwrap();
}

fn config(variant: RasterVariant, budget: u64) -> ProgressiveConfig {
    ProgressiveConfig {
        load: LoadConfig {
            batch_points: 3_000,
            ..Default::default()
        },
        variant,
        page_size: 1024,
        fixed_budget: Some(budget),
        ..Default::default()
    }
}

/// The scene's own rasterizer with default screen passes and one-pixel points.
fn settings_of(scene: &ProgressiveScene) -> RenderSettings {
    RenderSettings {
        variant: scene.variant(),
        ..Default::default()
    }
}

fn frame(
    ctx: &GpuContext,
    scene: &mut ProgressiveScene,
    camera: &Camera,
    target: &mut RenderTarget,
) -> ProgressiveReport {
    frame_with(ctx, scene, camera, &SplatSettings::default(), target)
}

fn frame_with(
    ctx: &GpuContext,
    scene: &mut ProgressiveScene,
    camera: &Camera,
    splats: &SplatSettings,
    target: &mut RenderTarget,
) -> ProgressiveReport {
    let settings = RenderSettings {
        splats: *splats,
        ..settings_of(scene)
    };
    scene.frame(ctx, camera, &settings, target).unwrap()
}

/// Frames of `camera` until the scene says the image is final; the frames it took.
fn converge(
    ctx: &GpuContext,
    scene: &mut ProgressiveScene,
    camera: &Camera,
    target: &mut RenderTarget,
) -> u64 {
    converge_with(ctx, scene, camera, &SplatSettings::default(), target)
}

fn converge_with(
    ctx: &GpuContext,
    scene: &mut ProgressiveScene,
    camera: &Camera,
    splats: &SplatSettings,
    target: &mut RenderTarget,
) -> u64 {
    let give_up = Instant::now() + Duration::from_secs(120);
    let mut frames = 0;
    loop {
        let r = frame_with(ctx, scene, camera, splats, target);
        frames += 1;
        assert!(r.failure.is_none(), "{:?}", r.failure);
        if r.converged {
            return frames;
        }
        assert!(Instant::now() < give_up, "never converged");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Every point of `path` drawn at once by the static path, coloured by the scene's scale.
fn static_image(
    ctx: &GpuContext,
    path: &Path,
    scene: &ProgressiveScene,
    variant: RasterVariant,
    camera: &Camera,
) -> Image {
    static_image_with(ctx, path, scene, variant, &SplatSettings::default(), camera)
}

fn static_image_with(
    ctx: &GpuContext,
    path: &Path,
    scene: &ProgressiveScene,
    variant: RasterVariant,
    splats: &SplatSettings,
    camera: &Camera,
) -> Image {
    let scale = scene.color().expect("colouring chosen").scale;
    let mut reader = pointlet_engine::open_points(path, &Default::default()).unwrap();
    let mut set = PointSet::default();
    while let Some(b) = reader.read_batch(10_000).unwrap() {
        for i in 0..b.len() {
            set.positions.push(b.xyz[i]);
            set.colors.push(point_color(&b, i, &scale));
        }
    }
    let mut cloud = GpuCloud::upload(ctx, &set, PointEncoding::Full16, 1024).unwrap();
    let mut target = RenderTarget::new(ctx, W, H).unwrap();
    let settings = RenderSettings {
        variant,
        splats: *splats,
        ..Default::default()
    };
    Renderer::new(ctx)
        .render(ctx, &mut cloud, camera, &settings, &mut target)
        .unwrap();
    Image {
        rgba: target.read_rgba(ctx).unwrap(),
        depth: target.read_depth(ctx).unwrap(),
    }
}

struct Image {
    rgba: Vec<u8>,
    depth: Vec<f32>,
}

fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count()
}

fn lit(rgba: &[u8]) -> usize {
    rgba.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

#[test]
fn a_still_camera_converges_to_drawing_every_point_for_every_file_kind() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let variants = [
        RasterVariant::AtomicMin,
        RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
    ];
    for path in files(dir.path()) {
        for variant in variants {
            let mut scene = ProgressiveScene::open(&ctx, &path, config(variant, 7_777)).unwrap();
            assert_eq!(scene.slots(), N as u64, "{}", path.display());
            let mut target = RenderTarget::new(&ctx, W, H).unwrap();
            // Moving while loading, then still: the image must still become exact.
            for _ in 0..3 {
                frame(&ctx, &mut scene, &moved(), &mut target);
            }
            let frames = converge(&ctx, &mut scene, &camera(), &mut target);
            assert!(frames >= (N as u64).div_ceil(7_777), "{frames} frames");
            let got = Image {
                rgba: target.read_rgba(&ctx).unwrap(),
                depth: target.read_depth(&ctx).unwrap(),
            };
            let want = static_image(&ctx, &path, &scene, variant, &camera());
            assert!(
                lit(&want.rgba) > (W * H / 4) as usize,
                "the view shows the terrain"
            );
            let name = format!("{} with {}", path.display(), variant.name());
            // Every pixel's closest depth is the same: the same points won.
            assert!(
                got.depth == want.depth,
                "{name}: the converged depths differ"
            );
            // And the same colours, where points share the closest depth exactly too (the
            // terrain has such ties: the kept colour keys give the static path's smaller colour).
            let differ = differing(&got.rgba, &want.rgba);
            assert!(differ == 0, "{name}: {differ} pixels differ in colour");
        }
    }
}

#[test]
fn a_store_in_several_buffers_converges_to_every_point() {
    let probe = context();
    // The memory comes from Vulkan directly on lavapipe, as on the GPU machine.
    assert!(probe.caps.direct_memory, "no direct point memory on Vulkan");
    for direct in [false, true] {
        let mut ctx = context();
        // Buffers of 5 pages of 1 024 slots: pointlets of 128 points, 40 to a chunk, 8 chunks.
        // Through wgpu all but the first are made while frames are drawn; directly, all at once,
        // the pointlets interleaved over all of them.
        ctx.caps.max_binding = 1024 * 12 * 5;
        ctx.caps.direct_memory = direct;
        let dir = tempfile::tempdir().unwrap();
        let las = dir.path().join("t.las");
        write_las(&las, &terrain(), false);
        let store = dir.path().join("t.pointlet");
        write_store(&store, &las);
        let variant = RasterVariant::AtomicMin;
        let mut scene = ProgressiveScene::open(&ctx, &store, config(variant, 7_777)).unwrap();
        assert_eq!(scene.slots(), N as u64);
        let made = scene.buffer_chunks();
        assert_eq!(made.0, if direct { made.1 } else { 1 }, "direct {direct}");
        assert!(made.1 > 1, "{made:?}");
        let mut target = RenderTarget::new(&ctx, W, H).unwrap();
        for _ in 0..3 {
            frame(&ctx, &mut scene, &moved(), &mut target);
        }
        converge(&ctx, &mut scene, &camera(), &mut target);
        assert_eq!(scene.buffer_chunks(), (made.1, made.1));
        let got = Image {
            rgba: target.read_rgba(&ctx).unwrap(),
            depth: target.read_depth(&ctx).unwrap(),
        };
        let want = static_image(&ctx, &store, &scene, variant, &camera());
        assert!(lit(&want.rgba) > (W * H / 4) as usize);
        assert!(
            got.depth == want.depth,
            "direct {direct}: the converged depths differ"
        );
        let differ = differing(&got.rgba, &want.rgba);
        assert!(
            differ == 0,
            "direct {direct}: {differ} pixels differ in colour"
        );
        // Every point is in a slot (a chunk's unused slots stay empty).
        let (contents, _) = scene.read_buffer(&ctx).unwrap();
        let filled = contents
            .positions
            .chunks(3)
            .filter(|w| w[0] != u32::MAX)
            .count();
        assert_eq!(filled, N, "direct {direct}");
    }
}

#[test]
fn fixed_splats_converge_to_drawing_every_point_as_splats() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let splats = SplatSettings {
        size: PointSize::Fixed(3),
        shape: SplatShape::Square,
        ..Default::default()
    };
    let path = files(dir.path()).swap_remove(0);
    for variant in [
        RasterVariant::AtomicMin,
        RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
    ] {
        let mut scene = ProgressiveScene::open(&ctx, &path, config(variant, 7_777)).unwrap();
        let mut target = RenderTarget::new(&ctx, W, H).unwrap();
        for _ in 0..3 {
            frame_with(&ctx, &mut scene, &moved(), &splats, &mut target);
        }
        converge_with(&ctx, &mut scene, &camera(), &splats, &mut target);
        let got = target.read_rgba(&ctx).unwrap();
        let want = static_image_with(&ctx, &path, &scene, variant, &splats, &camera());
        assert!(
            lit(&want.rgba) > lit(&static_image(&ctx, &path, &scene, variant, &camera()).rgba),
            "splats cover more than points"
        );
        let differ = differing(&got, &want.rgba);
        assert!(
            differ == 0,
            "{}: {differ} pixels differ (lit {} vs {})",
            variant.name(),
            lit(&got),
            lit(&want.rgba)
        );
    }
}

/// χ² of `counts` against `expected` (cells expecting fewer than 5 are pooled) and its
/// degrees of freedom.
fn chi_square(counts: &[f64], expected: &[f64]) -> (f64, usize) {
    let (mut chi, mut cells, mut pool_c, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
    for (c, e) in counts.iter().zip(expected) {
        if *e < 5.0 {
            pool_c += c;
            pool_e += e;
            continue;
        }
        chi += (c - e).powi(2) / e;
        cells += 1;
    }
    if pool_e > 0.0 {
        chi += (pool_c - pool_e).powi(2) / pool_e;
        cells += 1;
    }
    (chi, cells.saturating_sub(1))
}

/// The χ² quantile of 1 - 0.001 (Wilson–Hilferty approximation).
fn chi_critical(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.090_232; // standard normal quantile of 0.999
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

#[test]
fn a_file_beyond_the_vram_budget_keeps_a_uniform_subset() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let batch = terrain();
    let path = dir.path().join("big.las");
    write_las(&path, &batch, false);
    // A LAS file keeps the reservoir's subset; a store the first points of every pointlet.
    let store = dir.path().join("big.pointlet");
    write_store(&store, &path);
    for path in [&path, &store] {
        assert_eq!(keeps_a_uniform_subset(&ctx, path, &batch), 1);
    }
    // The store again in buffers of 4 pages: its kept rows in 3 chunks, made while drawn.
    let mut chunked = context();
    chunked.caps.max_binding = 1024 * 12 * 4;
    assert_eq!(keeps_a_uniform_subset(&chunked, &store, &batch), 3);
}

/// Loads `path` beyond a VRAM budget and checks the subset kept; the buffer's chunks.
fn keeps_a_uniform_subset(
    ctx: &pointlet_gpu::GpuContext,
    path: &Path,
    batch: &PointBatch,
) -> usize {
    let keep = 10_000u64;
    let mut cfg = config(RasterVariant::AtomicMin, 4_000);
    cfg.vram_budget = keep * pointlet_engine::SLOT_BYTES;
    let mut scene = ProgressiveScene::open(ctx, path, cfg).unwrap();
    assert_eq!(scene.points(), N as u64);
    // A store keeps whole rows of its pointlets: up to a row (a point a pointlet) fewer.
    let kept = scene.slots();
    assert!(
        kept <= keep && kept * 50 >= keep * 49,
        "{kept} kept of {keep}"
    );
    let mut target = RenderTarget::new(ctx, W, H).unwrap();
    converge(ctx, &mut scene, &camera(), &mut target);
    assert!(lit(&target.read_rgba(ctx).unwrap()) > 1000);
    assert_eq!(scene.progress().uploaded, N as u64, "every point was read");

    // Which point of the file each slot holds.
    let index: HashMap<[i64; 3], usize> = batch
        .xyz
        .iter()
        .enumerate()
        .map(|(i, p)| (p.map(|v| (v * GRID).round() as i64), i))
        .collect();
    // The slots a store's chunks leave unused at their ends stay empty: as many are filled
    // as were kept.
    let (contents, origin) = scene.read_buffer(ctx).unwrap();
    let slots: Vec<usize> = contents
        .positions
        .chunks(3)
        .filter(|w| w[0] != u32::MAX)
        .map(|w| {
            let p: [f64; 3] = std::array::from_fn(|a| origin[a] + f32::from_bits(w[a]) as f64);
            let key = p.map(|v| (v * GRID).round() as i64);
            *index.get(&key).expect("a slot holds a point of the file")
        })
        .collect();
    assert_eq!(slots.len() as u64, kept);
    let distinct: HashSet<usize> = slots.iter().copied().collect();
    assert_eq!(distinct.len(), slots.len(), "a point kept twice");

    // Uniform over the file order: 20 bins of file indices.
    let mut bins = vec![0.0; 20];
    for &i in &slots {
        bins[i * 20 / N] += 1.0;
    }
    let (chi, dof) = chi_square(&bins, &[kept as f64 / 20.0; 20]);
    assert!(
        chi < chi_critical(dof),
        "{}, file order: χ² {chi:.1} ≥ {:.1}",
        path.display(),
        chi_critical(dof)
    );

    // Uniform in space, for the whole buffer and for a prefix (of one chunk: several are
    // uniform by the same share of each, core's tests): 8 × 8 cells over the terrain,
    // expected in proportion to the file's points per cell.
    let cell = |i: usize| {
        let p = batch.xyz[i];
        ((p[0] / 8.0) as usize).min(7) * 8 + ((p[1] / 8.0) as usize).min(7)
    };
    let mut file_cells = vec![0.0; 64];
    for i in 0..N {
        file_cells[cell(i)] += 1.0;
    }
    let prefixes = if scene.buffer_chunks().1 == 1 {
        vec![kept as usize, 2_000]
    } else {
        vec![kept as usize]
    };
    for prefix in prefixes {
        let mut got = vec![0.0; 64];
        for &i in &slots[..prefix] {
            got[cell(i)] += 1.0;
        }
        let want: Vec<f64> = file_cells
            .iter()
            .map(|c| c * prefix as f64 / N as f64)
            .collect();
        let (chi, dof) = chi_square(&got, &want);
        assert!(
            chi < chi_critical(dof),
            "{}, prefix {prefix}: spatial χ² {chi:.1} ≥ {:.1}",
            path.display(),
            chi_critical(dof)
        );
    }
    scene.buffer_chunks().1
}

#[test]
fn a_damaged_file_shows_what_was_read_and_reports_the_error_once() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let scene_gen = SceneGenerator::new(SceneConfig {
        points: 300_000,
        seed: 5,
    });
    let meta = scene_gen.meta();
    let path = dir.path().join("cut.las");
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
    let mut r = scene_gen.reader();
    while let Some(b) = r.read_batch(50_000).unwrap() {
        w.write_batch(&b).unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let data_start = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as u64;
    let record = u16::from_le_bytes(bytes[105..107].try_into().unwrap()) as u64;
    drop(bytes);
    let mut cfg = config(RasterVariant::AtomicMin, 1 << 20);
    // One batch decoding, one queued: the load thread waits for the frames before the cut.
    cfg.load.queue_batches = 1;
    cfg.load.parallel_parts = 1;
    cfg.load.batches_decoding = 1;
    let mut scene = ProgressiveScene::open(&ctx, &path, cfg).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(data_start + 100_000 * record)
        .unwrap();
    let camera = Camera::overview(&scene.bounds(), 60.0);
    let mut target = RenderTarget::new(&ctx, W, H).unwrap();
    let give_up = Instant::now() + Duration::from_secs(60);
    let mut failures = Vec::new();
    while !scene.progress().is_finished() {
        failures.extend(frame(&ctx, &mut scene, &camera, &mut target).failure);
        assert!(Instant::now() < give_up, "loading never ended");
    }
    for _ in 0..3 {
        failures.extend(frame(&ctx, &mut scene, &camera, &mut target).failure);
    }
    assert_eq!(failures.len(), 1, "{failures:?}");
    let message = &failures[0];
    assert!(message.contains(&path.display().to_string()), "{message}");
    assert!(
        message.contains(&format!("byte {}", data_start + 100_000 * record)),
        "{message}"
    );
    assert_eq!(scene.failure(), Some(message.as_str()));
    let p = scene.progress();
    assert!(p.uploaded > 0 && p.uploaded <= 100_000, "{p:?}");
    assert!(
        lit(&target.read_rgba(&ctx).unwrap()) > 500,
        "the points read stay drawn"
    );
}

#[test]
fn the_fill_budget_follows_the_frame_time() {
    let mut b = FillBudget::new(100_000_000, 16.0);
    let start = b.current();
    let slow = ProgressiveTiming {
        reproject_ms: 1.0,
        fill_ms: 40.0,
        screen_ms: 1.0,
    };
    b.observe(start, &slow);
    assert_eq!(b.current(), start / 2, "a slow frame halves S at most");
    let fast = ProgressiveTiming {
        fill_ms: 1.0,
        ..slow
    };
    for _ in 0..40 {
        let s = b.current();
        b.observe(s, &fast);
    }
    // 16 ms · 0.85 - 2 ms of fixed passes, at 1 ms per S points.
    let s = b.current();
    b.observe(s, &fast);
    assert_eq!(b.current(), 100_000_000, "capped at every slot");
    for _ in 0..60 {
        let s = b.current();
        b.observe(
            s,
            &ProgressiveTiming {
                fill_ms: 1e6,
                ..slow
            },
        );
    }
    assert_eq!(b.current(), b.floor(), "never below the floor");
    assert_eq!(b.floor(), 100_000_000 / 600);
}

#[test]
fn picking_names_the_point_of_the_file_under_the_cursor() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let batch = terrain();
    let path = dir.path().join("pick.las");
    write_las(&path, &batch, false);
    let mut scene =
        ProgressiveScene::open(&ctx, &path, config(RasterVariant::AtomicMin, 50_000)).unwrap();
    let mut target = RenderTarget::new(&ctx, W, H).unwrap();
    converge(&ctx, &mut scene, &camera(), &mut target);
    let depth = target.read_depth(&ctx).unwrap();
    let points: HashSet<[i64; 3]> = batch
        .xyz
        .iter()
        .map(|p| p.map(|v| (v * GRID).round() as i64))
        .collect();
    let mut picked = 0;
    for k in (0..depth.len()).step_by(97).filter(|k| depth[*k] > 0.0) {
        let pixel = [k as u32 % W, k as u32 / W];
        let p = scene
            .pick(&ctx, pixel, 0)
            .unwrap()
            .expect("a lit pixel has a point");
        let key = p.map(|v| (v * GRID).round() as i64);
        assert!(points.contains(&key), "{p:?} is no point of the file");
        let (at, _) = pointlet_gpu::reference::project(&camera(), W, H, p).expect("in view");
        assert_eq!(at, k, "the picked point lies under pixel {pixel:?}");
        picked += 1;
    }
    assert!(picked > 20, "{picked} pixels picked");
    // A pixel outside the image names nothing.
    assert!(scene.pick(&ctx, [W + 5, 0], 3).unwrap().is_none());
}

#[test]
fn recolouring_a_loaded_file_rewrites_the_colours_only() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("colours.las");
    write_las(&path, &terrain(), false);
    let mut cfg = config(RasterVariant::AtomicMin, 50_000);
    cfg.load.color = Some(ColorMode::Elevation);
    let mut scene = ProgressiveScene::open(&ctx, &path, cfg).unwrap();
    let mut target = RenderTarget::new(&ctx, W, H).unwrap();
    converge(&ctx, &mut scene, &camera(), &mut target);
    let (before, origin) = scene.read_buffer(&ctx).unwrap();
    let elevation = target.read_rgba(&ctx).unwrap();
    // The file as read, by grid position, to recompute each slot's colour.
    let mut reader = pointlet_io::open(&path).unwrap();
    let file = reader.read_batch(N).unwrap().unwrap();
    let index: HashMap<[i64; 3], usize> = file
        .xyz
        .iter()
        .enumerate()
        .map(|(i, p)| (p.map(|v| (v * GRID).round() as i64), i))
        .collect();
    let check = |scene: &ProgressiveScene, scale: &pointlet_core::color::ColorScale| {
        let (after, _) = scene.read_buffer(&ctx).unwrap();
        assert!(
            after.positions == before.positions,
            "positions were rewritten"
        );
        for (w, c) in after.positions.chunks(3).zip(&after.colors) {
            let key: [i64; 3] = std::array::from_fn(|a| {
                ((origin[a] + f32::from_bits(w[a]) as f64) * GRID).round() as i64
            });
            assert_eq!(*c, point_color(&file, index[&key], scale));
        }
    };
    scene.recolor(ColorMode::Rgb).unwrap();
    converge(&ctx, &mut scene, &camera(), &mut target);
    let rgb = scene.color().unwrap().scale;
    assert_eq!(rgb.mode, ColorMode::Rgb);
    check(&scene, &rgb);
    assert!(target.read_rgba(&ctx).unwrap() != elevation);
    // An edited scale is taken as it is.
    let mut edited = pointlet_core::color::ColorScale::fit(ColorMode::Elevation, &[], [0.0, 1.0]);
    edited.range = [7.0, 9.0];
    scene.recolor_with(edited).unwrap();
    converge(&ctx, &mut scene, &camera(), &mut target);
    assert_eq!(scene.color().unwrap().scale, edited);
    check(&scene, &edited);
}

/// The terrain's points whose x is below (`west`) or from 32 on.
fn half(batch: &PointBatch, west: bool) -> PointBatch {
    let mut out = PointBatch::with_capacity(batch.layout, batch.len() / 2);
    for i in (0..batch.len()).filter(|i| (batch.xyz[*i][0] < 32.0) == west) {
        out.push_from(batch, i);
    }
    out
}

#[test]
fn several_inputs_converge_to_drawing_all_their_points_and_reopen_with_fewer() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let all = terrain();
    let (west, east) = (half(&all, true), half(&all, false));
    let whole = d.join("whole.las");
    write_las(&whole, &all, false);
    let west_laz = d.join("west.laz");
    write_las(&west_laz, &west, true);
    let west_las = d.join("west.las");
    write_las(&west_las, &west, false);
    let east_las = d.join("east.las");
    write_las(&east_las, &east, false);
    let east_store = d.join("east.pointlet");
    write_store(&east_store, &east_las);
    let east_xyz = d.join("east.xyz");
    write_xyz(&east_xyz, &east);
    let variant = RasterVariant::AtomicMin;
    let mut cfg = config(variant, 7_777);
    cfg.load.color = Some(ColorMode::Elevation);
    // Parts from a LAZ file and a store; then a LAS file with a text file read front to back.
    for inputs in [
        vec![west_laz.clone(), east_store.clone()],
        vec![west_las.clone(), east_xyz.clone()],
    ] {
        let mut scene = ProgressiveScene::open_many(&ctx, &inputs, cfg.clone()).unwrap();
        assert_eq!(scene.points(), N as u64);
        assert_eq!(scene.inputs(), &inputs[..]);
        assert!(scene.path().display().to_string().contains(" + "));
        let mut target = RenderTarget::new(&ctx, W, H).unwrap();
        converge(&ctx, &mut scene, &camera(), &mut target);
        let got = target.read_rgba(&ctx).unwrap();
        let want = static_image(&ctx, &whole, &scene, variant, &camera());
        let differ = differing(&got, &want.rgba);
        assert!(
            differ == 0 && target.read_depth(&ctx).unwrap() == want.depth,
            "{inputs:?}: {differ} pixels differ from drawing the whole terrain"
        );
        // Hiding one input: the other alone, exactly.
        scene.reopen(&ctx, &inputs[..1]).unwrap();
        assert_eq!(scene.points(), west.len() as u64);
        converge(&ctx, &mut scene, &camera(), &mut target);
        let got = target.read_rgba(&ctx).unwrap();
        let want = static_image(&ctx, &west_las, &scene, variant, &camera());
        assert_eq!(
            differing(&got, &want.rgba),
            0,
            "{inputs:?}: the west half alone"
        );
        assert!(lit(&got) < lit(&static_image(&ctx, &whole, &scene, variant, &camera()).rgba));
    }
}
