//! CPU reference rasterizers for golden tests: the same projection, pixel and tie rules as the
//! shaders, computed in f64 from absolute coordinates. Exact for closest-point variants wherever
//! a point is not within rounding distance of a pixel border or of another point's depth (for
//! splats: of a 1/256-pixel border, the grid their footprints are computed on).

use crate::splat::{SplatSettings, SplatShape};
use pointlet_core::lod::transform;
use pointlet_core::Camera;

/// Pixel index and view depth (f32, as the GPU stores it) of `p`, if inside the frustum.
pub fn project(camera: &Camera, width: u32, height: u32, p: [f64; 3]) -> Option<(usize, f32)> {
    let vp = camera.view_projection(width as f64 / height as f64);
    project_with(&vp, width, height, p)
}

fn project_with(
    vp: &pointlet_core::lod::Mat4,
    width: u32,
    height: u32,
    p: [f64; 3],
) -> Option<(usize, f32)> {
    let c = transform(vp, p);
    let inside =
        c[3] > 0.0 && c[0].abs() <= c[3] && c[1].abs() <= c[3] && c[2] >= 0.0 && c[2] <= c[3];
    if !inside {
        return None;
    }
    let fx = (c[0] / c[3] * 0.5 + 0.5) * width as f64;
    let fy = (0.5 - c[1] / c[3] * 0.5) * height as f64;
    let x = (fx.max(0.0) as u32).min(width - 1);
    let y = (fy.max(0.0) as u32).min(height - 1);
    Some(((y * width + x) as usize, c[3] as f32))
}

/// Closest point per pixel: (depth, RGBA); on equal depth the smaller RGBA value wins.
pub fn closest_points(
    positions: &[[f64; 3]],
    colors: &[u32],
    camera: &Camera,
    width: u32,
    height: u32,
) -> Vec<Option<(f32, u32)>> {
    let vp = camera.view_projection(width as f64 / height as f64);
    let mut px: Vec<Option<(f32, u32)>> = vec![None; (width * height) as usize];
    for (p, c) in positions.iter().zip(colors) {
        if let Some((i, d)) = project_with(&vp, width, height, *p) {
            let better = match px[i] {
                None => true,
                Some((bd, bc)) => d < bd || (d == bd && *c < bc),
            };
            if better {
                px[i] = Some((d, *c));
            }
        }
    }
    px
}

/// HQS: the integer average colour of the points within `blend` × the closest depth.
pub fn blended(
    positions: &[[f64; 3]],
    colors: &[u32],
    camera: &Camera,
    width: u32,
    height: u32,
    blend: f32,
) -> Vec<Option<u32>> {
    let vp = camera.view_projection(width as f64 / height as f64);
    let hits: Vec<Option<(usize, f32)>> = positions
        .iter()
        .map(|p| project_with(&vp, width, height, *p))
        .collect();
    let mut closest = vec![f32::INFINITY; (width * height) as usize];
    for (i, d) in hits.iter().flatten() {
        closest[*i] = closest[*i].min(*d);
    }
    let mut sums = vec![[0u64; 4]; closest.len()];
    for (h, c) in hits.iter().zip(colors) {
        if let Some((i, d)) = h {
            if *d <= closest[*i] * blend {
                add_color(&mut sums[*i], *c);
            }
        }
    }
    averages(&sums)
}

/// Adds an RGBA colour to r, g, b sums and a count, as HQS's accumulation does.
fn add_color(sums: &mut [u64; 4], color: u32) {
    for (k, v) in sums.iter_mut().take(3).enumerate() {
        *v += ((color >> (8 * k)) & 0xff) as u64;
    }
    sums[3] += 1;
}

/// The integer average colour of each pixel's sums (None where nothing added), as HQS's
/// resolve divides.
fn averages(sums: &[[u64; 4]]) -> Vec<Option<u32>> {
    sums.iter()
        .map(|s| {
            (s[3] > 0).then(|| {
                let avg = |k: usize| (s[k] / s[3]) as u32;
                avg(0) | avg(1) << 8 | avg(2) << 16
            })
        })
        .collect()
}

/// RGBA8 image of per-pixel colours (alpha forced opaque), `background` where empty.
pub fn image(pixels: &[Option<u32>], background: [u8; 4]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| match p {
            Some(c) => {
                let b = c.to_le_bytes();
                [b[0], b[1], b[2], 255]
            }
            None => background,
        })
        .collect()
}

/// A splat as the shaders place it (common.wgsl `project_splat`): centre in 1/256 pixel, view
/// depth, footprint and ring sides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatRef {
    pub q: [i64; 2],
    pub depth: f32,
    pub side: u32,
    pub ring: u32,
}

/// Where `p`'s splat lands, if anywhere near the image; `spacing` sizes adaptive splats.
pub fn project_splat(
    camera: &Camera,
    width: u32,
    height: u32,
    p: [f64; 3],
    spacing: f32,
    splats: &SplatSettings,
) -> Option<SplatRef> {
    let vp = camera.view_projection(width as f64 / height as f64);
    let [fixed, scale, max, ring_ratio] = splats.uniform(camera.focal_px(height), false);
    splat_with(
        &vp,
        width,
        height,
        p,
        spacing,
        [fixed, scale, max, ring_ratio],
    )
}

fn splat_with(
    vp: &pointlet_core::lod::Mat4,
    width: u32,
    height: u32,
    p: [f64; 3],
    spacing: f32,
    [fixed, scale, max, ring_ratio]: [f32; 4],
) -> Option<SplatRef> {
    let c = transform(vp, p);
    if !(c[3] > 0.0 && c[2] >= 0.0 && c[2] <= c[3]) {
        return None;
    }
    let w = c[3] as f32;
    let size = if scale > 0.0 {
        scale * spacing / w
    } else {
        fixed
    };
    // WGSL's round() takes ties to even.
    let side_of = |s: f32| s.round_ties_even().clamp(1.0, max) as u32;
    let side = side_of(size);
    let ring = side_of(size * ring_ratio).max(side);
    let fx = (c[0] / c[3] * 0.5 + 0.5) * width as f64;
    let fy = (0.5 - c[1] / c[3] * 0.5) * height as f64;
    let m = ring as f64;
    if !(fx >= -m && fy >= -m && fx <= width as f64 + m && fy <= height as f64 + m) {
        return None;
    }
    Some(SplatRef {
        q: [(fx * 256.0).floor() as i64, (fy * 256.0).floor() as i64],
        depth: w,
        side,
        ring,
    })
}

/// The pixels a splat covers (row-major index) and whether each is in its gap-filling ring.
pub fn splat_pixels(
    s: &SplatRef,
    shape: SplatShape,
    width: u32,
    height: u32,
) -> Vec<(usize, bool)> {
    let corner = |side: u32| {
        s.q.map(|q| (q - 128 * (side as i64 + 1)).div_euclid(256) + 1)
    };
    let (inner, outer) = (corner(s.side), corner(s.ring));
    let mut out = Vec::new();
    for dy in 0..s.ring as i64 {
        for dx in 0..s.ring as i64 {
            let (x, y) = (outer[0] + dx, outer[1] + dy);
            if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                continue;
            }
            let (inside, in_ring) = match shape {
                SplatShape::Circle => {
                    let d = [x * 256 + 128 - s.q[0], y * 256 + 128 - s.q[1]];
                    let d2 = d[0] * d[0] + d[1] * d[1];
                    let (r, rr) = (128 * s.side as i64, 128 * s.ring as i64);
                    let centre = x == s.q[0].div_euclid(256) && y == s.q[1].div_euclid(256);
                    (d2 <= r * r || centre, d2 <= rr * rr)
                }
                SplatShape::Square => {
                    let o = [x - inner[0], y - inner[1]];
                    let side = s.side as i64;
                    ((0..side).contains(&o[0]) && (0..side).contains(&o[1]), true)
                }
            };
            if inside || in_ring {
                out.push(((y * width as i64 + x) as usize, !inside));
            }
        }
    }
    out
}

/// The inverted depth word a splat pixel competes with: larger wins; the ring's is of a lower
/// tier (its top bit cleared), so it only fills pixels no footprint covers.
fn tiered(depth: f32, ring: bool) -> u32 {
    let inv = !depth.to_bits();
    if ring {
        inv & 0x7fff_ffff
    } else {
        inv
    }
}

/// Closest splat per pixel: (view depth, colour word: RGB and the splat's side in the alpha
/// byte); on equal depth the smaller word. No rings: the closest-point path fills gaps on the
/// screen ([`fill_splat_gaps`]).
/// `spacing` is each point's surface spacing (adaptive splats).
pub fn closest_splats(
    positions: &[[f64; 3]],
    colors: &[u32],
    spacing: f32,
    camera: &Camera,
    (width, height): (u32, u32),
    splats: &SplatSettings,
) -> Vec<Option<(f32, u32)>> {
    let vp = camera.view_projection(width as f64 / height as f64);
    let uniform = splats.uniform(camera.focal_px(height), false);
    let mut best: Vec<Option<(u32, u32, f32)>> = vec![None; (width * height) as usize];
    for (p, c) in positions.iter().zip(colors) {
        let Some(s) = splat_with(&vp, width, height, *p, spacing, uniform) else {
            continue;
        };
        // The colour word carries the splat's side in its alpha byte (common.wgsl).
        let shown = (*c & 0x00ff_ffff) | s.side << 24;
        for (i, ring) in splat_pixels(&s, splats.shape, width, height) {
            let key = (tiered(s.depth, ring), !shown);
            if best[i].is_none_or(|(inv, nc, _)| key > (inv, nc)) {
                best[i] = Some((key.0, key.1, s.depth));
            }
        }
    }
    best.into_iter()
        .map(|b| b.map(|(_, nc, d)| (d, !nc)))
        .collect()
}

/// Blended splats (Botsch et al.): per pixel, the integer average colour of the splat pixels
/// of the closest's tier within `blend` × its depth (adaptive splats with their rings).
pub fn blended_splats(
    positions: &[[f64; 3]],
    colors: &[u32],
    spacing: f32,
    camera: &Camera,
    (width, height): (u32, u32),
    splats: &SplatSettings,
    blend: f32,
) -> Vec<Option<u32>> {
    let vp = camera.view_projection(width as f64 / height as f64);
    let uniform = splats.uniform(camera.focal_px(height), true);
    let fragments: Vec<(usize, u32, f32, u32)> = positions
        .iter()
        .zip(colors)
        .filter_map(|(p, c)| splat_with(&vp, width, height, *p, spacing, uniform).map(|s| (s, *c)))
        .flat_map(|(s, c)| {
            splat_pixels(&s, splats.shape, width, height)
                .into_iter()
                .map(move |(i, ring)| (i, tiered(s.depth, ring), s.depth, c))
        })
        .collect();
    let mut closest = vec![0u32; (width * height) as usize];
    for (i, inv, _, _) in &fragments {
        closest[*i] = closest[*i].max(*inv);
    }
    let mut sums = vec![[0u64; 4]; closest.len()];
    for (i, inv, depth, c) in &fragments {
        let stored = closest[*i];
        let nearest = f32::from_bits(!(stored | 0x8000_0000));
        if (stored & 0x8000_0000) == (inv & 0x8000_0000) && *depth <= nearest * blend {
            add_color(&mut sums[*i], *c);
        }
    }
    averages(&sums)
}

/// The screen's gap filling of closest-point splats (gaps.wgsl): an empty pixel takes the
/// closest (then smaller colour word) of the splat pixels within their reach of it — the
/// splat's side, from the colour word's alpha byte, through [`crate::splat::gap_reach`]; the
/// window is a square, or a disc for circles.
pub fn fill_splat_gaps(
    pixels: &[Option<(f32, u32)>],
    (width, height): (u32, u32),
    shape: SplatShape,
) -> Vec<Option<(f32, u32)>> {
    let (w, h) = (width as i64, height as i64);
    let r = crate::splat::GAP_REACH_MAX as i64;
    let mut out = pixels.to_vec();
    for y in 0..h {
        for x in 0..w {
            if pixels[(y * w + x) as usize].is_some() {
                continue;
            }
            let mut best: Option<(f32, u32)> = None;
            for qy in (y - r).max(0)..=(y + r).min(h - 1) {
                for qx in (x - r).max(0)..=(x + r).min(w - 1) {
                    let Some((d, c)) = pixels[(qy * w + qx) as usize] else {
                        continue;
                    };
                    let reach = crate::splat::gap_reach(c >> 24) as i64;
                    let (dx, dy) = (qx - x, qy - y);
                    let inside = match shape {
                        SplatShape::Square => dx.abs() <= reach && dy.abs() <= reach,
                        SplatShape::Circle => dx * dx + dy * dy <= reach * reach,
                    };
                    if inside && best.is_none_or(|(bd, bc)| d < bd || (d == bd && c < bc)) {
                        best = Some((d, c));
                    }
                }
            }
            out[(y * w + x) as usize] = best;
        }
    }
    out
}
