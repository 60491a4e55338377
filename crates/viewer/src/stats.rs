//! Frame statistics for the stats panel: frame times (FPS and the graph) and when to read the
//! GPU's stage timings (reading them waits for the GPU, so it happens a few times a second,
//! not every frame).

use pointlet_gpu::FrameTiming;
use std::collections::VecDeque;

/// Frame times kept for the graph.
pub const HISTORY: usize = 240;
/// Seconds between two reads of the GPU timestamps.
const TIMING_PERIOD: f64 = 0.5;

/// Main-thread time of one frame's stages, in milliseconds: the overlay (egui layout and
/// tessellation), drawing (residency, encoding and submitting the frame) and presenting
/// (acquiring the surface texture, which waits for the display and the GPU, and the blit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CpuTimes {
    pub ui_ms: f64,
    pub draw_ms: f64,
    pub present_ms: f64,
}

#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// Seconds between consecutive frames, newest last.
    times: VecDeque<f64>,
    last_frame: Option<f64>,
    last_timing_read: Option<f64>,
    pub gpu: Option<FrameTiming>,
    pub frames: u64,
    pub cpu: CpuTimes,
    cpu_sum: CpuTimes,
    cpu_frames: u64,
}

impl FrameStats {
    /// Records a frame finished at clock time `now` (seconds).
    pub fn frame(&mut self, now: f64) {
        if let Some(prev) = self.last_frame {
            if self.times.len() == HISTORY {
                self.times.pop_front();
            }
            self.times.push_back((now - prev).max(0.0));
        }
        self.last_frame = Some(now);
        self.frames += 1;
    }

    /// Records the main thread's stage times of a frame.
    pub fn cpu_times(&mut self, t: CpuTimes) {
        self.cpu = t;
        self.cpu_sum.ui_ms += t.ui_ms;
        self.cpu_sum.draw_ms += t.draw_ms;
        self.cpu_sum.present_ms += t.present_ms;
        self.cpu_frames += 1;
    }

    /// Mean stage times over every recorded frame.
    pub fn cpu_mean(&self) -> Option<CpuTimes> {
        let n = self.cpu_frames as f64;
        (self.cpu_frames > 0).then(|| CpuTimes {
            ui_ms: self.cpu_sum.ui_ms / n,
            draw_ms: self.cpu_sum.draw_ms / n,
            present_ms: self.cpu_sum.present_ms / n,
        })
    }

    /// Forgets the time since the last frame (after idling: the gap is not a slow frame).
    pub fn idle(&mut self) {
        self.last_frame = None;
    }

    /// True when the GPU timings are due for a read at `now`.
    pub fn timing_due(&mut self, now: f64) -> bool {
        let due = self
            .last_timing_read
            .is_none_or(|t| now - t >= TIMING_PERIOD);
        if due {
            self.last_timing_read = Some(now);
        }
        due
    }

    pub fn frame_times(&self) -> impl Iterator<Item = f64> + '_ {
        self.times.iter().copied()
    }

    /// Mean frames per second over the history.
    pub fn fps(&self) -> Option<f64> {
        let total: f64 = self.times.iter().sum();
        (total > 0.0).then(|| self.times.len() as f64 / total)
    }

    /// Slowest frame of the history, in seconds.
    pub fn worst(&self) -> Option<f64> {
        self.times.iter().copied().reduce(f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fps_history_and_timing_cadence() {
        let mut s = FrameStats::default();
        assert_eq!(s.fps(), None);
        for k in 0..=HISTORY + 10 {
            s.frame(k as f64 * 0.02);
        }
        assert_eq!(s.frame_times().count(), HISTORY);
        assert!((s.fps().expect("fps") - 50.0).abs() < 1e-6);
        s.idle();
        s.frame(100.0);
        assert!(
            (s.worst().expect("worst") - 0.02).abs() < 1e-9,
            "idle gaps are not frames"
        );
        assert!(s.timing_due(1.0));
        assert!(!s.timing_due(1.2));
        assert!(s.timing_due(1.6));
        assert_eq!(s.cpu_mean(), None);
        let t = |ms| CpuTimes {
            ui_ms: ms,
            draw_ms: 2.0 * ms,
            present_ms: 3.0 * ms,
        };
        s.cpu_times(t(1.0));
        s.cpu_times(t(3.0));
        assert_eq!(s.cpu_mean(), Some(t(2.0)));
        assert_eq!(s.cpu, t(3.0));
    }
}
