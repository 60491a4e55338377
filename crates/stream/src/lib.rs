//! The CPU half of the virtual memory system (virtualized paper §III-C3).
//!
//! Each pointlet keeps a loaded *prefix* of its shuffled points in RAM. Every frame the render
//! thread hands over the point count the LoD pass wants per pointlet ([`RamCache::request`]);
//! that call never blocks: it only enqueues load tasks (always, when more is wanted) and unload
//! tasks (only under memory pressure) into a bounded queue. Loader threads take tasks, compare
//! them with the pointlet's current state under its own mutex, and extend or truncate the prefix.
//! When RAM allows, a load reads up to 25 % beyond the request to anticipate the next frames.

mod cache;
mod source;

pub use cache::{CacheConfig, CacheStats, RamCache};
pub use source::{PointletData, PointletSource, SourceError};
