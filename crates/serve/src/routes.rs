//! The routes: `/stores.json`, `/stores/NAME.pointlet`, `/` and the viewer's files, behind
//! CORS for any origin.
//!
//! A store is found by its name in the [`Catalog`]; a viewer file by its path in
//! [`ViewerFiles`]; no route builds a file-system path from the request. Every answer says
//! `X-Content-Type-Options: nosniff`; methods other than GET and HEAD get 405 (CORS
//! preflights are answered by the CORS layer before routing).

use crate::catalog::{Catalog, STORE_EXTENSION};
use crate::listing::{store_url, Listing};
use crate::mime::content_type;
use crate::respond::{self, FileKind};
use crate::viewer::ViewerFiles;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, Response, StatusCode, Uri};
use axum::routing::get;
use axum::Router;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Semaphore;
use tower_http::cors::{Any, CorsLayer};
use tower_http::set_header::SetResponseHeaderLayer;

/// What the handlers share.
pub struct AppState {
    pub catalog: Catalog,
    pub viewer: Option<ViewerFiles>,
    pub listing: Listing,
    pub streams: Arc<Semaphore>,
    pub store_kind: FileKind,
}

type Shared = State<Arc<AppState>>;

/// The application with its middleware.
pub fn router(state: Arc<AppState>) -> Router {
    let cors = CorsLayer::new()
        .allow_origin(Any)
        .allow_methods([Method::GET, Method::HEAD, Method::OPTIONS])
        .allow_headers(Any)
        .expose_headers([
            header::CONTENT_RANGE,
            header::ETAG,
            header::ACCEPT_RANGES,
            header::CONTENT_LENGTH,
            header::LAST_MODIFIED,
        ])
        .max_age(Duration::from_secs(86_400));
    Router::new()
        .route("/", get(index))
        .route("/stores.json", get(stores_json))
        .route("/stores/{file}", get(store))
        .fallback(viewer_file)
        .with_state(state)
        .layer(cors)
        .layer(SetResponseHeaderLayer::overriding(
            header::X_CONTENT_TYPE_OPTIONS,
            HeaderValue::from_static("nosniff"),
        ))
}

async fn store(
    State(state): Shared,
    Path(file): Path<String>,
    method: Method,
    headers: HeaderMap,
) -> Response<Body> {
    let found = file
        .strip_suffix(STORE_EXTENSION)
        .and_then(|name| state.catalog.get(name));
    let Some(store) = found else {
        return respond::text(
            StatusCode::NOT_FOUND,
            "not found: no such store (see /stores.json)",
        );
    };
    let path = store.path.clone();
    let streams = Arc::clone(&state.streams);
    respond::file(path, &state.store_kind, &method, &headers, streams).await
}

async fn stores_json(State(state): Shared) -> Response<Body> {
    let work = Arc::clone(&state);
    let json = tokio::task::spawn_blocking(move || work.listing.json(&work.catalog)).await;
    let Ok(json) = json else {
        return respond::text(
            StatusCode::INTERNAL_SERVER_ERROR,
            "listing the stores failed",
        );
    };
    let mut response = Response::new(Body::from(json));
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}

async fn index(State(state): Shared, method: Method, headers: HeaderMap) -> Response<Body> {
    if let Some(viewer) = state.viewer.as_ref().filter(|v| v.has_index()) {
        if let Some((name, path)) = viewer.lookup("/") {
            return viewer_response(&state, name, path.to_path_buf(), &method, &headers).await;
        }
    }
    let mut items = String::new();
    for s in state.catalog.stores() {
        let url = store_url(&s.name);
        items.push_str(&format!(
            "<li><a href=\"{}\">{}</a> — {} points</li>\n",
            html_escape(&url),
            html_escape(&s.name),
            s.info.points
        ));
    }
    let page = format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>pointlet serve</title></head>\n\
         <body><h1>pointlet serve</h1>\n\
         <p>The web viewer is not built yet: build it with <code>bash scripts/build-web.sh</code> \
         (it writes <code>target/web</code>), or point <code>--web-dir</code> or \
         <code>POINTLET_WEB_DIR</code> at its files, then restart <code>pointlet serve</code>.</p>\n\
         <p>The stores are served all the same, listed in \
         <a href=\"/stores.json\">/stores.json</a>:</p>\n<ul>\n{items}</ul>\n</body></html>\n"
    );
    let mut response = Response::new(Body::from(page));
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}

async fn viewer_file(
    State(state): Shared,
    method: Method,
    uri: Uri,
    headers: HeaderMap,
) -> Response<Body> {
    if method != Method::GET && method != Method::HEAD {
        let mut r = respond::text(
            StatusCode::METHOD_NOT_ALLOWED,
            "only GET and HEAD are served",
        );
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return r;
    }
    let found = state.viewer.as_ref().and_then(|v| v.lookup(uri.path()));
    let Some((name, path)) = found else {
        return respond::text(
            StatusCode::NOT_FOUND,
            "not found: this server serves /, /stores.json and /stores/NAME.pointlet",
        );
    };
    viewer_response(&state, name, path.to_path_buf(), &method, &headers).await
}

async fn viewer_response(
    state: &AppState,
    name: &str,
    path: std::path::PathBuf,
    method: &Method,
    headers: &HeaderMap,
) -> Response<Body> {
    let kind = FileKind {
        content_type: content_type(name),
        cache_control: HeaderValue::from_static("no-cache"),
    };
    respond::file(path, &kind, method, headers, Arc::clone(&state.streams)).await
}

fn html_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}
