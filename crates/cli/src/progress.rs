//! Progress bars only when a person is watching (stderr is a terminal), and point rates as
//! people read them.

use indicatif::{ProgressBar, ProgressStyle};
use pointlet_store::{BuildPhase, BuildProgress};
use std::io::IsTerminal;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub fn bar(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    let style = ProgressStyle::with_template(
        "{msg:>10} [{bar:40}] {human_pos}/{human_len} ({rate}, {eta})",
    )
    .map(|s| {
        s.with_key(
            "rate",
            |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = w.write_str(&points_per_second(state.per_sec()));
            },
        )
    })
    .unwrap_or_else(|_| ProgressStyle::default_bar())
    .progress_chars("=> ");
    pb.set_style(style);
    pb.set_message(what.to_string());
    pb
}

/// The store builder's progress callback: a bar over the whole conversion with the stage, the
/// stage's points/s and the time left; none when no person watches.
pub fn build_bar() -> Option<Arc<dyn Fn(BuildProgress) + Send + Sync>> {
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let pb = ProgressBar::new(WHOLE);
    let style = ProgressStyle::with_template("{prefix:>8} [{bar:40}] {percent:>3}%  {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    pb.set_style(style);
    let overall = Mutex::new(Overall::new(Instant::now()));
    Some(Arc::new(move |p: BuildProgress| {
        // A poisoned lock only means an earlier update panicked; the bar is not worth another.
        let Ok(mut overall) = overall.lock() else {
            return;
        };
        let status = overall.update(p, Instant::now());
        pb.set_prefix(format!("{:?}", p.phase).to_lowercase());
        pb.set_position((status.fraction * WHOLE as f64).round() as u64);
        let rate = status.rate.map_or("…".into(), points_per_second);
        let left = status.left.map_or("…".into(), time_left);
        pb.set_message(format!("{rate}, {left} left"));
    }))
}

/// Steps of the whole-conversion bar.
const WHOLE: u64 = 1000;

/// Share of the whole conversion each stage takes, in [`stage`] order (reading, sorting,
/// writing): reading dominates.
const STAGE_SHARE: [f64; 3] = [0.6, 0.15, 0.25];

fn stage(phase: BuildPhase) -> usize {
    match phase {
        BuildPhase::Reading => 0,
        BuildPhase::Sorting => 1,
        BuildPhase::Writing => 2,
    }
}

/// Where the whole conversion stands after a report.
#[derive(Debug, PartialEq)]
struct Status {
    /// 0 to 1, never going back.
    fraction: f64,
    /// Points per second of the reported stage since it began.
    rate: Option<f64>,
    /// Time left for the whole conversion, at the pace so far.
    left: Option<Duration>,
}

/// Each stage's own progress, weighted by its share: stages may interleave (spills during
/// reading), and once writing starts every other stage is over.
struct Overall {
    started: Instant,
    done: [f64; 3],
    /// When each stage was first reported, and its count then.
    began: [Option<(Instant, u64)>; 3],
    fraction: f64,
}

impl Overall {
    fn new(started: Instant) -> Self {
        Overall {
            started,
            done: [0.0; 3],
            began: [None; 3],
            fraction: 0.0,
        }
    }

    fn update(&mut self, p: BuildProgress, now: Instant) -> Status {
        let i = stage(p.phase);
        let part = if p.total == 0 {
            1.0
        } else {
            (p.done as f64 / p.total as f64).min(1.0)
        };
        self.done[i] = self.done[i].max(part);
        if p.phase == BuildPhase::Writing {
            self.done[..i].fill(1.0);
        }
        let weighted: f64 = self.done.iter().zip(STAGE_SHARE).map(|(d, s)| d * s).sum();
        self.fraction = self.fraction.max(weighted.min(1.0));
        let (t0, done0) = *self.began[i].get_or_insert((now, p.done));
        let stage_secs = now.duration_since(t0).as_secs_f64();
        let rate = (stage_secs > 0.0).then(|| p.done.saturating_sub(done0) as f64 / stage_secs);
        let elapsed = now.duration_since(self.started).as_secs_f64();
        // Too early a guess swings wildly: wait for a second and a percent of the work.
        let left = (elapsed >= 1.0 && self.fraction >= 0.01)
            .then(|| Duration::from_secs_f64(elapsed * (1.0 - self.fraction) / self.fraction));
        Status {
            fraction: self.fraction,
            rate,
            left,
        }
    }
}

/// A duration as a clock reads it: `0:42`, `12:05`, `1:02:03`.
fn time_left(d: Duration) -> String {
    let s = d.as_secs_f64().round() as u64;
    match (s / 3600, s / 60 % 60, s % 60) {
        (0, m, s) => format!("{m}:{s:02}"),
        (h, m, s) => format!("{h}:{m:02}:{s:02}"),
    }
}

/// A rate of points with three significant digits and a unit: `1.63 M points/s`.
pub fn points_per_second(rate: f64) -> String {
    let (value, unit) = match rate {
        r if !r.is_finite() || r < 0.0 => return "? points/s".into(),
        r if r >= 1e9 => (r / 1e9, "G "),
        r if r >= 1e6 => (r / 1e6, "M "),
        r if r >= 1e3 => (r / 1e3, "k "),
        r => (r, ""),
    };
    let decimals = match value {
        v if v >= 100.0 => 0,
        v if v >= 10.0 => 1,
        _ => 2,
    };
    let decimals = if unit.is_empty() { 0 } else { decimals };
    format!("{value:.decimals$} {unit}points/s")
}

#[cfg(test)]
mod tests {
    use super::{BuildPhase, BuildProgress, Overall, Status};
    use std::time::{Duration, Instant};

    fn report(phase: BuildPhase, done: u64, total: u64) -> BuildProgress {
        BuildProgress { phase, done, total }
    }

    #[test]
    fn the_whole_conversion_advances_by_stage_shares() {
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        let mut o = Overall::new(t0);
        // Half the points read in 10 s: 30 % of the whole, so 23.3 s left.
        let s = o.update(report(BuildPhase::Reading, 0, 1000), t0);
        assert_eq!(s.rate, None);
        let s = o.update(report(BuildPhase::Reading, 500, 1000), at(10));
        assert!((s.fraction - 0.3).abs() < 1e-9, "{s:?}");
        assert_eq!(s.rate, Some(50.0));
        assert_eq!(s.left.map(|d| d.as_secs()), Some(23));
        // Sorting (in memory: nothing to report until it is over) counts its own share.
        o.update(report(BuildPhase::Reading, 1000, 1000), at(20));
        o.update(report(BuildPhase::Sorting, 0, 1000), at(20));
        let s = o.update(report(BuildPhase::Sorting, 1000, 1000), at(24));
        assert!((s.fraction - 0.75).abs() < 1e-9, "{s:?}");
        assert_eq!(s.rate, Some(250.0));
        // Writing takes the rest; the last report is the whole.
        let s = o.update(report(BuildPhase::Writing, 0, 1000), at(24));
        assert!((s.fraction - 0.75).abs() < 1e-9, "{s:?}");
        let s = o.update(report(BuildPhase::Writing, 1000, 1000), at(30));
        assert_eq!(
            s,
            Status {
                fraction: 1.0,
                rate: Some(1000.0 / 6.0),
                left: Some(Duration::ZERO)
            }
        );
    }

    #[test]
    fn interleaved_stages_never_move_the_bar_back() {
        let t0 = Instant::now();
        let mut o = Overall::new(t0);
        let mut last = 0.0;
        for (i, phase) in [BuildPhase::Reading, BuildPhase::Sorting]
            .into_iter()
            .cycle()
            .take(10)
            .enumerate()
        {
            let s = o.update(report(phase, i as u64 * 100, 1000), t0);
            assert!(s.fraction >= last, "{s:?} after {last}");
            last = s.fraction;
        }
        assert!(last < 0.75, "not past reading and sorting: {last}");
    }

    #[test]
    fn time_left_reads_as_a_clock() {
        let f = |s| super::time_left(Duration::from_secs_f64(s));
        assert_eq!(f(0.4), "0:00");
        assert_eq!(f(42.0), "0:42");
        assert_eq!(f(725.0), "12:05");
        assert_eq!(f(3723.0), "1:02:03");
    }

    #[test]
    fn rates_read_as_people_write_them() {
        let f = super::points_per_second;
        assert_eq!(f(1_633_913.521_1), "1.63 M points/s");
        assert_eq!(f(25_400.0), "25.4 k points/s");
        assert_eq!(f(999.6), "1000 points/s");
        assert_eq!(f(3.2e9), "3.20 G points/s");
        assert_eq!(f(f64::NAN), "? points/s");
    }
}
