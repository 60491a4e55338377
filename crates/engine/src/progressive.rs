//! Loading a point file while it is drawn (progressive-rendering paper §3.2, Fig. 3): a load
//! thread decodes the file in batches (the parts of LAS/LAZ files in parallel on rayon, handed
//! over in file order; other files front to back) and encodes each batch for the GPU; every
//! frame the render thread takes the batches that are ready and scatters them into the shuffled
//! buffer at their points' global indices. Encoded batches wait in a bounded queue, so memory
//! stays bounded whatever the file's size.
//!
//! The caller sizes the [`ShuffledBuffer`] to [`ProgressiveLoad::slots`] and gives it
//! [`ProgressiveLoad::order`]. Slots: the header's point count, or fewer
//! (`LoadConfig::max_slots`, from the VRAM budget), in which case the buffer keeps a uniform
//! random subset of the whole file ([`Reservoir`]): the first points go to their permuted
//! slots, each later one replaces a random slot or is left out. A store's pointlets, shuffled
//! inside, are interleaved instead of permuted ([`GroupRows`]): a batch's points land in runs
//! of neighbouring slots of one chunk of the buffer, and past the slots the first points of
//! every pointlet are kept. A colours-only
//! load ([`LoadConfig::colors_only`]) reads the file again and rewrites only the colours of the
//! same slots (attribute switching, paper §3.5).

use crate::EngineError;
use pointlet_core::color::{
    default_color, point_colors, sample_indices, ColorMode, ColorScale, DefaultColor,
};
use pointlet_core::density::SurfaceDensity;
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::progressive::{
    GroupRows, Reservoir, ShuffleError, ShufflePermutation, SlotOrder,
};
use pointlet_core::{PartedSource, PointBatch, PointLayout};
use pointlet_gpu::shuffle::{
    Dequantize, EncodedBatch, ShufflePass, ShuffledBuffer, StagedBatch, StagedRegion, Targets,
    UploadMemory,
};
use pointlet_gpu::{encode_point, GpuContext, PointEncoding};
use pointlet_io::{PointReader, ReadOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Points per batch: the paper's 500 k.
pub const BATCH_POINTS: usize = 500_000;
/// Encoded batches that may wait for the render thread: enough that decoding goes on while the
/// scene is made and its first frames are drawn (~0.1 s on the H200, when four batches
/// stalled the loader). Upload memory held by waiting batches is reused until loading ends.
pub const QUEUE_BATCHES: usize = 64;
/// Batches of LAS/LAZ parts decoding at once; their parts run in file order, so this bounds how
/// far decoding runs ahead of the oldest batch.
pub const BATCHES_DECODING: usize = 8;

/// Words of a Full16 position.
const WORDS: usize = 3;
/// Full16 ignores the compact quantization step.
const NO_STEP: [f64; 3] = [1.0; 3];

/// How to load.
#[derive(Clone, Debug)]
pub struct LoadConfig {
    /// The colouring asked for; `None` picks the data's default from a sample.
    pub color: Option<ColorMode>,
    /// The exact scale to colour with (its mode wins over `color`); `None` fits one on the
    /// sample.
    pub scale: Option<ColorScale>,
    /// Points per batch (LAS/LAZ batches are whole parts: at least one part, else at most this).
    pub batch_points: usize,
    /// Encoded batches that may wait in the queue (at least 1); the load thread holds one more.
    pub queue_batches: usize,
    /// LAS/LAZ parts a batch takes at least, beyond `batch_points` (0: one per decoding thread).
    pub parallel_parts: usize,
    /// Batches of LAS/LAZ parts that may be decoding at once (at least 1), so that no core waits
    /// for the slowest part of one batch; they are handed over in file order.
    pub batches_decoding: usize,
    /// What text files do not say for themselves.
    pub read: ReadOptions,
    /// Slots of the shuffled buffer at most (the VRAM budget's points); a file with more
    /// points keeps a uniform subset of this many.
    pub max_slots: u64,
    /// Decode and upload only the colours (the positions are already in the buffer).
    pub colors_only: bool,
    /// Seed of the reservoir's choices (a colours-only load must use the points load's).
    pub seed: u64,
}

impl Default for LoadConfig {
    fn default() -> Self {
        Self {
            color: None,
            scale: None,
            batch_points: BATCH_POINTS,
            queue_batches: QUEUE_BATCHES,
            parallel_parts: 0,
            batches_decoding: BATCHES_DECODING,
            read: ReadOptions::default(),
            max_slots: u64::from(u32::MAX),
            colors_only: false,
            seed: 0x5eed,
        }
    }
}

/// How the points are coloured: the scale, and the data's default with its reason when no
/// colouring was asked for (for a `note:` line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadColor {
    pub scale: ColorScale,
    pub default: Option<DefaultColor>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadState {
    Loading,
    /// Every point of the file is in the shuffled buffer.
    Loaded,
    /// Reading ended with an error (reported once by [`ProgressiveLoad::upload_ready`]); the
    /// points uploaded before it stay in the buffer.
    Failed,
}

/// Where loading stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadProgress {
    /// Points the header claims.
    pub total: u64,
    /// Slots of the shuffled buffer: `total`, or fewer when the file exceeds the VRAM budget.
    pub slots: u64,
    /// Points decoded and encoded by the load thread.
    pub loaded: u64,
    /// Points scattered into the shuffled buffer.
    pub uploaded: u64,
    /// Size of the file.
    pub file_bytes: u64,
    /// Since the load started, until it ended.
    pub elapsed: Duration,
    pub state: LoadState,
    /// Batches staged in upload memory: newly made (and, where wgpu maps it, zero-filled)
    /// and reused once the GPU had copied them.
    pub staged_new: u64,
    pub staged_reused: u64,
    /// Time the load threads spent making new upload memory, in all.
    pub staging: Duration,
    /// Of the batches newly made, those made by Vulkan directly (see [`UploadMemory`]).
    pub staged_direct: u64,
    /// Time the load thread waited for the render thread to take batches (the queue was full).
    pub queue_waited: Duration,
}

impl LoadProgress {
    pub fn is_finished(&self) -> bool {
        self.state != LoadState::Loading
    }

    /// Points of the file the buffer holds now.
    pub fn shown(&self) -> u64 {
        self.uploaded.min(self.slots)
    }

    /// Points uploaded per second.
    pub fn points_per_s(&self) -> f64 {
        self.uploaded as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    /// MB (10⁶ bytes) of the file per second, counting the file's share of the points uploaded
    /// (compressed bytes for LAZ).
    pub fn mb_per_s(&self) -> f64 {
        let share = self.uploaded as f64 / self.total.max(1) as f64;
        self.file_bytes as f64 * share / 1e6 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// What one [`ProgressiveLoad::upload_ready`] call did.
#[derive(Debug, Default)]
pub struct Uploaded {
    pub batches: usize,
    pub points: u64,
    /// Of `points`, those whose positions went to the GPU as the store keeps them.
    pub stored: u64,
    /// The reader's error that ended loading, in the one call that received it.
    pub failure: Option<EngineError>,
}

/// Encoded points of the file: those of indices `first..first + colors.len()`, or with
/// `slots`, points past the reservoir's capacity with the slot each replaces. `positions` is
/// empty for a colours-only load. With `staged`, the points are in mapped upload memory
/// instead (indices `first..first + read`, within the capacity) and both vectors are empty.
struct EncodedPoints {
    first: u64,
    slots: Option<Vec<u32>>,
    positions: Vec<u32>,
    colors: Vec<u32>,
    staged: Option<StagedBatch>,
    /// Points of the file this message accounts for (left-out points included).
    read: u64,
}

enum Message {
    Batch(EncodedPoints),
    Failed(String),
    Done,
}

/// Why the load thread stopped early.
enum Stop {
    /// The load was dropped: nobody takes batches any more.
    Closed,
    Failed(String),
}

/// What the load thread and the render thread both see.
struct Shared {
    loaded: AtomicU64,
    color: OnceLock<LoadColor>,
    /// The file's surface spacing at full density, measured on the colour sample.
    spacing: OnceLock<f64>,
    /// The GPU's upload memory, once the render thread has a GPU: batches then go there.
    upload: OnceLock<UploadMemory>,
    /// Staged batches the GPU is done with, writable again, for the next batches.
    staged_pool: Mutex<Vec<StagedBatch>>,
    /// Whether batches are still recycled into the pool (not once loading ended).
    recycling: AtomicBool,
    staged_direct: AtomicU64,
    staged_new: AtomicU64,
    staged_reused: AtomicU64,
    /// Nanoseconds of `LoadProgress::staging` and `LoadProgress::queue_waited`.
    staging_ns: AtomicU64,
    queue_wait_ns: AtomicU64,
}

impl Shared {
    /// A staged batch with room for `points`: one from the pool, else a new one, made by
    /// Vulkan directly where it can be (see [`UploadMemory`]).
    fn take_staged(&self, upload: &UploadMemory, points: u64) -> Option<StagedBatch> {
        let reused = {
            let mut pool = self.staged_pool.lock().unwrap_or_else(|e| e.into_inner());
            let fits = pool.iter().position(|b| b.capacity() >= points);
            fits.map(|i| pool.swap_remove(i))
        };
        if reused.is_some() {
            self.staged_reused.fetch_add(1, Ordering::Relaxed);
            return reused;
        }
        let started = Instant::now();
        // Where Vulkan cannot make it (or its memory is used up), memory wgpu maps.
        let direct = StagedBatch::direct(upload, PointEncoding::Full16, points)
            .ok()
            .flatten();
        self.staged_direct
            .fetch_add(u64::from(direct.is_some()), Ordering::Relaxed);
        let new = direct.or_else(|| StagedBatch::new(upload, PointEncoding::Full16, points).ok());
        self.staging_ns.fetch_add(nanos(started), Ordering::Relaxed);
        self.staged_new
            .fetch_add(u64::from(new.is_some()), Ordering::Relaxed);
        new
    }

    /// Returns a staged batch whose copy was submitted to the pool once it is writable again.
    fn recycle(self: &Arc<Self>, staged: StagedBatch) {
        if !self.recycling.load(Ordering::Relaxed) {
            return;
        }
        let shared = Arc::clone(self);
        staged.recycle(move |b| {
            if shared.recycling.load(Ordering::Relaxed) {
                let mut pool = shared.staged_pool.lock().unwrap_or_else(|e| e.into_inner());
                pool.push(b);
            }
        });
    }
}

/// What the load thread needs besides the reader.
struct Job {
    path: PathBuf,
    total: u64,
    order: SlotOrder,
    reservoir: Reservoir,
    colors_only: bool,
    extras: ExtraAttributes,
    origin: [f64; 3],
    z_range: [f64; 2],
    layout: PointLayout,
    asked: Option<ColorMode>,
    scale: Option<ColorScale>,
    batch_points: usize,
    parallel_parts: usize,
    batches_decoding: usize,
    shared: Arc<Shared>,
    queue: SyncSender<Message>,
}

/// A point file loading into a shuffled buffer; see the module documentation. Dropping it
/// stops the load thread (after the batch it is decoding).
pub struct ProgressiveLoad {
    /// The input's path, or several inputs' joined ([`crate::inputs_name`]).
    path: PathBuf,
    inputs: Vec<PathBuf>,
    layout: PointLayout,
    extras: ExtraAttributes,
    /// What the reader noted about the file (for `note:` lines).
    notes: Vec<String>,
    bounds: pointlet_core::Aabb,
    total: u64,
    slots: u64,
    order: SlotOrder,
    colors_only: bool,
    origin: [f64; 3],
    file_bytes: u64,
    shared: Arc<Shared>,
    queue: Option<Receiver<Message>>,
    /// A message [`wait_ready`](ProgressiveLoad::wait_ready) took off the queue.
    stash: Option<Message>,
    thread: Option<JoinHandle<()>>,
    uploaded: u64,
    started: Instant,
    ended: Option<Instant>,
    state: LoadState,
}

impl ProgressiveLoad {
    /// Opens `path` and starts its load thread. Errors here (a missing file, a bad header, a
    /// colouring the file cannot give) mean nothing was loaded.
    pub fn start(path: &Path, config: LoadConfig) -> Result<Self, EngineError> {
        Self::start_many(&[path.to_path_buf()], config)
    }

    /// [`start`](Self::start) for several inputs drawn as one scene ([`crate::Datasets`]).
    pub fn start_many(inputs: &[PathBuf], config: LoadConfig) -> Result<Self, EngineError> {
        let reader = crate::open_inputs(inputs, &config.read)
            .map_err(|e| EngineError::Read(e.to_string()))?;
        let name = crate::inputs_name(inputs);
        let path = name.as_path();
        let meta = reader.meta();
        let asked = config.scale.map(|s| s.mode).or(config.color);
        if let Some(mode) = asked.filter(|m| !m.available_in(&meta.layout)) {
            return Err(EngineError::Config(format!(
                "{} has no {} attribute to colour by",
                path.display(),
                mode.name()
            )));
        }
        let (total, bounds) = (meta.point_count, meta.bounds);
        let notes = reader.notes().to_vec();
        let layout = meta.layout;
        let slots = total.min(config.max_slots.min(u64::from(u32::MAX)));
        let reservoir = Reservoir::new(slots, config.seed)
            .map_err(|e| EngineError::Config(format!("{}: {e}", path.display())))?;
        let order = slot_order(
            reader.parted().and_then(|p| p.shuffled_groups()),
            total,
            slots,
        )
        .map_err(|e| EngineError::Config(format!("{}: {e}", path.display())))?;
        // An interleave keeps whole rows of every pointlet: at most the budget's points.
        let slots = order.placed();
        let extras = ExtraAttributes::from_vlrs(&meta.vlrs, usize::from(meta.layout.extra_bytes));
        if let Some(ColorMode::Extra(i)) = asked {
            if usize::from(i) >= extras.attributes.len() {
                return Err(EngineError::Config(format!(
                    "{} has no extra-bytes attribute {i} to colour by",
                    path.display()
                )));
            }
        }
        let (origin, z_range) = if meta.bounds.is_empty() {
            ([0.0; 3], [0.0, 1.0])
        } else {
            (meta.bounds.min, [meta.bounds.min[2], meta.bounds.max[2]])
        };
        // Remote tilesets have no one size: their MB/s is not reported.
        let mut file_bytes = 0;
        for input in inputs.iter().filter(|p| !pointlet_store::is_remote(p)) {
            file_bytes += std::fs::metadata(input)
                .map_err(|e| EngineError::Read(format!("{}: {e}", input.display())))?
                .len();
        }
        let shared = Arc::new(Shared {
            loaded: AtomicU64::new(0),
            color: OnceLock::new(),
            spacing: OnceLock::new(),
            upload: OnceLock::new(),
            staged_pool: Mutex::new(Vec::new()),
            recycling: AtomicBool::new(true),
            staged_direct: AtomicU64::new(0),
            staged_new: AtomicU64::new(0),
            staged_reused: AtomicU64::new(0),
            staging_ns: AtomicU64::new(0),
            queue_wait_ns: AtomicU64::new(0),
        });
        let (tx, rx) = sync_channel(config.queue_batches.max(1));
        let job_extras = extras.clone();
        let job = Job {
            path: path.to_path_buf(),
            total,
            order,
            reservoir,
            colors_only: config.colors_only,
            extras,
            origin,
            z_range,
            layout: meta.layout,
            asked,
            scale: config.scale,
            batch_points: config.batch_points.max(1),
            parallel_parts: config.parallel_parts,
            batches_decoding: config.batches_decoding.max(1),
            shared: Arc::clone(&shared),
            queue: tx,
        };
        let thread = std::thread::Builder::new()
            .name("point-load".into())
            .spawn(move || load(reader, job))
            .map_err(|e| EngineError::Read(format!("starting the load thread: {e}")))?;
        Ok(Self {
            path: path.to_path_buf(),
            inputs: inputs.to_vec(),
            layout,
            extras: job_extras,
            notes,
            bounds,
            total,
            slots,
            order,
            colors_only: config.colors_only,
            origin,
            file_bytes,
            shared,
            queue: Some(rx),
            stash: None,
            thread: Some(thread),
            uploaded: 0,
            started: Instant::now(),
            ended: None,
            state: LoadState::Loading,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The files (or stores, or tilesets) loading, in order.
    pub fn inputs(&self) -> &[PathBuf] {
        &self.inputs
    }

    /// What the reader noted about the file.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The attributes the file has.
    pub fn layout(&self) -> PointLayout {
        self.layout
    }

    /// Its extra-bytes attributes.
    pub fn extras(&self) -> &ExtraAttributes {
        &self.extras
    }

    /// The header's bounds (positions are encoded relative to their minimum).
    pub fn bounds(&self) -> pointlet_core::Aabb {
        self.bounds
    }

    /// Points the header claims.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Slots of the shuffled buffer to scatter into: [`total`](Self::total), or the VRAM
    /// budget's points when the file holds more.
    pub fn slots(&self) -> u64 {
        self.slots
    }

    /// Where the points go in the buffer: the shuffled buffer must place them so.
    pub fn order(&self) -> SlotOrder {
        self.order
    }

    pub fn colors_only(&self) -> bool {
        self.colors_only
    }

    /// Positions are relative to this point (the header bounds' minimum).
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// The file's surface spacing at full density (1/√density), once the load thread has
    /// measured it on its sample.
    pub fn spacing(&self) -> Option<f64> {
        self.shared.spacing.get().copied()
    }

    /// The colouring, once the load thread has chosen it from its sample.
    pub fn color(&self) -> Option<LoadColor> {
        self.shared.color.get().copied()
    }

    pub fn progress(&self) -> LoadProgress {
        LoadProgress {
            total: self.total,
            slots: self.slots,
            loaded: self.shared.loaded.load(Ordering::Relaxed),
            uploaded: self.uploaded,
            file_bytes: self.file_bytes,
            elapsed: self.ended.unwrap_or_else(Instant::now) - self.started,
            state: self.state,
            staged_new: self.shared.staged_new.load(Ordering::Relaxed),
            staged_reused: self.shared.staged_reused.load(Ordering::Relaxed),
            staging: Duration::from_nanos(self.shared.staging_ns.load(Ordering::Relaxed)),
            staged_direct: self.shared.staged_direct.load(Ordering::Relaxed),
            queue_waited: Duration::from_nanos(self.shared.queue_wait_ns.load(Ordering::Relaxed)),
        }
    }

    /// The GPU the batches are for: from now on the load thread decodes into its upload
    /// memory (before, batches wait in memory and the render thread uploads them).
    pub fn use_device(&self, ctx: &GpuContext) {
        self.shared.upload.get_or_init(|| UploadMemory::new(ctx));
    }

    /// Like [`use_device`](Self::use_device), with the upload memory of another load.
    pub(crate) fn use_upload(&self, upload: &UploadMemory) {
        self.shared.upload.get_or_init(|| upload.clone());
    }

    /// The upload memory given by [`use_device`](Self::use_device), if any.
    pub(crate) fn upload(&self) -> Option<&UploadMemory> {
        self.shared.upload.get()
    }

    /// Scatters up to `max_batches` batches that are ready into `dst` (a Full16 buffer of
    /// [`slots`](Self::slots) slots) without waiting for the load thread. An `Err` is a GPU or
    /// configuration error; the reader's error comes back once, in [`Uploaded::failure`].
    pub fn upload_ready(
        &mut self,
        ctx: &GpuContext,
        pass: &mut ShufflePass,
        dst: &ShuffledBuffer,
        max_batches: usize,
    ) -> Result<Uploaded, EngineError> {
        let same_order = match (dst.order(), self.order) {
            (SlotOrder::Permuted(a), SlotOrder::Permuted(b)) => a == b,
            // The buffer's chunks are its own.
            (SlotOrder::Interleaved(a), SlotOrder::Interleaved(b)) => {
                (a.len(), a.shift(), a.rows()) == (b.len(), b.shift(), b.rows())
            }
            _ => false,
        };
        if dst.encoding() != PointEncoding::Full16 || dst.placed() != self.slots || !same_order {
            return Err(EngineError::Config(format!(
                "{} loads into a full16 shuffled buffer of {} slots ({:?}), not a {} one of {} \
                 ({:?})",
                self.path.display(),
                self.slots,
                self.order,
                dst.encoding().name(),
                dst.slots(),
                dst.order()
            )));
        }
        self.use_device(ctx);
        let mut up = Uploaded::default();
        while up.batches < max_batches {
            let Some(queue) = &self.queue else { break };
            let next = match self.stash.take() {
                Some(m) => Ok(m),
                None => queue.try_recv(),
            };
            match next {
                Ok(Message::Batch(mut b)) => {
                    // Points for a chunk of the buffer not made yet wait for it.
                    if b.slots.is_none() && !dst.ready_for(b.first, b.read) {
                        self.stash = Some(Message::Batch(b));
                        break;
                    }
                    let targets = match &b.slots {
                        Some(slots) => Targets::Slots(slots),
                        // The load thread keeps permuted batches within the slots ≤ u32::MAX.
                        None => Targets::Permuted {
                            first: u32::try_from(b.first).map_err(|_| {
                                EngineError::Config(format!(
                                    "point {} lies beyond u32 slots",
                                    b.first
                                ))
                            })?,
                        },
                    };
                    // Staged batches are within the capacity: always permuted.
                    if let (Some(staged), Targets::Permuted { first }) = (b.staged.take(), targets)
                    {
                        pass.scatter_staged(ctx, dst, first, &staged)?;
                        if staged.holds_stored_positions() {
                            up.stored += b.read;
                        }
                        self.shared.recycle(staged);
                    } else if self.colors_only {
                        pass.scatter_colors(ctx, dst, targets, &b.colors)?;
                    } else {
                        let batch = EncodedBatch {
                            positions: &b.positions,
                            fine: &[],
                            colors: &b.colors,
                        };
                        pass.scatter_to(ctx, dst, targets, batch)?;
                    }
                    self.uploaded += b.read;
                    up.batches += 1;
                    up.points += b.read;
                }
                Ok(Message::Done) => self.end(LoadState::Loaded),
                Ok(Message::Failed(message)) => {
                    self.end(LoadState::Failed);
                    up.failure = Some(EngineError::Read(message));
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.end(LoadState::Failed);
                    up.failure = Some(EngineError::Read(format!(
                        "{}: the load thread stopped before the end of the file",
                        self.path.display()
                    )));
                }
            }
        }
        Ok(up)
    }

    /// Waits up to `timeout` until the load thread has something for
    /// [`upload_ready`](Self::upload_ready) (a batch, the end or an error); false if nothing
    /// came. For callers with nothing to draw until then (`render`).
    pub fn wait_ready(&mut self, timeout: Duration) -> bool {
        if self.stash.is_some() {
            return true;
        }
        let Some(queue) = &self.queue else {
            return true;
        };
        match queue.recv_timeout(timeout) {
            Ok(m) => {
                self.stash = Some(m);
                true
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => false,
            // upload_ready reports the stopped thread.
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => true,
        }
    }

    fn end(&mut self, state: LoadState) {
        // The pool's mapped memory is not needed any more.
        self.shared.recycling.store(false, Ordering::Relaxed);
        self.shared
            .staged_pool
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
        self.state = state;
        self.ended = Some(Instant::now());
        self.stop_thread();
    }

    fn stop_thread(&mut self) {
        // Without its queue the load thread's next send fails and it returns.
        self.queue = None;
        self.stash = None;
        if let Some(thread) = self.thread.take() {
            // A panic there was already reported as a disconnected queue.
            let _ = thread.join();
        }
    }
}

impl Drop for ProgressiveLoad {
    fn drop(&mut self) {
        self.stop_thread();
    }
}

/// The load thread: every batch, then `Done`, or the error that ended reading.
fn load(mut reader: Box<dyn PointReader>, job: Job) {
    let end = match reader.parted() {
        Some(parts) => load_parts(parts, &job),
        None => load_sequential(reader.as_mut(), &job),
    };
    let last = match end {
        Ok(()) => Message::Done,
        Err(Stop::Failed(message)) => Message::Failed(message),
        Err(Stop::Closed) => return,
    };
    // A closed queue here means the load was dropped: nobody is left to tell.
    let _ = job.queue.send(last);
}

/// Parts grouped into batches in file order, each group decoded in parallel.
fn load_parts(parts: &dyn PartedSource, job: &Job) -> Result<(), Stop> {
    let sizes = parts.part_sizes();
    let mut sample = Vec::new();
    let color = *job.shared.color.get_or_init(|| {
        // Decoded in parallel: the sample delays the first batch. A part that fails is left
        // out of it: loading reports the failure when it gets there.
        sample = sample_indices(sizes.len())
            .into_par_iter()
            .map(|i| {
                let mut b = PointBatch::default();
                match parts.decode_part(i, &mut b, &mut Vec::new()) {
                    Ok(()) => b,
                    Err(_) => PointBatch::default(),
                }
            })
            .collect();
        choose_color(job, &sample.iter().collect::<Vec<_>>())
    });
    // A batch is decoded in parallel and waits for its slowest part: it takes at least one
    // part per thread (LAZ chunks are 50 000 points: ten would leave 16 cores idle).
    let threads = match job.parallel_parts {
        0 => rayon::current_num_threads(),
        n => n,
    };
    let mut plan = Vec::new();
    let (mut part, mut first) = (0, 0u64);
    while part < sizes.len() {
        let mut end = part + 1;
        let mut points = sizes[part];
        while end < sizes.len()
            && (points + sizes[end] <= job.batch_points as u64 || end - part < threads)
        {
            points += sizes[end];
            end += 1;
        }
        plan.push(PlannedBatch {
            parts: part..end,
            first,
            points,
        });
        first += points;
        part = end;
    }
    // Each batch in flight has a thread of its own that queues the batch's parts as separate
    // tasks and waits for them outside the pool. Parts then run in the order they were queued
    // and batches finish in file order: batches decoded with nested parallel loops interleave,
    // since a worker waiting for its half of one batch takes on parts of the next ones, and
    // they all finish late, together.
    let (cancelled, scratches) = (AtomicBool::new(false), ScratchPool::default());
    let (work, tickets) = std::sync::mpsc::channel::<(usize, PlannedBatch)>();
    let tickets = Mutex::new(tickets);
    std::thread::scope(|threads| {
        // Owned here: dropping it on return ends the batch threads, which the scope joins.
        let work = work;
        // The spacing is for splat sizes, not needed to decode: measured beside the batches.
        if !sample.is_empty() {
            let sample = &sample;
            let spawned = std::thread::Builder::new()
                .name("point-spacing".into())
                .spawn_scoped(threads, move || measure_spacing(job, sample));
            if spawned.is_err() {
                measure_spacing(job, sample);
            }
        }
        let (done, decoded) = std::sync::mpsc::channel();
        for _ in 0..job.batches_decoding {
            let (tickets, done, cancelled) = (&tickets, done.clone(), &cancelled);
            let (color, scratches) = (&color, &scratches);
            let batch_thread = move || loop {
                // The lock is held only while waiting for the next batch.
                let next = tickets.lock().unwrap_or_else(|e| e.into_inner()).recv();
                let Ok((k, batch)) = next else { return };
                let result = if cancelled.load(Ordering::Relaxed) {
                    Err(Stop::Closed)
                } else {
                    decode_batch(parts, job, color, batch, scratches)
                };
                // The receiver is gone only when loading already stopped.
                let _ = done.send((k, result));
            };
            std::thread::Builder::new()
                .name("point-batch".into())
                .spawn_scoped(threads, batch_thread)
                .map_err(|e| Stop::Failed(format!("starting a decoding thread: {e}")))?;
        }
        drop(done);
        let mut planned = plan.into_iter().enumerate();
        let mut finished = std::collections::BTreeMap::new();
        let (mut next, mut given) = (0, 0);
        loop {
            while given < next + job.batches_decoding {
                let Some(batch) = planned.next() else { break };
                // The batch threads hold the receiver until this sender is dropped.
                let _ = work.send(batch);
                given += 1;
            }
            if next == given {
                return Ok(());
            }
            let (k, result) = decoded.recv().map_err(|_| {
                Stop::Failed(format!(
                    "{}: the decoding threads stopped before the end of the file",
                    job.path.display()
                ))
            })?;
            finished.insert(k, result);
            while let Some(result) = finished.remove(&next) {
                next += 1;
                let end = result.and_then(|(out, failure)| {
                    send(job, out)?;
                    failure.map_or(Ok(()), |message| Err(Stop::Failed(message)))
                });
                if end.is_err() {
                    cancelled.store(true, Ordering::Relaxed);
                    return end;
                }
            }
        }
    })
}

impl Job {
    /// Points the buffer's order places (the GPU leaves out those past its slots); the
    /// reservoir chooses the slots of later ones.
    fn placed_in_order(&self) -> u64 {
        match self.order {
            SlotOrder::Interleaved(_) => self.total,
            SlotOrder::Permuted(_) => self.reservoir.capacity(),
        }
    }
}

/// The order of a file of `total` points in a buffer of `slots`: a source of shuffled groups
/// interleaves them (all points placed, those past the slots left out: the first points of
/// every group, a uniform subset); any other is permuted, the reservoir placing what is past
/// the slots. The GPU indexes points with 32 bits: a file of more points is permuted too.
fn slot_order(groups: Option<u64>, total: u64, slots: u64) -> Result<SlotOrder, String> {
    let interleaved = match groups.filter(|_| total <= u64::from(u32::MAX)) {
        Some(k) => match GroupRows::new(total, k, slots) {
            Ok(g) => Some(g),
            // A budget of fewer slots than pointlets: no row of them fits, a subset is kept.
            Err(ShuffleError::TooFewSlots { .. }) => None,
            Err(e) => return Err(e.to_string()),
        },
        None => None,
    };
    match interleaved {
        Some(g) => Ok(SlotOrder::Interleaved(g)),
        None => ShufflePermutation::new(slots)
            .map(SlotOrder::Permuted)
            .map_err(|e| e.to_string()),
    }
}

/// Parts that make one batch, and the index of its first point in the file.
struct PlannedBatch {
    parts: std::ops::Range<usize>,
    first: u64,
    points: u64,
}

/// Decodes and encodes the parts of `batch` in parallel: the points of the parts before the
/// first that failed, and that part's error.
fn decode_batch(
    parts: &dyn PartedSource,
    job: &Job,
    color: &LoadColor,
    batch: PlannedBatch,
    scratches: &ScratchPool,
) -> Result<(Vec<EncodedPoints>, Option<String>), Stop> {
    let sizes = parts.part_sizes();
    let PlannedBatch {
        parts: range,
        first,
        points,
    } = batch;
    check_fits(job, first, points)?;
    let words = if job.colors_only { 0 } else { WORDS };
    // Within the reservoir's capacity and once the GPU is there, straight into upload memory.
    let mut staged = job
        .shared
        .upload
        .get()
        .filter(|_| !job.colors_only && first + points <= job.placed_in_order())
        .and_then(|upload| job.shared.take_staged(upload, points));
    let is_staged = staged.is_some();
    let in_memory = if is_staged { 0 } else { points as usize };
    let mut out = EncodedPoints {
        first,
        slots: None,
        positions: vec![0; in_memory * words],
        colors: vec![0; in_memory],
        staged: None,
        read: points,
    };
    let mut view = staged
        .as_mut()
        .map(StagedBatch::map)
        .transpose()
        .map_err(|e| Stop::Failed(format!("{}: {e}", job.path.display())))?;
    // Each part's share of the batch, so that threads encode in place.
    let mut jobs = Vec::with_capacity(range.len());
    match view.as_mut() {
        Some(view) => {
            let regions = view.regions();
            let (mut pos, mut col) = (regions.positions, regions.colors);
            for i in range.clone() {
                let size = sizes[i] as usize;
                let (p, rest_p) = pos.split_at(size * WORDS * 4);
                let (c, rest_c) = col.split_at(size * 4);
                jobs.push((i, Share::Mapped(p, c)));
                (pos, col) = (rest_p, rest_c);
            }
        }
        _ => {
            let (mut pos, mut col) = (&mut out.positions[..], &mut out.colors[..]);
            for i in range.clone() {
                let size = sizes[i] as usize;
                let (p, rest_p) = std::mem::take(&mut pos).split_at_mut(size * words);
                let (c, rest_c) = std::mem::take(&mut col).split_at_mut(size);
                jobs.push((i, Share::Slices(p, c)));
                (pos, col) = (rest_p, rest_c);
            }
        }
    }
    // A store's positions go to the GPU as stored, dequantized there (unless the colouring
    // needs them here: elevation).
    let stored = parts
        .quantized_positions()
        .filter(|_| is_staged && color.scale.mode != ColorMode::Elevation)
        .map(|q| Dequantize::new(q.scale, q.offset, job.origin));
    // One task per part, queued in order (see `load_parts`), each with scratch from the pool.
    let mut results: Vec<Result<(), String>> = jobs.iter().map(|_| Ok(())).collect();
    rayon::in_place_scope(|scope| {
        for ((i, share), result) in jobs.into_iter().zip(results.iter_mut()) {
            scope.spawn(move |_| {
                let mut scratch = scratches.take();
                *result = encode_part(parts, job, color, stored, i, share, &mut scratch);
                scratches.put(scratch);
            });
        }
    });
    // The parts before the first that failed are good: they go to the GPU before the error.
    let good = results.iter().take_while(|r| r.is_ok()).count();
    let kept: u64 = sizes[range.start..range.start + good].iter().sum();
    drop(view);
    match staged {
        Some(mut staged) => {
            staged.finish(kept);
            if let Some(d) = stored {
                staged
                    .set_dequantize(d)
                    .map_err(|e| Stop::Failed(format!("{}: {e}", job.path.display())))?;
            }
            out.staged = Some(staged);
        }
        None => {
            out.positions.truncate(kept as usize * words);
            out.colors.truncate(kept as usize);
        }
    }
    out.read = kept;
    let failure = results.into_iter().nth(good).and_then(Result::err);
    Ok((split_at_capacity(job, out), failure))
}

/// Decodes part `i` and encodes it into its share of the batch.
fn encode_part(
    parts: &dyn PartedSource,
    job: &Job,
    color: &LoadColor,
    stored: Option<Dequantize>,
    i: usize,
    share: Share<'_>,
    scratch: &mut PartScratch,
) -> Result<(), String> {
    let share = match (stored, share) {
        (Some(_), Share::Mapped(p, c)) => return stored_part(parts, job, color, i, scratch, p, c),
        (_, share) => share,
    };
    let PartScratch {
        batch,
        bytes,
        positions,
        colors,
        ..
    } = scratch;
    parts
        .decode_part_for(i, batch, bytes, color.scale.mode)
        .map_err(|e| e.to_string())?;
    let size = parts.part_sizes()[i];
    if batch.len() as u64 != size {
        return Err(format!(
            "{}: part {i} decoded to {} points, its size is {size}",
            job.path.display(),
            batch.len(),
        ));
    }
    match share {
        Share::Slices(p, c) => encode_into(batch, job.origin, &color.scale, p, c),
        Share::Mapped(mut p, mut c) => {
            // Encoded in cache, then written once: mapped memory may be write-combining.
            positions.resize(batch.len() * WORDS, 0u32);
            colors.resize(batch.len(), 0u32);
            encode_into(batch, job.origin, &color.scale, positions, colors);
            p.write(positions).map_err(|e| e.to_string())?;
            c.write(colors).map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

/// What decoding one part needs besides its share: reused from part to part.
#[derive(Default)]
pub struct PartScratch {
    batch: PointBatch,
    bytes: Vec<u8>,
    positions: Vec<u32>,
    colors: Vec<u32>,
    classes: Vec<u8>,
}

/// Scratch of finished parts for the next ones (dropped with the load).
#[derive(Default)]
struct ScratchPool(Mutex<Vec<PartScratch>>);

impl ScratchPool {
    fn take(&self) -> PartScratch {
        let mut pool = self.0.lock().unwrap_or_else(|e| e.into_inner());
        pool.pop().unwrap_or_default()
    }

    fn put(&self, scratch: PartScratch) {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(scratch);
    }
}

/// A store's part for a [`Share::Mapped`]: its positions as stored into the position region
/// (the GPU dequantizes them), its colours computed from the streams they need.
fn stored_part(
    parts: &dyn PartedSource,
    job: &Job,
    color: &LoadColor,
    i: usize,
    scratch: &mut PartScratch,
    mut p: StagedRegion<'_>,
    mut c: StagedRegion<'_>,
) -> Result<(), String> {
    let write_positions = |bytes: &[u8]| p.write(bytes).map_err(|e| e.to_string());
    let colors = read_stored_part(parts, &job.path, &color.scale, i, scratch, write_positions)?;
    c.write(colors).map_err(|e| e.to_string())
}

/// Part `i` of a store as a load sends it to the GPU: its positions as stored (12 bytes a
/// point, checksummed) handed to `positions`, then its colours under `scale` made from the
/// streams they need (or from its attributes decoded, where `scale` needs more), returned.
/// `bench-read --staged` measures loads through it.
pub fn read_stored_part<'s>(
    parts: &dyn PartedSource,
    path: &Path,
    scale: &ColorScale,
    i: usize,
    scratch: &'s mut PartScratch,
    positions: impl FnOnce(&[u8]) -> Result<(), String>,
) -> Result<&'s [u32], String> {
    let PartScratch {
        batch,
        bytes: raw,
        colors: c_words,
        classes,
        ..
    } = scratch;
    let size = parts.part_sizes()[i];
    let bytes = parts
        .read_quantized_positions(i, raw)
        .map_err(|e| e.to_string())?;
    if bytes as u64 != size * 12 {
        return Err(format!(
            "{}: part {i} holds {bytes} bytes of positions, its size is {size} points",
            path.display(),
        ));
    }
    positions(&raw[..bytes])?;
    c_words.resize(size as usize, 0u32);
    let direct = parts
        .stored_colors(i, scale, c_words, raw, classes)
        .map_err(|e| e.to_string())?;
    if !direct {
        parts
            .decode_attributes_for(i, batch, raw, scale.mode)
            .map_err(|e| e.to_string())?;
        point_colors(batch, scale, c_words);
    }
    Ok(c_words)
}

/// One part's share of a batch's encoded points.
enum Share<'a> {
    Slices(&'a mut [u32], &'a mut [u32]),
    /// Bytes of mapped upload memory: position words, colours.
    Mapped(StagedRegion<'a>, StagedRegion<'a>),
}

/// Batches read front to back; the first one chooses the colouring, as `render` does.
fn load_sequential(reader: &mut dyn PointReader, job: &Job) -> Result<(), Stop> {
    let mut first = 0u64;
    loop {
        let batch = match reader.read_batch(job.batch_points) {
            Ok(Some(b)) => b,
            Ok(None) if first == job.total => return Ok(()),
            Ok(None) => {
                return Err(Stop::Failed(format!(
                    "{}: the file ends after {first} of the {} points its header claims",
                    job.path.display(),
                    job.total
                )))
            }
            Err(e) => return Err(Stop::Failed(e.to_string())),
        };
        if batch.is_empty() {
            continue;
        }
        let color = *job.shared.color.get_or_init(|| {
            measure_spacing(job, std::slice::from_ref(&batch));
            choose_color(job, &[&batch])
        });
        let n = batch.len();
        check_fits(job, first, n as u64)?;
        let words = if job.colors_only { 0 } else { WORDS };
        let mut out = EncodedPoints {
            first,
            slots: None,
            positions: vec![0; n * words],
            colors: vec![0; n],
            staged: None,
            read: n as u64,
        };
        encode_into(
            &batch,
            job.origin,
            &color.scale,
            &mut out.positions,
            &mut out.colors,
        );
        send(job, split_at_capacity(job, out))?;
        first += n as u64;
    }
}

/// The surface spacing of the file where `sample` (whole parts at full density) lies.
fn measure_spacing(job: &Job, sample: &[PointBatch]) {
    let mut bounds = pointlet_core::Aabb::EMPTY;
    for b in sample {
        for p in &b.xyz {
            bounds.grow(*p);
        }
    }
    let mut density = SurfaceDensity::new(&bounds);
    for b in sample {
        let stride = (b.len() / 65_536).max(1);
        density.add(b.xyz.iter().step_by(stride).copied());
    }
    let points: usize = sample.iter().map(|b| b.len()).sum();
    if let Some(s) = density.spacing(points as u64) {
        let _ = job.shared.spacing.set(s);
    }
}

/// The colouring asked for, or the data's default decided on `sample`.
fn choose_color(job: &Job, sample: &[&PointBatch]) -> LoadColor {
    if let Some(scale) = job.scale {
        return LoadColor {
            scale,
            default: None,
        };
    }
    let default = match job.asked {
        Some(_) => None,
        None => Some(default_color(&job.layout, sample)),
    };
    let mode = job
        .asked
        .or(default.map(|d| d.mode))
        .unwrap_or(ColorMode::Elevation);
    LoadColor {
        scale: ColorScale::fit_in(mode, sample, job.z_range, &job.extras),
        default,
    }
}

/// Points `first..first + n` must lie within the header's count (the buffer's slots).
fn check_fits(job: &Job, first: u64, n: u64) -> Result<(), Stop> {
    if first + n > job.total {
        return Err(Stop::Failed(format!(
            "{}: the file holds more points than the {} its header claims",
            job.path.display(),
            job.total
        )));
    }
    Ok(())
}

/// Full16 position words relative to `origin` (none when `positions` is empty: a colours-only
/// load) and RGBA8 colours of every point of `batch`.
fn encode_into(
    batch: &PointBatch,
    origin: [f64; 3],
    scale: &ColorScale,
    positions: &mut [u32],
    colors: &mut [u32],
) {
    point_colors(batch, scale, colors);
    for (p, xyz) in positions.chunks_exact_mut(WORDS).zip(&batch.xyz) {
        p.copy_from_slice(&encode_point(*xyz, origin, NO_STEP, PointEncoding::Full16));
    }
}

/// A batch as the render thread takes it: the points within the reservoir's capacity as they
/// are, those past it with the slots they replace (on the calling thread, in parallel: this is
/// a file's whole rest once it outgrows the GPU budget).
fn split_at_capacity(job: &Job, batch: EncodedPoints) -> Vec<EncodedPoints> {
    let capacity = job.placed_in_order();
    let (first, n) = (batch.first, batch.read);
    if n == 0 || first + n <= capacity {
        return vec![batch];
    }
    let words = batch.positions.len() / batch.colors.len().max(1);
    let inside = capacity.saturating_sub(first) as usize;
    let mut out = Vec::with_capacity(2);
    if inside > 0 {
        out.push(EncodedPoints {
            first,
            slots: None,
            positions: batch.positions[..inside * words].to_vec(),
            colors: batch.colors[..inside].to_vec(),
            staged: None,
            read: inside as u64,
        });
    }
    // (slot, last-to-first index) keys: sorted, the first key of each slot is the batch's
    // last point that picked it, which must win (a later point replaces an earlier one).
    let mut keys: Vec<u64> = (inside..batch.colors.len())
        .into_par_iter()
        .filter_map(|k| {
            let slot = job.reservoir.slot(first + k as u64)?;
            Some(slot << 32 | u64::from(u32::MAX - k as u32))
        })
        .collect();
    keys.par_sort_unstable();
    keys.dedup_by_key(|key| *key >> 32);
    let index = |key: u64| (u32::MAX - key as u32) as usize;
    let mut positions = vec![0u32; keys.len() * words];
    if words > 0 {
        positions
            .par_chunks_mut(words)
            .zip(keys.par_iter())
            .for_each(|(p, &key)| {
                let k = index(key);
                p.copy_from_slice(&batch.positions[k * words..(k + 1) * words]);
            });
    }
    out.push(EncodedPoints {
        first: first + inside as u64,
        slots: Some(keys.iter().map(|key| (key >> 32) as u32).collect()),
        positions,
        colors: keys
            .par_iter()
            .map(|&key| batch.colors[index(key)])
            .collect(),
        staged: None,
        read: n - inside as u64,
    });
    out
}

/// Hands batches to the render thread, waiting while the queue is full.
fn send(job: &Job, batches: Vec<EncodedPoints>) -> Result<(), Stop> {
    for m in batches {
        if m.read == 0 {
            continue;
        }
        job.shared.loaded.fetch_add(m.read, Ordering::Relaxed);
        match job.queue.try_send(Message::Batch(m)) {
            Ok(()) => {}
            Err(TrySendError::Full(m)) => {
                let started = Instant::now();
                job.queue.send(m).map_err(|_| Stop::Closed)?;
                job.shared
                    .queue_wait_ns
                    .fetch_add(nanos(started), Ordering::Relaxed);
            }
            Err(TrySendError::Disconnected(_)) => return Err(Stop::Closed),
        }
    }
    Ok(())
}

/// Nanoseconds since `started`, for the load's time counters.
fn nanos(started: Instant) -> u64 {
    u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stores_interleave_within_32_bits_and_everything_else_is_permuted() {
        let max = u64::from(u32::MAX);
        let interleaved = |o| matches!(o, Ok(SlotOrder::Interleaved(_)));
        assert!(interleaved(slot_order(Some(4096), 1_000_000, 1_000_000)));
        assert!(interleaved(slot_order(Some(4096), max, 1 << 20)));
        // Past 2^32 - 1 points a store keeps the reservoir's subset, as any file does.
        let huge = slot_order(Some(4096), max + 1, max);
        assert_eq!(
            huge,
            Ok(SlotOrder::Permuted(ShufflePermutation::new(max).unwrap()))
        );
        let file = slot_order(None, 5_000, 4_000);
        assert_eq!(
            file,
            Ok(SlotOrder::Permuted(ShufflePermutation::new(4_000).unwrap()))
        );
        assert!(slot_order(Some(48), 100, 100).is_err());
        // Fewer slots than pointlets: not a row of each fits, the reservoir keeps a subset.
        assert_eq!(
            slot_order(Some(64), 6_400, 50),
            Ok(SlotOrder::Permuted(ShufflePermutation::new(50).unwrap()))
        );
        // Whole rows of every pointlet within the budget.
        match slot_order(Some(64), 6_400, 1_000) {
            Ok(SlotOrder::Interleaved(g)) => assert_eq!((g.rows(), g.placed()), (10, 1_000)),
            other => panic!("{other:?}"),
        }
    }
}
