//! Progress bars only when a person is watching (stderr is a terminal), and point rates as
//! people read them.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;

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
