//! Golden tests: GPU images against the CPU reference rasterizer.

mod common;
use common::*;
use pointlet_gpu::reference;
use pointlet_gpu::{PointEncoding, PointSet, RasterVariant, ScreenSettings};

const BLACK: [u8; 4] = [0, 0, 0, 255];

fn closest_reference(positions: &[[f64; 3]], colors: &[u32]) -> Vec<u8> {
    let px = reference::closest_points(positions, colors, &camera(), W, H);
    let colors: Vec<Option<u32>> = px.iter().map(|p| p.map(|(_, c)| c)).collect();
    reference::image(&colors, BLACK)
}

#[test]
fn closest_point_variants_match_the_reference_exactly() {
    let ctx = context();
    let scene = layered_scene(1, true);
    for encoding in PointEncoding::ALL {
        let drawn = drawn_positions(&ctx, &scene.set, encoding, &camera());
        let expected = closest_reference(&drawn, &scene.set.colors);
        let filled = expected.chunks(4).filter(|p| *p != BLACK).count();
        assert!(filled > 1000, "the scene covers most pixels: {filled}");
        for variant in [
            RasterVariant::AtomicMin,
            RasterVariant::EarlyZ,
            RasterVariant::Reduce,
            RasterVariant::ReduceEarlyZ,
            RasterVariant::Dedup,
            RasterVariant::AtomicMin32,
        ] {
            let got = render(
                &ctx,
                &scene.set,
                encoding,
                variant,
                ScreenSettings::default(),
                &camera(),
            );
            let (max, n) = diff(&got, &expected);
            assert_eq!(
                (max, n),
                (0, 0),
                "{} / {}: {n} pixels differ (max {max})",
                variant.name(),
                encoding.name()
            );
        }
    }
}

#[test]
fn hardware_points_draw_the_same_closest_points() {
    let ctx = context();
    // No exact duplicates: the hardware depth test breaks ties by draw order, not colour.
    let scene = layered_scene(2, false);
    let expected = closest_reference(&scene.set.positions, &scene.set.colors);
    let got = render(
        &ctx,
        &scene.set,
        PointEncoding::Full16,
        RasterVariant::HwPoints,
        ScreenSettings::default(),
        &camera(),
    );
    assert_eq!(diff(&got, &expected), (0, 0));
}

/// Clusters inside single pixels: three points within 0.4 % of the closest depth blend, one
/// 5 % behind does not; `crowd` pixels get `crowd` points to exercise HQS1R's overflow path.
fn blend_scene(crowd: usize) -> PointSet {
    let cam = camera();
    let mut rng = pointlet_core::shuffle::SplitMix64::new(7);
    let mut set = PointSet::default();
    for y in (0..H).step_by(2) {
        for x in (0..W).step_by(2) {
            let d = 25.0 + rng.unit_f64() * 30.0;
            let n = if (x + y) % 10 == 0 { crowd } else { 3 };
            for k in 0..n {
                let u = x as f64 + 0.5 + (rng.unit_f64() - 0.5) * 0.5;
                let v = y as f64 + 0.5 + (rng.unit_f64() - 0.5) * 0.5;
                let depth = d * (1.0 + 0.002 * (k % 3) as f64);
                set.positions.push(unproject(&cam, u, v, depth));
                set.colors.push(rng.next_u64() as u32 | 0xff00_0000);
            }
            set.positions
                .push(unproject(&cam, x as f64 + 0.5, y as f64 + 0.5, d * 1.05));
            set.colors.push(0xff00_00ff);
        }
    }
    set
}

#[test]
fn hqs_variants_match_the_blending_reference() {
    let ctx = context();
    for crowd in [3, 300, 1000] {
        let set = blend_scene(crowd);
        let avg = reference::blended(&set.positions, &set.colors, &camera(), W, H, 1.01);
        let expected = reference::image(&avg, BLACK);
        for variant in [RasterVariant::Hqs, RasterVariant::Hqs1r] {
            let got = render(
                &ctx,
                &set,
                PointEncoding::Full16,
                variant,
                ScreenSettings::default(),
                &camera(),
            );
            let (max, n) = diff(&got, &expected);
            assert!(
                max <= 1,
                "{} with {crowd} points per crowded pixel: {n} pixels differ, max {max}",
                variant.name()
            );
        }
    }
}

#[test]
fn hole_filling_takes_the_mean_of_non_empty_neighbours() {
    let ctx = context();
    let scene = layered_scene(3, false);
    let radius = 1u32;
    let px = reference::closest_points(&scene.set.positions, &scene.set.colors, &camera(), W, H);
    let colors: Vec<Option<u32>> = px.iter().map(|p| p.map(|(_, c)| c)).collect();
    let mut filled = colors.clone();
    for y in 0..H as i64 {
        for x in 0..W as i64 {
            if colors[(y * W as i64 + x) as usize].is_some() {
                continue;
            }
            let mut sum = [0u32; 3];
            let mut n = 0;
            for dy in -(radius as i64)..=radius as i64 {
                for dx in -(radius as i64)..=radius as i64 {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= W as i64 || qy >= H as i64 {
                        continue;
                    }
                    if let Some(c) = colors[(qy * W as i64 + qx) as usize] {
                        for (k, s) in sum.iter_mut().enumerate() {
                            *s += (c >> (8 * k)) & 0xff;
                        }
                        n += 1;
                    }
                }
            }
            if n > 0 {
                let mean = |k: usize| (sum[k] as f32 / n as f32).round() as u32;
                filled[(y * W as i64 + x) as usize] = Some(mean(0) | mean(1) << 8 | mean(2) << 16);
            }
        }
    }
    let expected = reference::image(&filled, BLACK);
    let got = render(
        &ctx,
        &scene.set,
        PointEncoding::Full16,
        RasterVariant::EarlyZ,
        ScreenSettings {
            fill_radius: radius,
            ..Default::default()
        },
        &camera(),
    );
    let (max, n) = diff(&got, &expected);
    assert!(max <= 1, "{n} pixels differ, max {max}");
    let before = colors.iter().filter(|c| c.is_none()).count();
    let after = filled.iter().filter(|c| c.is_none()).count();
    assert!(
        after < before / 2,
        "filling closes most holes: {before} → {after}"
    );
}

#[test]
fn eye_dome_lighting_darkens_only_behind_depth_edges() {
    let ctx = context();
    let cam = camera();
    // A far wall of one colour with a near square in front of its centre.
    let mut set = PointSet::default();
    for y in 0..H {
        for x in 0..W {
            let near = (20..44).contains(&x) && (14..34).contains(&y);
            let d = if near { 20.0 } else { 40.0 };
            set.positions
                .push(unproject(&cam, x as f64 + 0.5, y as f64 + 0.5, d));
            set.colors.push(0xff80_8080);
        }
    }
    let plain = render(
        &ctx,
        &set,
        PointEncoding::Full16,
        RasterVariant::EarlyZ,
        ScreenSettings::default(),
        &cam,
    );
    let edl = render(
        &ctx,
        &set,
        PointEncoding::Full16,
        RasterVariant::EarlyZ,
        ScreenSettings {
            edl: Some(pointlet_gpu::EdlSettings {
                strength: 1.0,
                radius: 1.0,
            }),
            ..Default::default()
        },
        &cam,
    );
    let at = |img: &[u8], x: u32, y: u32| img[((y * W + x) * 4) as usize];
    // Far pixels next to the near square are darkened; flat areas and the square are not.
    assert!(
        at(&edl, 19, 24) < at(&plain, 19, 24) / 2,
        "edge behind the square"
    );
    assert_eq!(at(&edl, 5, 5), at(&plain, 5, 5), "flat far wall");
    assert_eq!(at(&edl, 30, 24), at(&plain, 30, 24), "flat near square");
    assert_eq!(
        at(&edl, 20, 24),
        at(&plain, 20, 24),
        "the near side of the edge"
    );
}

#[test]
fn without_64_bit_atomics_the_two_pass_path_draws_the_same_image() {
    let ctx = pointlet_gpu::GpuContext::new(&pointlet_gpu::AdapterRequest {
        webgpu_baseline: true,
        ..Default::default()
    })
    .expect("adapter");
    assert!(!ctx.caps.int64_atomics && !ctx.caps.subgroups);
    for v in [
        RasterVariant::AtomicMin,
        RasterVariant::Dedup,
        RasterVariant::Hqs1r,
    ] {
        assert!(v.unsupported_reason(&ctx.caps).is_some(), "{}", v.name());
    }
    assert_eq!(
        RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
        RasterVariant::AtomicMin32
    );
    assert_eq!(RasterVariant::Hqs1r.fallback(&ctx.caps), RasterVariant::Hqs);
    let scene = layered_scene(4, true);
    let expected = closest_reference(&scene.set.positions, &scene.set.colors);
    let got = render(
        &ctx,
        &scene.set,
        PointEncoding::Full16,
        RasterVariant::AtomicMin32,
        ScreenSettings::default(),
        &camera(),
    );
    assert_eq!(diff(&got, &expected), (0, 0));
}

#[test]
fn hidden_classes_are_not_drawn() {
    let ctx = context();
    let mut scene = layered_scene(8, false);
    // Classes 2 and 6 (ground, building) in the alpha byte of every other point.
    for (k, c) in scene.set.colors.iter_mut().enumerate() {
        *c = (*c & 0x00ff_ffff) | if k % 2 == 0 { 2 << 24 } else { 6 << 24 };
    }
    let kept: Vec<usize> = (0..scene.set.len()).filter(|k| k % 2 == 0).collect();
    let positions: Vec<[f64; 3]> = kept.iter().map(|k| scene.set.positions[*k]).collect();
    let colors: Vec<u32> = kept.iter().map(|k| scene.set.colors[*k]).collect();
    let expected = closest_reference(&positions, &colors);
    // One pass, and the depth pass then colour pass of the 32-bit fallback.
    for variant in [RasterVariant::EarlyZ, RasterVariant::AtomicMin32] {
        let mut settings = pointlet_gpu::RenderSettings {
            variant,
            ..Default::default()
        };
        settings.set_class_hidden(6, true);
        assert!(settings.class_hidden(6) && !settings.class_hidden(2));
        let mut cloud =
            pointlet_gpu::GpuCloud::upload(&ctx, &scene.set, PointEncoding::Full16, 256)
                .expect("upload");
        let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
        let mut renderer = pointlet_gpu::Renderer::new(&ctx);
        renderer
            .render(&ctx, &mut cloud, &camera(), &settings, &mut target)
            .expect("render");
        let got = target.read_rgba(&ctx).expect("readback");
        assert_eq!(diff(&got, &expected), (0, 0), "{variant:?}");
    }
}

#[test]
fn picking_returns_the_closest_point_under_the_cursor() {
    let ctx = context();
    let scene = layered_scene(9, false);
    let cam = camera();
    let px = reference::closest_points(&scene.set.positions, &scene.set.colors, &cam, W, H);
    let mut cloud = pointlet_gpu::GpuCloud::upload(&ctx, &scene.set, PointEncoding::Compact8, 256)
        .expect("upload");
    let mut target = pointlet_gpu::RenderTarget::new(&ctx, W, H).expect("target");
    let mut renderer = pointlet_gpu::Renderer::new(&ctx);
    let settings = pointlet_gpu::RenderSettings::default();
    let mut checked = 0;
    for k in (0..W * H).step_by(97) {
        let (x, y) = (k % W, k / W);
        let hit = renderer
            .pick(&ctx, &mut cloud, &cam, &settings, &mut target, [x, y], 0)
            .expect("pick");
        let i = (y * W + x) as usize;
        match (hit, px[i]) {
            (Some(h), Some((depth, _))) => {
                let p = scene.set.positions[h.id as usize];
                let (j, d) = reference::project(&cam, W, H, p).expect("visible");
                assert_eq!(j, i, "the picked point lies under the cursor");
                assert!(
                    (d - depth).abs() <= depth * 1e-3,
                    "and is the closest: {d} vs {depth}"
                );
                checked += 1;
            }
            (None, None) => {}
            (h, r) => panic!("pixel ({x},{y}): GPU {h:?}, reference {r:?}"),
        }
    }
    assert!(checked >= 10, "{checked}");
    // With a radius, an empty pixel next to points still finds one.
    let empty = (0..W * H)
        .find(|i| px[*i as usize].is_none())
        .expect("an empty pixel");
    let hit = renderer
        .pick(
            &ctx,
            &mut cloud,
            &cam,
            &settings,
            &mut target,
            [empty % W, empty / W],
            3,
        )
        .expect("pick");
    assert!(hit.is_some_and(|h| h.pixel != [empty % W, empty / W]));
}

#[test]
fn occlusion_filter_drops_points_seen_through_a_nearer_surface() {
    let ctx = context();
    let cam = camera();
    // A near wall (depth 20) with holes every 4th pixel, a far wall (depth 40) behind it, and a
    // free region on the right where only the far wall shows.
    let mut set = PointSet::default();
    let mut through_hole = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            set.positions.push(unproject(&cam, u, v, 40.0));
            set.colors.push(0xff00_00ff);
            let hole = x % 4 == 1 && y % 4 == 1;
            if x < 40 && !hole {
                set.positions.push(unproject(&cam, u, v, 20.0));
                set.colors.push(0xff00_ff00);
            } else if x < 36 && x > 4 && y > 4 && y < H - 4 {
                through_hole.push((x, y));
            }
        }
    }
    let screen = ScreenSettings {
        occlusion: Some(pointlet_gpu::OcclusionSettings::default()),
        ..Default::default()
    };
    let img = render(
        &ctx,
        &set,
        PointEncoding::Full16,
        RasterVariant::EarlyZ,
        screen,
        &cam,
    );
    let at = |x: u32, y: u32| &img[((y * W + x) * 4) as usize..((y * W + x) * 4 + 3) as usize];
    assert!(!through_hole.is_empty());
    for (x, y) in &through_hole {
        assert_eq!(
            at(*x, *y),
            [0, 0, 0],
            "far point seen through the hole at ({x},{y}) dropped"
        );
    }
    assert_eq!(at(50, 20), [255, 0, 0], "the far wall in the open stays");
    assert_eq!(
        at(41, 20),
        [255, 0, 0],
        "the background just beside the silhouette stays"
    );
    assert_eq!(at(10, 10), [0, 255, 0], "the near wall stays");
    // With hole filling after it, the holes take the near wall's colour.
    let filled = render(
        &ctx,
        &set,
        PointEncoding::Full16,
        RasterVariant::EarlyZ,
        ScreenSettings {
            fill_radius: 1,
            ..screen
        },
        &cam,
    );
    let (x, y) = through_hole[0];
    let p = ((y * W + x) * 4) as usize;
    assert_eq!(&filled[p..p + 3], [0, 255, 0]);
}
