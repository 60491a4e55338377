//! HTTP range reads with the browser's `fetch`.

use crate::ranges::total_from_content_range;
use std::ops::Range;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::JsFuture;

/// A response body and the file offset its first byte has.
pub struct Fetched {
    pub body: Vec<u8>,
    pub body_start: u64,
    /// The file's length, when the server said it.
    pub total: Option<u64>,
}

fn text(v: wasm_bindgen::JsValue) -> String {
    v.as_string()
        .or_else(|| {
            v.dyn_ref::<js_sys::Error>()
                .map(|e| String::from(e.message()))
        })
        .unwrap_or_else(|| format!("{v:?}"))
}

/// Bytes `range` of `url`. A server that ignores `Range` answers 200 with the whole file,
/// which works too (its body starts at 0).
pub async fn fetch_range(url: &str, range: Range<u64>) -> Result<Fetched, String> {
    let window = web_sys::window().ok_or("no window")?;
    let init = web_sys::RequestInit::new();
    init.set_method("GET");
    let headers = web_sys::Headers::new().map_err(text)?;
    let last = range.end.max(range.start + 1) - 1;
    headers
        .set("Range", &format!("bytes={}-{last}", range.start))
        .map_err(text)?;
    init.set_headers(&headers);
    let request = web_sys::Request::new_with_str_and_init(url, &init).map_err(text)?;
    let response: web_sys::Response = JsFuture::from(window.fetch_with_request(&request))
        .await
        .map_err(|e| format!("fetching {url}: {}", text(e)))?
        .dyn_into()
        .map_err(|_| "fetch did not return a Response")?;
    let status = response.status();
    let body_start = match status {
        206 => range.start,
        200 => 0,
        404 => return Err(format!("{url} was not found (HTTP 404)")),
        s => {
            return Err(format!(
                "fetching {url}: HTTP {s} {}",
                response.status_text()
            ))
        }
    };
    let content_range = response.headers().get("Content-Range").ok().flatten();
    let buffer = JsFuture::from(response.array_buffer().map_err(text)?)
        .await
        .map_err(|e| format!("reading {url}: {}", text(e)))?;
    let body = js_sys::Uint8Array::new(&buffer).to_vec();
    let total = match status {
        206 => content_range.as_deref().and_then(total_from_content_range),
        _ => Some(body.len() as u64),
    };
    Ok(Fetched {
        body,
        body_start,
        total,
    })
}
