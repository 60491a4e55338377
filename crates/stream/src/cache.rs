//! The RAM cache of pointlet prefixes and its loader threads.

use crate::source::{PointletData, PointletSource, SourceError, BYTES_PER_POINT};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering::*};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

#[derive(Clone, Debug)]
pub struct CacheConfig {
    /// Bytes of point data the cache may hold.
    pub ram_budget: u64,
    /// Loader threads.
    pub loaders: usize,
    /// Pending tasks at most: keeps the latency of each task within a few frames.
    pub queue_capacity: usize,
    /// Extra fraction read beyond a request when RAM allows (the paper's 25 %).
    pub prefetch: f64,
    /// Fraction of the budget above which unused points are unloaded.
    pub pressure: f64,
    /// Load tasks a loader takes from the queue at once and hands to
    /// [`PointletSource::read_many`]: 1 for a local disk, more where each read waits for a
    /// round trip.
    pub batch: usize,
}

impl Default for CacheConfig {
    fn default() -> Self {
        Self {
            ram_budget: 1 << 30,
            loaders: 4,
            queue_capacity: 4096,
            prefetch: 0.25,
            pressure: 0.9,
            batch: 1,
        }
    }
}

/// Counters since the cache was created (ram_* are current / peak bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CacheStats {
    pub load_tasks: u64,
    pub unload_tasks: u64,
    pub points_loaded: u64,
    pub points_evicted: u64,
    pub bytes_read: u64,
    pub ram_used: u64,
    pub ram_peak: u64,
    pub queued: usize,
    pub read_errors: u64,
}

/// What a request pass found for a pointlet.
const LOAD: u8 = 1;
const UNLOAD: u8 = 2;

#[derive(Clone, Copy, Debug)]
enum Task {
    Load(u32),
    Unload(u32),
}

struct Shared<S> {
    source: S,
    slots: Vec<Mutex<PointletData>>,
    /// Mirror of each slot's held window [held_from, loaded), readable without the lock.
    loaded: Vec<AtomicU32>,
    held_from: Vec<AtomicU32>,
    wanted: Vec<AtomicU32>,
    /// Points below this are no longer needed (already on the GPU and drawn).
    keep_from: Vec<AtomicU32>,
    /// Frame in which the pointlet was last wanted (for least-recently-used eviction).
    last_wanted: Vec<AtomicU64>,
    load_queued: Vec<AtomicBool>,
    unload_queued: Vec<AtomicBool>,
    /// A loader owns the pointlet; others skip it (the paper's per-pointlet mutex, try-locked).
    busy: Vec<AtomicBool>,
    config: CacheConfig,
    ram_used: AtomicU64,
    ram_peak: AtomicU64,
    queued: AtomicUsize,
    in_flight: AtomicUsize,
    load_tasks: AtomicU64,
    unload_tasks: AtomicU64,
    points_loaded: AtomicU64,
    points_evicted: AtomicU64,
    read_errors: AtomicU64,
    last_error: Mutex<Option<SourceError>>,
}

/// The RAM cache. Owned by the render thread; loader threads share its state.
pub struct RamCache<S: PointletSource> {
    shared: Arc<Shared<S>>,
    tx: Option<SyncSender<Task>>,
    workers: Vec<JoinHandle<()>>,
    frame: u64,
}

impl<S: PointletSource> RamCache<S> {
    pub fn new(source: S, config: CacheConfig) -> std::io::Result<Self> {
        let n = source.pointlet_count();
        let atomics32 = || (0..n).map(|_| AtomicU32::new(0)).collect::<Vec<_>>();
        let flags = || (0..n).map(|_| AtomicBool::new(false)).collect::<Vec<_>>();
        let shared = Arc::new(Shared {
            source,
            slots: (0..n)
                .map(|_| Mutex::new(PointletData::default()))
                .collect(),
            loaded: atomics32(),
            held_from: atomics32(),
            wanted: atomics32(),
            keep_from: atomics32(),
            last_wanted: (0..n).map(|_| AtomicU64::new(0)).collect(),
            load_queued: flags(),
            unload_queued: flags(),
            busy: flags(),
            config: config.clone(),
            ram_used: AtomicU64::new(0),
            ram_peak: AtomicU64::new(0),
            queued: AtomicUsize::new(0),
            in_flight: AtomicUsize::new(0),
            load_tasks: AtomicU64::new(0),
            unload_tasks: AtomicU64::new(0),
            points_loaded: AtomicU64::new(0),
            points_evicted: AtomicU64::new(0),
            read_errors: AtomicU64::new(0),
            last_error: Mutex::new(None),
        });
        let (tx, rx) = sync_channel(config.queue_capacity.max(1));
        let rx = Arc::new(Mutex::new(rx));
        let mut workers = Vec::new();
        for k in 0..config.loaders.max(1) {
            let (shared, rx) = (shared.clone(), rx.clone());
            workers.push(
                std::thread::Builder::new()
                    .name(format!("pointlet-loader-{k}"))
                    .spawn(move || worker(&shared, &rx))?,
            );
        }
        Ok(Self {
            shared,
            tx: Some(tx),
            workers,
            frame: 0,
        })
    }

    pub fn pointlet_count(&self) -> usize {
        self.shared.slots.len()
    }

    /// One past the last point of pointlet `i` held now.
    pub fn resident(&self, i: usize) -> u32 {
        self.shared.loaded.get(i).map_or(0, |a| a.load(Acquire))
    }

    /// The points of pointlet `i` held now: a window of its shuffled order.
    pub fn held(&self, i: usize) -> std::ops::Range<u32> {
        let from = self.shared.held_from.get(i).map_or(0, |a| a.load(Acquire));
        from..self.resident(i).max(from)
    }

    /// Hands over this frame's wanted counts (one per pointlet: a prefix) and enqueues tasks.
    /// Never blocks: when the queue is full, the rest waits for a later frame.
    pub fn request(&mut self, wanted: &[u32]) {
        self.request_window(wanted, &[]);
    }

    /// Like [`request`](Self::request), but points of pointlet i below `keep_from[i]` are no
    /// longer needed (missing entries mean 0): under pressure they are dropped first, so a
    /// window slides over a pointlet larger than the budget.
    pub fn request_window(&mut self, wanted: &[u32], keep_from: &[u32]) {
        let n = wanted.len();
        self.request_with(n, |i| (wanted[i], keep_from.get(i).copied().unwrap_or(0)));
    }

    /// Like [`request_window`](Self::request_window), with pointlet i's (wanted, keep_from)
    /// given by `want(i)` for i < `n`: callers need not build the two arrays every frame.
    pub fn request_with(&mut self, n: usize, want: impl Fn(usize) -> (u32, u32) + Sync) {
        self.frame += 1;
        let sh = &self.shared;
        let Some(tx) = &self.tx else { return };
        let budget = sh.config.ram_budget as f64;
        let pressure = sh.ram_used.load(Relaxed) as f64 > budget * sh.config.pressure;
        let frame = self.frame;
        let n = n.min(sh.slots.len());
        // One pass over all pointlets, in parallel: each touches only its own atomics and
        // yields its task, if any.
        let tasks: Vec<(u8, u32)> = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .filter_map(|i| {
                let (w, keep) = want(i);
                let w = w.min(sh.source.pointlet_len(i));
                let keep = keep.min(w);
                sh.wanted[i].store(w, Relaxed);
                sh.keep_from[i].store(keep, Relaxed);
                if w > 0 {
                    sh.last_wanted[i].store(frame, Relaxed);
                }
                let have = sh.loaded[i].load(Acquire);
                let from = sh.held_from[i].load(Acquire);
                let gap = keep < from && w > keep;
                if (w > have || gap) && !sh.load_queued[i].load(Acquire) {
                    Some((LOAD, i as u32))
                } else if (w < have || keep > from)
                    && pressure
                    && !sh.unload_queued[i].load(Acquire)
                {
                    Some((UNLOAD, i as u32))
                } else {
                    None
                }
            })
            .collect();
        let loads = tasks.iter().filter(|t| t.0 == LOAD).map(|t| t.1);
        let mut surplus: Vec<(u64, u32)> = tasks
            .iter()
            .filter(|t| t.0 == UNLOAD)
            .map(|&(_, i)| (sh.last_wanted[i as usize].load(Relaxed), i))
            .collect();
        // Under pressure, unloads go first (stalest first): they make room for the loads.
        if pressure {
            surplus.sort_unstable();
            let target = (budget * (sh.config.pressure - 0.1).max(0.0)) as u64;
            let mut to_free = sh.ram_used.load(Relaxed).saturating_sub(target);
            for (_, i) in surplus {
                if to_free == 0 {
                    break;
                }
                let i = i as usize;
                let (from, have) = (sh.held_from[i].load(Relaxed), sh.loaded[i].load(Relaxed));
                let extra = have.saturating_sub(sh.wanted[i].load(Relaxed).max(from))
                    + sh.keep_from[i].load(Relaxed).min(have).saturating_sub(from);
                sh.unload_queued[i].store(true, Release);
                if !self.send(tx, Task::Unload(i as u32)) {
                    sh.unload_queued[i].store(false, Release);
                    break;
                }
                to_free = to_free.saturating_sub(extra as u64 * BYTES_PER_POINT);
            }
        }
        for i in loads {
            sh.load_queued[i as usize].store(true, Release);
            if !self.send(tx, Task::Load(i)) {
                sh.load_queued[i as usize].store(false, Release);
                break;
            }
        }
    }

    fn send(&self, tx: &SyncSender<Task>, t: Task) -> bool {
        self.shared.queued.fetch_add(1, AcqRel);
        match tx.try_send(t) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.shared.queued.fetch_sub(1, AcqRel);
                false
            }
        }
    }

    /// Calls `f` with the held points of pointlet `i` in `range` (clamped to what is held) and
    /// the index of the first one. Holds the pointlet's lock only for the call: loaders read
    /// outside it.
    pub fn with_points<R>(
        &self,
        i: usize,
        range: std::ops::Range<u32>,
        f: impl FnOnce(u32, &[[u32; 3]], &[u32]) -> R,
    ) -> Option<R> {
        let slot = self.shared.slots.get(i)?.lock().ok()?;
        let first = range.start.clamp(slot.start, slot.end());
        let end = range.end.clamp(first, slot.end());
        let (a, b) = ((first - slot.start) as usize, (end - slot.start) as usize);
        Some(f(first, &slot.positions[a..b], &slot.attribute[a..b]))
    }

    pub fn stats(&self) -> CacheStats {
        let sh = &self.shared;
        CacheStats {
            load_tasks: sh.load_tasks.load(Relaxed),
            unload_tasks: sh.unload_tasks.load(Relaxed),
            points_loaded: sh.points_loaded.load(Relaxed),
            points_evicted: sh.points_evicted.load(Relaxed),
            bytes_read: sh.points_loaded.load(Relaxed) * BYTES_PER_POINT,
            ram_used: sh.ram_used.load(Relaxed),
            ram_peak: sh.ram_peak.load(Relaxed),
            queued: sh.queued.load(Relaxed),
            read_errors: sh.read_errors.load(Relaxed),
        }
    }

    /// The most recent read error, if any (the cache keeps serving what it has).
    pub fn take_error(&self) -> Option<SourceError> {
        self.shared
            .last_error
            .lock()
            .ok()
            .and_then(|mut e| e.take())
    }

    /// The source the loaders read from (e.g. to change what it computes per point).
    pub fn source(&self) -> &S {
        &self.shared.source
    }

    /// Drops every held point (after the source changed what it delivers). Waits for tasks in
    /// flight so none adds stale points afterwards; loads restart with the next request.
    pub fn clear(&mut self) {
        self.wait_idle();
        let sh = &self.shared;
        for (i, slot) in sh.slots.iter().enumerate() {
            if let Ok(mut s) = slot.lock() {
                let freed = s.len() as u64;
                *s = PointletData::default();
                sh.loaded[i].store(0, Release);
                sh.held_from[i].store(0, Release);
                sh.ram_used.fetch_sub(freed * BYTES_PER_POINT, AcqRel);
                sh.points_evicted.fetch_add(freed, Relaxed);
            }
        }
    }

    /// True when no task is queued or running (for tests and benchmarks).
    pub fn is_idle(&self) -> bool {
        self.shared.queued.load(Acquire) == 0 && self.shared.in_flight.load(Acquire) == 0
    }

    /// Waits until idle; for tests, benchmarks and tools, never the render loop.
    pub fn wait_idle(&self) {
        while !self.is_idle() {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
    }
}

impl<S: PointletSource> Drop for RamCache<S> {
    fn drop(&mut self) {
        self.tx = None; // closes the queue: workers finish their task and exit
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

/// Loaders yield to the render thread: on Linux, niceness is per thread.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority on the calling thread (who = 0) only changes its scheduling weight.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}

fn worker<S: PointletSource>(sh: &Shared<S>, rx: &Mutex<Receiver<Task>>) {
    lower_priority();
    let batch = sh.config.batch.max(1);
    let mut tasks = Vec::with_capacity(batch);
    loop {
        tasks.clear();
        {
            let Ok(r) = rx.lock() else { return };
            let Ok(first) = r.recv() else { return };
            tasks.push(first);
            // Whatever else is queued already joins this batch (never waits for more).
            while tasks.len() < batch {
                match r.try_recv() {
                    Ok(t) => tasks.push(t),
                    Err(_) => break,
                }
            }
        }
        sh.in_flight.fetch_add(tasks.len(), AcqRel);
        sh.queued.fetch_sub(tasks.len(), AcqRel);
        let mut loads = Vec::with_capacity(tasks.len());
        for task in &tasks {
            match *task {
                Task::Load(i) => {
                    sh.load_queued[i as usize].store(false, Release);
                    loads.push(i as usize);
                }
                Task::Unload(i) => {
                    sh.unload_queued[i as usize].store(false, Release);
                    unload(sh, i as usize);
                }
            }
        }
        load(sh, &loads);
        sh.in_flight.fetch_sub(tasks.len(), AcqRel);
    }
}

/// Reserves `bytes` of the budget, or as much as is free in whole points; returns points granted.
fn reserve(sh: &Shared<impl PointletSource>, points: u32) -> u32 {
    let budget = sh.config.ram_budget;
    let mut used = sh.ram_used.load(Relaxed);
    loop {
        let free_points = (budget.saturating_sub(used) / BYTES_PER_POINT).min(points as u64) as u32;
        if free_points == 0 {
            return 0;
        }
        let new = used + free_points as u64 * BYTES_PER_POINT;
        match sh
            .ram_used
            .compare_exchange_weak(used, new, AcqRel, Relaxed)
        {
            Ok(_) => {
                sh.ram_peak.fetch_max(new, Relaxed);
                return free_points;
            }
            Err(u) => used = u,
        }
    }
}

/// Brings pointlets `ids` up to what is wanted of them, their reads issued as one batch.
fn load<S: PointletSource>(sh: &Shared<S>, ids: &[usize]) {
    let mut requests = Vec::with_capacity(ids.len());
    for &i in ids {
        if sh.busy[i]
            .compare_exchange(false, true, AcqRel, Relaxed)
            .is_err()
        {
            continue; // another loader is already bringing this pointlet up to date
        }
        match plan_load(sh, i) {
            Some(range) => requests.push((i, range)),
            None => sh.busy[i].store(false, Release),
        }
    }
    if requests.is_empty() {
        return;
    }
    let mut fresh: Vec<PointletData> = requests
        .iter()
        .map(|(_, r)| {
            let n = (r.end - r.start) as usize;
            PointletData {
                start: r.start,
                positions: Vec::with_capacity(n),
                attribute: Vec::with_capacity(n),
            }
        })
        .collect();
    let mut results = sh.source.read_many(&requests, &mut fresh).into_iter();
    for ((i, range), data) in requests.into_iter().zip(fresh) {
        let granted = range.end - range.start;
        // A source that answers fewer requests than asked fails the rest.
        let result = results.next().unwrap_or_else(|| {
            Err(SourceError {
                pointlet: i,
                range: range.clone(),
                message: "the source gave no result for this read".into(),
            })
        });
        match result {
            Ok(()) if data.len() == granted as usize => {
                if let Ok(mut slot) = sh.slots[i].lock() {
                    slot.positions.extend_from_slice(&data.positions);
                    slot.attribute.extend_from_slice(&data.attribute);
                    sh.loaded[i].store(slot.end(), Release);
                }
                sh.points_loaded.fetch_add(granted as u64, Relaxed);
            }
            Ok(()) => {
                sh.ram_used
                    .fetch_sub(granted as u64 * BYTES_PER_POINT, AcqRel);
                record_error(
                    sh,
                    SourceError {
                        pointlet: i,
                        range,
                        message: format!("source returned {} points", data.len()),
                    },
                );
            }
            Err(e) => {
                sh.ram_used
                    .fetch_sub(granted as u64 * BYTES_PER_POINT, AcqRel);
                record_error(sh, e);
            }
        }
        sh.busy[i].store(false, Release);
    }
}

/// With pointlet `i` owned (busy): restarts its window where needed and reserves RAM for the
/// next read; the points to read, if any.
fn plan_load<S: PointletSource>(sh: &Shared<S>, i: usize) -> Option<std::ops::Range<u32>> {
    sh.load_tasks.fetch_add(1, Relaxed);
    let mut have = sh.loaded[i].load(Acquire);
    let want = sh.wanted[i].load(Relaxed);
    let keep = sh.keep_from[i].load(Relaxed);
    let from = sh.held_from[i].load(Acquire);
    if (want > have && keep >= have) || (keep < from && want > keep) {
        // Nothing held is still needed, or the window starts past what is needed now: restart
        // it at `keep` (a window holds one contiguous run).
        if let Ok(mut slot) = sh.slots[i].lock() {
            let freed = slot.positions.len() as u64;
            slot.positions = Vec::new();
            slot.attribute = Vec::new();
            slot.start = keep;
            sh.held_from[i].store(keep, Release);
            sh.loaded[i].store(keep, Release);
            sh.ram_used.fetch_sub(freed * BYTES_PER_POINT, AcqRel);
            sh.points_evicted.fetch_add(freed, Relaxed);
            have = keep;
        }
    }
    if want <= have {
        return None;
    }
    let len = sh.source.pointlet_len(i);
    let budget = sh.config.ram_budget as f64;
    let ahead = ((want as f64) * sh.config.prefetch).ceil() as u32;
    let with_prefetch = want.saturating_add(ahead).min(len);
    let used = sh.ram_used.load(Relaxed) as f64;
    // Prefetch only while the cache stays below the pressure mark afterwards.
    let extra_bytes = (with_prefetch - have) as f64 * BYTES_PER_POINT as f64;
    let target = if used + extra_bytes <= budget * sh.config.pressure {
        with_prefetch
    } else {
        want
    };
    let granted = reserve(sh, target - have);
    (granted > 0).then_some(have..have + granted)
}

fn unload<S: PointletSource>(sh: &Shared<S>, i: usize) {
    if sh.busy[i]
        .compare_exchange(false, true, AcqRel, Relaxed)
        .is_err()
    {
        return;
    }
    sh.unload_tasks.fetch_add(1, Relaxed);
    let want = sh.wanted[i].load(Relaxed);
    let keep = sh.keep_from[i].load(Relaxed);
    if let Ok(mut slot) = sh.slots[i].lock() {
        let before = slot.len() as u64;
        let (start, held_end) = (slot.start, slot.end());
        let end = want.clamp(start, held_end);
        slot.truncate((end - start) as usize);
        slot.drop_before(keep);
        sh.loaded[i].store(slot.end(), Release);
        sh.held_from[i].store(slot.start, Release);
        let freed = before - slot.len() as u64;
        sh.ram_used.fetch_sub(freed * BYTES_PER_POINT, AcqRel);
        sh.points_evicted.fetch_add(freed, Relaxed);
    }
    sh.busy[i].store(false, Release);
}

fn record_error<S>(sh: &Shared<S>, e: SourceError) {
    sh.read_errors.fetch_add(1, Relaxed);
    if let Ok(mut slot) = sh.last_error.lock() {
        *slot = Some(e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ops::Range;

    /// A source whose point j of pointlet i is ([i, j, i ^ j], i * 65536 + j).
    struct Synthetic {
        pointlets: usize,
        size: u32,
        fail_on: Option<usize>,
        /// The most requests one read_many was given.
        largest_batch: AtomicUsize,
        /// Reads wait while this is false: tasks pile up in the queue meanwhile.
        open: AtomicBool,
    }

    impl PointletSource for Synthetic {
        fn pointlet_count(&self) -> usize {
            self.pointlets
        }
        fn pointlet_len(&self, _: usize) -> u32 {
            self.size
        }
        fn read(&self, i: usize, r: Range<u32>, out: &mut PointletData) -> Result<(), SourceError> {
            if self.fail_on == Some(i) {
                return Err(SourceError {
                    pointlet: i,
                    range: r,
                    message: "disk on fire".into(),
                });
            }
            for j in r {
                out.positions.push([i as u32, j, (i as u32) ^ j]);
                out.attribute.push((i as u32) << 16 | j);
            }
            Ok(())
        }
        fn read_many(
            &self,
            requests: &[(usize, Range<u32>)],
            outs: &mut [PointletData],
        ) -> Vec<Result<(), SourceError>> {
            while !self.open.load(Acquire) {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            self.largest_batch.fetch_max(requests.len(), Relaxed);
            requests
                .iter()
                .zip(outs.iter_mut())
                .map(|((i, r), out)| self.read(*i, r.clone(), out))
                .collect()
        }
    }

    fn cache(budget_points: u64, fail_on: Option<usize>) -> RamCache<Synthetic> {
        cache_batched(budget_points, fail_on, 1)
    }

    fn cache_batched(
        budget_points: u64,
        fail_on: Option<usize>,
        batch: usize,
    ) -> RamCache<Synthetic> {
        let src = Synthetic {
            pointlets: 100,
            size: 1000,
            fail_on,
            largest_batch: AtomicUsize::new(0),
            open: AtomicBool::new(true),
        };
        RamCache::new(
            src,
            CacheConfig {
                ram_budget: budget_points * BYTES_PER_POINT,
                loaders: 3,
                queue_capacity: 64,
                batch,
                ..Default::default()
            },
        )
        .expect("threads")
    }

    /// Requests until the cache has nothing left to do (several frames: the queue is bounded).
    fn settle(c: &mut RamCache<Synthetic>, wanted: &[u32]) {
        for _ in 0..50 {
            c.request(wanted);
            c.wait_idle();
        }
    }

    #[test]
    fn loads_prefixes_with_the_right_points() {
        let mut c = cache(1_000_000, None);
        let wanted: Vec<u32> = (0..100).map(|i| (i * 7 % 1000) as u32).collect();
        settle(&mut c, &wanted);
        for (i, w) in wanted.iter().enumerate() {
            assert!(c.resident(i) >= *w, "pointlet {i}: {} < {w}", c.resident(i));
            c.with_points(i, 0..*w, |_, p, a| {
                for (j, (p, a)) in p.iter().zip(a).enumerate() {
                    assert_eq!(*p, [i as u32, j as u32, i as u32 ^ j as u32]);
                    assert_eq!(*a, (i as u32) << 16 | j as u32);
                }
            })
            .expect("slot");
        }
        // Plenty of RAM: prefetch read beyond the request.
        assert!(c.stats().points_loaded > wanted.iter().map(|w| *w as u64).sum::<u64>());
    }

    #[test]
    fn batched_loads_hold_the_same_points_and_errors_stay_per_pointlet() {
        let wanted: Vec<u32> = (0..100).map(|i| (i * 7 % 1000) as u32).collect();
        let mut one = cache(1_000_000, Some(3));
        let mut many = cache_batched(1_000_000, Some(3), 16);
        // The loaders' first reads wait until a whole frame's tasks are queued, so that later
        // ones find several waiting (unheld, loaders as fast as the requests took them one by
        // one now and then).
        many.source().open.store(false, Release);
        many.request(&wanted);
        many.source().open.store(true, Release);
        for c in [&mut one, &mut many] {
            settle(c, &wanted);
        }
        assert_eq!(one.source().largest_batch.load(Relaxed), 1);
        assert!(many.source().largest_batch.load(Relaxed) > 1);
        for (i, &w) in wanted.iter().enumerate() {
            assert_eq!(one.held(i).start, many.held(i).start);
            let w = if i == 3 { 0 } else { w };
            assert!(many.resident(i) >= w, "pointlet {i}");
            let a = one.with_points(i, 0..w, |_, p, a| (p.to_vec(), a.to_vec()));
            let b = many.with_points(i, 0..w, |_, p, a| (p.to_vec(), a.to_vec()));
            assert_eq!(a, b, "pointlet {i}");
        }
        assert_eq!(many.resident(3), 0);
        assert!(many.take_error().is_some_and(|e| e.pointlet == 3));
    }

    #[test]
    fn budget_holds_and_evicts_what_is_no_longer_wanted() {
        // Budget: 20 000 points out of 100 000.
        let mut c = cache(20_000, None);
        let mut first = vec![0u32; 100];
        first[..20].iter_mut().for_each(|w| *w = 900);
        settle(&mut c, &first);
        let s1 = c.stats();
        assert!(s1.ram_used <= 20_000 * BYTES_PER_POINT, "{s1:?}");
        assert!(
            (0..20).map(|i| c.resident(i) as u64).sum::<u64>() >= 17_000,
            "{s1:?}"
        );
        // The camera moves: other pointlets are wanted, the first ones are evicted.
        let mut second = vec![0u32; 100];
        second[50..70].iter_mut().for_each(|w| *w = 900);
        settle(&mut c, &second);
        let s2 = c.stats();
        assert!(s2.points_evicted > 0 && s2.unload_tasks > 0, "{s2:?}");
        assert!(s2.ram_peak <= 20_000 * BYTES_PER_POINT, "{s2:?}");
        assert!((50..70).all(|i| c.resident(i) >= 800), "{s2:?}");
        assert!((0..20).all(|i| c.resident(i) == 0), "{s2:?}");
    }

    #[test]
    fn no_unloads_without_pressure() {
        let mut c = cache(1_000_000, None);
        settle(&mut c, &[500; 100]);
        settle(&mut c, &[0; 100]);
        let s = c.stats();
        assert_eq!(s.points_evicted, 0, "{s:?}");
        assert!((0..100).all(|i| c.resident(i) >= 500));
    }

    #[test]
    fn read_errors_are_reported_not_fatal() {
        let mut c = cache(1_000_000, Some(3));
        settle(&mut c, &[100; 100]);
        assert_eq!(c.resident(3), 0);
        assert!(c.resident(4) >= 100);
        let e = c.take_error().expect("error kept");
        assert!(e.to_string().contains("disk on fire"), "{e}");
        assert!(c.stats().read_errors > 0);
    }

    #[test]
    fn a_window_slides_over_pointlets_larger_than_the_budget() {
        // Budget 600 points, a pointlet of 1 000 walked through in steps: each step wants the
        // next 250 points and keeps nothing before them.
        let mut c = cache(600, None);
        let mut wanted = vec![0u32; 100];
        let mut keep = vec![0u32; 100];
        for step in 0..4u32 {
            keep[7] = step * 250;
            wanted[7] = keep[7] + 250;
            settle_window(&mut c, &wanted, &keep);
            let held = c.held(7);
            assert!(held.start <= keep[7] && held.end >= wanted[7], "{held:?}");
            c.with_points(7, keep[7]..wanted[7], |first, p, a| {
                assert_eq!(first, keep[7]);
                for (j, (p, a)) in p.iter().zip(a).enumerate() {
                    let j = first as usize + j;
                    assert_eq!(*p, [7, j as u32, 7 ^ j as u32]);
                    assert_eq!(*a, 7 << 16 | j as u32);
                }
            })
            .expect("slot");
        }
        assert!(
            c.held(7).start > 0,
            "drawn points were dropped under pressure"
        );
        assert!(c.stats().ram_peak <= 600 * BYTES_PER_POINT);
        assert!(c.stats().points_evicted > 0);
        // A window past everything held starts there without reading the gap.
        keep[9] = 900;
        wanted[9] = 1000;
        settle_window(&mut c, &wanted, &keep);
        assert_eq!(c.held(9), 900..1000);
    }

    fn settle_window(c: &mut RamCache<Synthetic>, wanted: &[u32], keep: &[u32]) {
        for _ in 0..50 {
            c.request_window(wanted, keep);
            c.wait_idle();
        }
    }

    #[test]
    fn request_never_blocks_on_a_full_queue() {
        let mut c = cache(10_000_000, None);
        // More loads than the queue holds: request returns at once, later frames finish the job.
        c.request(&[1000; 100]);
        settle(&mut c, &[1000; 100]);
        assert!((0..100).all(|i| c.resident(i) == 1000));
    }
}
