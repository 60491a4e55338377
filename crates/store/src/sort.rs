//! Sorting (key, input index) pairs on every core: one parallel radix pass on the keys' top
//! varying bits scatters the pairs into buckets, then each bucket is sorted on its own: one
//! comparison sort of packed keys for a bucket of up to 32 K pairs, further radix passes on its
//! own varying bits first for a larger one.
//!
//! The buckets come out in key order, so a caller can sort the first buckets and start writing
//! them while later buckets are still unsorted (the in-memory build does).

use rayon::prelude::*;

/// A (Hilbert key, input index) pair; pairs are unique, so any correct sort gives one order.
/// Packed into 12 bytes rather than a 16-byte tuple: the radix pass moves a quarter less, and
/// a run holds more points within its budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[repr(C, packed(4))]
pub(crate) struct Pair(pub u64, pub u32);

// SAFETY: two integers, packed: all-zero bytes are a valid pair.
unsafe impl bytemuck::Zeroable for Pair {}

impl Pair {
    /// `n` zero pairs from the allocator's zeroed pages, untouched until written: `vec![Pair::
    /// default(); n]` writes every pair on the calling thread first (a 200 M-point run's 2.4 GB
    /// took 1.6 s on one core before the parallel reading began).
    pub(crate) fn zeroed(n: usize) -> Vec<Pair> {
        match std::alloc::Layout::array::<Pair>(n) {
            Ok(layout) if layout.size() > 0 => {
                // SAFETY: the layout is not zero-sized.
                let ptr = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<Pair>();
                if ptr.is_null() {
                    std::alloc::handle_alloc_error(layout);
                }
                // SAFETY: allocated by the global allocator with the layout of n pairs (a
                // Vec's own for capacity n), and all-zero bytes are a valid Pair.
                unsafe { Vec::from_raw_parts(ptr, n, n) }
            }
            _ => vec![Pair::default(); n],
        }
    }

    /// Makes `v` `len` pairs long for pairs the caller overwrites, keeping none of its
    /// contents: past its capacity it is replaced by [`Pair::zeroed`] of at least `reserve`
    /// pairs (on 2 MiB pages), so that growth is neither copied nor written on this thread.
    pub(crate) fn resize_for_overwrite(v: &mut Vec<Pair>, len: usize, reserve: usize) {
        if v.capacity() < len {
            *v = Pair::zeroed(len.max(reserve));
            crate::pio::huge_pages(v);
        }
        v.resize(len, Pair::default());
    }
}

/// Most bits of the radix pass: 2^16 buckets of a few thousand pairs each sort inside the L2
/// cache.
const RADIX_BITS: u32 = 16;
/// Below this, one sort of the whole slice beats the radix pass.
const SMALL: usize = 1 << 16;

/// Pairs per bucket the radix pass aims at.
const BUCKET_PAIRS: usize = 4096;
/// Keys sampled to find how many cells of the key space are occupied.
const SAMPLES: usize = 1 << 16;

/// Bits of the radix pass for `pairs`, whose keys vary in their low `varying` bits above
/// `min`: the fewest (at most [`RADIX_BITS`]) that give the buckets a sample of the keys falls
/// in ~[`BUCKET_PAIRS`] pairs each. Points on a surface occupy a small share of the cells of
/// the key space (481 of 4096 top cells for a generated terrain), so sizing buckets by the
/// number of cells left them 40–85 K pairs each; more bits than needed cost per-chunk bucket
/// tables and the serial sum over them.
fn radix_bits(pairs: &[Pair], min: u64, varying: u32) -> u32 {
    let n = pairs.len();
    let top = varying.min(RADIX_BITS);
    let shift = varying - top;
    let base = min >> shift;
    let mut seen = vec![false; 1 << top];
    for p in pairs.iter().step_by((n / SAMPLES).max(1)) {
        seen[((p.0 >> shift) - base) as usize] = true;
    }
    for bits in 1..top {
        // Cells of the coarser pass are whole groups of 2^(top - bits) finer cells.
        let coarse = top - bits;
        let mut occupied = 0usize;
        let mut last = u64::MAX;
        for (c, _) in seen.iter().enumerate().filter(|(_, &s)| s) {
            let cell = (c as u64 + base) >> coarse;
            if cell != last {
                occupied += 1;
                last = cell;
            }
        }
        if n / occupied.max(1) <= BUCKET_PAIRS {
            return bits;
        }
    }
    top
}

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
    match radix_pass(pairs) {
        Some(RadixPass { count, shift, base }) => Buckets {
            starts: bucket_by(pairs, scratch, count, |k| ((k >> shift) - base) as usize),
        },
        None => Buckets { starts: vec![0, n] },
    }
}

/// The buckets of one radix pass: `(key >> shift) - base`, below `count`.
struct RadixPass {
    count: usize,
    shift: u32,
    base: u64,
}

/// The radix pass over the top varying bits of `pairs`' keys; `None` when every key is the
/// same.
fn radix_pass(pairs: &[Pair]) -> Option<RadixPass> {
    let (min, max) = pairs
        .par_iter()
        .fold(|| (u64::MAX, 0), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)))
        .reduce(|| (u64::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let varying = 64 - (min ^ max).leading_zeros();
    if varying == 0 {
        return None;
    }
    let bits = radix_bits(pairs, min, varying);
    let shift = varying - bits;
    let base = min >> shift;
    Some(RadixPass {
        count: ((max >> shift) - base + 1) as usize,
        shift,
        base,
    })
}

/// Scatters `pairs` into `nb` buckets by `bucket` (below `nb` for every key), in bucket order
/// and stable inside a bucket, on every core; returns where each bucket starts (and the end).
pub(crate) fn bucket_by(
    pairs: &mut Vec<Pair>,
    scratch: &mut Vec<Pair>,
    nb: usize,
    bucket: impl Fn(u64) -> usize + Sync,
) -> Vec<usize> {
    let n = pairs.len();
    scratch.clear();
    scratch.reserve_exact(n);
    crate::pio::huge_pages(scratch);
    let dst = SharedOut(scratch.spare_capacity_mut().as_mut_ptr().cast::<Pair>());
    // SAFETY: the spare capacity holds n pairs; `bucket` stays below nb.
    let starts = unsafe { scatter_by(pairs, &dst, nb, bucket) };
    // SAFETY: the scatter wrote every one of the n slots exactly once.
    unsafe { scratch.set_len(n) };
    std::mem::swap(pairs, scratch);
    starts
}

/// Writes `pairs` to `dst` by `bucket` (stable inside a bucket), every one of `pairs.len()`
/// slots once, and returns the `nb + 1` bucket boundaries.
///
/// # Safety
/// `dst` must be valid for writes of `pairs.len()` pairs that nothing else touches meanwhile,
/// and `bucket` below `nb` for every key of `pairs`.
unsafe fn scatter_by(
    pairs: &[Pair],
    dst: &SharedOut,
    nb: usize,
    bucket: impl Fn(u64) -> usize + Sync,
) -> Vec<usize> {
    let n = pairs.len();
    // A few chunks per thread: each counts its pairs per bucket, then scatters them.
    let chunk = n.div_ceil(rayon::current_num_threads() * 4).max(SMALL / 4);
    // Each chunk's count of pairs per bucket, turned in place into its first slot in each.
    let mut offsets: Vec<Vec<usize>> = pairs
        .par_chunks(chunk)
        .map(|c| {
            let mut h = vec![0usize; nb];
            for p in c {
                h[bucket(p.0)] += 1;
            }
            h
        })
        .collect();
    // The sums over chunks go a block of buckets per task: 2^16 buckets of 64 chunks summed
    // on one thread took 40 ms while the other cores waited (GPU machine, 200 M points).
    let block = nb.div_ceil(rayon::current_num_threads() * 4).max(1024);
    let block_count = nb.div_ceil(block);
    let buckets_of = |j: usize| j * block..((j + 1) * block).min(nb);
    let totals: Vec<usize> = (0..block_count)
        .into_par_iter()
        .flat_map_iter(|j| {
            let mut t = vec![0usize; buckets_of(j).len()];
            for h in &offsets {
                for (t, n) in t.iter_mut().zip(&h[buckets_of(j)]) {
                    *t += n;
                }
            }
            t
        })
        .collect();
    let mut starts = Vec::with_capacity(nb + 1);
    let mut at = 0usize;
    for t in totals {
        starts.push(at);
        at += t;
    }
    starts.push(at);
    let mut blocks: Vec<Vec<&mut [usize]>> = (0..block_count)
        .map(|_| Vec::with_capacity(offsets.len()))
        .collect();
    for h in offsets.iter_mut() {
        for (b, part) in blocks.iter_mut().zip(h.chunks_mut(block)) {
            b.push(part);
        }
    }
    blocks.into_par_iter().enumerate().for_each(|(j, parts)| {
        let mut at = starts[buckets_of(j)].to_vec();
        for part in parts {
            for (o, a) in part.iter_mut().zip(at.iter_mut()) {
                let n = *o;
                *o = *a;
                *a += n;
            }
        }
    });
    pairs
        .par_chunks(chunk)
        .zip(offsets.into_par_iter())
        .for_each(|(c, mut off)| {
            for p in c {
                let b = bucket(p.0);
                // SAFETY: the offsets give every (chunk, bucket) its own range of slots, all
                // below n (they add up to n), and the caller gives n writable slots.
                unsafe { dst.0.add(off[b]).write(*p) };
                off[b] += 1;
            }
        });
    starts
}

/// Sorts buckets `range` of `pairs` (each on its own, in parallel).
pub(crate) fn sort_buckets(pairs: &mut [Pair], buckets: &Buckets, range: std::ops::Range<usize>) {
    sort_buckets_at(pairs, 0, buckets, range);
}

/// [`sort_buckets`] where `pairs` starts at position `base` of the bucketed array. Every
/// bucket of two pairs or more is a task of its own: with rayon's default split one thread
/// worked through the sequential splits of a run of large buckets for 40 ms while the other
/// cores waited (a stretch of 25 K buckets, most of them empty; GPU machine, 200 M points,
/// docs/BENCHMARKS.md, session 57).
pub(crate) fn sort_buckets_at(
    pairs: &mut [Pair],
    base: usize,
    buckets: &Buckets,
    range: std::ops::Range<usize>,
) {
    if range.is_empty() {
        return;
    }
    let (lo, hi) = (buckets.starts[range.start], buckets.starts[range.end]);
    let mut tasks = bucket_slices(&mut pairs[lo - base..hi - base], buckets, range);
    tasks.retain(|s| s.len() > 1);
    tasks
        .into_par_iter()
        .with_max_len(1)
        .for_each(|s| with_second(s.len(), |tmp| sort_bucket(s, tmp)));
}

thread_local! {
    /// Each thread's second array for the buckets it sorts, out of the cell while in use (a
    /// nested parallel sort may start another bucket on the same thread meanwhile). A task's
    /// own would be megabytes of new pages to fault in and unmap again for every bucket.
    static SECOND: std::cell::Cell<Vec<Pair>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Pairs a thread's kept second array holds at most (3 MiB).
const SECOND_MAX: usize = 1 << 18;

/// Runs `f` with `n` pairs of this thread's second array; above [`SECOND_MAX`] pairs with an
/// array of its own, so that no thread keeps more than a few megabytes.
fn with_second<R>(n: usize, f: impl FnOnce(&mut [Pair]) -> R) -> R {
    if n > SECOND_MAX {
        return f(&mut vec![Pair::default(); n]);
    }
    let mut tmp = SECOND.take();
    if tmp.len() < n {
        tmp.resize(n, Pair::default());
    }
    let r = f(&mut tmp[..n]);
    let other = SECOND.take();
    SECOND.set(if other.len() > tmp.len() { other } else { tmp });
    r
}

/// Frees the second arrays of every thread of the pool (at most [`SECOND_MAX`] pairs each).
pub(crate) fn release_second_arrays() {
    rayon::broadcast(|_| drop(SECOND.take()));
}

/// [`sort_buckets`] of every bucket, with `tmp` (as long as `pairs`) as the second array.
pub(crate) fn sort_buckets_in(pairs: &mut [Pair], tmp: &mut [Pair], buckets: &Buckets) {
    for_each_bucket(pairs, tmp, buckets, |_, s, t| {
        if s.len() > 1 {
            sort_bucket(s, t)
        }
    });
}

/// Runs `f(j, a_j, b_j)` on bucket `j`'s slices of `a` and of `b` (as long as `a`), in
/// parallel; empty buckets are left out. A group's or a large bucket's buckets hold from none
/// to many thousands of pairs: the larger ones are each a task of their own, as in
/// `sort_buckets_at`.
fn for_each_bucket(
    a: &mut [Pair],
    b: &mut [Pair],
    buckets: &Buckets,
    f: impl Fn(usize, &mut [Pair], &mut [Pair]) + Sync,
) {
    let all = 0..buckets.len();
    let (large, small): (Vec<_>, Vec<_>) = bucket_slices(a, buckets, all.clone())
        .into_iter()
        .zip(bucket_slices(b, buckets, all))
        .enumerate()
        .filter(|(_, (s, _))| !s.is_empty())
        .partition(|(_, (s, _))| s.len() > PARALLEL / 8);
    rayon::join(
        || {
            large
                .into_par_iter()
                .with_max_len(1)
                .for_each(|(j, (s, t))| f(j, s, t))
        },
        || small.into_par_iter().for_each(|(j, (s, t))| f(j, s, t)),
    );
}

/// `pairs` (buckets `range` of a bucketed array, nothing else) cut at the bucket boundaries.
fn bucket_slices<'a>(
    mut pairs: &'a mut [Pair],
    buckets: &Buckets,
    range: std::ops::Range<usize>,
) -> Vec<&'a mut [Pair]> {
    let mut slices = Vec::with_capacity(range.len());
    for b in range {
        let len = buckets.starts[b + 1] - buckets.starts[b];
        let (head, tail) = std::mem::take(&mut pairs).split_at_mut(len);
        slices.push(head);
        pairs = tail;
    }
    slices
}

/// Up to this many pairs whose keys do not pack, a comparison sort finishes a bucket.
const LEAF: usize = 256;
/// Above this many pairs a bucket is split by a parallel pass: points on a surface fill few of
/// the top cells, and a dataset with a far outlier puts almost every point in one bucket.
const LARGE: usize = 1 << 20;
/// Above this many pairs the sub-buckets of a bucket are sorted in parallel; up to it a bucket
/// is sorted whole as packed keys.
const PARALLEL: usize = 1 << 15;

/// Sorts one bucket: up to [`PARALLEL`] pairs as packed keys ([`sort_packed`]), a larger one
/// (or one whose keys do not pack) by radix passes on its own varying bits (at most 13 at a
/// time) first. Buckets come out larger than planned where keys cluster below the sample's
/// resolution.
fn sort_bucket(s: &mut [Pair], tmp: &mut [Pair]) {
    let n = s.len();
    if n < 2 {
        return;
    }
    if n > LARGE {
        let Some(RadixPass { count, shift, base }) = radix_pass(s) else {
            return s.par_sort_unstable();
        };
        let dst = SharedOut(tmp.as_mut_ptr());
        // SAFETY: `tmp` holds n pairs, borrowed mutably here only; the pass's buckets are
        // below `count` for every key of `s`.
        let starts = unsafe { scatter_by(s, &dst, count, |k| ((k >> shift) - base) as usize) };
        return sort_cells_into(tmp, s, starts, base, shift);
    }
    let (min, max) = s
        .iter()
        .fold((u64::MAX, 0), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)));
    let varying = 64 - (min ^ max).leading_zeros();
    if varying == 0 {
        return s.sort_unstable();
    }
    if n <= PARALLEL {
        if let Some(place_bits) = packing(n, max - min) {
            return PACKED.with_borrow_mut(|packed| {
                packed.resize(n, 0);
                sort_packed(s, tmp, packed, min, place_bits);
            });
        }
    }
    if n <= LEAF {
        // Pairs are unique, so the unstable sort of (key, index) gives the one order.
        return s.sort_unstable();
    }
    // Points on a surface fill about 2^(2b/3) of a bucket's 2^b sub-cells: three bits more
    // than ~64 pairs a sub-bucket would need leave a few hundred a sub-bucket there
    // (`sort_time` at 100 M on dev, buckets of 48 K pairs: 1.22 and 1.29 s against 1.51 and
    // 1.56, two runs' means).
    let bits = varying.min(((n / 64).ilog2() + 3).clamp(1, 13));
    let shift = varying - bits;
    let base = min >> shift;
    let mut starts = vec![0usize; ((max >> shift) - base + 2) as usize];
    for p in s.iter() {
        starts[((p.0 >> shift) - base) as usize + 1] += 1;
    }
    for b in 1..starts.len() {
        starts[b] += starts[b - 1];
    }
    let mut at = starts.clone();
    for p in s.iter() {
        let b = ((p.0 >> shift) - base) as usize;
        tmp[at[b]] = *p;
        at[b] += 1;
    }
    // Each sub-bucket is sorted from `tmp` back into its place in `s`: no copy back first.
    if n > PARALLEL {
        // One thread sorting a bucket of a million pairs while the others had nothing left
        // to do stalled the in-memory writing stage for up to 0.1 s at a time.
        return sort_cells_into(tmp, s, starts, base, shift);
    }
    for (j, w) in starts.windows(2).enumerate() {
        let lo = (base + j as u64) << shift;
        sort_into(&mut tmp[w[0]..w[1]], &mut s[w[0]..w[1]], lo, shift);
    }
}

/// Sorts the cells of a radix pass on bits from `shift` (cell `j` holds keys from
/// `(base + j) << shift`, from `starts[j]` in `from`) into their places in `to`, in parallel.
fn sort_cells_into(from: &mut [Pair], to: &mut [Pair], starts: Vec<usize>, base: u64, shift: u32) {
    for_each_bucket(from, to, &Buckets { starts }, |j, from, to| {
        sort_into(from, to, (base + j as u64) << shift, shift)
    });
}

/// Sorts the pairs of `from`, whose keys lie in `lo..lo + 2^shift` (a sub-bucket), into `to`
/// (as long), leaving `from` as scratch: packed keys where they pack, else copied over and
/// sorted by [`sort_bucket`].
fn sort_into(from: &mut [Pair], to: &mut [Pair], lo: u64, shift: u32) {
    let n = from.len();
    if (2..=PARALLEL).contains(&n) {
        // The sub-bucket's span, not its keys' own: no pass to find them.
        if let Some(place_bits) = packing(n, (1u64 << shift) - 1) {
            return PACKED.with_borrow_mut(|packed| {
                packed.resize(n, 0);
                sort_packed_into(from, to, packed, lo, place_bits);
            });
        }
    }
    to.copy_from_slice(from);
    sort_bucket(to, from);
}

thread_local! {
    /// Each thread's packed keys for [`sort_bucket`]: at most [`PARALLEL`] of them (256 KiB).
    static PACKED: std::cell::RefCell<Vec<u64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Bits for a pair's place among `n` when its key's offset from the smallest, below `span`,
/// and its place pack into one `u64`; `None` when they do not (keys spanning nearly 64 bits).
fn packing(n: usize, span: u64) -> Option<u32> {
    let place_bits = usize::BITS - n.saturating_sub(1).leading_zeros();
    (64 - span.leading_zeros() + place_bits <= 64).then_some(place_bits)
}

/// Sorts `s` (keys from `min`, [`packing`] gave `place_bits`) through `packed`, one `u64` a
/// pair of its key's offset above its place: plain integers sort without unpredictable
/// branches and move two thirds of a pair's bytes; a bucket of a few thousand pairs sorted so
/// took ~20 % less time than radix passes down to leaves of ~64 (`sort_time`, dev). `copy`
/// is as long as `s`.
fn sort_packed(s: &mut [Pair], copy: &mut [Pair], packed: &mut [u64], min: u64, place_bits: u32) {
    copy.copy_from_slice(s);
    sort_packed_into(copy, s, packed, min, place_bits);
}

/// [`sort_packed`] of `from` into `to` (as long). Equal keys come out in place order, and get
/// index order after.
fn sort_packed_into(from: &[Pair], to: &mut [Pair], packed: &mut [u64], min: u64, place_bits: u32) {
    for (j, (q, p)) in packed.iter_mut().zip(from.iter()).enumerate() {
        *q = (p.0 - min) << place_bits | j as u64;
    }
    packed.sort_unstable();
    let place = (1u64 << place_bits) - 1;
    for (p, q) in to.iter_mut().zip(packed.iter()) {
        *p = from[(*q & place) as usize];
    }
    // Runs of equal keys (points given twice) in index order.
    let mut i = 0;
    while i < to.len() {
        let run = to[i..].iter().take_while(|p| p.0 == to[i].0).count();
        if run > 1 {
            to[i..i + run].sort_unstable_by_key(|p| p.1);
        }
        i += run;
    }
}

/// Sorts pairs by key, ties by input index.
#[cfg(test)]
fn sort_pairs(pairs: &mut Vec<Pair>) {
    sort_pairs_with(pairs, &mut Vec::new());
}

/// [`sort_pairs`] with the radix pass's second array given.
#[cfg(test)]
fn sort_pairs_with(pairs: &mut Vec<Pair>, scratch: &mut Vec<Pair>) {
    let buckets = partition(pairs, scratch);
    // The radix pass's first array (already `pairs.len()` long after a scatter) is free now:
    // the buckets' sorts use it, so a spilled run's sort needs no memory beyond the two arrays
    // the budget counts.
    scratch.resize(pairs.len(), Pair::default());
    sort_buckets_in(pairs, scratch, &buckets);
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
        // As the in-memory build sorts: bucketed, then two stretches of buckets on their own.
        let mut stretched = pairs.clone();
        let buckets = partition(&mut stretched, &mut Vec::new());
        let half = buckets.len() / 2;
        let (first, rest) = stretched.split_at_mut(buckets.starts[half]);
        sort_buckets(first, &buckets, 0..half);
        sort_buckets_at(rest, buckets.starts[half], &buckets, half..buckets.len());
        assert!(stretched == want, "sorted in stretches");
        sort_pairs(&mut pairs);
        assert!(pairs == want, "sorted at once");
    }

    #[test]
    fn buckets_hold_a_few_thousand_pairs() {
        let mut rng = SplitMix64::new(11);
        let bits = |pairs: &[Pair]| {
            let min = pairs.iter().map(|p| p.0).min().unwrap_or(0);
            let max = pairs.iter().map(|p| p.0).max().unwrap_or(0);
            radix_bits(pairs, min, 64 - (min ^ max).leading_zeros())
        };
        // Keys over the whole space: 2^b cells of ~4096 pairs.
        let uniform: Vec<Pair> = (0..4_000_000)
            .map(|i| Pair(rng.next_u64() >> 4, i))
            .collect();
        assert_eq!(bits(&uniform), 10);
        // The same count in 1 of every 8 top cells (a surface): three more bits.
        let surface: Vec<Pair> = uniform
            .iter()
            .map(|p| Pair(p.0 & !(7 << 56), p.1))
            .collect();
        assert_eq!(bits(&surface), 13);
        // Never past RADIX_BITS, however many pairs; keys varying in fewer bits use those.
        let many: Vec<Pair> = (0..1_000_000)
            .map(|i| Pair(rng.next_u64() >> 1, i))
            .collect();
        assert!(bits(&many) <= RADIX_BITS);
        let narrow: Vec<Pair> = (0..1_000_000).map(|i| Pair(rng.below(8), i)).collect();
        assert_eq!(bits(&narrow), 3);
    }

    #[test]
    fn sorts_like_a_comparison_sort() {
        let mut rng = SplitMix64::new(7);
        let n = 300_000;
        // Keys spread over 63 bits, clustered in a narrow range, and with many ties.
        check(
            (0..n)
                .map(|i| Pair(rng.next_u64() >> 1, i as u32))
                .collect(),
        );
        check(
            (0..n)
                .map(|i| Pair((1 << 40) + rng.below(1 << 20), i as u32))
                .collect(),
        );
        check((0..n).map(|i| Pair(rng.below(5), i as u32)).collect());
        check((0..n).map(|i| Pair(42, i as u32)).collect());
        check((0..1000).map(|i| Pair(rng.next_u64(), i as u32)).collect());
        // Keys spanning all 64 bits but nearly all in the first sub-bucket, which does not
        // pack at its sub-bucket's span and is sorted on its own keys' span instead.
        check(
            (0..300)
                .map(|i| Pair(if i == 7 { u64::MAX } else { rng.below(1 << 20) }, i))
                .collect(),
        );
        check(Vec::new());
        // Pairs out of index order, and a far outlier that leaves almost every pair in one
        // top bucket (split again by a parallel pass).
        let mut far: Vec<Pair> = (0..1_200_000)
            .map(|i: u32| {
                Pair(
                    (1 << 40) + rng.below(1 << 24),
                    (i as u64 * 7919 % 1_200_001) as u32,
                )
            })
            .collect();
        far.push(Pair(u64::MAX >> 1, 1_200_000));
        check(far);
        // A dense cluster below the sample's resolution: one bucket of 200 k pairs, whose
        // sub-buckets are sorted in parallel.
        check(
            (0..300_000u32)
                .map(|i| match i % 3 {
                    0 => Pair(rng.next_u64() >> 1, i),
                    _ => Pair((1 << 50) + rng.below(1 << 20), i),
                })
                .collect(),
        );
        // Points of a surface: every key in a few narrow bands, with duplicates.
        check(
            (0..400_000u32)
                .map(|i| Pair((rng.below(8) << 50) + rng.below(1 << 12) * 977, i))
                .collect(),
        );
    }

    #[test]
    fn buckets_are_in_key_order_and_cover_every_pair() {
        let mut rng = SplitMix64::new(3);
        let mut pairs: Vec<Pair> = (0..200_000).map(|i| Pair(rng.next_u64() >> 1, i)).collect();
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

    /// Sort time of a spilled run's worth of surface points (5 M, a terrain seen from above;
    /// `SORT_TIME_POINTS` others), the radix pass and the buckets apart, checked against a
    /// comparison sort:
    /// `cargo test --release -p pointlet-store --lib sort_time -- --ignored --nocapture`.
    #[test]
    #[ignore = "a timing, not a check"]
    fn sort_time_of_surface_points() {
        let n: u32 = std::env::var("SORT_TIME_POINTS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(5_000_000);
        let grid = pointlet_core::codes::KeyGrid::new(&pointlet_core::Aabb {
            min: [0.0; 3],
            max: [1000.0, 1000.0, 100.0],
        });
        let pairs: Vec<Pair> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut rng = SplitMix64::new(5 ^ u64::from(i) << 20);
                let (x, y) = (rng.below(1 << 20) as f64, rng.below(1 << 20) as f64);
                let (x, y) = (x / 1048.576, y / 1048.576);
                let z = 50.0 + 20.0 * (x / 90.0).sin() * (y / 70.0).cos();
                Pair(grid.hilbert([x, y, z]), i)
            })
            .collect();
        let mut scratch = Vec::new();
        let mut want = pairs.clone();
        want.par_sort_unstable();
        for round in 0..5 {
            let mut p = pairs.clone();
            let t = std::time::Instant::now();
            let buckets = partition(&mut p, &mut scratch);
            let parted = t.elapsed();
            scratch.resize(p.len(), Pair::default());
            sort_buckets_in(&mut p, &mut scratch, &buckets);
            let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
            let sizes = buckets.starts.windows(2).map(|w| w[1] - w[0]);
            let over = sizes.filter(|&s| s > PARALLEL).count();
            eprintln!(
                "round {round}: partition {:.1} ms, buckets {:.1} ms ({} buckets, {over} over {PARALLEL} pairs)",
                ms(parted),
                ms(t.elapsed() - parted),
                buckets.len(),
            );
            assert!(p == want);
        }
    }
}
