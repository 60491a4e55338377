//! The CPU half of the virtual memory system (virtualized paper §III-C3).
//!
//! Each pointlet keeps a *window* [keep_from, loaded) of its shuffled points in RAM: a prefix
//! while the camera moves, a window that slides forward when a still camera accumulates detail
//! beyond what RAM holds. Every frame the render thread hands over the point count the LoD pass
//! wants per pointlet ([`RamCache::request`]); that call never blocks: it only enqueues load
//! tasks (always, when more is wanted) and unload tasks (only under memory pressure) into a
//! bounded queue. Loader threads take tasks, compare them with the pointlet's current state
//! under its own mutex, and extend or truncate the window. When RAM allows, a load reads up to
//! 25 % beyond the request to anticipate the next frames.

mod cache;
mod source;

pub use cache::{CacheConfig, CacheStats, RamCache};
pub use source::{PointletData, PointletSource, SourceError};
