//! Stores read over the network, through the `object_store` crate: `http(s)://host/path` (any
//! server that answers byte ranges, `pointlet serve` among them) and `s3://bucket/key`
//! (credentials, region and endpoint from the usual AWS environment variables, then the
//! profile files). Every read is a ranged GET that must still find the ETag the store had when
//! it was opened (`If-Match`), so a store replaced while being read is an error, never a mix
//! of two files. Reads of several
//! ranges join those less than [`JOIN_GAP`] apart and keep up to [`IN_FLIGHT`] requests going.
//! Timeouts, resets and 5xx answers are retried with backoff by the crate's client; 403, 404
//! and a changed ETag are errors at once.

use crate::source::{ByteSource, SourceError};
use object_store::path::Path as ObjectPath;
use object_store::{BackoffConfig, ClientOptions, GetOptions, GetRange, ObjectStore, RetryConfig};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

/// Ranges closer than this are fetched as one.
pub const JOIN_GAP: u64 = 256 << 10;
/// Requests one `read_ranges` keeps going at once.
pub const IN_FLIGHT: usize = 8;
/// One request may take this long before it counts as stalled (and is retried), unless
/// `POINTLET_REMOTE_TIMEOUT_MS` says otherwise.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(20);
const MAX_RETRIES: usize = 4;

fn request_timeout() -> Duration {
    std::env::var("POINTLET_REMOTE_TIMEOUT_MS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .filter(|ms| *ms > 0)
        .map_or(REQUEST_TIMEOUT, Duration::from_millis)
}

/// The runtime the remote sources' requests run on (the loader threads block on them).
fn runtime() -> Result<&'static tokio::runtime::Runtime, SourceError> {
    static RUNTIME: OnceLock<Result<tokio::runtime::Runtime, String>> = OnceLock::new();
    RUNTIME
        .get_or_init(|| {
            tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .thread_name("pointlet-remote")
                .enable_all()
                .build()
                .map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|e| SourceError::Remote(format!("starting the network runtime: {e}")))
}

/// An object read by ranges.
pub struct RemoteObject {
    store: Arc<dyn ObjectStore>,
    path: ObjectPath,
    len: u64,
    etag: Option<String>,
}

impl std::fmt::Debug for RemoteObject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteObject")
            .field("path", &self.path)
            .field("len", &self.len)
            .field("etag", &self.etag)
            .finish()
    }
}

fn client_options() -> ClientOptions {
    let timeout = request_timeout();
    ClientOptions::new()
        .with_timeout(timeout)
        .with_connect_timeout(timeout.min(Duration::from_secs(10)))
        .with_allow_http(true)
}

fn retry() -> RetryConfig {
    RetryConfig {
        backoff: BackoffConfig {
            init_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(5),
            base: 2.0,
        },
        max_retries: MAX_RETRIES,
        // Every try may stall for the whole timeout; past this, no more tries.
        retry_timeout: request_timeout() * (MAX_RETRIES as u32 + 1),
    }
}

fn error(e: object_store::Error) -> SourceError {
    match e {
        object_store::Error::NotFound { .. } => SourceError::NotFound,
        object_store::Error::Precondition { .. } => SourceError::Changed,
        object_store::Error::PermissionDenied { .. }
        | object_store::Error::Unauthenticated { .. } => SourceError::Denied,
        other => SourceError::Remote(other.to_string()),
    }
}

impl RemoteObject {
    /// Opens `url` (`http://`, `https://` or `s3://`): its size and ETag come from a first
    /// ranged read.
    pub fn open(url: &str) -> Result<Self, SourceError> {
        let (store, path) = store_for(url)?;
        let rt = runtime()?;
        let options = GetOptions {
            range: Some(GetRange::Bounded(0..1)),
            ..Default::default()
        };
        let first = rt.block_on(store.get_opts(&path, options)).map_err(error)?;
        let len = first.meta.size;
        let etag = first.meta.e_tag.clone();
        Ok(Self {
            store,
            path,
            len,
            etag,
        })
    }

    async fn fetch(&self, start: u64, end: u64) -> Result<bytes::Bytes, SourceError> {
        let options = GetOptions {
            if_match: self.etag.clone(),
            range: Some(GetRange::Bounded(start..end)),
            ..Default::default()
        };
        let got = self
            .store
            .get_opts(&self.path, options)
            .await
            .map_err(error)?;
        if got.meta.size != self.len {
            return Err(SourceError::Changed);
        }
        let bytes = got.bytes().await.map_err(error)?;
        if bytes.len() as u64 != end - start {
            return Err(SourceError::Remote(format!(
                "asked for {} bytes at {start}, the server sent {}",
                end - start,
                bytes.len()
            )));
        }
        Ok(bytes)
    }
}

/// S3 settings from the environment, then the AWS profile files for what it leaves unset.
fn s3_builder() -> object_store::aws::AmazonS3Builder {
    use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
    let mut builder = AmazonS3Builder::from_env();
    for (name, value) in crate::aws_profile::profile_settings() {
        if let Ok(key) = name.parse::<AmazonS3ConfigKey>() {
            if builder.get_config_value(&key).is_none() {
                builder = builder.with_config(key, value);
            }
        }
    }
    builder
}

/// The object store and the object's path for `url`.
fn store_for(url: &str) -> Result<(Arc<dyn ObjectStore>, ObjectPath), SourceError> {
    let bad = |why: &str| SourceError::Remote(format!("'{url}' is not a store address: {why}"));
    if let Some(rest) = url.strip_prefix("s3://") {
        let (bucket, key) = rest
            .split_once('/')
            .filter(|(b, k)| !b.is_empty() && !k.is_empty())
            .ok_or_else(|| bad("give s3://BUCKET/KEY"))?;
        let store = s3_builder()
            .with_bucket_name(bucket)
            .with_client_options(client_options())
            .with_retry(retry())
            .build()
            .map_err(error)?;
        let path = ObjectPath::parse(key).map_err(|e| bad(&e.to_string()))?;
        return Ok((Arc::new(store), path));
    }
    let scheme_end = url.find("://").ok_or_else(|| bad("no scheme"))? + 3;
    let path_start = url[scheme_end..]
        .find('/')
        .map(|k| scheme_end + k)
        .ok_or_else(|| bad("no path"))?;
    let (base, path) = url.split_at(path_start);
    let store = object_store::http::HttpBuilder::new()
        .with_url(base)
        .with_client_options(client_options())
        .with_retry(retry())
        .build()
        .map_err(error)?;
    let path = ObjectPath::from_url_path(path).map_err(|e| bad(&e.to_string()))?;
    Ok((Arc::new(store), path))
}

impl ByteSource for RemoteObject {
    fn size(&self) -> u64 {
        self.len
    }

    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> Result<(), SourceError> {
        let end = offset + buf.len() as u64;
        if end > self.len {
            return Err(SourceError::Truncated);
        }
        if buf.is_empty() {
            return Ok(());
        }
        let bytes = runtime()?.block_on(self.fetch(offset, end))?;
        buf.copy_from_slice(&bytes);
        Ok(())
    }

    fn read_ranges(&self, reads: &mut [(u64, &mut [u8])]) -> Result<(), SourceError> {
        if reads.iter().any(|(o, b)| o + b.len() as u64 > self.len) {
            return Err(SourceError::Truncated);
        }
        // Join ranges less than JOIN_GAP apart (in offset order) into fetches.
        let mut order: Vec<usize> = (0..reads.len())
            .filter(|k| !reads[*k].1.is_empty())
            .collect();
        order.sort_by_key(|k| reads[*k].0);
        let mut fetches: Vec<(u64, u64, Vec<usize>)> = Vec::new();
        for k in order {
            let (start, end) = (reads[k].0, reads[k].0 + reads[k].1.len() as u64);
            match fetches.last_mut() {
                Some((_, e, members)) if start <= *e + JOIN_GAP => {
                    *e = (*e).max(end);
                    members.push(k);
                }
                _ => fetches.push((start, end, vec![k])),
            }
        }
        let rt = runtime()?;
        let fetched: Vec<Result<bytes::Bytes, SourceError>> = rt.block_on(async {
            use futures::stream::StreamExt;
            futures::stream::iter(fetches.iter().map(|(s, e, _)| self.fetch(*s, *e)))
                .buffered(IN_FLIGHT)
                .collect()
                .await
        });
        for ((start, _, members), bytes) in fetches.iter().zip(fetched) {
            let bytes = bytes?;
            for k in members {
                let (offset, buf) = &mut reads[*k];
                let at = (*offset - start) as usize;
                buf.copy_from_slice(&bytes[at..at + buf.len()]);
            }
        }
        Ok(())
    }
}

/// The whole object at `url` (`http(s)://` or `s3://`), with the same timeouts and retries as
/// store reads; objects over `max_bytes` are refused before their body is read.
pub fn fetch_object(url: &str, max_bytes: u64) -> Result<Vec<u8>, SourceError> {
    let (store, path) = store_for(url)?;
    runtime()?.block_on(async {
        let got = store
            .get_opts(&path, GetOptions::default())
            .await
            .map_err(error)?;
        if got.meta.size > max_bytes {
            return Err(SourceError::Remote(format!(
                "{} bytes, over the limit of {max_bytes}",
                got.meta.size
            )));
        }
        let bytes = got.bytes().await.map_err(error)?;
        Ok(bytes.to_vec())
    })
}
