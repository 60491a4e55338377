//! A static point cloud on the GPU: all points uploaded once in their given order, cut into
//! pages of consecutive points (the raster benchmark and in-core rendering).
//!
//! Each page's origin (its AABB minimum) stays in f64 on the CPU; every frame
//! [`GpuCloud::prepare`] writes each origin minus the eye in f32, so shaders only see
//! camera-relative coordinates.

use crate::context::GpuContext;
use crate::renderer::RenderSettings;
use crate::storage::{
    check_page_size, compact_step, encode_positions, needs_fine, DrawBuffers, GpuDrawEntry,
    GpuDrawInfo, GpuFrame, PointEncoding, PointStorage,
};
use crate::GpuError;
use pointlet_core::{Aabb, Camera};
use rayon::prelude::*;

/// Points as the CPU hands them over: data coordinates in f64 and RGBA8 colours (red in the
/// low byte).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointSet {
    pub positions: Vec<[f64; 3]>,
    pub colors: Vec<u32>,
}

impl PointSet {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in &self.positions {
            b.grow(*p);
        }
        b
    }
}

/// CPU-side description of one page.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PageMeta {
    pub origin: [f64; 3],
    pub extent: [f64; 3],
    pub count: u32,
}

impl PageMeta {
    pub fn step(&self) -> [f64; 3] {
        compact_step(self.extent)
    }

    pub fn needs_fine(&self, eye: [f64; 3], focal_px: f64) -> bool {
        needs_fine(self.origin, self.extent, eye, focal_px)
    }
}

/// A point cloud uploaded to the GPU.
pub struct GpuCloud {
    pub encoding: PointEncoding,
    pub page_size: u32,
    pub points: u64,
    pub bounds: Aabb,
    pages: Vec<PageMeta>,
    pub(crate) storage: PointStorage,
    infos: wgpu::Buffer,
    pub(crate) frame_uniform: wgpu::Buffer,
    _entries: wgpu::Buffer,
    _entry_counts: wgpu::Buffer,
    staging: Vec<GpuDrawInfo>,
    fine_points: u64,
    /// Surface spacing of the whole cloud, for adaptive splats.
    spacing: f64,
}

/// Bytes encoded and written per upload step: bounds the staging memory of huge uploads.
const UPLOAD_SLICE_BYTES: u64 = 64 << 20;

impl GpuCloud {
    /// Uploads `set` in its current order: pages are consecutive runs of `page_size` points.
    pub fn upload(
        ctx: &GpuContext,
        set: &PointSet,
        encoding: PointEncoding,
        page_size: u32,
    ) -> Result<Self, GpuError> {
        if set.positions.len() != set.colors.len() {
            return Err(GpuError::InvalidInput(format!(
                "{} positions but {} colours",
                set.positions.len(),
                set.colors.len()
            )));
        }
        check_page_size(page_size)?;
        if set.positions.iter().flatten().any(|v| !v.is_finite()) {
            return Err(GpuError::InvalidInput(
                "point positions must be finite".into(),
            ));
        }
        let n = set.positions.len();
        if n as u64 >= u32::MAX as u64 - page_size as u64 {
            return Err(GpuError::InvalidInput(format!(
                "{n} points: a static cloud holds fewer than 2^32 (use a store: it streams)"
            )));
        }
        let ps = page_size as usize;
        let pages: Vec<PageMeta> = set
            .positions
            .par_chunks(ps)
            .map(|chunk| {
                let mut b = Aabb::EMPTY;
                for p in chunk {
                    b.grow(*p);
                }
                PageMeta {
                    origin: b.min,
                    extent: b.extent(),
                    count: chunk.len() as u32,
                }
            })
            .collect();
        let page_count = u32::try_from(pages.len())
            .map_err(|_| GpuError::InvalidInput(format!("{n} points: too many pages")))?;
        let device = &ctx.device;
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.checked("allocating draw lists", || {
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
            "draw infos",
            pages.len() as u64 * std::mem::size_of::<GpuDrawInfo>() as u64,
            storage_usage,
        )?;
        let entries = buffer(
            "draw entries",
            pages.len() as u64 * std::mem::size_of::<GpuDrawEntry>() as u64,
            storage_usage,
        )?;
        // Pages are listed in slot order, one entry each, so every chunk draws all its pages.
        let list: Vec<GpuDrawEntry> = pages
            .iter()
            .enumerate()
            .map(|(k, p)| GpuDrawEntry {
                slot: k as u32,
                info: k as u32,
                first: 0,
                count: p.count,
            })
            .collect();
        ctx.queue
            .write_buffer(&entries, 0, bytemuck::cast_slice(&list));
        let chunks = PointStorage::chunk_count(ctx, encoding, page_size, page_count);
        let per_chunk = PointStorage::slots_per_chunk(ctx, encoding, page_size);
        let counts: Vec<u32> = (0..chunks)
            .map(|c| (page_count - c * per_chunk).min(per_chunk))
            .collect();
        let offsets: Vec<u32> = (0..chunks).map(|c| c * per_chunk).collect();
        let entry_counts = buffer("entry counts", chunks as u64 * 4, storage_usage)?;
        ctx.queue
            .write_buffer(&entry_counts, 0, bytemuck::cast_slice(&counts));
        let frame_uniform = buffer(
            "frame",
            std::mem::size_of::<GpuFrame>() as u64,
            wgpu::BufferUsages::UNIFORM,
        )?;
        let storage = PointStorage::new(
            ctx,
            encoding,
            page_size,
            page_count,
            &DrawBuffers {
                frame: &frame_uniform,
                infos: &infos,
                entries: &entries,
                entry_counts: &entry_counts,
                list_offsets: &offsets,
            },
        )?;
        // Encode and write runs of whole pages that stay inside one chunk.
        let slice_pages = (UPLOAD_SLICE_BYTES
            / (encoding.resident_bytes_per_point() * page_size as u64))
            .max(1) as u32;
        let mut first = 0u32;
        while first < page_count {
            let chunk_end = (first / per_chunk + 1) * per_chunk;
            let end = (first + slice_pages).min(page_count).min(chunk_end);
            let (main, fine, colors) = encode_page_run(set, &pages, first, end, ps, encoding);
            storage.write(&ctx.queue, first, 0, &main, &fine, &colors);
            // Hand the staged bytes to the GPU before encoding more (bounded staging memory).
            ctx.queue.submit([]);
            ctx.wait()?;
            first = end;
        }
        Ok(Self {
            encoding,
            page_size,
            points: n as u64,
            bounds: set.bounds(),
            staging: vec![GpuDrawInfo::default(); pages.len()],
            pages,
            storage,
            infos,
            frame_uniform,
            _entries: entries,
            _entry_counts: entry_counts,
            fine_points: 0,
            spacing: pointlet_core::density::cloud_spacing(&set.positions, n as u64, 1 << 20)
                .unwrap_or(0.0),
        })
    }

    /// GPU memory held by point data, in bytes.
    pub fn point_bytes(&self) -> u64 {
        self.storage.bytes()
    }

    /// Points whose fine position word the last prepared frame reads (compact encoding).
    pub fn fine_points(&self) -> u64 {
        self.fine_points
    }

    pub fn page_metas(&self) -> &[PageMeta] {
        &self.pages
    }

    /// Surface spacing adaptive splats are sized from (1/√density; measured at upload).
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Overrides the measured spacing (when the cloud stands for more points than it holds).
    pub fn set_spacing(&mut self, spacing: f64) {
        self.spacing = spacing;
    }

    /// Replaces every colour (same points, same order: e.g. another attribute to colour by);
    /// only the colour stream is uploaded.
    pub fn recolor(&self, ctx: &GpuContext, colors: &[u32]) -> Result<(), GpuError> {
        if colors.len() as u64 != self.points {
            return Err(GpuError::InvalidInput(format!(
                "{} colours for {} points",
                colors.len(),
                self.points
            )));
        }
        let ps = self.page_size as usize;
        let slice_pages = (UPLOAD_SLICE_BYTES / (4 * ps as u64)).max(1) as usize;
        let per_chunk = self.storage.slots_per_chunk as usize;
        let mut first = 0usize;
        while first < self.pages.len() {
            let end = (first + slice_pages)
                .min(self.pages.len())
                .min((first / per_chunk + 1) * per_chunk);
            let padded = page_colors(colors, &self.pages, first as u32, end as u32, ps);
            self.storage
                .write_colors(&ctx.queue, first as u32, 0, &padded);
            ctx.queue.submit([]);
            first = end;
        }
        Ok(())
    }

    /// Writes this frame's camera-relative page origins and the frame uniform.
    pub fn prepare(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        size: (u32, u32),
        settings: &RenderSettings,
    ) {
        let height = size.1;
        let spacing = self.spacing as f32;
        let focal_px = camera.focal_px(height);
        let eye = camera.eye;
        let compact = self.encoding == PointEncoding::Compact8;
        self.staging
            .par_iter_mut()
            .zip(self.pages.par_iter())
            .for_each(|(g, p)| {
                *g = GpuDrawInfo {
                    origin: [0, 1, 2].map(|a| (p.origin[a] - eye[a]) as f32),
                    flags: (compact && p.needs_fine(eye, focal_px)) as u32,
                    step: p.step().map(|s| s as f32),
                    spacing,
                };
            });
        self.fine_points = self
            .staging
            .iter()
            .zip(&self.pages)
            .filter(|(g, _)| g.flags & 1 != 0)
            .map(|(_, p)| p.count as u64)
            .sum();
        if !self.staging.is_empty() {
            ctx.queue
                .write_buffer(&self.infos, 0, bytemuck::cast_slice(&self.staging));
        }
        write_frame(ctx, &self.frame_uniform, camera, size, settings);
    }
}

/// Writes the per-frame uniform: the camera-relative view-projection, the image size, the
/// hidden classes and the splat sizes.
pub(crate) fn write_frame(
    ctx: &GpuContext,
    uniform: &wgpu::Buffer,
    camera: &Camera,
    (width, height): (u32, u32),
    settings: &RenderSettings,
) {
    let hidden_classes = &settings.hidden_classes;
    let frame = GpuFrame {
        view_proj: pointlet_core::camera::to_f32(
            &camera.relative_view_projection(width as f64 / height.max(1) as f64),
        ),
        size: [width, height],
        blend_factor: 1.01,
        _pad: 0,
        hidden_classes: *hidden_classes,
        splat: settings.splat_words(camera.focal_px(height)),
    };
    ctx.queue
        .write_buffer(uniform, 0, bytemuck::bytes_of(&frame));
}

/// Encodes pages `first..end` into whole-page runs of the position, fine and colour streams
/// (unused slots of a partial page stay zero; shaders skip them by count).
fn encode_page_run(
    set: &PointSet,
    pages: &[PageMeta],
    first: u32,
    end: u32,
    page_size: usize,
    encoding: PointEncoding,
) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let words = (encoding.position_bytes() / 4) as usize;
    let fine_words = if encoding == PointEncoding::Compact8 {
        1
    } else {
        0
    };
    let parts: Vec<(Vec<u32>, Vec<u32>)> = (first..end)
        .into_par_iter()
        .map(|k| {
            let page = &pages[k as usize];
            let start = k as usize * page_size;
            let range = start..start + page.count as usize;
            let mut main = Vec::with_capacity(page_size * words);
            let mut fine = Vec::with_capacity(page_size * fine_words);
            encode_positions(
                &set.positions[range],
                page.origin,
                page.step(),
                encoding,
                &mut main,
                &mut fine,
            );
            main.resize(page_size * words, 0);
            fine.resize(page_size * fine_words, 0);
            (main, fine)
        })
        .collect();
    let mut main = Vec::with_capacity(parts.len() * page_size * words);
    let mut fine = Vec::with_capacity(parts.len() * page_size * fine_words);
    for (m, f) in parts {
        main.extend_from_slice(&m);
        fine.extend_from_slice(&f);
    }
    (
        main,
        fine,
        page_colors(&set.colors, pages, first, end, page_size),
    )
}

/// The colours of pages `first..end`, each page padded to `page_size`.
fn page_colors(
    colors: &[u32],
    pages: &[PageMeta],
    first: u32,
    end: u32,
    page_size: usize,
) -> Vec<u32> {
    let mut out = vec![0u32; (end - first) as usize * page_size];
    out.par_chunks_mut(page_size)
        .zip(first..end)
        .for_each(|(page, k)| {
            let start = k as usize * page_size;
            let n = pages[k as usize].count as usize;
            page[..n].copy_from_slice(&colors[start..start + n]);
        });
    out
}
