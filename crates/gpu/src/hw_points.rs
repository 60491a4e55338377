//! `hw-points`: the hardware point-list baseline, drawing into the same colour/depth layer the
//! compute resolve writes, so the screen passes treat both alike.

use crate::cloud::GpuCloud;
use crate::shaders;
use crate::storage::{point_group_layout, PointEncoding};
use crate::target::{begin_layer_pass, Layer, COLOR_FORMAT, DEPTH_FORMAT};

pub(crate) struct HwPointsPipeline {
    pipeline: wgpu::RenderPipeline,
}

impl HwPointsPipeline {
    pub fn new(device: &wgpu::Device, encoding: PointEncoding, page_size: u32) -> Self {
        let source = format!("{}\n{}", shaders::COMMON, shaders::HW_POINTS);
        let module = shaders::module(device, "hw-points", &source);
        let group0 = point_group_layout(device, encoding);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("hw-points"),
            bind_group_layouts: &[Some(&group0)],
            immediate_size: 0,
        });
        let attribute = |format, shader_location| {
            [wgpu::VertexAttribute {
                format,
                offset: 0,
                shader_location,
            }]
        };
        let position = attribute(wgpu::VertexFormat::Float32x3, 0);
        let coarse = attribute(wgpu::VertexFormat::Uint32, 0);
        let color = attribute(wgpu::VertexFormat::Uint32, 1);
        let fine = attribute(wgpu::VertexFormat::Uint32, 2);
        let vertex = |stride, attributes| {
            Some(wgpu::VertexBufferLayout {
                array_stride: stride,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes,
            })
        };
        let (entry, buffers) = match encoding {
            PointEncoding::Full16 => (
                "vs_full16",
                vec![vertex(12, &position[..]), vertex(4, &color[..])],
            ),
            PointEncoding::Compact8 => (
                "vs_compact8",
                vec![
                    vertex(4, &coarse[..]),
                    vertex(4, &color[..]),
                    vertex(4, &fine[..]),
                ],
            ),
        };
        let constants = [("PAGE_SIZE", page_size as f64)];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("hw-points"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                buffers: &buffers,
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::PointList,
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
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(COLOR_FORMAT.into()), Some(DEPTH_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self { pipeline }
    }

    /// Draws `cloud` into `layer`, with `depth_attachment` for the hardware depth test.
    pub fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        cloud: &GpuCloud,
        layer: &Layer,
        depth_attachment: &wgpu::Texture,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let mut pass = begin_layer_pass(enc, "hw-points", layer, depth_attachment, timestamps);
        pass.set_pipeline(&self.pipeline);
        for chunk in &cloud.storage.chunks {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            pass.set_vertex_buffer(0, chunk.positions.slice(..));
            pass.set_vertex_buffer(1, chunk.colors.slice(..));
            if let Some(f) = &chunk.fine {
                pass.set_vertex_buffer(2, f.slice(..));
            }
            pass.draw(0..chunk.slots * cloud.page_size, 0..1);
        }
    }
}
