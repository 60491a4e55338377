//! The crate's one error type. Every variant names where the problem is: the URI of the file
//! (tileset JSON or tile content) and, for tileset problems, the tile's path in the tree
//! (`root.children[2].children[0]`). Errors of a tile's content read through a [`crate::Tileset`]
//! are wrapped in [`TilesError::Tile`], which adds the tile's path.

use thiserror::Error;

#[derive(Debug, Error)]
pub enum TilesError {
    /// A file could not be read (missing, unreadable, too large).
    #[error("{uri}: cannot read {location}: {source}")]
    Read {
        uri: String,
        /// Where the source looked (a file path for local sources).
        location: String,
        #[source]
        source: std::io::Error,
    },
    /// A tileset file that is not valid JSON or not shaped like a tileset.
    #[error("{uri}: invalid tileset JSON: {source}")]
    Json {
        uri: String,
        #[source]
        source: serde_json::Error,
    },
    /// A tile whose description breaks the specification (missing or malformed fields).
    #[error("{uri}: tile {tile}: {message}")]
    InvalidTile {
        uri: String,
        tile: String,
        message: String,
    },
    /// A tile transform that is not finite, not affine or singular (alone or accumulated).
    #[error("{uri}: tile {tile}: transform {message}")]
    BadTransform {
        uri: String,
        tile: String,
        message: String,
    },
    /// External tilesets that reference each other in a loop; the chain ends with the URI
    /// that closes the loop.
    #[error("cycle of external tilesets: {}", chain.join(" -> "))]
    Cycle { chain: Vec<String> },
    /// A tileset beyond the limits of [`crate::LoadLimits`] (depth, tile count, file size).
    #[error("{uri}: {message}")]
    Limit { uri: String, message: String },
    /// Tile content that is malformed: wrong magic, lengths beyond the buffer, truncated, ...
    #[error("{uri}: {message}")]
    InvalidContent { uri: String, message: String },
    /// Tile content or a tileset feature that this crate does not decode (Draco, implicit
    /// tiling, mesh content, ...).
    #[error("{uri}: unsupported: {message}")]
    Unsupported { uri: String, message: String },
    /// An error of a tile's content, with the tile it belongs to.
    #[error("tile {tile} of {tileset}: {source}")]
    Tile {
        tileset: String,
        tile: String,
        #[source]
        source: Box<TilesError>,
    },
}

impl TilesError {
    pub(crate) fn content(uri: &str, message: impl Into<String>) -> Self {
        TilesError::InvalidContent {
            uri: uri.to_string(),
            message: message.into(),
        }
    }

    pub(crate) fn unsupported(uri: &str, message: impl Into<String>) -> Self {
        TilesError::Unsupported {
            uri: uri.to_string(),
            message: message.into(),
        }
    }

    pub(crate) fn tile(uri: &str, tile: &str, message: impl Into<String>) -> Self {
        TilesError::InvalidTile {
            uri: uri.to_string(),
            tile: tile.to_string(),
            message: message.into(),
        }
    }

    /// The innermost error: the cause under any [`TilesError::Tile`] wrappers.
    pub fn root_cause(&self) -> &TilesError {
        match self {
            TilesError::Tile { source, .. } => source.root_cause(),
            other => other,
        }
    }
}
