//! Putting a frame on the window: the renderer's image is copied texel for texel onto the
//! surface, then egui's overlay is drawn over it. On request the same composition is also drawn
//! into an offscreen texture and read back (a screenshot of the window, overlay included).

use crate::ViewerError;
use pointlet_gpu::GpuContext;

const BLIT: &str = include_str!("../shaders/blit.wgsl");

/// egui's draw data of one frame.
pub struct Overlay<'a> {
    pub primitives: &'a [egui::ClippedPrimitive],
    /// Drained by `present` (egui insists every delta is handled).
    pub textures: &'a mut egui::TexturesDelta,
    pub pixels_per_point: f32,
}

pub struct Presenter {
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    blit: wgpu::RenderPipeline,
    blit_layout: wgpu::BindGroupLayout,
    egui: egui_wgpu::Renderer,
}

/// What presenting a frame did.
pub enum Presented {
    /// Shown; with the window's pixels (RGBA8, rows top down) when a capture was asked for.
    Shown(Option<Vec<u8>>),
    /// The surface could not give a texture now (minimised, resized meanwhile): try again.
    Skipped,
}

/// A format that stores values as written, so the window shows the image's exact bytes; an
/// sRGB one (the blit then decodes) only if the window offers nothing else.
fn pick_format(formats: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
    use wgpu::TextureFormat as F;
    [
        F::Bgra8Unorm,
        F::Rgba8Unorm,
        F::Bgra8UnormSrgb,
        F::Rgba8UnormSrgb,
    ]
    .into_iter()
    .find(|f| formats.contains(f))
}

impl Presenter {
    pub fn new(
        ctx: &GpuContext,
        surface: wgpu::Surface<'static>,
        caps: &wgpu::SurfaceCapabilities,
        size: (u32, u32),
        vsync: bool,
    ) -> Result<Self, ViewerError> {
        let format = pick_format(&caps.formats).ok_or_else(|| {
            ViewerError::Gpu(format!(
                "the window offers no 8-bit RGBA/BGRA format (it offers {:?})",
                caps.formats
            ))
        })?;
        let present_mode = if vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.0.max(1),
            height: size.1.max(1),
            desired_maximum_frame_latency: 2,
            present_mode,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
        };
        let device = &ctx.device;
        ctx.checked("configuring the window surface", || {
            surface.configure(device, &config)
        })
        .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blit"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let blit = ctx
            .checked("building the blit pipeline", || {
                blit_pipeline(device, &blit_layout, format)
            })
            .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        let egui = egui_wgpu::Renderer::new(
            device,
            format,
            egui_wgpu::RendererOptions {
                // Screenshots of the window should not vary from run to run.
                dithering: false,
                ..Default::default()
            },
        );
        Ok(Self {
            surface,
            config,
            blit,
            blit_layout,
            egui,
        })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    pub fn resize(&mut self, ctx: &GpuContext, width: u32, height: u32) {
        if width == 0 || height == 0 || (width, height) == self.size() {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&ctx.device, &self.config);
    }

    /// Shows `image` (the renderer's RGBA8 output) under the overlay; with `capture`, also
    /// returns the composed window's pixels.
    pub fn present(
        &mut self,
        ctx: &GpuContext,
        image: &wgpu::Texture,
        overlay: &mut Overlay<'_>,
        capture: bool,
    ) -> Result<Presented, ViewerError> {
        for (id, deltas) in overlay.textures.set.drain() {
            for delta in &deltas {
                self.egui.update_texture(&ctx.device, &ctx.queue, id, delta);
            }
        }
        // Freed after this frame is drawn, or now if no frame is drawn.
        let free: Vec<egui::TextureId> = overlay.textures.free.drain().collect();
        let shown = self.draw(ctx, image, overlay, capture);
        for id in &free {
            self.egui.free_texture(id);
        }
        shown
    }

    fn draw(
        &mut self,
        ctx: &GpuContext,
        image: &wgpu::Texture,
        overlay: &Overlay<'_>,
        capture: bool,
    ) -> Result<Presented, ViewerError> {
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(Presented::Skipped)
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&ctx.device, &self.config);
                return Ok(Presented::Skipped);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(ViewerError::Gpu(
                    "the window surface rejected the frame (validation error)".into(),
                ))
            }
        };
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [self.config.width, self.config.height],
            pixels_per_point: overlay.pixels_per_point,
        };
        let image_view = image.create_view(&Default::default());
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blit"),
            layout: &self.blit_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&image_view),
            }],
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let mut commands = self.egui.update_buffers(
            &ctx.device,
            &ctx.queue,
            &mut enc,
            overlay.primitives,
            &screen,
        );
        let view = frame.texture.create_view(&Default::default());
        self.compose(&mut enc, &view, &bind, overlay.primitives, &screen);
        let capture = capture.then(|| self.capture(ctx, &mut enc, &bind, overlay, &screen));
        commands.push(enc.finish());
        ctx.checked("presenting a frame", || ctx.queue.submit(commands))
            .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        let pixels = match capture {
            Some((texture, buffer, padded)) => {
                Some(self.read_capture(ctx, &texture, &buffer, padded)?)
            }
            None => None,
        };
        ctx.queue.present(frame);
        Ok(Presented::Shown(pixels))
    }

    /// Blit then overlay, into `view`.
    fn compose(
        &self,
        enc: &mut wgpu::CommandEncoder,
        view: &wgpu::TextureView,
        bind: &wgpu::BindGroup,
        primitives: &[egui::ClippedPrimitive],
        screen: &egui_wgpu::ScreenDescriptor,
    ) {
        let pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("present"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        // egui-wgpu records into a pass of any lifetime only through a 'static one.
        let mut pass = pass.forget_lifetime();
        pass.set_pipeline(&self.blit);
        pass.set_bind_group(0, bind, &[]);
        pass.draw(0..3, 0..1);
        self.egui.render(&mut pass, primitives, screen);
    }

    /// Composes the frame once more into an offscreen texture and copies it to a buffer.
    fn capture(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        bind: &wgpu::BindGroup,
        overlay: &Overlay<'_>,
        screen: &egui_wgpu::ScreenDescriptor,
    ) -> (wgpu::Texture, wgpu::Buffer, u32) {
        let (w, h) = self.size();
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("window capture"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.config.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        self.compose(
            enc,
            &texture.create_view(&Default::default()),
            bind,
            overlay.primitives,
            screen,
        );
        let padded = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("window capture"),
            size: padded as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            size,
        );
        (texture, buffer, padded)
    }

    fn read_capture(
        &self,
        ctx: &GpuContext,
        texture: &wgpu::Texture,
        buffer: &wgpu::Buffer,
        padded: u32,
    ) -> Result<Vec<u8>, ViewerError> {
        let (w, h) = (texture.width(), texture.height());
        let slice = buffer.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        ctx.wait()
            .map_err(|e| ViewerError::Gpu(format!("capturing the window: {e}")))?;
        rx.recv()
            .map_err(|_| ViewerError::Gpu("capturing the window: mapping dropped".into()))?
            .map_err(|e| ViewerError::Gpu(format!("capturing the window: {e}")))?;
        let bytes = slice
            .get_mapped_range()
            .map_err(|e| ViewerError::Gpu(format!("capturing the window: {e}")))?;
        let bgra = self.config.format.remove_srgb_suffix() == wgpu::TextureFormat::Bgra8Unorm;
        let row = (w * 4) as usize;
        let mut out = Vec::with_capacity(row * h as usize);
        for chunk in bytes.chunks(padded as usize).take(h as usize) {
            for px in chunk[..row.min(chunk.len())].chunks_exact(4) {
                let (r, b) = if bgra { (px[2], px[0]) } else { (px[0], px[2]) };
                // The window is opaque whatever alpha egui left.
                out.extend_from_slice(&[r, px[1], b, 255]);
            }
        }
        drop(bytes);
        buffer.unmap();
        Ok(out)
    }
}

fn blit_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("blit"),
        source: wgpu::ShaderSource::Wgsl(BLIT.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("blit"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let entry = if format.is_srgb() {
        "fs_srgb"
    } else {
        "fs_plain"
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("blit"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            targets: &[Some(format.into())],
        }),
        multiview_mask: None,
        cache: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::TextureFormat as F;

    #[test]
    fn plain_formats_are_preferred_and_others_refused() {
        assert_eq!(
            pick_format(&[F::Bgra8UnormSrgb, F::Bgra8Unorm]),
            Some(F::Bgra8Unorm)
        );
        assert_eq!(pick_format(&[F::Rgba8UnormSrgb]), Some(F::Rgba8UnormSrgb));
        assert_eq!(pick_format(&[F::Rgb10a2Unorm]), None);
    }
}
