//! Level of detail per pointlet (virtualized paper §III-B, eq. 2–3): the CPU reference that the
//! GPU LoD pass is tested against.
//!
//! l_i = γ_i · ‖(v/2)·p_center_i − (v/2)·p_max_i‖, with p the projected AABB centre and max
//! corner in NDC and v the viewport in pixels; γ_i = (Σ_j h_j)² / h_i² where h is the AABB's
//! half diagonal, damping pointlets with anomalous extents. Culled pointlets get l_i = 0; visible
//! ones at least one pixel's worth. The requested count is l_i / Σl · B, clamped to the
//! pointlet's size, and at least one point for a visible pointlet.

use crate::Aabb;

/// A column-major 4×4 matrix (m[column][row]), as WGSL and most GPU code expect.
pub type Mat4 = [[f64; 4]; 4];

pub fn transform(m: &Mat4, p: [f64; 3]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (r, o) in out.iter_mut().enumerate() {
        *o = m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r];
    }
    out
}

/// True when the box lies entirely outside one clip plane (-w ≤ x,y ≤ w, 0 ≤ z ≤ w).
pub fn outside_frustum(view_proj: &Mat4, b: &Aabb) -> bool {
    let corners: Vec<[f64; 4]> = (0..8)
        .map(|c| {
            let p = [
                if c & 1 == 0 { b.min[0] } else { b.max[0] },
                if c & 2 == 0 { b.min[1] } else { b.max[1] },
                if c & 4 == 0 { b.min[2] } else { b.max[2] },
            ];
            transform(view_proj, p)
        })
        .collect();
    let planes: [fn(&[f64; 4]) -> bool; 6] = [
        |c| c[0] < -c[3],
        |c| c[0] > c[3],
        |c| c[1] < -c[3],
        |c| c[1] > c[3],
        |c| c[2] < 0.0,
        |c| c[2] > c[3],
    ];
    planes.iter().any(|out| corners.iter().all(out))
}

/// Projected length in pixels of the segment from the AABB centre to its max corner; boxes that
/// reach behind the eye count as filling the viewport.
pub fn projected_size(view_proj: &Mat4, b: &Aabb, viewport: [f64; 2]) -> f64 {
    let c = transform(view_proj, b.center());
    let m = transform(view_proj, b.max);
    if c[3] <= 1e-9 || m[3] <= 1e-9 {
        return (viewport[0] * viewport[0] + viewport[1] * viewport[1]).sqrt();
    }
    let dx = 0.5 * viewport[0] * (c[0] / c[3] - m[0] / m[3]);
    let dy = 0.5 * viewport[1] * (c[1] / c[3] - m[1] / m[3]);
    (dx * dx + dy * dy).sqrt()
}

/// Requested points per pointlet for a bucket of `bucket` points.
pub fn requested_points(
    view_proj: &Mat4,
    viewport: [f64; 2],
    boxes: &[Aabb],
    counts: &[u32],
    bucket: u64,
) -> Vec<u32> {
    let half: Vec<f64> = boxes.iter().map(|b| 0.5 * b.diagonal()).collect();
    let sum_h: f64 = half.iter().sum();
    let importance: Vec<f64> = boxes
        .iter()
        .zip(&half)
        .map(|(b, h)| {
            if outside_frustum(view_proj, b) {
                return 0.0;
            }
            // A degenerate (single-point) box has no anomaly to damp.
            let gamma = if *h > 0.0 {
                sum_h * sum_h / (h * h)
            } else {
                1.0
            };
            // At least a pixel: a pointlet whose box collapsed to a point still gets points.
            gamma * projected_size(view_proj, b, viewport).max(1.0)
        })
        .collect();
    let total: f64 = importance.iter().sum();
    if total <= 0.0 {
        return vec![0; boxes.len()];
    }
    importance
        .iter()
        .zip(counts)
        .map(|(l, n)| {
            if *l == 0.0 {
                return 0;
            }
            // A point at least: a bucket too small to share out still shows every visible one.
            ((l / total * bucket as f64).round() as u64)
                .max(1)
                .min(*n as u64) as u32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Looks down -y from y = -10 onto the origin: x right, z up, perspective 90° (depth 0..1).
    fn camera() -> Mat4 {
        // view: x' = x, y' = z, z' = -(y + 10) (eye at y = -10 looking along +y)
        let view: Mat4 = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, -10.0, 1.0],
        ];
        let (n, f) = (0.1, 100.0);
        let proj: Mat4 = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, f / (n - f), -1.0],
            [0.0, 0.0, n * f / (n - f), 0.0],
        ];
        let mut vp = [[0.0; 4]; 4];
        for c in 0..4 {
            for r in 0..4 {
                vp[c][r] = (0..4).map(|k| proj[k][r] * view[c][k]).sum();
            }
        }
        vp
    }

    fn cube(c: [f64; 3], h: f64) -> Aabb {
        Aabb {
            min: [c[0] - h, c[1] - h, c[2] - h],
            max: [c[0] + h, c[1] + h, c[2] + h],
        }
    }

    #[test]
    fn culls_boxes_behind_or_beside_the_camera() {
        let vp = camera();
        assert!(!outside_frustum(&vp, &cube([0.0, 0.0, 0.0], 1.0)));
        assert!(
            outside_frustum(&vp, &cube([0.0, -20.0, 0.0], 1.0)),
            "behind"
        );
        assert!(outside_frustum(&vp, &cube([50.0, 0.0, 0.0], 1.0)), "right");
        assert!(
            outside_frustum(&vp, &cube([0.0, 500.0, 0.0], 1.0)),
            "beyond far"
        );
    }

    #[test]
    fn nearer_pointlets_get_more_points_and_the_bucket_is_respected() {
        let vp = camera();
        let boxes = [
            cube([0.0, -5.0, 0.0], 0.5),
            cube([0.0, 20.0, 0.0], 0.5),
            cube([0.0, -20.0, 0.0], 0.5),
        ];
        let r = requested_points(&vp, [1000.0, 1000.0], &boxes, &[1_000_000; 3], 10_000);
        assert!(r[0] > r[1] && r[1] > 0, "{r:?}");
        assert_eq!(r[2], 0, "culled");
        assert!((r[0] + r[1]) as i64 - 10_000 <= 1, "{r:?}");
        // Clamped to the pointlet's size.
        let r = requested_points(&vp, [1000.0, 1000.0], &boxes, &[100; 3], 10_000);
        assert_eq!(&r[..2], &[100, 100]);
    }

    #[test]
    fn a_bucket_too_small_to_share_still_gives_every_visible_pointlet_a_point() {
        let vp = camera();
        let boxes = [
            cube([0.0, -5.0, 0.0], 0.5),
            cube([0.0, 20.0, 0.0], 0.5),
            cube([0.0, -20.0, 0.0], 0.5),
        ];
        for bucket in [0, 1, 10] {
            let r = requested_points(&vp, [1000.0, 1000.0], &boxes, &[1_000_000, 5, 5], bucket);
            assert!(r[0] >= 1 && r[1] >= 1, "bucket {bucket}: {r:?}");
            assert_eq!(r[2], 0, "culled");
        }
        // An empty pointlet asks for nothing.
        let r = requested_points(&vp, [1000.0, 1000.0], &boxes[..1], &[0], 10);
        assert_eq!(r, [0]);
    }

    #[test]
    fn gamma_damps_anomalously_large_boxes() {
        let vp = camera();
        // Same projected size (twice as large at twice the distance), different extents.
        let small = cube([0.0, 0.0, 0.0], 0.5);
        let large = cube([0.0, 10.0, 0.0], 1.0);
        let r = requested_points(
            &vp,
            [1000.0, 1000.0],
            &[small, large],
            &[1_000_000; 2],
            10_000,
        );
        assert!(r[0] > 2 * r[1], "{r:?}");
    }
}
