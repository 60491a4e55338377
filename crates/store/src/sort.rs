//! Sorting (key, input index) pairs on every core: one parallel radix pass on the keys' top
//! varying bits scatters the pairs into buckets, then each bucket is sorted on its own.
//!
//! The buckets come out in key order, so a caller can sort the first buckets and start writing
//! them while later buckets are still unsorted (the in-memory build does).

use rayon::prelude::*;

/// A (Hilbert key, input index) pair; pairs are unique, so any correct sort gives one order.
pub(crate) type Pair = (u64, u32);

/// Most bits of the radix pass: 2^16 buckets of a few thousand pairs each sort inside the L2
/// cache.
const RADIX_BITS: u32 = 16;
/// Below this, one sort of the whole slice beats the radix pass.
const SMALL: usize = 1 << 16;

/// Bits of the radix pass for `n` pairs: buckets of ~[`BUCKET_PAIRS`] on average, at most
/// [`RADIX_BITS`]. A spilled run of a few million pairs in 2^16 buckets spent most of its sort
/// on per-chunk bucket tables and the serial sum over them.
fn radix_bits(n: usize) -> u32 {
    let buckets = (n / BUCKET_PAIRS).max(2);
    (usize::BITS - 1 - buckets.leading_zeros()).min(RADIX_BITS)
}

/// Pairs per bucket the radix pass aims at.
const BUCKET_PAIRS: usize = 4096;

/// Bucket boundaries: bucket `b` is `pairs[starts[b]..starts[b + 1]]`.
pub(crate) struct Buckets {
    pub starts: Vec<usize>,
}

impl Buckets {
    pub fn len(&self) -> usize {
        self.starts.len() - 1
    }

    /// Buckets that hold any of the first `n` positions: `0..count`.
    pub fn covering(&self, n: usize) -> usize {
        self.starts[..self.len()].partition_point(|&s| s < n)
    }
}

/// Scatters `pairs` into buckets by the top varying bits of their keys (in key order, unsorted
/// inside, in their input order). `scratch` is grown to `pairs.len()` and left holding garbage.
pub(crate) fn partition(pairs: &mut Vec<Pair>, scratch: &mut Vec<Pair>) -> Buckets {
    let n = pairs.len();
    if n < SMALL {
        return Buckets { starts: vec![0, n] };
    }
    let (min, max) = pairs
        .par_iter()
        .fold(|| (u64::MAX, 0), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)))
        .reduce(|| (u64::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let varying = 64 - (min ^ max).leading_zeros();
    if varying == 0 {
        return Buckets { starts: vec![0, n] };
    }
    let bits = varying.min(radix_bits(n));
    let shift = varying - bits;
    let base = min >> shift;
    let nb = ((max >> shift) - base + 1) as usize;
    let bucket = |k: u64| ((k >> shift) - base) as usize;
    // A few chunks per thread: each counts its pairs per bucket, then scatters them.
    let chunk = n.div_ceil(rayon::current_num_threads() * 4).max(SMALL / 4);
    let counts: Vec<Vec<u32>> = pairs
        .par_chunks(chunk)
        .map(|c| {
            let mut h = vec![0u32; nb];
            for p in c {
                h[bucket(p.0)] += 1;
            }
            h
        })
        .collect();
    let mut starts = Vec::with_capacity(nb + 1);
    let mut offsets: Vec<Vec<usize>> = vec![vec![0; nb]; counts.len()];
    let mut at = 0usize;
    for b in 0..nb {
        starts.push(at);
        for (c, h) in counts.iter().enumerate() {
            offsets[c][b] = at;
            at += h[b] as usize;
        }
    }
    starts.push(at);
    scratch.clear();
    scratch.reserve_exact(n);
    let out = SharedOut(scratch.spare_capacity_mut().as_mut_ptr().cast::<Pair>());
    pairs
        .par_chunks(chunk)
        .zip(offsets.into_par_iter())
        .for_each(|(c, mut off)| {
            let out = &out;
            for p in c {
                let b = bucket(p.0);
                // SAFETY: the offsets give every (chunk, bucket) its own range of slots, all
                // below n (they add up to n), so no two writes touch the same slot.
                unsafe { out.0.add(off[b]).write(*p) };
                off[b] += 1;
            }
        });
    // SAFETY: the scatter wrote every one of the n slots exactly once.
    unsafe { scratch.set_len(n) };
    std::mem::swap(pairs, scratch);
    Buckets { starts }
}

/// Sorts buckets `range` of `pairs` (each on its own, in parallel).
pub(crate) fn sort_buckets(pairs: &mut [Pair], buckets: &Buckets, range: std::ops::Range<usize>) {
    if range.is_empty() {
        return;
    }
    let (lo, hi) = (buckets.starts[range.start], buckets.starts[range.end]);
    let mut slices = Vec::with_capacity(range.len());
    let mut rest = &mut pairs[lo..hi];
    for b in range {
        let len = buckets.starts[b + 1] - buckets.starts[b];
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(len);
        slices.push(head);
        rest = tail;
    }
    // The scatter keeps input order inside a bucket and pairs come in index order, so a stable
    // sort on the key alone gives the (key, index) order, with cheaper comparisons. Large
    // buckets (points on a surface fill few of the top cells) are split over threads too: a
    // block being written may need only a few of them.
    slices.into_par_iter().for_each(|s| {
        if s.len() > SMALL {
            s.par_sort_by_key(|p| p.0);
        } else {
            s.sort_by_key(|p| p.0);
        }
    });
}

/// Sorts pairs by key, ties by input index. Pairs must come in index order (each run's pairs
/// do: index i at position i), which lets equal keys keep their order instead of comparing
/// indices.
pub(crate) fn sort_pairs(pairs: &mut Vec<Pair>) {
    sort_pairs_with(pairs, &mut Vec::new());
}

/// [`sort_pairs`] with the radix pass's second array given (and kept: a run spilled after
/// another reuses it instead of faulting in fresh pages).
pub(crate) fn sort_pairs_with(pairs: &mut Vec<Pair>, scratch: &mut Vec<Pair>) {
    let buckets = partition(pairs, scratch);
    sort_buckets(pairs, &buckets, 0..buckets.len());
}

/// The scatter's output, shared by the threads that write disjoint slots of it.
struct SharedOut(*mut Pair);
// SAFETY: threads write disjoint slots only (see `partition`).
unsafe impl Sync for SharedOut {}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::shuffle::SplitMix64;

    fn check(mut pairs: Vec<Pair>) {
        let mut want = pairs.clone();
        want.sort_unstable();
        sort_pairs(&mut pairs);
        assert_eq!(pairs, want);
    }

    #[test]
    fn buckets_hold_a_few_thousand_pairs() {
        assert_eq!(radix_bits(0), 1);
        assert_eq!(radix_bits(SMALL), 4);
        assert_eq!(radix_bits(5_500_000), 10);
        assert_eq!(radix_bits(200_000_000), 15);
        assert_eq!(radix_bits(usize::MAX), RADIX_BITS);
    }

    #[test]
    fn sorts_like_a_comparison_sort() {
        let mut rng = SplitMix64::new(7);
        let n = 300_000;
        // Keys spread over 63 bits, clustered in a narrow range, and with many ties.
        check((0..n).map(|i| (rng.next_u64() >> 1, i as u32)).collect());
        check(
            (0..n)
                .map(|i| ((1 << 40) + rng.below(1 << 20), i as u32))
                .collect(),
        );
        check((0..n).map(|i| (rng.below(5), i as u32)).collect());
        check((0..n).map(|i| (42, i as u32)).collect());
        check((0..1000).map(|i| (rng.next_u64(), i as u32)).collect());
        check(Vec::new());
    }

    #[test]
    fn buckets_are_in_key_order_and_cover_every_pair() {
        let mut rng = SplitMix64::new(3);
        let mut pairs: Vec<Pair> = (0..200_000).map(|i| (rng.next_u64() >> 1, i)).collect();
        let mut scratch = Vec::new();
        let buckets = partition(&mut pairs, &mut scratch);
        assert!(buckets.len() > 1);
        assert_eq!(*buckets.starts.last().unwrap(), pairs.len());
        for b in 1..buckets.len() {
            let prev = &pairs[buckets.starts[b - 1]..buckets.starts[b]];
            let this = &pairs[buckets.starts[b]..buckets.starts[b + 1]];
            let prev_max = prev.iter().map(|p| p.0).max();
            let this_min = this.iter().map(|p| p.0).min();
            if let (Some(a), Some(b)) = (prev_max, this_min) {
                assert!(a < b);
            }
        }
        assert_eq!(buckets.covering(0), 0);
        assert_eq!(buckets.covering(1), 1);
        assert_eq!(buckets.covering(pairs.len()), buckets.len());
    }
}
