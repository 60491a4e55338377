//! Virtualized point memory on the GPU: a fixed pool of page slots under a VRAM budget, a page
//! table per pointlet, and the LoD pass that picks each frame's points and builds the draw list
//! on the GPU (lod.wgsl). Which pages live where is decided on the CPU (the engine's residency
//! policy); this module is the mechanism: write points into slots, publish residency, draw.

use crate::cloud::write_frame;
use crate::context::GpuContext;
use crate::raster::storage_group;
use crate::renderer::RenderSettings;
use crate::storage::{
    DrawBuffers, GpuDrawEntry, GpuDrawInfo, GpuFrame, PointEncoding, PointStorage,
};
use crate::upload::{BatchLayout, PageBatch, PageJob, PageSink, PageWrite, UploadQueue};
use crate::{box_spacing, shaders, GpuError};
use bytemuck::{Pod, Zeroable};
use pointlet_core::{Aabb, Camera};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

/// A pointlet as the GPU LoD needs it: its bounding box and point count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointletDesc {
    pub aabb: Aabb,
    pub count: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuPointlet {
    origin_hi: [f32; 3],
    count: u32,
    origin_lo: [f32; 3],
    gamma: f32,
    extent: [f32; 3],
    /// Factor on the box spacing of adaptive splats (see [`spacing_factors`]).
    spacing_factor: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LodParams {
    view_proj: [[f32; 4]; 4],
    eye_hi: [f32; 3],
    pointlet_count: u32,
    eye_lo: [f32; 3],
    bucket: f32,
    viewport: [f32; 2],
    focal_px: f32,
    compact: u32,
    accumulate: u32,
    page_size: u32,
    max_pages: u32,
    chunk_slots: u32,
    chunk_count: u32,
    partial_count: u32,
    cull_margin_px: f32,
    _pad: u32,
}

/// f64 → (hi, lo) f32 pair with hi + lo ≈ v to ~2^-48 relative: lets the GPU subtract the eye
/// from an origin of 10^6–10^7 m without losing millimetres.
fn split(v: f64) -> (f32, f32) {
    let hi = v as f32;
    (hi, (v - hi as f64) as f32)
}

/// γ_i of eq. 3: (Σ_j h_j)² / h_i², with h the AABB half-diagonal; normalised so that the
/// typical pointlet gets γ ≈ 1 (only ratios matter: the LoD divides by Σl).
pub fn gammas(pointlets: &[PointletDesc]) -> Vec<f32> {
    let half: Vec<f64> = pointlets.iter().map(|p| 0.5 * p.aabb.diagonal()).collect();
    let sum: f64 = half.iter().sum();
    let n = half.len().max(1) as f64;
    half.iter()
        .map(|h| {
            if *h > 0.0 && sum > 0.0 {
                ((sum / n) * (sum / n) / (h * h)) as f32
            } else {
                1.0
            }
        })
        .collect()
}

/// Pointlets on each side whose spacings bound a pointlet's (neighbours in the store's Hilbert
/// order are neighbours in space).
const SPACING_NEIGHBOURS: usize = 8;
/// How far a pointlet's box spacing may exceed the median of its neighbours'.
const SPACING_OVER_NEIGHBOURS: f64 = 3.0;

/// Per pointlet, the factor (at most 1) that keeps its adaptive splats within
/// [`SPACING_OVER_NEIGHBOURS`] × the median box spacing of the pointlets around it. A box
/// spans its points only when they lie on one surface: a pointlet holding a few stray points
/// (noise above a scan, a far return) gets a box many times its surface's, and its points,
/// drawn as splats of that size, showed as squares of up to 32 pixels.
pub fn spacing_factors(pointlets: &[PointletDesc]) -> Vec<f32> {
    let own: Vec<f64> = pointlets
        .iter()
        .map(|p| box_spacing(p.aabb.extent(), p.count as u64))
        .collect();
    // ~130 ns a pointlet: on every core, as it delays a large store's first frame.
    (0..own.len())
        .into_par_iter()
        .map_init(Vec::new, |window, i| {
            window.clear();
            let lo = i.saturating_sub(SPACING_NEIGHBOURS);
            let hi = (i + SPACING_NEIGHBOURS + 1).min(own.len());
            window.extend(own[lo..hi].iter().filter(|s| **s > 0.0));
            if own[i] <= 0.0 || window.is_empty() {
                return 1.0;
            }
            let mid = window.len() / 2;
            let (_, median, _) = window.select_nth_unstable_by(mid, f64::total_cmp);
            (SPACING_OVER_NEIGHBOURS * *median / own[i]).min(1.0) as f32
        })
        .collect()
}

const READBACKS: usize = 3;
const FREE: u8 = 0;
const IN_FLIGHT: u8 = 1;
const READY: u8 = 2;

struct Readback {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
    frame: u64,
}

/// What the GPU LoD decided in one frame, read back to drive streaming.
#[derive(Clone, Debug, PartialEq)]
pub struct LodFeedback {
    /// The frame (see [`PagedCloud::frames`]) these values belong to.
    pub frame: u64,
    /// Points requested per pointlet (a prefix of its shuffled order).
    pub requested: Vec<u32>,
    /// Points of each pointlet now in the framebuffer: the end of the range drawn.
    pub drawn: Vec<u32>,
}

/// How a frame of a paged cloud is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PagedView {
    /// Point budget B of the LoD (the paper's bucket).
    pub bucket: f64,
    /// Keep the framebuffer and draw only points not drawn yet (camera still).
    pub accumulate: bool,
}

pub struct PagedCloud {
    pub encoding: PointEncoding,
    pub page_size: u32,
    /// Page-table entries per pointlet: ceil(largest pointlet / page size).
    pub max_pages: u32,
    pub slots: u32,
    pointlets: Vec<PointletDesc>,
    pub(crate) storage: PointStorage,
    pub(crate) frame_uniform: wgpu::Buffer,
    pub(crate) indirect: wgpu::Buffer,
    /// Draw arguments of the billboard quads per chunk (quads.rs): four u32 each.
    pub(crate) draw_args: wgpu::Buffer,
    pub(crate) entry_counts: wgpu::Buffer,
    lod_params: wgpu::Buffer,
    feedback: wgpu::Buffer,
    state: wgpu::Buffer,
    page_table: wgpu::Buffer,
    lod_group: wgpu::BindGroup,
    list_group: wgpu::BindGroup,
    importance: wgpu::ComputePipeline,
    total: wgpu::ComputePipeline,
    build: wgpu::ComputePipeline,
    finalize: wgpu::ComputePipeline,
    partial_count: u32,
    readbacks: Vec<Readback>,
    pending_map: Option<usize>,
    frame: u64,
    table_bytes: u64,
    uploads: UploadQueue,
    /// Packed uploads waiting for the next frame.
    pending: PageBatch,
    layout: Arc<BatchLayout>,
}

impl PagedCloud {
    /// GPU bytes of everything but the page pool, for `pointlets` pointlets.
    pub fn overhead_bytes(pointlets: &[PointletDesc], page_size: u32) -> u64 {
        let n = pointlets.len() as u64;
        let max_pages = Self::max_pages_for(pointlets, page_size) as u64;
        // pointlet table, importance(+partials), requested, infos, state, page table, readbacks
        n * (48 + 4 + 8 + 32 + 16 + 4 * max_pages + 8 * READBACKS as u64) + 4 * n / 256 + 4096
    }

    /// GPU bytes per page slot (pool plus its draw-list entry).
    pub fn slot_bytes(encoding: PointEncoding, page_size: u32) -> u64 {
        encoding.resident_bytes_per_point() * page_size as u64 + 16
    }

    fn max_pages_for(pointlets: &[PointletDesc], page_size: u32) -> u32 {
        pointlets
            .iter()
            .map(|p| p.count.div_ceil(page_size))
            .max()
            .unwrap_or(1)
            .max(1)
    }

    pub fn new(
        ctx: &GpuContext,
        pointlets: Vec<PointletDesc>,
        encoding: PointEncoding,
        page_size: u32,
        slots: u32,
    ) -> Result<Self, GpuError> {
        if pointlets.is_empty() {
            return Err(GpuError::InvalidInput("no pointlets to draw".into()));
        }
        if pointlets.iter().any(|p| {
            p.aabb.is_empty() || p.aabb.min.iter().chain(&p.aabb.max).any(|v| !v.is_finite())
        }) {
            return Err(GpuError::InvalidInput(
                "every pointlet needs a finite bounding box".into(),
            ));
        }
        // Pick ids are slot · page size + index: keep them within 32 bits.
        let slots = slots.clamp(1, u32::MAX / page_size.max(1));
        let n = pointlets.len() as u32;
        let max_pages = Self::max_pages_for(&pointlets, page_size);
        let device = &ctx.device;
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.checked("allocating the page tables", || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: size.max(16),
                    usage,
                    mapped_at_creation: false,
                })
            })
        };
        use wgpu::BufferUsages as U;
        let rw = U::STORAGE | U::COPY_DST;
        let partial_count = n.div_ceil(256);
        let frame_uniform = buffer(
            "frame",
            std::mem::size_of::<GpuFrame>() as u64,
            U::UNIFORM | U::COPY_DST,
        )?;
        let infos = buffer(
            "draw infos",
            n as u64 * std::mem::size_of::<GpuDrawInfo>() as u64,
            rw,
        )?;
        let entries = buffer(
            "draw entries",
            slots as u64 * std::mem::size_of::<GpuDrawEntry>() as u64,
            rw,
        )?;
        let chunks = PointStorage::chunk_count(ctx, encoding, page_size, slots);
        let chunk_slots = PointStorage::slots_per_chunk(ctx, encoding, page_size);
        let entry_counts = buffer("entry counts", chunks as u64 * 4, rw)?;
        let indirect = buffer(
            "indirect dispatch",
            chunks as u64 * 12,
            U::STORAGE | U::INDIRECT,
        )?;
        let draw_args = buffer(
            "indirect quad draws",
            chunks as u64 * 16,
            U::STORAGE | U::INDIRECT,
        )?;
        let offsets: Vec<u32> = (0..chunks).map(|c| c * chunk_slots).collect();
        let storage = PointStorage::new(
            ctx,
            encoding,
            page_size,
            slots,
            &DrawBuffers {
                frame: &frame_uniform,
                infos: &infos,
                entries: &entries,
                entry_counts: &entry_counts,
                list_offsets: &offsets,
            },
        )?;
        let gamma = gammas(&pointlets);
        let factors = spacing_factors(&pointlets);
        let table: Vec<GpuPointlet> = pointlets
            .iter()
            .zip(gamma.iter().zip(&factors))
            .map(|(p, (g, f))| {
                let s = p.aabb.min.map(split);
                GpuPointlet {
                    origin_hi: s.map(|v| v.0),
                    count: p.count,
                    origin_lo: s.map(|v| v.1),
                    gamma: *g,
                    extent: p.aabb.extent().map(|e| e as f32),
                    spacing_factor: *f,
                }
            })
            .collect();
        let pointlet_buf = buffer("pointlets", n as u64 * 48, U::STORAGE | U::COPY_DST)?;
        ctx.queue
            .write_buffer(&pointlet_buf, 0, bytemuck::cast_slice(&table));
        let importance = buffer("importance", (n + partial_count + 1) as u64 * 4, U::STORAGE)?;
        let feedback = buffer("lod feedback", n as u64 * 8, U::STORAGE | U::COPY_SRC)?;
        let state = buffer("residency", n as u64 * 16, rw)?;
        let page_table = buffer("page table", n as u64 * max_pages as u64 * 4, rw)?;
        let lod_params = buffer(
            "lod params",
            std::mem::size_of::<LodParams>() as u64,
            U::UNIFORM | U::COPY_DST,
        )?;
        let readbacks = (0..READBACKS)
            .map(|_| {
                Ok(Readback {
                    buffer: buffer("feedback readback", n as u64 * 8, U::MAP_READ | U::COPY_DST)?,
                    state: Arc::new(AtomicU8::new(FREE)),
                    frame: 0,
                })
            })
            .collect::<Result<Vec<_>, GpuError>>()?;
        let module = shaders::module(device, "lod", shaders::LOD);
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        let group0_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lod"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, read),
                entry(2, write),
                entry(3, write),
                entry(4, write),
                entry(5, write),
                entry(6, read),
                entry(7, write),
            ],
        });
        let group1_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("draw list"),
            entries: &[entry(0, write), entry(1, write), entry(2, write)],
        });
        // One layout for the four passes, so the same bind groups serve them all.
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lod"),
            bind_group_layouts: &[Some(&group0_layout), Some(&group1_layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let (importance_p, total_p, build_p, finalize_p) =
            ctx.checked("building the LoD pass", || {
                (
                    pipeline("importance_pass"),
                    pipeline("total_pass"),
                    pipeline("build_pass"),
                    pipeline("finalize_pass"),
                )
            })?;
        let lod_group = storage_group(
            device,
            "lod",
            &group0_layout,
            &[
                &lod_params,
                &pointlet_buf,
                &importance,
                &feedback,
                &infos,
                &state,
                &page_table,
                &entries,
            ],
        );
        let list_group = storage_group(
            device,
            "lod",
            &group1_layout,
            &[&entry_counts, &indirect, &draw_args],
        );
        let uploads = UploadQueue::new(ctx)?;
        let layout = Arc::new(BatchLayout {
            words: (encoding.position_bytes() / 4) as usize,
            compact: encoding == PointEncoding::Compact8,
            page_size,
            slots_per_chunk: storage.slots_per_chunk,
            chunks: storage.chunks.len(),
            max_pages,
            encoding,
            boxes: pointlets.iter().map(|p| p.aabb).collect(),
        });
        let table_bytes = infos.size()
            + entries.size()
            + pointlet_buf.size()
            + importance.size()
            + feedback.size()
            + state.size()
            + page_table.size()
            + READBACKS as u64 * n as u64 * 8;
        Ok(Self {
            encoding,
            page_size,
            max_pages,
            slots,
            pointlets,
            storage,
            frame_uniform,
            indirect,
            draw_args,
            entry_counts,
            lod_params,
            feedback,
            state,
            page_table,
            lod_group,
            list_group,
            importance: importance_p,
            total: total_p,
            build: build_p,
            finalize: finalize_p,
            partial_count,
            readbacks,
            pending_map: None,
            frame: 0,
            table_bytes,
            uploads,
            pending: PageBatch::new(Arc::clone(&layout)),
            layout,
        })
    }

    pub fn pointlets(&self) -> &[PointletDesc] {
        &self.pointlets
    }

    /// GPU bytes allocated: the page pool plus every table.
    pub fn gpu_bytes(&self) -> u64 {
        self.storage.bytes() + self.table_bytes
    }

    /// Queues point runs for their page slots (each run inside one page); they reach the GPU
    /// with the next frame, in one batch.
    pub fn write_pages(&mut self, pages: &[PageWrite<'_>]) {
        self.pending.write_pages(pages);
    }

    /// Queues `jobs`, each encoded by `fill(k, sink)` (in parallel); returns the points each
    /// delivered.
    pub fn write_jobs(
        &mut self,
        jobs: &[PageJob],
        fill: impl Fn(usize, &mut PageSink<'_>) + Sync,
    ) -> Vec<u32> {
        self.pending.write_jobs(jobs, fill)
    }

    /// Publishes (with the next frame) that points `lo..hi` of `pointlet` are resident, page j
    /// (from lo / page size) in `slots[j - lo / page size]`.
    pub fn set_residency(&mut self, pointlet: u32, lo: u32, hi: u32, slots: &[u32]) {
        self.pending.set_state(pointlet, lo, hi);
        let first = lo / self.page_size;
        for (k, slot) in slots.iter().enumerate() {
            self.pending.set_page(pointlet, first + k as u32, *slot);
        }
    }

    /// An empty batch to pack uploads into on another thread.
    pub fn new_batch(&self) -> PageBatch {
        PageBatch::new(Arc::clone(&self.layout))
    }

    /// Queues a batch packed elsewhere for the next frame (after anything queued before);
    /// returns an empty batch for reuse.
    pub fn submit(&mut self, mut batch: PageBatch) -> PageBatch {
        if self.pending.is_empty() {
            std::mem::swap(&mut self.pending, &mut batch);
            batch
        } else {
            self.pending.append(batch);
            self.new_batch()
        }
    }

    /// Records the LoD and draw-list passes of a frame (and the copy of the requests).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record_lod(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        camera: &Camera,
        (width, height): (u32, u32),
        view: &PagedView,
        settings: &RenderSettings,
        queries: Option<&wgpu::QuerySet>,
    ) -> Result<(), GpuError> {
        // Timestamps: LoD at 0/1, uploads at 6/7 (raster and screen use 2–5).
        let stamps = |begin: u32| {
            queries.map(|q| wgpu::ComputePassTimestampWrites {
                query_set: q,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        self.uploads.flush(
            ctx,
            enc,
            &mut self.pending,
            &self.storage,
            &self.page_table,
            &self.state,
            stamps(6),
        )?;
        let timestamps = stamps(0);
        write_frame(ctx, &self.frame_uniform, camera, (width, height), settings);
        let eye = camera.eye.map(split);
        let params = LodParams {
            view_proj: pointlet_core::camera::to_f32(
                &camera.relative_view_projection(width as f64 / height.max(1) as f64),
            ),
            eye_hi: eye.map(|v| v.0),
            pointlet_count: self.pointlets.len() as u32,
            eye_lo: eye.map(|v| v.1),
            bucket: view.bucket as f32,
            viewport: [width as f32, height as f32],
            focal_px: camera.focal_px(height) as f32,
            compact: (self.encoding == PointEncoding::Compact8) as u32,
            accumulate: view.accumulate as u32,
            page_size: self.page_size,
            max_pages: self.max_pages,
            chunk_slots: self.storage.slots_per_chunk,
            chunk_count: self.storage.chunks.len() as u32,
            partial_count: self.partial_count,
            cull_margin_px: settings.splats.reach_px(),
            _pad: 0,
        };
        ctx.queue
            .write_buffer(&self.lod_params, 0, bytemuck::bytes_of(&params));
        enc.clear_buffer(&self.entry_counts, 0, None);
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lod"),
                timestamp_writes: timestamps,
            });
            pass.set_bind_group(0, &self.lod_group, &[]);
            pass.set_bind_group(1, &self.list_group, &[]);
            let groups = self.partial_count;
            pass.set_pipeline(&self.importance);
            pass.dispatch_workgroups(groups, 1, 1);
            pass.set_pipeline(&self.total);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&self.build);
            pass.dispatch_workgroups(groups, 1, 1);
            pass.set_pipeline(&self.finalize);
            pass.dispatch_workgroups(self.storage.chunks.len().div_ceil(64) as u32, 1, 1);
        }
        self.frame += 1;
        self.pending_map = None;
        if let Some(k) = self
            .readbacks
            .iter()
            .position(|r| r.state.load(Ordering::Acquire) == FREE)
        {
            let r = &mut self.readbacks[k];
            // Buffers are at least 16 bytes: copy and map only the feedback's 2n words.
            let bytes = self.pointlets.len() as u64 * 8;
            enc.copy_buffer_to_buffer(&self.feedback, 0, &r.buffer, 0, bytes);
            r.state.store(IN_FLIGHT, Ordering::Release);
            r.frame = self.frame;
            self.pending_map = Some(k);
        }
        Ok(())
    }

    /// Call after the frame's submission: starts mapping the requests copied this frame.
    pub(crate) fn after_submit(&mut self) {
        if let Some(k) = self.pending_map.take() {
            let r = &self.readbacks[k];
            let state = r.state.clone();
            r.buffer.slice(..self.pointlets.len() as u64 * 8).map_async(
                wgpu::MapMode::Read,
                move |result| {
                    state.store(if result.is_ok() { READY } else { FREE }, Ordering::Release);
                },
            );
        }
    }

    /// The most recent LoD feedback that has arrived on the CPU, never blocking.
    pub fn poll_feedback(&mut self, ctx: &GpuContext) -> Option<LodFeedback> {
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        let n = self.pointlets.len();
        let mut newest: Option<LodFeedback> = None;
        for r in &mut self.readbacks {
            if r.state.load(Ordering::Acquire) != READY {
                continue;
            }
            let data = r
                .buffer
                .slice(..n as u64 * 8)
                .get_mapped_range()
                .ok()
                .map(|v| bytemuck::pod_collect_to_vec::<u8, u32>(&v));
            r.buffer.unmap();
            r.state.store(FREE, Ordering::Release);
            if let Some(mut d) = data {
                if d.len() == 2 * n && newest.as_ref().is_none_or(|f| f.frame < r.frame) {
                    let drawn = d.split_off(n);
                    newest = Some(LodFeedback {
                        frame: r.frame,
                        requested: d,
                        drawn,
                    });
                }
            }
        }
        newest
    }

    /// Frames submitted so far (the numbering [`LodFeedback::frame`] uses).
    pub fn frames(&self) -> u64 {
        self.frame
    }

    /// Like [`poll_feedback`](Self::poll_feedback) but waits for the last frame's (tests, tools,
    /// benchmarks — never the render loop).
    pub fn wait_feedback(&mut self, ctx: &GpuContext) -> Result<LodFeedback, GpuError> {
        ctx.wait()?;
        self.poll_feedback(ctx)
            .ok_or_else(|| GpuError::Device("the LoD feedback did not arrive".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(x: f64, side: f64, height: f64, count: u32) -> PointletDesc {
        PointletDesc {
            aabb: Aabb {
                min: [x, 0.0, 0.0],
                max: [x + side, side, height],
            },
            count,
        }
    }

    #[test]
    fn a_pointlet_boxed_by_stray_points_draws_near_its_neighbours_spacing() {
        // A row of 10 m tiles of 400 points (spacing 0.5 m); tile 10 also holds a point 200 m
        // up, which stretches its box (and its box spacing) twentyfold.
        let mut row: Vec<_> = (0..21)
            .map(|i| tile(10.0 * i as f64, 10.0, 0.1, 400))
            .collect();
        row[10] = tile(100.0, 10.0, 200.0, 400);
        let f = spacing_factors(&row);
        assert!(f.iter().enumerate().all(|(i, &f)| i == 10 || f == 1.0));
        let own = box_spacing(row[10].aabb.extent(), 400);
        assert!((own - 0.5 * 20f64.sqrt()).abs() < 1e-9, "{own}");
        let drawn = own * f[10] as f64;
        assert!(
            (drawn - SPACING_OVER_NEIGHBOURS * 0.5).abs() < 1e-6,
            "{drawn}"
        );
    }

    #[test]
    fn sparse_regions_keep_their_spacing_where_their_neighbours_are_as_sparse() {
        // Density falling away from a terrestrial scanner: each tile twice as sparse as the
        // last, so every tile's spacing is within a few times its neighbours'.
        let row: Vec<_> = (0..12)
            .map(|i| tile(10.0 * i as f64, 10.0, 0.1, 4096 >> i))
            .collect();
        let f = spacing_factors(&row);
        assert!(f[..8].iter().all(|&f| f == 1.0), "{f:?}");
        // Empty and single-point boxes are left alone.
        let degenerate = [tile(0.0, 0.0, 0.0, 1), tile(5.0, 10.0, 0.1, 0)];
        assert_eq!(spacing_factors(&degenerate), vec![1.0, 1.0]);
    }
}
