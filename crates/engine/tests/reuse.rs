//! Temporal reuse in the virtualized path: while the camera moves, a frame starts from the last
//! one reprojected, so it shows more than the LoD image of its bucket; once the camera stops,
//! the image still converges to exactly the full-detail image of a scene without reuse.

mod common;
use common::context;

use pointlet_core::color::ColorMode;
use pointlet_core::Camera;
use pointlet_engine::{SceneConfig, VirtualScene};
use pointlet_gpu::{GpuContext, RasterVariant, RenderSettings, RenderTarget, Renderer};
use std::path::Path;

const W: u32 = 128;
const H: u32 = 96;

fn build_store(path: &Path, points: u64) {
    common::build_store(path, points, 3, 200);
}

fn settings(ctx: &GpuContext) -> RenderSettings {
    RenderSettings {
        variant: RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
        ..Default::default()
    }
}

fn lit(image: &[u8]) -> usize {
    image.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

struct View {
    scene: VirtualScene,
    target: RenderTarget,
    renderer: Renderer,
}

impl View {
    fn open(ctx: &GpuContext, path: &Path, temporal_reuse: bool) -> Self {
        let config = SceneConfig {
            bucket: 500.0,
            color: ColorMode::Elevation,
            temporal_reuse,
            ..Default::default()
        };
        Self {
            scene: VirtualScene::open(ctx, path, config, (W, H)).expect("open"),
            target: RenderTarget::new(ctx, W, H).expect("target"),
            renderer: Renderer::new(ctx),
        }
    }

    fn frame(&mut self, ctx: &GpuContext, camera: &Camera) -> bool {
        let r = self
            .scene
            .frame(
                ctx,
                &mut self.renderer,
                camera,
                &settings(ctx),
                &mut self.target,
            )
            .expect("frame");
        r.converged
    }

    fn converge(&mut self, ctx: &GpuContext, camera: &Camera) -> Vec<u8> {
        for _ in 0..5_000 {
            if self.frame(ctx, camera) {
                return self.target.read_rgba(ctx).expect("readback");
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        panic!("no convergence");
    }
}

#[test]
fn a_moving_camera_reuses_the_last_frame_and_a_still_one_still_converges_exactly() {
    let ctx = context();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("s.pointlet");
    build_store(&path, 150_000);
    let mut plain = View::open(&ctx, &path, false);
    let mut reusing = View::open(&ctx, &path, true);
    let bounds = plain.scene.bounds();
    let start = Camera::overview(&bounds, 60.0);
    let full = plain.converge(&ctx, &start);
    reusing.converge(&ctx, &start);
    assert!(lit(&full) > 1000);
    // Small steps sideways: each moving frame draws the bucket's LoD, the reusing one also
    // the last frame's surface (a pixel is carried through at most 4 reprojections).
    let step = bounds.diagonal() * 0.002;
    let mut camera = start;
    let (mut lit_plain, mut lit_reusing) = (0, 0);
    for _ in 0..4 {
        camera.eye[0] += step;
        camera.target[0] += step;
        plain.frame(&ctx, &camera);
        reusing.frame(&ctx, &camera);
        lit_plain = lit(&plain.target.read_rgba(&ctx).expect("readback"));
        lit_reusing = lit(&reusing.target.read_rgba(&ctx).expect("readback"));
    }
    assert!(
        lit_reusing > lit_plain * 3 / 2,
        "moving with reuse lights {lit_reusing} pixels, without {lit_plain}"
    );
    // Still again: both reach the same full-detail image.
    let want = plain.converge(&ctx, &camera);
    let got = reusing.converge(&ctx, &camera);
    assert!(lit(&want) > 1000);
    assert!(
        got == want,
        "the still image after reuse differs from full detail"
    );
    // Switched off right after a reusing frame, the still view still refines from clean.
    camera.eye[1] += step;
    camera.target[1] += step;
    reusing.frame(&ctx, &camera);
    reusing.scene.set_temporal_reuse(false);
    let want = plain.converge(&ctx, &camera);
    let got = reusing.converge(&ctx, &camera);
    assert!(
        got == want,
        "switching reuse off left reprojected pixels behind"
    );
}
