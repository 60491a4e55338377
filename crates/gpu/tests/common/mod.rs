//! Test scenes and helpers shared by the GPU tests. They run on whatever adapter exists
//! (lavapipe in CI); no adapter is a failure, never a skip.
#![allow(dead_code)]

use pointlet_core::shuffle::SplitMix64;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::{
    AdapterRequest, GpuCloud, GpuContext, PagedCloud, PointEncoding, PointSet, PointletDesc,
    RasterVariant, RenderSettings, RenderTarget, Renderer, ScreenSettings,
};

pub const W: u32 = 64;
pub const H: u32 = 48;

pub fn context() -> GpuContext {
    GpuContext::new(&AdapterRequest::default()).unwrap_or_else(|e| {
        panic!("GPU tests need a Vulkan adapter (CI installs mesa-vulkan-drivers): {e}")
    })
}

pub fn camera() -> Camera {
    Camera {
        eye: [-30.0, -20.0, 15.0],
        target: [0.0, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y_deg: 60.0,
        near: 0.5,
        far: 500.0,
    }
}

/// World position seen at pixel coordinates (u, v) (pixel centres at .5) at view depth `d`.
pub fn unproject(cam: &Camera, u: f64, v: f64, d: f64) -> [f64; 3] {
    let t = (cam.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = W as f64 / H as f64;
    let nx = u / W as f64 * 2.0 - 1.0;
    let ny = 1.0 - v / H as f64 * 2.0;
    let view = [nx * t * aspect * d, ny * t * d, -d];
    let [r, up, b] = cam.basis();
    [0, 1, 2].map(|i| cam.eye[i] + r[i] * view[0] + up[i] * view[1] + b[i] * view[2])
}

pub struct Scene {
    pub set: PointSet,
}

/// Points on rays through pixel centres (±0.3 px jitter, so no point sits near a pixel border)
/// at depths 5 % apart, random colours; with `ties`, exact duplicates with other colours;
/// plus points behind the camera and beside the frustum. Groups of duplicates are kept inside
/// one page: only there are they bit-identical on the GPU (positions are page-relative).
pub fn layered_scene(seed: u64, ties: bool) -> Scene {
    let cam = camera();
    let mut rng = SplitMix64::new(seed);
    let mut groups: Vec<Vec<([f64; 3], u32)>> = Vec::new();
    for y in 0..H {
        for x in 0..W {
            if rng.below(10) < 4 {
                continue;
            }
            let u = x as f64 + 0.5 + (rng.unit_f64() - 0.5) * 0.6;
            let v = y as f64 + 0.5 + (rng.unit_f64() - 0.5) * 0.6;
            let base = 20.0 + rng.unit_f64() * 40.0;
            let layers = 1 + rng.below(4);
            for k in 0..layers {
                let d = base * (1.0 + 0.05 * k as f64);
                let p = unproject(&cam, u, v, d);
                let mut group = vec![(p, (rng.next_u64() as u32) | 0xff00_0000)];
                if ties && rng.below(6) == 0 {
                    group.push((p, (rng.next_u64() as u32) | 0xff00_0000));
                }
                groups.push(group);
            }
        }
    }
    for _ in 0..500 {
        let u = rng.unit_f64() * W as f64;
        let v = rng.unit_f64() * H as f64;
        let behind = unproject(&cam, u, v, -5.0 - rng.unit_f64() * 20.0);
        groups.push(vec![(behind, 0xff00_ff00)]);
        groups.push(vec![(
            unproject(&cam, -3.0 * W as f64 + u, v, 30.0),
            0xff00_ff00,
        )]);
    }
    // Shuffle so pages mix pixels and depths (the result must not depend on order).
    pointlet_core::shuffle::shuffle(&mut groups, seed ^ 0xabc);
    Scene {
        set: in_pages(groups),
    }
}

/// The groups' points in order, each group inside one 256-point page (filler points behind
/// the camera before a group that would straddle a page border): only within a page are
/// duplicates bit-identical on the GPU (positions are page-relative).
fn in_pages(groups: Vec<Vec<([f64; 3], u32)>>) -> PointSet {
    let mut set = PointSet::default();
    let filler = unproject(&camera(), 1.0, 1.0, -1.0);
    for g in groups {
        while set.len() % 256 + g.len() > 256 {
            set.positions.push(filler);
            set.colors.push(0);
        }
        for (p, c) in g {
            set.positions.push(p);
            set.colors.push(c);
        }
    }
    set
}

pub fn render(
    ctx: &GpuContext,
    set: &PointSet,
    encoding: PointEncoding,
    variant: RasterVariant,
    screen: ScreenSettings,
    cam: &Camera,
) -> Vec<u8> {
    let settings = RenderSettings {
        variant,
        screen,
        ..Default::default()
    };
    render_with(ctx, set, encoding, &settings, cam)
}

pub fn render_with(
    ctx: &GpuContext,
    set: &PointSet,
    encoding: PointEncoding,
    settings: &RenderSettings,
    cam: &Camera,
) -> Vec<u8> {
    let mut cloud = GpuCloud::upload(ctx, set, encoding, 256).expect("upload");
    let mut target = RenderTarget::new(ctx, W, H).expect("target");
    let mut renderer = Renderer::new(ctx);
    renderer
        .render(ctx, &mut cloud, cam, settings, &mut target)
        .expect("render");
    target.read_rgba(ctx).expect("readback")
}

/// Points for splat tests: a jittered grid every `step` pixels, each point's projection at the
/// centre of a 1/256-pixel cell (the grid footprints are computed on, so f32 rounding on the
/// GPU cannot move a footprint), one to three layers 3 % apart in depth, with `ties`
/// duplicates of another colour; plus points half outside the image and behind the eye.
pub fn splat_scene(seed: u64, step: u32, ties: bool) -> PointSet {
    let cam = camera();
    let mut rng = SplitMix64::new(seed);
    let cell = |v: f64| ((v * 256.0).floor() + 0.5) / 256.0;
    let mut groups: Vec<Vec<([f64; 3], u32)>> = Vec::new();
    let margin = 2 * step as i64;
    for y in (-margin..H as i64 + margin).step_by(step as usize) {
        for x in (-margin..W as i64 + margin).step_by(step as usize) {
            let u = cell(x as f64 + rng.unit_f64() * step as f64);
            let v = cell(y as f64 + rng.unit_f64() * step as f64);
            let base = 20.0 + rng.unit_f64() * 30.0;
            for k in 0..1 + rng.below(3) {
                let p = unproject(&cam, u, v, base * (1.0 + 0.03 * k as f64));
                let mut group = vec![(p, (rng.next_u64() as u32) | 0xff00_0000)];
                if ties && rng.below(5) == 0 {
                    group.push((p, (rng.next_u64() as u32) | 0xff00_0000));
                }
                groups.push(group);
            }
        }
    }
    for _ in 0..200 {
        let (u, v) = (rng.unit_f64() * W as f64, rng.unit_f64() * H as f64);
        groups.push(vec![(unproject(&cam, u, v, -5.0), 0xff00_ff00)]);
    }
    pointlet_core::shuffle::shuffle(&mut groups, seed ^ 0x5eed);
    in_pages(groups)
}

/// Positions as the GPU sees them for `encoding` (compact points snap to their cells).
pub fn drawn_positions(
    ctx: &GpuContext,
    set: &PointSet,
    encoding: PointEncoding,
    cam: &Camera,
) -> Vec<[f64; 3]> {
    match encoding {
        PointEncoding::Full16 => set.positions.clone(),
        PointEncoding::Compact8 => {
            let cloud = GpuCloud::upload(ctx, set, encoding, 256).expect("upload");
            let focal = 0.5 * H as f64 / (cam.fov_y_deg.to_radians() * 0.5).tan();
            let mut out = Vec::with_capacity(set.len());
            for (k, page) in cloud.page_metas().iter().enumerate() {
                let step = page.step();
                let fine = page.needs_fine(cam.eye, focal);
                for p in &set.positions[k * 256..k * 256 + page.count as usize] {
                    let q = pointlet_gpu::quantize_compact(*p, page.origin, step);
                    out.push(pointlet_gpu::decode_compact(q, page.origin, step, fine));
                }
            }
            out
        }
    }
}

/// Largest per-channel difference and the number of differing pixels.
pub fn diff(a: &[u8], b: &[u8]) -> (u8, usize) {
    assert_eq!(a.len(), b.len());
    let mut max = 0;
    let mut n = 0;
    for (pa, pb) in a.chunks(4).zip(b.chunks(4)) {
        let d = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        max = max.max(d);
        n += (d > 0) as usize;
    }
    (max, n)
}

/// Cuts `set` into pointlets of `k` consecutive points.
pub fn pointlets(set: &PointSet, k: usize) -> Vec<PointletDesc> {
    set.positions
        .chunks(k)
        .map(|c| {
            let mut b = Aabb::EMPTY;
            c.iter().for_each(|p| b.grow(*p));
            PointletDesc {
                aabb: b,
                count: c.len() as u32,
            }
        })
        .collect()
}

/// Uploads every point of every pointlet into the pool (pages in order) and publishes it.
pub fn make_resident(ctx: &GpuContext, paged: &mut PagedCloud, set: &PointSet, k: usize) {
    let _ = ctx;
    let ps = paged.page_size as usize;
    let mut slot = 0u32;
    let descs = paged.pointlets().to_vec();
    let mut pages = Vec::new();
    let mut published = Vec::new();
    for (i, desc) in descs.iter().enumerate() {
        let start = i * k;
        let mut slots = Vec::new();
        for first in (0..desc.count as usize).step_by(ps) {
            let end = (first + ps).min(desc.count as usize);
            pages.push(pointlet_gpu::PageWrite {
                pointlet: i as u32,
                slot,
                first_point: first as u32,
                positions: &set.positions[start + first..start + end],
                colors: &set.colors[start + first..start + end],
            });
            slots.push(slot);
            slot += 1;
        }
        published.push((i as u32, desc.count, slots));
    }
    paged.write_pages(&pages);
    for (i, count, slots) in published {
        paged.set_residency(i, 0, count, &slots);
    }
}

/// Page slots for `set` cut into pointlets of `k` points, pages of `ps`.
pub fn slots_needed(set: &PointSet, k: usize, ps: usize) -> u32 {
    set.positions
        .chunks(k)
        .map(|c| c.len().div_ceil(ps) as u32)
        .sum()
}
