//! A [`ByteSource`] over the byte ranges fetched so far: the store reader's validation and
//! decoding run unchanged on bytes the browser fetched asynchronously beforehand.

use pointlet_store::{ByteSource, SourceError};
use std::collections::BTreeMap;
use std::sync::{Arc, RwLock};

/// Fetched ranges of a file of known length, shared between the fetch tasks and the reader.
#[derive(Clone, Debug, Default)]
pub struct SparseBytes {
    len: u64,
    /// Start offset → bytes; ranges may overlap.
    ranges: Arc<RwLock<BTreeMap<u64, Vec<u8>>>>,
}

impl SparseBytes {
    pub fn new(len: u64) -> Self {
        Self {
            len,
            ranges: Arc::default(),
        }
    }

    /// Keeps `bytes` as the file's bytes at `offset`.
    pub fn insert(&self, offset: u64, bytes: Vec<u8>) {
        if let Ok(mut r) = self.ranges.write() {
            let keep = r.get(&offset).is_none_or(|old| old.len() < bytes.len());
            if keep {
                r.insert(offset, bytes);
            }
        }
    }

    /// Drops every range but those starting before `keep_below` (the store's metadata).
    pub fn forget_from(&self, keep_below: u64) {
        if let Ok(mut r) = self.ranges.write() {
            let _ = r.split_off(&keep_below);
        }
    }

    /// Whether `offset..offset + len` was fetched (within one range).
    pub fn has(&self, offset: u64, len: u64) -> bool {
        self.ranges.read().is_ok_and(|r| {
            r.range(..=offset)
                .next_back()
                .is_some_and(|(start, b)| offset + len <= start + b.len() as u64)
        })
    }
}

impl ByteSource for SparseBytes {
    fn size(&self) -> u64 {
        self.len
    }

    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> Result<(), SourceError> {
        let end = offset + buf.len() as u64;
        if end > self.len {
            return Err(SourceError::Truncated);
        }
        let ranges = self
            .ranges
            .read()
            .map_err(|_| SourceError::Remote("the fetched bytes are unreadable".into()))?;
        // Any range starting at or before `offset` may hold it (ranges overlap).
        for (start, bytes) in ranges.range(..=offset).rev() {
            let from = (offset - start) as usize;
            if let Some(src) = bytes.get(from..from + buf.len()) {
                buf.copy_from_slice(src);
                return Ok(());
            }
        }
        Err(SourceError::Remote(format!(
            "bytes {offset}..{end} were not fetched"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_within_fetched_ranges_only() {
        let s = SparseBytes::new(100);
        s.insert(10, (10..30).collect());
        s.insert(40, (40..50).collect());
        let mut buf = [0u8; 5];
        s.read_exact_at(&mut buf, 12).unwrap();
        assert_eq!(buf, [12, 13, 14, 15, 16]);
        assert!(s.read_exact_at(&mut buf, 27).is_err());
        assert!(s.read_exact_at(&mut buf, 98).is_err());
        assert!(s.has(40, 10) && !s.has(40, 11) && !s.has(0, 1));
        s.insert(0, (0..20).collect());
        s.read_exact_at(&mut buf, 22).unwrap();
        assert_eq!(buf[0], 22);
        s.forget_from(5);
        assert!(s.read_exact_at(&mut buf, 22).is_err());
        assert!(s.has(0, 20));
    }
}
