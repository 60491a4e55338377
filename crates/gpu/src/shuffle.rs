//! The shuffled point buffer of progressive rendering (progressive-rendering paper §3.1,
//! §3.3): batches arrive in a staging ("Distribute") buffer in load order, and `ShufflePass`
//! scatters each point to its slot under the prime-number permutation (or, for a store, its
//! pointlets interleaved: [`SlotOrder`]), so that any prefix of the buffer is a spread-out
//! subsample of the points loaded so far. Points are stored like
//! the point storage's: encoded position words, fine words (Compact8) and RGBA8 colours, in
//! as many buffers as the binding limit requires.

use crate::context::GpuContext;
use crate::device_memory::{DirectAllocator, MappedBuffer};
use crate::raster::{grid, storage_group};
use crate::shaders;
use crate::storage::{PointChunk, PointEncoding, PointStorage};
use crate::target::map_read;
use crate::GpuError;
use bytemuck::{Pod, Zeroable};
use pointlet_core::progressive::{ShufflePermutation, SlotOrder};

/// Points of a batch, encoded as the streams store them (see [`crate::encode_point`]):
/// `positions` has 3 words per point for Full16 and 1 for Compact8, `fine` one word per point
/// for Compact8 and none for Full16.
#[derive(Clone, Copy, Debug)]
pub struct EncodedBatch<'a> {
    pub positions: &'a [u32],
    pub fine: &'a [u32],
    pub colors: &'a [u32],
}

/// Where [`StagedBatch`]es are made. On Vulkan, memory made by Vulkan directly in the device's
/// own memory that the host sees (the resizable BAR on a discrete GPU), mapped for good: no
/// allocator lock and no zero-filling by one thread per batch, as memory wgpu maps has (~8 ms a
/// 16 MB batch on the H100 machine). Elsewhere (browsers, [`Capabilities::direct_memory`] off,
/// no such memory left), memory wgpu maps.
///
/// Host memory the GPU pulls over the bus was tried (docs/BENCHMARKS.md, issue 11, sessions
/// 47–48): threads write it twice as fast as the BAR, but the driver pins it as it makes it
/// (3.6–5.8 GB/s), and its copies over the bus take the frames' one queue: loads were slower
/// and frames stalled while loading.
///
/// [`Capabilities::direct_memory`]: crate::Capabilities::direct_memory
#[derive(Clone)]
pub struct UploadMemory {
    device: wgpu::Device,
    queue: wgpu::Queue,
    direct: Option<std::sync::Arc<DirectAllocator>>,
}

impl UploadMemory {
    pub fn new(ctx: &GpuContext) -> Self {
        Self {
            device: ctx.device.clone(),
            queue: ctx.queue.clone(),
            direct: ctx.direct_allocator().map(std::sync::Arc::new),
        }
    }

    /// Whether batches can be made by Vulkan directly ([`StagedBatch::direct`]).
    pub fn makes_directly(&self) -> bool {
        self.direct.is_some()
    }
}

/// A batch encoded straight into mapped upload memory by the threads that decode it: the
/// render thread then records only its copy to the GPU and its scatter, without a copy of its
/// own on the CPU (a whole batch through `Queue::write_buffer` runs at one core's memcpy).
/// Regions: position words, fine words (Compact8), colours, each for `capacity` points.
pub struct StagedBatch {
    memory: StagedMemory,
    encoding: PointEncoding,
    capacity: u64,
    /// Points written (set by [`finish`](Self::finish)).
    count: u64,
    /// Set when the position region holds stored positions for the GPU to dequantize.
    dequantize: Option<Dequantize>,
}

/// How the shuffle pass turns a store's positions as stored (x, y, z as i32 of its
/// quantization) into Full16 words relative to the buffer's origin: `(q - base) · step +
/// shift`, with `base` the grid point nearest the origin and `shift` the origin's distance
/// from it. Within about an ulp of the f64 `encode_point` of the dequantized position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dequantize {
    base: [i32; 3],
    step: [f64; 3],
    shift: [f64; 3],
}

impl Dequantize {
    /// For positions `q · scale + offset` in a buffer whose positions are relative to `origin`.
    pub fn new(scale: [f64; 3], offset: [f64; 3], origin: [f64; 3]) -> Self {
        let base = [0, 1, 2].map(|a| {
            let q = ((origin[a] - offset[a]) / scale[a]).round();
            if q.is_finite() {
                q.clamp(i32::MIN as f64, i32::MAX as f64) as i32
            } else {
                0
            }
        });
        Self {
            base,
            step: scale,
            shift: [0, 1, 2].map(|a| base[a] as f64 * scale[a] + offset[a] - origin[a]),
        }
    }

    /// One stored position's Full16 words, computed as the shader computes them (f32
    /// products and sums in its order; a GPU that fuses them may differ by an ulp).
    pub fn words(&self, q: [i32; 3]) -> [u32; 3] {
        let u = self.uniform();
        [0, 1, 2].map(|a| {
            let b = u.base[a];
            let dh = (q[a] >> 16) - (b >> 16);
            let dl = (q[a] & 0xffff) - (b & 0xffff);
            let (hs, ls) = (u.step_hi[a], u.step_lo[a]);
            if dh.abs() < 255 {
                let d = (dh * 65536 + dl) as f32;
                return (d * hs + (d * ls + u.shift[a])).to_bits();
            }
            let hi = dh as f32 * 65536.0;
            let lo = dl as f32;
            (hi * hs + (hi * ls + (lo * hs + (lo * ls + u.shift[a])))).to_bits()
        })
    }

    fn uniform(&self) -> DequantizeUniform {
        let hi = self.step.map(|s| s as f32);
        let lo = [0, 1, 2].map(|a| (self.step[a] - hi[a] as f64) as f32);
        let shift = self.shift.map(|s| s as f32);
        let [b0, b1, b2] = self.base;
        DequantizeUniform {
            base: [b0, b1, b2, 0],
            step_hi: [hi[0], hi[1], hi[2], 0.0],
            step_lo: [lo[0], lo[1], lo[2], 0.0],
            shift: [shift[0], shift[1], shift[2], 0.0],
        }
    }
}

/// The dequantization part of shuffle.wgsl's uniform.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct DequantizeUniform {
    base: [i32; 4],
    step_hi: [f32; 4],
    step_lo: [f32; 4],
    shift: [f32; 4],
}

/// The memory of a [`StagedBatch`].
enum StagedMemory {
    /// Upload memory wgpu maps for writing and unmaps for the GPU.
    Mapped(wgpu::Buffer),
    /// Memory Vulkan made, mapped as long as it lives (boxed: a batch travels through
    /// channels).
    Direct(Box<DirectStaging>),
}

struct DirectStaging {
    memory: MappedBuffer,
    /// Says when the GPU is done copying the batch.
    #[cfg_attr(
        target_arch = "wasm32",
        expect(dead_code, reason = "a browser makes no memory directly")
    )]
    queue: wgpu::Queue,
}

/// A [`StagedBatch`]'s bytes while the CPU writes them; [`regions`](Self::regions) splits them.
pub struct StagedView<'a> {
    bytes: StagedBytes<'a>,
    /// Where the fine and colour regions start.
    fine_at: usize,
    colors_at: usize,
}

enum StagedBytes<'a> {
    Mapped(wgpu::BufferViewMut),
    Direct(&'a mut [u8]),
}

impl StagedView<'_> {
    /// The position, fine and colour regions.
    pub fn regions(&mut self) -> StagedRegions<'_> {
        let whole: wgpu::WriteOnly<'_, [u8]> = match &mut self.bytes {
            StagedBytes::Mapped(view) => view.slice(..),
            StagedBytes::Direct(bytes) => wgpu::WriteOnly::from(&mut **bytes),
        };
        let (positions, rest) = whole.split_at(self.fine_at);
        let (fine, colors) = rest.split_at(self.colors_at - self.fine_at);
        StagedRegions {
            positions: StagedRegion(positions),
            fine: StagedRegion(fine),
            colors: StagedRegion(colors),
        }
    }
}

/// The regions of a mapped [`StagedBatch`], to be split between the threads that fill them.
pub struct StagedRegions<'a> {
    pub positions: StagedRegion<'a>,
    pub fine: StagedRegion<'a>,
    pub colors: StagedRegion<'a>,
}

/// Bytes of a mapped [`StagedBatch`] that one thread writes, [`BUS_WRITERS`] threads at once.
pub struct StagedRegion<'a>(pub(crate) wgpu::WriteOnly<'a, [u8]>);

/// Threads that copy into upload memory at once. On a discrete GPU that memory is the
/// resizable BAR's, written across the bus, and a few threads fill what it takes: on the H100
/// machine one thread writes it at 15.3 GB/s, two at 30.4, four at 32.8, eight at 33.2 and
/// sixteen at 31.4 (docs/BENCHMARKS.md, issue 11). Beyond those, a thread's copy only stalls
/// its core, which a load needs for reading and encoding its next parts.
pub const BUS_WRITERS: usize = 4;

/// Counts the threads copying into mapped memory (others wait for one to finish) and how
/// long the bus had any.
#[cfg(not(target_arch = "wasm32"))]
struct BusWriters {
    state: std::sync::Mutex<BusState>,
    freed: std::sync::Condvar,
}

#[cfg(not(target_arch = "wasm32"))]
struct BusState {
    writers: usize,
    /// When the bus last went from no writer to one.
    since: Option<std::time::Instant>,
    time: BusTime,
}

/// What the threads copying into upload memory did since the process started: whether a load
/// kept the bus busy or left it waiting for data.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BusTime {
    /// Time at least one thread was copying.
    pub busy: std::time::Duration,
    /// Time of all copies added up (busy × the mean number of writers).
    pub writing: std::time::Duration,
    pub bytes: u64,
}

#[cfg(not(target_arch = "wasm32"))]
static BUS: BusWriters = BusWriters {
    state: std::sync::Mutex::new(BusState {
        writers: 0,
        since: None,
        time: BusTime {
            busy: std::time::Duration::ZERO,
            writing: std::time::Duration::ZERO,
            bytes: 0,
        },
    }),
    freed: std::sync::Condvar::new(),
};

/// The bus's time so far (a browser's stays zero: it has no clock of that kind).
pub fn bus_time() -> BusTime {
    #[cfg(not(target_arch = "wasm32"))]
    {
        let state = BUS.state.lock().unwrap_or_else(|e| e.into_inner());
        let mut time = state.time;
        // A copy going on now counts up to now.
        time.busy += state
            .since
            .map_or(std::time::Duration::ZERO, |s| s.elapsed());
        time
    }
    #[cfg(target_arch = "wasm32")]
    BusTime::default()
}

impl BusTime {
    /// What was added between `earlier` and `self`.
    pub fn since(&self, earlier: &BusTime) -> BusTime {
        BusTime {
            busy: self.busy.saturating_sub(earlier.busy),
            writing: self.writing.saturating_sub(earlier.writing),
            bytes: self.bytes.saturating_sub(earlier.bytes),
        }
    }
}

/// Runs `copy` of `bytes` as one of at most [`BUS_WRITERS`] threads (a browser has one thread).
fn as_bus_writer(bytes: usize, copy: impl FnOnce()) {
    #[cfg(not(target_arch = "wasm32"))]
    {
        use std::time::Instant;
        /// Gives the place back however `copy` ends.
        struct Seat(Instant, usize);
        impl Drop for Seat {
            fn drop(&mut self) {
                let now = Instant::now();
                let mut state = BUS.state.lock().unwrap_or_else(|e| e.into_inner());
                state.writers -= 1;
                state.time.writing += now - self.0;
                state.time.bytes += self.1 as u64;
                if state.writers == 0 {
                    if let Some(since) = state.since.take() {
                        state.time.busy += now - since;
                    }
                }
                BUS.freed.notify_one();
            }
        }
        let mut state = BUS.state.lock().unwrap_or_else(|e| e.into_inner());
        while state.writers >= BUS_WRITERS {
            state = BUS.freed.wait(state).unwrap_or_else(|e| e.into_inner());
        }
        let now = Instant::now();
        if state.writers == 0 {
            state.since = Some(now);
        }
        state.writers += 1;
        drop(state);
        let _seat = Seat(now, bytes);
        copy();
    }
    #[cfg(target_arch = "wasm32")]
    {
        let _ = bytes;
        copy();
    }
}

// SAFETY: a WriteOnly<[u8]> is a unique pointer to bytes, as `&mut [u8]` (which is Send) is;
// wgpu implements Send only for sized targets.
unsafe impl Send for StagedRegion<'_> {}

impl<'a> StagedRegion<'a> {
    /// Bytes `..mid` and `mid..`.
    pub fn split_at(self, mid: usize) -> (Self, Self) {
        let (a, b) = self.0.split_at(mid);
        (Self(a), Self(b))
    }

    /// Writes the whole region (`data` holds exactly its bytes).
    pub fn write<T: Pod>(&mut self, data: &[T]) -> Result<(), GpuError> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        if bytes.len() != self.0.len() {
            return Err(GpuError::InvalidInput(format!(
                "{} bytes written into a staged region of {}",
                bytes.len(),
                self.0.len()
            )));
        }
        as_bus_writer(bytes.len(), || self.0.copy_from_slice(bytes));
        Ok(())
    }
}

impl StagedBatch {
    /// Upload memory made by Vulkan directly for `capacity` points, mapped for good (from any
    /// thread): `None` where it cannot be made so ([`UploadMemory::makes_directly`], or no
    /// such memory type).
    pub fn direct(
        upload: &UploadMemory,
        encoding: PointEncoding,
        capacity: u64,
    ) -> Result<Option<Self>, GpuError> {
        let Some(direct) = &upload.direct else {
            return Ok(None);
        };
        let bytes = Self::bytes_for(encoding, capacity);
        let usage = wgpu::BufferUsages::COPY_SRC;
        let Some(memory) = direct.upload_buffer("staged batch", bytes, usage)? else {
            return Ok(None);
        };
        let memory = StagedMemory::Direct(Box::new(DirectStaging {
            memory,
            queue: upload.queue.clone(),
        }));
        Ok(Some(Self::empty(memory, encoding, capacity)))
    }

    /// Upload memory wgpu maps, for `capacity` points, mapped (from any thread).
    pub fn new(
        upload: &UploadMemory,
        encoding: PointEncoding,
        capacity: u64,
    ) -> Result<Self, GpuError> {
        let bytes = Self::bytes_for(encoding, capacity);
        let device = &upload.device;
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staged batch"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: true,
        });
        let v = pollster::block_on(validation.pop());
        if let Some(e) = pollster::block_on(oom.pop()) {
            return Err(GpuError::OutOfMemory(format!(
                "allocating a staged batch: {e}"
            )));
        }
        if let Some(e) = v {
            return Err(GpuError::Validation(format!(
                "allocating a staged batch: {e}"
            )));
        }
        Ok(Self::empty(
            StagedMemory::Mapped(buffer),
            encoding,
            capacity,
        ))
    }

    /// Bytes of the regions of `capacity` points (at least 4: no buffer is empty).
    fn bytes_for(encoding: PointEncoding, capacity: u64) -> u64 {
        (capacity * region_bytes(encoding).iter().sum::<u64>()).max(4)
    }

    /// A batch of nothing yet in `memory`.
    fn empty(memory: StagedMemory, encoding: PointEncoding, capacity: u64) -> Self {
        Self {
            memory,
            encoding,
            capacity,
            count: 0,
            dequantize: None,
        }
    }

    /// Whether Vulkan made the batch's memory ([`direct`](Self::direct)).
    pub fn is_direct(&self) -> bool {
        matches!(self.memory, StagedMemory::Direct(_))
    }

    fn buffer(&self) -> &wgpu::Buffer {
        match &self.memory {
            StagedMemory::Mapped(buffer) => buffer,
            StagedMemory::Direct(direct) => direct.memory.buffer(),
        }
    }

    /// Points the batch has room for.
    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Hands the batch to `ready`, writable again, once the GPU is done with it (its copy was
    /// submitted), on the thread that polls the device: mapped again (on a mapping error the
    /// batch is dropped), or, memory Vulkan made, once the queue's work so far is done. A new
    /// mapping is zero-filled by one thread before anything is written (wgpu initializes memory
    /// on first map): a reused batch skips that and the allocation.
    pub fn recycle(mut self, ready: impl FnOnce(StagedBatch) + Send + 'static) {
        self.count = 0;
        self.dequantize = None;
        match &self.memory {
            StagedMemory::Mapped(buffer) => {
                let buffer = buffer.clone();
                buffer.map_async(wgpu::MapMode::Write, .., move |mapped| {
                    if mapped.is_ok() {
                        ready(self);
                    }
                });
            }
            // A browser has no memory made directly (nor a batch that may cross threads).
            #[cfg(not(target_arch = "wasm32"))]
            StagedMemory::Direct(direct) => {
                let queue = direct.queue.clone();
                queue.on_submitted_work_done(move || ready(self));
            }
            #[cfg(target_arch = "wasm32")]
            StagedMemory::Direct(_) => drop(ready),
        }
    }

    /// Whether the position region holds stored positions for the GPU to dequantize.
    pub fn holds_stored_positions(&self) -> bool {
        self.dequantize.is_some()
    }

    /// Says that the position region holds stored positions (12 bytes a point, as
    /// [`Dequantize`] reads them) instead of Full16 words (Full16 batches only: a stored
    /// position takes a Full16 position's 12 bytes).
    pub fn set_dequantize(&mut self, dequantize: Dequantize) -> Result<(), GpuError> {
        if self.encoding != PointEncoding::Full16 {
            return Err(GpuError::InvalidInput(format!(
                "stored positions in a {} staged batch (Full16 only)",
                self.encoding.name()
            )));
        }
        self.dequantize = Some(dequantize);
        Ok(())
    }

    /// Where the position, fine and colour regions start in the buffer.
    fn region_starts(&self) -> [u64; 3] {
        let [positions, fine, _] = region_bytes(self.encoding);
        [
            0,
            self.capacity * positions,
            self.capacity * (positions + fine),
        ]
    }

    /// A write view of the whole batch; [`StagedView::regions`] splits it. Drop it before
    /// [`finish`](Self::finish).
    pub fn map(&mut self) -> Result<StagedView<'_>, GpuError> {
        let [_, fine_at, colors_at] = self.region_starts().map(|b| b as usize);
        let bytes = match &mut self.memory {
            StagedMemory::Mapped(buffer) => StagedBytes::Mapped(
                buffer
                    .get_mapped_range_mut(..)
                    .map_err(|e| GpuError::InvalidInput(format!("writing a staged batch: {e}")))?,
            ),
            StagedMemory::Direct(direct) => StagedBytes::Direct(direct.memory.bytes()),
        };
        Ok(StagedView {
            bytes,
            fine_at,
            colors_at,
        })
    }

    /// Ends writing: the first `count` points of each region hold the batch. Every view of
    /// the batch must be dropped by now.
    pub fn finish(&mut self, count: u64) {
        self.count = count.min(self.capacity);
        if let StagedMemory::Mapped(buffer) = &self.memory {
            buffer.unmap();
        }
    }
}

/// Bytes per point of a staged batch's position, fine and colour regions.
fn region_bytes(encoding: PointEncoding) -> [u64; 3] {
    let fine = if encoding == PointEncoding::Compact8 {
        4
    } else {
        0
    };
    [encoding.position_bytes(), fine, 4]
}

/// The streams of a shuffled buffer read back to the CPU, in slot order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ShuffledContents {
    pub positions: Vec<u32>,
    pub fine: Vec<u32>,
    pub colors: Vec<u32>,
}

/// The buffers of slots `first_slot..first_slot + slots`.
struct ShuffledChunk {
    positions: wgpu::Buffer,
    fine: Option<wgpu::Buffer>,
    colors: wgpu::Buffer,
    first_slot: u32,
    slots: u32,
}

/// A point buffer of n slots that batches are shuffled into: point i goes to slot
/// `order.target(i)`, or is left out when it has none or that lies past the slots. Its
/// buffers may come later than the buffer itself (a store's chunks, installed as they are
/// made): batches for slots of missing buffers must wait ([`ready_for`](Self::ready_for)).
pub struct ShuffledBuffer {
    encoding: PointEncoding,
    slots: u32,
    order: SlotOrder,
    chunks: Vec<ShuffledChunk>,
}

impl ShuffledBuffer {
    /// A buffer of `n` slots, split where the binding limit requires.
    pub fn new(ctx: &GpuContext, encoding: PointEncoding, n: u32) -> Result<Self, GpuError> {
        Self::with_chunk_slots(ctx, encoding, n, u32::MAX)
    }

    /// Like [`new`](Self::new), with at most `max_chunk_slots` slots per buffer (splitting
    /// small buffers exercises the chunked path without gigabytes of memory).
    pub fn with_chunk_slots(
        ctx: &GpuContext,
        encoding: PointEncoding,
        n: u32,
        max_chunk_slots: u32,
    ) -> Result<Self, GpuError> {
        let order = permuted(n)?;
        // The position stream is the largest per point: it decides how many slots fit.
        let limit = ctx.caps.max_binding.min(ctx.caps.max_buffer) / encoding.position_bytes();
        let per_chunk = limit.min(max_chunk_slots as u64).max(1) as u32;
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::VERTEX
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC;
        let alloc = |label: &str, bytes: u64| {
            ctx.checked("allocating the shuffled point buffer", || {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage,
                    mapped_at_creation: false,
                })
            })
        };
        let mut chunks = Vec::new();
        let mut first_slot = 0u32;
        // An empty buffer still gets one (one-slot) chunk, so bindings are never empty.
        while first_slot < n.max(1) {
            let slots = (n.max(1) - first_slot).min(per_chunk);
            let positions = alloc(
                "shuffled positions",
                slots as u64 * encoding.position_bytes(),
            )?;
            let fine = match encoding {
                PointEncoding::Full16 => None,
                PointEncoding::Compact8 => Some(alloc("shuffled fine", slots as u64 * 4)?),
            };
            let colors = alloc("shuffled colours", slots as u64 * 4)?;
            chunks.push(ShuffledChunk {
                positions,
                fine,
                colors,
                first_slot,
                slots,
            });
            first_slot += slots;
        }
        Ok(Self {
            encoding,
            slots: n,
            order,
            chunks,
        })
    }

    /// A buffer of `n` slots in the page slots of `storage`: shuffled slot s is point
    /// s % page_size of page s / page_size, so the rasterizers draw it as they draw any page
    /// (progressive.rs). The buffers are shared, not copied.
    pub(crate) fn in_storage(storage: &PointStorage, n: u32) -> Result<Self, GpuError> {
        let mut buffer = Self {
            encoding: storage.encoding,
            slots: n,
            order: permuted(n)?,
            chunks: Vec::new(),
        };
        for c in &storage.chunks {
            buffer.install(c, storage.page_size);
        }
        Ok(buffer)
    }

    /// Adds the storage chunk that follows the last one.
    pub(crate) fn install(&mut self, c: &PointChunk, page_size: u32) {
        let page = page_size as u64;
        let first_slot = c.first_slot as u64 * page;
        // Slots past n (the last page's tail) are never shuffled into.
        let slots = (c.slots as u64 * page).min((self.slots as u64).saturating_sub(first_slot));
        self.chunks.push(ShuffledChunk {
            positions: c.positions.clone(),
            fine: c.fine.clone(),
            colors: c.colors.clone(),
            first_slot: first_slot.min(u32::MAX as u64) as u32,
            slots: slots as u32,
        });
    }

    /// Places points by `order` instead of the permutation of the slots: a permutation of
    /// fewer points than slots is refused (slots nothing could fill), and an interleave must
    /// span the slots exactly.
    pub fn set_order(&mut self, order: SlotOrder) -> Result<(), GpuError> {
        let fits = match order {
            SlotOrder::Permuted(p) => p.len() >= u64::from(self.slots),
            SlotOrder::Interleaved(g) => g.physical_slots() == u64::from(self.slots),
        };
        if !fits {
            return Err(GpuError::InvalidInput(format!(
                "an order of {} points in {} slots for a shuffled buffer of {} slots",
                order.len(),
                order.physical_slots(),
                self.slots
            )));
        }
        self.order = order;
        Ok(())
    }

    /// Points the buffer holds once every batch is in (its slots, unless an interleave's
    /// chunks leave some unused).
    pub fn placed(&self) -> u64 {
        match self.order {
            SlotOrder::Permuted(_) => u64::from(self.slots),
            SlotOrder::Interleaved(g) => g.placed(),
        }
    }

    /// Whether the buffers of every slot that points `first..first + count` may go to are
    /// there.
    pub fn ready_for(&self, first: u64, count: u64) -> bool {
        let end = match (self.order, count) {
            (_, 0) => return true,
            (SlotOrder::Interleaved(g), _) => {
                let last = (first + count - 1) >> g.shift();
                g.chunk_span(g.chunk_of(last.min(g.groups().saturating_sub(1))))
                    .end
            }
            (SlotOrder::Permuted(_), _) => u64::from(self.slots),
        };
        self.installed_slots() >= end.min(u64::from(self.slots))
    }

    /// Slots whose buffers are there (a prefix of the buffer).
    fn installed_slots(&self) -> u64 {
        self.chunks
            .last()
            .map_or(0, |c| u64::from(c.first_slot) + u64::from(c.slots))
    }

    pub fn encoding(&self) -> PointEncoding {
        self.encoding
    }

    /// Slots of the buffer.
    pub fn slots(&self) -> u32 {
        self.slots
    }

    pub fn order(&self) -> SlotOrder {
        self.order
    }

    /// Buffers the slots are split over.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Reads every stream back in slot order (waits for the GPU).
    pub fn read(&self, ctx: &GpuContext) -> Result<ShuffledContents, GpuError> {
        let mut out = ShuffledContents::default();
        for chunk in &self.chunks {
            out.positions.extend(read_words(ctx, &chunk.positions)?);
            if let Some(fine) = &chunk.fine {
                out.fine.extend(read_words(ctx, fine)?);
            }
            out.colors.extend(read_words(ctx, &chunk.colors)?);
        }
        // The one-slot chunk of an empty buffer holds no point.
        let n = self.slots as usize;
        let words = (self.encoding.position_bytes() / 4) as usize;
        out.positions.truncate(n * words);
        out.fine.truncate(n);
        out.colors.truncate(n);
        Ok(out)
    }
}

/// The paper's permutation of `n` slots.
fn permuted(n: u32) -> Result<SlotOrder, GpuError> {
    ShufflePermutation::new(u64::from(n))
        .map(SlotOrder::Permuted)
        .map_err(|e| GpuError::InvalidInput(e.to_string()))
}

fn read_words(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u32>, GpuError> {
    let readback = ctx.checked("reading the shuffled point buffer", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shuffled readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    enc.copy_buffer_to_buffer(buffer, 0, &readback, 0, buffer.size());
    ctx.queue.submit([enc.finish()]);
    let bytes = map_read(ctx, &readback)?;
    Ok(bytemuck::pod_collect_to_vec(&bytes))
}

/// The uniform of shuffle.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ShuffleUniform {
    n: u32,
    prime: u32,
    first: u32,
    count: u32,
    first_slot: u32,
    slots: u32,
    words: u32,
    has_fine: u32,
    explicit: u32,
    colors_only: u32,
    quantized: u32,
    neg_inv: u32,
    r2: u32,
    interleaved: u32,
    group_shift: u32,
    groups: u32,
    full_rows: u32,
    window: u32,
    points: u32,
    block_shift: u32,
    blocks: u32,
    rows: u32,
    first_group: u32,
    chunk_base: u32,
    window_first: u32,
    _pad: [u32; 3],
    dequantize: DequantizeUniform,
}

/// The Montgomery constants (R = 2^32) of an odd modulus p < 2^32 that shuffle.wgsl's
/// `Modulus` takes: -p⁻¹ mod R and R² mod p; (0, 0) for an even p (0: no permutation).
pub fn montgomery_constants(p: u32) -> (u32, u32) {
    if p.is_multiple_of(2) {
        return (0, 0);
    }
    // Newton's iteration doubles the correct low bits of p⁻¹ mod 2^32: p·p ≡ 1 mod 8 holds.
    let mut inv = p;
    for _ in 0..4 {
        inv = inv.wrapping_mul(2u32.wrapping_sub(p.wrapping_mul(inv)));
    }
    let r2 = ((1u128 << 64) % u128::from(p)) as u32;
    (inv.wrapping_neg(), r2)
}

/// The staging streams, grown on demand.
struct Staging {
    capacity: u64,
    positions: wgpu::Buffer,
    fine: wgpu::Buffer,
    colors: wgpu::Buffer,
    slots: wgpu::Buffer,
}

/// Where the points of a scattered batch go.
#[derive(Clone, Copy, Debug)]
pub enum Targets<'a> {
    /// Points of global indices `first..`: each to its slot under the buffer's permutation.
    Permuted { first: u32 },
    /// Point j to slot `slots[j]` (a reservoir's choice for points past the capacity).
    Slots(&'a [u32]),
}

/// Scatters batches into a [`ShuffledBuffer`] (shuffle.wgsl).
pub struct ShufflePass {
    pipeline: wgpu::ComputePipeline,
    staging: Option<Staging>,
}

impl ShufflePass {
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let pipeline = ctx.checked("building the shuffle pass", || {
            let module = shaders::module(&ctx.device, "shuffle", shaders::SHUFFLE);
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("shuffle"),
                    layout: None,
                    module: &module,
                    entry_point: Some("scatter"),
                    compilation_options: Default::default(),
                    cache: None,
                })
        })?;
        Ok(Self {
            pipeline,
            staging: None,
        })
    }

    /// Uploads `batch`, the points of global indices `first..first + count`, and moves each to
    /// its shuffled slot of `dst`; submits the work (batches may follow at once).
    pub fn scatter(
        &mut self,
        ctx: &GpuContext,
        dst: &ShuffledBuffer,
        first: u32,
        batch: EncodedBatch<'_>,
    ) -> Result<(), GpuError> {
        self.scatter_to(ctx, dst, Targets::Permuted { first }, batch)
    }

    /// Uploads `batch` and moves each point to its slot of `dst` as `targets` says.
    pub fn scatter_to(
        &mut self,
        ctx: &GpuContext,
        dst: &ShuffledBuffer,
        targets: Targets<'_>,
        batch: EncodedBatch<'_>,
    ) -> Result<(), GpuError> {
        let count = batch.colors.len() as u64;
        let words = dst.encoding.position_bytes() / 4;
        let compact = dst.encoding == PointEncoding::Compact8;
        let fine_words = if compact { count } else { 0 };
        if batch.positions.len() as u64 != count * words || batch.fine.len() as u64 != fine_words {
            return Err(GpuError::InvalidInput(format!(
                "a {} batch of {count} colours needs {} position and {fine_words} fine words, \
                 got {} and {}",
                dst.encoding.name(),
                count * words,
                batch.positions.len(),
                batch.fine.len()
            )));
        }
        self.dispatch(ctx, dst, targets, Input::Slices(Some(batch), batch.colors))
    }

    /// Scatters a [`StagedBatch`] (finished) to the slots of the points of global indices
    /// `first..first + staged.count()`.
    pub fn scatter_staged(
        &mut self,
        ctx: &GpuContext,
        dst: &ShuffledBuffer,
        first: u32,
        staged: &StagedBatch,
    ) -> Result<(), GpuError> {
        if staged.encoding != dst.encoding {
            return Err(GpuError::InvalidInput(format!(
                "a {} staged batch for a {} shuffled buffer",
                staged.encoding.name(),
                dst.encoding.name()
            )));
        }
        self.dispatch(ctx, dst, Targets::Permuted { first }, Input::Staged(staged))
    }

    /// Rewrites only the colours of the points `targets` names (attribute switching: the
    /// positions stay where they are).
    pub fn scatter_colors(
        &mut self,
        ctx: &GpuContext,
        dst: &ShuffledBuffer,
        targets: Targets<'_>,
        colors: &[u32],
    ) -> Result<(), GpuError> {
        self.dispatch(ctx, dst, targets, Input::Slices(None, colors))
    }

    fn dispatch(
        &mut self,
        ctx: &GpuContext,
        dst: &ShuffledBuffer,
        targets: Targets<'_>,
        input: Input<'_>,
    ) -> Result<(), GpuError> {
        let (count, colors_only, dequantize) = match input {
            Input::Slices(batch, colors) => (colors.len() as u64, batch.is_none(), None),
            Input::Staged(b) => (b.count, false, b.dequantize),
        };
        let words = dst.encoding.position_bytes() / 4;
        let compact = dst.encoding == PointEncoding::Compact8;
        let n = dst.order.len();
        let (first, slots) = match targets {
            Targets::Permuted { first } => (first, None),
            Targets::Slots(s) => (0, Some(s)),
        };
        match slots {
            None if first as u64 + count > n => {
                return Err(GpuError::InvalidInput(format!(
                    "points {first}..{} do not fit a shuffled buffer of {n} slots",
                    first as u64 + count
                )));
            }
            Some(s) if s.len() as u64 != count => {
                return Err(GpuError::InvalidInput(format!(
                    "{} slots given for a batch of {count} points",
                    s.len()
                )));
            }
            Some(s) if s.iter().any(|&t| t >= dst.slots) => {
                return Err(GpuError::InvalidInput(format!(
                    "a slot beyond the {} of the shuffled buffer",
                    dst.slots
                )));
            }
            _ => {}
        }
        if count == 0 {
            return Ok(());
        }
        let staging = staging_for(&mut self.staging, ctx, count, words)?;
        let q = &ctx.queue;
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        match input {
            Input::Slices(batch, colors) => {
                if let Some(b) = &batch {
                    q.write_buffer(&staging.positions, 0, bytemuck::cast_slice(b.positions));
                    q.write_buffer(&staging.fine, 0, bytemuck::cast_slice(b.fine));
                }
                q.write_buffer(&staging.colors, 0, bytemuck::cast_slice(colors));
            }
            Input::Staged(b) => {
                // The regions start where the capacity puts them; the count says how much.
                let starts = b.region_starts();
                let sizes = region_bytes(b.encoding).map(|bytes| count * bytes);
                let dsts = [&staging.positions, &staging.fine, &staging.colors];
                for ((at, size), dst) in starts.into_iter().zip(sizes).zip(dsts) {
                    if size > 0 {
                        enc.copy_buffer_to_buffer(b.buffer(), at, dst, 0, size);
                    }
                }
            }
        }
        if let Some(s) = slots {
            q.write_buffer(&staging.slots, 0, bytemuck::cast_slice(s));
        }
        let layout = self.pipeline.get_bind_group_layout(0);
        let base = ShuffleUniform {
            n: dst.slots,
            first,
            count: count as u32,
            words: words as u32,
            has_fine: compact as u32,
            explicit: slots.is_some() as u32,
            colors_only: colors_only as u32,
            quantized: dequantize.is_some() as u32,
            points: n.min(u64::from(u32::MAX)) as u32,
            dequantize: dequantize.map(|d| d.uniform()).unwrap_or_default(),
            ..Zeroable::zeroed()
        };
        // (uniform, threads, the physical slots the dispatch may write) per dispatch.
        let mut work: Vec<(ShuffleUniform, u64, std::ops::Range<u64>)> = Vec::new();
        match (dst.order, slots) {
            // Interleaved groups: per chunk the batch touches, one thread per kept point of
            // the window of its groups, row by row.
            (SlotOrder::Interleaved(g), None) => {
                let shift = g.shift();
                let (g0, g1) = (first as u64 >> shift, (first as u64 + count - 1) >> shift);
                let last = g.groups().saturating_sub(1);
                for c in g.chunk_of(g0.min(last))..=g.chunk_of(g1.min(last)) {
                    let (first_group, chunk) = g
                        .chunk(c)
                        .map_err(|e| GpuError::InvalidInput(e.to_string()))?;
                    let window_first = g0.max(first_group);
                    let window_end = (g1 + 1).min(first_group + chunk.groups());
                    if window_end <= window_first {
                        continue;
                    }
                    let window = window_end - window_first;
                    let prime = chunk.blocks().prime() as u32;
                    let (neg_inv, r2) = montgomery_constants(prime);
                    let span = g.chunk_span(c);
                    let uniform = ShuffleUniform {
                        prime,
                        neg_inv,
                        r2,
                        interleaved: 1,
                        group_shift: shift,
                        groups: chunk.groups() as u32,
                        full_rows: chunk.full_rows() as u32,
                        window: window as u32,
                        block_shift: chunk.block_shift(),
                        blocks: chunk.blocks().len() as u32,
                        rows: chunk.rows() as u32,
                        first_group: first_group as u32,
                        chunk_base: span.start as u32,
                        window_first: window_first as u32,
                        ..base
                    };
                    work.push((uniform, window * chunk.rows(), span));
                }
            }
            (order, _) => {
                let prime = match order {
                    SlotOrder::Permuted(p) => p.prime() as u32,
                    SlotOrder::Interleaved(_) => 0,
                };
                let (neg_inv, r2) = montgomery_constants(prime);
                let uniform = ShuffleUniform {
                    prime,
                    neg_inv,
                    r2,
                    ..base
                };
                work.push((uniform, count, 0..u64::from(dst.slots)));
            }
        }
        ctx.checked("recording the shuffle pass", || {
            // One uniform and bind group per destination chunk a dispatch may write: each
            // dispatch sees its own.
            let mut groups = Vec::new();
            for (uniform, threads, span) in &work {
                for c in &dst.chunks {
                    let (start, end) = (c.first_slot as u64, c.first_slot as u64 + c.slots as u64);
                    if end <= span.start || start >= span.end {
                        continue;
                    }
                    let uniform = ShuffleUniform {
                        first_slot: c.first_slot,
                        slots: c.slots,
                        ..*uniform
                    };
                    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("shuffle uniform"),
                        size: std::mem::size_of::<ShuffleUniform>() as u64,
                        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    q.write_buffer(&buffer, 0, bytemuck::bytes_of(&uniform));
                    // Full16 binds the colours in the fine slot: the shader never touches it.
                    let fine_dst = c.fine.as_ref().unwrap_or(&c.colors);
                    let buffers = [
                        &buffer,
                        &staging.positions,
                        &staging.fine,
                        &staging.colors,
                        &c.positions,
                        fine_dst,
                        &c.colors,
                        &staging.slots,
                    ];
                    let group = storage_group(&ctx.device, "shuffle", &layout, &buffers);
                    groups.push((group, grid(threads.div_ceil(256) as u32)));
                }
            }
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("shuffle"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            for (g, [x, y]) in &groups {
                pass.set_bind_group(0, g, &[]);
                pass.dispatch_workgroups(*x, *y, 1);
            }
        })?;
        q.submit([enc.finish()]);
        Ok(())
    }
}

/// What a dispatch scatters: slices written through the queue (no positions for a
/// colours-only batch), or a staged batch copied on the GPU.
#[derive(Clone, Copy)]
enum Input<'a> {
    Slices(Option<EncodedBatch<'a>>, &'a [u32]),
    Staged(&'a StagedBatch),
}

/// The staging of `slot`, grown to hold `count` points of `words` position words.
fn staging_for<'s>(
    slot: &'s mut Option<Staging>,
    ctx: &GpuContext,
    count: u64,
    words: u64,
) -> Result<&'s Staging, GpuError> {
    let bytes = count * words * 4;
    let max = ctx.caps.max_binding.min(ctx.caps.max_buffer);
    if bytes > max {
        return Err(GpuError::InvalidInput(format!(
            "a batch of {count} points ({bytes} bytes of positions) exceeds the binding \
             limit of {max} bytes: send smaller batches"
        )));
    }
    let grown = match slot.take() {
        Some(s) if s.capacity >= count => s,
        old => {
            let old_capacity = old.map_or(0, |s| s.capacity);
            let capacity = count
                .max(old_capacity * 2)
                .max(1 << 16)
                .min(max / (words * 4));
            let buffer = |label: &str, bytes: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            ctx.checked("allocating the shuffle staging", || Staging {
                capacity,
                positions: buffer("shuffle staging positions", capacity * words * 4),
                fine: buffer("shuffle staging fine", capacity * 4),
                colors: buffer("shuffle staging colours", capacity * 4),
                slots: buffer("shuffle staging slots", capacity * 4),
            })?
        }
    };
    Ok(slot.insert(grown))
}

#[cfg(test)]
mod tests {
    use super::montgomery_constants;

    #[test]
    fn montgomery_constants_invert_and_square_r() {
        for p in [3u32, 7, 65_519, 2_147_483_647, 4_294_967_291, 4_294_967_279] {
            let (neg_inv, r2) = montgomery_constants(p);
            assert_eq!(p.wrapping_mul(neg_inv), u32::MAX, "-p⁻¹ for {p}");
            let r = (1u128 << 32) % u128::from(p);
            assert_eq!(u128::from(r2), r * r % u128::from(p), "R² for {p}");
        }
        assert_eq!(montgomery_constants(0), (0, 0));
    }
}
