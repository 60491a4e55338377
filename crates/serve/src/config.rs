//! What to serve and how: the store arguments, the address, the optional viewer folder and the
//! limits. Plain data; [`Server::bind`](crate::Server::bind) checks it.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::path::PathBuf;

/// Where `pointlet serve` listens unless told otherwise: loopback only.
pub const DEFAULT_BIND: SocketAddr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 8080));

/// Bytes read from disk and handed to the connection at once.
pub const CHUNK_BYTES: usize = 64 << 10;

/// The server's configuration.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    /// `.pointlet` files, and folders whose `.pointlet` files (directly inside) are served.
    pub stores: Vec<PathBuf>,
    /// The address to listen on; port 0 picks a free port (see
    /// [`RunningServer::local_addr`](crate::RunningServer::local_addr)).
    pub bind: SocketAddr,
    /// A folder of web-viewer files (`index.html`, `.js`, `.wasm`, …) served from `/`; without
    /// one, `/` is a placeholder page linking to `/stores.json`.
    pub viewer_dir: Option<PathBuf>,
    /// File bodies streamed at once; further requests wait for a slot. Each stream holds at most
    /// a few chunks of [`CHUNK_BYTES`] in memory, so this bounds the server's buffers.
    pub max_streams: usize,
    /// `max-age` of the stores' `Cache-Control` (seconds). 0, the default, sends `no-cache`:
    /// caches revalidate by ETag (a 304 has no body), so a store rebuilt in place is seen at
    /// once and no reader mixes cached ranges of the old file with ranges of the new one.
    pub store_max_age: u32,
}

impl ServeConfig {
    /// Serves `stores` on [`DEFAULT_BIND`] with the default limits.
    pub fn new(stores: Vec<PathBuf>) -> ServeConfig {
        ServeConfig {
            stores,
            bind: DEFAULT_BIND,
            viewer_dir: None,
            max_streams: 256,
            store_max_age: 0,
        }
    }
}
