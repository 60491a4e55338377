//! Camera paths: keyframed flights for benchmarks and the viewer's path recorder, and the
//! evaluation path of the virtualized paper (§IV-B: orbit the data while zooming the vertical
//! field of view in and out).
//!
//! # JSON format
//!
//! One object with a `keyframes` array. Each keyframe has `time` (seconds; strictly increasing
//! from one keyframe to the next; the path need not start at 0), `eye` and `target` (world
//! coordinates, `eye` ≠ `target`), `up` (any vector not parallel to the view direction; may be
//! omitted and then defaults to +z) and `fov` (vertical field of view in degrees, in (0, 180)).
//! Unknown fields are rejected so that a misspelt key is an error, not a silent default.
//!
//! ```json
//! {"keyframes":[
//!   {"time":0.0,"eye":[100.0,0.0,50.0],"target":[0.0,0.0,0.0],"up":[0.0,0.0,1.0],"fov":60.0},
//!   {"time":2.5,"eye":[0.0,100.0,50.0],"target":[0.0,0.0,0.0],"up":[0.0,0.0,1.0],"fov":30.0}
//! ]}
//! ```
//!
//! # Interpolation
//!
//! Eye and target follow cubic Hermite splines whose tangents are time-aware Catmull-Rom finite
//! differences (one-sided at the ends), so the motion is C¹ and passes through every keyframe
//! exactly; fov and up are interpolated linearly and up is then re-orthogonalised against the
//! view direction. Times outside the path are clamped to its first and last keyframes.

use crate::camera::{cross, dot, length, normalize, sub};
use crate::{Aabb, Camera};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Largest file `CameraPath::load` reads: a path is kilobytes to a few megabytes, and the limit
/// keeps a wrong argument (a point cloud, a device) from being read into memory whole.
pub const MAX_PATH_FILE_BYTES: u64 = 64 << 20;

/// The orbit's widest and narrowest vertical field of view (degrees).
pub const ORBIT_FOV_WIDE: f64 = 60.0;
pub const ORBIT_FOV_NARROW: f64 = 15.0;
/// Height of the orbiting eye above the data centre, as an angle (degrees).
pub const ORBIT_ELEVATION_DEG: f64 = 30.0;
/// Zoom cycles (wide → narrow → wide) per orbit.
pub const ORBIT_ZOOM_CYCLES: f64 = 2.0;
/// Keyframes per orbit: at least this many (1/64 turn apart keeps the spline on the circle to
/// ~1e-6 of the radius) and at most one per frame up to the cap.
const ORBIT_MIN_KEYFRAMES: f64 = 64.0;
const ORBIT_MAX_KEYFRAMES: f64 = 3600.0;
/// First azimuth of the orbit: the south-west view that `Camera::overview` also uses.
const ORBIT_START_AZIMUTH_DEG: f64 = 225.0;

const Z_UP: [f64; 3] = [0.0, 0.0, 1.0];

fn z_up() -> [f64; 3] {
    Z_UP
}

/// One camera pose at one time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Seconds from the path's time origin.
    pub time: f64,
    pub eye: [f64; 3],
    pub target: [f64; 3],
    #[serde(default = "z_up")]
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov: f64,
}

/// Why a keyframe is unusable.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KeyframeProblem {
    #[error("{0} is not a finite number")]
    NotFinite(&'static str),
    #[error("time {time} s does not come after the previous keyframe's {previous} s")]
    TimeNotIncreasing { time: f64, previous: f64 },
    #[error("eye and target coincide")]
    EyeIsTarget,
    #[error("fov {0}° must lie in (0, 180)")]
    BadFov(f64),
    #[error("up vector is zero or parallel to the view direction")]
    UpParallel,
}

#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("cannot read camera path {}: {source}", file.display())]
    Read {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "camera path {} is larger than the {MAX_PATH_FILE_BYTES}-byte limit for path files",
        file.display()
    )]
    TooLarge { file: PathBuf },
    #[error("cannot write camera path {}: {source}", file.display())]
    Write {
        file: PathBuf,
        source: std::io::Error,
    },
    /// A content problem (`Json`, `Empty`, `Keyframe`) found in a file.
    #[error("{}: {source}", file.display())]
    InFile {
        file: PathBuf,
        source: Box<PathError>,
    },
    #[error(
        "not a camera path of the form {{\"keyframes\":[{{\"time\":s,\"eye\":[x,y,z],\
         \"target\":[x,y,z],\"up\":[x,y,z],\"fov\":deg}},...]}}: {0}"
    )]
    Json(#[from] serde_json::Error),
    #[error("a camera path needs at least one keyframe")]
    Empty,
    #[error("camera path keyframe {index} (time {time} s): {problem}")]
    Keyframe {
        index: usize,
        time: f64,
        problem: KeyframeProblem,
    },
    #[error("orbit path needs a finite {what} > 0, got {value}")]
    BadOrbitParameter { what: &'static str, value: f64 },
    #[error("orbit path needs non-empty finite bounds, got min {min:?} max {max:?}")]
    BadBounds { min: [f64; 3], max: [f64; 3] },
}

impl PathError {
    fn in_file(self, file: &Path) -> PathError {
        PathError::InFile {
            file: file.to_path_buf(),
            source: Box::new(self),
        }
    }
}

impl Keyframe {
    /// The pose of `camera` at `time` (for recording a path from the viewer).
    pub fn from_camera(time: f64, camera: &Camera) -> Keyframe {
        Keyframe {
            time,
            eye: camera.eye,
            target: camera.target,
            up: camera.up,
            fov: camera.fov_y_deg,
        }
    }

    fn check(&self) -> Result<(), KeyframeProblem> {
        let fields: [(&'static str, &[f64]); 5] = [
            ("time", std::slice::from_ref(&self.time)),
            ("eye", &self.eye),
            ("target", &self.target),
            ("up", &self.up),
            ("fov", std::slice::from_ref(&self.fov)),
        ];
        for (name, values) in fields {
            if values.iter().any(|v| !v.is_finite()) {
                return Err(KeyframeProblem::NotFinite(name));
            }
        }
        let dir = sub(self.target, self.eye);
        let dist = length(dir);
        if dist == 0.0 {
            return Err(KeyframeProblem::EyeIsTarget);
        }
        if !dist.is_finite() {
            return Err(KeyframeProblem::NotFinite("eye-to-target distance"));
        }
        if !(self.fov > 0.0 && self.fov < 180.0) {
            return Err(KeyframeProblem::BadFov(self.fov));
        }
        if length(cross(normalize(dir), unit(self.up))) < 1e-9 {
            return Err(KeyframeProblem::UpParallel);
        }
        Ok(())
    }
}

/// A camera flight through time, defined by keyframes (see the module docs for the JSON format).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    pub keyframes: Vec<Keyframe>,
}

impl CameraPath {
    /// Checks every rule of the format: at least one keyframe, all values finite, times
    /// strictly increasing, eye ≠ target, fov in (0, 180), up not parallel to the view.
    pub fn validate(&self) -> Result<(), PathError> {
        if self.keyframes.is_empty() {
            return Err(PathError::Empty);
        }
        let mut previous: Option<f64> = None;
        for (index, k) in self.keyframes.iter().enumerate() {
            let fail = |problem| PathError::Keyframe {
                index,
                time: k.time,
                problem,
            };
            k.check().map_err(fail)?;
            if let Some(previous) = previous {
                if k.time <= previous {
                    return Err(fail(KeyframeProblem::TimeNotIncreasing {
                        time: k.time,
                        previous,
                    }));
                }
            }
            previous = Some(k.time);
        }
        Ok(())
    }

    /// Parses and validates a path from its JSON text.
    pub fn from_json(text: &str) -> Result<CameraPath, PathError> {
        let path: CameraPath = serde_json::from_str(text)?;
        path.validate()?;
        Ok(path)
    }

    /// The JSON text of the path, one keyframe per line. Numbers are written in their shortest
    /// round-trip form; a non-finite value (only possible in an unvalidated path) is written as
    /// `null`, which `from_json` rejects.
    pub fn to_json(&self) -> String {
        let mut out = String::from("{\"keyframes\":[");
        for (i, k) in self.keyframes.iter().enumerate() {
            out.push_str(if i == 0 { "\n  " } else { ",\n  " });
            out.push_str(&format!(
                "{{\"time\":{},\"eye\":{},\"target\":{},\"up\":{},\"fov\":{}}}",
                json_number(k.time),
                json_vec3(k.eye),
                json_vec3(k.target),
                json_vec3(k.up),
                json_number(k.fov)
            ));
        }
        out.push_str("\n]}\n");
        out
    }

    /// Reads and validates a path file; errors name the file.
    pub fn load(file: &Path) -> Result<CameraPath, PathError> {
        let read_error = |source| PathError::Read {
            file: file.to_path_buf(),
            source,
        };
        let handle = std::fs::File::open(file).map_err(read_error)?;
        let mut text = String::new();
        // Reading one byte past the limit tells an over-long file from one exactly at it.
        handle
            .take(MAX_PATH_FILE_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(read_error)?;
        if text.len() as u64 > MAX_PATH_FILE_BYTES {
            return Err(PathError::TooLarge {
                file: file.to_path_buf(),
            });
        }
        CameraPath::from_json(&text).map_err(|e| e.in_file(file))
    }

    /// Validates the path, then writes it beside `file` and renames it into place, so readers
    /// never see a partial file.
    pub fn save(&self, file: &Path) -> Result<(), PathError> {
        self.validate().map_err(|e| e.in_file(file))?;
        let write_error = |source| PathError::Write {
            file: file.to_path_buf(),
            source,
        };
        let dir = file
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = file
            .file_name()
            .ok_or_else(|| {
                write_error(std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the path names no file",
                ))
            })?
            .to_string_lossy();
        let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
        let result = (|| -> std::io::Result<()> {
            let mut out = std::fs::File::create(&tmp)?;
            out.write_all(self.to_json().as_bytes())?;
            out.sync_all()?;
            std::fs::rename(&tmp, file)
        })();
        if result.is_err() {
            // Best effort: the temporary may not exist if creating it was what failed.
            let _ = std::fs::remove_file(&tmp);
        }
        result.map_err(write_error)
    }

    /// Time from the first to the last keyframe, in seconds (0 for fewer than two keyframes).
    pub fn duration(&self) -> f64 {
        match (self.keyframes.first(), self.keyframes.last()) {
            (Some(first), Some(last)) => last.time - first.time,
            _ => 0.0,
        }
    }

    /// The camera at time `t` (clamped to the path; NaN means the start), with near and far
    /// planes fitted to `near_far_from` (`Camera::fit_planes`). Bounds that are empty or not
    /// finite give planes around the target instead (distance / 1000 to distance · 1000).
    /// The result always passes `Camera::validate` for a validated path. An empty path (which
    /// `validate` rejects) yields `Camera::overview` of the bounds at 60°.
    pub fn camera_at(&self, t: f64, near_far_from: &Aabb) -> Camera {
        let keys = &self.keyframes;
        let (Some(first), Some(last)) = (keys.first(), keys.last()) else {
            return Camera::overview(near_far_from, ORBIT_FOV_WIDE);
        };
        // max/min instead of clamp: clamp panics on an unvalidated path whose ends are unordered.
        let t = if t.is_nan() {
            first.time
        } else {
            t.max(first.time).min(last.time)
        };
        if keys.len() == 1 {
            return finish(*first, first, first, 0.0, near_far_from);
        }
        // Segment [k, k+1] holding t; k ≤ len − 2 so both ends exist.
        let k = keys
            .partition_point(|key| key.time <= t)
            .saturating_sub(1)
            .min(keys.len() - 2);
        let (a, b) = (&keys[k], &keys[k + 1]);
        let h = b.time - a.time;
        let s = if h > 0.0 {
            ((t - a.time) / h).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let eye = hermite(
            a.eye,
            self.tangent(k, |f| f.eye),
            b.eye,
            self.tangent(k + 1, |f| f.eye),
            h,
            s,
        );
        let target = hermite(
            a.target,
            self.tangent(k, |f| f.target),
            b.target,
            self.tangent(k + 1, |f| f.target),
            h,
            s,
        );
        let pose = Keyframe {
            time: t,
            eye,
            target,
            up: normalize(lerp3(unit(a.up), unit(b.up), s)),
            fov: a.fov + (b.fov - a.fov) * s,
        };
        finish(pose, a, b, s, near_far_from)
    }

    /// Time-aware Catmull-Rom tangent (units per second) of one vector at keyframe `i`:
    /// central difference inside the path, one-sided at its ends.
    fn tangent(&self, i: usize, field: impl Fn(&Keyframe) -> [f64; 3]) -> [f64; 3] {
        let keys = &self.keyframes;
        let before = &keys[i.saturating_sub(1)];
        let after = &keys[(i + 1).min(keys.len() - 1)];
        let dt = after.time - before.time;
        if dt > 0.0 {
            let d = sub(field(after), field(before));
            [d[0] / dt, d[1] / dt, d[2] / dt]
        } else {
            [0.0; 3]
        }
    }

    /// `frames` cameras evenly spaced in time from the first to the last keyframe, both
    /// included (one frame: the first keyframe), computed lazily.
    pub fn cameras<'a>(
        &'a self,
        frames: u32,
        near_far_from: &'a Aabb,
    ) -> impl Iterator<Item = Camera> + 'a {
        let start = self.keyframes.first().map_or(0.0, |k| k.time);
        let step = if frames > 1 {
            self.duration() / f64::from(frames - 1)
        } else {
            0.0
        };
        (0..frames).map(move |i| self.camera_at(start + step * f64::from(i), near_far_from))
    }

    /// `frames` evenly spaced cameras (see `cameras`), for benchmarks with a fixed frame count.
    /// Allocates one `Camera` per frame: bound `frames` before calling with user input.
    pub fn sample(&self, frames: u32, near_far_from: &Aabb) -> Vec<Camera> {
        self.cameras(frames, near_far_from).collect()
    }

    /// The paper's evaluation path (§IV-B): one counter-clockwise orbit around the centre of
    /// `bounds` at 30° elevation and at the distance where a 60° vertical fov frames the whole
    /// bounding sphere, starting from the south-west, while the vertical fov zooms
    /// 60° → 15° → 60° twice per orbit (a cosine in the orbit angle). Keyframes are placed one
    /// per frame at `fps`, but no fewer than 64 and no more than 3600 per orbit.
    pub fn orbit(bounds: &Aabb, duration_s: f64, fps: f64) -> Result<CameraPath, PathError> {
        for (what, value) in [("duration", duration_s), ("frame rate", fps)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(PathError::BadOrbitParameter { what, value });
            }
        }
        let finite = bounds.min.iter().chain(&bounds.max).all(|v| v.is_finite());
        if bounds.is_empty() || !finite {
            return Err(PathError::BadBounds {
                min: bounds.min,
                max: bounds.max,
            });
        }
        let centre = bounds.center();
        let radius = (0.5 * bounds.diagonal()).max(1e-3);
        let distance = radius / (ORBIT_FOV_WIDE.to_radians() * 0.5).sin();
        let elevation = ORBIT_ELEVATION_DEG.to_radians();
        // The product may overflow to +inf; clamp then caps it.
        let segments = (duration_s * fps)
            .round()
            .clamp(ORBIT_MIN_KEYFRAMES, ORBIT_MAX_KEYFRAMES) as u32;
        let (mid, amplitude) = (
            0.5 * (ORBIT_FOV_WIDE + ORBIT_FOV_NARROW),
            0.5 * (ORBIT_FOV_WIDE - ORBIT_FOV_NARROW),
        );
        let keyframes = (0..=segments)
            .map(|i| {
                let u = f64::from(i) / f64::from(segments);
                let azimuth = ORBIT_START_AZIMUTH_DEG.to_radians() + std::f64::consts::TAU * u;
                let dir = [
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                ];
                let zoom = (std::f64::consts::TAU * ORBIT_ZOOM_CYCLES * u).cos();
                Keyframe {
                    time: duration_s * u,
                    eye: [
                        centre[0] + dir[0] * distance,
                        centre[1] + dir[1] * distance,
                        centre[2] + dir[2] * distance,
                    ],
                    target: centre,
                    up: Z_UP,
                    fov: (mid + amplitude * zoom).clamp(ORBIT_FOV_NARROW, ORBIT_FOV_WIDE),
                }
            })
            .collect();
        let path = CameraPath { keyframes };
        // Catches durations so small that keyframe times underflow into duplicates.
        path.validate()?;
        Ok(path)
    }
}

fn json_number(v: f64) -> String {
    if v.is_finite() {
        // Debug prints the shortest round-trip form ("60.0", "1e-7"), all valid JSON numbers.
        format!("{v:?}")
    } else {
        "null".to_string()
    }
}

fn json_vec3(v: [f64; 3]) -> String {
    format!(
        "[{},{},{}]",
        json_number(v[0]),
        json_number(v[1]),
        json_number(v[2])
    )
}

/// `v` normalised, scaled by its largest component first so that huge finite vectors do not
/// overflow to a zero result; the zero vector stays zero.
fn unit(v: [f64; 3]) -> [f64; 3] {
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if largest > 0.0 {
        normalize(v.map(|x| x / largest))
    } else {
        v
    }
}

fn lerp3(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * s,
        a[1] + (b[1] - a[1]) * s,
        a[2] + (b[2] - a[2]) * s,
    ]
}

/// Cubic Hermite between p0 (tangent m0) and p1 (tangent m1) over an interval of `h` seconds;
/// s = 0 and s = 1 return p0 and p1 exactly.
fn hermite(p0: [f64; 3], m0: [f64; 3], p1: [f64; 3], m1: [f64; 3], h: f64, s: f64) -> [f64; 3] {
    let (s2, s3) = (s * s, s * s * s);
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = s3 - 2.0 * s2 + s;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = s3 - s2;
    std::array::from_fn(|i| h00 * p0[i] + h10 * h * m0[i] + h01 * p1[i] + h11 * h * m1[i])
}

/// Builds a valid camera from `pose`, interpolated at `s` between keyframes `a` and `b`:
/// repairs a vanished view direction or up vector (possible between keyframes that swap eye and
/// target or roll by 180°), then fits the planes.
fn finish(pose: Keyframe, a: &Keyframe, b: &Keyframe, s: f64, near_far_from: &Aabb) -> Camera {
    let Keyframe {
        eye,
        mut target,
        up,
        fov,
        ..
    } = pose;
    if length(sub(target, eye)) == 0.0 {
        let (dir_a, dir_b) = (
            normalize(sub(a.target, a.eye)),
            normalize(sub(b.target, b.eye)),
        );
        let blended = normalize(lerp3(dir_a, dir_b, s));
        let dir = if length(blended) > 0.5 {
            blended
        } else {
            dir_a
        };
        let dist_a = length(sub(a.target, a.eye));
        let dist = dist_a + (length(sub(b.target, b.eye)) - dist_a) * s;
        target = [
            eye[0] + dir[0] * dist,
            eye[1] + dir[1] * dist,
            eye[2] + dir[2] * dist,
        ];
    }
    let view = normalize(sub(target, eye));
    let up = [unit(up), unit(a.up), unit(b.up)]
        .into_iter()
        .map(|u| orthogonal_part(u, view))
        .find(|u| length(*u) > 1e-6)
        .unwrap_or_else(|| any_perpendicular(view));
    let mut camera = Camera {
        eye,
        target,
        up: normalize(up),
        fov_y_deg: fov,
        near: 0.0,
        far: 0.0,
    };
    let finite = near_far_from
        .min
        .iter()
        .chain(&near_far_from.max)
        .all(|v| v.is_finite());
    if !near_far_from.is_empty() && finite {
        camera.fit_planes(near_far_from);
    } else {
        let dist = length(sub(target, eye));
        camera.near = dist * 1e-3;
        camera.far = dist * 1e3;
    }
    camera
}

/// The component of `v` perpendicular to the unit vector `n`.
fn orthogonal_part(v: [f64; 3], n: [f64; 3]) -> [f64; 3] {
    let d = dot(v, n);
    [v[0] - d * n[0], v[1] - d * n[1], v[2] - d * n[2]]
}

/// Some unit vector perpendicular to the unit vector `n`: crossed with the axis it is least
/// aligned with, so the cross product is never small.
fn any_perpendicular(n: [f64; 3]) -> [f64; 3] {
    let axis = if n[0].abs() <= n[1].abs() && n[0].abs() <= n[2].abs() {
        [1.0, 0.0, 0.0]
    } else if n[1].abs() <= n[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    normalize(cross(n, axis))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::transform;

    fn key(time: f64, eye: [f64; 3], target: [f64; 3], fov: f64) -> Keyframe {
        Keyframe {
            time,
            eye,
            target,
            up: Z_UP,
            fov,
        }
    }

    fn three_keys() -> CameraPath {
        CameraPath {
            keyframes: vec![
                key(0.0, [100.0, 0.0, 50.0], [0.0, 0.0, 0.0], 60.0),
                key(2.5, [0.0, 100.0, 50.0], [1.0, 2.0, 0.5], 30.0),
                key(4.0, [-80.0, 10.0, 20.0], [0.0, 0.0, 0.0], 45.0),
            ],
        }
    }

    fn bounds() -> Aabb {
        Aabb {
            min: [500_000.0, 4_100_000.0, 100.0],
            max: [501_000.0, 4_100_600.0, 180.0],
        }
    }

    fn small_bounds() -> Aabb {
        Aabb {
            min: [-10.0, -10.0, -1.0],
            max: [10.0, 10.0, 1.0],
        }
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pointlet-path-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn keyframe_problem(path: &CameraPath) -> (usize, KeyframeProblem) {
        match path.validate() {
            Err(PathError::Keyframe { index, problem, .. }) => (index, problem),
            other => panic!("expected a keyframe problem, got {other:?}"),
        }
    }

    #[test]
    fn json_round_trip_is_exact() {
        let path = three_keys();
        let text = path.to_json();
        assert_eq!(CameraPath::from_json(&text).unwrap(), path);
        // The serde form agrees with the hand-written one.
        let via_serde = serde_json::to_string(&path).unwrap();
        assert_eq!(CameraPath::from_json(&via_serde).unwrap(), path);

        let orbit = CameraPath::orbit(&bounds(), 10.0, 30.0).unwrap();
        let back = CameraPath::from_json(&orbit.to_json()).unwrap();
        assert_eq!(back.keyframes.len(), orbit.keyframes.len());
        for (x, y) in back.keyframes.iter().zip(&orbit.keyframes) {
            for (u, v) in x.eye.iter().zip(&y.eye) {
                assert!((u - v).abs() <= 1e-15 * v.abs(), "{u} vs {v}");
            }
            assert_eq!(x.target, y.target);
        }
    }

    #[test]
    fn documented_example_parses_and_up_defaults_to_z() {
        let text = r#"{"keyframes":[
            {"time":0,"eye":[100,0,50],"target":[0,0,0],"up":[0,0,1],"fov":60},
            {"time":2.5,"eye":[0,100,50],"target":[0,0,0],"fov":30}
        ]}"#;
        let path = CameraPath::from_json(text).unwrap();
        assert_eq!(path.keyframes.len(), 2);
        assert_eq!(path.keyframes[1].up, [0.0, 0.0, 1.0]);
        assert_eq!(path.duration(), 2.5);
    }

    #[test]
    fn validation_errors() {
        assert!(matches!(
            CameraPath::from_json(r#"{"keyframes":[]}"#),
            Err(PathError::Empty)
        ));
        let e = CameraPath::from_json(
            r#"{"keyframes":[{"time":0,"eye":[1,0,0],"target":[0,0,0],"fov":60,"zoom":2}]}"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("zoom"), "{e}");
        let e = CameraPath::from_json("{\"keyframes\":[{\"time\":0}").unwrap_err();
        assert!(matches!(e, PathError::Json(_)), "{e}");

        let mut p = three_keys();
        p.keyframes[2].time = 2.5;
        assert_eq!(
            keyframe_problem(&p),
            (
                2,
                KeyframeProblem::TimeNotIncreasing {
                    time: 2.5,
                    previous: 2.5
                }
            )
        );
        let mut p = three_keys();
        p.keyframes[1].time = -1.0;
        assert!(matches!(
            keyframe_problem(&p),
            (1, KeyframeProblem::TimeNotIncreasing { .. })
        ));
        let mut p = three_keys();
        p.keyframes[0].eye[1] = f64::NAN;
        assert_eq!(keyframe_problem(&p), (0, KeyframeProblem::NotFinite("eye")));
        let mut p = three_keys();
        p.keyframes[2].time = f64::INFINITY;
        assert_eq!(
            keyframe_problem(&p),
            (2, KeyframeProblem::NotFinite("time"))
        );
        let mut p = three_keys();
        p.keyframes[1].target = p.keyframes[1].eye;
        assert_eq!(keyframe_problem(&p), (1, KeyframeProblem::EyeIsTarget));
        let mut p = three_keys();
        p.keyframes[0].eye = [1e308, 0.0, 0.0];
        p.keyframes[0].target = [-1e308, 0.0, 0.0];
        assert!(matches!(
            keyframe_problem(&p),
            (0, KeyframeProblem::NotFinite(_))
        ));
        for fov in [0.0, 180.0, -5.0] {
            let mut p = three_keys();
            p.keyframes[1].fov = fov;
            assert_eq!(keyframe_problem(&p), (1, KeyframeProblem::BadFov(fov)));
        }
        let mut p = three_keys();
        p.keyframes[0].up = [-2.0, 0.0, -1.0]; // along eye − target: parallel to the view
        assert_eq!(keyframe_problem(&p), (0, KeyframeProblem::UpParallel));
        let mut p = three_keys();
        p.keyframes[0].up = [0.0, 1e300, 1e300];
        p.validate().unwrap();
        let c = p.camera_at(0.0, &small_bounds());
        c.validate().unwrap();
        assert!(
            c.up[1] > 0.1 && c.up[2] > 0.1,
            "the given up is kept: {:?}",
            c.up
        );
        p.keyframes[0].up = [0.0; 3];
        assert_eq!(keyframe_problem(&p), (0, KeyframeProblem::UpParallel));

        let msg = PathError::Keyframe {
            index: 1,
            time: 2.5,
            problem: KeyframeProblem::BadFov(190.0),
        }
        .to_string();
        assert_eq!(
            msg,
            "camera path keyframe 1 (time 2.5 s): fov 190° must lie in (0, 180)"
        );
    }

    #[test]
    fn save_and_load_name_the_file() {
        let dir = temp_dir("io");
        let file = dir.join("flight.json");
        let path = three_keys();
        path.save(&file).unwrap();
        assert_eq!(CameraPath::load(&file).unwrap(), path);
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(leftovers.len(), 1, "no temporary left: {leftovers:?}");

        let bad = dir.join("bad.json");
        std::fs::write(
            &bad,
            r#"{"keyframes":[{"time":0,"eye":[0,0,0],"target":[0,0,0],"fov":60}]}"#,
        )
        .unwrap();
        let e = CameraPath::load(&bad).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("bad.json") && msg.contains("eye and target coincide"),
            "{msg}"
        );

        let missing = dir.join("missing.json");
        let msg = CameraPath::load(&missing).unwrap_err().to_string();
        assert!(
            msg.contains("cannot read camera path") && msg.contains("missing.json"),
            "{msg}"
        );

        let invalid = CameraPath { keyframes: vec![] };
        let out = dir.join("empty.json");
        let msg = invalid.save(&out).unwrap_err().to_string();
        assert!(
            msg.contains("empty.json") && msg.contains("at least one keyframe"),
            "{msg}"
        );
        assert!(!out.exists(), "an invalid path is not written");

        let msg = path
            .save(&dir.join("no-such-dir").join("p.json"))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("cannot write camera path") && msg.contains("p.json"),
            "{msg}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn interpolation_passes_through_keyframes_exactly() {
        let path = three_keys();
        for k in &path.keyframes {
            let c = path.camera_at(k.time, &small_bounds());
            assert_eq!(c.eye, k.eye);
            assert_eq!(c.target, k.target);
            assert_eq!(c.fov_y_deg, k.fov);
            c.validate().unwrap();
            // Up is re-orthogonalised: perpendicular to the view, in the plane of view and z.
            let view = normalize(sub(k.target, k.eye));
            assert!(dot(c.up, view).abs() < 1e-12);
            assert!((length(c.up) - 1.0).abs() < 1e-12);
            assert!(dot(c.up, cross(view, Z_UP)).abs() < 1e-12);
            assert!(c.up[2] > 0.0);
        }
    }

    #[test]
    fn interpolation_is_continuous_and_smooth() {
        let path = three_keys();
        let b = small_bounds();
        let dt = 1e-4;
        let steps = (path.duration() / dt) as u32;
        let mut prev = path.camera_at(0.0, &b);
        let mut max_step: f64 = 0.0;
        for i in 1..=steps {
            let c = path.camera_at(f64::from(i) * dt, &b);
            c.validate().unwrap();
            max_step = max_step.max(length(sub(c.eye, prev.eye)));
            assert!((c.fov_y_deg - prev.fov_y_deg).abs() < 0.01);
            prev = c;
        }
        // Speeds are ~100 units/s, so a 0.1 ms step moves ~0.01 units; a jump would show.
        assert!(max_step < 0.2, "largest step {max_step}");
        // C¹ at the inner keyframe: velocities just before and after agree.
        let t = path.keyframes[1].time;
        let velocity = |t0: f64, t1: f64| {
            let d = sub(path.camera_at(t1, &b).eye, path.camera_at(t0, &b).eye);
            d.map(|v| v / (t1 - t0))
        };
        let (before, after) = (velocity(t - 1e-6, t), velocity(t, t + 1e-6));
        assert!(
            length(sub(before, after)) < 1e-2 * length(before),
            "{before:?} {after:?}"
        );
    }

    #[test]
    fn times_outside_the_path_clamp_to_its_ends() {
        let path = three_keys();
        let b = small_bounds();
        assert_eq!(path.camera_at(-5.0, &b), path.camera_at(0.0, &b));
        assert_eq!(path.camera_at(f64::NAN, &b), path.camera_at(0.0, &b));
        assert_eq!(path.camera_at(1e9, &b), path.camera_at(4.0, &b));
        let single = CameraPath {
            keyframes: vec![path.keyframes[1]],
        };
        let c = single.camera_at(7.0, &b);
        assert_eq!(
            (c.eye, c.target),
            (path.keyframes[1].eye, path.keyframes[1].target)
        );
        assert_eq!(single.duration(), 0.0);
        let mut huge_up = single.clone();
        huge_up.keyframes[0].up = [1e300, 0.0, 1e300];
        let c = huge_up.camera_at(0.0, &b);
        c.validate().unwrap();
        assert!(c.up[2] > 0.5, "{:?}", c.up);
        // Empty path: documented fallback, no panic.
        let c = CameraPath::default().camera_at(1.0, &b);
        c.validate().unwrap();
    }

    #[test]
    fn degenerate_interpolation_still_gives_valid_cameras() {
        // Eye and target swap places: at the midpoint they coincide on the spline.
        let swap = CameraPath {
            keyframes: vec![
                key(0.0, [10.0, 0.0, 0.0], [-10.0, 0.0, 0.0], 60.0),
                key(1.0, [-10.0, 0.0, 0.0], [10.0, 0.0, 0.0], 60.0),
            ],
        };
        swap.validate().unwrap();
        let mid = swap.camera_at(0.5, &small_bounds());
        mid.validate().unwrap();
        // A 180° roll: the linear blend of the ups vanishes halfway.
        let mut roll = swap.clone();
        roll.keyframes[1] = Keyframe {
            up: [0.0, 0.0, -1.0],
            ..roll.keyframes[0]
        };
        roll.keyframes[1].time = 1.0;
        roll.validate().unwrap();
        for i in 0..=100 {
            roll.camera_at(f64::from(i) / 100.0, &small_bounds())
                .validate()
                .unwrap();
        }
        // Empty bounds: planes come from the eye–target distance.
        let c = swap.camera_at(0.0, &Aabb::EMPTY);
        c.validate().unwrap();
        assert_eq!((c.near, c.far), (20.0 * 1e-3, 20.0 * 1e3));
    }

    #[test]
    fn sample_is_evenly_spaced_and_includes_both_ends() {
        let path = three_keys();
        let b = small_bounds();
        let cams = path.sample(9, &b);
        assert_eq!(cams.len(), 9);
        assert_eq!(cams[0], path.camera_at(0.0, &b));
        assert_eq!(cams[4], path.camera_at(2.0, &b));
        assert_eq!(cams[8], path.camera_at(4.0, &b));
        assert!(path.sample(0, &b).is_empty());
        assert_eq!(path.sample(1, &b), vec![path.camera_at(0.0, &b)]);
    }

    #[test]
    fn orbit_circles_the_centre_while_zooming() {
        let b = bounds();
        let centre = b.center();
        let path = CameraPath::orbit(&b, 20.0, 60.0).unwrap();
        assert_eq!(path.keyframes.len(), 1201, "one keyframe per frame");
        assert_eq!(path.duration(), 20.0);
        let start = path.camera_at(0.0, &b);
        let end = path.camera_at(20.0, &b);
        assert!(
            length(sub(start.eye, end.eye)) < 1e-6,
            "returns to its start"
        );
        assert_eq!(start.fov_y_deg, end.fov_y_deg);

        let radius = 0.5 * b.diagonal();
        let distance = radius / 30f64.to_radians().sin();
        let cams = path.sample(997, &b);
        let (mut fov_min, mut fov_max) = (f64::MAX, f64::MIN);
        let mut turned = 0.0;
        let mut prev_azimuth: Option<f64> = None;
        for c in &cams {
            c.validate().unwrap();
            let q = transform(&c.view_projection(16.0 / 9.0), centre);
            assert!(q[3] > 0.0, "centre in front of the eye");
            assert!(
                (q[0] / q[3]).abs() < 1e-6 && (q[1] / q[3]).abs() < 1e-6,
                "centre on axis"
            );
            assert!(
                q[2] / q[3] > 0.0 && q[2] / q[3] < 1.0,
                "centre within the planes"
            );
            let offset = sub(c.eye, centre);
            assert!((length(offset) - distance).abs() < 1e-6 * distance);
            let elevation = (offset[2] / length(offset)).asin().to_degrees();
            assert!((elevation - 30.0).abs() < 1e-6, "{elevation}");
            assert!((15.0..=60.0).contains(&c.fov_y_deg), "{}", c.fov_y_deg);
            fov_min = fov_min.min(c.fov_y_deg);
            fov_max = fov_max.max(c.fov_y_deg);
            let azimuth = offset[1].atan2(offset[0]);
            if let Some(p) = prev_azimuth {
                let mut d = azimuth - p;
                if d < -std::f64::consts::PI {
                    d += std::f64::consts::TAU;
                }
                assert!(d > 0.0, "counter-clockwise");
                turned += d;
            }
            prev_azimuth = Some(azimuth);
        }
        assert!(
            (turned - std::f64::consts::TAU).abs() < 1e-6,
            "one full turn: {turned}"
        );
        assert!(fov_min < 15.01 && fov_max > 59.99, "{fov_min} {fov_max}");
        // The zoom goes in and out twice: narrowest at a quarter and three quarters.
        assert!((path.camera_at(5.0, &b).fov_y_deg - 15.0).abs() < 1e-9);
        assert!((path.camera_at(10.0, &b).fov_y_deg - 60.0).abs() < 1e-9);
        assert!((path.camera_at(15.0, &b).fov_y_deg - 15.0).abs() < 1e-9);

        // At 60° the whole bounds are framed.
        let vp = start.view_projection(16.0 / 9.0);
        for k in 0..8 {
            let p = [
                if k & 1 == 0 { b.min[0] } else { b.max[0] },
                if k & 2 == 0 { b.min[1] } else { b.max[1] },
                if k & 4 == 0 { b.min[2] } else { b.max[2] },
            ];
            let q = transform(&vp, p);
            assert!(q[3] > 0.0 && (q[0] / q[3]).abs() <= 1.0 && (q[1] / q[3]).abs() <= 1.0);
        }
    }

    #[test]
    fn orbit_keyframe_count_is_bounded_and_parameters_checked() {
        let b = bounds();
        assert_eq!(CameraPath::orbit(&b, 1.0, 1.0).unwrap().keyframes.len(), 65);
        assert_eq!(
            CameraPath::orbit(&b, 1e6, 1e6).unwrap().keyframes.len(),
            3601
        );
        assert_eq!(
            CameraPath::orbit(&b, f64::MAX, f64::MAX)
                .unwrap()
                .keyframes
                .len(),
            3601
        );
        for (d, f) in [
            (0.0, 60.0),
            (-1.0, 60.0),
            (f64::NAN, 60.0),
            (10.0, 0.0),
            (10.0, f64::INFINITY),
        ] {
            let e = CameraPath::orbit(&b, d, f).unwrap_err();
            assert!(matches!(e, PathError::BadOrbitParameter { .. }), "{e}");
        }
        assert!(matches!(
            CameraPath::orbit(&Aabb::EMPTY, 10.0, 60.0),
            Err(PathError::BadBounds { .. })
        ));
        // Keyframe times that underflow into duplicates are caught, not returned.
        assert!(CameraPath::orbit(&b, 5e-324, 1.0).is_err());
        // A single point still gets a valid orbit.
        let point = Aabb {
            min: [3.0, 4.0, 5.0],
            max: [3.0, 4.0, 5.0],
        };
        let p = CameraPath::orbit(&point, 4.0, 30.0).unwrap();
        for c in p.sample(50, &point) {
            c.validate().unwrap();
        }
    }

    #[test]
    fn recorded_keyframes_reproduce_the_camera() {
        let cam = Camera::overview(&bounds(), 50.0);
        let k = Keyframe::from_camera(1.5, &cam);
        let path = CameraPath { keyframes: vec![k] };
        path.validate().unwrap();
        let back = path.camera_at(1.5, &bounds());
        assert_eq!(
            (back.eye, back.target, back.fov_y_deg),
            (cam.eye, cam.target, 50.0)
        );
    }
}
