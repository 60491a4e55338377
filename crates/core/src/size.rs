//! Human-written sizes: `512MiB`, `4GiB`, `100MB` (bytes) and `25M`, `1.5G` (counts).

use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
#[error("cannot parse size '{input}': {}", self.reason())]
pub struct SizeError {
    input: String,
    why: &'static str,
}

impl SizeError {
    /// The problem without the input, for a caller that shows the input itself (clap does).
    pub fn reason(&self) -> String {
        format!("{} (examples: 512MiB, 4GiB, 100MB, 25M)", self.why)
    }
}

/// Parses a byte size. Binary (KiB, MiB, GiB, TiB) and decimal (KB, MB, GB, TB) suffixes;
/// a bare number is bytes.
pub fn parse_bytes(s: &str) -> Result<u64, SizeError> {
    parse_with(
        s,
        &[
            ("kib", 1u64 << 10),
            ("mib", 1 << 20),
            ("gib", 1 << 30),
            ("tib", 1 << 40),
            ("kb", 1_000),
            ("mb", 1_000_000),
            ("gb", 1_000_000_000),
            ("tb", 1_000_000_000_000),
            ("k", 1 << 10),
            ("m", 1 << 20),
            ("g", 1 << 30),
            ("b", 1),
        ],
    )
}

/// Parses a count: `25M` = 25 000 000, `1G`/`1B` = 10^9, `100k`.
pub fn parse_count(s: &str) -> Result<u64, SizeError> {
    parse_with(
        s,
        &[
            ("k", 1_000u64),
            ("m", 1_000_000),
            ("g", 1_000_000_000),
            ("b", 1_000_000_000),
        ],
    )
}

fn parse_with(s: &str, units: &[(&str, u64)]) -> Result<u64, SizeError> {
    let err = |why| SizeError {
        input: s.to_string(),
        why,
    };
    let t = s.trim().to_ascii_lowercase().replace('_', "");
    if t.is_empty() {
        return Err(err("empty"));
    }
    let (num, mul) = units
        .iter()
        .find(|(u, _)| t.ends_with(u))
        .map(|(u, m)| (t[..t.len() - u.len()].trim(), *m))
        .unwrap_or((t.as_str(), 1));
    let v: f64 = num.parse().map_err(|_| err("not a number"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(err("must be a finite, non-negative number"));
    }
    let out = v * mul as f64;
    if out > u64::MAX as f64 {
        return Err(err("too large"));
    }
    Ok(out.round() as u64)
}

/// Formats bytes for humans, e.g. `1.50 GiB`.
pub fn format_bytes(b: u64) -> String {
    const U: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut i = 0;
    while v >= 1024.0 && i < U.len() - 1 {
        v /= 1024.0;
        i += 1;
    }
    if i == 0 {
        format!("{b} B")
    } else {
        format!("{v:.2} {}", U[i])
    }
}

/// Formats a count for humans, e.g. `412 M`, `1.2 G`, `53 k` (three significant digits).
pub fn format_count(n: u64) -> String {
    const U: [(f64, &str); 3] = [(1e9, "G"), (1e6, "M"), (1e3, "k")];
    for (scale, unit) in U {
        let v = n as f64 / scale;
        if v >= 1.0 {
            let decimals = if v >= 100.0 {
                0
            } else if v >= 10.0 {
                1
            } else {
                2
            };
            return format!("{v:.decimals$} {unit}");
        }
    }
    n.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts() {
        assert_eq!(format_count(999), "999");
        assert_eq!(format_count(53_400), "53.4 k");
        assert_eq!(format_count(412_000_000), "412 M");
        assert_eq!(format_count(1_200_000_000), "1.20 G");
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("4GiB"), Ok(4 << 30));
        assert_eq!(parse_bytes("100MB"), Ok(100_000_000));
        assert_eq!(parse_bytes("1234"), Ok(1234));
        assert_eq!(parse_count("25M"), Ok(25_000_000));
        assert_eq!(parse_count("1.5G"), Ok(1_500_000_000));
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("-1MiB").is_err());
        assert!(parse_count("").is_err());
        assert_eq!(format_bytes(1536 << 20), "1.50 GiB");
    }
}
