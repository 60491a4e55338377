//! The camera controller: input (drags, wheel steps, held keys, elapsed time) → f64 camera.
//! No window types here, so every motion is unit-tested. All state is the f64 `Camera`
//! itself; georeferenced data at 10^6 m moves as precisely as data at the origin.

use pointlet_core::camera::{cross, dot, length, normalize, sub};
use pointlet_core::{Aabb, Camera};

/// How dragging with the primary button and the movement keys steer the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NavMode {
    /// Rotate around the target; keys slide eye and target together.
    Orbit,
    /// Look around from the eye; keys move forward/back/sideways like a first-person game.
    Fly,
}

/// What a mouse drag does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drag {
    /// Orbit around the target, or look around in fly mode.
    Rotate,
    /// Slide the view parallel to the screen.
    Pan,
}

/// Movement keys (WASD + Q/E), held between key-down and key-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKey {
    Forward,
    Back,
    Left,
    Right,
    Up,
    Down,
}

const Z_UP: [f64; 3] = [0.0, 0.0, 1.0];
/// Rotation per dragged pixel: a drag across 1000 pixels turns 180°.
const RADIANS_PER_PIXEL: f64 = std::f64::consts::PI / 1000.0;
/// Elevation stays this far from straight up/down so that `up` never meets the view axis.
const MAX_ELEVATION: f64 = 89.0 * std::f64::consts::PI / 180.0;
/// Each wheel step brings the camera this much closer to the point under the cursor.
const ZOOM_PER_STEP: f64 = 0.85;
/// Key movement at speed 1: a quarter of the data's diagonal per second.
const SPEED_PER_DIAGONAL: f64 = 0.25;
/// Held-shift multiplier of key movement.
pub const FAST_FACTOR: f64 = 4.0;

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Unit vector at `azimuth` (from +x towards +y) and `elevation` (above the xy plane).
fn direction(azimuth: f64, elevation: f64) -> [f64; 3] {
    [
        elevation.cos() * azimuth.cos(),
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
    ]
}

/// Azimuth and elevation of a non-zero vector.
fn angles(v: [f64; 3]) -> (f64, f64) {
    let v = normalize(v);
    (v[1].atan2(v[0]), v[2].clamp(-1.0, 1.0).asin())
}

pub struct Navigator {
    pub camera: Camera,
    pub mode: NavMode,
    /// User speed factor on top of the data-size scaling (1 = a quarter diagonal per second).
    pub speed: f64,
    bounds: Aabb,
    held: [bool; 6],
    fast: bool,
}

impl Navigator {
    /// Starts from `camera` over data of `bounds` (which scales speeds and clip planes).
    pub fn new(camera: Camera, bounds: Aabb) -> Self {
        let mut nav = Self {
            camera,
            mode: NavMode::Orbit,
            speed: 1.0,
            bounds,
            held: [false; 6],
            fast: false,
        };
        nav.settle();
        nav
    }

    /// Replaces the camera (bookmarks, paths), keeping the z-up convention of the controller.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = camera;
        self.settle();
    }

    /// Distance from eye to target.
    pub fn distance(&self) -> f64 {
        length(sub(self.camera.target, self.camera.eye))
    }

    /// Key movement in data units per second.
    pub fn units_per_second(&self) -> f64 {
        let fast = if self.fast { FAST_FACTOR } else { 1.0 };
        self.bounds.diagonal().max(1e-3) * SPEED_PER_DIAGONAL * self.speed * fast
    }

    /// Keeps `up` = +z and the clip planes around the data after every change.
    fn settle(&mut self) {
        self.camera.up = Z_UP;
        let dist = self.distance();
        let floor = self.min_distance();
        if dist < floor {
            let back = normalize(sub(self.camera.eye, self.camera.target));
            let back = if length(back) > 0.0 {
                back
            } else {
                [0.0, -1.0, 0.0]
            };
            self.camera.eye = add(self.camera.target, scale(back, floor));
        }
        self.camera.fit_planes(&self.bounds);
    }

    /// The closest the eye may come to the target: zooming further would stop moving.
    fn min_distance(&self) -> f64 {
        (self.bounds.diagonal() * 1e-6).max(1e-4)
    }

    /// Applies a mouse drag of `delta` pixels (x right, y down) in a viewport of `size`.
    pub fn drag(&mut self, kind: Drag, delta: [f64; 2], size: [u32; 2]) {
        match kind {
            Drag::Rotate => self.rotate(delta),
            Drag::Pan => self.pan(delta, size),
        }
        self.settle();
    }

    fn rotate(&mut self, delta: [f64; 2]) {
        let cam = &mut self.camera;
        let d_az = -delta[0] * RADIANS_PER_PIXEL;
        let d_el = delta[1] * RADIANS_PER_PIXEL;
        match self.mode {
            NavMode::Orbit => {
                // The eye circles the target: dragging right turns the data right.
                let offset = sub(cam.eye, cam.target);
                let (az, el) = angles(offset);
                let el = (el + d_el).clamp(-MAX_ELEVATION, MAX_ELEVATION);
                cam.eye = add(cam.target, scale(direction(az + d_az, el), length(offset)));
            }
            NavMode::Fly => {
                // The target circles the eye: dragging right looks right.
                let offset = sub(cam.target, cam.eye);
                let (az, el) = angles(offset);
                let el = (el - d_el).clamp(-MAX_ELEVATION, MAX_ELEVATION);
                cam.target = add(cam.eye, scale(direction(az + d_az, el), length(offset)));
            }
        }
    }

    /// Data units per pixel at the target's depth.
    fn units_per_pixel(&self, height: u32) -> f64 {
        2.0 * self.distance() * (self.camera.fov_y_deg.to_radians() * 0.5).tan()
            / height.max(1) as f64
    }

    fn pan(&mut self, delta: [f64; 2], size: [u32; 2]) {
        // The point under the cursor at the target's depth follows the cursor.
        let [right, up, _] = self.camera.basis();
        let k = self.units_per_pixel(size[1]);
        let shift = add(scale(right, -delta[0] * k), scale(up, delta[1] * k));
        self.camera.eye = add(self.camera.eye, shift);
        self.camera.target = add(self.camera.target, shift);
    }

    /// Direction (unit) of the ray from the eye through `pixel` (origin top left).
    pub fn cursor_ray(&self, pixel: [f64; 2], size: [u32; 2]) -> [f64; 3] {
        let [right, up, back] = self.camera.basis();
        let (w, h) = (size[0].max(1) as f64, size[1].max(1) as f64);
        let t = (self.camera.fov_y_deg.to_radians() * 0.5).tan();
        let x = (2.0 * pixel[0] / w - 1.0) * t * w / h;
        let y = (1.0 - 2.0 * pixel[1] / h) * t;
        normalize(add(add(scale(right, x), scale(up, y)), scale(back, -1.0)))
    }

    /// The point on the cursor ray at the target's view depth: what the cursor "touches"
    /// without reading anything back from the GPU.
    pub fn cursor_point(&self, pixel: [f64; 2], size: [u32; 2]) -> [f64; 3] {
        let ray = self.cursor_ray(pixel, size);
        let forward = normalize(sub(self.camera.target, self.camera.eye));
        let along = self.distance() / dot(ray, forward).max(1e-6);
        add(self.camera.eye, scale(ray, along))
    }

    /// Zooms by wheel `steps` (positive = closer) towards the point under `pixel`, which stays
    /// under the cursor: eye and target scale about it.
    pub fn zoom_at(&mut self, steps: f64, pixel: [f64; 2], size: [u32; 2]) {
        let anchor = self.cursor_point(pixel, size);
        let mut f = ZOOM_PER_STEP.powf(steps);
        // Never past the closest allowed distance: the anchor would otherwise be crossed.
        let floor = self.min_distance() / self.distance().max(f64::MIN_POSITIVE);
        f = f.max(floor);
        let cam = &mut self.camera;
        cam.eye = add(anchor, scale(sub(cam.eye, anchor), f));
        cam.target = add(anchor, scale(sub(cam.target, anchor), f));
        self.settle();
    }

    pub fn set_key(&mut self, key: MoveKey, down: bool) {
        self.held[key as usize] = down;
    }

    /// Shift held: keys move `FAST_FACTOR` times faster.
    pub fn set_fast(&mut self, fast: bool) {
        self.fast = fast;
    }

    /// Forgets held keys (the window lost focus and will not see their release).
    pub fn release_keys(&mut self) {
        self.held = [false; 6];
        self.fast = false;
    }

    pub fn moving(&self) -> bool {
        self.held.iter().any(|h| *h)
    }

    /// Advances key movement by `dt` seconds; true if the camera moved.
    pub fn update(&mut self, dt: f64) -> bool {
        // NaN or non-positive steps move nothing.
        if !self.moving() || dt.is_nan() || dt <= 0.0 {
            return false;
        }
        let axis = |plus: MoveKey, minus: MoveKey| {
            self.held[plus as usize] as i32 as f64 - self.held[minus as usize] as i32 as f64
        };
        let (f, r, u) = (
            axis(MoveKey::Forward, MoveKey::Back),
            axis(MoveKey::Right, MoveKey::Left),
            axis(MoveKey::Up, MoveKey::Down),
        );
        let [right, _, back] = self.camera.basis();
        let forward = match self.mode {
            // Fly follows the view; orbit slides over the ground like a map.
            NavMode::Fly => scale(back, -1.0),
            NavMode::Orbit => {
                let flat = normalize([-back[0], -back[1], 0.0]);
                if length(flat) > 0.0 {
                    flat
                } else {
                    normalize(cross(Z_UP, right))
                }
            }
        };
        let step = self.units_per_second() * dt;
        let shift = scale(
            add(add(scale(forward, f), scale(right, r)), scale(Z_UP, u)),
            step,
        );
        self.camera.eye = add(self.camera.eye, shift);
        self.camera.target = add(self.camera.target, shift);
        self.settle();
        true
    }

    /// Zoom to fit: the whole data in view, keeping the current viewing direction.
    pub fn fit(&mut self) {
        let back = normalize(sub(self.camera.eye, self.camera.target));
        let c = self.bounds.center();
        let radius = 0.5 * self.bounds.diagonal().max(1e-3);
        let dist = radius / (self.camera.fov_y_deg.to_radians() * 0.5).sin();
        self.camera.target = c;
        self.camera.eye = add(c, scale(back, dist));
        self.settle();
    }

    /// Double-click: look at `point` from the current direction, twice as close as the target
    /// was (but no closer than a thousandth of the data), orbiting around it from now on.
    pub fn focus(&mut self, point: [f64; 3]) {
        let back = normalize(sub(self.camera.eye, self.camera.target));
        let dist = (self.distance() * 0.5).max(self.bounds.diagonal() * 1e-3);
        self.camera.target = point;
        self.camera.eye = add(point, scale(back, dist));
        self.settle();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::lod::transform;

    const SIZE: [u32; 2] = [800, 600];

    fn bounds(offset: f64) -> Aabb {
        Aabb {
            min: [offset, offset + 10.0, 100.0],
            max: [offset + 1000.0, offset + 610.0, 180.0],
        }
    }

    fn screen(cam: &Camera, p: [f64; 3]) -> [f64; 2] {
        let q = transform(&cam.view_projection(SIZE[0] as f64 / SIZE[1] as f64), p);
        [
            (q[0] / q[3] + 1.0) * 0.5 * SIZE[0] as f64,
            (1.0 - q[1] / q[3]) * 0.5 * SIZE[1] as f64,
        ]
    }

    fn nav(offset: f64) -> Navigator {
        let b = bounds(offset);
        Navigator::new(Camera::overview(&b, 60.0), b)
    }

    #[test]
    fn orbit_keeps_distance_and_target_and_clamps_elevation() {
        let mut n = nav(0.0);
        let (t, d) = (n.camera.target, n.distance());
        n.drag(Drag::Rotate, [250.0, 0.0], SIZE);
        assert_eq!(n.camera.target, t);
        assert!((n.distance() - d).abs() < 1e-9 * d);
        // A huge vertical drag stops short of looking straight down.
        n.drag(Drag::Rotate, [0.0, 1e6], SIZE);
        n.camera.validate().expect("camera stays valid");
        let (_, el) = angles(sub(n.camera.eye, n.camera.target));
        assert!((el - MAX_ELEVATION).abs() < 1e-9);
    }

    #[test]
    fn fly_look_keeps_the_eye() {
        let mut n = nav(0.0);
        n.mode = NavMode::Fly;
        let eye = n.camera.eye;
        n.drag(Drag::Rotate, [100.0, -40.0], SIZE);
        assert_eq!(n.camera.eye, eye);
        n.camera.validate().expect("valid");
    }

    #[test]
    fn zoom_keeps_the_point_under_the_cursor_far_from_the_origin() {
        for offset in [0.0, 4.0e6] {
            let mut n = nav(offset);
            let pixel = [600.0, 150.0];
            let anchor = n.cursor_point(pixel, SIZE);
            assert!(
                (screen(&n.camera, anchor)[0] - pixel[0]).abs() < 1e-6,
                "the cursor point projects to the cursor"
            );
            let d = n.distance();
            n.zoom_at(3.0, pixel, SIZE);
            assert!((n.distance() - d * ZOOM_PER_STEP.powi(3)).abs() < 1e-6 * d);
            let s = screen(&n.camera, anchor);
            assert!(
                (s[0] - pixel[0]).abs() < 1e-4 && (s[1] - pixel[1]).abs() < 1e-4,
                "offset {offset}: anchor moved to {s:?}"
            );
        }
    }

    #[test]
    fn zooming_in_forever_stops_at_the_minimum_distance() {
        let mut n = nav(0.0);
        for _ in 0..1000 {
            n.zoom_at(10.0, [400.0, 300.0], SIZE);
        }
        n.camera.validate().expect("valid");
        assert!(n.distance() >= n.min_distance() * 0.999);
    }

    #[test]
    fn pan_moves_the_target_plane_with_the_cursor_at_georeferenced_scale() {
        let mut n = nav(6.4e6);
        let p = n.camera.target;
        n.drag(Drag::Pan, [10.0, -5.0], SIZE);
        let s = screen(&n.camera, p);
        assert!(
            (s[0] - (400.0 + 10.0)).abs() < 1e-6 && (s[1] - (300.0 - 5.0)).abs() < 1e-6,
            "{s:?}"
        );
        // A sub-millimetre pan survives the 10^6 m coordinates.
        let mut n = nav(6.4e6);
        let before = n.camera.eye;
        let k = n.units_per_pixel(SIZE[1]);
        n.drag(Drag::Pan, [1e-3 / k, 0.0], SIZE);
        let moved = length(sub(n.camera.eye, before));
        assert!((moved - 1e-3).abs() < 1e-6, "moved {moved}");
    }

    #[test]
    fn keys_move_at_a_speed_scaled_to_the_data() {
        let mut n = nav(0.0);
        let eye = n.camera.eye;
        assert!(!n.update(1.0), "no key, no motion");
        n.set_key(MoveKey::Forward, true);
        assert!(n.update(0.5));
        let moved = length(sub(n.camera.eye, eye));
        let expected = bounds(0.0).diagonal() * SPEED_PER_DIAGONAL * 0.5;
        assert!((moved - expected).abs() < 1e-9 * expected);
        assert_eq!(n.camera.eye[2], eye[2], "orbit mode slides horizontally");
        n.set_fast(true);
        n.mode = NavMode::Fly;
        let eye = n.camera.eye;
        n.update(0.5);
        let moved = length(sub(n.camera.eye, eye));
        assert!((moved - expected * FAST_FACTOR).abs() < 1e-9 * expected);
        assert!(
            n.camera.eye[2] < eye[2],
            "fly mode follows the downward view"
        );
        n.release_keys();
        assert!(!n.moving());
    }

    #[test]
    fn fit_and_focus() {
        let mut n = nav(1e6);
        n.zoom_at(20.0, [10.0, 10.0], SIZE);
        n.fit();
        let b = bounds(1e6);
        assert_eq!(n.camera.target, b.center());
        for k in 0..8 {
            let p = [
                if k & 1 == 0 { b.min[0] } else { b.max[0] },
                if k & 2 == 0 { b.min[1] } else { b.max[1] },
                if k & 4 == 0 { b.min[2] } else { b.max[2] },
            ];
            let s = screen(&n.camera, p);
            assert!(s[1] >= 0.0 && s[1] <= SIZE[1] as f64, "corner {k} at {s:?}");
        }
        let p = [1e6 + 300.0, 1e6 + 200.0, 120.0];
        let d = n.distance();
        n.focus(p);
        assert_eq!(n.camera.target, p);
        assert!((n.distance() - d * 0.5).abs() < 1e-6 * d);
    }
}
