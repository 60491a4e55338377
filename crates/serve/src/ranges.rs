//! The `Range` header (RFC 9110 §14): one byte range, in any of its three forms.
//!
//! `bytes=a-b`, `bytes=a-` and `bytes=-n` give the range clamped to the file (a last position
//! past the end, or a suffix longer than the file, is cut to the file). A header in another
//! unit (`items=0-1`) is ignored, as RFC 9110 §14.2 requires: the whole file is sent.
//! Everything else is refused with a reason, which the server answers with 416 and
//! `Content-Range: bytes */LEN`:
//! - several ranges (`bytes=0-1,5-6`): this server sends no `multipart/byteranges`; clients
//!   ask for one range per request;
//! - a range starting at or past the end, and the empty suffix `bytes=-0`;
//! - syntax errors: a last position before the first, signs, spaces inside a range, no `=`.
//!   RFC 9110 lets a server ignore an invalid range or refuse it; a refusal tells a client
//!   its bug instead of sending it a whole store of many gigabytes.

use std::ops::Range;

/// Why a `Range` header was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RangeError {
    /// Not a byte-range header this server reads.
    Malformed(String),
    /// More than one range.
    Multiple,
    /// A well-formed range that selects no byte of the file.
    Unsatisfiable(String),
}

impl std::fmt::Display for RangeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RangeError::Malformed(why) => write!(f, "malformed Range header: {why}"),
            RangeError::Multiple => write!(
                f,
                "several ranges in one request are not served (no multipart/byteranges): ask for one range per request"
            ),
            RangeError::Unsatisfiable(why) => write!(f, "range not satisfiable: {why}"),
        }
    }
}

/// The byte range (end exclusive) that `header` selects from a file of `len` bytes; `None`
/// when the header is in a unit other than bytes, which is ignored.
pub fn parse(header: &str, len: u64) -> Result<Option<Range<u64>>, RangeError> {
    let malformed = |why: &str| RangeError::Malformed(why.to_string());
    let (unit, set) = header
        .split_once('=')
        .ok_or_else(|| malformed("expected bytes=FIRST-LAST, bytes=FIRST- or bytes=-SUFFIX"))?;
    if !is_token(unit) {
        return Err(malformed("the range unit is not a token"));
    }
    if !unit.eq_ignore_ascii_case("bytes") {
        return Ok(None);
    }
    // List elements may be empty and surrounded by spaces or tabs (RFC 9110 §5.6.1).
    let mut specs = set
        .split(',')
        .map(|s| s.trim_matches([' ', '\t']))
        .filter(|s| !s.is_empty());
    let spec = specs.next().ok_or_else(|| malformed("no range given"))?;
    if specs.next().is_some() {
        return Err(RangeError::Multiple);
    }
    let (first, last) = spec
        .split_once('-')
        .ok_or_else(|| malformed("a range needs a '-'"))?;
    if first.is_empty() {
        let suffix = number(last).ok_or_else(|| malformed("the suffix length is not a number"))?;
        if suffix == 0 || len == 0 {
            return Err(RangeError::Unsatisfiable(format!(
                "the last {suffix} bytes of a {len}-byte file select nothing"
            )));
        }
        return Ok(Some(len.saturating_sub(suffix)..len));
    }
    let first = number(first).ok_or_else(|| malformed("the first position is not a number"))?;
    let last = match last {
        "" => None,
        s => Some(number(s).ok_or_else(|| malformed("the last position is not a number"))?),
    };
    if let Some(last) = last {
        if last < first {
            return Err(RangeError::Malformed(format!(
                "the last position {last} is before the first {first}"
            )));
        }
    }
    if first >= len {
        return Err(RangeError::Unsatisfiable(format!(
            "the range starts at byte {first}, the file has {len} bytes"
        )));
    }
    let end = last.map_or(len, |l| l.saturating_add(1).min(len));
    Ok(Some(first..end))
}

/// An HTTP token (RFC 9110 §5.6.2), as a range unit must be.
fn is_token(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b))
}

/// A decimal of ASCII digits only (no sign, no spaces); values beyond `u64` saturate, since
/// they are past the end of any file either way.
fn number(s: &str) -> Option<u64> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some(s.bytes().fold(0u64, |acc, b| {
        acc.saturating_mul(10).saturating_add(u64::from(b - b'0'))
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(h: &str, len: u64) -> Range<u64> {
        match parse(h, len) {
            Ok(Some(r)) => r,
            other => panic!("{h}: {other:?}"),
        }
    }

    #[test]
    fn the_three_forms_and_clamping() {
        assert_eq!(ok("bytes=0-0", 10), 0..1);
        assert_eq!(ok("bytes=2-5", 10), 2..6);
        assert_eq!(ok("bytes=2-", 10), 2..10);
        assert_eq!(ok("bytes=-3", 10), 7..10);
        assert_eq!(ok("bytes=-30", 10), 0..10);
        assert_eq!(ok("bytes=5-100", 10), 5..10);
        assert_eq!(ok("bytes=9-99999999999999999999999999", 10), 9..10);
        assert_eq!(ok("BYTES=1-2", 10), 1..3);
        assert_eq!(ok("bytes= 1-2 ,", 10), 1..3);
    }

    #[test]
    fn refusals() {
        let malformed = |h: &str| {
            assert!(
                matches!(parse(h, 10), Err(RangeError::Malformed(_))),
                "{h}: {:?}",
                parse(h, 10)
            )
        };
        for h in [
            "bytes=5-2",
            "bytes=abc",
            "bytes=",
            "bytes=-",
            "bytes=+1-2",
            "bytes=1-+2",
            "bytes=1 -2",
            "bytes=--1",
            "bytes 0-1",
            "bytes=0x1-2",
            "bytes=1-2-3",
            "=0-1",
        ] {
            malformed(h);
        }
        assert_eq!(parse("bytes=0-1,5-6", 10), Err(RangeError::Multiple));
        // Another unit is ignored (the whole file), not refused.
        assert_eq!(parse("items=0-1", 10), Ok(None));
        assert_eq!(parse("Bytes2=5-2", 10), Ok(None));
        for h in [
            "bytes=10-",
            "bytes=10-20",
            "bytes=-0",
            "bytes=99999999999999999999999-",
        ] {
            assert!(
                matches!(parse(h, 10), Err(RangeError::Unsatisfiable(_))),
                "{h}"
            );
        }
        assert!(matches!(
            parse("bytes=-5", 0),
            Err(RangeError::Unsatisfiable(_))
        ));
    }
}
