//! `/stores.json`: the served stores with their sizes, point counts, bounds and validators.
//!
//! Each request looks at every store's file again (a `stat`, not following a symlink put in
//! its place): the validators it lists are those a request for the store would get now, and
//! when they changed since the last look (the file was replaced) the store's header is read
//! again. A store that is gone or no longer valid is still listed, with an `error` instead
//! of its facts.

use crate::catalog::{Catalog, StoreInfo};
use crate::files::Validators;
use serde::Serialize;
use std::fs;
use std::sync::Mutex;

/// The listing's memory of each store's header facts, by the validators they were read at.
#[derive(Debug)]
pub struct Listing {
    seen: Mutex<Vec<(Validators, Result<StoreInfo, String>)>>,
}

/// One store in `stores.json`.
#[derive(Serialize)]
struct Entry<'a> {
    name: &'a str,
    /// Path of the store's URL (percent-encoded), relative to the server.
    url: String,
    /// Bytes in the file.
    #[serde(skip_serializing_if = "Option::is_none")]
    size: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    points: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pointlets: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    bounds: Option<pointlet_core::Aabb>,
    #[serde(skip_serializing_if = "Option::is_none")]
    etag: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    last_modified: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
}

impl Listing {
    pub fn new(catalog: &Catalog) -> Listing {
        let seen = catalog
            .stores()
            .iter()
            .map(|s| (s.validators.clone(), Ok(s.info.clone())))
            .collect();
        Listing {
            seen: Mutex::new(seen),
        }
    }

    /// The JSON array of the stores (blocking: reads file metadata and maybe headers).
    pub fn json(&self, catalog: &Catalog) -> Vec<u8> {
        let mut seen = match self.seen.lock() {
            Ok(guard) => guard,
            Err(poisoned) => poisoned.into_inner(),
        };
        let mut entries = Vec::with_capacity(catalog.stores().len());
        for (store, memo) in catalog.stores().iter().zip(seen.iter_mut()) {
            let mut entry = Entry {
                name: &store.name,
                url: store_url(&store.name),
                size: None,
                points: None,
                pointlets: None,
                bounds: None,
                etag: None,
                last_modified: None,
                error: None,
            };
            let validators = match fs::symlink_metadata(&store.path) {
                Ok(meta) if meta.is_file() => Validators::of(&meta),
                Ok(_) => {
                    entry.error = Some("no longer a regular file".into());
                    entries.push(entry);
                    continue;
                }
                Err(e) => {
                    entry.error = Some(format!("not available: {e}"));
                    entries.push(entry);
                    continue;
                }
            };
            entry.size = Some(validators.len);
            if memo.0 != validators {
                let info = StoreInfo::read(&store.path).map_err(|e| e.to_string());
                *memo = (validators.clone(), info);
            }
            match &memo.1 {
                Ok(info) => {
                    entry.points = Some(info.points);
                    entry.pointlets = Some(info.pointlets);
                    entry.bounds = Some(info.bounds);
                    entry.last_modified = Some(validators.last_modified());
                    entry.etag = Some(validators.etag);
                }
                Err(e) => entry.error = Some(e.clone()),
            }
            entries.push(entry);
        }
        let mut json = serde_json::to_vec_pretty(&entries).unwrap_or_else(|_| b"[]".to_vec());
        json.push(b'\n');
        json
    }
}

/// `/stores/NAME.pointlet`, NAME percent-encoded as a path segment.
pub fn store_url(name: &str) -> String {
    const SEGMENT: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
        .remove(b'-')
        .remove(b'_')
        .remove(b'.')
        .remove(b'~');
    format!(
        "/stores/{}.pointlet",
        percent_encoding::utf8_percent_encode(name, SEGMENT)
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn urls_encode_the_name() {
        assert_eq!(super::store_url("city"), "/stores/city.pointlet");
        assert_eq!(super::store_url("a b%"), "/stores/a%20b%25.pointlet");
    }
}
