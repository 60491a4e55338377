//! The per-frame passes of progressive rendering (progressive-rendering paper §3.4) over a
//! shuffled point buffer:
//! - **Reproject** draws the points the previous frame showed, with the new camera;
//! - **Fill** draws the next S slots of the shuffled buffer, cycling through it;
//! - **Prepare** lists the slot of every pixel's closest point for the next frame.
//!
//! Reproject and Fill key pixels by slot (`~depth << 32 | ~slot`, atomicMax) in an index
//! framebuffer; a colour lookup turns those keys into the colour keys the existing 64-bit
//! resolve and screen passes read. A frame is: clear → reproject (previous list) → fill (next S)
//! → lookup → resolve and screen passes → prepare (list for the next frame). A still camera
//! converges to exactly the closest-point image of all points after ⌈N / S⌉ frames; on equal
//! depth the smaller slot wins (where the static path picks the smaller colour).

use crate::cloud::write_frame;
use crate::context::GpuContext;
use crate::frame::{FrameGraph, FramePass, FrameShape, Source};
use crate::pick::{nearest_in_rows, rows_around, untier, PickHit};
use crate::raster::{
    grid, storage_group, storage_layout, RasterDispatch, RasterPipelines, RasterVariant, WORKGROUP,
};
use crate::renderer::{frame_shape, record_frame, RenderSettings, Renderer};
use crate::screen::{ScreenPasses, ScreenSettings};
use crate::shaders;
use crate::shuffle::ShuffledBuffer;
use crate::splat::{self, SplatMode, SplatSettings};
use crate::storage::{
    check_page_size, chunks_of, point_group_layout, ChunkMaker, DrawBuffers, GpuDrawEntry,
    GpuDrawInfo, GpuFrame, PointChunk, PointEncoding, PointStorage,
};
use crate::target::{map_read, RenderTarget};
use crate::GpuError;
use pointlet_core::progressive::{ShufflePermutation, SlotOrder};
use pointlet_core::{Aabb, Camera};
use std::collections::hash_map::Entry;
use std::collections::HashMap;

/// The encoding of progressive clouds. Pages of a shuffled buffer hold points from all over
/// the cloud, so per-page origins would buy no precision: every page takes the cloud's bounds
/// minimum as origin, and points are f32 offsets from it (Compact8's coarse grid over the whole
/// cloud would be far too coarse).
pub const ENCODING: PointEncoding = PointEncoding::Full16;

/// A shuffled point buffer in page slots, drawn by the progressive passes. Batches are
/// scattered into [`shuffled`](Self::shuffled) with [`crate::shuffle::ShufflePass`], their
/// positions encoded (Full16) relative to [`origin`](Self::origin).
pub struct ProgressiveCloud {
    /// Points the buffer holds (N: the Fill pass cycles through them).
    points: u32,
    /// Slots of the buffer (past `points` when an interleave's chunks leave some unused).
    physical: u32,
    /// The stretches of slots each fill takes the same share of. One for a permutation; a
    /// chunk each for an interleave, whose prefix is uniform within the chunk.
    fill_units: Vec<std::ops::Range<u64>>,
    /// What makes the chunks of the buffer not made yet.
    maker: Option<ChunkMaker>,
    page_size: u32,
    origin: [f64; 3],
    storage: PointStorage,
    shuffled: ShuffledBuffer,
    frame_uniform: wgpu::Buffer,
    infos: wgpu::Buffer,
    entries: wgpu::Buffer,
    entry_counts: wgpu::Buffer,
    /// Indirect dispatch arguments of the Fill pass, three u32 per chunk.
    fill_args: wgpu::Buffer,
    /// Draw entries reserved per chunk in `entries`.
    entry_stride: u32,
    /// Surface spacing of the points in the buffer, for adaptive splats (0: unknown).
    spacing: f64,
    /// One bit per slot: listed by this frame's Prepare pass (splats win many pixels but are
    /// listed once), allocated on the first frame of splats; a placeholder until then.
    listed: std::cell::OnceCell<wgpu::Buffer>,
    no_list_bits: wgpu::Buffer,
}

impl ProgressiveCloud {
    /// Room for `points` points inside `bounds`, in pages of `page_size` slots, placed by the
    /// paper's permutation.
    pub fn new(
        ctx: &GpuContext,
        points: u32,
        bounds: Aabb,
        page_size: u32,
    ) -> Result<Self, GpuError> {
        let order = SlotOrder::Permuted(
            ShufflePermutation::new(u64::from(points))
                .map_err(|e| GpuError::InvalidInput(e.to_string()))?,
        );
        Self::with_order(ctx, order, bounds, page_size)
    }

    /// Slots of one chunk of a store's interleave on this device (the binding limit's), or
    /// `None` where its memory is made quickly ([`Capabilities::direct_memory`]) and the
    /// pointlets interleave over the whole buffer, made before the first frame. An
    /// interleave's chunks must be as large
    /// ([`GroupRows::chunked`](pointlet_core::progressive::GroupRows::chunked)). Smaller
    /// chunks would be quicker to make, but the Fill pass dispatches once per chunk, and a
    /// chunk of a store is one region of it: with 512 MiB chunks a 1 G-point store's fill took
    /// 9.4 instead of 5.3 ms on the H100 (docs/BENCHMARKS.md, issue 11, session 45); with
    /// chunks of the binding limit, 6.0 against 5.2 ms for the whole store interleaved.
    ///
    /// [`Capabilities::direct_memory`]: crate::Capabilities::direct_memory
    pub fn chunk_slots(ctx: &GpuContext, page_size: u32) -> Option<u64> {
        (!ctx.caps.direct_memory).then(|| {
            PointStorage::slots_per_chunk(ctx, ENCODING, page_size) as u64 * page_size as u64
        })
    }

    /// Room for the points `order` places inside `bounds`. An interleave in chunks
    /// ([`chunk_slots`](Self::chunk_slots)) has its chunks after the first made a frame at a
    /// time while the first ones are drawn ([`make_next_chunk`](Self::make_next_chunk)); any
    /// other order's are all made now (a permutation's batches go to every chunk).
    pub fn with_order(
        ctx: &GpuContext,
        order: SlotOrder,
        bounds: Aabb,
        page_size: u32,
    ) -> Result<Self, GpuError> {
        check_page_size(page_size)?;
        let too_many = |n: u64| GpuError::InvalidInput(format!("{n} slots exceed 2^32 - 1"));
        let points = u32::try_from(order.placed()).map_err(|_| too_many(order.placed()))?;
        let physical =
            u32::try_from(order.physical_slots()).map_err(|_| too_many(order.physical_slots()))?;
        let finite = bounds.min.iter().chain(&bounds.max).all(|v| v.is_finite());
        if points > 0 && (!finite || (0..3).any(|a| bounds.min[a] > bounds.max[a])) {
            return Err(GpuError::InvalidInput(format!(
                "a progressive cloud of {points} points needs finite bounds, got {bounds:?}"
            )));
        }
        let fill_units = match order {
            SlotOrder::Permuted(p) => std::iter::once(0..p.len()).collect(),
            SlotOrder::Interleaved(g) => {
                if g.chunks() > 1 && g.chunk_slots() % page_size as u64 != 0 {
                    return Err(GpuError::InvalidInput(format!(
                        "an interleave in chunks of {} slots for a buffer of {page_size}-slot \
                         pages",
                        g.chunk_slots()
                    )));
                }
                (0..g.chunks()).map(|c| g.chunk_span(c)).collect()
            }
        };
        let origin = if points > 0 { bounds.min } else { [0.0; 3] };
        let pages = physical.div_ceil(page_size);
        let per_chunk = match order {
            SlotOrder::Interleaved(g) if g.chunks() > 1 => {
                (g.chunk_slots() / page_size as u64).min(u64::from(u32::MAX)) as u32
            }
            _ => PointStorage::slots_per_chunk(ctx, ENCODING, page_size),
        };
        let chunks = chunks_of(pages, per_chunk);
        // A fill range and its wrapped rest are disjoint, so they share at most one page.
        let entry_stride = per_chunk.min(pages.max(1)) + 1;
        let device = &ctx.device;
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.checked("allocating the progressive draw lists", || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: size.max(16),
                    usage: usage | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
        };
        let storage_usage = wgpu::BufferUsages::STORAGE;
        let infos = buffer(
            "progressive draw info",
            std::mem::size_of::<GpuDrawInfo>() as u64,
            storage_usage,
        )?;
        let entries = buffer(
            "fill entries",
            chunks as u64 * entry_stride as u64 * std::mem::size_of::<GpuDrawEntry>() as u64,
            storage_usage,
        )?;
        let entry_counts = buffer("fill entry counts", chunks as u64 * 4, storage_usage)?;
        let fill_args = buffer(
            "fill dispatch",
            chunks as u64 * 12,
            wgpu::BufferUsages::INDIRECT,
        )?;
        let frame_uniform = buffer(
            "progressive frame",
            std::mem::size_of::<GpuFrame>() as u64,
            wgpu::BufferUsages::UNIFORM,
        )?;
        let list_offsets: Vec<u32> = (0..chunks).map(|c| c * entry_stride).collect();
        let (mut storage, maker) = PointStorage::planned(
            ctx,
            ENCODING,
            page_size,
            pages,
            &DrawBuffers {
                frame: &frame_uniform,
                infos: &infos,
                entries: &entries,
                entry_counts: &entry_counts,
                list_offsets: &list_offsets,
            },
            per_chunk,
        )?;
        let deferred =
            matches!(order, SlotOrder::Interleaved(g) if g.chunks() > 1) && maker.chunks() > 1;
        let made_now = if deferred { 1 } else { maker.chunks() };
        for index in 0..made_now {
            storage.chunks.push(maker.make(ctx, index)?);
        }
        mark_empty(ctx, &storage.chunks, page_size)?;
        let mut shuffled = ShuffledBuffer::in_storage(&storage, physical)?;
        shuffled.set_order(order)?;
        let maker = deferred.then_some(maker);
        Ok(Self {
            points,
            physical,
            fill_units,
            maker,
            page_size,
            origin,
            storage,
            shuffled,
            frame_uniform,
            infos,
            entries,
            entry_counts,
            fill_args,
            entry_stride,
            spacing: 0.0,
            listed: std::cell::OnceCell::new(),
            no_list_bits: buffer("no listed bits", 16, storage_usage)?,
        })
    }

    /// Makes the next chunk of the buffer, if one is missing (its slots empty): one a frame
    /// while the chunks before it are drawn, where the device makes memory slowly (through
    /// wgpu, ~60 ms for a 2.5 GiB chunk). Batches for a chunk wait until it is made
    /// ([`ShuffledBuffer::ready_for`]). Whether a chunk was made.
    pub fn make_next_chunk(&mut self, ctx: &GpuContext) -> Result<bool, GpuError> {
        let Some(maker) = &self.maker else {
            return Ok(false);
        };
        let index = self.storage.chunks.len() as u32;
        let chunk = match maker.make(ctx, index) {
            Ok(chunk) => chunk,
            Err(e) => {
                // Reported once: the device had no room for the buffer it was opened with.
                self.maker = None;
                return Err(e);
            }
        };
        mark_empty(ctx, std::slice::from_ref(&chunk), self.page_size)?;
        self.shuffled.install(&chunk, self.page_size);
        self.storage.chunks.push(chunk);
        if index + 1 >= maker.chunks() {
            self.maker = None;
        }
        Ok(true)
    }

    /// Chunks of the buffer in, and all it will have.
    pub fn chunks(&self) -> (usize, usize) {
        (self.storage.chunks.len(), self.storage.planned_chunks())
    }

    /// Points the shuffled buffer holds (N).
    pub fn points(&self) -> u32 {
        self.points
    }

    pub fn page_size(&self) -> u32 {
        self.page_size
    }

    /// The origin every page shares: positions are encoded relative to it.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// The buffer to scatter batches into.
    pub fn shuffled(&self) -> &ShuffledBuffer {
        &self.shuffled
    }

    /// The position of the point in `slot` (f32 offsets from the origin), `None` for an empty
    /// or missing slot; waits for the GPU.
    pub fn position(&self, ctx: &GpuContext, slot: u32) -> Result<Option<[f64; 3]>, GpuError> {
        if slot >= self.physical {
            return Ok(None);
        }
        let page = slot / self.page_size;
        let Some(chunk) = self
            .storage
            .chunks
            .get((page / self.storage.slots_per_chunk) as usize)
        else {
            return Ok(None);
        };
        let index = (slot - chunk.first_slot * self.page_size) as u64;
        let bytes = ENCODING.position_bytes();
        let words: Vec<u32> =
            bytemuck::pod_collect_to_vec(&read_range(ctx, &chunk.positions, index * bytes, bytes)?);
        if words.len() != 3 || words[0] == EMPTY_SLOT {
            return Ok(None);
        }
        Ok(Some(std::array::from_fn(|a| {
            self.origin[a] + f32::from_bits(words[a]) as f64
        })))
    }

    /// The listed-slot bits for frames of `splats` (allocated zeroed on first use).
    fn listed_bits(&self, ctx: &GpuContext, splats: bool) -> Result<&wgpu::Buffer, GpuError> {
        if !splats {
            return Ok(&self.no_list_bits);
        }
        if let Some(b) = self.listed.get() {
            return Ok(b);
        }
        let bytes = (self.storage.planned_chunks() as u64
            * self.storage.slots_per_chunk as u64
            * self.page_size as u64)
            .div_ceil(32)
            * 4;
        let buffer = ctx.checked("allocating the listed-slot bits", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("listed slots"),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        Ok(self.listed.get_or_init(|| buffer))
    }

    /// Sets the surface spacing of the points in the buffer (adaptive splats are sized from
    /// it): the loader measures the file's density as it reads.
    pub fn set_spacing(&mut self, spacing: f64) {
        self.spacing = spacing;
    }

    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Writes the camera-relative origin and the frame uniform.
    fn prepare(
        &self,
        ctx: &GpuContext,
        camera: &Camera,
        size: (u32, u32),
        settings: &ProgressiveSettings,
    ) {
        let info = GpuDrawInfo {
            origin: [0, 1, 2].map(|a| (self.origin[a] - camera.eye[a]) as f32),
            spacing: self.spacing as f32,
            ..Default::default()
        };
        ctx.queue
            .write_buffer(&self.infos, 0, bytemuck::bytes_of(&info));
        let render = RenderSettings {
            variant: RasterVariant::AtomicMin,
            hidden_classes: settings.hidden_classes,
            splats: settings.splats,
            ..Default::default()
        };
        write_frame(ctx, &self.frame_uniform, camera, size, &render);
    }

    /// Writes the Fill pass's draw entries for fill positions `first..first + count` (wrapping
    /// at N): the same share of every fill unit, one entry per page touched, listed under the
    /// page's chunk; chunks not made yet are left out.
    fn write_fill(&self, ctx: &GpuContext, first: u32, count: u32) {
        let chunks = self.storage.planned_chunks();
        let mut lists: Vec<Vec<GpuDrawEntry>> = vec![Vec::new(); chunks];
        let ps = self.page_size as u64;
        for unit in &self.fill_units {
            let len = unit.end - unit.start;
            for (a, b) in unit_ranges(self.points, len, first, count) {
                let (a, b) = (unit.start + a, unit.start + b);
                for page in a / ps..b.div_ceil(ps) {
                    let (lo, hi) = (a.max(page * ps), b.min((page + 1) * ps));
                    let chunk = (page / self.storage.slots_per_chunk as u64) as usize;
                    if chunk >= self.storage.chunks.len() {
                        continue;
                    }
                    lists[chunk].push(GpuDrawEntry {
                        slot: page as u32,
                        info: 0,
                        first: (lo - page * ps) as u32,
                        count: (hi - lo) as u32,
                    });
                }
            }
        }
        let entry_bytes = std::mem::size_of::<GpuDrawEntry>() as u64;
        let mut counts = Vec::with_capacity(chunks);
        let mut args = Vec::with_capacity(chunks * 3);
        for (c, list) in lists.iter().enumerate() {
            if !list.is_empty() {
                let offset = c as u64 * self.entry_stride as u64 * entry_bytes;
                ctx.queue
                    .write_buffer(&self.entries, offset, bytemuck::cast_slice(list));
            }
            let [x, y] = grid(list.len() as u32);
            counts.push(list.len() as u32);
            args.extend_from_slice(&[x, y, 1]);
        }
        ctx.queue
            .write_buffer(&self.entry_counts, 0, bytemuck::cast_slice(&counts));
        ctx.queue
            .write_buffer(&self.fill_args, 0, bytemuck::cast_slice(&args));
    }
}

/// The ranges of a fill unit of `len` slots that fill positions `first..first + count` of a
/// cycle of `points` take: the unit's share, up to its end and the wrapped rest (empty ranges
/// are `(0, 0)`). Consecutive fills tile the unit, and a whole cycle covers it exactly once.
pub fn unit_ranges(points: u32, len: u64, first: u32, count: u32) -> [(u64, u64); 2] {
    let n = points as u128;
    if n == 0 || len == 0 {
        return [(0, 0); 2];
    }
    let len = len as u128;
    let start = first as u128 % n;
    let end = start + (count as u128).min(n);
    // Floors of the same proportion: the next fill starts where this one ends.
    let (a, b) = (start * len / n, end * len / n);
    [
        (a as u64, b.min(len) as u64),
        (0, b.saturating_sub(len) as u64),
    ]
}

/// The x word of a slot no point has been loaded into (empty_slots.wgsl, fetch_full16.wgsl).
pub const EMPTY_SLOT: u32 = u32::MAX;

/// Marks every slot of `chunks` empty (empty_slots.wgsl): the Fill pass skips slots that no
/// point has been loaded into yet.
fn mark_empty(ctx: &GpuContext, chunks: &[PointChunk], page_size: u32) -> Result<(), GpuError> {
    if chunks.is_empty() {
        return Ok(());
    }
    let device = &ctx.device;
    let words = (ENCODING.position_bytes() / 4) as u32;
    ctx.checked("marking the shuffled buffer empty", || {
        let module = shaders::module(device, "empty slots", shaders::EMPTY_SLOTS);
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("empty slots"),
            layout: None,
            module: &module,
            entry_point: Some("mark"),
            compilation_options: Default::default(),
            cache: None,
        });
        let layout = pipeline.get_bind_group_layout(0);
        let mut enc = device.create_command_encoder(&Default::default());
        let groups: Vec<(wgpu::BindGroup, u32)> = chunks
            .iter()
            .map(|c| {
                let slots = c.slots * page_size;
                let uniform = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("empty slots"),
                    size: 16,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                ctx.queue
                    .write_buffer(&uniform, 0, bytemuck::cast_slice(&[slots, words, 0, 0]));
                let group =
                    storage_group(device, "empty slots", &layout, &[&uniform, &c.positions]);
                (group, slots)
            })
            .collect();
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("empty slots"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&pipeline);
        for (group, slots) in &groups {
            let [x, y] = grid(slots.div_ceil(256));
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        drop(pass);
        ctx.queue.submit([enc.finish()]);
    })
}

/// What a progressive view keeps between frames, for one cloud and one image size: the index
/// framebuffer, the slots the last frame showed (Prepare's list) and where the next fill starts.
pub struct ProgressiveState {
    width: u32,
    height: u32,
    /// `~depth << 32 | ~slot` per pixel, 0 = empty.
    indexed: wgpu::Buffer,
    /// `~depth << 32 | ~rgba` of the points drawn since the view last changed: the colour
    /// shown where points share the closest depth (color_keys_kept.wgsl).
    color_keys: wgpu::Buffer,
    /// Whether `color_keys` belong to the current view (else the next frame clears them).
    color_keys_kept: bool,
    list: wgpu::Buffer,
    /// The list's length in its first u32.
    list_len: wgpu::Buffer,
    has_list: bool,
    next_fill: u32,
}

impl ProgressiveState {
    /// State for frames drawn into targets of `target`'s size.
    pub fn new(ctx: &GpuContext, target: &RenderTarget) -> Result<Self, GpuError> {
        let (width, height) = (target.width, target.height);
        let pixels = width as u64 * height as u64;
        let device = &ctx.device;
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.checked("allocating the progressive framebuffer", || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: size.max(16),
                    usage: usage | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
        };
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        Ok(Self {
            width,
            height,
            indexed: buffer("index keys", pixels * 8, storage)?,
            color_keys: buffer("colour keys", pixels * 8, storage)?,
            color_keys_kept: false,
            list: buffer("reproject list", pixels * 4, storage)?,
            list_len: buffer("reproject list length", 16, storage)?,
            has_list: false,
            next_fill: 0,
        })
    }

    /// The image size this state is for.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Forgets the last frame and fills from slot 0 again (for another cloud).
    pub fn restart(&mut self) {
        self.has_list = false;
        self.next_fill = 0;
        self.color_keys_kept = false;
    }

    /// The camera, the hidden classes or the buffer's contents changed since the last frame:
    /// the colour keys kept for exact ties start over (the next frames rebuild them).
    pub fn changed(&mut self) {
        self.color_keys_kept = false;
    }

    /// The slot the next Fill pass starts at.
    pub fn next_fill(&self) -> u32 {
        self.next_fill
    }

    /// The point the last frame showed nearest to `pixel` (within `radius` pixels; on equal
    /// distance the closer in depth), its id being its slot; waits for the GPU.
    pub fn pick(
        &self,
        ctx: &GpuContext,
        pixel: [u32; 2],
        radius: u32,
    ) -> Result<Option<PickHit>, GpuError> {
        let (w, h) = (self.width, self.height);
        let Some(rows) = rows_around(pixel, radius, w, h).filter(|_| self.has_list) else {
            return Ok(None);
        };
        let row = w as u64 * 8;
        let (y0, y1) = (*rows.start() as u64, *rows.end() as u64);
        let keys: Vec<u64> = bytemuck::pod_collect_to_vec(&read_range(
            ctx,
            &self.indexed,
            y0 * row,
            (y1 - y0 + 1) * row,
        )?);
        let hit_at = |k: usize| match keys.get(k) {
            Some(&key) if key != 0 => {
                Some((!(key as u32), f32::from_bits(untier((key >> 32) as u32))))
            }
            _ => None,
        };
        Ok(nearest_in_rows(w, pixel, radius, rows, hit_at))
    }

    /// The slots the last frame's Prepare pass listed (waits for the GPU); empty before the
    /// first frame.
    pub fn read_list(&self, ctx: &GpuContext) -> Result<Vec<u32>, GpuError> {
        if !self.has_list {
            return Ok(Vec::new());
        }
        let len = read_words(ctx, &self.list_len, 4)?
            .first()
            .copied()
            .unwrap_or(0);
        // Prepare appends at most one slot per pixel; a longer count is a GPU fault.
        let capacity = self.width as u64 * self.height as u64;
        if len as u64 > capacity {
            return Err(GpuError::Device(format!(
                "the reproject list claims {len} entries for {capacity} pixels"
            )));
        }
        read_words(ctx, &self.list, len as u64 * 4)
    }
}

/// The first `bytes` bytes of a COPY_SRC buffer, as u32 words.
fn read_words(ctx: &GpuContext, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u32>, GpuError> {
    Ok(bytemuck::pod_collect_to_vec(&read_range(
        ctx, buffer, 0, bytes,
    )?))
}

/// Bytes `offset..offset + bytes` of a COPY_SRC buffer (both multiples of 4).
fn read_range(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    offset: u64,
    bytes: u64,
) -> Result<Vec<u8>, GpuError> {
    if bytes == 0 {
        return Ok(Vec::new());
    }
    let readback = ctx.checked("reading the reproject list", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("reproject list readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(buffer, offset, &readback, 0, bytes);
    ctx.queue.submit([enc.finish()]);
    map_read(ctx, &readback)
}

/// A compute pipeline over the point bind group (group 0) of the progressive encoding and
/// `group1_len` read-write storage buffers (group 1).
fn point_pipeline(
    device: &wgpu::Device,
    label: &str,
    body: &str,
    entry: &str,
    group1_len: usize,
    constants: &[(&str, f64)],
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let group0 = point_group_layout(device, ENCODING);
    let group1 = storage_layout(device, group1_len, false);
    let module = shaders::module(device, label, &shaders::point_pass(ENCODING, body));
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&group0), Some(&group1)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            zero_initialize_workgroup_memory: false,
        },
        cache: None,
    });
    (pipeline, group1)
}

type Stamps<'a> = Option<wgpu::ComputePassTimestampWrites<'a>>;

/// Pass 1: the previous frame's points (progressive_reproject.wgsl).
struct ReprojectPass {
    pipeline: wgpu::ComputePipeline,
    group1: wgpu::BindGroupLayout,
}

impl ReprojectPass {
    fn new(device: &wgpu::Device, page_size: u32, splats: SplatMode) -> Self {
        let [splat, circle] = splat::constants(splats);
        let (pipeline, group1) = point_pipeline(
            device,
            "reproject",
            shaders::PROGRESSIVE_REPROJECT,
            "reproject",
            5,
            &[
                ("WG", WORKGROUP as f64),
                ("PAGE_SIZE", page_size as f64),
                splat,
                circle,
            ],
        );
        Self { pipeline, group1 }
    }

    fn record(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        cloud: &ProgressiveCloud,
        state: &ProgressiveState,
        listed: &wgpu::Buffer,
        stamps: Stamps<'_>,
    ) {
        let group1 = storage_group(
            device,
            "reproject",
            &self.group1,
            &[
                &state.indexed,
                &state.list,
                &state.list_len,
                &state.color_keys,
                listed,
            ],
        );
        // One thread per possible entry: the list holds at most one slot per pixel.
        let pixels = state.width as u64 * state.height as u64;
        let [x, y] = grid(pixels.div_ceil(WORKGROUP as u64) as u32);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("reproject"),
            timestamp_writes: stamps,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(1, &group1, &[]);
        for chunk in &cloud.storage.chunks {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

/// Pass 2: the next S slots, drawn by a closest-point variant keyed by slot (keeping colour
/// keys beside).
struct FillPass {
    pipelines: RasterPipelines,
}

impl FillPass {
    fn new(
        device: &wgpu::Device,
        variant: RasterVariant,
        page_size: u32,
        splats: SplatMode,
    ) -> Self {
        Self {
            pipelines: RasterPipelines::indexed(device, variant, ENCODING, page_size, splats),
        }
    }

    fn record(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        cloud: &ProgressiveCloud,
        state: &ProgressiveState,
        stamps: Stamps<'_>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("fill"),
            timestamp_writes: stamps,
        });
        self.pipelines.record(
            device,
            &mut pass,
            &cloud.storage,
            RasterDispatch::Indirect(&cloud.fill_args),
            &[&state.indexed, &state.color_keys],
        );
    }
}

/// Index keys → colour keys for the resolve (progressive_lookup.wgsl).
struct LookupPass {
    pipeline: wgpu::ComputePipeline,
    group1: wgpu::BindGroupLayout,
}

impl LookupPass {
    fn new(device: &wgpu::Device, page_size: u32, splats: SplatMode) -> Self {
        let [splat, circle] = splat::constants(splats);
        let (pipeline, group1) = point_pipeline(
            device,
            "colour lookup",
            shaders::PROGRESSIVE_LOOKUP,
            "lookup",
            3,
            &[("PAGE_SIZE", page_size as f64), splat, circle],
        );
        Self { pipeline, group1 }
    }

    fn record(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        cloud: &ProgressiveCloud,
        state: &ProgressiveState,
        keys: &wgpu::Buffer,
    ) {
        enc.clear_buffer(keys, 0, None);
        let group1 = storage_group(
            device,
            "colour lookup",
            &self.group1,
            &[&state.indexed, keys, &state.color_keys],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("colour lookup"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(1, &group1, &[]);
        for chunk in &cloud.storage.chunks {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            pass.dispatch_workgroups(state.width.div_ceil(8), state.height.div_ceil(8), 1);
        }
    }
}

/// Pass 3: the list of the slots shown, for the next frame (progressive_prepare.wgsl).
struct PreparePass {
    pipeline: wgpu::ComputePipeline,
    group1: wgpu::BindGroupLayout,
}

impl PreparePass {
    fn new(device: &wgpu::Device, page_size: u32, splats: SplatMode) -> Self {
        let [splat, circle] = splat::constants(splats);
        let (pipeline, group1) = point_pipeline(
            device,
            "prepare",
            shaders::PROGRESSIVE_PREPARE,
            "prepare",
            4,
            &[("PAGE_SIZE", page_size as f64), splat, circle],
        );
        Self { pipeline, group1 }
    }

    fn record(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        cloud: &ProgressiveCloud,
        state: &ProgressiveState,
        listed: &wgpu::Buffer,
    ) {
        enc.clear_buffer(&state.list_len, 0, None);
        let group1 = storage_group(
            device,
            "prepare",
            &self.group1,
            &[&state.indexed, &state.list, &state.list_len, listed],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prepare"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(1, &group1, &[]);
        for chunk in &cloud.storage.chunks {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            pass.dispatch_workgroups(state.width.div_ceil(8), state.height.div_ceil(8), 1);
        }
    }
}

/// The passes that draw points, for one splat mode.
struct PointPasses {
    reproject: ReprojectPass,
    fill: FillPass,
    lookup: LookupPass,
    prepare: PreparePass,
}

/// One progressive frame's choices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgressiveSettings {
    /// S: slots the Fill pass draws this frame (at most all of them).
    pub budget: u32,
    /// Draw the previous frame's points first; off, every frame starts from an empty image.
    pub reproject: bool,
    pub screen: ScreenSettings,
    /// One bit per ASPRS class, as [`crate::RenderSettings::hidden_classes`].
    pub hidden_classes: [u32; 8],
    /// Point size and shape (adaptive splats take the cloud's spacing).
    pub splats: SplatSettings,
}

/// The progressive passes of one closest-point variant and page size, and the screen passes
/// they feed.
pub struct ProgressiveRenderer {
    variant: RasterVariant,
    page_size: u32,
    /// Built on first use of each splat mode.
    points: HashMap<SplatMode, PointPasses>,
    screen: ScreenPasses,
    graphs: HashMap<FrameShape, FrameGraph>,
    /// Frames submitted so far (the ids timings carry).
    frames: u64,
    in_flight: std::collections::VecDeque<wgpu::SubmissionIndex>,
}

/// GPU time of a progressive frame's passes, from timestamp queries.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProgressiveTiming {
    /// Redrawing last frame's points (0 when the frame did not reproject).
    pub reproject_ms: f64,
    /// Drawing the next S slots.
    pub fill_ms: f64,
    /// Resolve, occlusion, hole filling, EDL.
    pub screen_ms: f64,
}

impl ProgressiveTiming {
    pub fn total_ms(&self) -> f64 {
        self.reproject_ms + self.fill_ms + self.screen_ms
    }
}

impl ProgressiveRenderer {
    pub fn new(ctx: &GpuContext, variant: RasterVariant, page_size: u32) -> Result<Self, GpuError> {
        if !variant.accumulates() {
            return Err(GpuError::Unsupported {
                what: variant.name().to_string(),
                why: "progressive rendering keeps one closest point per pixel across frames: \
                      use atomic-min, early-z, reduce, reduce-early-z or dedup"
                    .into(),
                adapter: ctx.describe(),
            });
        }
        if let Some(why) = variant.unsupported_reason(&ctx.caps) {
            return Err(GpuError::Unsupported {
                what: variant.name().to_string(),
                why: why.to_string(),
                adapter: ctx.describe(),
            });
        }
        check_page_size(page_size)?;
        let device = &ctx.device;
        ctx.checked("building the progressive passes", || Self {
            variant,
            page_size,
            points: HashMap::new(),
            screen: ScreenPasses::new(device),
            graphs: HashMap::new(),
            frames: 0,
            in_flight: std::collections::VecDeque::new(),
        })
    }

    /// Blocks until at most `max` submitted frames are still running on the GPU (as a swap
    /// chain would).
    pub fn limit_frames_in_flight(&mut self, ctx: &GpuContext, max: usize) -> Result<(), GpuError> {
        crate::renderer::limit_in_flight(ctx, &mut self.in_flight, max)
    }

    pub fn variant(&self) -> RasterVariant {
        self.variant
    }

    /// Frames submitted so far; timings carry these numbers.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// GPU timings that have arrived (never blocks), oldest first, with their frame numbers;
    /// none without timestamp queries.
    pub fn poll_timings(
        &mut self,
        ctx: &GpuContext,
        target: &mut RenderTarget,
    ) -> Vec<(u64, ProgressiveTiming)> {
        let Some(t) = target.timer.as_mut() else {
            return Vec::new();
        };
        t.poll(ctx)
            .into_iter()
            .map(|(frame, [reproject, fill, screen, _], reprojected)| {
                let timing = ProgressiveTiming {
                    reproject_ms: if reprojected { reproject } else { 0.0 },
                    fill_ms: fill,
                    screen_ms: screen,
                };
                (frame, timing)
            })
            .collect()
    }

    /// Records and submits one frame of `cloud` seen by `camera` into `target`, advancing
    /// `state` (its list and fill position).
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        cloud: &ProgressiveCloud,
        state: &mut ProgressiveState,
        camera: &Camera,
        settings: &ProgressiveSettings,
        target: &mut RenderTarget,
    ) -> Result<(), GpuError> {
        Renderer::check(ctx, self.variant, &settings.splats, camera)?;
        let mode = settings.splats.mode();
        if let Entry::Vacant(slot) = self.points.entry(mode) {
            let (device, variant, page_size) = (&ctx.device, self.variant, self.page_size);
            slot.insert(
                ctx.checked("building the progressive passes", || PointPasses {
                    reproject: ReprojectPass::new(device, page_size, mode),
                    fill: FillPass::new(device, variant, page_size, mode),
                    lookup: LookupPass::new(device, page_size, mode),
                    prepare: PreparePass::new(device, page_size, mode),
                })?,
            );
        }
        let Some(passes) = self.points.get(&mode) else {
            return Ok(());
        };
        if cloud.page_size != self.page_size {
            return Err(GpuError::InvalidInput(format!(
                "a cloud of {}-point pages drawn by passes built for {}-point pages",
                cloud.page_size, self.page_size
            )));
        }
        if (state.width, state.height) != (target.width, target.height) {
            return Err(GpuError::InvalidInput(format!(
                "progressive state for {}×{} used with a {}×{} image",
                state.width, state.height, target.width, target.height
            )));
        }
        let budget = settings.budget.min(cloud.points);
        cloud.prepare(ctx, camera, (target.width, target.height), settings);
        cloud.write_fill(ctx, state.next_fill, budget);
        let device = &ctx.device;
        self.frames += 1;
        let frame = self.frames;
        let reproject = settings.reproject && state.has_list;
        let listed = cloud.listed_bits(ctx, !settings.splats.is_pixel())?;
        let render_settings = RenderSettings {
            variant: self.variant,
            screen: settings.screen,
            hidden_classes: settings.hidden_classes,
            splats: settings.splats,
        };
        let shape = frame_shape(Source::Progressive, &render_settings, false);
        let mut enc = device.create_command_encoder(&Default::default());
        enc.clear_buffer(&state.indexed, 0, None);
        // Reproject clears the bits of the slots it draws; without it, some may be left.
        if !reproject {
            enc.clear_buffer(listed, 0, None);
        }
        // Kept over frames while the view stays still; else this frame's own.
        if !(reproject && state.color_keys_kept) {
            enc.clear_buffer(&state.color_keys, 0, None);
        }
        let state_ref = &*state;
        let _graph_overhead = record_frame(
            (&mut self.screen, &mut self.graphs),
            ctx,
            &mut enc,
            target,
            &render_settings,
            camera,
            shape,
            |pass, enc, px, stamps| {
                match pass {
                    FramePass::Reproject if reproject => {
                        passes.reproject.record(
                            device,
                            enc,
                            cloud,
                            state_ref,
                            listed,
                            stamps.compute(),
                        );
                    }
                    FramePass::Fill => {
                        passes
                            .fill
                            .record(device, enc, cloud, state_ref, stamps.compute());
                    }
                    FramePass::Lookup => {
                        passes.lookup.record(device, enc, cloud, state_ref, px.keys);
                    }
                    FramePass::Prepare => {
                        passes.prepare.record(device, enc, cloud, state_ref, listed);
                    }
                    _ => {}
                }
                Ok(())
            },
        )?;
        if let Some(t) = target.timer.as_mut() {
            t.resolve(&mut enc, frame, reproject);
        }
        let submission = ctx.checked("rendering a progressive frame", || {
            ctx.queue.submit([enc.finish()])
        })?;
        if let Some(t) = target.timer.as_mut() {
            t.after_submit();
        }
        self.in_flight.push_back(submission);
        while self.in_flight.len() > 16 {
            self.in_flight.pop_front();
        }
        state.has_list = true;
        state.color_keys_kept = true;
        state.next_fill =
            ((state.next_fill as u64 + budget as u64) % cloud.points.max(1) as u64) as u32;
        Ok(())
    }
}
