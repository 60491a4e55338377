//! CPU reference rasterizers for golden tests: the same projection, pixel and tie rules as the
//! shaders, computed in f64 from absolute coordinates. Exact for closest-point variants wherever
//! a point is not within rounding distance of a pixel border or of another point's depth.

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
                let s = &mut sums[*i];
                for (k, v) in s.iter_mut().take(3).enumerate() {
                    *v += ((c >> (8 * k)) & 0xff) as u64;
                }
                s[3] += 1;
            }
        }
    }
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
