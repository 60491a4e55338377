//! Adaptive splats on a store: a pointlet drawn at a fraction of its points gets splats sized
//! to the spacing of what is drawn, so a densely sampled flat surface stays closed at any LoD;
//! a still camera still converges (redrawing, as splats shrink while points are added).

mod common;
use common::context;

use pointlet_core::color::ColorMode;
use pointlet_core::{Aabb, Camera, PointBatch, PointLayout, Quantization, SourceMeta};
use pointlet_engine::{SceneConfig, VirtualScene};
use pointlet_gpu::{
    GpuContext, RasterVariant, RenderSettings, RenderTarget, Renderer, SplatSettings,
};
use pointlet_store::{BuildConfig, StoreBuilder};
use std::path::Path;

const W: u32 = 128;
const H: u32 = 96;
/// Grid points per side of the plane, one every 5 cm over 40 m: 640 000 points.
const SIDE: usize = 800;
const STEP: f64 = 0.05;

/// A flat plane z = 0 sampled on a regular grid, intensity by position (colours vary).
fn build_plane(path: &Path) {
    let extent = SIDE as f64 * STEP;
    let meta = SourceMeta {
        format: "plane".into(),
        point_count: (SIDE * SIDE) as u64,
        bounds: Aabb {
            min: [0.0, 0.0, 0.0],
            max: [extent, extent, 0.0],
        },
        quantization: Some(Quantization {
            scale: [0.001; 3],
            offset: [0.0; 3],
        }),
        layout: PointLayout::default(),
        las_point_format: None,
        vlrs: Vec::new(),
        las: None,
    };
    let config = BuildConfig {
        target_pointlets: 400,
        ..Default::default()
    };
    let mut builder =
        StoreBuilder::create(path, config, &meta, vec!["plane".into()]).expect("builder");
    for row in 0..SIDE {
        let mut b = PointBatch::with_capacity(PointLayout::default(), SIDE);
        for col in 0..SIDE {
            b.xyz.push([col as f64 * STEP, row as f64 * STEP, 0.0]);
            b.intensity
                .push(((col * 7 + row * 13) % 251) as u16 * 200 + 5000);
            b.returns.push(0x11);
            b.flags.push(0);
            b.classification.push(2);
            b.scan_angle.push(0.0);
            b.user_data.push(0);
            b.point_source_id.push(1);
        }
        builder.push(&b).expect("push");
    }
    builder.finish().expect("finish");
}

/// Looking down at the plane's middle from 60° above it; the plane fills the view.
fn camera() -> Camera {
    let c = SIDE as f64 * STEP / 2.0;
    Camera {
        eye: [c - 5.0, c - 5.0, 12.0],
        target: [c, c, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y_deg: 50.0,
        near: 0.5,
        far: 200.0,
    }
}

fn settings(splats: SplatSettings) -> RenderSettings {
    RenderSettings {
        variant: RasterVariant::ReduceEarlyZ,
        splats,
        ..Default::default()
    }
}

fn empty(image: &[u8]) -> usize {
    image.chunks(4).filter(|p| p[..3] == [0, 0, 0]).count()
}

/// Frames of a moving camera's LoD image (no accumulation) until the drawn points settle.
fn lod_image(ctx: &GpuContext, scene: &mut VirtualScene, splats: SplatSettings) -> (Vec<u8>, u64) {
    let mut renderer = Renderer::new(ctx);
    let mut target = RenderTarget::new(ctx, W, H).expect("target");
    scene.set_accumulation(false);
    let mut last = 0;
    let mut same = 0;
    for _ in 0..400 {
        let r = scene
            .frame(
                ctx,
                &mut renderer,
                &camera(),
                &settings(splats),
                &mut target,
            )
            .expect("frame");
        same = if r.drawn_points == last && last > 0 {
            same + 1
        } else {
            0
        };
        last = r.drawn_points;
        if same >= 5 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    (target.read_rgba(ctx).expect("readback"), last)
}

#[test]
fn adaptive_splats_keep_a_plane_closed_at_a_fraction_of_its_points() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("plane.pointlet");
    build_plane(&path);
    let total = (SIDE * SIDE) as u64;
    for share in [0.005, 0.02] {
        let bucket = total as f64 * share;
        let mut scene = VirtualScene::open(
            &ctx,
            &path,
            SceneConfig {
                bucket,
                color: ColorMode::Intensity,
                ..Default::default()
            },
            (W, H),
        )
        .expect("open");
        let (one, drawn) = lod_image(&ctx, &mut scene, SplatSettings::default());
        assert!(
            drawn < total / 2,
            "{share}: the LoD draws a fraction of the plane ({drawn} of {total})"
        );
        assert!(
            empty(&one) > (W * H) as usize / 20,
            "{share}: one-pixel points leave holes ({} empty)",
            empty(&one)
        );
        let (splats, _) = lod_image(&ctx, &mut scene, SplatSettings::adaptive());
        assert_eq!(
            empty(&splats),
            0,
            "{share}: adaptive splats leave no background pixel inside the plane"
        );
    }
}

#[test]
fn a_still_camera_with_adaptive_splats_converges() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("plane.pointlet");
    build_plane(&path);
    let mut scene = VirtualScene::open(
        &ctx,
        &path,
        SceneConfig {
            bucket: 5_000.0,
            color: ColorMode::Intensity,
            ..Default::default()
        },
        (W, H),
    )
    .expect("open");
    let mut renderer = Renderer::new(&ctx);
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let splats = settings(SplatSettings::adaptive());
    let mut converged = None;
    for frame in 1..=600 {
        let r = scene
            .frame(&ctx, &mut renderer, &camera(), &splats, &mut target)
            .expect("frame");
        assert!(
            !r.accumulating || !splats.accumulates(),
            "adaptive splats redraw"
        );
        if r.converged {
            converged = Some(frame);
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    assert!(converged.is_some(), "a still view converges");
    let image = target.read_rgba(&ctx).expect("readback");
    assert_eq!(empty(&image), 0, "the converged plane is closed");
}
