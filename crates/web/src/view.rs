//! The camera of the page: built from the URL exactly as `pointlet render` builds it from its
//! flags (the overview of the data, then eye/target/up/fov, near and far fitted to the data),
//! and moved by orbit, pan and zoom around the target.

use crate::params::ViewParams;
use pointlet_core::camera::{length, normalize, sub, CameraError};
use pointlet_core::{Aabb, Camera};

/// Up direction of `pointlet render`'s default `--up` (data is z-up).
pub const UP: [f64; 3] = [0.0, 0.0, 1.0];

/// The camera `params` describe for data within `bounds`.
pub fn camera_for(params: &ViewParams, bounds: &Aabb) -> Result<Camera, CameraError> {
    let mut cam = Camera::overview(bounds, params.fov);
    if let (Some(eye), Some(target)) = (params.eye, params.target) {
        cam.eye = eye;
        cam.target = target;
        cam.up = UP;
        cam.fit_planes(bounds);
    }
    cam.fov_y_deg = params.fov;
    cam.validate()?;
    Ok(cam)
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Turns the eye around the target: `yaw` about z, `pitch` up or down (radians), stopping
/// short of the poles so the up vector stays meaningful.
pub fn orbit(cam: &mut Camera, yaw: f64, pitch: f64, bounds: &Aabb) {
    let offset = sub(cam.eye, cam.target);
    let r = length(offset);
    if r <= 0.0 {
        return;
    }
    let horizontal = offset[0].hypot(offset[1]);
    let mut elevation = offset[2].atan2(horizontal);
    let mut azimuth = offset[1].atan2(offset[0]);
    azimuth -= yaw;
    let limit = 89f64.to_radians();
    elevation = (elevation + pitch).clamp(-limit, limit);
    cam.eye = add(
        cam.target,
        [
            r * elevation.cos() * azimuth.cos(),
            r * elevation.cos() * azimuth.sin(),
            r * elevation.sin(),
        ],
    );
    cam.up = UP;
    cam.fit_planes(bounds);
}

/// Moves eye and target together across the view: `dx`, `dy` in pixels of an image
/// `height` pixels tall, so the point at the target follows the cursor.
pub fn pan(cam: &mut Camera, dx: f64, dy: f64, height: u32, bounds: &Aabb) {
    let [right, up, _] = cam.basis();
    let dist = length(sub(cam.eye, cam.target));
    let per_px = dist / cam.focal_px(height.max(1));
    let shift = add(scale(right, -dx * per_px), scale(up, dy * per_px));
    cam.eye = add(cam.eye, shift);
    cam.target = add(cam.target, shift);
    cam.fit_planes(bounds);
}

/// Moves the eye towards (`factor` < 1) or away from the target, never onto it.
pub fn zoom(cam: &mut Camera, factor: f64, bounds: &Aabb) {
    let offset = sub(cam.eye, cam.target);
    let r = length(offset);
    let min = (bounds.diagonal() * 1e-6).max(1e-6);
    let new_r = (r * factor.clamp(0.01, 100.0)).max(min);
    if r > 0.0 {
        cam.eye = add(cam.target, scale(normalize(offset), new_r));
    }
    cam.fit_planes(bounds);
}

/// Where `p` lands on an image of `size` pixels (x right, y down) and its view depth; `None`
/// behind the eye.
pub fn project(cam: &Camera, size: (u32, u32), p: [f64; 3]) -> Option<([f64; 2], f64)> {
    let [right, up, back] = cam.basis();
    let d = sub(p, cam.eye);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let depth = -dot(d, back);
    if depth <= 0.0 {
        return None;
    }
    let f = cam.focal_px(size.1);
    let x = 0.5 * size.0 as f64 + f * dot(d, right) / depth;
    let y = 0.5 * size.1 as f64 - f * dot(d, up) / depth;
    Some(([x, y], depth))
}

/// Distance between two points.
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    length(sub(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds() -> Aabb {
        Aabb {
            min: [0.0, 0.0, 0.0],
            max: [100.0, 50.0, 10.0],
        }
    }

    #[test]
    fn url_camera_is_the_render_camera() {
        let p = ViewParams::parse("eye=-10,20,30&target=50,25,5&fov=40").unwrap();
        let cam = camera_for(&p, &bounds()).unwrap();
        let mut want = Camera::overview(&bounds(), 40.0);
        want.eye = [-10.0, 20.0, 30.0];
        want.target = [50.0, 25.0, 5.0];
        want.up = UP;
        want.fit_planes(&bounds());
        assert_eq!(cam, want);
        let overview = camera_for(&ViewParams::default(), &bounds()).unwrap();
        assert_eq!(overview, Camera::overview(&bounds(), 60.0));
    }

    #[test]
    fn orbit_keeps_the_distance_and_the_target() {
        let mut cam = Camera::overview(&bounds(), 60.0);
        let r = distance(cam.eye, cam.target);
        let t = cam.target;
        orbit(&mut cam, 0.7, -0.2, &bounds());
        assert!((distance(cam.eye, cam.target) - r).abs() < 1e-9 * r);
        assert_eq!(cam.target, t);
        orbit(&mut cam, 0.0, 10.0, &bounds());
        assert!(cam.validate().is_ok());
    }

    #[test]
    fn pan_moves_the_target_with_the_cursor() {
        let mut cam = Camera::overview(&bounds(), 60.0);
        let size = (800, 600);
        let before = project(&cam, size, [50.0, 25.0, 5.0]).unwrap().0;
        pan(&mut cam, 40.0, -30.0, size.1, &bounds());
        let after = project(&cam, size, [50.0, 25.0, 5.0]).unwrap().0;
        assert!(
            (after[0] - before[0] - 40.0).abs() < 1.0,
            "{before:?} {after:?}"
        );
        assert!(
            (after[1] - before[1] + 30.0).abs() < 1.0,
            "{before:?} {after:?}"
        );
    }

    #[test]
    fn zoom_approaches_without_reaching_the_target() {
        let mut cam = Camera::overview(&bounds(), 60.0);
        let r = distance(cam.eye, cam.target);
        zoom(&mut cam, 0.5, &bounds());
        assert!((distance(cam.eye, cam.target) - 0.5 * r).abs() < 1e-9 * r);
        for _ in 0..100 {
            zoom(&mut cam, 0.01, &bounds());
        }
        assert!(cam.validate().is_ok());
    }

    #[test]
    fn the_target_projects_to_the_centre() {
        let cam = Camera::overview(&bounds(), 60.0);
        let (px, depth) = project(&cam, (640, 480), cam.target).unwrap();
        assert!((px[0] - 320.0).abs() < 1e-9 && (px[1] - 240.0).abs() < 1e-9);
        assert!(depth > 0.0);
        assert!(project(&cam, (640, 480), scale(sub(cam.eye, cam.target), 3.0)).is_none());
    }
}
