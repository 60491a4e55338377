//! Streamed tile content (`TilePool`): tiles in the suballocator drawn through the
//! continuous-LoD filter give, with the filter off, exactly the image of the same points drawn
//! as one static cloud; with it on, each tile keeps the points eq. 9 keeps, as computed on the
//! CPU; tiles removed and uploaded again reuse the pool's ranges without disturbing the others.

mod common;
use common::*;
use pointlet_core::shuffle::SplitMix64;
use pointlet_gpu::tile_pool::clod_random;
use pointlet_gpu::{
    PointEncoding, RasterVariant, RenderSettings, RenderTarget, Renderer, ScreenSettings,
    TileContent, TileDraw, TilePool,
};

/// Points `set` cut into tiles of 1–700 points, each with an origin of its own.
fn tiles_of(
    set: &pointlet_gpu::PointSet,
    seed: u64,
) -> Vec<(u64, [f64; 3], std::ops::Range<usize>)> {
    let mut rng = SplitMix64::new(seed);
    let mut out = Vec::new();
    let mut start = 0;
    while start < set.len() {
        let n = (1 + rng.below(700) as usize).min(set.len() - start);
        let origin = set.positions[start].map(|v| v + rng.unit_f64() - 0.5);
        out.push((out.len() as u64 + 100, origin, start..start + n));
        start += n;
    }
    out
}

fn draw(
    ctx: &pointlet_gpu::GpuContext,
    pool: &mut TilePool,
    draws: &[TileDraw],
    variant: RasterVariant,
) -> Vec<u8> {
    let settings = RenderSettings {
        variant,
        screen: ScreenSettings::default(),
        ..Default::default()
    };
    let mut target = RenderTarget::new(ctx, W, H).expect("target");
    let mut renderer = Renderer::new(ctx);
    let laid = pool.prepare(ctx, &camera(), (W, H), &settings, draws);
    assert_eq!(laid.skipped, 0, "every tile fits the output");
    renderer
        .render_tiles(ctx, pool, &camera(), &settings, &mut target)
        .expect("render tiles");
    target.read_rgba(ctx).expect("readback")
}

#[test]
fn tiles_drawn_whole_match_the_static_cloud_after_removals() {
    let ctx = context();
    let scene = layered_scene(7, false);
    let set = &scene.set;
    let tiles = tiles_of(set, 3);
    assert!(tiles.len() > 10, "{} tiles", tiles.len());
    let mut pool = TilePool::new(&ctx, set.len() as u64 * 2, 256, 1 << 20).expect("pool");
    // Junk tiles first, removed after the real ones are in: their ranges come back.
    let junk: Vec<[f64; 3]> = (0..5000).map(|i| [i as f64, 0.0, -1000.0]).collect();
    let junk_colors = vec![0xff00_00ffu32; junk.len()];
    for k in 0..4 {
        let content = TileContent {
            positions: &junk[k * 1000..(k + 1) * 1000 + 300],
            colors: &junk_colors[k * 1000..(k + 1) * 1000 + 300],
        };
        pool.upload(&ctx, k as u64, [0.0; 3], content)
            .expect("upload junk");
    }
    for (key, origin, range) in &tiles {
        let content = TileContent {
            positions: &set.positions[range.clone()],
            colors: &set.colors[range.clone()],
        };
        pool.upload(&ctx, *key, *origin, content).expect("upload");
    }
    for k in 0..4 {
        assert!(pool.remove(k), "junk tile {k} was there");
    }
    assert!(!pool.remove(1), "removed twice");
    // The first tile again, at another origin: replaced in place.
    let (key, _, range) = &tiles[0];
    let content = TileContent {
        positions: &set.positions[range.clone()],
        colors: &set.colors[range.clone()],
    };
    pool.upload(&ctx, *key, [5.0, -3.0, 2.0], content)
        .expect("upload again");
    assert_eq!(pool.len(), tiles.len());
    let stats = pool.content_stats();
    assert_eq!(
        stats.used,
        tiles
            .iter()
            .map(|t| TilePool::tile_bytes(t.2.len()))
            .sum::<u64>()
    );

    let draws: Vec<TileDraw> = tiles
        .iter()
        .map(|(key, _, _)| TileDraw {
            key: *key,
            clod: None,
            spacing: 0.0,
        })
        .collect();
    for variant in [
        RasterVariant::AtomicMin,
        RasterVariant::EarlyZ,
        RasterVariant::ReduceEarlyZ,
        RasterVariant::Dedup,
        RasterVariant::AtomicMin32,
    ] {
        let expected = render(
            &ctx,
            set,
            PointEncoding::Full16,
            variant,
            ScreenSettings::default(),
            &camera(),
        );
        let lit = expected.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(lit > 1000, "the scene covers most pixels: {lit}");
        let got = draw(&ctx, &mut pool, &draws, variant);
        let (max, n) = diff(&got, &expected);
        assert_eq!((max, n), (0, 0), "{}: {n} pixels differ", variant.name());
    }
    // Half the tiles drawn: only their points.
    let half: Vec<TileDraw> = draws.iter().step_by(2).copied().collect();
    let mut subset = pointlet_gpu::PointSet::default();
    for (_, _, range) in tiles.iter().step_by(2) {
        subset
            .positions
            .extend_from_slice(&set.positions[range.clone()]);
        subset.colors.extend_from_slice(&set.colors[range.clone()]);
    }
    let variant = RasterVariant::ReduceEarlyZ;
    let expected = render(
        &ctx,
        &subset,
        PointEncoding::Full16,
        variant,
        ScreenSettings::default(),
        &camera(),
    );
    assert_eq!(
        diff(&draw(&ctx, &mut pool, &half, variant), &expected),
        (0, 0)
    );
}

#[test]
fn the_clod_filter_keeps_the_points_eq_9_keeps() {
    let ctx = context();
    let cam = camera();
    let mut rng = SplitMix64::new(11);
    let mut pool = TilePool::new(&ctx, 1 << 18, 256, 1 << 20).expect("pool");
    // Three tiles of 20 000 points at growing distances from the eye.
    let mut tiles = Vec::new();
    for (k, depth) in [12.0, 30.0, 70.0].into_iter().enumerate() {
        let positions: Vec<[f64; 3]> = (0..20_000)
            .map(|_| {
                unproject(
                    &cam,
                    rng.unit_f64() * W as f64,
                    rng.unit_f64() * H as f64,
                    depth * (1.0 + 0.2 * rng.unit_f64()),
                )
            })
            .collect();
        let colors = vec![0xff80_8080u32; positions.len()];
        let origin = positions[0];
        pool.upload(
            &ctx,
            k as u64,
            origin,
            TileContent {
                positions: &positions,
                colors: &colors,
            },
        )
        .expect("upload");
        tiles.push((positions, origin));
    }
    let clod = 15.0;
    let draws: Vec<TileDraw> = (0..3)
        .map(|k| TileDraw {
            key: k,
            clod: Some(clod),
            spacing: 0.0,
        })
        .collect();
    draw(&ctx, &mut pool, &draws, RasterVariant::ReduceEarlyZ);
    let got = pool.read_survivors(&ctx).expect("survivors");
    assert_eq!(got.len(), 3);
    let mut shares = Vec::new();
    for (k, (positions, origin)) in tiles.iter().enumerate() {
        let rel_origin = [0, 1, 2].map(|a| (origin[a] - cam.eye[a]) as f32);
        let expected = positions
            .iter()
            .filter(|p| {
                let local = [0, 1, 2].map(|a| (p[a] - origin[a]) as f32);
                let rel = [0, 1, 2].map(|a| rel_origin[a] + local[a]);
                let d = (rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt();
                clod_random(local) * d < clod as f32
            })
            .count() as i64;
        let diff = (got[k] as i64 - expected).abs();
        // length() on the GPU may round differently: a point exactly at the edge may flip.
        assert!(
            diff <= 5,
            "tile {k}: {} survivors, the CPU keeps {expected}",
            got[k]
        );
        shares.push(got[k] as f64 / positions.len() as f64);
    }
    // Nearer tiles keep more: the share follows 1 / distance (clod / d, capped at 1).
    assert!(
        shares[0] > 0.9 && shares[1] < 0.6 && shares[2] < 0.25,
        "{shares:?}"
    );
    assert!(shares[0] > shares[1] && shares[1] > shares[2], "{shares:?}");

    // Filter off: every point survives.
    let all: Vec<TileDraw> = draws
        .iter()
        .map(|d| TileDraw { clod: None, ..*d })
        .collect();
    draw(&ctx, &mut pool, &all, RasterVariant::ReduceEarlyZ);
    assert_eq!(
        pool.read_survivors(&ctx).expect("survivors"),
        vec![20_000; 3]
    );
}

#[test]
fn a_full_output_leaves_the_last_tiles_out_and_says_so() {
    let ctx = context();
    let mut pool = TilePool::new(&ctx, 1024, 256, 1 << 20).expect("pool");
    assert_eq!(pool.capacity(), 1024);
    let positions: Vec<[f64; 3]> = (0..600).map(|i| [i as f64 * 0.01, 0.0, 0.0]).collect();
    let colors = vec![0xffff_ffffu32; 600];
    for k in 0..3 {
        pool.upload(
            &ctx,
            k,
            [0.0; 3],
            TileContent {
                positions: &positions,
                colors: &colors,
            },
        )
        .expect("upload");
    }
    let draws: Vec<TileDraw> = (0..4)
        .map(|k| TileDraw {
            key: k,
            clod: None,
            spacing: 0.0,
        })
        .collect();
    let laid = pool.prepare(&ctx, &camera(), (W, H), &RenderSettings::default(), &draws);

    assert_eq!((laid.tiles, laid.skipped, laid.points), (1, 3, 600));
    let too_big: Vec<[f64; 3]> = (0..2000).map(|i| [i as f64, 0.0, 0.0]).collect();
    let white = vec![0u32; 2000];
    let err = pool
        .upload(
            &ctx,
            9,
            [0.0; 3],
            TileContent {
                positions: &too_big,
                colors: &white,
            },
        )
        .expect_err("larger than the output");
    assert!(err.to_string().contains("2000 points"), "{err}");
}
