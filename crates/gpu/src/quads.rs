//! Splats as billboard quads through the render pipeline (splat_quads.wgsl): the WebGPU-engine
//! paper's way of drawing points with a size, kept beside the compute footprints
//! (`--splat-raster quads`) to measure one against the other. Closest-point only: it writes the
//! raster layer directly, with the hardware depth test deciding the closest.

use crate::shaders;
use crate::splat::{self, SplatShape};
use crate::storage::{point_group_layout, PointEncoding, PointStorage};
use crate::target::{begin_layer_pass, Layer, COLOR_FORMAT, DEPTH_FORMAT};

pub(crate) struct QuadsPipeline {
    pipeline: wgpu::RenderPipeline,
    page_size: u32,
}

/// How many instances each chunk draws: every slot (static clouds list all their pages), or
/// the LoD's count of entries (four u32 of draw arguments per chunk).
#[derive(Clone, Copy)]
pub(crate) enum QuadDraw<'a> {
    Direct,
    Indirect(&'a wgpu::Buffer),
}

impl QuadsPipeline {
    pub fn new(
        device: &wgpu::Device,
        encoding: PointEncoding,
        page_size: u32,
        shape: SplatShape,
    ) -> Self {
        let source = shaders::point_pass(encoding, shaders::SPLAT_QUADS);
        let module = shaders::module(device, "splat quads", &source);
        let group0 = point_group_layout(device, encoding);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("splat quads"),
            bind_group_layouts: &[Some(&group0)],
            immediate_size: 0,
        });
        let [splats, circle] = splat::constants(splat::SplatMode::Splats(shape));
        let constants = [("PAGE_SIZE", page_size as f64), splats, circle];
        let options = || wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        };
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("splat quads"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: options(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: options(),
                targets: &[Some(COLOR_FORMAT.into()), Some(DEPTH_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self {
            pipeline,
            page_size,
        }
    }

    /// Draws the splats of `storage` into `layer` (cleared first), with `depth_attachment` for
    /// the depth test.
    pub fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        storage: &PointStorage,
        draw: QuadDraw<'_>,
        layer: &Layer,
        depth_attachment: &wgpu::Texture,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let mut pass = begin_layer_pass(enc, "splat quads", layer, depth_attachment, timestamps);
        pass.set_pipeline(&self.pipeline);
        for (c, chunk) in storage.chunks.iter().enumerate() {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            match draw {
                // Static clouds list every page of a chunk, one entry each.
                QuadDraw::Direct => pass.draw(0..4, 0..chunk.slots * self.page_size),
                QuadDraw::Indirect(args) => pass.draw_indirect(args, c as u64 * 16),
            }
        }
    }
}
