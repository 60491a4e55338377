//! Frame-time statistics (Table II of the virtualized paper) and per-stage breakdowns (Fig. 15).

use crate::ReportError;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Summary of a run's frame times.
///
/// Definitions, for n frames with times tᵢ in milliseconds:
/// - `avg_fps` = n / (Σ tᵢ / 1000): frames per second of wall time spent rendering (not the
///   mean of per-frame FPS, which over-weights fast frames);
/// - `min_fps` = 1000 / max tᵢ (the slowest frame), `max_fps` = 1000 / min tᵢ (the fastest);
/// - `low_1pct_fps` ("1 % low") = the average FPS over the slowest 1 % of frames: the
///   k = ⌈n / 100⌉ slowest frames (at least one), k / (Σ of their tᵢ / 1000);
///   `low_01pct_fps` ("0.1 % low") the same with k = ⌈n / 1000⌉;
/// - `median_ms`: the middle time, or the mean of the two middle times for even n;
/// - `p99_ms` / `p999_ms`: the nearest-rank 99th / 99.9th percentile frame time, i.e. the
///   smallest tᵢ such that at least 99 % / 99.9 % of frames take no longer: with times sorted
///   ascending, the one at 1-based rank ⌈0.99 n⌉ / ⌈0.999 n⌉.
///
/// With no frames every field is 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameStats {
    pub frames: usize,
    pub total_ms: f64,
    pub avg_fps: f64,
    pub min_fps: f64,
    pub max_fps: f64,
    pub low_1pct_fps: f64,
    pub low_01pct_fps: f64,
    pub median_ms: f64,
    pub p99_ms: f64,
    pub p999_ms: f64,
}

impl FrameStats {
    /// Statistics of `times_ms` (one entry per frame, in milliseconds); every time must be a
    /// finite number > 0, since a zero or negative frame time has no FPS.
    pub fn from_frame_times_ms(times_ms: &[f64]) -> Result<FrameStats, ReportError> {
        if let Some((index, &ms)) = times_ms
            .iter()
            .enumerate()
            .find(|(_, ms)| !(ms.is_finite() && **ms > 0.0))
        {
            return Err(ReportError::BadFrameTime { index, ms });
        }
        let n = times_ms.len();
        let sorted = sorted(times_ms);
        let (Some(&fastest), Some(&slowest)) = (sorted.first(), sorted.last()) else {
            return Ok(FrameStats::default());
        };
        let total_ms: f64 = times_ms.iter().sum();
        // Average FPS over the k slowest frames (the tail of the ascending order).
        let low = |k: usize| {
            let tail = &sorted[n - k..];
            k as f64 * 1000.0 / tail.iter().sum::<f64>()
        };
        Ok(FrameStats {
            frames: n,
            total_ms,
            avg_fps: n as f64 * 1000.0 / total_ms,
            min_fps: 1000.0 / slowest,
            max_fps: 1000.0 / fastest,
            low_1pct_fps: low(n.div_ceil(100)),
            low_01pct_fps: low(n.div_ceil(1000)),
            median_ms: median_of_sorted(&sorted),
            p99_ms: nearest_rank(&sorted, 99, 100),
            p999_ms: nearest_rank(&sorted, 999, 1000),
        })
    }
}

impl fmt::Display for FrameStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} frames: avg {:.1} fps, min {:.1}, max {:.1}, 1% low {:.1}, 0.1% low {:.1}; \
             median {:.3} ms, p99 {:.3} ms, p99.9 {:.3} ms",
            self.frames,
            self.avg_fps,
            self.min_fps,
            self.max_fps,
            self.low_1pct_fps,
            self.low_01pct_fps,
            self.median_ms,
            self.p99_ms,
            self.p999_ms
        )
    }
}

/// A copy of `values` sorted ascending (callers have rejected NaN).
fn sorted(values: &[f64]) -> Vec<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v
}

/// Median of ascending values; 0 when empty.
fn median_of_sorted(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => sorted[n / 2],
        _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    }
}

/// Nearest-rank percentile num/den of ascending values (1-based rank ⌈n·num/den⌉); 0 when empty.
fn nearest_rank(sorted: &[f64], num: usize, den: usize) -> f64 {
    let rank = (sorted.len() * num).div_ceil(den);
    sorted.get(rank.saturating_sub(1)).copied().unwrap_or(0.0)
}

#[derive(Clone, Debug, PartialEq, Serialize)]
struct StageSeries {
    name: String,
    ms: Vec<f64>,
}

/// Per-frame times of named rendering stages (e.g. "lod", "residency", "upload", "raster",
/// "resolve"): one value per stage per frame. Serialises as
/// `{"stages":[{"name":"lod","ms":[0.4,0.5,...]},...]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageBreakdown {
    stages: Vec<StageSeries>,
}

/// One stage's times over all frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageSummary {
    pub name: String,
    pub avg_ms: f64,
    pub median_ms: f64,
    pub max_ms: f64,
}

impl StageBreakdown {
    /// An empty breakdown over the given stages, in display order (bottom to top when stacked).
    pub fn new<S: Into<String>>(
        names: impl IntoIterator<Item = S>,
    ) -> Result<StageBreakdown, ReportError> {
        let mut stages: Vec<StageSeries> = Vec::new();
        for name in names {
            let name = name.into();
            if stages.iter().any(|s| s.name == name) {
                return Err(ReportError::DuplicateStage(name));
            }
            stages.push(StageSeries {
                name,
                ms: Vec::new(),
            });
        }
        if stages.is_empty() {
            return Err(ReportError::NoStages);
        }
        Ok(StageBreakdown { stages })
    }

    /// Adds one frame: `ms[i]` is the time of stage i (finite, ≥ 0: a skipped stage takes 0).
    /// On error nothing is added.
    pub fn push_frame(&mut self, ms: &[f64]) -> Result<(), ReportError> {
        let frame = self.frames();
        if ms.len() != self.stages.len() {
            return Err(ReportError::StageCount {
                frame,
                expected: self.stages.len(),
                got: ms.len(),
            });
        }
        if let Some((stage, &v)) = self
            .stages
            .iter()
            .zip(ms)
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        {
            return Err(ReportError::BadStageTime {
                frame,
                stage: stage.name.clone(),
                ms: v,
            });
        }
        for (stage, &v) in self.stages.iter_mut().zip(ms) {
            stage.ms.push(v);
        }
        Ok(())
    }

    pub fn frames(&self) -> usize {
        self.stages.first().map_or(0, |s| s.ms.len())
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.stages.iter().map(|s| s.name.as_str())
    }

    /// The per-frame times of one stage.
    pub fn stage_ms(&self, name: &str) -> Option<&[f64]> {
        self.stages
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.ms.as_slice())
    }

    /// Sum over stages, per frame.
    pub fn frame_totals_ms(&self) -> Vec<f64> {
        (0..self.frames())
            .map(|i| self.stages.iter().map(|s| s.ms[i]).sum())
            .collect()
    }

    /// Average, median and maximum time per stage (all 0 with no frames), in stage order.
    pub fn summary(&self) -> Vec<StageSummary> {
        self.stages
            .iter()
            .map(|s| {
                let sorted = sorted(&s.ms);
                let avg_ms = if s.ms.is_empty() {
                    0.0
                } else {
                    s.ms.iter().sum::<f64>() / s.ms.len() as f64
                };
                StageSummary {
                    name: s.name.clone(),
                    avg_ms,
                    median_ms: median_of_sorted(&sorted),
                    max_ms: sorted.last().copied().unwrap_or(0.0),
                }
            })
            .collect()
    }

    /// Per-stage series for plotting (x = frame index, y = ms), in stage order.
    pub(crate) fn series(&self) -> impl Iterator<Item = (&str, &[f64])> {
        self.stages
            .iter()
            .map(|s| (s.name.as_str(), s.ms.as_slice()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(1.0)
    }

    #[test]
    fn one_percent_low_is_the_slowest_percent_averaged() {
        let mut t = vec![10.0; 99];
        t.push(100.0);
        let s = FrameStats::from_frame_times_ms(&t).unwrap();
        assert_eq!(s.frames, 100);
        assert!(close(s.total_ms, 1090.0));
        assert!(close(s.avg_fps, 100.0 / 1.09), "{}", s.avg_fps);
        assert!(close(s.min_fps, 10.0));
        assert!(close(s.max_fps, 100.0));
        assert!(close(s.low_1pct_fps, 10.0));
        assert!(close(s.low_01pct_fps, 10.0));
        assert_eq!(s.median_ms, 10.0);
        assert_eq!(s.p99_ms, 10.0, "rank 99 of 100 is still a 10 ms frame");
        assert_eq!(s.p999_ms, 100.0, "rank ⌈99.9⌉ = 100");
    }

    #[test]
    fn lows_average_several_frames_when_there_are_many() {
        // 1000 frames: 980 of 5 ms, 10 of 20 ms, 10 of 40 ms. The 1 % (10 frames) are the
        // 40 ms ones: 25 fps; the 0.1 % is one 40 ms frame: 25 fps.
        let mut t = vec![5.0; 980];
        t.extend([20.0; 10]);
        t.extend([40.0; 10]);
        let s = FrameStats::from_frame_times_ms(&t).unwrap();
        assert!(close(s.low_1pct_fps, 25.0));
        assert!(close(s.low_01pct_fps, 25.0));
        assert_eq!(s.p99_ms, 20.0, "rank 990 is the last 20 ms frame");
        assert_eq!(s.p999_ms, 40.0);

        // 200 frames: 196 of 5 ms, then 20, 20, 40 and 50 ms. The 1 % (2 frames) are 50 and
        // 40 ms: 2 frames / 0.09 s; the 0.1 % (rounded up to 1 frame) is 50 ms: 20 fps.
        let mut t = vec![5.0; 196];
        t.extend([20.0, 20.0, 40.0, 50.0]);
        let s = FrameStats::from_frame_times_ms(&t).unwrap();
        assert!(close(s.low_1pct_fps, 2.0 / 0.09));
        assert!(close(s.low_01pct_fps, 20.0));
        assert!(close(s.min_fps, 20.0));
        assert_eq!(s.median_ms, 5.0);
        assert_eq!(s.p99_ms, 20.0, "rank 198 of 200");
    }

    #[test]
    fn median_of_even_count_averages_the_middle_pair() {
        let s = FrameStats::from_frame_times_ms(&[4.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(s.median_ms, 2.5);
        assert!(close(s.avg_fps, 4000.0 / 10.0));
        assert_eq!(s.p99_ms, 4.0);
    }

    #[test]
    fn zero_and_one_frames() {
        let s = FrameStats::from_frame_times_ms(&[]).unwrap();
        assert_eq!(s, FrameStats::default());
        let s = FrameStats::from_frame_times_ms(&[20.0]).unwrap();
        assert_eq!(s.frames, 1);
        for fps in [
            s.avg_fps,
            s.min_fps,
            s.max_fps,
            s.low_1pct_fps,
            s.low_01pct_fps,
        ] {
            assert!(close(fps, 50.0), "{fps}");
        }
        assert_eq!((s.median_ms, s.p99_ms, s.p999_ms), (20.0, 20.0, 20.0));
        assert!(s.to_string().starts_with("1 frames: avg 50.0 fps"), "{s}");
    }

    #[test]
    fn bad_frame_times_are_rejected() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = FrameStats::from_frame_times_ms(&[5.0, 5.0, bad]).unwrap_err();
            assert!(
                matches!(e, ReportError::BadFrameTime { index: 2, .. }),
                "{e}"
            );
        }
    }

    #[test]
    fn stage_breakdown_summaries() {
        let mut b = StageBreakdown::new(["lod", "raster", "resolve"]).unwrap();
        b.push_frame(&[1.0, 4.0, 0.5]).unwrap();
        b.push_frame(&[3.0, 6.0, 0.5]).unwrap();
        b.push_frame(&[2.0, 20.0, 0.0]).unwrap();
        assert_eq!(b.frames(), 3);
        assert_eq!(b.names().collect::<Vec<_>>(), ["lod", "raster", "resolve"]);
        assert_eq!(b.stage_ms("raster"), Some(&[4.0, 6.0, 20.0][..]));
        assert_eq!(b.stage_ms("upload"), None);
        assert_eq!(b.frame_totals_ms(), vec![5.5, 9.5, 22.0]);
        let s = b.summary();
        assert_eq!(s[0].name, "lod");
        assert_eq!((s[0].avg_ms, s[0].median_ms, s[0].max_ms), (2.0, 2.0, 3.0));
        assert_eq!(
            (s[1].avg_ms, s[1].median_ms, s[1].max_ms),
            (10.0, 6.0, 20.0)
        );
        assert!(close(s[2].avg_ms, 1.0 / 3.0));
        assert_eq!((s[2].median_ms, s[2].max_ms), (0.5, 0.5));

        let json = serde_json::to_string(&b).unwrap();
        assert_eq!(
            json,
            r#"{"stages":[{"name":"lod","ms":[1.0,3.0,2.0]},{"name":"raster","ms":[4.0,6.0,20.0]},{"name":"resolve","ms":[0.5,0.5,0.0]}]}"#
        );
        let summary_json = serde_json::to_string(&s[0]).unwrap();
        assert_eq!(
            summary_json,
            r#"{"name":"lod","avg_ms":2.0,"median_ms":2.0,"max_ms":3.0}"#
        );
        let back: StageSummary = serde_json::from_str(&summary_json).unwrap();
        assert_eq!(back, s[0]);
    }

    #[test]
    fn stage_breakdown_errors_leave_it_unchanged() {
        assert!(matches!(
            StageBreakdown::new(Vec::<String>::new()),
            Err(ReportError::NoStages)
        ));
        assert!(matches!(
            StageBreakdown::new(["a", "b", "a"]),
            Err(ReportError::DuplicateStage(n)) if n == "a"
        ));
        let mut b = StageBreakdown::new(["lod", "raster"]).unwrap();
        let e = b.push_frame(&[1.0]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "frame 0: got 1 stage times for the 2 stages of the breakdown"
        );
        let e = b.push_frame(&[1.0, f64::NAN]).unwrap_err();
        assert!(e.to_string().contains("\"raster\""), "{e}");
        assert!(b.push_frame(&[-0.5, 1.0]).is_err());
        assert_eq!(b.frames(), 0);
        assert_eq!(b.stage_ms("lod"), Some(&[][..]));
        let s = b.summary();
        assert_eq!((s[0].avg_ms, s[0].median_ms, s[0].max_ms), (0.0, 0.0, 0.0));
    }
}
