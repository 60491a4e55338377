//! The f64 camera. Conventions: right-handed world, +z up (LAS data is z-up); view space looks
//! down −z with +y up; clip depth in [0, 1] (WebGPU). Rendering is camera-relative: the GPU only
//! ever sees the rotation-projection matrix with the eye at the origin, and positions minus the
//! eye, subtracted here in f64 (WebGPU paper §5), so coordinates of 10^6–10^7 m do not jitter.

use crate::lod::Mat4;
use crate::Aabb;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    /// Near and far plane distances (> 0, near < far).
    pub near: f64,
    pub far: f64,
}

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn length(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

pub fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = length(a);
    if l > 0.0 {
        [a[0] / l, a[1] / l, a[2] / l]
    } else {
        a
    }
}

/// `a · b` for column-major matrices.
pub fn mat_mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [[0.0; 4]; 4];
    for (c, col) in m.iter_mut().enumerate() {
        for (r, v) in col.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[k][r] * b[c][k]).sum();
        }
    }
    m
}

pub fn to_f32(m: &Mat4) -> [[f32; 4]; 4] {
    m.map(|c| c.map(|v| v as f32))
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    #[error("camera eye and target coincide")]
    EyeIsTarget,
    #[error("camera up vector is parallel to the view direction")]
    UpParallel,
    #[error("field of view {0}° must lie in (0, 180)")]
    BadFov(f64),
    #[error("near {near} and far {far} planes must satisfy 0 < near < far")]
    BadPlanes { near: f64, far: f64 },
    #[error("camera values must be finite")]
    NotFinite,
}

impl Camera {
    pub fn validate(&self) -> Result<(), CameraError> {
        let all = self.eye.iter().chain(&self.target).chain(&self.up).chain([
            &self.fov_y_deg,
            &self.near,
            &self.far,
        ]);
        if all.into_iter().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        let dir = sub(self.target, self.eye);
        if length(dir) == 0.0 {
            return Err(CameraError::EyeIsTarget);
        }
        if length(cross(normalize(dir), normalize(self.up))) < 1e-9 {
            return Err(CameraError::UpParallel);
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(CameraError::BadFov(self.fov_y_deg));
        }
        if !(self.near > 0.0 && self.near < self.far) {
            return Err(CameraError::BadPlanes {
                near: self.near,
                far: self.far,
            });
        }
        Ok(())
    }

    /// Orthonormal camera basis: right, up, back (view space x, y, z in world coordinates).
    pub fn basis(&self) -> [[f64; 3]; 3] {
        let back = normalize(sub(self.eye, self.target));
        let right = normalize(cross(self.up, back));
        let up = cross(back, right);
        [right, up, back]
    }

    /// World → view rotation with the eye at the origin (camera-relative view matrix).
    pub fn rotation(&self) -> Mat4 {
        let [r, u, b] = self.basis();
        [
            [r[0], u[0], b[0], 0.0],
            [r[1], u[1], b[1], 0.0],
            [r[2], u[2], b[2], 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// Pixels per unit of (lateral size / view depth) in an image `height` pixels tall.
    pub fn focal_px(&self, height: u32) -> f64 {
        0.5 * height as f64 / (self.fov_y_deg.to_radians() * 0.5).tan()
    }

    /// Right-handed perspective projection, depth 0 at near and 1 at far; clip w = view depth.
    pub fn projection(&self, aspect: f64) -> Mat4 {
        let f = 1.0 / (self.fov_y_deg.to_radians() * 0.5).tan();
        let (n, fa) = (self.near, self.far);
        [
            [f / aspect, 0.0, 0.0, 0.0],
            [0.0, f, 0.0, 0.0],
            [0.0, 0.0, fa / (n - fa), -1.0],
            [0.0, 0.0, n * fa / (n - fa), 0.0],
        ]
    }

    /// Projection · rotation: what the GPU gets; positions must be given relative to the eye.
    pub fn relative_view_projection(&self, aspect: f64) -> Mat4 {
        mat_mul(&self.projection(aspect), &self.rotation())
    }

    /// The absolute world → clip matrix (for CPU-side culling in f64).
    pub fn view_projection(&self, aspect: f64) -> Mat4 {
        let mut t = [[0.0; 4]; 4];
        for (i, c) in t.iter_mut().enumerate() {
            c[i] = 1.0;
        }
        t[3] = [-self.eye[0], -self.eye[1], -self.eye[2], 1.0];
        mat_mul(&self.relative_view_projection(aspect), &t)
    }

    /// Near/far planes that enclose `bounds` from the current eye, keeping depth precision sane.
    pub fn fit_planes(&mut self, bounds: &Aabb) {
        let diag = bounds.diagonal().max(1e-6);
        let far_corner = (0..8)
            .map(|c| {
                let p = [
                    if c & 1 == 0 {
                        bounds.min[0]
                    } else {
                        bounds.max[0]
                    },
                    if c & 2 == 0 {
                        bounds.min[1]
                    } else {
                        bounds.max[1]
                    },
                    if c & 4 == 0 {
                        bounds.min[2]
                    } else {
                        bounds.max[2]
                    },
                ];
                length(sub(p, self.eye))
            })
            .fold(0.0, f64::max);
        self.far = (far_corner * 1.05).max(diag * 1e-3);
        self.near = (self.far * 1e-5).max(1e-4);
    }

    /// Looking at the whole of `bounds` from above at an angle (south-west, 35° down).
    pub fn overview(bounds: &Aabb, fov_y_deg: f64) -> Camera {
        let c = bounds.center();
        let radius = 0.5 * bounds.diagonal().max(1e-3);
        let dist = radius / (fov_y_deg.to_radians() * 0.5).sin();
        let (yaw, pitch) = (225f64.to_radians(), 35f64.to_radians());
        let dir = [
            pitch.cos() * yaw.cos(),
            pitch.cos() * yaw.sin(),
            pitch.sin(),
        ];
        let mut cam = Camera {
            eye: [
                c[0] + dir[0] * dist,
                c[1] + dir[1] * dist,
                c[2] + dir[2] * dist,
            ],
            target: c,
            up: [0.0, 0.0, 1.0],
            fov_y_deg,
            near: 0.1,
            far: 1.0,
        };
        cam.fit_planes(bounds);
        cam
    }

    /// Close to the centre of `bounds`, low over the data, looking across it: most points are
    /// outside the frustum and the rest spread over the screen.
    pub fn closeup(bounds: &Aabb, fov_y_deg: f64) -> Camera {
        let c = bounds.center();
        let e = bounds.extent();
        let span = e[0].max(e[1]).max(1e-3);
        let step = span * 0.06;
        let eye = [c[0] - step, c[1] - step, c[2] + e[2] * 0.25 + span * 0.02];
        let target = [c[0] + step, c[1] + step, c[2] - e[2] * 0.1];
        let mut cam = Camera {
            eye,
            target,
            up: [0.0, 0.0, 1.0],
            fov_y_deg,
            near: 0.1,
            far: 1.0,
        };
        cam.fit_planes(bounds);
        cam
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::transform;

    fn cam() -> Camera {
        Camera {
            eye: [6_400_000.0, 10.0, 5.0],
            target: [6_400_010.0, 10.0, 5.0],
            up: [0.0, 0.0, 1.0],
            fov_y_deg: 60.0,
            near: 0.5,
            far: 100.0,
        }
    }

    #[test]
    fn relative_and_absolute_agree_and_depth_is_view_distance() {
        let c = cam();
        let p = [6_400_005.0, 11.0, 5.5];
        let abs = transform(&c.view_projection(1.5), p);
        let rel = transform(&c.relative_view_projection(1.5), sub(p, c.eye));
        for i in 0..4 {
            assert!((abs[i] - rel[i]).abs() < 1e-6, "{abs:?} {rel:?}");
        }
        assert!(
            (rel[3] - 5.0).abs() < 1e-9,
            "w is the distance along the view axis"
        );
        // Looking along +x with z up: a point to the left (+y) lands at negative x in clip space.
        assert!(rel[0] < 0.0 && rel[1] > 0.0);
        let near = transform(&c.relative_view_projection(1.0), [0.5, 0.0, 0.0]);
        assert!(
            (near[2] / near[3]).abs() < 1e-9,
            "depth 0 at the near plane"
        );
    }

    #[test]
    fn validation() {
        let mut c = cam();
        c.validate().unwrap();
        c.up = [1.0, 0.0, 0.0];
        assert_eq!(c.validate(), Err(CameraError::UpParallel));
        let mut c = cam();
        c.fov_y_deg = 190.0;
        assert!(c.validate().is_err());
        c = cam();
        c.target = c.eye;
        assert_eq!(c.validate(), Err(CameraError::EyeIsTarget));
    }

    #[test]
    fn overview_sees_every_corner() {
        let b = Aabb {
            min: [500_000.0, 4_100_000.0, 100.0],
            max: [501_000.0, 4_100_600.0, 180.0],
        };
        let c = Camera::overview(&b, 60.0);
        c.validate().unwrap();
        let vp = c.view_projection(16.0 / 9.0);
        for k in 0..8 {
            let p = [
                if k & 1 == 0 { b.min[0] } else { b.max[0] },
                if k & 2 == 0 { b.min[1] } else { b.max[1] },
                if k & 4 == 0 { b.min[2] } else { b.max[2] },
            ];
            let q = transform(&vp, p);
            assert!(q[3] > 0.0 && (q[0] / q[3]).abs() <= 1.0 && (q[1] / q[3]).abs() <= 1.0);
            assert!(q[2] / q[3] > 0.0 && q[2] / q[3] < 1.0);
        }
    }
}

/// An east–north–up frame at a point near the Earth's surface in ECEF coordinates (the world
/// frame of georeferenced 3D Tiles): predefined views and orbits of such data are made in it,
/// so that "up" is the local vertical rather than ECEF's z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalFrame {
    pub origin: [f64; 3],
    /// East, north and up, unit vectors in world coordinates.
    pub axes: [[f64; 3]; 3],
}

/// WGS 84 semi-axes in metres.
const WGS84_A: f64 = 6_378_137.0;
const WGS84_B: f64 = 6_356_752.314_245;

impl LocalFrame {
    /// The frame at `p` when `p` lies 6 200–6 500 km from the Earth's centre (ECEF data), its
    /// up the ellipsoid's normal there; `None` for anything else (local coordinates).
    pub fn at_ecef(p: [f64; 3]) -> Option<Self> {
        let r = length(p);
        if !(6.2e6..6.5e6).contains(&r) {
            return None;
        }
        let (a2, b2) = (WGS84_A * WGS84_A, WGS84_B * WGS84_B);
        let up = normalize([p[0] / a2, p[1] / a2, p[2] / b2]);
        let east = cross([0.0, 0.0, 1.0], up);
        // At a pole any east will do.
        let east = if length(east) < 1e-9 {
            [1.0, 0.0, 0.0]
        } else {
            normalize(east)
        };
        let north = cross(up, east);
        Some(Self {
            origin: p,
            axes: [east, north, up],
        })
    }

    /// World coordinates of local point `p`.
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        let d = self.direction_to_world(p);
        [0, 1, 2].map(|i| self.origin[i] + d[i])
    }

    /// World direction of local direction `v`.
    pub fn direction_to_world(&self, v: [f64; 3]) -> [f64; 3] {
        let [e, n, u] = self.axes;
        [0, 1, 2].map(|i| e[i] * v[0] + n[i] * v[1] + u[i] * v[2])
    }

    /// Local coordinates of world point `p`.
    pub fn to_local(&self, p: [f64; 3]) -> [f64; 3] {
        let d = sub(p, self.origin);
        self.axes.map(|a| dot(d, a))
    }

    /// A camera made in this frame, placed in world coordinates.
    pub fn camera_to_world(&self, c: &Camera) -> Camera {
        Camera {
            eye: self.to_world(c.eye),
            target: self.to_world(c.target),
            up: self.direction_to_world(c.up),
            ..*c
        }
    }
}

#[cfg(test)]
mod local_frame_tests {
    use super::*;

    #[test]
    fn an_ecef_point_gets_a_right_handed_east_north_up_frame() {
        // 44.06° N, 123.07° W at 150 m (Eugene, Oregon).
        let (lat, lon) = (44.06f64.to_radians(), (-123.07f64).to_radians());
        let e2 = 1.0 - (WGS84_B * WGS84_B) / (WGS84_A * WGS84_A);
        let n = WGS84_A / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        let h = 150.0;
        let p = [
            (n + h) * lat.cos() * lon.cos(),
            (n + h) * lat.cos() * lon.sin(),
            (n * (1.0 - e2) + h) * lat.sin(),
        ];
        let f = LocalFrame::at_ecef(p).expect("near the surface");
        let [e, no, u] = f.axes;
        let geodetic_up = [lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()];
        assert!(
            dot(u, geodetic_up) > 1.0 - 1e-12,
            "up is the ellipsoid normal"
        );
        assert!(e[2].abs() < 1e-12, "east is horizontal");
        assert!(no[2] > 0.0, "north points to the pole");
        let c = cross(e, no);
        assert!((0..3).all(|i| (c[i] - u[i]).abs() < 1e-12), "right-handed");
        let q = [12.5, -40.0, 3.0];
        let back = f.to_local(f.to_world(q));
        assert!((0..3).all(|i| (back[i] - q[i]).abs() < 1e-6), "{back:?}");
        assert_eq!(LocalFrame::at_ecef([500_000.0, 4_100_000.0, 200.0]), None);
    }
}
