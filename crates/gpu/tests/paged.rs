//! The virtualized path on the GPU: LoD against the CPU reference, drawing from page slots, and
//! accumulation converging to the full-detail image.

mod common;
use common::*;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::reference;
use pointlet_gpu::{
    GpuContext, PagedCloud, PagedView, PointEncoding, PointSet, PointletDesc, RasterVariant,
    RenderSettings, RenderTarget, Renderer, ScreenSettings,
};

fn frame(
    ctx: &GpuContext,
    renderer: &mut Renderer,
    paged: &mut PagedCloud,
    target: &mut RenderTarget,
    variant: RasterVariant,
    view: PagedView,
    cam: &Camera,
) -> Vec<u8> {
    renderer
        .render_paged(
            ctx,
            paged,
            cam,
            &RenderSettings {
                variant,
                screen: ScreenSettings::default(),
                ..Default::default()
            },
            &view,
            target,
            None,
        )
        .expect("frame");
    target.read_rgba(ctx).expect("readback")
}

#[test]
fn gpu_lod_matches_the_cpu_reference() {
    let ctx = context();
    // Hilbert order makes pointlets compact, so those behind the camera can be culled.
    let raw = layered_scene(5, false).set;
    let perm =
        pointlet_core::order::VertexOrder::Hilbert.permutation(&raw.positions, &raw.bounds(), 0);
    let set = PointSet {
        positions: pointlet_core::order::apply(&raw.positions, &perm),
        colors: pointlet_core::order::apply(&raw.colors, &perm),
    };
    let k = 300;
    let mut descs = pointlets(&set, k);
    // Two more boxes, behind the eye and far beside the view: both must be culled.
    let cam = camera();
    for p in [
        unproject(&cam, 32.0, 24.0, -40.0),
        unproject(&cam, -400.0, 24.0, 40.0),
    ] {
        descs.push(PointletDesc {
            aabb: Aabb {
                min: p.map(|v| v - 1.0),
                max: p.map(|v| v + 1.0),
            },
            count: 500,
        });
    }
    let mut paged =
        PagedCloud::new(&ctx, descs.clone(), PointEncoding::Full16, 256, 64).expect("paged");
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = Renderer::new(&ctx);
    for bucket in [1.0, 1_000.0, 20_000.0, 1e9] {
        frame(
            &ctx,
            &mut renderer,
            &mut paged,
            &mut target,
            RasterVariant::EarlyZ,
            PagedView {
                bucket,
                accumulate: false,
            },
            &cam,
        );
        let gpu = paged.wait_feedback(&ctx).expect("feedback").requested;
        let boxes: Vec<Aabb> = descs.iter().map(|d| d.aabb).collect();
        let counts: Vec<u32> = descs.iter().map(|d| d.count).collect();
        let cpu = pointlet_core::lod::requested_points(
            &cam.view_projection(W as f64 / H as f64),
            [W as f64, H as f64],
            &boxes,
            &counts,
            bucket as u64,
        );
        assert_eq!(gpu.len(), cpu.len());
        for (i, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            assert!(
                g.abs_diff(*c) <= 1 + c / 1000,
                "bucket {bucket}, pointlet {i}: GPU {g} vs CPU {c}"
            );
        }
        let total: u64 = gpu.iter().map(|v| *v as u64).sum();
        let all: u64 = counts.iter().map(|v| *v as u64).sum();
        assert!(
            total <= (bucket as u64).min(all) + descs.len() as u64,
            "{total}"
        );
        assert_eq!(&gpu[gpu.len() - 2..], &[0, 0], "culled boxes get nothing");
        assert_eq!(&cpu[cpu.len() - 2..], &[0, 0]);
        // However small the bucket, every pointlet in view shows a point.
        let cam_vp = cam.view_projection(W as f64 / H as f64);
        for (i, (d, g)) in descs.iter().zip(&gpu).enumerate() {
            let visible = !pointlet_core::lod::outside_frustum(&cam_vp, &d.aabb);
            assert_eq!(
                *g > 0,
                visible,
                "bucket {bucket}, pointlet {i}: {g} requested"
            );
        }
    }
}

#[test]
fn a_single_pointlet_gets_its_feedback() {
    let ctx = context();
    // One pointlet's feedback (2 words) is smaller than a GPU buffer's minimum size.
    let set = layered_scene(5, false).set;
    let k = 100;
    let descs = pointlets(&set, k)[..1].to_vec();
    let mut paged = PagedCloud::new(&ctx, descs, PointEncoding::Full16, 256, 1).expect("paged");
    make_resident(&ctx, &mut paged, &set, k);
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = Renderer::new(&ctx);
    let view = PagedView {
        bucket: 1e9,
        accumulate: false,
    };
    let cam = Camera::overview(&paged.pointlets()[0].aabb, 60.0);
    frame(
        &ctx,
        &mut renderer,
        &mut paged,
        &mut target,
        RasterVariant::EarlyZ,
        view,
        &cam,
    );
    let fb = paged
        .wait_feedback(&ctx)
        .expect("the feedback of one pointlet");
    assert_eq!((fb.requested, fb.drawn), (vec![100], vec![100]));
}

#[test]
fn fully_resident_paged_cloud_draws_the_reference_image() {
    let ctx = context();
    let scene = layered_scene(6, true);
    let k = 1000;
    for encoding in PointEncoding::ALL {
        let descs = pointlets(&scene.set, k);
        let slots = slots_needed(&scene.set, k, 256);
        let mut paged = PagedCloud::new(&ctx, descs, encoding, 256, slots).expect("paged");
        make_resident(&ctx, &mut paged, &scene.set, k);
        let mut target = RenderTarget::new(&ctx, W, H).expect("target");
        let mut renderer = Renderer::new(&ctx);
        let got = frame(
            &ctx,
            &mut renderer,
            &mut paged,
            &mut target,
            RasterVariant::ReduceEarlyZ,
            PagedView {
                bucket: 1e12,
                accumulate: false,
            },
            &camera(),
        );
        let px =
            reference::closest_points(&scene.set.positions, &scene.set.colors, &camera(), W, H);
        if encoding == PointEncoding::Full16 {
            let expected = reference::image(
                &px.iter().map(|p| p.map(|(_, c)| c)).collect::<Vec<_>>(),
                [0, 0, 0, 255],
            );
            assert_eq!(diff(&got, &expected), (0, 0), "{}", encoding.name());
        } else {
            // Compact positions snap to cells: the same pixels are covered.
            let covered = |img: &[u8]| img.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
            let expected = px.iter().filter(|p| p.is_some()).count();
            assert!(
                covered(&got).abs_diff(expected) < expected / 50,
                "{}",
                encoding.name()
            );
        }
    }
}

#[test]
fn accumulation_converges_to_the_full_detail_image() {
    let ctx = context();
    let scene = layered_scene(7, true);
    let k = 700;
    let descs = pointlets(&scene.set, k);
    let slots = slots_needed(&scene.set, k, 256);
    let mut paged = PagedCloud::new(&ctx, descs, PointEncoding::Full16, 256, slots).expect("paged");
    make_resident(&ctx, &mut paged, &scene.set, k);
    let mut target = RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = Renderer::new(&ctx);
    let cam = camera();
    let full = frame(
        &ctx,
        &mut renderer,
        &mut paged,
        &mut target,
        RasterVariant::EarlyZ,
        PagedView {
            bucket: 1e12,
            accumulate: false,
        },
        &cam,
    );
    // A small bucket misses points; growing it over still frames fills the image in.
    let first = frame(
        &ctx,
        &mut renderer,
        &mut paged,
        &mut target,
        RasterVariant::EarlyZ,
        PagedView {
            bucket: 500.0,
            accumulate: false,
        },
        &cam,
    );
    assert!(
        diff(&first, &full).1 > 100,
        "a small bucket draws fewer points"
    );
    let mut bucket = 500.0;
    let mut last = first;
    for _ in 0..20 {
        bucket *= 2.0;
        last = frame(
            &ctx,
            &mut renderer,
            &mut paged,
            &mut target,
            RasterVariant::EarlyZ,
            PagedView {
                bucket,
                accumulate: true,
            },
            &cam,
        );
    }
    assert_eq!(diff(&last, &full), (0, 0));
}
