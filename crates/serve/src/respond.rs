//! The HTTP answer for one served file: preconditions, then the whole file (200), one range
//! (206) or a refusal (304, 412, 416), each with the file's validators, `Accept-Ranges`,
//! `Cache-Control` and `Content-Type`.
//!
//! Only GET reads a `Range` (RFC 9110 §14.2): HEAD answers with the headers of the whole
//! file's GET, without a body. A 416 carries `Content-Range: bytes */LEN` and says why in
//! its text body; a range in another unit than bytes is ignored ([`ranges`]).

use crate::conditional::{self, Outcome};
use crate::files::{self, OpenFile};
use crate::ranges;
use axum::body::Body;
use axum::http::{header, HeaderMap, HeaderValue, Method, Response, StatusCode};
use std::path::PathBuf;
use std::sync::Arc;
use tokio::sync::Semaphore;

/// How a kind of file is labelled.
#[derive(Clone, Debug)]
pub struct FileKind {
    pub content_type: &'static str,
    pub cache_control: HeaderValue,
}

/// Answers `method` with `headers` for the file at `path`, holding a slot of `streams` while
/// its body is read.
pub async fn file(
    path: PathBuf,
    kind: &FileKind,
    method: &Method,
    headers: &HeaderMap,
    streams: Arc<Semaphore>,
) -> Response<Body> {
    let Ok(permit) = streams.acquire_owned().await else {
        return text(StatusCode::SERVICE_UNAVAILABLE, "the server is stopping");
    };
    let opened = tokio::task::spawn_blocking(move || files::open_regular(&path)).await;
    let OpenFile { file, validators } = match opened {
        Ok(Ok(Some(open))) => open,
        Ok(Ok(None)) => return text(StatusCode::NOT_FOUND, "not found: the file is gone"),
        Ok(Err(_)) | Err(_) => {
            return text(
                StatusCode::INTERNAL_SERVER_ERROR,
                "the file could not be opened",
            )
        }
    };
    let len = validators.len;
    let mut response = Response::builder()
        .header(header::ETAG, validators.etag.as_str())
        .header(header::LAST_MODIFIED, validators.last_modified())
        .header(header::CACHE_CONTROL, kind.cache_control.clone())
        .header(header::ACCEPT_RANGES, "bytes");
    let use_range = match conditional::evaluate(method, headers, &validators) {
        Outcome::NotModified => {
            // The length a 200 would have (RFC 9110 §8.6), or the router would say 0.
            let not_modified = response
                .status(StatusCode::NOT_MODIFIED)
                .header(header::CONTENT_LENGTH, len);
            return finish(not_modified, Body::empty());
        }
        Outcome::Failed => {
            return finish(
                response
                    .status(StatusCode::PRECONDITION_FAILED)
                    .header(header::CONTENT_TYPE, "text/plain; charset=utf-8"),
                Body::from("precondition failed: the file has changed\n"),
            )
        }
        Outcome::Proceed { use_range } => use_range && method == Method::GET,
    };
    let range = match headers.get(header::RANGE).filter(|_| use_range) {
        None => 0..len,
        Some(value) => {
            let parsed = match value.to_str() {
                Ok(v) => ranges::parse(v.trim(), len),
                Err(_) => Err(ranges::RangeError::Malformed("not ASCII".into())),
            };
            match parsed {
                Ok(None) => 0..len,
                Ok(Some(r)) => {
                    response = response.status(StatusCode::PARTIAL_CONTENT).header(
                        header::CONTENT_RANGE,
                        format!("bytes {}-{}/{len}", r.start, r.end - 1),
                    );
                    r
                }
                Err(e) => {
                    return finish(
                        response
                            .status(StatusCode::RANGE_NOT_SATISFIABLE)
                            .header(header::CONTENT_RANGE, format!("bytes */{len}"))
                            .header(header::CONTENT_TYPE, "text/plain; charset=utf-8"),
                        Body::from(format!("{e}\n")),
                    );
                }
            }
        }
    };
    response = response
        .header(header::CONTENT_TYPE, kind.content_type)
        .header(header::CONTENT_LENGTH, range.end - range.start);
    let body = if method == Method::HEAD || range.is_empty() {
        Body::empty()
    } else {
        files::body(file, range, permit)
    };
    finish(response, body)
}

/// A plain-text answer.
pub fn text(status: StatusCode, message: &str) -> Response<Body> {
    finish(
        Response::builder()
            .status(status)
            .header(header::CONTENT_TYPE, "text/plain; charset=utf-8")
            .header(header::CACHE_CONTROL, "no-store"),
        Body::from(format!("{message}\n")),
    )
}

/// Builds the response; a header this module made cannot be invalid, but should one be, the
/// client gets a 500 rather than the server a panic.
fn finish(builder: axum::http::response::Builder, body: Body) -> Response<Body> {
    builder.body(body).unwrap_or_else(|_| {
        let mut r = Response::new(Body::from("internal error: bad response header\n"));
        *r.status_mut() = StatusCode::INTERNAL_SERVER_ERROR;
        r
    })
}
