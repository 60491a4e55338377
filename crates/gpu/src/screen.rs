//! Screen passes after the raster: resolve the pixel buffers into a colour/depth layer, filter
//! it (occlusion, hole filling), then compose the background and Eye-Dome Lighting into the
//! output image — or, for blending without filters, normalise and compose in one pass. Which of
//! them a frame runs, and on which layers, is its render graph's business (frame.rs).

use crate::raster::{storage_group, storage_layout, PixelKind};
use crate::shaders;
use crate::splat::SplatShape;
use crate::target::{Layer, RenderTarget, COLOR_FORMAT, DEPTH_FORMAT};
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
    /// A read-write storage buffer.
    Buffer,
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
                Binding::Buffer => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: false },
                    has_dynamic_offset: false,
                    min_binding_size: None,
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
    /// Hole filling per radius (a constant of the pipeline: lavapipe recompiles a loop bounded
    /// by a uniform at every bind).
    fills: HashMap<u32, wgpu::ComputePipeline>,
    /// This frame's hole-filling radius (set by `prepare`).
    fill_radius: u32,
    occlusion: wgpu::ComputePipeline,
    compose_layout: wgpu::BindGroupLayout,
    /// Without and with EDL.
    compose: [wgpu::ComputePipeline; 2],
    blended_out_layout: wgpu::BindGroupLayout,
    /// Normalisation + EDL per blending kind, without and with EDL.
    blended: HashMap<(PixelKind, bool), (wgpu::ComputePipeline, wgpu::BindGroupLayout)>,
    /// Whether this frame's compose passes shade with EDL (set by `prepare`).
    edl: bool,
    gaps_layout: wgpu::BindGroupLayout,
    /// Splat gap filling per shape: the tile pass and the fill pass.
    gaps: HashMap<SplatShape, (wgpu::ComputePipeline, wgpu::ComputePipeline)>,
    uniforms: wgpu::Buffer,
}

const SCREEN_OFFSET: u64 = 0;
const COMPOSE_OFFSET: u64 = 512;
const OCCLUSION_OFFSET: u64 = 768;
/// Directions (of 8) that must be blocked for the occlusion filter to drop a pixel.
const OCCLUSION_MIN_BLOCKED: u32 = 6;

/// A screen pass from one layer to another.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Filter {
    Occlusion,
    HoleFill,
}

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
        let blended_out_layout = layout(
            device,
            "normalise and compose",
            &[Binding::Uniform, Binding::Storage(COLOR_FORMAT)],
        );
        let gaps_layout = layout(
            device,
            "splat gaps",
            &[
                Binding::Sampled,
                Binding::Sampled,
                Binding::Storage(COLOR_FORMAT),
                Binding::Storage(DEPTH_FORMAT),
                Binding::Buffer,
            ],
        );
        // Same bindings as filling: one layer in, the other out.
        let occlusion = pipeline(
            device,
            "occlusion",
            shaders::OCCLUSION,
            "occlusion",
            &[&fill_layout],
        );
        let compose = [false, true].map(|edl| {
            pipeline_with(
                device,
                "compose",
                &format!("{}\n{}", shaders::EDL, shaders::COMPOSE),
                "compose",
                &[&compose_layout],
                &[("EDL", edl as u32 as f64)],
            )
        });
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
            fills: HashMap::new(),
            fill_radius: 0,
            occlusion,
            compose_layout,
            compose,
            blended_out_layout,
            blended: HashMap::new(),
            edl: false,
            gaps_layout,
            gaps: HashMap::new(),
            uniforms,
        }
    }

    /// The pixel buffers' bind group layout and the body that reads them, per kind.
    fn pixel_source(kind: PixelKind) -> Option<(usize, &'static str)> {
        match kind {
            PixelKind::Hardware => None,
            PixelKind::Key64 => Some((1, shaders::RESOLVE_MIN64)),
            PixelKind::TwoPass32 => Some((2, shaders::RESOLVE_MIN32)),
            PixelKind::Hqs => Some((2, shaders::BLEND_HQS)),
            PixelKind::Hqs1r => Some((3, shaders::BLEND_HQS1R)),
        }
    }

    fn resolve_pipeline(
        &mut self,
        device: &wgpu::Device,
        kind: PixelKind,
        splat_sizes: bool,
    ) -> Option<&(wgpu::ComputePipeline, wgpu::BindGroupLayout)> {
        let (n, body) = Self::pixel_source(kind)?;
        let blended = matches!(kind, PixelKind::Hqs | PixelKind::Hqs1r);
        let out = &self.resolve_out_layout;
        Some(self.resolve.entry((kind, splat_sizes)).or_insert_with(|| {
            let group1 = storage_layout(device, n, true);
            let source = if blended {
                shaders::resolve_pass(&format!("{body}\n{}", shaders::RESOLVE_BLENDED))
            } else {
                shaders::resolve_pass(body)
            };
            let p = pipeline_with(
                device,
                "resolve",
                &source,
                "resolve",
                &[out, &group1],
                &[("SPLAT_SIZES", splat_sizes as u32 as f64)],
            );
            (p, group1)
        }))
    }

    /// Writes this frame's uniforms; call before recording. `fov_y_deg` sizes pixels for the
    /// occlusion filter and splats for EDL.
    pub fn prepare(
        &mut self,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        s: &ScreenSettings,
        fov_y_deg: f64,
    ) {
        let screen = ScreenUniform {
            size: [target.width, target.height],
            _pad: [0; 2],
        };
        self.fill_radius = s.fill_radius;
        self.edl = s.edl.is_some();
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

    /// A bind group of a uniform range and texture views, bindings 0, 1, 2…
    fn textures(
        &self,
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        (offset, size): (u64, u64),
        textures: &[&wgpu::Texture],
    ) -> wgpu::BindGroup {
        let views: Vec<wgpu::TextureView> = textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
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
    }

    /// Records the resolve of `kind`'s pixel `buffers` into the target's raster layer.
    pub fn resolve(
        &mut self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        target: &RenderTarget,
        kind: PixelKind,
        splat_sizes: bool,
        buffers: &[&wgpu::Buffer],
    ) {
        let Some((p, g1)) = self.resolve_pipeline(device, kind, splat_sizes).cloned() else {
            return;
        };
        let layer = &target.raster_layer;
        let group0 = self.textures(
            device,
            &self.resolve_out_layout,
            (SCREEN_OFFSET, 16),
            &[&layer.color, &layer.depth],
        );
        let group1 = storage_group(device, "pixel buffers", &g1, buffers);
        pass.set_pipeline(&p);
        pass.set_bind_group(0, &group0, &[]);
        pass.set_bind_group(1, &group1, &[]);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }

    /// Records a filter from layer `src` to layer `dst`.
    pub fn filter(
        &mut self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        target: &RenderTarget,
        filter: Filter,
        src: &Layer,
        dst: &Layer,
    ) {
        let (pipeline, offset) = match filter {
            Filter::Occlusion => (self.occlusion.clone(), OCCLUSION_OFFSET),
            // Filling reads no uniform; its layout is the occlusion filter's.
            Filter::HoleFill => {
                let layout = &self.fill_layout;
                let fill = self.fills.entry(self.fill_radius).or_insert_with(|| {
                    pipeline_with(
                        device,
                        "fill",
                        shaders::FILL,
                        "fill",
                        &[layout],
                        &[("RADIUS", self.fill_radius as f64)],
                    )
                });
                (fill.clone(), SCREEN_OFFSET)
            }
        };
        let group = self.textures(
            device,
            &self.fill_layout,
            (offset, 16),
            &[&src.color, &src.depth, &dst.color, &dst.depth],
        );
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }

    /// Records background and EDL from layer `src` into the output image.
    pub fn compose(
        &self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        target: &RenderTarget,
        src: &Layer,
    ) {
        let group = self.textures(
            device,
            &self.compose_layout,
            (COMPOSE_OFFSET, 32),
            &[&src.color, &src.depth, &target.output],
        );
        pass.set_pipeline(&self.compose[self.edl as usize]);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }

    /// Records the gap filling of closest-point splats of `shape` from layer `src` to `dst`,
    /// with `tiles` (a buffer of at least a u32 per 16 × 16 tile) for the largest sides.
    #[allow(clippy::too_many_arguments)]
    pub fn gaps(
        &mut self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        target: &RenderTarget,
        shape: SplatShape,
        src: &Layer,
        dst: &Layer,
        tiles: &wgpu::Buffer,
    ) {
        let layout = &self.gaps_layout;
        let (tile_pass, fill) = self.gaps.entry(shape).or_insert_with(|| {
            let circle = [("CIRCLE", (shape == SplatShape::Circle) as u32 as f64)];
            let make = |entry| {
                pipeline_with(
                    device,
                    "splat gaps",
                    shaders::GAPS,
                    entry,
                    &[layout],
                    &circle,
                )
            };
            (make("tiles_pass"), make("fill"))
        });
        let views: Vec<wgpu::TextureView> = [&src.color, &src.depth, &dst.color, &dst.depth]
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let mut entries: Vec<wgpu::BindGroupEntry> = views
            .iter()
            .enumerate()
            .map(|(i, v)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 4,
            resource: tiles.as_entire_binding(),
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat gaps"),
            layout,
            entries: &entries,
        });
        pass.set_bind_group(0, &group, &[]);
        pass.set_pipeline(tile_pass);
        pass.dispatch_workgroups(target.width.div_ceil(16), target.height.div_ceil(16), 1);
        pass.set_pipeline(fill);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }

    /// Records blending's normalisation, background and EDL straight from `kind`'s pixel
    /// `buffers` into the output image.
    pub fn compose_blended(
        &mut self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        target: &RenderTarget,
        kind: PixelKind,
        buffers: &[&wgpu::Buffer],
    ) {
        let Some((n, body)) = Self::pixel_source(kind) else {
            return;
        };
        let out = &self.blended_out_layout;
        let edl = self.edl;
        let (p, g1) = self
            .blended
            .entry((kind, edl))
            .or_insert_with(|| {
                let group1 = storage_layout(device, n, true);
                let source = format!("{}\n{body}\n{}", shaders::EDL, shaders::COMPOSE_BLENDED);
                let p = pipeline_with(
                    device,
                    "normalise and compose",
                    &source,
                    "compose",
                    &[out, &group1],
                    &[("EDL", edl as u32 as f64)],
                );
                (p, group1)
            })
            .clone();
        let group0 = self.textures(
            device,
            &self.blended_out_layout,
            (COMPOSE_OFFSET, 32),
            &[&target.output],
        );
        let group1 = storage_group(device, "pixel buffers", &g1, buffers);
        pass.set_pipeline(&p);
        pass.set_bind_group(0, &group0, &[]);
        pass.set_bind_group(1, &group1, &[]);
        pass.dispatch_workgroups(target.width.div_ceil(8), target.height.div_ceil(8), 1);
    }
}
