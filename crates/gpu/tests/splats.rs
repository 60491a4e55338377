//! Splats against the CPU reference: fixed-size squares and circles drawn by every
//! closest-point rasterizer must cover exactly the reference's pixels with exactly its colours;
//! blended splats (HQS, HQS1R) stay within ±1 per channel.

mod common;
use common::*;
use pointlet_gpu::reference;
use pointlet_gpu::{
    PointEncoding, PointSize, RasterVariant, RenderSettings, ScreenSettings, SplatRaster,
    SplatSettings, SplatShape,
};

const BLACK: [u8; 4] = [0, 0, 0, 255];

const CLOSEST: [RasterVariant; 6] = [
    RasterVariant::AtomicMin,
    RasterVariant::EarlyZ,
    RasterVariant::Reduce,
    RasterVariant::ReduceEarlyZ,
    RasterVariant::Dedup,
    RasterVariant::AtomicMin32,
];

fn settings(variant: RasterVariant, size: PointSize, shape: SplatShape) -> RenderSettings {
    RenderSettings {
        variant,
        splats: SplatSettings {
            size,
            shape,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn fixed_splats_match_the_reference_exactly() {
    let ctx = context();
    let cam = camera();
    let set = splat_scene(11, 4, true);
    for shape in SplatShape::ALL {
        for px in [2u32, 3, 6] {
            let splats = SplatSettings {
                size: PointSize::Fixed(px),
                shape,
                ..Default::default()
            };
            for encoding in PointEncoding::ALL {
                let drawn = drawn_positions(&ctx, &set, encoding, &cam);
                let closest =
                    reference::closest_splats(&drawn, &set.colors, 0.0, &cam, (W, H), &splats);
                let colors: Vec<Option<u32>> = closest.iter().map(|p| p.map(|(_, c)| c)).collect();
                let expected = reference::image(&colors, BLACK);
                let lit = expected.chunks(4).filter(|p| *p != BLACK).count();
                assert!(lit > 400, "splats cover much of the image: {lit}");
                for variant in CLOSEST {
                    let got = render_with(
                        &ctx,
                        &set,
                        encoding,
                        &settings(variant, splats.size, shape),
                        &cam,
                    );
                    assert_eq!(
                        diff(&got, &expected),
                        (0, 0),
                        "{} / {} / {px} px {}",
                        variant.name(),
                        encoding.name(),
                        shape.name()
                    );
                }
            }
        }
    }
}

#[test]
fn a_one_pixel_splat_is_the_one_pixel_point() {
    // The same closest points as the point path, so `--point-size 1` changes nothing.
    let ctx = context();
    let cam = camera();
    let set = splat_scene(12, 2, true);
    let one = reference::closest_splats(
        &set.positions,
        &set.colors,
        0.0,
        &cam,
        (W, H),
        &SplatSettings::default(),
    );
    let points = reference::closest_points(&set.positions, &set.colors, &cam, W, H);
    // The same depths and RGB (a splat's colour word carries its side in the alpha byte).
    let rgb = |px: &[Option<(f32, u32)>]| -> Vec<Option<(f32, u32)>> {
        px.iter()
            .map(|p| p.map(|(d, c)| (d, c & 0xff_ffff)))
            .collect()
    };
    assert!(rgb(&one) == rgb(&points), "one-pixel splats are the points");
    let got = render_with(
        &ctx,
        &set,
        PointEncoding::Full16,
        &RenderSettings::default(),
        &cam,
    );
    let colors: Vec<Option<u32>> = points.iter().map(|p| p.map(|(_, c)| c)).collect();
    assert_eq!(diff(&got, &reference::image(&colors, BLACK)), (0, 0));
}

/// A random `share` of a 0.4-unit grid on the square |x|, |y| ≤ 12 of the plane z = 0 (about
/// a point per pixel where the test camera sees it).
fn sampled_plane(share: f64, seed: u64) -> pointlet_gpu::PointSet {
    let mut rng = pointlet_core::shuffle::SplitMix64::new(seed);
    let mut set = pointlet_gpu::PointSet::default();
    for i in 0..=60 {
        for j in 0..=60 {
            if rng.unit_f64() < share {
                set.positions
                    .push([-12.0 + 0.4 * i as f64, -12.0 + 0.4 * j as f64, 0.0]);
                set.colors
                    .push(0xff00_0000 | (rng.next_u64() as u32 & 0x00ff_ffff));
            }
        }
    }
    set
}

/// Pixels whose centre ray meets the square at least `inset` units inside its border.
fn inside_plane(inset: f64) -> Vec<usize> {
    let cam = camera();
    let mut out = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let near = unproject(&cam, x as f64 + 0.5, y as f64 + 0.5, 1.0);
            let dir: Vec<f64> = (0..3).map(|a| near[a] - cam.eye[a]).collect();
            if dir[2] >= 0.0 {
                continue;
            }
            let t = -cam.eye[2] / dir[2];
            let hit = [cam.eye[0] + t * dir[0], cam.eye[1] + t * dir[1]];
            if hit.iter().all(|v| v.abs() <= 12.0 - inset) {
                out.push((y * W + x) as usize);
            }
        }
    }
    out
}

#[test]
fn adaptive_splats_close_a_randomly_thinned_surface() {
    let ctx = context();
    let cam = camera();
    let inside = inside_plane(0.5);
    assert!(
        inside.len() > 200,
        "the plane fills part of the view: {}",
        inside.len()
    );
    let empty = |img: &[u8]| {
        inside
            .iter()
            .filter(|i| img[*i * 4..*i * 4 + 4] == BLACK)
            .count()
    };
    // A tenth and a third of the grid: a LoD's random prefixes of its pointlets.
    for share in [0.1, 0.25] {
        let set = sampled_plane(share, 16);
        let one = render_with(
            &ctx,
            &set,
            PointEncoding::Full16,
            &RenderSettings::default(),
            &cam,
        );
        for variant in [
            RasterVariant::ReduceEarlyZ,
            RasterVariant::AtomicMin32,
            RasterVariant::Hqs,
        ] {
            let adaptive = RenderSettings {
                variant,
                splats: SplatSettings::adaptive(),
                ..Default::default()
            };
            let got = render_with(&ctx, &set, PointEncoding::Full16, &adaptive, &cam);
            assert!(
                empty(&one) > inside.len() / 20,
                "one-pixel points leave holes"
            );
            assert_eq!(
                empty(&got),
                0,
                "{}: adaptive splats of {share} of the grid leave no hole",
                variant.name()
            );
        }
    }
}

#[test]
fn blended_splats_match_the_reference() {
    let ctx = context();
    let cam = camera();
    let set = splat_scene(14, 3, false);
    for shape in SplatShape::ALL {
        let splats = SplatSettings {
            size: PointSize::Fixed(4),
            shape,
            ..Default::default()
        };
        let avg = reference::blended_splats(
            &set.positions,
            &set.colors,
            0.0,
            &cam,
            (W, H),
            &splats,
            1.01,
        );
        let expected = reference::image(&avg, BLACK);
        for variant in [RasterVariant::Hqs, RasterVariant::Hqs1r] {
            let got = render_with(
                &ctx,
                &set,
                PointEncoding::Full16,
                &RenderSettings {
                    variant,
                    screen: ScreenSettings::default(),
                    splats,
                    ..Default::default()
                },
                &cam,
            );
            let (max, n) = diff(&got, &expected);
            assert!(
                max <= 1,
                "{} {}: {n} pixels differ, max {max}",
                variant.name(),
                shape.name()
            );
        }
    }
}

#[test]
fn hw_points_refuse_larger_points() {
    let ctx = context();
    let set = splat_scene(15, 4, false);
    let mut cloud =
        pointlet_gpu::GpuCloud::upload(&ctx, &set, PointEncoding::Full16, 256).expect("upload");
    let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = pointlet_gpu::Renderer::new(&ctx);
    let err = renderer
        .render(
            &ctx,
            &mut cloud,
            &camera(),
            &settings(
                RasterVariant::HwPoints,
                PointSize::Fixed(3),
                SplatShape::Square,
            ),
            &mut target,
        )
        .expect_err("hw-points draws one-pixel points");
    assert!(err.to_string().contains("one-pixel"), "{err}");
}

#[test]
fn billboard_quads_draw_the_compute_splats() {
    let ctx = context();
    let cam = camera();
    // No exact duplicates: the depth test breaks ties by draw order, not colour.
    let set = splat_scene(17, 4, false);
    for shape in SplatShape::ALL {
        for size in [
            PointSize::Fixed(3),
            PointSize::Fixed(6),
            PointSize::adaptive(),
        ] {
            let compute = settings(RasterVariant::ReduceEarlyZ, size, shape);
            let quads = RenderSettings {
                splats: SplatSettings {
                    raster: SplatRaster::Quads,
                    ..compute.splats
                },
                ..compute
            };
            for encoding in PointEncoding::ALL {
                let want = render_with(&ctx, &set, encoding, &compute, &cam);
                let got = render_with(&ctx, &set, encoding, &quads, &cam);
                assert_eq!(
                    diff(&got, &want),
                    (0, 0),
                    "{} {} {}",
                    size.name(),
                    shape.name(),
                    encoding.name()
                );
            }
        }
    }
}

#[test]
fn billboard_quads_refuse_blending() {
    let ctx = context();
    let set = splat_scene(18, 4, false);
    let mut cloud =
        pointlet_gpu::GpuCloud::upload(&ctx, &set, PointEncoding::Full16, 256).expect("upload");
    let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = pointlet_gpu::Renderer::new(&ctx);
    let mut hqs = settings(RasterVariant::Hqs, PointSize::Fixed(3), SplatShape::Square);
    hqs.splats.raster = SplatRaster::Quads;
    let err = renderer
        .render(&ctx, &mut cloud, &camera(), &hqs, &mut target)
        .expect_err("quads keep the closest splat");
    assert!(err.to_string().contains("closest"), "{err}");
}

#[test]
fn adaptive_splats_and_their_gap_filling_match_the_reference() {
    let ctx = context();
    let cam = camera();
    // Sparse: splats of 2–4 pixels a point every 6, so the screen's gap filling has work.
    let set = splat_scene(19, 6, true);
    let spacing = 0.9f32;
    for shape in SplatShape::ALL {
        let splats = SplatSettings {
            size: PointSize::adaptive(),
            shape,
            ..Default::default()
        };
        for encoding in PointEncoding::ALL {
            let drawn = drawn_positions(&ctx, &set, encoding, &cam);
            let closest =
                reference::closest_splats(&drawn, &set.colors, spacing, &cam, (W, H), &splats);
            let filled = reference::fill_splat_gaps(&closest, (W, H), shape);
            let gaps = filled.iter().zip(&closest).filter(|(f, c)| f != c).count();
            assert!(gaps > 50, "gap filling fills pixels: {gaps}");
            let colors: Vec<Option<u32>> = filled.iter().map(|p| p.map(|(_, c)| c)).collect();
            let expected = reference::image(&colors, BLACK);
            let mut cloud =
                pointlet_gpu::GpuCloud::upload(&ctx, &set, encoding, 256).expect("upload");
            cloud.set_spacing(spacing as f64);
            for variant in CLOSEST {
                let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
                let settings = RenderSettings {
                    variant,
                    splats,
                    ..Default::default()
                };
                pointlet_gpu::Renderer::new(&ctx)
                    .render(&ctx, &mut cloud, &cam, &settings, &mut target)
                    .expect("render");
                let got = target.read_rgba(&ctx).expect("readback");
                assert_eq!(
                    diff(&got, &expected),
                    (0, 0),
                    "{} / {} / {}",
                    variant.name(),
                    encoding.name(),
                    shape.name()
                );
            }
        }
    }
}

#[test]
fn a_paged_cloud_draws_the_static_image_of_its_splats_up_to_the_border() {
    use pointlet_gpu::{GpuCloud, PagedCloud, PagedView, PointSet};
    let ctx = context();
    let cam = camera();
    // A ground plane from under the camera into the distance, cut into 4 × 4 pointlets (dyadic
    // coordinates, exact in f32): each draws with spacing √(3 · 3 / 16) = 0.75, so splats are
    // 1–3 pixels wide, and pointlets just beside the view reach into it. The same points as a
    // static cloud of that spacing (no culling; reference-tested above) give the image.
    let mut rng = pointlet_core::shuffle::SplitMix64::new(23);
    let mut set = PointSet {
        positions: Vec::new(),
        colors: Vec::new(),
    };
    for by in (-40..40).step_by(4) {
        for bx in (-40..40).step_by(4) {
            for k in 0..16 {
                let p = [
                    (bx + k % 4) as f64 + 0.3125,
                    (by + k / 4) as f64 + 0.1875,
                    0.0,
                ];
                set.positions.push(p);
                set.colors.push((rng.next_u64() as u32) | 0xff00_0000);
            }
        }
    }
    let descs = pointlets(&set, 16);
    let slots = slots_needed(&set, 16, 256);
    let view = PagedView {
        bucket: 1e12,
        accumulate: false,
    };
    for shape in SplatShape::ALL {
        let splats = SplatSettings {
            size: PointSize::adaptive(),
            shape,
            ..Default::default()
        };
        let mut cloud = GpuCloud::upload(&ctx, &set, PointEncoding::Full16, 256).expect("upload");
        cloud.set_spacing(0.75);
        for variant in CLOSEST {
            let settings = RenderSettings {
                variant,
                splats,
                ..Default::default()
            };
            let mut renderer = pointlet_gpu::Renderer::new(&ctx);
            let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
            renderer
                .render(&ctx, &mut cloud, &cam, &settings, &mut target)
                .expect("static render");
            let expected = target.read_rgba(&ctx).expect("readback");
            let mut paged = PagedCloud::new(&ctx, descs.clone(), PointEncoding::Full16, 256, slots)
                .expect("paged");
            make_resident(&ctx, &mut paged, &set, 16);
            renderer
                .render_paged(&ctx, &mut paged, &cam, &settings, &view, &mut target, None)
                .expect("paged render");
            let got = target.read_rgba(&ctx).expect("readback");
            assert_eq!(
                diff(&got, &expected),
                (0, 0),
                "{} / {}",
                variant.name(),
                shape.name()
            );
        }
    }
}
