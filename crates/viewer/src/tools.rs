//! The viewer's tools as plain state: measuring between picked points, camera bookmarks and
//! the camera-path recorder (writes the JSON that `pointlet bench` reads).

use pointlet_core::camera::{length, sub};
use pointlet_core::path::{CameraPath, Keyframe, PathError};
use pointlet_core::Camera;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Distance between two picked points (exact stored coordinates, not pixel positions).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measure {
    points: Vec<[f64; 3]>,
}

impl Measure {
    /// Adds a picked point; a third pick starts a new measurement.
    pub fn add(&mut self, p: [f64; 3]) {
        if self.points.len() == 2 {
            self.points.clear();
        }
        self.points.push(p);
    }

    pub fn clear(&mut self) {
        self.points.clear();
    }

    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// Straight-line distance once both points are picked.
    pub fn distance(&self) -> Option<f64> {
        match self.points.as_slice() {
            [a, b] => Some(length(sub(*b, *a))),
            _ => None,
        }
    }

    /// Horizontal (xy) distance and height difference (second minus first).
    pub fn components(&self) -> Option<(f64, f64)> {
        match self.points.as_slice() {
            [a, b] => Some((
                ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt(),
                b[2] - a[2],
            )),
            _ => None,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bookmark {
    pub name: String,
    pub camera: Camera,
}

#[derive(Debug, thiserror::Error)]
pub enum BookmarkError {
    #[error("cannot read bookmarks {}: {source}", file.display())]
    Read {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write bookmarks {}: {source}", file.display())]
    Write {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("bookmarks {} are not valid: {message}", file.display())]
    Invalid { file: PathBuf, message: String },
}

/// Saved views, in the order they were added (keys 1–9 recall the first nine).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Bookmarks {
    pub list: Vec<Bookmark>,
}

/// Bookmark files are tiny; anything larger is the wrong file.
const MAX_BOOKMARK_FILE_BYTES: u64 = 16 << 20;

impl Bookmarks {
    /// Adds `camera` under a generated name, which is returned.
    pub fn add(&mut self, camera: Camera) -> String {
        let name = format!("view {}", self.list.len() + 1);
        self.list.push(Bookmark {
            name: name.clone(),
            camera,
        });
        name
    }

    pub fn get(&self, index: usize) -> Option<&Camera> {
        self.list.get(index).map(|b| &b.camera)
    }

    pub fn remove(&mut self, index: usize) {
        if index < self.list.len() {
            self.list.remove(index);
        }
    }

    pub fn to_json(&self) -> String {
        // Serializing plain structs of finite floats and strings cannot fail; an empty list is
        // the harmless fallback if it ever did.
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "{\"list\":[]}".into())
    }

    /// Reads bookmarks; every camera must be valid.
    pub fn load(file: &Path) -> Result<Bookmarks, BookmarkError> {
        let read = |source| BookmarkError::Read {
            file: file.to_path_buf(),
            source,
        };
        let len = std::fs::metadata(file).map_err(read)?.len();
        if len > MAX_BOOKMARK_FILE_BYTES {
            return Err(BookmarkError::Invalid {
                file: file.to_path_buf(),
                message: format!("{len} bytes is more than a bookmark file holds"),
            });
        }
        let text = std::fs::read_to_string(file).map_err(read)?;
        let invalid = |message: String| BookmarkError::Invalid {
            file: file.to_path_buf(),
            message,
        };
        let marks: Bookmarks = serde_json::from_str(&text).map_err(|e| invalid(e.to_string()))?;
        for b in &marks.list {
            b.camera
                .validate()
                .map_err(|e| invalid(format!("'{}': {e}", b.name)))?;
        }
        Ok(marks)
    }

    pub fn save(&self, file: &Path) -> Result<(), BookmarkError> {
        std::fs::write(file, self.to_json()).map_err(|source| BookmarkError::Write {
            file: file.to_path_buf(),
            source,
        })
    }
}

/// Records the flown camera as keyframes: one whenever the camera changed and at least
/// `interval` seconds passed since the last one, so still periods add no keyframes and the
/// replayed path spends the same time moving as the flight did.
#[derive(Clone, Debug)]
pub struct PathRecorder {
    interval: f64,
    /// Clock reading of the first keyframe; `None` while not recording.
    start: Option<f64>,
    /// Seconds spent still (subtracted so that pauses do not become slow motion).
    paused: f64,
    last: Option<(f64, Camera)>,
    path: CameraPath,
}

impl PathRecorder {
    pub fn new(interval: f64) -> Self {
        Self {
            interval: interval.max(1e-3),
            start: None,
            paused: 0.0,
            last: None,
            path: CameraPath::default(),
        }
    }

    pub fn recording(&self) -> bool {
        self.start.is_some()
    }

    pub fn keyframes(&self) -> usize {
        self.path.keyframes.len()
    }

    /// Starts a new recording at clock time `now` with `camera` as the first keyframe.
    pub fn start(&mut self, now: f64, camera: &Camera) {
        self.path = CameraPath {
            keyframes: vec![Keyframe::from_camera(0.0, camera)],
        };
        self.start = Some(now);
        self.paused = 0.0;
        self.last = Some((now, *camera));
    }

    /// Offers the camera at clock time `now` (call every frame while recording).
    pub fn sample(&mut self, now: f64, camera: &Camera) {
        let (Some(start), Some((last_t, last_cam))) = (self.start, self.last) else {
            return;
        };
        let since = now - last_t;
        if since.is_nan() || since < self.interval {
            return;
        }
        if *camera == last_cam {
            // A still camera: the pause is cut from the path's time line.
            self.paused += since;
            self.last = Some((now, last_cam));
            return;
        }
        let time = now - start - self.paused;
        let previous = self.path.keyframes.last().map_or(f64::MIN, |k| k.time);
        if time > previous {
            self.path
                .keyframes
                .push(Keyframe::from_camera(time, camera));
        }
        self.last = Some((now, *camera));
    }

    /// Ends the recording and returns the path (at least the first keyframe).
    pub fn stop(&mut self) -> CameraPath {
        self.start = None;
        self.last = None;
        std::mem::take(&mut self.path)
    }

    /// Stops and writes the path to `file` in the JSON format of `pointlet_core::path`.
    pub fn save(&mut self, file: &Path) -> Result<CameraPath, PathError> {
        let path = self.stop();
        path.save(file)?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(x: f64) -> Camera {
        Camera {
            eye: [x, -100.0, 50.0],
            target: [x, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y_deg: 60.0,
            near: 0.1,
            far: 1000.0,
        }
    }

    #[test]
    fn measure_two_points_then_restart() {
        let mut m = Measure::default();
        m.add([500_000.0, 4_000_000.0, 10.0]);
        assert_eq!(m.distance(), None);
        m.add([500_003.0, 4_000_004.0, 22.0]);
        assert_eq!(m.distance(), Some(13.0));
        assert_eq!(m.components(), Some((5.0, 12.0)));
        m.add([1.0, 2.0, 3.0]);
        assert_eq!(m.points(), &[[1.0, 2.0, 3.0]]);
    }

    #[test]
    fn bookmarks_round_trip_and_reject_bad_cameras() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("marks.json");
        let mut b = Bookmarks::default();
        b.add(cam(1.0));
        b.add(cam(2.0));
        b.save(&file).expect("save");
        let back = Bookmarks::load(&file).expect("load");
        assert_eq!(back, b);
        assert_eq!(back.get(1), Some(&cam(2.0)));
        let mut bad = b.clone();
        bad.list[0].camera.fov_y_deg = 0.0;
        bad.save(&file).expect("save");
        let err = Bookmarks::load(&file).expect_err("invalid camera");
        assert!(err.to_string().contains("marks.json"), "{err}");
        std::fs::write(&file, "not json").expect("write");
        assert!(Bookmarks::load(&file).is_err());
    }

    #[test]
    fn recorder_skips_still_time_and_writes_a_loadable_path() {
        let mut r = PathRecorder::new(0.1);
        r.start(10.0, &cam(0.0));
        r.sample(10.05, &cam(1.0)); // too soon
        r.sample(10.2, &cam(1.0));
        r.sample(10.4, &cam(1.0)); // still: 0.2 s paused
        r.sample(11.0, &cam(1.0)); // still: 0.6 s more
        r.sample(11.2, &cam(2.0));
        assert_eq!(r.keyframes(), 3);
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("flight.json");
        let path = r.save(&file).expect("save");
        assert!(!r.recording());
        let times: Vec<f64> = path.keyframes.iter().map(|k| k.time).collect();
        assert!(
            (times[1] - 0.2).abs() < 1e-9 && (times[2] - 0.4).abs() < 1e-9,
            "{times:?}"
        );
        let loaded = CameraPath::load(&file).expect("bench can read it");
        assert_eq!(loaded, path);
    }
}
