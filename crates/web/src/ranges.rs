//! HTTP range planning: which bytes of which streams a set of pointlet point ranges needs,
//! joined into few requests (nearby ranges merged, as the remote reader does), and the
//! `Content-Range` answer parsed.

#[cfg(test)]
use pointlet_core::{Aabb, PointLayout, Quantization};
#[cfg(test)]
use pointlet_store::StreamInfo;
use pointlet_store::{PointletEntry, StoreHeader, StreamKind};
use std::ops::Range;

/// Ranges closer than this are fetched as one request (the gap is read and dropped).
pub const JOIN_GAP: u64 = 64 << 10;
/// Largest single request: keeps one slow response from holding back everything else.
pub const MAX_REQUEST: u64 = 8 << 20;

/// Points `points` of `pointlet` wanted in the streams of a fetch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PointRange {
    pub pointlet: usize,
    pub points: Range<u32>,
}

/// One HTTP request: bytes `bytes` of the file, and the pieces of it each point range needs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    pub bytes: Range<u64>,
    /// (index into the fetch's point ranges, stream kind, byte range within the file)
    pub pieces: Vec<(usize, StreamKind, Range<u64>)>,
}

/// The file bytes of `range` in stream `kind`; `None` when the store lacks the stream or the
/// range is outside the pointlet.
pub fn stream_bytes(
    header: &StoreHeader,
    entry: &PointletEntry,
    kind: StreamKind,
    points: &Range<u32>,
) -> Option<Range<u64>> {
    let s = header.stream(kind)?;
    if points.start > points.end || points.end > entry.count {
        return None;
    }
    let bpp = s.bytes_per_point as u64;
    let start = s.offset + (entry.first + points.start as u64) * bpp;
    Some(start..start + (points.end - points.start) as u64 * bpp)
}

/// The requests fetching `kinds` of every range in `wanted`: pieces sorted by offset, joined
/// while the gap is at most [`JOIN_GAP`] and the request stays within [`MAX_REQUEST`].
pub fn plan(
    header: &StoreHeader,
    entries: &[PointletEntry],
    wanted: &[PointRange],
    kinds: &[StreamKind],
) -> Vec<Request> {
    let mut pieces: Vec<(usize, StreamKind, Range<u64>)> = Vec::new();
    for (k, w) in wanted.iter().enumerate() {
        let Some(entry) = entries.get(w.pointlet) else {
            continue;
        };
        for kind in kinds {
            if let Some(r) = stream_bytes(header, entry, *kind, &w.points) {
                if !r.is_empty() {
                    pieces.push((k, *kind, r));
                }
            }
        }
    }
    pieces.sort_by_key(|p| p.2.start);
    let mut out: Vec<Request> = Vec::new();
    for piece in pieces {
        match out.last_mut() {
            Some(req)
                if piece.2.start <= req.bytes.end + JOIN_GAP
                    && piece.2.end.max(req.bytes.end) - req.bytes.start <= MAX_REQUEST =>
            {
                req.bytes.end = req.bytes.end.max(piece.2.end);
                req.pieces.push(piece);
            }
            _ => out.push(Request {
                bytes: piece.2.clone(),
                pieces: vec![piece],
            }),
        }
    }
    out
}

/// The total length from a `Content-Range: bytes a-b/total` header.
pub fn total_from_content_range(value: &str) -> Option<u64> {
    let rest = value.trim().strip_prefix("bytes")?.trim_start();
    let (_, total) = rest.split_once('/')?;
    total.trim().parse().ok()
}

/// The bytes of `want` from a response body that starts at file offset `body_start` (a 206
/// answer starts at the range, a 200 answer at 0).
pub fn slice_of<'a>(body: &'a [u8], body_start: u64, want: &Range<u64>) -> Option<&'a [u8]> {
    let from = want.start.checked_sub(body_start)? as usize;
    let to = want.end.checked_sub(body_start)? as usize;
    body.get(from..to)
}

/// A store header of four pointlets of 256 points, the default layout (tests).
#[cfg(test)]
pub(crate) fn tests_header() -> StoreHeader {
    let layout = PointLayout::default();
    let mut offset = 4096;
    let mut streams = Vec::new();
    for (kind, bpp) in StreamKind::present(&layout) {
        streams.push(StreamInfo {
            kind,
            offset,
            bytes_per_point: bpp as u32,
            length: 1024 * bpp as u64,
        });
        offset = (offset + 1024 * bpp as u64).div_ceil(4096) * 4096;
    }
    let b = Aabb {
        min: [0.0; 3],
        max: [1.0; 3],
    };
    StoreHeader {
        version: 2,
        points: 1024,
        pointlets: 4,
        pointlet_size: 256,
        target_pointlets: 4,
        seed: 0,
        bounds: b,
        key_bounds: b,
        quantization: Quantization {
            scale: [0.001; 3],
            offset: [0.0; 3],
        },
        layout,
        las_point_format: 0,
        vlrs: vec![],
        las: None,
        sources: vec![],
        streams,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::Aabb;

    fn entries() -> Vec<PointletEntry> {
        (0..4)
            .map(|i| PointletEntry {
                first: i * 256,
                count: 256,
                aabb: Aabb {
                    min: [0.0; 3],
                    max: [1.0; 3],
                },
            })
            .collect()
    }

    #[test]
    fn bytes_of_a_range_follow_the_layout() {
        let h = tests_header();
        let e = entries();
        let pos = stream_bytes(&h, &e[1], StreamKind::Position, &(10..20)).unwrap();
        assert_eq!(pos, 4096 + 266 * 12..4096 + 276 * 12);
        assert!(stream_bytes(&h, &e[1], StreamKind::Position, &(10..300)).is_none());
        assert!(stream_bytes(&h, &e[1], StreamKind::Rgb, &(0..1)).is_none());
    }

    #[test]
    fn nearby_ranges_join_and_every_piece_is_kept() {
        let h = tests_header();
        let e = entries();
        let wanted: Vec<PointRange> = (0..4)
            .map(|i| PointRange {
                pointlet: i,
                points: 0..64,
            })
            .collect();
        let kinds = [StreamKind::Position, StreamKind::Classification];
        let reqs = plan(&h, &e, &wanted, &kinds);
        // The two streams lie within a join gap of each other: one request.
        assert_eq!(reqs.len(), 1);
        assert_eq!(reqs[0].pieces.len(), 8);
        for r in &reqs {
            for p in &r.pieces {
                assert!(r.bytes.start <= p.2.start && p.2.end <= r.bytes.end);
            }
        }
    }

    #[test]
    fn far_ranges_stay_apart() {
        let mut h = tests_header();
        h.streams[4].offset += 10 * JOIN_GAP;
        let reqs = plan(
            &h,
            &entries(),
            &[PointRange {
                pointlet: 0,
                points: 0..8,
            }],
            &[StreamKind::Position, StreamKind::Classification],
        );
        assert_eq!(reqs.len(), 2);
    }

    #[test]
    fn content_range_and_slices() {
        assert_eq!(total_from_content_range("bytes 0-127/5000"), Some(5000));
        assert_eq!(total_from_content_range("bytes */5000"), Some(5000));
        assert_eq!(total_from_content_range("bytes 0-127/*"), None);
        let body: Vec<u8> = (0..100).collect();
        assert_eq!(slice_of(&body, 1000, &(1010..1012)), Some(&[10u8, 11][..]));
        assert_eq!(slice_of(&body, 1000, &(990..1012)), None);
        assert_eq!(slice_of(&body, 1000, &(1090..1200)), None);
    }
}
