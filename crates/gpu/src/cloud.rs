//! Point data resident on the GPU, in fixed-size pages, split over as many buffers as the
//! device's binding limit requires.
//!
//! A page holds up to `page_size` consecutive points that share an origin (the page's AABB
//! minimum, kept in f64 on the CPU). Every frame [`GpuCloud::prepare`] writes each page's origin
//! minus the eye into the page table in f32, so shaders only see camera-relative coordinates.

use crate::context::GpuContext;
use crate::GpuError;
use bytemuck::{Pod, Zeroable};
use pointlet_core::{Aabb, Camera};
use rayon::prelude::*;

/// How points are laid out in GPU memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointEncoding {
    /// f32 xyz relative to the page origin + RGBA8: 16 bytes, one load per point.
    Full16,
    /// 3 × 10-bit coarse position + RGBA8 (8 bytes), plus a 4-byte fine word read only for pages
    /// seen up close (Schütz et al. 2022's adaptive precision).
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

    /// Bytes of the main stream per point (the fine stream of Compact8 is extra, when read).
    pub fn bytes_per_point(self) -> u64 {
        match self {
            PointEncoding::Full16 => 16,
            PointEncoding::Compact8 => 8,
        }
    }
}

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

/// Quantization steps per axis of the compact encoding: 20 bits over the page's extent.
pub const COMPACT_STEPS: f64 = (1u64 << 20) as f64;

/// CPU-side description of one page.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PageMeta {
    pub origin: [f64; 3],
    pub extent: [f64; 3],
    pub count: u32,
}

impl PageMeta {
    /// One compact quantization step per axis (never 0, so flat pages still decode).
    pub fn step(&self) -> [f64; 3] {
        self.extent.map(|e| e.max(1e-9) / COMPACT_STEPS)
    }

    /// True when one coarse (10-bit) cell of this page covers more than half a pixel: the
    /// compact encoding then reads the fine word too.
    pub fn needs_fine(&self, eye: [f64; 3], focal_px: f64) -> bool {
        let cell = self.step().iter().fold(0.0f64, |m, s| m.max(*s)) * 1024.0;
        let d2: f64 = (0..3)
            .map(|i| {
                let (lo, hi) = (self.origin[i], self.origin[i] + self.extent[i]);
                let d = (lo - eye[i]).max(eye[i] - hi).max(0.0);
                d * d
            })
            .sum();
        cell * focal_px > 0.5 * d2.sqrt()
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuPage {
    origin: [f32; 3],
    count: u32,
    step: [f32; 3],
    flags: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuFrame {
    pub view_proj: [[f32; 4]; 4],
    pub size: [u32; 2],
    pub blend_factor: f32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuDispatch {
    first_page: u32,
    list_offset: u32,
    page_count: u32,
    _pad: u32,
}

/// One point buffer (≤ the binding limit) and the pages it holds.
pub struct CloudChunk {
    pub(crate) points: wgpu::Buffer,
    pub(crate) fine: Option<wgpu::Buffer>,
    pub(crate) page_count: u32,
    pub(crate) bind_group: wgpu::BindGroup,
    _dispatch: wgpu::Buffer,
}

/// Layout of bind group 0 for every point pass of an encoding; identical descriptors give
/// compatible layouts, so clouds and pipelines can each create their own.
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
        storage(2, wgpu::ShaderStages::COMPUTE),
        uniform(3, both),
        storage(4, wgpu::ShaderStages::COMPUTE),
    ];
    if encoding == PointEncoding::Compact8 {
        entries.push(storage(5, wgpu::ShaderStages::COMPUTE));
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(encoding.name()),
        entries: &entries,
    })
}

/// A point cloud uploaded to the GPU.
pub struct GpuCloud {
    pub encoding: PointEncoding,
    pub page_size: u32,
    pub points: u64,
    pub bounds: Aabb,
    pub(crate) pages: Vec<PageMeta>,
    pub(crate) chunks: Vec<CloudChunk>,
    page_table: wgpu::Buffer,
    pub(crate) frame_uniform: wgpu::Buffer,
    _page_list: wgpu::Buffer,
    staging_pages: Vec<GpuPage>,
}

/// Bytes encoded and written per upload step: bounds the staging memory of huge uploads.
const UPLOAD_SLICE_PAGES_BYTES: u64 = 64 << 20;

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
        if !(page_size.is_power_of_two() && (256..=1 << 16).contains(&page_size)) {
            return Err(GpuError::InvalidInput(format!(
                "page size {page_size} must be a power of two in 256..=65536"
            )));
        }
        if set.positions.iter().flatten().any(|v| !v.is_finite()) {
            return Err(GpuError::InvalidInput(
                "point positions must be finite".into(),
            ));
        }
        let n = set.positions.len();
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
        if pages.len() > u32::MAX as usize / 2 {
            return Err(GpuError::InvalidInput(format!(
                "{n} points: too many pages"
            )));
        }
        let device = &ctx.device;
        let bpp = encoding.bytes_per_point();
        let page_bytes = bpp * page_size as u64;
        let max_chunk_bytes = ctx.caps.max_binding.min(ctx.caps.max_buffer);
        let pages_per_chunk = (max_chunk_bytes / page_bytes).max(1) as usize;
        if page_bytes > max_chunk_bytes {
            return Err(GpuError::InvalidInput(format!(
                "a page of {page_size} points ({page_bytes} bytes) exceeds the binding limit of {max_chunk_bytes} bytes"
            )));
        }
        let layout = point_group_layout(device, encoding);
        let page_table = ctx.checked("allocating the page table", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("page table"),
                size: (pages.len().max(1) * std::mem::size_of::<GpuPage>()) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let list: Vec<u32> = (0..pages.len().max(1) as u32).collect();
        let page_list = ctx.checked("allocating the page list", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("page list"),
                size: (list.len() * 4) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        ctx.queue
            .write_buffer(&page_list, 0, bytemuck::cast_slice(&list));
        let frame_uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<GpuFrame>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut chunks = Vec::new();
        for (c, chunk_pages) in pages.chunks(pages_per_chunk).enumerate() {
            let first_page = (c * pages_per_chunk) as u32;
            let count = chunk_pages.len() as u64;
            let usage = wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::VERTEX
                | wgpu::BufferUsages::COPY_DST;
            let points = ctx.checked("allocating point memory", || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("points"),
                    size: count * page_bytes,
                    usage,
                    mapped_at_creation: false,
                })
            })?;
            let fine = match encoding {
                PointEncoding::Full16 => None,
                PointEncoding::Compact8 => Some(ctx.checked("allocating point memory", || {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("fine positions"),
                        size: count * page_size as u64 * 4,
                        usage,
                        mapped_at_creation: false,
                    })
                })?),
            };
            // Encode and write a slice of pages at a time.
            let slice_pages = (UPLOAD_SLICE_PAGES_BYTES / page_bytes).max(1) as usize;
            for (s, slice) in chunk_pages.chunks(slice_pages).enumerate() {
                let first = first_page as usize + s * slice_pages;
                let (main, fine_words) =
                    encode_pages(set, &pages, first, slice.len(), ps, encoding);
                let offset = (s * slice_pages) as u64;
                ctx.queue
                    .write_buffer(&points, offset * page_bytes, bytemuck::cast_slice(&main));
                if let Some(f) = &fine {
                    ctx.queue.write_buffer(
                        f,
                        offset * page_size as u64 * 4,
                        bytemuck::cast_slice(&fine_words),
                    );
                }
                // Hand the staged bytes to the GPU before encoding more (bounded staging memory).
                ctx.queue.submit([]);
                ctx.wait()?;
            }
            let dispatch = GpuDispatch {
                first_page,
                list_offset: first_page,
                page_count: count as u32,
                _pad: 0,
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
                entry(0, &frame_uniform),
                entry(1, &page_table),
                entry(2, &page_list),
                entry(3, &dispatch_buffer),
                entry(4, &points),
            ];
            if let Some(f) = &fine {
                entries.push(entry(5, f));
            }
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("points"),
                layout: &layout,
                entries: &entries,
            });
            chunks.push(CloudChunk {
                points,
                fine,
                page_count: count as u32,
                bind_group,
                _dispatch: dispatch_buffer,
            });
        }
        let staging_pages = vec![GpuPage::zeroed(); pages.len()];
        Ok(Self {
            encoding,
            page_size,
            points: n as u64,
            bounds: set.bounds(),
            pages,
            chunks,
            page_table,
            frame_uniform,
            _page_list: page_list,
            staging_pages,
        })
    }

    /// GPU memory held by point data, in bytes.
    pub fn point_bytes(&self) -> u64 {
        self.chunks
            .iter()
            .map(|c| c.points.size() + c.fine.as_ref().map_or(0, |f| f.size()))
            .sum()
    }

    pub fn page_metas(&self) -> &[PageMeta] {
        &self.pages
    }

    /// Writes this frame's camera-relative page origins and the frame uniform.
    pub fn prepare(&mut self, ctx: &GpuContext, camera: &Camera, width: u32, height: u32) {
        let focal_px = 0.5 * height as f64 / (camera.fov_y_deg.to_radians() * 0.5).tan();
        let eye = camera.eye;
        let encoding = self.encoding;
        self.staging_pages
            .par_iter_mut()
            .zip(self.pages.par_iter())
            .for_each(|(g, p)| {
                let fine = encoding == PointEncoding::Compact8 && p.needs_fine(eye, focal_px);
                *g = GpuPage {
                    origin: [
                        (p.origin[0] - eye[0]) as f32,
                        (p.origin[1] - eye[1]) as f32,
                        (p.origin[2] - eye[2]) as f32,
                    ],
                    count: p.count,
                    step: p.step().map(|s| s as f32),
                    flags: fine as u32,
                };
            });
        if !self.staging_pages.is_empty() {
            ctx.queue.write_buffer(
                &self.page_table,
                0,
                bytemuck::cast_slice(&self.staging_pages),
            );
        }
        let frame = GpuFrame {
            view_proj: pointlet_core::camera::to_f32(
                &camera.relative_view_projection(width as f64 / height.max(1) as f64),
            ),
            size: [width, height],
            blend_factor: 1.01,
            _pad: 0,
        };
        ctx.queue
            .write_buffer(&self.frame_uniform, 0, bytemuck::bytes_of(&frame));
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// Encodes pages `first .. first + count` into the main stream (u32 words) and, for Compact8,
/// the fine stream. Unused slots of a partial page stay zero (shaders skip them by count).
fn encode_pages(
    set: &PointSet,
    pages: &[PageMeta],
    first: usize,
    count: usize,
    page_size: usize,
    encoding: PointEncoding,
) -> (Vec<u32>, Vec<u32>) {
    let words = (encoding.bytes_per_point() / 4) as usize;
    let mut main = vec![0u32; count * page_size * words];
    let mut fine = match encoding {
        PointEncoding::Full16 => Vec::new(),
        PointEncoding::Compact8 => vec![0u32; count * page_size],
    };
    let encode_one = |k: usize, out: &mut [u32], fine_out: &mut [u32]| {
        let page = &pages[first + k];
        let start = (first + k) * page_size;
        let pts = &set.positions[start..start + page.count as usize];
        let cols = &set.colors[start..start + page.count as usize];
        match encoding {
            PointEncoding::Full16 => {
                for (j, (p, c)) in pts.iter().zip(cols).enumerate() {
                    let o = &mut out[j * 4..j * 4 + 4];
                    for a in 0..3 {
                        o[a] = ((p[a] - page.origin[a]) as f32).to_bits();
                    }
                    o[3] = *c;
                }
            }
            PointEncoding::Compact8 => {
                let step = page.step();
                for (j, (p, c)) in pts.iter().zip(cols).enumerate() {
                    let q = quantize_compact(*p, page.origin, step);
                    out[j * 2] = (q[0] >> 10) | (q[1] >> 10) << 10 | (q[2] >> 10) << 20;
                    out[j * 2 + 1] = *c;
                    fine_out[j] = (q[0] & 1023) | (q[1] & 1023) << 10 | (q[2] & 1023) << 20;
                }
            }
        }
    };
    match encoding {
        PointEncoding::Full16 => main
            .par_chunks_mut(page_size * words)
            .enumerate()
            .for_each(|(k, out)| encode_one(k, out, &mut [])),
        PointEncoding::Compact8 => main
            .par_chunks_mut(page_size * words)
            .zip(fine.par_chunks_mut(page_size))
            .enumerate()
            .for_each(|(k, (out, f))| encode_one(k, out, f)),
    }
    (main, fine)
}

/// 20-bit grid coordinates of `p` in a page (clamped: the page box contains its points).
pub fn quantize_compact(p: [f64; 3], origin: [f64; 3], step: [f64; 3]) -> [u32; 3] {
    let max = COMPACT_STEPS - 1.0;
    [0, 1, 2].map(|a| ((p[a] - origin[a]) / step[a]).floor().clamp(0.0, max) as u32)
}

/// Where the GPU will draw a compact point: the centre of its fine or coarse cell.
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
