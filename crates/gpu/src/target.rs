//! Everything a frame is drawn into: the rasterizers' per-pixel buffers, the intermediate images
//! of the screen passes and the final RGBA8 image, plus the timestamp queries of a frame.

use crate::context::GpuContext;
use crate::graph::TransientPool;
use crate::GpuError;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

/// An image and its linear view depth (0 = empty pixel).
pub(crate) struct Layer {
    pub color: wgpu::Texture,
    pub depth: wgpu::Texture,
}

/// What frames are drawn into. The resources that outlive a frame are here: the 64-bit keys
/// (a still view accumulates into them, temporal reuse and progressive rendering read them),
/// the resolved raster layer (read back for tests and picking) and the output image. Everything
/// else a frame needs is a transient of its render graph (frame.rs), allocated in `pool`.
pub struct RenderTarget {
    pub width: u32,
    pub height: u32,
    /// `~depth << 32 | ~rgba` per pixel (0 = empty).
    pub(crate) keys: wgpu::Buffer,
    pub(crate) raster_layer: Layer,
    pub(crate) output: wgpu::Texture,
    pub(crate) pool: TransientPool,
    pub(crate) timer: Option<FrameTimer>,
}

pub(crate) const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// GPU bytes per pixel at most: keys 8, raster layer 8, output 4, and the largest set of
/// transients a frame graph takes (HQS1R's depth, packed and overflow words, 28, and two
/// filtered layers, 16).
const BYTES_PER_PIXEL: u64 = 64;

/// A render pass that clears `layer` (colour and linear depth, its two attachments) and the
/// `depth_attachment` of the hardware depth test: hardware points and billboard quads draw
/// into the raster layer the resolve would write.
pub(crate) fn begin_layer_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    layer: &Layer,
    depth_attachment: &wgpu::Texture,
    timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    let color = layer.color.create_view(&Default::default());
    let depth = layer.depth.create_view(&Default::default());
    let z = depth_attachment.create_view(&Default::default());
    let clear = |view| {
        Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                store: wgpu::StoreOp::Store,
            },
        })
    };
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[clear(&color), clear(&depth)],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: &z,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: timestamps,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// A texture of `size`.
pub(crate) fn image(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

impl RenderTarget {
    /// GPU bytes a target of this size allocates at most.
    pub fn bytes_for(width: u32, height: u32) -> u64 {
        width as u64 * height as u64 * BYTES_PER_PIXEL
    }

    /// GPU bytes allocated so far (transients are allocated as frame graphs need them).
    pub fn gpu_bytes(&self) -> u64 {
        self.width as u64 * self.height as u64 * 20 + self.pool.bytes()
    }

    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        let max = ctx.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::InvalidInput(format!(
                "image size {width}×{height} must be between 1 and {max} pixels per side"
            )));
        }
        let device = &ctx.device;
        let px = width as u64 * height as u64;
        let keys = ctx.checked("allocating the framebuffer", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("keys"),
                size: px * 8,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        })?;
        let sampled = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING;
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let size = (width, height);
        let raster_layer = ctx.checked("allocating the raster layer", || Layer {
            color: image(
                device,
                "raster colour",
                size,
                COLOR_FORMAT,
                sampled | attach,
            ),
            // COPY_SRC: read_depth copies it out (without it the copy fails validation).
            depth: image(
                device,
                "raster depth",
                size,
                DEPTH_FORMAT,
                sampled | attach | wgpu::TextureUsages::COPY_SRC,
            ),
        })?;
        let output = ctx.checked("allocating the output image", || {
            image(
                device,
                "image",
                size,
                COLOR_FORMAT,
                sampled | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST,
            )
        })?;
        let timer = ctx.caps.timestamps.then(|| FrameTimer::new(ctx));
        Ok(Self {
            width,
            height,
            keys,
            raster_layer,
            output,
            pool: TransientPool::new(width, height),
            timer,
        })
    }

    /// The final image (RGBA8), for presenting or copying.
    pub fn output(&self) -> &wgpu::Texture {
        &self.output
    }

    /// Reads the final image back: `width * height * 4` bytes, rows top to bottom.
    pub fn read_rgba(&self, ctx: &GpuContext) -> Result<Vec<u8>, GpuError> {
        read_texture(ctx, &self.output, 4)
    }

    /// Reads the raster layer's linear depth (0 = empty), for tests and picking. Frames whose
    /// graph needs no resolved layer (blending without screen filters) leave it as it was.
    pub fn read_depth(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        let bytes = read_texture(ctx, &self.raster_layer.depth, 4)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}

/// Copies a texture into a mappable buffer and returns its tightly packed bytes.
pub(crate) fn read_texture(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    bytes_per_pixel: u32,
) -> Result<Vec<u8>, GpuError> {
    let (w, h) = (texture.width(), texture.height());
    let row = w * bytes_per_pixel;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: padded as u64 * h as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        texture.size(),
    );
    ctx.queue.submit([enc.finish()]);
    let bytes = map_read(ctx, &buffer)?;
    let mut out = Vec::with_capacity((row * h) as usize);
    for y in 0..h as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&bytes[start..start + row as usize]);
    }
    Ok(out)
}

/// Maps a MAP_READ buffer and copies its contents out.
pub(crate) fn map_read(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait()?;
    rx.recv()
        .map_err(|_| GpuError::Device("buffer mapping was dropped".into()))?
        .map_err(|e| GpuError::Device(format!("mapping a buffer for reading: {e}")))?;
    let out = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Device(format!("reading a mapped buffer: {e}")))?
        .to_vec();
    buffer.unmap();
    Ok(out)
}

/// Timestamps at the borders of a frame's passes: LoD, raster, screen and upload start/end.
/// Results
/// come back through a small ring of mappable buffers, so a render loop never waits for them.
pub(crate) struct FrameTimer {
    pub queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    ring: Vec<TimerSlot>,
    /// Ring slot the frame being recorded resolves into, if one was free.
    pending: Option<usize>,
    period_ns: f64,
}

struct TimerSlot {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
    frame: u64,
    had_lod: bool,
}

pub(crate) const TIMESTAMPS: u32 = 8;
const RING: usize = 8;
const FREE: u8 = 0;
const IN_FLIGHT: u8 = 1;
const READY: u8 = 2;

impl FrameTimer {
    fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let bytes = TIMESTAMPS as u64 * 8;
        Self {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: TIMESTAMPS,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: bytes,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            ring: (0..RING)
                .map(|_| TimerSlot {
                    buffer: device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("timestamps readback"),
                        size: bytes,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    }),
                    state: Arc::new(AtomicU8::new(FREE)),
                    frame: 0,
                    had_lod: false,
                })
                .collect(),
            pending: None,
            period_ns: ctx.queue.get_timestamp_period() as f64,
        }
    }

    /// Records the copy of this frame's timestamps into a free ring slot (none free: this
    /// frame goes untimed).
    pub fn resolve(&mut self, enc: &mut wgpu::CommandEncoder, frame: u64, had_lod: bool) {
        self.pending = self
            .ring
            .iter()
            .position(|r| r.state.load(Ordering::Acquire) == FREE);
        if let Some(k) = self.pending {
            let slot = &mut self.ring[k];
            enc.resolve_query_set(&self.queries, 0..TIMESTAMPS, &self.resolve, 0);
            enc.copy_buffer_to_buffer(&self.resolve, 0, &slot.buffer, 0, TIMESTAMPS as u64 * 8);
            slot.frame = frame;
            slot.had_lod = had_lod;
            slot.state.store(IN_FLIGHT, Ordering::Release);
        }
    }

    /// Call after submitting the frame: starts mapping its timestamps.
    pub fn after_submit(&mut self) {
        if let Some(k) = self.pending.take() {
            let state = self.ring[k].state.clone();
            self.ring[k]
                .buffer
                .slice(..)
                .map_async(wgpu::MapMode::Read, move |r| {
                    state.store(if r.is_ok() { READY } else { FREE }, Ordering::Release);
                });
        }
    }

    /// Timings that have arrived, oldest first: (frame, [LoD, raster, screen, upload] ms, had
    /// the paged passes).
    pub fn poll(&mut self, ctx: &GpuContext) -> Vec<(u64, [f64; 4], bool)> {
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        let mut out = Vec::new();
        for slot in &mut self.ring {
            if slot.state.load(Ordering::Acquire) != READY {
                continue;
            }
            let t: Option<Vec<u64>> = slot
                .buffer
                .slice(..)
                .get_mapped_range()
                .ok()
                .map(|v| bytemuck::pod_collect_to_vec(&v));
            slot.buffer.unmap();
            slot.state.store(FREE, Ordering::Release);
            if let Some(t) = t {
                let ms = |k: usize| match (t.get(2 * k), t.get(2 * k + 1)) {
                    (Some(a), Some(b)) => b.saturating_sub(*a) as f64 * self.period_ns * 1e-6,
                    _ => 0.0,
                };
                out.push((slot.frame, [ms(0), ms(1), ms(2), ms(3)], slot.had_lod));
            }
        }
        out.sort_by_key(|r| r.0);
        out
    }
}
