//! The out-of-core build's last phase: the spilled runs read back a group of buckets at a
//! time, each group sorted in memory and emitted while the next one is read and sorted.
//!
//! Runs hold their records grouped by key bucket ([`Bucketing`]), in input order inside a
//! bucket, and runs come in input order; so a group's records, read run after run, need only
//! the in-memory sort by (key, place) to stand in the total order of the in-memory build. A
//! group ends on a bucket boundary, not on a pointlet's: the records of the pointlet it leaves
//! unfinished (all with smaller keys than the next group's) go before the next group's.

use crate::builder::{key_rows, report, Progress};
use crate::emit::{Emitter, Source};
use crate::runs::{self, Bucketing, RunFile};
use crate::sort::{self, Pair};
use crate::{pio, BuildPhase, StoreError};
use pointlet_core::codes::KeyGrid;
use pointlet_core::Quantization;
use rayon::prelude::*;
use std::path::Path;

/// Bytes read by one task: a large piece of a run is read by several threads.
const READ_BYTES: usize = 4 << 20;

/// Records `from..to` of one run.
#[derive(Clone, Copy)]
struct Piece<'a> {
    run: &'a RunFile,
    from: u64,
    to: u64,
}

impl Piece<'_> {
    fn len(&self) -> usize {
        (self.to - self.from) as usize
    }
}

/// What a group reads, and where its buckets' records land: pieces are read one after
/// another (a run's buckets are one stretch of its file), while the pairs are laid out bucket
/// by bucket, so that the sort needs no pass to bucket them.
struct Load<'a> {
    pieces: Vec<Piece<'a>>,
    /// Stretches (first, count) of the records read, bucket by bucket in key order, each
    /// bucket's in run order.
    segments: Vec<(usize, usize)>,
    /// Where each bucket's segments end.
    bucket_ends: Vec<usize>,
}

impl<'a> Load<'a> {
    /// Stretches of one bucket, in run order: read order is bucket order.
    fn one_bucket(pieces: Vec<Piece<'a>>) -> Load<'a> {
        let mut at = 0;
        let segments = pieces
            .iter()
            .map(|p| {
                at += p.len();
                (at - p.len(), p.len())
            })
            .collect::<Vec<_>>();
        Load {
            bucket_ends: vec![segments.len()],
            pieces,
            segments,
        }
    }

    /// Buckets `range` of every run.
    fn buckets(runs: &'a [RunFile], range: std::ops::Range<usize>) -> Result<Load<'a>, StoreError> {
        let (mut pieces, mut bases, mut starts) = (Vec::new(), Vec::new(), Vec::new());
        let mut at = 0;
        for run in runs {
            let s = run.starts(range.clone())?;
            let (from, to) = (s[0], s[s.len() - 1]);
            if to > from {
                pieces.push(Piece { run, from, to });
                bases.push(at);
                starts.push(s);
                at += (to - from) as usize;
            }
        }
        let (mut segments, mut bucket_ends) = (Vec::new(), Vec::new());
        for j in 0..range.len() {
            for ((p, &base), s) in pieces.iter().zip(&bases).zip(&starts) {
                let (from, to) = (s[j], s[j + 1]);
                if to > from {
                    segments.push((base + (from - p.from) as usize, (to - from) as usize));
                }
            }
            if bucket_ends.last() != Some(&segments.len()) {
                bucket_ends.push(segments.len());
            }
        }
        Ok(Load {
            pieces,
            segments,
            bucket_ends,
        })
    }
}

/// A group in memory: records and their pairs, sorted; `first` is the sorted position of
/// `pairs[0]` (a pointlet's first point), and the first `whole` of them are emitted with it.
#[derive(Default)]
struct Group {
    /// At least `len` records long (kept at its longest so reuse does not zero it again).
    records: Vec<u8>,
    pairs: Vec<Pair>,
    len: usize,
    first: u64,
    whole: usize,
}

/// What the phase needs to know of the build.
pub(crate) struct GroupSettings<'a> {
    pub quantization: Quantization,
    pub grid: KeyGrid,
    /// Records a group holds at most (the records of an unfinished pointlet may come on top).
    pub capacity: usize,
    /// Pointlets emitted as one block.
    pub step: u64,
    /// Bytes gathered at a time when a bucket too large for a group is spilled again.
    pub io_chunk: usize,
    pub run_dir: &'a Path,
    pub run_maps: &'a runs::RunMaps,
    pub stem: &'a str,
    pub progress: Progress,
}

/// Reads, sorts and emits the spilled runs' groups in key order.
pub(crate) struct GroupSorter<'e, 'a> {
    em: &'e Emitter<'a>,
    set: GroupSettings<'e>,
    rb: usize,
    /// Sorted and waiting to be emitted.
    pending: Option<Group>,
    spare: Group,
    scratch: Vec<Pair>,
    /// The keys of the records a group reads (after its carried ones), in the same order.
    keys: Vec<u64>,
    /// Records, in sorted order, of the pointlet the last group left unfinished.
    carry: Vec<u8>,
    /// Sorted position of the next group's first record (its carried records included).
    next_first: u64,
}

impl<'e, 'a> GroupSorter<'e, 'a> {
    pub fn new(em: &'e Emitter<'a>, set: GroupSettings<'e>) -> Self {
        GroupSorter {
            rb: em.record_len(),
            em,
            set,
            pending: None,
            spare: Group::default(),
            scratch: Vec::new(),
            keys: Vec::new(),
            carry: Vec::new(),
            next_first: 0,
        }
    }

    /// Emits every record of `runs`, bucketed by `b`, in sorted order.
    pub fn walk(&mut self, runs: &[RunFile], b: Bucketing) -> Result<(), StoreError> {
        let mut totals = vec![0u64; b.count];
        for run in runs {
            let starts = run.starts(0..b.count)?;
            for (t, w) in totals.iter_mut().zip(starts.windows(2)) {
                *t += w[1] - w[0];
            }
        }
        let cap = self.set.capacity as u64;
        let mut i = 0;
        while i < b.count {
            if totals[i] == 0 {
                i += 1;
                continue;
            }
            if totals[i] > cap {
                match b.within(i) {
                    Some(finer) => {
                        let again = self.spill_again(runs, i, finer)?;
                        self.walk(&again, finer)?;
                    }
                    // One key: its records are in sorted order already, taken as they come.
                    None => {
                        for chunk in chunks(runs, i, self.set.capacity)? {
                            self.push(&Load::one_bucket(chunk))?;
                        }
                    }
                }
                i += 1;
                continue;
            }
            // Buckets while the group has room; always at least one.
            let room = cap.saturating_sub((self.carry.len() / self.rb) as u64);
            let (mut j, mut sum) = (i, 0u64);
            while j < b.count && totals[j] <= cap && (j == i || sum + totals[j] <= room) {
                sum += totals[j];
                j += 1;
            }
            self.push(&Load::buckets(runs, i..j)?)?;
            i = j;
        }
        Ok(())
    }

    /// Emits the last group; fails unless every point was emitted.
    pub fn finish(mut self) -> Result<(), StoreError> {
        self.flush()?;
        if self.next_first != self.em.points() || !self.carry.is_empty() {
            return Err(StoreError::build(
                self.em.path(),
                format!(
                    "internal error: the runs gave {} of {} points",
                    self.next_first + (self.carry.len() / self.rb) as u64,
                    self.em.points()
                ),
            ));
        }
        Ok(())
    }

    /// Reads and sorts the records `load` names (after the carried ones) while the pending
    /// group is emitted; the new group waits in turn.
    fn push(&mut self, load: &Load<'_>) -> Result<(), StoreError> {
        let mut group = std::mem::take(&mut self.spare);
        let pending = self.pending.take();
        let mut scratch = std::mem::take(&mut self.scratch);
        let mut keys = std::mem::take(&mut self.keys);
        let mut carry = std::mem::take(&mut self.carry);
        let first = self.next_first;
        let (k, n) = (self.em.k(), self.em.points());
        let this = &*self;
        let (emitted, loaded) = rayon::join(
            || pending.as_ref().map_or(Ok(()), |g| this.emit(g)),
            || {
                this.load(&mut group, &mut keys, &carry, &load.pieces)?;
                let buckets = this.key(&mut group, &keys, carry.len() / this.rb, load);
                // One second array for every bucket: a bucket may hold most of the group.
                Pair::resize_for_overwrite(&mut scratch, group.len, this.full_group());
                sort::sort_buckets_in(&mut group.pairs, &mut scratch, &buckets);
                group.first = first;
                let end = first + group.len as u64;
                let whole_end = if end == n { n } else { end / k * k };
                group.whole = (whole_end - first) as usize;
                // The unfinished pointlet's records go on, in sorted order, with the next group.
                carry.clear();
                for p in &group.pairs[group.whole..] {
                    let at = p.1 as usize * this.rb;
                    carry.extend_from_slice(&group.records[at..at + this.rb]);
                }
                Ok::<u64, StoreError>(whole_end)
            },
        );
        self.scratch = scratch;
        self.keys = keys;
        self.carry = carry;
        self.spare = pending.unwrap_or_default();
        self.next_first = loaded?;
        self.pending = Some(group);
        emitted
    }

    /// Emits the pending group, if any.
    fn flush(&mut self) -> Result<(), StoreError> {
        if let Some(g) = self.pending.take() {
            let r = self.emit(&g);
            self.spare = g;
            r?;
        }
        Ok(())
    }

    /// Emits a sorted group's whole pointlets.
    fn emit(&self, g: &Group) -> Result<(), StoreError> {
        if g.whole == 0 {
            return Ok(());
        }
        let (k, n) = (self.em.k(), self.em.points());
        let p0 = g.first / k;
        let end = g.first + g.whole as u64;
        let p_end = end.div_ceil(k);
        // The last group's mapped pages are written: they leave the process now.
        self.em.release_before(p0);
        let source = Source {
            records: &g.records,
            order: &g.pairs[..g.whole],
            first: g.first,
        };
        let mut p = p0;
        while p < p_end {
            let p1 = (p + self.set.step).min(p_end);
            self.em.block(p, p1, &source)?;
            report(&self.set.progress, BuildPhase::Writing, (p1 * k).min(n), n);
            p = p1;
        }
        Ok(())
    }

    /// Records of a full group: buffers are made this long at once, not grown group by group.
    fn full_group(&self) -> usize {
        self.set.capacity.min(self.em.points() as usize)
    }

    /// Fills `g` with the carried records, then those of `pieces`, and `keys` with the keys of
    /// the latter, read on every core.
    fn load(
        &self,
        g: &mut Group,
        keys: &mut Vec<u64>,
        carry: &[u8],
        pieces: &[Piece<'_>],
    ) -> Result<(), StoreError> {
        let rb = self.rb;
        let carried = carry.len() / rb;
        let read = pieces.iter().map(Piece::len).sum::<usize>();
        g.len = carried + read;
        if keys.len() < read {
            // Zeroed pages from the allocator, like the records below.
            *keys = vec![0; read.max(self.full_group())];
        }
        if g.records.len() < g.len * rb {
            // Zeroed pages from the allocator: resizing would write them all on this thread.
            g.records = vec![0; g.len.max(self.full_group()) * rb];
            pio::huge_pages(&g.records);
        }
        g.records[..carry.len()].copy_from_slice(carry);
        let mut rest = &mut g.records[carry.len()..g.len * rb];
        let mut rest_keys = &mut keys[..read];
        let per_read = (READ_BYTES / rb).max(1) as u64;
        let mut reads = Vec::new();
        for p in pieces {
            let mut from = p.from;
            while from < p.to {
                let to = (from + per_read).min(p.to);
                let n = (to - from) as usize;
                let (here, after) = std::mem::take(&mut rest).split_at_mut(n * rb);
                let (here_keys, after_keys) = std::mem::take(&mut rest_keys).split_at_mut(n);
                reads.push((p.run, from, here, here_keys));
                (rest, rest_keys) = (after, after_keys);
                from = to;
            }
        }
        reads
            .into_par_iter()
            .try_for_each(|(run, from, out, out_keys)| {
                runs::read_records(run, from, out, out_keys)
            })?;
        // Once all are read, a piece at a time: giving pages back takes the file's lock, which
        // reads of the same run would otherwise wait for.
        pieces
            .par_iter()
            .try_for_each(|p| runs::release_records(p.run, p.from, p.to))
    }

    /// The pairs (key, place) of `g`'s records, the `carried` first (keyed here), then bucket
    /// by bucket as `load` lays them out (their `keys` as read); where each bucket's pairs
    /// start.
    fn key(&self, g: &mut Group, keys: &[u64], carried: usize, load: &Load<'_>) -> sort::Buckets {
        const TASK: usize = 1 << 14;
        let (rb, q, grid) = (self.rb, self.set.quantization, self.set.grid);
        // Every pair is written below.
        Pair::resize_for_overwrite(&mut g.pairs, g.len, self.full_group());
        let mut starts = vec![0];
        if carried > 0 {
            starts.push(carried);
        }
        // Stretches of pairs in order: (count, the first record's place).
        let mut stretches = vec![(carried, 0)];
        let mut at = carried;
        let mut segment = 0;
        for &end in &load.bucket_ends {
            for &(first, count) in &load.segments[segment..end] {
                stretches.push((count, carried + first));
                at += count;
            }
            segment = end;
            starts.push(at);
        }
        // Tasks of at most TASK pairs: (their pairs, the first record's place).
        let mut tasks = Vec::new();
        let mut rest = &mut g.pairs[..];
        for (count, first) in stretches {
            let mut done = 0;
            while done < count {
                let n = (count - done).min(TASK);
                let (here, after) = std::mem::take(&mut rest).split_at_mut(n);
                tasks.push((here, first + done));
                rest = after;
                done += n;
            }
        }
        let records = &g.records;
        tasks.into_par_iter().for_each(|(pairs, first)| {
            if first >= carried {
                let read = &keys[first - carried..first - carried + pairs.len()];
                for (j, (p, &k)) in pairs.iter_mut().zip(read).enumerate() {
                    *p = Pair(k, (first + j) as u32);
                }
            } else {
                let recs = &records[first * rb..(first + pairs.len()) * rb];
                // The group's bounds are not needed: the grid is the build's.
                key_rows(recs, q, grid, rb, first, pairs);
            }
        });
        starts.dedup();
        sort::Buckets { starts }
    }

    /// Spills bucket `bucket` of `runs` again, as runs bucketed by `finer`: the pending group
    /// is emitted first, so that its buffers hold the pieces.
    fn spill_again(
        &mut self,
        runs: &[RunFile],
        bucket: usize,
        finer: Bucketing,
    ) -> Result<Vec<RunFile>, StoreError> {
        self.flush()?;
        let mut g = std::mem::take(&mut self.spare);
        let mut keys = std::mem::take(&mut self.keys);
        let mut out = Vec::new();
        for chunk in chunks(runs, bucket, self.set.capacity)? {
            let load = Load::one_bucket(chunk);
            self.load(&mut g, &mut keys, &[], &load.pieces)?;
            self.key(&mut g, &keys, 0, &load);
            let starts = sort::bucket_by(&mut g.pairs, &mut self.scratch, finer.count, |k| {
                finer.of(k)
            });
            let path = runs::temp_name(self.set.run_dir, self.set.stem, "run");
            out.push(runs::write_run(
                path,
                &g.records[..g.len * self.rb],
                &g.pairs,
                &starts,
                self.rb,
                self.set.io_chunk,
                self.set.run_maps,
            )?);
        }
        self.spare = g;
        self.keys = keys;
        Ok(out)
    }
}

/// Bucket `bucket` of every run, in run order, cut into chunks of at most `capacity` records.
fn chunks(
    runs: &[RunFile],
    bucket: usize,
    capacity: usize,
) -> Result<Vec<Vec<Piece<'_>>>, StoreError> {
    let capacity = capacity.max(1) as u64;
    let (mut all, mut chunk, mut size) = (Vec::new(), Vec::new(), 0u64);
    for run in runs {
        let (mut from, to) = run.span(bucket..bucket + 1)?;
        while from < to {
            let take = (to - from).min(capacity - size);
            chunk.push(Piece {
                run,
                from,
                to: from + take,
            });
            (size, from) = (size + take, from + take);
            if size == capacity {
                all.push(std::mem::take(&mut chunk));
                size = 0;
            }
        }
    }
    if size > 0 {
        all.push(chunk);
    }
    Ok(all)
}
