//! Tileset files and tile content read over HTTP(S) or from S3, for `*.json` tileset URLs:
//! whole files, with the store reader's timeouts, retries and error kinds.

use pointlet_tiles::{TileSource, TilesError};

/// Files larger than this are refused (a tile content or tileset JSON, not a store).
const MAX_FILE_BYTES: u64 = 1 << 30;

/// Tileset files fetched by their resolved (absolute) URIs.
pub struct RemoteTiles;

impl TileSource for RemoteTiles {
    fn read(&self, uri: &str) -> Result<Vec<u8>, TilesError> {
        pointlet_store::fetch_object(uri, MAX_FILE_BYTES).map_err(|e| TilesError::Read {
            uri: uri.to_string(),
            location: "it".into(),
            source: std::io::Error::other(e.to_string()),
        })
    }
}
