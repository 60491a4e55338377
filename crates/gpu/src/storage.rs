//! GPU point memory: fixed-size page slots in as many buffers ("chunks") as the binding limit
//! requires, the point encodings, and the bind group every point pass reads through.

use crate::context::GpuContext;
use crate::device_memory::DirectAllocator;
use crate::GpuError;
use bytemuck::{Pod, Zeroable};

/// How points are laid out in GPU memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointEncoding {
    /// f32 xyz relative to the draw origin + RGBA8: 16 bytes, one load per point.
    Full16,
    /// 3 × 10-bit coarse position + RGBA8 (8 bytes), plus a 4-byte fine word read only where
    /// the coarse step is visible on screen (Schütz et al. 2022's adaptive precision).
    Compact8,
}

impl PointEncoding {
    pub const ALL: [PointEncoding; 2] = [PointEncoding::Full16, PointEncoding::Compact8];

    pub fn name(self) -> &'static str {
        match self {
            PointEncoding::Full16 => "full16",
            PointEncoding::Compact8 => "compact8",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == s)
    }

    /// Bytes a point costs to draw: position + colour (the fine word of Compact8 is extra,
    /// read only where needed).
    pub fn bytes_per_point(self) -> u64 {
        self.position_bytes() + 4
    }

    /// Bytes of the position stream per point.
    pub fn position_bytes(self) -> u64 {
        match self {
            PointEncoding::Full16 => 12,
            PointEncoding::Compact8 => 4,
        }
    }

    /// Bytes of GPU memory a point slot takes, fine stream included.
    pub fn resident_bytes_per_point(self) -> u64 {
        match self {
            PointEncoding::Full16 => 16,
            PointEncoding::Compact8 => 12,
        }
    }
}

/// Quantization steps per axis of the compact encoding: 20 bits over the box's extent.
pub const COMPACT_STEPS: f64 = (1u64 << 20) as f64;

/// One compact quantization step per axis for a box of `extent` (never 0, so flat boxes work).
pub fn compact_step(extent: [f64; 3]) -> [f64; 3] {
    extent.map(|e| e.max(1e-9) / COMPACT_STEPS)
}

/// 20-bit grid coordinates of `p` in a box (clamped: the box contains its points).
pub fn quantize_compact(p: [f64; 3], origin: [f64; 3], step: [f64; 3]) -> [u32; 3] {
    let max = COMPACT_STEPS - 1.0;
    [0, 1, 2].map(|a| ((p[a] - origin[a]) / step[a]).floor().clamp(0.0, max) as u32)
}

/// Where the GPU draws a compact point: the centre of its fine or coarse cell.
pub fn decode_compact(q: [u32; 3], origin: [f64; 3], step: [f64; 3], fine: bool) -> [f64; 3] {
    [0, 1, 2].map(|a| {
        let cell = if fine {
            q[a] as f64 + 0.5
        } else {
            ((q[a] >> 10) * 1024) as f64 + 512.0
        };
        origin[a] + cell * step[a]
    })
}

/// True when one coarse (10-bit) cell of a box with compact `step` covers more than half a
/// pixel as seen from `eye`: the compact encoding must read the fine word there.
pub fn needs_fine(origin: [f64; 3], extent: [f64; 3], eye: [f64; 3], focal_px: f64) -> bool {
    let cell = compact_step(extent).iter().fold(0.0f64, |m, s| m.max(*s)) * 1024.0;
    let d2: f64 = (0..3)
        .map(|i| {
            let (lo, hi) = (origin[i], origin[i] + extent[i]);
            let d = (lo - eye[i]).max(eye[i] - hi).max(0.0);
            d * d
        })
        .sum();
    cell * focal_px > 0.5 * d2.sqrt()
}

/// One point's position words as the streams store them: Full16 `[x, y, z]` f32 bits relative
/// to `origin`; Compact8 `[coarse, fine, 0]`. Loaders encode with this, so the render thread
/// only copies words.
#[inline]
pub fn encode_point(
    p: [f64; 3],
    origin: [f64; 3],
    step: [f64; 3],
    encoding: PointEncoding,
) -> [u32; 3] {
    match encoding {
        PointEncoding::Full16 => [0, 1, 2].map(|a| ((p[a] - origin[a]) as f32).to_bits()),
        PointEncoding::Compact8 => {
            let q = quantize_compact(p, origin, step);
            [
                (q[0] >> 10) | (q[1] >> 10) << 10 | (q[2] >> 10) << 20,
                (q[0] & 1023) | (q[1] & 1023) << 10 | (q[2] & 1023) << 20,
                0,
            ]
        }
    }
}

/// Encodes positions into the position stream (u32 words: 3 per point for Full16, 1 for
/// Compact8) and, for Compact8, the fine stream, relative to a box `origin` (and its compact
/// `step`). Colours need no encoding: they are uploaded as they are.
pub fn encode_positions(
    positions: &[[f64; 3]],
    origin: [f64; 3],
    step: [f64; 3],
    encoding: PointEncoding,
    main: &mut Vec<u32>,
    fine: &mut Vec<u32>,
) {
    for p in positions {
        let w = encode_point(*p, origin, step, encoding);
        match encoding {
            PointEncoding::Full16 => main.extend_from_slice(&w),
            PointEncoding::Compact8 => {
                main.push(w[0]);
                fine.push(w[1]);
            }
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuDrawInfo {
    pub origin: [f32; 3],
    pub flags: u32,
    pub step: [f32; 3],
    /// Surface spacing of the points drawn from here (adaptive splats; 0: unknown).
    pub spacing: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuDrawEntry {
    pub slot: u32,
    pub info: u32,
    pub first: u32,
    pub count: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuFrame {
    pub view_proj: [[f32; 4]; 4],
    pub size: [u32; 2],
    pub blend_factor: f32,
    pub _pad: u32,
    pub hidden_classes: [u32; 8],
    /// Fixed side, adaptive scale, largest side, ring ratio (`SplatSettings::uniform`).
    pub splat: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuDispatch {
    first_slot: u32,
    list_offset: u32,
    chunk: u32,
    slots: u32,
}

/// Layout of bind group 0 for every point pass of an encoding; identical descriptors give
/// compatible layouts, so storages and pipelines can each create their own.
pub(crate) fn point_group_layout(
    device: &wgpu::Device,
    encoding: PointEncoding,
) -> wgpu::BindGroupLayout {
    let both = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::VERTEX;
    let uniform = |binding, visibility| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let storage = |binding, visibility| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let mut entries = vec![
        uniform(0, both),
        storage(1, both),
        storage(2, both),
        uniform(3, both),
        // The vertex stage pulls points too: billboard quads (quads.rs).
        storage(4, both),
        storage(6, both),
        storage(7, both),
    ];
    if encoding == PointEncoding::Compact8 {
        entries.push(storage(5, both));
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(encoding.name()),
        entries: &entries,
    })
}

/// The point buffers of a range of slots (each ≤ the binding limit).
pub(crate) struct PointChunk {
    pub positions: wgpu::Buffer,
    pub colors: wgpu::Buffer,
    pub fine: Option<wgpu::Buffer>,
    pub first_slot: u32,
    pub slots: u32,
    pub bind_group: wgpu::BindGroup,
    _dispatch: wgpu::Buffer,
}

/// The buffers a storage's bind groups point at besides the points themselves.
pub(crate) struct DrawBuffers<'a> {
    pub frame: &'a wgpu::Buffer,
    pub infos: &'a wgpu::Buffer,
    pub entries: &'a wgpu::Buffer,
    pub entry_counts: &'a wgpu::Buffer,
    /// Where each chunk's entries start in `entries` (dispatch `list_offset`).
    pub list_offsets: &'a [u32],
}

/// Page slots of `page_size` points, spread over chunk buffers.
pub(crate) struct PointStorage {
    pub encoding: PointEncoding,
    pub page_size: u32,
    pub slots_per_chunk: u32,
    /// The chunks made so far, in slot order.
    pub chunks: Vec<PointChunk>,
    planned: usize,
}

/// Makes the chunks of a [`PointStorage`]: a chunk's buffers and its bind group, one at a
/// time. Its memory comes from Vulkan directly where it can (3.3 ms for a 2.5 GiB chunk on
/// the H100); through wgpu a chunk takes ~60 ms, so there the first chunks of a store can be
/// drawn while the next are made.
pub(crate) struct ChunkMaker {
    layout: wgpu::BindGroupLayout,
    frame: wgpu::Buffer,
    infos: wgpu::Buffer,
    entries: wgpu::Buffer,
    entry_counts: wgpu::Buffer,
    list_offsets: Vec<u32>,
    encoding: PointEncoding,
    page_size: u32,
    slots_per_chunk: u32,
    total_slots: u32,
    /// Makes the point memory where the device allows ([`Capabilities::direct_memory`]).
    direct: Option<DirectAllocator>,
}

impl ChunkMaker {
    /// Chunks of the storage (an empty storage still gets a one-page chunk).
    pub fn chunks(&self) -> u32 {
        chunks_of(self.total_slots, self.slots_per_chunk)
    }

    /// Chunk `index`'s buffers and bind group.
    pub fn make(&self, ctx: &GpuContext, index: u32) -> Result<PointChunk, GpuError> {
        let memory = match &self.direct {
            Some(d) => {
                let memory =
                    self.memory(index, |label, bytes| d.buffer(label, bytes, CHUNK_USAGE))?;
                // Zeroed as wgpu's own buffers are (memory made directly comes as the driver
                // leaves it): ~5 ms of the GPU for 15 GiB on the H100.
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let ChunkMemory {
                    positions,
                    colors,
                    fine,
                } = &memory;
                for b in [positions, colors].into_iter().chain(fine) {
                    enc.clear_buffer(b, 0, None);
                }
                ctx.queue.submit([enc.finish()]);
                memory
            }
            None => ctx.checked("allocating GPU point memory", || {
                self.memory(index, |label, bytes| {
                    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: bytes,
                        usage: CHUNK_USAGE,
                        mapped_at_creation: false,
                    }))
                })
            })??,
        };
        self.finish(ctx, index, memory)
    }

    /// Chunk `index`'s point buffers, each made by `alloc(label, bytes)`.
    fn memory(
        &self,
        index: u32,
        mut alloc: impl FnMut(&str, u64) -> Result<wgpu::Buffer, GpuError>,
    ) -> Result<ChunkMemory, GpuError> {
        let slots = self.slots_of(index) as u64;
        let page_size = self.page_size as u64;
        let page_bytes = self.encoding.position_bytes() * page_size;
        Ok(ChunkMemory {
            positions: alloc("positions", slots * page_bytes)?,
            colors: alloc("colours", slots * page_size * 4)?,
            fine: match self.encoding {
                PointEncoding::Full16 => None,
                PointEncoding::Compact8 => Some(alloc("fine positions", slots * page_size * 4)?),
            },
        })
    }

    fn slots_of(&self, index: u32) -> u32 {
        let first_slot = index * self.slots_per_chunk;
        (self.total_slots.max(1) - first_slot).min(self.slots_per_chunk)
    }

    /// Chunk `index` made of `memory` (from [`memory`](Self::memory)): its dispatch uniform
    /// and bind group.
    fn finish(
        &self,
        ctx: &GpuContext,
        index: u32,
        memory: ChunkMemory,
    ) -> Result<PointChunk, GpuError> {
        let device = &ctx.device;
        let first_slot = index * self.slots_per_chunk;
        let slots = self.slots_of(index);
        let ChunkMemory {
            positions,
            colors,
            fine,
        } = memory;
        ctx.checked("making a chunk's bind group", || {
            let dispatch = GpuDispatch {
                first_slot,
                list_offset: self.list_offsets.get(index as usize).copied().unwrap_or(0),
                chunk: index,
                slots,
            };
            let dispatch_buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dispatch"),
                size: std::mem::size_of::<GpuDispatch>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            ctx.queue
                .write_buffer(&dispatch_buffer, 0, bytemuck::bytes_of(&dispatch));
            let mut entries = vec![
                entry(0, &self.frame),
                entry(1, &self.infos),
                entry(2, &self.entries),
                entry(3, &dispatch_buffer),
                entry(4, &positions),
                entry(6, &self.entry_counts),
                entry(7, &colors),
            ];
            if let Some(f) = &fine {
                entries.push(entry(5, f));
            }
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("points"),
                layout: &self.layout,
                entries: &entries,
            });
            PointChunk {
                positions,
                colors,
                fine,
                first_slot,
                slots,
                bind_group,
                _dispatch: dispatch_buffer,
            }
        })
    }
}

/// The point buffers of one chunk.
struct ChunkMemory {
    positions: wgpu::Buffer,
    colors: wgpu::Buffer,
    fine: Option<wgpu::Buffer>,
}

/// The usage of a chunk's point buffers. COPY_SRC: a shuffled buffer living in them can be
/// read back.
const CHUNK_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::VERTEX)
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

/// Chunks of `per_chunk` slots that `total_slots` slots take (at least one).
pub(crate) fn chunks_of(total_slots: u32, per_chunk: u32) -> u32 {
    total_slots.max(1).div_ceil(per_chunk.max(1))
}

pub(crate) fn check_page_size(page_size: u32) -> Result<(), GpuError> {
    if page_size.is_power_of_two() && (256..=1 << 15).contains(&page_size) {
        Ok(())
    } else {
        Err(GpuError::InvalidInput(format!(
            "page size {page_size} must be a power of two in 256..=32768"
        )))
    }
}

impl PointStorage {
    /// How many slots one chunk buffer holds on this device.
    pub fn slots_per_chunk(ctx: &GpuContext, encoding: PointEncoding, page_size: u32) -> u32 {
        // The position stream is the largest per point: it decides how many slots fit.
        let page_bytes = encoding.position_bytes() * page_size as u64;
        let max = ctx.caps.max_binding.min(ctx.caps.max_buffer);
        (max / page_bytes).clamp(1, u32::MAX as u64 / page_size as u64) as u32
    }

    pub fn new(
        ctx: &GpuContext,
        encoding: PointEncoding,
        page_size: u32,
        total_slots: u32,
        draw: &DrawBuffers<'_>,
    ) -> Result<Self, GpuError> {
        let per_chunk = Self::slots_per_chunk(ctx, encoding, page_size);
        let (mut storage, maker) =
            Self::planned(ctx, encoding, page_size, total_slots, draw, per_chunk)?;
        for index in 0..maker.chunks() {
            storage.chunks.push(maker.make(ctx, index)?);
        }
        Ok(storage)
    }

    /// A storage of `total_slots` slots in chunks of `slots_per_chunk` (at most the device's
    /// [`slots_per_chunk`](Self::slots_per_chunk)) without its chunks yet, and what makes
    /// them; they must be pushed onto `chunks` in order.
    pub fn planned(
        ctx: &GpuContext,
        encoding: PointEncoding,
        page_size: u32,
        total_slots: u32,
        draw: &DrawBuffers<'_>,
        slots_per_chunk: u32,
    ) -> Result<(Self, ChunkMaker), GpuError> {
        check_page_size(page_size)?;
        let page_bytes = encoding.position_bytes() * page_size as u64;
        if page_bytes > ctx.caps.max_binding.min(ctx.caps.max_buffer) {
            return Err(GpuError::InvalidInput(format!(
                "a page of {page_size} points ({page_bytes} bytes) exceeds the binding limit"
            )));
        }
        let limit = Self::slots_per_chunk(ctx, encoding, page_size);
        if slots_per_chunk == 0 || slots_per_chunk > limit {
            return Err(GpuError::InvalidInput(format!(
                "chunks of {slots_per_chunk} pages, where the binding limit allows 1 to {limit}"
            )));
        }
        let maker = ChunkMaker {
            layout: point_group_layout(&ctx.device, encoding),
            frame: draw.frame.clone(),
            infos: draw.infos.clone(),
            entries: draw.entries.clone(),
            entry_counts: draw.entry_counts.clone(),
            list_offsets: draw.list_offsets.to_vec(),
            encoding,
            page_size,
            slots_per_chunk,
            total_slots,
            direct: ctx.direct_allocator(),
        };
        let storage = Self {
            encoding,
            page_size,
            slots_per_chunk,
            chunks: Vec::new(),
            planned: maker.chunks() as usize,
        };
        Ok((storage, maker))
    }

    /// Chunks the storage has once all are made.
    pub fn planned_chunks(&self) -> usize {
        self.planned
    }

    /// Chunks needed for `total_slots` slots on this device.
    pub fn chunk_count(
        ctx: &GpuContext,
        encoding: PointEncoding,
        page_size: u32,
        total_slots: u32,
    ) -> u32 {
        chunks_of(total_slots, Self::slots_per_chunk(ctx, encoding, page_size))
    }

    /// The chunk holding `slot` and the index of the slot's point `first` in its buffers.
    fn locate(&self, slot: u32, first: u32) -> Option<(&PointChunk, u64)> {
        let chunk = self.chunks.get((slot / self.slots_per_chunk) as usize)?;
        let point = (slot - chunk.first_slot) as u64 * self.page_size as u64 + first as u64;
        Some((chunk, point))
    }

    /// Writes encoded positions (and fine words) and colours into `slot` from its point `first`.
    pub fn write(
        &self,
        queue: &wgpu::Queue,
        slot: u32,
        first: u32,
        positions: &[u32],
        fine: &[u32],
        colors: &[u32],
    ) {
        let Some((chunk, point)) = self.locate(slot, first) else {
            return;
        };
        queue.write_buffer(
            &chunk.positions,
            point * self.encoding.position_bytes(),
            bytemuck::cast_slice(positions),
        );
        if let Some(f) = &chunk.fine {
            queue.write_buffer(f, point * 4, bytemuck::cast_slice(fine));
        }
        self.write_colors(queue, slot, first, colors);
    }

    /// Replaces the colours of `slot` from its point `first` (recolouring touches nothing else).
    pub fn write_colors(&self, queue: &wgpu::Queue, slot: u32, first: u32, colors: &[u32]) {
        if let Some((chunk, point)) = self.locate(slot, first) {
            queue.write_buffer(&chunk.colors, point * 4, bytemuck::cast_slice(colors));
        }
    }

    /// GPU bytes of point memory.
    pub fn bytes(&self) -> u64 {
        self.chunks
            .iter()
            .map(|c| c.positions.size() + c.colors.size() + c.fine.as_ref().map_or(0, |f| f.size()))
            .sum()
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}
