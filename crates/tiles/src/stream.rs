//! The fetching half of tileset streaming: each frame's [`TilePlan`] replaces the request queue
//! (requests of tiles that left the view and had not started are cancelled), a fixed number of
//! worker threads fetch and decode the most important requests first (the concurrency limit),
//! and decoded tiles stay in RAM within a budget, the least recently drawn evicted first and
//! the tiles of the latest plan never. A renderer can have the workers turn contents into what
//! it uploads ([`TileStream::with_prepare`]), so that its own thread only copies. What draws
//! them (GPU residency) is the renderer's part.

use crate::content::TilePoints;
use crate::select::{TilePlan, WantedTile};
use crate::{TileSource, Tileset};
use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileStreamConfig {
    /// Tiles fetched and decoded at once.
    pub workers: usize,
    /// RAM for decoded tiles.
    pub ram_budget: u64,
}

impl Default for TileStreamConfig {
    fn default() -> Self {
        Self {
            workers: 6,
            ram_budget: 1 << 30,
        }
    }
}

/// Counters since the stream started (bytes: decoded tiles held now).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileStreamStats {
    pub loaded: u64,
    pub cancelled: u64,
    pub evicted: u64,
    pub failed: u64,
    pub bytes: u64,
    pub queued: usize,
    pub in_flight: usize,
    /// Most fetches that ran at once.
    pub peak_in_flight: usize,
}

/// What the stream holds of a tile: its decoded contents, or what a renderer made of them.
pub trait TileData: Send + Sync + 'static {
    /// Bytes it holds (counted against the RAM budget).
    fn bytes(&self) -> u64;
}

impl TileData for Vec<TilePoints> {
    fn bytes(&self) -> u64 {
        bytes_of(self)
    }
}

/// Turns a tile's decoded contents into what the stream holds of it.
type Prepare<T> = dyn Fn(usize, Vec<TilePoints>) -> Result<T, crate::TilesError> + Send + Sync;

struct Held<T> {
    contents: Arc<T>,
    bytes: u64,
    last_used: u64,
}

struct State<T> {
    queue: VecDeque<WantedTile>,
    in_flight: HashSet<usize>,
    held: HashMap<usize, Held<T>>,
    /// Tiles of the latest plan (drawn or requested): never evicted.
    protected: HashSet<usize>,
    frame: u64,
    /// Tiles that failed since the last take, with the error naming the tile.
    errors: Vec<(usize, crate::TilesError)>,
    stats: TileStreamStats,
    stop: bool,
}

impl<T> Default for State<T> {
    fn default() -> Self {
        Self {
            queue: VecDeque::new(),
            in_flight: HashSet::new(),
            held: HashMap::new(),
            protected: HashSet::new(),
            frame: 0,
            errors: Vec::new(),
            stats: TileStreamStats::default(),
            stop: false,
        }
    }
}

struct Shared<T> {
    tileset: Arc<Tileset>,
    source: Arc<dyn TileSource>,
    budget: u64,
    prepare: Box<Prepare<T>>,
    state: Mutex<State<T>>,
    wake: Condvar,
}

impl<T> Shared<T> {
    fn lock(&self) -> MutexGuard<'_, State<T>> {
        // A worker that panicked left the state consistent between operations: keep going.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

pub struct TileStream<T: TileData = Vec<TilePoints>> {
    shared: Arc<Shared<T>>,
    workers: Vec<JoinHandle<()>>,
}

/// Bytes a tile's decoded contents hold.
fn bytes_of(contents: &[TilePoints]) -> u64 {
    contents
        .iter()
        .map(|c| {
            let normals = c.normals.as_ref().map_or(0, |n| n.len() * 12);
            let attributes: usize = c.attributes.iter().map(|a| a.values.len() * 8).sum();
            (c.positions.len() * 24 + c.colors.len() * 4 + normals + attributes) as u64
        })
        .sum()
}

impl TileStream<Vec<TilePoints>> {
    /// A stream holding the decoded contents of each tile.
    pub fn new(
        tileset: Arc<Tileset>,
        source: Arc<dyn TileSource>,
        config: TileStreamConfig,
    ) -> std::io::Result<Self> {
        Self::with_prepare(tileset, source, config, |_, contents| Ok(contents))
    }
}

impl<T: TileData> TileStream<T> {
    /// A stream whose workers also turn each tile's contents into what it holds of it
    /// (`prepare(tile, contents)`; an error fails the tile like a read error).
    pub fn with_prepare(
        tileset: Arc<Tileset>,
        source: Arc<dyn TileSource>,
        config: TileStreamConfig,
        prepare: impl Fn(usize, Vec<TilePoints>) -> Result<T, crate::TilesError> + Send + Sync + 'static,
    ) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            tileset,
            source,
            budget: config.ram_budget,
            prepare: Box::new(prepare),
            state: Mutex::new(State::default()),
            wake: Condvar::new(),
        });
        let workers = (0..config.workers.max(1))
            .map(|k| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("tile-fetch-{k}"))
                    .spawn(move || worker(&shared))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { shared, workers })
    }

    /// Takes this frame's plan: its requests replace the queue, its tiles are kept.
    pub fn update(&self, plan: &TilePlan) {
        let mut st = self.shared.lock();
        st.frame += 1;
        let frame = st.frame;
        let wanted: HashSet<usize> = plan.requests.iter().map(|w| w.tile).collect();
        let cancelled = st
            .queue
            .iter()
            .filter(|w| !wanted.contains(&w.tile))
            .count();
        st.stats.cancelled += cancelled as u64;
        let queue: VecDeque<WantedTile> = plan
            .requests
            .iter()
            .filter(|w| !st.in_flight.contains(&w.tile) && !st.held.contains_key(&w.tile))
            .copied()
            .collect();
        st.queue = queue;
        st.stats.queued = st.queue.len();
        st.protected = plan
            .draw
            .iter()
            .chain(&plan.requests)
            .map(|w| w.tile)
            .collect();
        for w in &plan.draw {
            if let Some(h) = st.held.get_mut(&w.tile) {
                h.last_used = frame;
            }
        }
        drop(st);
        self.shared.wake.notify_all();
    }

    pub fn is_loaded(&self, tile: usize) -> bool {
        self.shared.lock().held.contains_key(&tile)
    }

    /// What is held of `tile`, if anything.
    pub fn get(&self, tile: usize) -> Option<Arc<T>> {
        self.shared
            .lock()
            .held
            .get(&tile)
            .map(|h| Arc::clone(&h.contents))
    }

    pub fn stats(&self) -> TileStreamStats {
        let st = self.shared.lock();
        TileStreamStats {
            queued: st.queue.len(),
            in_flight: st.in_flight.len(),
            ..st.stats
        }
    }

    /// Errors since the last call, one line each naming the tile.
    pub fn take_errors(&self) -> Vec<String> {
        self.take_failures()
            .into_iter()
            .map(|(_, e)| e.to_string())
            .collect()
    }

    /// The tiles that failed since the last call, each with its error.
    pub fn take_failures(&self) -> Vec<(usize, crate::TilesError)> {
        std::mem::take(&mut self.shared.lock().errors)
    }

    /// True when nothing is queued or being fetched.
    pub fn is_idle(&self) -> bool {
        let st = self.shared.lock();
        st.queue.is_empty() && st.in_flight.is_empty()
    }
}

impl<T: TileData> Drop for TileStream<T> {
    fn drop(&mut self) {
        self.shared.lock().stop = true;
        self.shared.wake.notify_all();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn worker<T: TileData>(sh: &Shared<T>) {
    loop {
        let tile = {
            let mut st = sh.lock();
            loop {
                if st.stop {
                    return;
                }
                if let Some(w) = st.queue.pop_front() {
                    st.in_flight.insert(w.tile);
                    st.stats.peak_in_flight = st.stats.peak_in_flight.max(st.in_flight.len());
                    break w.tile;
                }
                st = sh.wake.wait(st).unwrap_or_else(|p| p.into_inner());
            }
        };
        let read = sh
            .tileset
            .read_tile(sh.source.as_ref(), tile)
            .and_then(|contents| (sh.prepare)(tile, contents));
        let mut st = sh.lock();
        st.in_flight.remove(&tile);
        match read {
            Ok(contents) => {
                let bytes = contents.bytes();
                let last_used = st.frame;
                st.held.insert(
                    tile,
                    Held {
                        contents: Arc::new(contents),
                        bytes,
                        last_used,
                    },
                );
                st.stats.loaded += 1;
                st.stats.bytes += bytes;
                evict(&mut st, sh.budget);
            }
            Err(e) => {
                st.stats.failed += 1;
                st.errors.push((tile, e));
            }
        }
    }
}

/// Drops the least recently drawn tiles outside the latest plan until the budget holds.
fn evict<T>(st: &mut State<T>, budget: u64) {
    if st.stats.bytes <= budget {
        return;
    }
    let mut candidates: Vec<(u64, usize)> = st
        .held
        .iter()
        .filter(|(t, _)| !st.protected.contains(t))
        .map(|(t, h)| (h.last_used, *t))
        .collect();
    candidates.sort_unstable();
    for (_, t) in candidates {
        if st.stats.bytes <= budget {
            break;
        }
        if let Some(h) = st.held.remove(&t) {
            st.stats.bytes -= h.bytes;
            st.stats.evicted += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::select::{plan, TileView};
    use crate::{LocalSource, TilesError};
    use pointlet_core::Camera;
    use std::path::Path;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::{Duration, Instant};

    /// A local source that takes `delay` per read and counts the reads running at once.
    struct Slow {
        inner: LocalSource,
        delay: Duration,
        running: AtomicUsize,
        most: AtomicUsize,
    }

    impl TileSource for Slow {
        fn read(&self, uri: &str) -> Result<Vec<u8>, TilesError> {
            let now = self.running.fetch_add(1, Ordering::SeqCst) + 1;
            self.most.fetch_max(now, Ordering::SeqCst);
            std::thread::sleep(self.delay);
            let r = self.inner.read(uri);
            self.running.fetch_sub(1, Ordering::SeqCst);
            r
        }
    }

    fn simple() -> (Arc<Tileset>, Arc<Slow>) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/tiles/simple_pnts/tileset.json");
        let (source, uri) = LocalSource::for_file(&path);
        let tileset = Tileset::load(&source, &uri).expect("tileset");
        let slow = Slow {
            inner: source,
            delay: Duration::from_millis(30),
            running: AtomicUsize::new(0),
            most: AtomicUsize::new(0),
        };
        (Arc::new(tileset), Arc::new(slow))
    }

    /// Every tile with content, wanted at once (the finest view of the whole set).
    fn everything(set: &Tileset) -> TilePlan {
        let b = set.tiles[0].volume.aabb();
        let c = b.center();
        let view = TileView {
            camera: Camera {
                eye: [c[0], c[1] - 1.0, c[2] + 3000.0],
                target: c,
                up: [0.0, 0.0, 1.0],
                fov_y_deg: 90.0,
                near: 0.1,
                far: 1e7,
            },
            width: 1000,
            height: 1000,
        };
        // An error of zero refines everything; nothing is loaded yet.
        plan(set, &view, 0.0, &|_| false)
    }

    fn settle(s: &TileStream) {
        let give_up = Instant::now() + Duration::from_secs(30);
        while !s.is_idle() {
            assert!(Instant::now() < give_up, "never idle");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn requests_load_within_the_concurrency_limit() {
        let (set, slow) = simple();
        let config = TileStreamConfig {
            workers: 2,
            ..Default::default()
        };
        let stream = TileStream::new(Arc::clone(&set), slow.clone(), config).expect("threads");
        let p = everything(&set);
        assert!(p.requests.len() >= 2, "{p:?}");
        stream.update(&p);
        settle(&stream);
        assert!(p.requests.iter().all(|w| stream.is_loaded(w.tile)));
        let s = stream.stats();
        assert_eq!(s.loaded, p.requests.len() as u64);
        assert!(slow.most.load(Ordering::SeqCst) <= 2, "{s:?}");
        assert!(s.peak_in_flight >= 1 && s.peak_in_flight <= 2, "{s:?}");
        let tile = p.requests[0].tile;
        let contents = stream.get(tile).expect("held");
        assert_eq!(*contents, set.read_tile(&slow.inner, tile).expect("read"));
        assert!(stream.take_errors().is_empty());
    }

    #[test]
    fn a_new_plan_cancels_what_had_not_started() {
        let (set, slow) = simple();
        let config = TileStreamConfig {
            workers: 1,
            ..Default::default()
        };
        let stream = TileStream::new(Arc::clone(&set), slow, config).expect("threads");
        let p = everything(&set);
        stream.update(&p);
        // The view moves away at once: only what already runs finishes.
        stream.update(&TilePlan::default());
        settle(&stream);
        let s = stream.stats();
        assert!(s.cancelled >= 1, "{s:?}");
        assert!(s.loaded < p.requests.len() as u64, "{s:?}");
        assert_eq!(s.loaded + s.cancelled, p.requests.len() as u64, "{s:?}");
    }

    #[test]
    fn the_budget_holds_and_the_latest_plan_stays() {
        let (set, slow) = simple();
        let p = everything(&set);
        let last = p.requests.last().expect("a request").tile;
        let one = bytes_of(&set.read_tile(&slow.inner, last).expect("read"));
        let config = TileStreamConfig {
            workers: 1,
            ram_budget: one,
        };
        let stream = TileStream::new(Arc::clone(&set), slow, config).expect("threads");
        // Each request alone, then a plan of nothing but drawing the last one.
        for w in &p.requests {
            stream.update(&TilePlan {
                draw: Vec::new(),
                requests: vec![*w],
            });
            settle(&stream);
        }
        stream.update(&TilePlan {
            draw: vec![p.requests[p.requests.len() - 1]],
            requests: Vec::new(),
        });
        let s = stream.stats();
        assert!(s.evicted >= 1, "{s:?}");
        assert!(s.bytes <= one, "{s:?}");
        assert!(stream.is_loaded(last));
    }
}
