//! Conditional requests (RFC 9110 §13): `If-Match`, `If-Unmodified-Since`, `If-None-Match`,
//! `If-Modified-Since` and `If-Range`, evaluated in the RFC's order against the file's
//! [`Validators`].
//!
//! Entity tags are compared strongly for `If-Match` and `If-Range` and weakly for
//! `If-None-Match`; a malformed `If-None-Match` or date is ignored, a malformed `If-Match`
//! fails. `If-Range` with a date holds only when it equals `Last-Modified` exactly.

use crate::files::Validators;
use axum::http::{header, HeaderMap, HeaderName, Method};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// What the preconditions decide.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Go on; `use_range` is false when `If-Range` did not match (send the whole file).
    Proceed { use_range: bool },
    /// 304 Not Modified.
    NotModified,
    /// 412 Precondition Failed.
    Failed,
}

/// Evaluates the request's preconditions against `v`.
pub fn evaluate(method: &Method, headers: &HeaderMap, v: &Validators) -> Outcome {
    let safe = method == Method::GET || method == Method::HEAD;
    if let Some(list) = joined(headers, &header::IF_MATCH) {
        if !matches_list(&list, &v.etag, true).unwrap_or(false) {
            return Outcome::Failed;
        }
    } else if let Some(date) = date(headers, &header::IF_UNMODIFIED_SINCE) {
        if seconds(v.modified) > seconds(date) {
            return Outcome::Failed;
        }
    }
    if let Some(list) = joined(headers, &header::IF_NONE_MATCH) {
        if matches_list(&list, &v.etag, false).unwrap_or(false) {
            return if safe {
                Outcome::NotModified
            } else {
                Outcome::Failed
            };
        }
    } else if safe {
        if let Some(date) = date(headers, &header::IF_MODIFIED_SINCE) {
            if seconds(v.modified) <= seconds(date) {
                return Outcome::NotModified;
            }
        }
    }
    let use_range = match headers.get(header::IF_RANGE).map(|h| h.to_str()) {
        None => true,
        Some(Err(_)) => false,
        Some(Ok(value)) => if_range_holds(value.trim(), v),
    };
    Outcome::Proceed { use_range }
}

/// `If-Range`: an entity tag compared strongly, or a date equal to `Last-Modified`.
fn if_range_holds(value: &str, v: &Validators) -> bool {
    if value.starts_with('"') || value.starts_with("W/") {
        return matches!(tags(value), Some(t) if t.len() == 1 && tag_matches(&t[0], &v.etag, true));
    }
    match httpdate::parse_http_date(value) {
        Ok(date) => seconds(date) == seconds(v.modified),
        Err(_) => false,
    }
}

/// All values of a list header, joined with commas; `None` when absent or not ASCII.
fn joined(headers: &HeaderMap, name: &HeaderName) -> Option<String> {
    let mut values = headers.get_all(name).iter().peekable();
    values.peek()?;
    let mut out = String::new();
    for value in values {
        if !out.is_empty() {
            out.push(',');
        }
        out.push_str(value.to_str().ok()?);
    }
    Some(out)
}

fn date(headers: &HeaderMap, name: &HeaderName) -> Option<SystemTime> {
    let value = headers.get(name)?.to_str().ok()?;
    httpdate::parse_http_date(value.trim()).ok()
}

/// Whole seconds since the epoch (HTTP dates have no finer resolution).
fn seconds(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs()
}

/// One entity tag of a list.
#[derive(Debug, PartialEq)]
struct Tag {
    weak: bool,
    /// With its quotes.
    opaque: String,
}

/// Whether `list` (`*` or entity tags) matches `ours`; `None` when the list is malformed.
fn matches_list(list: &str, ours: &str, strong: bool) -> Option<bool> {
    if list.trim() == "*" {
        return Some(true);
    }
    Some(tags(list)?.iter().any(|t| tag_matches(t, ours, strong)))
}

fn tag_matches(tag: &Tag, ours: &str, strong: bool) -> bool {
    (!strong || !tag.weak) && tag.opaque == ours
}

/// Parses `#entity-tag`: `W/"…"` or `"…"`, separated by commas and optional spaces. Commas may
/// appear inside the quotes.
fn tags(list: &str) -> Option<Vec<Tag>> {
    let mut out = Vec::new();
    let mut rest = list;
    loop {
        rest = rest.trim_start_matches([' ', '\t', ',']);
        if rest.is_empty() {
            break;
        }
        let weak = rest.starts_with("W/");
        if weak {
            rest = &rest[2..];
        }
        let inner = rest.strip_prefix('"')?;
        let close = inner.find('"')?;
        out.push(Tag {
            weak,
            opaque: format!("\"{}\"", &inner[..close]),
        });
        rest = &inner[close + 1..];
        let next = rest.trim_start_matches([' ', '\t']);
        if !(next.is_empty() || next.starts_with(',')) {
            return None;
        }
        rest = next;
    }
    (!out.is_empty()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn validators() -> Validators {
        Validators {
            len: 10,
            etag: "\"a-b-c\"".into(),
            modified: UNIX_EPOCH + Duration::from_secs(1_000_000_000),
        }
    }

    fn eval(method: Method, pairs: &[(HeaderName, &str)]) -> Outcome {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(k.clone(), HeaderValue::from_str(v).unwrap());
        }
        evaluate(&method, &h, &validators())
    }

    const GO: Outcome = Outcome::Proceed { use_range: true };
    const WHOLE: Outcome = Outcome::Proceed { use_range: false };

    #[test]
    fn entity_tag_lists() {
        assert_eq!(tags("\"x\", W/\"y\"").unwrap().len(), 2);
        assert_eq!(tags("\"a,b\"").unwrap()[0].opaque, "\"a,b\"");
        assert!(tags("x").is_none());
        assert!(tags("\"x\" y").is_none());
        assert!(tags("").is_none());
    }

    #[test]
    fn if_none_match_is_weak_and_gives_304() {
        let inm = header::IF_NONE_MATCH;
        assert_eq!(
            eval(Method::GET, &[(inm.clone(), "\"a-b-c\"")]),
            Outcome::NotModified
        );
        assert_eq!(
            eval(Method::HEAD, &[(inm.clone(), "W/\"a-b-c\"")]),
            Outcome::NotModified
        );
        assert_eq!(
            eval(Method::GET, &[(inm.clone(), "\"zz\", \"a-b-c\"")]),
            Outcome::NotModified
        );
        assert_eq!(
            eval(Method::GET, &[(inm.clone(), "*")]),
            Outcome::NotModified
        );
        assert_eq!(eval(Method::GET, &[(inm.clone(), "\"old\"")]), GO);
        assert_eq!(eval(Method::GET, &[(inm.clone(), "garbage")]), GO);
        // If-None-Match overrides If-Modified-Since.
        let ims = (header::IF_MODIFIED_SINCE, "Fri, 01 Jan 2100 00:00:00 GMT");
        assert_eq!(eval(Method::GET, &[(inm, "\"old\""), ims.clone()]), GO);
        assert_eq!(eval(Method::GET, &[ims]), Outcome::NotModified);
        let before = (header::IF_MODIFIED_SINCE, "Mon, 01 Jan 1990 00:00:00 GMT");
        assert_eq!(eval(Method::GET, &[before]), GO);
    }

    #[test]
    fn if_match_is_strong_and_gives_412() {
        let im = header::IF_MATCH;
        assert_eq!(eval(Method::GET, &[(im.clone(), "\"a-b-c\"")]), GO);
        assert_eq!(
            eval(Method::GET, &[(im.clone(), "W/\"a-b-c\"")]),
            Outcome::Failed
        );
        assert_eq!(
            eval(Method::GET, &[(im.clone(), "\"old\"")]),
            Outcome::Failed
        );
        assert_eq!(eval(Method::GET, &[(im, "*")]), GO);
        let ius = (header::IF_UNMODIFIED_SINCE, "Mon, 01 Jan 1990 00:00:00 GMT");
        assert_eq!(eval(Method::GET, &[ius]), Outcome::Failed);
    }

    #[test]
    fn if_range_needs_the_current_validator() {
        let ir = header::IF_RANGE;
        assert_eq!(eval(Method::GET, &[(ir.clone(), "\"a-b-c\"")]), GO);
        assert_eq!(eval(Method::GET, &[(ir.clone(), "W/\"a-b-c\"")]), WHOLE);
        assert_eq!(eval(Method::GET, &[(ir.clone(), "\"old\"")]), WHOLE);
        let lm = httpdate::fmt_http_date(validators().modified);
        assert_eq!(eval(Method::GET, &[(ir.clone(), lm.as_str())]), GO);
        assert_eq!(
            eval(
                Method::GET,
                &[(ir.clone(), "Fri, 01 Jan 2100 00:00:00 GMT")]
            ),
            WHOLE
        );
        assert_eq!(eval(Method::GET, &[(ir, "nonsense")]), WHOLE);
    }
}
