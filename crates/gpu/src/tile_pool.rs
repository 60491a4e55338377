//! Streamed 3D Tiles content on the GPU (WebGPU-engine paper §3.5, §5, §6.1). Each tile's points
//! live in one range of the buffer [`Suballocator`]: f32 xyz relative to the tile's origin, then
//! RGBA8 colours. Every frame the continuous-LoD filter (clod.wgsl) tests the points of the drawn
//! tiles and appends the survivors, camera-relative, to the tile's region of an output page
//! storage; the rasterizers and screen passes then draw those pages as they draw a store's.
//! Which tiles are here and which are drawn is the engine's choice; this is the mechanism.

use crate::cloud::write_frame;
use crate::context::GpuContext;
use crate::raster::grid;
use crate::renderer::RenderSettings;
use crate::storage::{
    encode_positions, DrawBuffers, GpuDrawEntry, GpuDrawInfo, PointEncoding, PointStorage,
};
use crate::suballoc::{Allocation, Suballocator, ALIGNMENT};
use crate::{shaders, GpuError};
use bytemuck::{Pod, Zeroable};
use pointlet_core::Camera;
use std::collections::HashMap;

/// Points one filter workgroup tests (clod.wgsl `BLOCK`).
const BLOCK: u32 = 4096;
/// Tiles drawn in one frame at most.
pub const MAX_DRAWN_TILES: u32 = 1 << 16;
/// Suballocator pages with drawn tiles in one frame at most (one filter dispatch each).
const MAX_PAGES_DRAWN: u32 = 4096;
/// Bytes of a content page (the paper finds 32–64 MB the best balance).
pub const CONTENT_PAGE_BYTES: u64 = 64 << 20;

/// One tile's points to upload: world positions in f64 and RGBA8 colours.
#[derive(Clone, Copy, Debug)]
pub struct TileContent<'a> {
    pub positions: &'a [[f64; 3]],
    pub colors: &'a [u32],
}

/// A tile to draw this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileDraw {
    pub key: u64,
    /// s_native / k of eq. 9 in metres (a point at distance d survives when r · d < this);
    /// `None` draws every point.
    pub clod: Option<f64>,
    /// Surface spacing of the points drawn from the tile (adaptive splats; 0: unknown).
    pub spacing: f32,
}

/// What one frame's filter was given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileFrame {
    /// Tiles whose points the filter tests.
    pub tiles: u32,
    /// Their points.
    pub points: u64,
    /// Drawn tiles left out: not uploaded, or past the output's capacity.
    pub skipped: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuTile {
    rel_origin: [f32; 3],
    count: u32,
    position_word: u32,
    color_word: u32,
    out_first: u32,
    keep_all: u32,
    clod: f32,
    _pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuRange {
    first_block: u32,
    count: u32,
    _pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuFinalize {
    entries: u32,
    page_size: u32,
    _pad: [u32; 2],
}

struct ResidentTile {
    alloc: Allocation,
    count: u32,
    origin: [f64; 3],
}

/// A filter dispatch: the drawn tiles of one content page.
struct PageDispatch {
    page: usize,
    blocks: u32,
}

pub struct TilePool {
    content: Suballocator,
    tiles: HashMap<u64, ResidentTile>,
    pub page_size: u32,
    /// Output page slots (one chunk).
    pub slots: u32,
    pub(crate) output: PointStorage,
    pub(crate) frame_uniform: wgpu::Buffer,
    infos: wgpu::Buffer,
    entries: wgpu::Buffer,
    entry_counts: wgpu::Buffer,
    pub(crate) indirect: wgpu::Buffer,
    pub(crate) draw_args: wgpu::Buffer,
    tile_params: wgpu::Buffer,
    blocks: wgpu::Buffer,
    ranges: wgpu::Buffer,
    survivors: wgpu::Buffer,
    entry_pages: wgpu::Buffer,
    finalize_params: wgpu::Buffer,
    filter_layout: wgpu::BindGroupLayout,
    filter: wgpu::ComputePipeline,
    finalize: wgpu::ComputePipeline,
    finalize_group: wgpu::BindGroup,
    /// Filter bind groups by content page (pages are never released, so these stay valid).
    page_groups: HashMap<usize, wgpu::BindGroup>,
    max_blocks: u32,
    /// Tiles drawn in one frame at most.
    max_tiles: u32,
    /// This frame's dispatches and entries.
    dispatches: Vec<PageDispatch>,
    entry_count: u32,
    drawn_tiles: u32,
}

/// Bytes between filter dispatch ranges (uniform dynamic offsets are 256-aligned).
const RANGE_STRIDE: u64 = 256;

impl TilePool {
    /// A pool drawing at most `output_points` points a frame in pages of `page_size`, its
    /// content in suballocator pages of `content_page_bytes` (at most [`CONTENT_PAGE_BYTES`]
    /// and the binding limit: a page is bound whole).
    pub fn new(
        ctx: &GpuContext,
        output_points: u64,
        page_size: u32,
        content_page_bytes: u64,
    ) -> Result<Self, GpuError> {
        crate::storage::check_page_size(page_size)?;
        let device = &ctx.device;
        let per_chunk = PointStorage::slots_per_chunk(ctx, PointEncoding::Full16, page_size);
        let slots = (output_points.div_ceil(page_size as u64).max(1)).min(per_chunk as u64) as u32;
        // A drawn tile takes at least one output page.
        let max_tiles = slots.min(MAX_DRAWN_TILES);
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.checked("allocating the tile tables", || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: size.max(16),
                    usage,
                    mapped_at_creation: false,
                })
            })
        };
        use wgpu::BufferUsages as U;
        let storage = U::STORAGE | U::COPY_DST;
        let frame_uniform = buffer(
            "tile frame",
            std::mem::size_of::<crate::storage::GpuFrame>() as u64,
            U::UNIFORM | U::COPY_DST,
        )?;
        let infos = buffer("tile infos", max_tiles as u64 * 32, storage)?;
        let entries = buffer("tile entries", slots as u64 * 16, storage)?;
        let entry_counts = buffer("tile entry counts", 16, storage)?;
        let indirect = buffer("tile indirect", 16, U::INDIRECT | U::STORAGE | U::COPY_DST)?;
        let draw_args = buffer("tile draw args", 16, U::INDIRECT | U::STORAGE | U::COPY_DST)?;
        let max_blocks = (slots as u64 * page_size as u64 / BLOCK as u64 + max_tiles as u64)
            .min(u32::MAX as u64) as u32;
        let tile_params = buffer(
            "tile params",
            max_tiles as u64 * std::mem::size_of::<GpuTile>() as u64,
            storage,
        )?;
        let blocks = buffer("tile blocks", max_blocks as u64 * 8, storage)?;
        let ranges = buffer(
            "tile ranges",
            MAX_PAGES_DRAWN as u64 * RANGE_STRIDE,
            U::UNIFORM | U::COPY_DST,
        )?;
        let survivors = buffer(
            "tile survivors",
            max_tiles as u64 * 4,
            storage | U::COPY_SRC,
        )?;
        let entry_pages = buffer("tile entry pages", slots as u64 * 4, storage)?;
        let finalize_params = buffer("tile finalize", 16, U::UNIFORM | U::COPY_DST)?;
        let draw = DrawBuffers {
            frame: &frame_uniform,
            infos: &infos,
            entries: &entries,
            entry_counts: &entry_counts,
            list_offsets: &[0],
        };
        let output = PointStorage::new(ctx, PointEncoding::Full16, page_size, slots, &draw)?;

        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        let storage_ty = |read_only| wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let filter_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("clod filter"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(16),
                    },
                ),
                entry(1, storage_ty(true)),
                entry(2, storage_ty(true)),
                entry(3, storage_ty(true)),
                entry(4, storage_ty(false)),
                entry(5, storage_ty(false)),
                entry(6, storage_ty(false)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("clod filter"),
            bind_group_layouts: &[Some(&filter_layout)],
            immediate_size: 0,
        });
        let filter = ctx.checked("building the continuous-LoD filter", || {
            let module = shaders::module(device, "clod", shaders::CLOD);
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("clod filter"),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some("filter_points"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &[("BLOCK", BLOCK as f64)],
                    ..Default::default()
                },
                cache: None,
            })
        })?;
        let finalize = ctx.checked("building the tile entry pass", || {
            let module = shaders::module(device, "clod entries", shaders::CLOD_ENTRIES);
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("clod entries"),
                layout: None,
                module: &module,
                entry_point: Some("finalize_entries"),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        let finalize_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("clod entries"),
            layout: &finalize.get_bind_group_layout(0),
            entries: &[
                whole(0, &finalize_params),
                whole(1, &entry_pages),
                whole(2, &survivors),
                whole(3, &entries),
            ],
        });
        let page_bytes = content_page_bytes
            .min(CONTENT_PAGE_BYTES)
            .min(ctx.caps.max_binding);
        Ok(Self {
            content: Suballocator::new(page_bytes),
            tiles: HashMap::new(),
            page_size,
            slots,
            output,
            frame_uniform,
            infos,
            entries,
            entry_counts,
            indirect,
            draw_args,
            tile_params,
            blocks,
            ranges,
            survivors,
            entry_pages,
            finalize_params,
            filter_layout,
            filter,
            finalize,
            finalize_group,
            page_groups: HashMap::new(),
            max_blocks,
            max_tiles,
            dispatches: Vec::new(),
            entry_count: 0,
            drawn_tiles: 0,
        })
    }

    /// Points the output holds: what one frame draws at most.
    pub fn capacity(&self) -> u64 {
        self.slots as u64 * self.page_size as u64
    }

    pub fn contains(&self, key: u64) -> bool {
        self.tiles.contains_key(&key)
    }

    /// Tiles on the GPU.
    pub fn len(&self) -> usize {
        self.tiles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tiles.is_empty()
    }

    /// GPU bytes a tile of `points` points takes in the pool.
    pub fn tile_bytes(points: usize) -> u64 {
        (points as u64 * 16).div_ceil(ALIGNMENT) * ALIGNMENT
    }

    /// Bytes of tile content allocated.
    pub fn content_bytes(&self) -> u64 {
        self.content.stats().used
    }

    /// Bytes of the content pages (allocated or not).
    pub fn content_reserved(&self) -> u64 {
        self.content.stats().reserved
    }

    /// GPU bytes a tile of `points` points would add in new content pages (0: it fits).
    pub fn growth_for(&self, points: usize) -> u64 {
        self.content
            .growth_for(wgpu::BufferUsages::STORAGE, points as u64 * 16)
    }

    /// GPU bytes of the pool: content pages, the output and the tables.
    pub fn gpu_bytes(&self) -> u64 {
        self.content.stats().reserved
            + self.output.bytes()
            + self.slots as u64 * 20
            + self.max_tiles as u64 * (32 + 48 + 4)
            + self.max_blocks as u64 * 8
    }

    pub fn content_stats(&self) -> crate::suballoc::SuballocatorStats {
        self.content.stats()
    }

    /// Puts the points of tile `key` on the GPU, relative to `origin` (replacing what the key
    /// held).
    pub fn upload(
        &mut self,
        ctx: &GpuContext,
        key: u64,
        origin: [f64; 3],
        content: TileContent<'_>,
    ) -> Result<(), GpuError> {
        if content.colors.len() != content.positions.len() {
            return Err(GpuError::InvalidInput(format!(
                "{} positions but {} colours",
                content.positions.len(),
                content.colors.len()
            )));
        }
        let words = encode_tile(content.positions, origin);
        self.upload_encoded(ctx, key, origin, &words, content.colors)
    }

    /// [`upload`](Self::upload) of positions already encoded by [`encode_tile`].
    pub fn upload_encoded(
        &mut self,
        ctx: &GpuContext,
        key: u64,
        origin: [f64; 3],
        positions: &[u32],
        colors: &[u32],
    ) -> Result<(), GpuError> {
        let n = colors.len();
        if positions.len() != 3 * n {
            return Err(GpuError::InvalidInput(format!(
                "{} position words for {n} colours",
                positions.len()
            )));
        }
        if n == 0 {
            return Err(GpuError::InvalidInput("a tile without points".into()));
        }
        let bytes = n as u64 * 16;
        if bytes > ctx.caps.max_binding || n as u64 > self.capacity() {
            return Err(GpuError::InvalidInput(format!(
                "a tile of {n} points is larger than the GPU binds at once ({} points)",
                (ctx.caps.max_binding / 16).min(self.capacity())
            )));
        }
        self.remove(key);
        let alloc = self
            .content
            .alloc(ctx, wgpu::BufferUsages::STORAGE, bytes)?;
        ctx.queue.write_buffer(
            alloc.buffer(),
            alloc.offset,
            bytemuck::cast_slice(positions),
        );
        ctx.queue.write_buffer(
            alloc.buffer(),
            alloc.offset + n as u64 * 12,
            bytemuck::cast_slice(colors),
        );
        let page = alloc.page();
        if let std::collections::hash_map::Entry::Vacant(slot) = self.page_groups.entry(page) {
            let chunk = self.output.chunks.first().ok_or_else(|| {
                GpuError::InvalidInput("the tile output has no point buffers".into())
            })?;
            slot.insert(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("clod page"),
                layout: &self.filter_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &self.ranges,
                            offset: 0,
                            size: wgpu::BufferSize::new(16),
                        }),
                    },
                    whole(1, alloc.buffer()),
                    whole(2, &self.tile_params),
                    whole(3, &self.blocks),
                    whole(4, &chunk.positions),
                    whole(5, &chunk.colors),
                    whole(6, &self.survivors),
                ],
            }));
        }
        self.tiles.insert(
            key,
            ResidentTile {
                alloc,
                count: n as u32,
                origin,
            },
        );
        Ok(())
    }

    /// Frees the GPU range of tile `key`; false when it was not here.
    pub fn remove(&mut self, key: u64) -> bool {
        match self.tiles.remove(&key) {
            Some(t) => {
                self.content.free(t.alloc);
                true
            }
            None => false,
        }
    }

    /// Lays out this frame: the drawn tiles' output regions (in `draws` order, until the
    /// output is full), their camera-relative origins, the filter's blocks and the draw
    /// entries, and the frame uniform.
    pub fn prepare(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        size: (u32, u32),
        settings: &RenderSettings,
        draws: &[TileDraw],
    ) -> TileFrame {
        let mut out = TileFrame::default();
        let eye = camera.eye;
        let page = self.page_size;
        let mut params: Vec<GpuTile> = Vec::new();
        let mut infos: Vec<GpuDrawInfo> = Vec::new();
        let mut entries: Vec<GpuDrawEntry> = Vec::new();
        let mut entry_pages: Vec<u32> = Vec::new();
        let mut by_page: Vec<(usize, u32, u32)> = Vec::new();
        let mut used = 0u32;
        for d in draws {
            let Some(t) = self.tiles.get(&d.key) else {
                out.skipped += 1;
                continue;
            };
            let need = t.count.div_ceil(page);
            let blocks = t.count.div_ceil(BLOCK);
            if params.len() as u32 >= self.max_tiles
                || used + need > self.slots
                || by_page.len() as u32 + blocks > self.max_blocks
            {
                out.skipped += 1;
                continue;
            }
            let index = params.len() as u32;
            let (keep_all, clod) = match d.clod {
                Some(c) if c.is_finite() => (0, c.max(0.0) as f32),
                _ => (1, 0.0),
            };
            let word = (t.alloc.offset / 4) as u32;
            params.push(GpuTile {
                rel_origin: [0, 1, 2].map(|a| (t.origin[a] - eye[a]) as f32),
                count: t.count,
                position_word: word,
                color_word: word + 3 * t.count,
                out_first: used * page,
                keep_all,
                clod,
                _pad: [0; 3],
            });
            infos.push(GpuDrawInfo {
                origin: [0.0; 3],
                flags: 0,
                step: [0.0; 3],
                spacing: d.spacing,
            });
            for j in 0..need {
                entries.push(GpuDrawEntry {
                    slot: used + j,
                    info: index,
                    first: 0,
                    count: 0,
                });
                entry_pages.push(j);
            }
            used += need;
            for b in 0..blocks {
                by_page.push((t.alloc.page(), index, b * BLOCK));
            }
            out.tiles += 1;
            out.points += t.count as u64;
        }
        // Blocks grouped by page: one dispatch per page, its blocks consecutive.
        by_page.sort_unstable_by_key(|(p, _, _)| *p);
        let mut blocks: Vec<[u32; 2]> = Vec::with_capacity(by_page.len());
        let mut ranges: Vec<u8> = Vec::new();
        self.dispatches.clear();
        for (k, (p, index, first)) in by_page.iter().enumerate() {
            let starts = k == 0 || by_page[k - 1].0 != *p;
            if starts {
                if self.dispatches.len() as u32 >= MAX_PAGES_DRAWN {
                    break;
                }
                self.dispatches.push(PageDispatch {
                    page: *p,
                    blocks: 0,
                });
                let range = GpuRange {
                    first_block: blocks.len() as u32,
                    count: 0,
                    _pad: [0; 2],
                };
                ranges.resize((self.dispatches.len() - 1) * RANGE_STRIDE as usize, 0);
                ranges.extend_from_slice(bytemuck::bytes_of(&range));
            }
            blocks.push([*index, *first]);
            let last = self.dispatches.len() - 1;
            if let Some(d) = self.dispatches.last_mut() {
                d.blocks += 1;
                let at = last * RANGE_STRIDE as usize + 4;
                ranges[at..at + 4].copy_from_slice(&d.blocks.to_le_bytes());
            }
        }
        let q = &ctx.queue;
        if !params.is_empty() {
            q.write_buffer(&self.tile_params, 0, bytemuck::cast_slice(&params));
            q.write_buffer(&self.infos, 0, bytemuck::cast_slice(&infos));
        }
        if !blocks.is_empty() {
            q.write_buffer(&self.blocks, 0, bytemuck::cast_slice(&blocks));
            q.write_buffer(&self.ranges, 0, &ranges);
        }
        if !entries.is_empty() {
            q.write_buffer(&self.entries, 0, bytemuck::cast_slice(&entries));
            q.write_buffer(&self.entry_pages, 0, bytemuck::cast_slice(&entry_pages));
        }
        let n = entries.len() as u32;
        let [x, y] = grid(n);
        let indirect = [if n == 0 { 0 } else { x }, y, 1, 0];
        q.write_buffer(&self.indirect, 0, bytemuck::cast_slice(&indirect));
        q.write_buffer(&self.entry_counts, 0, bytemuck::cast_slice(&[n, 0, 0, 0]));
        let draw_args = [4, n * page, 0, 0];
        q.write_buffer(&self.draw_args, 0, bytemuck::cast_slice(&draw_args));
        let fin = GpuFinalize {
            entries: n,
            page_size: page,
            _pad: [0; 2],
        };
        q.write_buffer(&self.finalize_params, 0, bytemuck::bytes_of(&fin));
        write_frame(ctx, &self.frame_uniform, camera, size, settings);
        self.entry_count = n;
        self.drawn_tiles = params.len() as u32;
        out
    }

    /// Records the filter and the entry pass of the frame [`prepare`](Self::prepare)d.
    pub(crate) fn record_filter(
        &self,
        enc: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        if self.drawn_tiles > 0 {
            enc.clear_buffer(&self.survivors, 0, Some(self.drawn_tiles as u64 * 4));
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("clod filter"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.filter);
        for (k, d) in self.dispatches.iter().enumerate() {
            let Some(group) = self.page_groups.get(&d.page) else {
                continue;
            };
            pass.set_bind_group(0, group, &[(k as u64 * RANGE_STRIDE) as u32]);
            let [x, y] = grid(d.blocks);
            pass.dispatch_workgroups(x, y, 1);
        }
        if self.entry_count > 0 {
            pass.set_pipeline(&self.finalize);
            pass.set_bind_group(0, &self.finalize_group, &[]);
            pass.dispatch_workgroups(self.entry_count.div_ceil(64), 1, 1);
        }
    }
}

/// A tile's positions as the pool holds them: f32 xyz relative to `origin`, as bits.
pub fn encode_tile(positions: &[[f64; 3]], origin: [f64; 3]) -> Vec<u32> {
    let mut words = Vec::with_capacity(positions.len() * 3);
    // Full16 has no quantization step and no fine stream.
    encode_positions(
        positions,
        origin,
        [0.0; 3],
        PointEncoding::Full16,
        &mut words,
        &mut Vec::new(),
    );
    words
}

/// The filter's r(p) of a point's tile-local f32 position (clod.wgsl `hash3`), in [0, 1).
pub fn clod_random(local: [f32; 3]) -> f32 {
    let [a, b, c] = local.map(f32::to_bits);
    let mut h =
        a.wrapping_mul(0x9e37_79b1) ^ b.wrapping_mul(0x85eb_ca77) ^ c.wrapping_mul(0xc2b2_ae3d);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

impl TilePool {
    /// Survivors of each tile the last frame drew, in [`prepare`](Self::prepare)'s order
    /// (waits for the GPU: for tests and diagnostics).
    pub fn read_survivors(&self, ctx: &GpuContext) -> Result<Vec<u32>, GpuError> {
        let n = self.drawn_tiles as u64;
        if n == 0 {
            return Ok(Vec::new());
        }
        let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("survivors readback"),
            size: n * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&self.survivors, 0, &rb, 0, n * 4);
        ctx.queue.submit([enc.finish()]);
        let slice = rb.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        ctx.wait()?;
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Device(format!("reading the survivors back: {e}")))?;
        let out = bytemuck::cast_slice(&view).to_vec();
        drop(view);
        rb.unmap();
        Ok(out)
    }
}

fn whole(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}
