//! Temporal reuse for the virtualized path (reuse.wgsl): a moving camera's frame starts from
//! the surface the last frame showed, reprojected pixel by pixel, and the LoD's points fill
//! in around it. Only closest-point variants keep a depth and colour per pixel to reuse.

use crate::context::GpuContext;
use crate::raster::storage_group;
use crate::shaders;
use crate::GpuError;
use bytemuck::{Pod, Zeroable};
use pointlet_core::camera::{mat_mul, to_f32};
use pointlet_core::lod::Mat4;
use pointlet_core::Camera;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ReuseUniform {
    to_new: [[f32; 4]; 4],
    size: [u32; 2],
    _pad: [u32; 2],
}

struct ReuseBuffers {
    previous: wgpu::Buffer,
    ghost: wgpu::Buffer,
    ages: wgpu::Buffer,
    ghost_ages: wgpu::Buffer,
    size: (u32, u32),
}

impl ReuseBuffers {
    fn group(
        &self,
        ctx: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        uniform: &wgpu::Buffer,
        keys: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        storage_group(
            &ctx.device,
            "temporal reuse",
            layout,
            &[
                uniform,
                &self.previous,
                keys,
                &self.ghost,
                &self.ages,
                &self.ghost_ages,
            ],
        )
    }

    fn clear_ghosts(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.ghost, 0, None);
        enc.clear_buffer(&self.ghost_ages, 0, None);
    }
}

/// The last frame's keys and the camera they were seen with, and the passes that reuse them.
pub struct TemporalReuse {
    reproject: wgpu::ComputePipeline,
    keep: wgpu::ComputePipeline,
    uniform: wgpu::Buffer,
    /// Keys kept from the last frame and the reprojected keys of this one, with their ages,
    /// for one image size.
    buffers: Option<ReuseBuffers>,
    /// The camera of the kept keys (`None`: nothing kept).
    kept: Option<Camera>,
}

impl TemporalReuse {
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        ctx.checked("building the temporal reuse passes", || {
            let module = shaders::module(device, "temporal reuse", shaders::REUSE);
            let pipeline = |entry: &str| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: None,
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            Self {
                reproject: pipeline("reproject"),
                keep: pipeline("keep"),
                uniform: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("temporal reuse"),
                    size: std::mem::size_of::<ReuseUniform>() as u64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                buffers: None,
                kept: None,
            }
        })
    }

    /// Drops the kept frame (the next frame starts empty).
    pub fn forget(&mut self) {
        self.kept = None;
    }

    /// Whether a frame is kept to reuse.
    pub fn has_frame(&self) -> bool {
        self.kept.is_some()
    }

    /// Records the reprojection of the kept frame into the frame's `keys` (an image of `size`)
    /// as seen by `camera` (nothing when no frame of this size is kept); true if it did.
    pub(crate) fn record_reproject(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        keys: &wgpu::Buffer,
        size: (u32, u32),
        camera: &Camera,
    ) -> Result<bool, GpuError> {
        let (Some(last), Some(buffers)) = (&self.kept, &self.buffers) else {
            return Ok(false);
        };
        if buffers.size != size {
            return Ok(false);
        }
        let aspect = size.0 as f64 / size.1 as f64;
        let uniform = ReuseUniform {
            to_new: to_f32(&reprojection(last, camera, aspect)),
            size: [size.0, size.1],
            _pad: [0; 2],
        };
        ctx.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        buffers.clear_ghosts(enc);
        let group = buffers.group(
            ctx,
            &self.reproject.get_bind_group_layout(0),
            &self.uniform,
            keys,
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("reproject last frame"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.reproject);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(size.0.div_ceil(8), size.1.div_ceil(8), 1);
        Ok(true)
    }

    /// Records keeping the frame's `keys` (less the pixels reprojection won) for the next
    /// frame, seen by `camera`. `reprojected`: whether this frame's ghost buffer is current.
    pub(crate) fn record_keep(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        keys: &wgpu::Buffer,
        size: (u32, u32),
        camera: &Camera,
        reprojected: bool,
    ) -> Result<(), GpuError> {
        if self.buffers.as_ref().is_none_or(|b| b.size != size) {
            let pixels = size.0 as u64 * size.1 as u64;
            let buffer = |label: &str, bytes: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: (pixels * bytes).max(16),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            let buffers =
                ctx.checked("allocating the temporal reuse buffers", || ReuseBuffers {
                    previous: buffer("kept keys", 8),
                    ghost: buffer("reprojected keys", 8),
                    ages: buffer("kept ages", 4),
                    ghost_ages: buffer("reprojected ages", 4),
                    size,
                })?;
            self.buffers = Some(buffers);
        }
        let Some(buffers) = &self.buffers else {
            return Ok(());
        };
        // After a reprojection the uniform already holds this size (and the matrix, which
        // keeping ignores): writing it again would replace the matrix before either pass runs.
        if !reprojected {
            buffers.clear_ghosts(enc);
            let uniform = ReuseUniform {
                to_new: [[0.0; 4]; 4],
                size: [size.0, size.1],
                _pad: [0; 2],
            };
            ctx.queue
                .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        }
        let group = buffers.group(
            ctx,
            &self.keep.get_bind_group_layout(0),
            &self.uniform,
            keys,
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("keep frame"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.keep);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(size.0.div_ceil(8), size.1.div_ceil(8), 1);
        self.kept = Some(*camera);
        Ok(())
    }
}

/// The matrix taking (ndc.x · w, ndc.y · w, w, 1) of a pixel seen by `last` (w its view depth)
/// to clip space of `next`, with both eyes' offset applied in f64.
pub fn reprojection(last: &Camera, next: &Camera, aspect: f64) -> Mat4 {
    let p = last.projection(aspect);
    // (u, v, w, 1) → view position of the last camera: x = u / P00, y = v / P11, z = -w.
    let to_view: Mat4 = [
        [1.0 / p[0][0], 0.0, 0.0, 0.0],
        [0.0, 1.0 / p[1][1], 0.0, 0.0],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    // The rotation is orthonormal: its inverse is its transpose.
    let r = last.rotation();
    let mut to_world = [[0.0; 4]; 4];
    for (c, col) in to_world.iter_mut().enumerate() {
        for (k, v) in col.iter_mut().enumerate() {
            *v = r[k][c];
        }
    }
    let mut shift: Mat4 = [[0.0; 4]; 4];
    for (i, col) in shift.iter_mut().enumerate() {
        col[i] = 1.0;
    }
    shift[3] = [
        last.eye[0] - next.eye[0],
        last.eye[1] - next.eye[1],
        last.eye[2] - next.eye[2],
        1.0,
    ];
    let back = mat_mul(&shift, &mat_mul(&to_world, &to_view));
    mat_mul(&next.relative_view_projection(aspect), &back)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::lod::transform;

    fn camera(eye: [f64; 3]) -> Camera {
        Camera {
            eye,
            target: [10.0, 20.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y_deg: 55.0,
            near: 0.1,
            far: 1000.0,
        }
    }

    #[test]
    fn a_pixel_reprojects_to_where_the_new_camera_sees_its_point() {
        let (last, next) = (camera([3.0, -40.0, 25.0]), camera([9.0, -35.0, 22.0]));
        let aspect = 1.5;
        let m = reprojection(&last, &next, aspect);
        for p in [[10.0, 20.0, 0.0], [4.0, 12.5, 3.0], [18.0, 30.0, -2.0]] {
            // The point as the last camera saw it: ndc and view depth.
            let c = transform(&last.view_projection(aspect), p);
            let (nx, ny, w) = (c[0] / c[3], c[1] / c[3], c[3]);
            let got: [f64; 4] = std::array::from_fn(|r| {
                (0..4).map(|k| m[k][r] * [nx * w, ny * w, w, 1.0][k]).sum()
            });
            let want = transform(&next.view_projection(aspect), p);
            for a in 0..4 {
                assert!(
                    (got[a] - want[a]).abs() < 1e-9 * want[3].abs().max(1.0),
                    "{got:?} {want:?}"
                );
            }
        }
    }
}
