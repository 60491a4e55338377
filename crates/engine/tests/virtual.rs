//! The virtualized renderer under budgets far below the store: it streams, evicts, keeps to the
//! budgets, and once the camera stops converges to exactly the full-detail image.

mod common;
use common::context;

use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::Camera;
use pointlet_engine::{target_bytes, SceneConfig, VirtualScene};
use pointlet_gpu::{
    GpuContext, PagedCloud, PointEncoding, PointletDesc, RasterVariant, RenderSettings,
    RenderTarget, Renderer,
};
use std::path::Path;

const W: u32 = 96;
const H: u32 = 64;

fn build_store(path: &Path, points: u64) {
    build_store_of(path, points, 300);
}

/// A store of about `pointlets` pointlets.
fn build_store_of(path: &Path, points: u64, pointlets: u64) {
    common::build_store(path, points, 11, pointlets);
}

fn settings() -> RenderSettings {
    RenderSettings {
        variant: RasterVariant::ReduceEarlyZ,
        ..Default::default()
    }
}

/// Renders `camera` still until the scene reports convergence; returns the image and frames.
fn converge(
    ctx: &GpuContext,
    scene: &mut VirtualScene,
    renderer: &mut Renderer,
    target: &mut RenderTarget,
    camera: &Camera,
    limit: u32,
) -> (Vec<u8>, u32) {
    for frame in 1..=limit {
        let report = scene
            .frame(ctx, renderer, camera, &settings(), target)
            .expect("frame");
        if report.converged {
            return (target.read_rgba(ctx).expect("readback"), frame);
        }
        // Give the loader threads a moment, as a real frame interval would.
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("no convergence within {limit} frames");
}

#[test]
fn budgets_far_below_the_store_still_converge_to_the_full_detail_image() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("gen.pointlet");
    let points = 300_000u64;
    build_store(&path, points);
    let store_bytes = std::fs::metadata(&path).expect("store").len();

    // Reference: everything fits, an effectively infinite bucket.
    let mut renderer = Renderer::new(&ctx);
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let mut full = VirtualScene::open(
        &ctx,
        &path,
        SceneConfig {
            vram_budget: 256 << 20,
            ram_budget: 256 << 20,
            bucket: 1e12,
            encoding: PointEncoding::Compact8,
            color: ColorMode::Rgb,
            ..Default::default()
        },
        (W, H),
    )
    .expect("open");
    let bounds = full.bounds();
    let overview = Camera::overview(&bounds, 60.0);
    let (expected, _) = converge(&ctx, &mut full, &mut renderer, &mut target, &overview, 400);
    drop(full);
    let covered = expected.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
    assert!(
        covered > (W * H / 10) as usize,
        "the overview shows the data: {covered}"
    );

    // Budgets: RAM a twentieth of the store file, VRAM room for a fifth of the points.
    let ram_budget = store_bytes / 20;
    let slot = PagedCloud::slot_bytes(PointEncoding::Compact8, 256);
    let vram_budget = target_bytes(W, H) + 300 * 1024 + (points / 5 / 256) * slot;
    let mut scene = VirtualScene::open(
        &ctx,
        &path,
        SceneConfig {
            vram_budget,
            ram_budget,
            bucket: 100_000.0,
            encoding: PointEncoding::Compact8,
            color: ColorMode::Rgb,
            upload_per_frame: 20_000,
            loaders: 2,
            ..Default::default()
        },
        (W, H),
    )
    .expect("open within budget");
    assert!(
        scene.gpu_bytes() + target_bytes(W, H) <= vram_budget,
        "{} + {} > {vram_budget}",
        scene.gpu_bytes(),
        target_bytes(W, H)
    );
    // Fly: a close-up, then the overview; each frame moves the camera a little.
    let closeup = Camera::closeup(&bounds, 60.0);
    let mut moving_evictions = 0;
    for k in 0..40 {
        let mut cam = if k < 20 { closeup } else { overview };
        cam.eye[2] += k as f64 * 0.01;
        let r = scene
            .frame(&ctx, &mut renderer, &cam, &settings(), &mut target)
            .expect("frame");
        assert!(!r.converged, "a moving camera never converges");
        moving_evictions += r.step.map_or(0, |s| s.pages_evicted);
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let (got, frames) = converge(
        &ctx,
        &mut scene,
        &mut renderer,
        &mut target,
        &overview,
        3000,
    );
    let stats = scene.cache_stats();
    assert!(stats.points_loaded > 0 && stats.load_tasks > 0, "{stats:?}");
    assert!(
        stats.points_evicted > 0 && stats.unload_tasks > 0,
        "RAM evictions: {stats:?}"
    );
    assert!(
        stats.ram_peak <= ram_budget,
        "RAM peak {} > budget {ram_budget}",
        stats.ram_peak
    );
    assert!(moving_evictions > 0, "GPU pages were evicted while flying");
    assert!(
        stats.points_loaded > points,
        "streaming re-read evicted points: {} loaded of {points}",
        stats.points_loaded
    );
    let differing = got
        .chunks(4)
        .zip(expected.chunks(4))
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(
        differing, 0,
        "converged after {frames} frames but {differing} pixels differ"
    );
}

#[test]
fn a_budget_too_small_for_the_tables_is_refused() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("small.pointlet");
    build_store(&path, 50_000);
    let err = VirtualScene::open(
        &ctx,
        &path,
        SceneConfig {
            vram_budget: 64 << 10,
            ..Default::default()
        },
        (W, H),
    )
    .err()
    .expect("refused");
    assert!(err.to_string().contains("VRAM budget"), "{err}");
}

#[test]
fn picking_reads_the_point_and_recolouring_replaces_only_colours() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("pick.pointlet");
    build_store(&path, 60_000);
    let mut renderer = Renderer::new(&ctx);
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let mut scene = VirtualScene::open(&ctx, &path, SceneConfig::default(), (W, H)).expect("open");
    let cam = Camera::overview(&scene.bounds(), 60.0);
    let (rgb, _) = converge(&ctx, &mut scene, &mut renderer, &mut target, &cam, 400);
    // The pixel at the centre shows data; the pick returns a stored point projecting there.
    let hit = scene
        .pick(
            &ctx,
            &mut renderer,
            &cam,
            &settings(),
            &mut target,
            [W / 2, H / 2],
            2,
        )
        .expect("pick")
        .expect("a point near the centre");
    let (pixel, depth) =
        pointlet_gpu::reference::project(&cam, W, H, hit.position).expect("in view");
    let (px, py) = ((pixel as u32 % W) as i64, (pixel as u32 / W) as i64);
    assert!(
        (px - (W / 2) as i64).abs() <= 2 && (py - (H / 2) as i64).abs() <= 2,
        "{px},{py}"
    );
    assert!((depth - hit.depth).abs() <= depth * 1e-3);
    let stored = scene.store().read_pointlet(hit.pointlet).expect("pointlet");
    assert_eq!(
        stored.xyz[hit.index as usize], hit.position,
        "exact stored coordinates"
    );
    // Classification colours: the picture changes, then converges again.
    let before = scene.cache_stats();
    scene
        .set_color(ColorMode::Classification)
        .expect("recolour");
    let mut moved = cam;
    moved.eye[2] += 1e-3;
    scene
        .frame(&ctx, &mut renderer, &moved, &settings(), &mut target)
        .expect("frame");
    let (classes, _) = converge(&ctx, &mut scene, &mut renderer, &mut target, &cam, 400);
    assert_ne!(rgb, classes);
    assert!(scene.cache_stats().points_evicted > before.points_evicted);
    // An edited scale (elevation over another range and gamma) recolours too; setting the
    // same scale again changes nothing.
    scene.set_color(ColorMode::Elevation).expect("elevation");
    let fitted = scene.color_scale();
    scene
        .frame(&ctx, &mut renderer, &moved, &settings(), &mut target)
        .expect("frame");
    let (elevation, _) = converge(&ctx, &mut scene, &mut renderer, &mut target, &cam, 400);
    let mid = 0.5 * (fitted.range[0] + fitted.range[1]);
    let edited = ColorScale {
        range: [mid, fitted.range[1]],
        gamma: 2.0,
        ..fitted
    };
    scene.set_color_scale(edited).expect("edited scale");
    let reloads = scene.cache_stats().points_evicted;
    scene.set_color_scale(edited).expect("same scale");
    assert_eq!(
        scene.cache_stats().points_evicted,
        reloads,
        "no reload for the same scale"
    );
    scene
        .frame(&ctx, &mut renderer, &moved, &settings(), &mut target)
        .expect("frame");
    let (edited_image, _) = converge(&ctx, &mut scene, &mut renderer, &mut target, &cam, 400);
    assert_ne!(elevation, edited_image);
    assert_eq!(scene.color_scale(), edited);
    // Recoloured while resident, the images equal those of scenes coloured so from the start
    // (no page keeps an old colour in the converged image).
    for (scale, image) in [(None, &classes), (Some(edited), &edited_image)] {
        let mut fresh = VirtualScene::open(
            &ctx,
            &path,
            SceneConfig {
                color: ColorMode::Classification,
                ..Default::default()
            },
            (W, H),
        )
        .expect("open");
        if let Some(scale) = scale {
            fresh.set_color_scale(scale).expect("scale");
        }
        let (expected, _) = converge(&ctx, &mut fresh, &mut renderer, &mut target, &cam, 400);
        let differing = expected
            .chunks(4)
            .zip(image.chunks(4))
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            differing,
            0,
            "{} pixels of the image recoloured to {:?} differ from a fresh scene's",
            differing,
            scale.map(|s| s.mode)
        );
    }
    assert!(
        scene.set_color(ColorMode::GpsTime).is_ok(),
        "the scene has GPS time"
    );
}

/// Renders `camera` still with `variant` until convergence; returns the image and the report.
fn converge_with(
    ctx: &GpuContext,
    scene: &mut VirtualScene,
    variant: RasterVariant,
    camera: &Camera,
    limit: u32,
) -> (Vec<u8>, pointlet_engine::FrameReport) {
    let mut renderer = Renderer::new(ctx);
    let mut target = RenderTarget::new(ctx, W, H).expect("target");
    let settings = RenderSettings {
        variant,
        ..Default::default()
    };
    for _ in 0..limit {
        let report = scene
            .frame(ctx, &mut renderer, camera, &settings, &mut target)
            .expect("frame");
        if report.converged {
            return (target.read_rgba(ctx).expect("readback"), report);
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("{} did not converge within {limit} frames", variant.name());
}

fn lit(image: &[u8]) -> usize {
    image.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks(4).zip(b.chunks(4)).filter(|(p, q)| p != q).count()
}

#[test]
fn stores_of_one_pointlet_and_a_few_points_draw_in_full() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    // One pointlet (its feedback is smaller than a GPU buffer's minimum), one point, exactly a
    // page, a page and a point, several pointlets.
    for points in [1u64, 106, 256, 257, 2000] {
        let path = dir.path().join(format!("{points}.pointlet"));
        build_store(&path, points);
        let mut scene =
            VirtualScene::open(&ctx, &path, SceneConfig::default(), (W, H)).expect("open");
        let cam = Camera::overview(&scene.bounds(), 60.0);
        let (image, report) =
            converge_with(&ctx, &mut scene, RasterVariant::ReduceEarlyZ, &cam, 200);
        assert_eq!(report.drawn_points, points, "{points} points drawn");
        assert!(lit(&image) > 0, "{points} points: the image is black");
    }
}

#[test]
fn a_tiny_bucket_draws_every_visible_pointlet_and_a_zero_bucket_is_refused() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("tiny.pointlet");
    build_store(&path, 60_000);
    let open = |bucket: f64| {
        VirtualScene::open(
            &ctx,
            &path,
            SceneConfig {
                bucket,
                ..Default::default()
            },
            (W, H),
        )
    };
    let mut full = open(1e12).expect("open");
    let cam = Camera::overview(&full.bounds(), 60.0);
    let (expected, _) = converge_with(&ctx, &mut full, RasterVariant::ReduceEarlyZ, &cam, 200);
    let pointlets = full.store().pointlets().len() as u64;
    drop(full);
    for bucket in [1.0, 10.0] {
        // The LoD image of the bucket alone: a point of every pointlet in view.
        let mut scene = open(bucket).expect("open");
        scene.set_accumulation(false);
        let mut renderer = Renderer::new(&ctx);
        let mut target = RenderTarget::new(&ctx, W, H).expect("target");
        let mut drawn = 0;
        for _ in 0..100 {
            let r = scene
                .frame(&ctx, &mut renderer, &cam, &settings(), &mut target)
                .expect("frame");
            assert!(
                !r.converged,
                "bucket {bucket}: the LoD image is not full detail"
            );
            drawn = r.drawn_points;
            if drawn >= pointlets {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        assert!(
            drawn >= pointlets && drawn < 60_000,
            "bucket {bucket}: {drawn} points drawn of {pointlets} pointlets in view"
        );
        assert!(lit(&target.read_rgba(&ctx).expect("readback")) > 0);
        // A still camera converges to full detail, never to a black image.
        scene.set_accumulation(true);
        let (got, _) = converge_with(&ctx, &mut scene, RasterVariant::ReduceEarlyZ, &cam, 200);
        assert_eq!(differing(&got, &expected), 0, "bucket {bucket}");
    }
    let err = open(0.0).err().expect("a zero bucket is refused");
    assert!(err.to_string().contains("bucket"), "{err}");
}

#[test]
fn variants_that_redraw_every_frame_converge_to_the_full_detail_image() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("hqs.pointlet");
    let points = 60_000u64;
    // Pointlets of several pages, so a pool of a page per pointlet and some more is short.
    build_store_of(&path, points, 30);
    let open = |bucket: f64, vram_budget: u64| {
        VirtualScene::open(
            &ctx,
            &path,
            SceneConfig {
                bucket,
                vram_budget,
                ..Default::default()
            },
            (W, H),
        )
        .expect("open")
    };
    // HQS and the 32-bit two-pass variant cannot add points to a kept framebuffer.
    for variant in [
        RasterVariant::Hqs,
        RasterVariant::Hqs1r,
        RasterVariant::AtomicMin32,
    ] {
        let mut full = open(1e12, 2 << 30);
        let cam = Camera::overview(&full.bounds(), 60.0);
        let (expected, report) = converge_with(&ctx, &mut full, variant, &cam, 200);
        assert_eq!(report.drawn_points, points);
        // From a bucket of a thirtieth of the store, the still camera reaches full detail.
        let mut scene = open(2_000.0, 2 << 30);
        let (got, report) = converge_with(&ctx, &mut scene, variant, &cam, 200);
        assert_eq!(report.drawn_points, points, "{}", variant.name());
        assert_eq!(differing(&got, &expected), 0, "{}", variant.name());
        // A pool that cannot hold the view at once: final with as many points as fit.
        let descs: Vec<PointletDesc> = full
            .store()
            .pointlets()
            .iter()
            .map(|p| PointletDesc {
                aabb: p.aabb,
                count: p.count,
            })
            .collect();
        let slot = PagedCloud::slot_bytes(PointEncoding::Compact8, 256);
        let tables = PagedCloud::overhead_bytes(&descs, 256) + target_bytes(W, H);
        // 40 pages beyond one per pointlet: requests of 10 240 points fit at once.
        let mut small = open(2_000.0, tables + (descs.len() as u64 + 40) * slot);
        let (got, report) = converge_with(&ctx, &mut small, variant, &cam, 200);
        assert!(
            report.drawn_points > 2_000 && report.drawn_points < points,
            "{}: {} points drawn",
            variant.name(),
            report.drawn_points
        );
        assert!(lit(&got) > 0);
    }
}

#[test]
fn the_page_pool_holds_the_store_not_the_whole_budget() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("pool.pointlet");
    let points = 60_000u64;
    build_store(&path, points);
    let scene = VirtualScene::open(&ctx, &path, SceneConfig::default(), (W, H)).expect("open");
    let pages: u64 = scene
        .store()
        .pointlets()
        .iter()
        .map(|p| p.count.div_ceil(256) as u64)
        .sum();
    assert_eq!(
        scene.slots() as u64,
        pages,
        "a page slot per page of the store"
    );
    // 60 000 points of 12 bytes, their tables: well under a percent of the 2 GiB budget.
    assert!(
        scene.gpu_bytes() < 4 << 20,
        "{} bytes allocated for {points} points",
        scene.gpu_bytes()
    );
}

#[test]
fn a_store_colour_scale_is_fitted_on_the_whole_scene_not_its_first_pointlet() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("s.pointlet");
    build_store_of(&path, 60_000, 200);
    let store = pointlet_store::Store::open(&path).expect("open");
    let all: Vec<_> = (0..store.pointlets().len())
        .map(|i| store.read_pointlet(i).expect("read"))
        .collect();
    for (mode, values) in [
        (
            ColorMode::Intensity,
            all.iter()
                .flat_map(|b| b.intensity.iter().map(|v| *v as f64))
                .collect::<Vec<_>>(),
        ),
        (
            ColorMode::GpsTime,
            all.iter().flat_map(|b| b.gps_time.clone()).collect(),
        ),
    ] {
        let [lo, hi] = pointlet_engine::fit_scale(&store, mode).expect("fit").range;
        // One spatial patch spans a sliver of the values: most points would clamp to an end.
        let outside = values.iter().filter(|v| **v < lo || **v > hi).count();
        assert!(
            outside * 5 < values.len(),
            "{}: {outside} of {} points outside the fitted range [{lo}, {hi}]",
            mode.name(),
            values.len()
        );
    }
}
