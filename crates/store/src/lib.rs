//! The `.pointlet` store: a file of Hilbert-sorted, per-pointlet-shuffled points kept as one
//! stream per attribute, its out-of-core builder and its validating reader.
//!
//! The byte layout is specified in `docs/FORMAT.md`; [`format`] holds its constants.
//! - [`StoreBuilder`] takes [`PointBatch`](pointlet_core::PointBatch)es in any order and any
//!   number, sorts them under a RAM budget (spilling runs grouped by key bucket to disk when
//!   they do not fit, then sorting a group of buckets at a time), and writes the store
//!   atomically at [`StoreBuilder::finish`].
//! - [`Store`] opens a store after validating its structure, and reads whole pointlets
//!   (checksummed) or any range of a pointlet's shuffled order (one positioned read per stream).

#[cfg(feature = "remote")]
mod aws_profile;
mod builder;
mod emit;
mod error;
pub mod format;
mod meta;
mod pio;
mod reader;
#[cfg(feature = "remote")]
mod remote;
mod runs;
mod sort;
pub mod source;
mod spilled;

pub use builder::{
    BuildConfig, BuildPhase, BuildProgress, BuildSummary, BuildTimings, SpillTimings, StoreBuilder,
};
pub use error::StoreError;
pub use format::{PointletEntry, StoreHeader, StreamInfo, StreamKind};
pub use meta::merge_meta;
pub use reader::{decode_positions, Store};
#[cfg(feature = "remote")]
pub use remote::fetch_object;
pub use source::{is_remote, ByteSource, SourceError};

/// Smallest pointlet the builder makes (paper eq. 1 clamped below).
pub const MIN_POINTLET_SIZE: u64 = 1 << 8;
/// Largest pointlet the builder makes; also keeps a pointlet's count within `u32`.
pub const MAX_POINTLET_SIZE: u64 = 1 << 20;

/// Points per pointlet for `n` points and a target of `m` pointlets (virtualized paper, eq. 1):
/// k = 2^round(log2(n / m)), clamped to [256, 2^20]. `m = 0` counts as 1.
pub fn pointlet_size(n: u64, m: u64) -> u64 {
    let ratio = n as f64 / m.max(1) as f64;
    let min_exp = MIN_POINTLET_SIZE.trailing_zeros() as f64;
    let max_exp = MAX_POINTLET_SIZE.trailing_zeros() as f64;
    // n = 0 gives log2(0) = -inf, which the clamp takes to the minimum.
    let exp = ratio.log2().round().clamp(min_exp, max_exp);
    1u64 << (exp as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pointlet_size_follows_eq_1_and_clamps() {
        assert_eq!(pointlet_size(110_000, 100), 1024);
        assert_eq!(pointlet_size(1_000_000, 1000), 1024);
        // 1500/1 = 2^10.55 rounds up; 1400 = 2^10.45 rounds down.
        assert_eq!(pointlet_size(1500, 1), 2048);
        assert_eq!(pointlet_size(1400, 1), 1024);
        assert_eq!(pointlet_size(0, 100), 256);
        assert_eq!(pointlet_size(1065, 100_000), 256);
        assert_eq!(pointlet_size(u64::MAX, 1), 1 << 20);
        assert_eq!(pointlet_size(1 << 30, 0), 1 << 20);
        assert_eq!(pointlet_size(100_000_000, 100_000), 1024);
    }
}
