//! Batched uploads for paged clouds: a frame's new pages and table changes are packed on the
//! CPU (encoding in parallel) and applied on the GPU by two small scatter passes
//! (upload.wgsl, tables.wgsl), so a frame costs a few buffer writes whatever changed.

use crate::context::GpuContext;
use crate::raster::{grid, storage_group};
use crate::shaders;
use crate::storage::{compact_step, encode_point, PointEncoding, PointStorage};
use crate::GpuError;
use bytemuck::{Pod, Zeroable};
use pointlet_core::Aabb;
use rayon::prelude::*;
use std::sync::Arc;

/// Points `first_point..` of a pointlet (absolute coordinates) going into one page slot; the
/// run must stay inside the page.
pub struct PageWrite<'a> {
    pub pointlet: u32,
    pub slot: u32,
    pub first_point: u32,
    pub positions: &'a [[f64; 3]],
    pub colors: &'a [u32],
}

/// A page run to fill (see [`UploadQueue::write_jobs`]): `count` points from `first_point`
/// of `pointlet` into `slot`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PageJob {
    pub pointlet: u32,
    pub slot: u32,
    pub first_point: u32,
    pub count: u32,
}

/// Where one job's points go: its slices of the staging streams. Fill it once.
pub struct PageSink<'a> {
    positions: &'a mut [u32],
    fine: &'a mut [u32],
    colors: &'a mut [u32],
    origin: [f64; 3],
    step: [f64; 3],
    encoding: PointEncoding,
    written: u32,
}

impl PageSink<'_> {
    /// Encodes absolute positions (at most the job's count).
    pub fn put(&mut self, positions: &[[f64; 3]], colors: &[u32]) {
        let (o, st, e) = (self.origin, self.step, self.encoding);
        let words: Vec<[u32; 3]> = positions
            .iter()
            .map(|p| encode_point(*p, o, st, e))
            .collect();
        self.put_words(&words, colors);
    }

    /// Copies points already encoded by [`encode_point`] (e.g. by loader threads).
    pub fn put_words(&mut self, words: &[[u32; 3]], colors: &[u32]) {
        let n = words.len().min(colors.len()).min(self.colors.len());
        match self.encoding {
            PointEncoding::Full16 => {
                for (out, w) in self.positions.chunks_exact_mut(3).zip(&words[..n]) {
                    out.copy_from_slice(w);
                }
            }
            PointEncoding::Compact8 => {
                let out = self.positions.iter_mut().zip(self.fine.iter_mut());
                for ((p, f), w) in out.zip(&words[..n]) {
                    *p = w[0];
                    *f = w[1];
                }
            }
        }
        self.colors[..n].copy_from_slice(&colors[..n]);
        self.written = n as u32;
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Run {
    dst: u32,
    src: u32,
    count: u32,
    flags: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ChunkRuns {
    offset: u32,
    count: u32,
    words: u32,
    has_fine: u32,
}

const COLORS_ONLY: u32 = 1;

/// A frame's new pages, recoloured runs and table changes, packed on the CPU (on any thread;
/// encoding in parallel) and handed to [`PagedCloud::submit`](crate::PagedCloud::submit).
pub struct PageBatch {
    layout: Arc<BatchLayout>,
    positions: Vec<u32>,
    fine: Vec<u32>,
    colors: Vec<u32>,
    runs: Vec<Vec<Run>>,
    page_updates: Vec<[u32; 2]>,
    state_updates: Vec<[u32; 4]>,
}

/// What packing needs to know of the pool: fixed for a cloud's life.
pub(crate) struct BatchLayout {
    pub words: usize,
    pub compact: bool,
    pub page_size: u32,
    pub slots_per_chunk: u32,
    pub chunks: usize,
    pub max_pages: u32,
    pub encoding: PointEncoding,
    pub boxes: Vec<Aabb>,
}

/// GPU side of the uploads: staging buffers (grown on demand) and the scatter passes.
pub(crate) struct UploadQueue {
    capacity_points: u64,
    capacity_runs: u64,
    capacity_updates: u64,
    staging: Option<Staging>,
    scatter: wgpu::ComputePipeline,
    tables: wgpu::ComputePipeline,
}

struct Staging {
    positions: wgpu::Buffer,
    fine: wgpu::Buffer,
    colors: wgpu::Buffer,
    runs: wgpu::Buffer,
    chunk_uniforms: Vec<wgpu::Buffer>,
    chunk_groups: Vec<wgpu::BindGroup>,
    page_updates: wgpu::Buffer,
    state_updates: wgpu::Buffer,
    counts: wgpu::Buffer,
    tables_group: wgpu::BindGroup,
}

impl PageBatch {
    pub(crate) fn new(layout: Arc<BatchLayout>) -> Self {
        let chunks = layout.chunks;
        Self {
            layout,
            positions: Vec::new(),
            fine: Vec::new(),
            colors: Vec::new(),
            runs: vec![Vec::new(); chunks],
            page_updates: Vec::new(),
            state_updates: Vec::new(),
        }
    }

    /// Nothing packed.
    pub fn is_empty(&self) -> bool {
        self.colors.is_empty()
            && self.runs.iter().all(Vec::is_empty)
            && self.page_updates.is_empty()
            && self.state_updates.is_empty()
    }

    /// Appends `later` (packed after this batch): its runs read behind this batch's points.
    pub(crate) fn append(&mut self, later: PageBatch) {
        let base = self.colors.len() as u32;
        self.positions.extend_from_slice(&later.positions);
        self.fine.extend_from_slice(&later.fine);
        self.colors.extend_from_slice(&later.colors);
        for (mine, theirs) in self.runs.iter_mut().zip(later.runs) {
            mine.extend(theirs.into_iter().map(|r| Run {
                src: r.src + base,
                ..r
            }));
        }
        self.page_updates.extend_from_slice(&later.page_updates);
        self.state_updates.extend_from_slice(&later.state_updates);
    }

    fn clear(&mut self) {
        self.positions.clear();
        self.fine.clear();
        self.colors.clear();
        self.runs.iter_mut().for_each(Vec::clear);
        self.page_updates.clear();
        self.state_updates.clear();
    }

    fn dst(&self, slot: u32, first_point: u32) -> (usize, u32) {
        let l = &self.layout;
        let chunk = (slot / l.slots_per_chunk) as usize;
        let in_chunk = (slot % l.slots_per_chunk) * l.page_size + first_point % l.page_size;
        (chunk, in_chunk)
    }

    /// Packs pages for the next flush, encoding them in parallel.
    pub fn write_pages(&mut self, pages: &[PageWrite<'_>]) {
        let jobs: Vec<PageJob> = pages
            .iter()
            .map(|p| PageJob {
                pointlet: p.pointlet,
                slot: p.slot,
                first_point: p.first_point,
                count: p.positions.len().min(p.colors.len()) as u32,
            })
            .collect();
        self.write_jobs(&jobs, |k, sink| {
            sink.put(pages[k].positions, pages[k].colors)
        });
    }

    /// Reserves staging for `jobs` and lets `fill(k, sink)` encode job k's points, all jobs in
    /// parallel. Returns the points each job wrote (a fill may deliver fewer than asked).
    pub fn write_jobs(
        &mut self,
        jobs: &[PageJob],
        fill: impl Fn(usize, &mut PageSink<'_>) + Sync,
    ) -> Vec<u32> {
        let base = self.colors.len();
        let total: usize = jobs.iter().map(|j| j.count as usize).sum();
        let layout = Arc::clone(&self.layout);
        let (words, boxes, encoding) = (layout.words, &layout.boxes, layout.encoding);
        self.positions
            .resize(self.positions.len() + total * words, 0);
        let compact = layout.compact;
        if compact {
            self.fine.resize(self.fine.len() + total, 0);
        }
        self.colors.resize(base + total, 0);
        // Disjoint output slices, one per job.
        let mut pos_rest = &mut self.positions[base * words..];
        let mut fine_rest: &mut [u32] = if compact {
            &mut self.fine[base..]
        } else {
            &mut []
        };
        let mut col_rest = &mut self.colors[base..];
        let mut sinks = Vec::with_capacity(jobs.len());
        for job in jobs {
            let n = job.count as usize;
            let (p, r) = std::mem::take(&mut pos_rest).split_at_mut(n * words);
            pos_rest = r;
            let f = if compact {
                let (f, r) = std::mem::take(&mut fine_rest).split_at_mut(n);
                fine_rest = r;
                f
            } else {
                &mut []
            };
            let (c, r) = std::mem::take(&mut col_rest).split_at_mut(n);
            col_rest = r;
            let b = boxes.get(job.pointlet as usize).copied().unwrap_or(Aabb {
                min: [0.0; 3],
                max: [0.0; 3],
            });
            sinks.push(PageSink {
                positions: p,
                fine: f,
                colors: c,
                origin: b.min,
                step: compact_step(b.extent()),
                encoding,
                written: 0,
            });
        }
        let written: Vec<u32> = sinks
            .into_par_iter()
            .enumerate()
            .map(|(k, mut sink)| {
                fill(k, &mut sink);
                sink.written
            })
            .collect();
        let mut src = base as u32;
        for (job, n) in jobs.iter().zip(&written) {
            let (chunk, dst) = self.dst(job.slot, job.first_point);
            if *n > 0 {
                if let Some(list) = self.runs.get_mut(chunk) {
                    list.push(Run {
                        dst,
                        src,
                        count: *n,
                        flags: 0,
                    });
                }
            }
            src += job.count;
        }
        written
    }

    /// Queues new colours (recolouring: positions stay) for points `first_point..` of `slot` (positions stay).
    pub fn write_colors(&mut self, slot: u32, first_point: u32, colors: &[u32]) {
        let src = self.colors.len() as u32;
        self.colors.extend_from_slice(colors);
        // Keep the streams aligned point for point: the run reads colours only.
        self.positions
            .resize(self.colors.len() * self.layout.words, 0);
        if self.layout.compact {
            self.fine.resize(self.colors.len(), 0);
        }
        let (chunk, dst) = self.dst(slot, first_point);
        if let Some(list) = self.runs.get_mut(chunk) {
            list.push(Run {
                dst,
                src,
                count: colors.len() as u32,
                flags: COLORS_ONLY,
            });
        }
    }

    /// Publishes (with the frame that flushes this batch) that page `page` of `pointlet` lives
    /// in `slot`.
    pub fn set_page(&mut self, pointlet: u32, page: u32, slot: u32) {
        let index = pointlet * self.layout.max_pages + page;
        self.page_updates.push([index, slot]);
    }

    /// Publishes that points `lo..hi` of `pointlet` are resident (their pages published with
    /// [`set_page`](Self::set_page)).
    pub fn set_state(&mut self, pointlet: u32, lo: u32, hi: u32) {
        self.state_updates.push([pointlet, lo, hi, 0]);
    }
}

impl UploadQueue {
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let (scatter, tables) = ctx.checked("building the upload passes", || {
            let pipeline = |label: &str, source: &str, entry: &str| {
                let module = shaders::module(device, label, source);
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: None,
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            (
                pipeline("upload", shaders::UPLOAD, "scatter"),
                pipeline("tables", shaders::TABLES, "apply"),
            )
        })?;
        Ok(Self {
            capacity_points: 0,
            capacity_runs: 0,
            capacity_updates: 0,
            staging: None,
            scatter,
            tables,
        })
    }

    fn ensure_capacity(
        &mut self,
        ctx: &GpuContext,
        batch: &PageBatch,
        storage: &PointStorage,
        page_table: &wgpu::Buffer,
        state: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let points = batch.colors.len() as u64;
        let runs: u64 = batch.runs.iter().map(|r| r.len() as u64).sum();
        let updates = batch.page_updates.len().max(batch.state_updates.len()) as u64;
        let (words, compact) = (batch.layout.words, batch.layout.compact);
        if self.staging.is_some()
            && points <= self.capacity_points
            && runs <= self.capacity_runs
            && updates <= self.capacity_updates
        {
            return Ok(());
        }
        self.capacity_points = points.max(self.capacity_points * 2).max(1 << 16);
        self.capacity_runs = runs.max(self.capacity_runs * 2).max(1 << 10);
        self.capacity_updates = updates.max(self.capacity_updates * 2).max(1 << 10);
        let device = &ctx.device;
        let buffer = |label: &str, bytes: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let s = wgpu::BufferUsages::STORAGE;
        let cap = self.capacity_points;
        let staging = ctx.checked("allocating upload staging", || {
            let positions = buffer("upload positions", cap * words as u64 * 4, s);
            let fine = buffer("upload fine", if compact { cap * 4 } else { 16 }, s);
            let colors = buffer("upload colours", cap * 4, s);
            let runs = buffer("upload runs", self.capacity_runs * 16, s);
            let page_updates = buffer("page updates", self.capacity_updates * 8, s);
            let state_updates = buffer("state updates", self.capacity_updates * 16, s);
            let counts = buffer("update counts", 16, wgpu::BufferUsages::UNIFORM);
            let chunk_uniforms: Vec<wgpu::Buffer> = storage
                .chunks
                .iter()
                .map(|_| buffer("chunk runs", 16, wgpu::BufferUsages::UNIFORM))
                .collect();
            // WebGPU refuses a buffer bound twice when one binding is writable: encodings without
            // a fine stream get a placeholder the shader never writes.
            let no_fine = buffer("no fine stream", 16, s);
            let layout = self.scatter.get_bind_group_layout(0);
            let chunk_groups = storage
                .chunks
                .iter()
                .zip(&chunk_uniforms)
                .map(|(c, u)| {
                    let fine_dst = c.fine.as_ref().unwrap_or(&no_fine);
                    let buffers = [
                        u,
                        &runs,
                        &positions,
                        &fine,
                        &colors,
                        &c.positions,
                        fine_dst,
                        &c.colors,
                    ];
                    storage_group(device, "uploads", &layout, &buffers)
                })
                .collect();
            let tables_group = storage_group(
                device,
                "tables",
                &self.tables.get_bind_group_layout(0),
                &[&counts, &page_updates, &state_updates, page_table, state],
            );
            Staging {
                positions,
                fine,
                colors,
                runs,
                chunk_uniforms,
                chunk_groups,
                page_updates,
                state_updates,
                counts,
                tables_group,
            }
        })?;
        self.staging = Some(staging);
        Ok(())
    }

    /// Uploads `batch` and records the scatter passes into `enc` (before anything that reads
    /// the pool or the tables this frame); leaves `batch` empty.
    #[allow(clippy::too_many_arguments)]
    pub fn flush(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        batch: &mut PageBatch,
        storage: &PointStorage,
        page_table: &wgpu::Buffer,
        state: &wgpu::Buffer,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), GpuError> {
        let has_runs = batch.runs.iter().any(|r| !r.is_empty());
        if !has_runs && batch.page_updates.is_empty() && batch.state_updates.is_empty() {
            // An empty pass still writes the frame's upload timestamps.
            if timestamps.is_some() {
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("uploads"),
                    timestamp_writes: timestamps,
                });
            }
            return Ok(());
        }
        self.ensure_capacity(ctx, batch, storage, page_table, state)?;
        let Some(st) = &self.staging else {
            return Ok(());
        };
        let q = &ctx.queue;
        let mut all_runs = Vec::new();
        let mut offsets = Vec::new();
        for list in &batch.runs {
            offsets.push((all_runs.len() as u32, list.len() as u32));
            all_runs.extend_from_slice(list);
        }
        if has_runs {
            q.write_buffer(&st.positions, 0, bytemuck::cast_slice(&batch.positions));
            if batch.layout.compact {
                q.write_buffer(&st.fine, 0, bytemuck::cast_slice(&batch.fine));
            }
            q.write_buffer(&st.colors, 0, bytemuck::cast_slice(&batch.colors));
            q.write_buffer(&st.runs, 0, bytemuck::cast_slice(&all_runs));
            for ((offset, count), u) in offsets.iter().zip(&st.chunk_uniforms) {
                let c = ChunkRuns {
                    offset: *offset,
                    count: *count,
                    words: batch.layout.words as u32,
                    has_fine: batch.layout.compact as u32,
                };
                q.write_buffer(u, 0, bytemuck::bytes_of(&c));
            }
        }
        let n_updates = batch.page_updates.len().max(batch.state_updates.len()) as u32;
        if n_updates > 0 {
            q.write_buffer(
                &st.page_updates,
                0,
                bytemuck::cast_slice(&batch.page_updates),
            );
            q.write_buffer(
                &st.state_updates,
                0,
                bytemuck::cast_slice(&batch.state_updates),
            );
            let counts = [
                batch.page_updates.len() as u32,
                batch.state_updates.len() as u32,
                0,
                0,
            ];
            q.write_buffer(&st.counts, 0, bytemuck::cast_slice(&counts));
        }
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("uploads"),
                timestamp_writes: timestamps,
            });
            if has_runs {
                pass.set_pipeline(&self.scatter);
                for ((_, count), g) in offsets.iter().zip(&st.chunk_groups) {
                    if *count > 0 {
                        pass.set_bind_group(0, g, &[]);
                        let [x, y] = grid(*count);
                        pass.dispatch_workgroups(x, y, 1);
                    }
                }
            }
            if n_updates > 0 {
                pass.set_pipeline(&self.tables);
                pass.set_bind_group(0, &st.tables_group, &[]);
                let [x, y] = grid(n_updates.div_ceil(256));
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        batch.clear();
        Ok(())
    }
}
