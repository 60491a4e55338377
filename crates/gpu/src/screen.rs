//! Screen passes after the raster: resolve the pixel buffers into a colour/depth layer, fill
//! holes, then compose the background and Eye-Dome Lighting into the output image.

use crate::raster::{storage_group, storage_layout, PixelKind};
use crate::shaders;
use crate::target::{RenderTarget, COLOR_FORMAT, DEPTH_FORMAT};
use bytemuck::{Pod, Zeroable};
use std::collections::HashMap;

/// Eye-Dome Lighting parameters (Boucheny; WebGPU paper §6.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdlSettings {
    /// Shading strength (k = 300 · strength in exp(−k · mean response)).
    pub strength: f32,
    /// Distance in pixels of the 8 neighbours sampled.
    pub radius: f32,
}

impl Default for EdlSettings {
    fn default() -> Self {
        Self {
            strength: 1.0,
            radius: 1.4,
        }
    }
}

/// The occlusion filter (virtualized paper §III-D2, eq. 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OcclusionSettings {
    /// Pixels searched in each of 8 directions.
    pub radius: u32,
    /// β below which a nearer neighbour blocks a direction (radians; the paper's 0.1).
    pub threshold: f32,
}

impl Default for OcclusionSettings {
    fn default() -> Self {
        Self {
            radius: 3,
            threshold: 0.1,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct OcclusionUniform {
    radius: u32,
    threshold: f32,
    pixel_angle: f32,
    min_blocked: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ScreenUniform {
    size: [u32; 2],
    _pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FillUniform {
    radius: u32,
    _pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ComposeUniform {
    background: [f32; 4],
    strength: f32,
    radius: f32,
    focal_px: f32,
    _pad: f32,
}

enum Binding {
    Uniform,
    Sampled,
    Storage(wgpu::TextureFormat),
}

fn layout(device: &wgpu::Device, label: &str, bindings: &[Binding]) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = bindings
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: match b {
                Binding::Uniform => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                Binding::Sampled => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                Binding::Storage(format) => wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format: *format,
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
            },
            count: None,
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

fn pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    entry: &str,
    groups: &[&wgpu::BindGroupLayout],
) -> wgpu::ComputePipeline {
    pipeline_with(device, label, source, entry, groups, &[])
}

fn pipeline_with(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    entry: &str,
    groups: &[&wgpu::BindGroupLayout],
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let module = shaders::module(device, label, source);
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(|g| Some(*g)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
        cache: None,
    })
}

pub(crate) struct ScreenPasses {
    resolve_out_layout: wgpu::BindGroupLayout,
    /// Per pixel kind, and whether colours carry splat sizes.
    resolve: HashMap<(PixelKind, bool), (wgpu::ComputePipeline, wgpu::BindGroupLayout)>,
    fill_layout: wgpu::BindGroupLayout,
    fill: wgpu::ComputePipeline,
    occlusion: wgpu::ComputePipeline,
    compose_layout: wgpu::BindGroupLayout,
    compose: wgpu::ComputePipeline,
    uniforms: wgpu::Buffer,
}

const SCREEN_OFFSET: u64 = 0;
const FILL_OFFSET: u64 = 256;
const COMPOSE_OFFSET: u64 = 512;
const OCCLUSION_OFFSET: u64 = 768;
/// Directions (of 8) that must be blocked for the occlusion filter to drop a pixel.
const OCCLUSION_MIN_BLOCKED: u32 = 6;

/// What the screen passes do this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenSettings {
    /// Drop points seen through gaps of nearer surfaces (before hole filling).
    pub occlusion: Option<OcclusionSettings>,
    /// Hole-filling radius in pixels (0 = off).
    pub fill_radius: u32,
    pub edl: Option<EdlSettings>,
    /// RGBA in 0..1 for empty pixels.
    pub background: [f32; 4],
}

impl Default for ScreenSettings {
    fn default() -> Self {
        Self {
            occlusion: None,
            fill_radius: 0,
            edl: None,
            background: [0.0, 0.0, 0.0, 1.0],
        }
    }
}

impl ScreenPasses {
    pub fn new(device: &wgpu::Device) -> Self {
        let resolve_out_layout = layout(
            device,
            "resolve output",
            &[
                Binding::Uniform,
                Binding::Storage(COLOR_FORMAT),
                Binding::Storage(DEPTH_FORMAT),
            ],
        );
        let fill_layout = layout(
            device,
            "fill",
            &[
                Binding::Uniform,
                Binding::Sampled,
                Binding::Sampled,
                Binding::Storage(COLOR_FORMAT),
                Binding::Storage(DEPTH_FORMAT),
            ],
        );
        let compose_layout = layout(
            device,
            "compose",
            &[
                Binding::Uniform,
                Binding::Sampled,
                Binding::Sampled,
                Binding::Storage(COLOR_FORMAT),
            ],
        );
        let fill = pipeline(device, "fill", shaders::FILL, "fill", &[&fill_layout]);
        // Same bindings as filling: one layer in, the other out.
        let occlusion = pipeline(
            device,
            "occlusion",
            shaders::OCCLUSION,
            "occlusion",
            &[&fill_layout],
        );
        let compose = pipeline(
            device,
            "compose",
            shaders::COMPOSE,
            "compose",
            &[&compose_layout],
        );
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("screen uniforms"),
            size: 1024,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            resolve_out_layout,
            resolve: HashMap::new(),
            fill_layout,
            fill,
            occlusion,
            compose_layout,
            compose,
            uniforms,
        }
    }

    fn resolve_pipeline(
        &mut self,
        device: &wgpu::Device,
        kind: PixelKind,
        splat_sizes: bool,
    ) -> Option<&(wgpu::ComputePipeline, wgpu::BindGroupLayout)> {
        let body = match kind {
            PixelKind::Hardware => return None,
            PixelKind::Key64 => shaders::RESOLVE_MIN64,
            PixelKind::TwoPass32 => shaders::RESOLVE_MIN32,
            PixelKind::Hqs => shaders::RESOLVE_HQS,
            PixelKind::Hqs1r => shaders::RESOLVE_HQS1R,
        };
        let out = &self.resolve_out_layout;
        Some(self.resolve.entry((kind, splat_sizes)).or_insert_with(|| {
            let n = match kind {
                PixelKind::Key64 => 1,
                PixelKind::Hqs1r => 3,
                _ => 2,
            };
            let group1 = storage_layout(device, n, true);
            let p = pipeline_with(
                device,
                "resolve",
                &shaders::resolve_pass(body),
                "resolve",
                &[out, &group1],
                &[("SPLAT_SIZES", splat_sizes as u32 as f64)],
            );
            (p, group1)
        }))
    }

    /// Writes this frame's uniforms; call before recording. `fov_y_deg` sizes pixels for the
    /// occlusion filter.
    pub fn prepare(
        &self,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        s: &ScreenSettings,
        fov_y_deg: f64,
    ) {
        let screen = ScreenUniform {
            size: [target.width, target.height],
            _pad: [0; 2],
        };
        let fill = FillUniform {
            radius: s.fill_radius,
            _pad: [0; 3],
        };
        let edl = s.edl.unwrap_or(EdlSettings {
            strength: 0.0,
            radius: 1.0,
        });
        let compose = ComposeUniform {
            background: s.background,
            strength: edl.strength,
            radius: edl.radius,
            focal_px: (0.5 * target.height as f64 / (fov_y_deg.to_radians() * 0.5).tan()) as f32,
            _pad: 0.0,
        };
        queue.write_buffer(&self.uniforms, SCREEN_OFFSET, bytemuck::bytes_of(&screen));
        queue.write_buffer(&self.uniforms, FILL_OFFSET, bytemuck::bytes_of(&fill));
        queue.write_buffer(&self.uniforms, COMPOSE_OFFSET, bytemuck::bytes_of(&compose));
        let o = s.occlusion.unwrap_or_default();
        let pixel_angle = 2.0 * (fov_y_deg.to_radians() * 0.5).tan() / target.height.max(1) as f64;
        let occlusion = OcclusionUniform {
            radius: o.radius.clamp(1, 64),
            threshold: o.threshold,
            pixel_angle: pixel_angle as f32,
            min_blocked: OCCLUSION_MIN_BLOCKED,
        };
        queue.write_buffer(
            &self.uniforms,
            OCCLUSION_OFFSET,
            bytemuck::bytes_of(&occlusion),
        );
    }

    fn uniform(&self, offset: u64, size: u64) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &self.uniforms,
            offset,
            size: wgpu::BufferSize::new(size),
        })
    }

    /// Records resolve → occlusion → fill → compose into one compute pass (the middle two
    /// ping-pong between the two layers).
    pub fn record(
        &mut self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        target: &RenderTarget,
        kind: PixelKind,
        splat_sizes: bool,
        settings: &ScreenSettings,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let a = &target.layers[0];
        let resolve_pipeline = self.resolve_pipeline(device, kind, splat_sizes).cloned();
        let resolve = resolve_pipeline.map(|(p, g1)| {
            let group0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("resolve output"),
                layout: &self.resolve_out_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.uniform(SCREEN_OFFSET, 16),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&view(&a.color)),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&view(&a.depth)),
                    },
                ],
            });
            let group1 = storage_group(device, "pixel buffers", &g1, &kind.buffers(target));
            (p, group0, group1)
        });
        let textures = |layout: &wgpu::BindGroupLayout,
                        offset: u64,
                        size: u64,
                        src: &crate::target::Layer,
                        dst: &[&wgpu::Texture]| {
            let views: Vec<wgpu::TextureView> = [&src.color, &src.depth]
                .into_iter()
                .chain(dst.iter().copied())
                .map(view)
                .collect();
            let mut entries = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: self.uniform(offset, size),
            }];
            for (i, v) in views.iter().enumerate() {
                entries.push(wgpu::BindGroupEntry {
                    binding: 1 + i as u32,
                    resource: wgpu::BindingResource::TextureView(v),
                });
            }
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout,
                entries: &entries,
            })
        };
        // Each enabled filter reads the current layer and writes the other one.
        let mut filters: Vec<(&wgpu::ComputePipeline, wgpu::BindGroup)> = Vec::new();
        let mut current = 0usize;
        for (on, pipeline, offset) in [
            (
                settings.occlusion.is_some(),
                &self.occlusion,
                OCCLUSION_OFFSET,
            ),
            (settings.fill_radius > 0, &self.fill, FILL_OFFSET),
        ] {
            if on {
                let (src, dst) = (&target.layers[current], &target.layers[1 - current]);
                let group = textures(
                    &self.fill_layout,
                    offset,
                    16,
                    src,
                    &[&dst.color, &dst.depth],
                );
                filters.push((pipeline, group));
                current = 1 - current;
            }
        }
        let compose_src = &target.layers[current];
        let compose_group = textures(
            &self.compose_layout,
            COMPOSE_OFFSET,
            32,
            compose_src,
            &[&target.output],
        );
        let groups = [target.width.div_ceil(8), target.height.div_ceil(8)];
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("screen passes"),
            timestamp_writes: timestamps,
        });
        if let Some((p, g0, g1)) = &resolve {
            pass.set_pipeline(p);
            pass.set_bind_group(0, g0, &[]);
            pass.set_bind_group(1, g1, &[]);
            pass.dispatch_workgroups(groups[0], groups[1], 1);
        }
        for (pipeline, group) in &filters {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(groups[0], groups[1], 1);
        }
        pass.set_pipeline(&self.compose);
        pass.set_bind_group(0, &compose_group, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], 1);
    }
}
