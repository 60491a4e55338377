//! Picking on the CPU: the nearest resident point under the cursor. The browser keeps the
//! quantized positions it fetched, so a click needs no GPU readback (which could only be
//! waited for asynchronously) and returns the stored, exact coordinates.

use crate::view::project;
use pointlet_core::{Camera, Quantization};

/// The point of smallest view depth among those landing within `radius` pixels of `pixel`
/// (the visible surface there), over every point of `windows` (quantized positions).
pub fn pick<'a>(
    cam: &Camera,
    size: (u32, u32),
    pixel: [f64; 2],
    radius: f64,
    quantization: &Quantization,
    windows: impl IntoIterator<Item = &'a [[i32; 3]]>,
) -> Option<[f64; 3]> {
    let mut best: Option<([f64; 3], f64)> = None;
    let r2 = radius * radius;
    for w in windows {
        for q in w {
            let p = quantization.dequantize(*q);
            let Some((px, depth)) = project(cam, size, p) else {
                continue;
            };
            if depth < cam.near || depth > cam.far {
                continue;
            }
            let (dx, dy) = (px[0] - pixel[0], px[1] - pixel[1]);
            if dx * dx + dy * dy <= r2 && best.is_none_or(|b| depth < b.1) {
                best = Some((p, depth));
            }
        }
    }
    best.map(|b| b.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::Aabb;

    #[test]
    fn picks_the_nearest_point_under_the_cursor() {
        let bounds = Aabb {
            min: [-10.0; 3],
            max: [10.0; 3],
        };
        let mut cam = Camera::overview(&bounds, 60.0);
        cam.eye = [0.0, -20.0, 0.0];
        cam.target = [0.0, 0.0, 0.0];
        cam.fit_planes(&bounds);
        let q = Quantization {
            scale: [0.01; 3],
            offset: [0.0; 3],
        };
        // Two points on the view axis (the nearer wins) and one far to the side.
        let pts = vec![[0, 0, 0], [0, -500, 0], [800, 0, 0]];
        let hit = pick(&cam, (200, 100), [100.0, 50.0], 3.0, &q, [pts.as_slice()]);
        assert_eq!(hit, Some([0.0, -5.0, 0.0]));
        assert_eq!(
            pick(&cam, (200, 100), [10.0, 10.0], 3.0, &q, [pts.as_slice()]),
            None
        );
    }
}
