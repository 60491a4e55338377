//! The copy kernel: the practical memory bandwidth of this GPU through wgpu, measured in the same
//! process as the rasterizers so their GB/s can be put in proportion.

use crate::context::GpuContext;
use crate::device_memory::MappedBuffer;
use crate::raster::grid;
use crate::shaders;
use crate::shuffle::StagedRegion;
use crate::target::map_read;
use crate::GpuError;

/// Median GB/s (bytes read + bytes written) of copying `bytes` bytes, over `runs` runs.
/// `None` without timestamp queries.
pub fn copy_bandwidth(ctx: &GpuContext, bytes: u64, runs: u32) -> Result<Option<f64>, GpuError> {
    if !ctx.caps.timestamps {
        return Ok(None);
    }
    let device = &ctx.device;
    let bytes =
        (bytes / 16 * 16).clamp(16, ctx.caps.max_binding.min(ctx.caps.max_buffer) / 16 * 16);
    let count = (bytes / 16) as u32;
    let make = |label, usage| {
        ctx.checked("allocating the copy buffers", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        })
    };
    let src = make(
        "copy src",
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    )?;
    let dst = make("copy dst", wgpu::BufferUsages::STORAGE)?;
    let params = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("copy params"),
        size: 16,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue
        .write_buffer(&params, 0, bytemuck::cast_slice(&[count, 0, 0, 0]));
    let module = shaders::module(device, "copy", shaders::COPY);
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("copy"),
        layout: None,
        module: &module,
        entry_point: Some("copy"),
        compilation_options: Default::default(),
        cache: None,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("copy"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: src.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: dst.as_entire_binding(),
            },
        ],
    });
    let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("copy timestamps"),
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolve = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let period = ctx.queue.get_timestamp_period() as f64;
    let [x, y] = grid(count.div_ceil(256 * 4));
    let mut times = Vec::new();
    // One warm-up run, then the measured ones.
    for _ in 0..runs.max(1) + 1 {
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("copy"),
                timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                    query_set: &queries,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        enc.resolve_query_set(&queries, 0..2, &resolve, 0);
        enc.copy_buffer_to_buffer(&resolve, 0, &readback, 0, 16);
        ctx.queue.submit([enc.finish()]);
        let t: Vec<u64> = bytemuck::pod_collect_to_vec(&map_read(ctx, &readback)?);
        times.push(t[1].saturating_sub(t[0]) as f64 * period);
    }
    times.remove(0);
    times.sort_by(f64::total_cmp);
    let ns = times[times.len() / 2].max(1.0);
    Ok(Some(2.0 * bytes as f64 / ns))
}

/// How fast points reach the GPU through mapped upload memory, the way progressive loading
/// sends them: threads write into freshly mapped `MAP_WRITE` buffers ([`BUS_WRITERS`] at a
/// time), then the GPU copies them into a device buffer (over PCIe, unless the upload memory
/// already lies in VRAM).
///
/// [`BUS_WRITERS`]: crate::shuffle::BUS_WRITERS
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UploadBandwidth {
    /// Bytes moved per run.
    pub bytes: u64,
    /// Median GB/s of every rayon thread writing into the mapped buffers.
    pub write_gbs: f64,
    /// Median GB/s of the GPU copying them into a device buffer (wall time, submit to done).
    pub copy_gbs: f64,
    /// The other way over the bus: median GB/s of every rayon thread writing host memory
    /// (system RAM the GPU reads), and of the GPU copying it into a device buffer. `None`
    /// where the device has no such memory or it cannot be made outside wgpu.
    pub host_write_gbs: Option<f64>,
    pub host_copy_gbs: Option<f64>,
    /// GB/s at which the driver makes such memory (one buffer after another): what staging
    /// batches in it would pay before the first write.
    pub host_make_gbs: Option<f64>,
}

/// Measures [`UploadBandwidth`] with `bytes` in buffers of `chunk` bytes, over `runs` runs.
pub fn upload_bandwidth(
    ctx: &GpuContext,
    bytes: u64,
    chunk: u64,
    runs: u32,
) -> Result<UploadBandwidth, GpuError> {
    use rayon::prelude::*;
    let device = &ctx.device;
    let chunk = (chunk / 16 * 16).clamp(16, ctx.caps.max_buffer / 16 * 16);
    let chunks = bytes.div_ceil(chunk).max(1);
    let bytes = chunks * chunk;
    let dst = ctx.checked("allocating the upload target", || {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("upload target"),
            size: chunk,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    // What the threads write: cached source bytes, as a decoder's output is.
    let pattern: Vec<u8> = (0..1u32 << 20)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    let (mut writes, mut copies) = (Vec::new(), Vec::new());
    // One warm-up run, then the measured ones.
    for _ in 0..runs.max(1) + 1 {
        let staged = ctx.checked("allocating upload memory", || {
            (0..chunks)
                .map(|_| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("upload memory"),
                        size: chunk,
                        usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: true,
                    })
                })
                .collect::<Vec<_>>()
        })?;
        let started = web_time::Instant::now();
        let mut views = staged
            .iter()
            .map(|b| b.get_mapped_range_mut(..))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| GpuError::InvalidInput(format!("mapping upload memory: {e}")))?;
        let mut pieces = Vec::new();
        for view in &mut views {
            let mut rest = view.slice(..);
            while !rest.is_empty() {
                let at = rest.len().min(pattern.len());
                let (piece, tail) = rest.split_at(at);
                pieces.push(piece);
                rest = tail;
            }
        }
        let pieces: Vec<StagedRegion> = pieces.into_iter().map(StagedRegion).collect();
        pieces
            .into_par_iter()
            .map(|mut p| {
                let len = p.0.len();
                p.write(&pattern[..len])
            })
            .collect::<Result<(), GpuError>>()?;
        drop(views);
        writes.push(started.elapsed().as_secs_f64());
        for b in &staged {
            b.unmap();
        }
        copies.push(copy_time(ctx, staged.iter(), &dst, chunk)?);
    }
    let median = |mut v: Vec<f64>| {
        v.remove(0);
        v.sort_by(f64::total_cmp);
        bytes as f64 / v[v.len() / 2].max(1e-9) / 1e9
    };
    let (host_write_gbs, host_copy_gbs, host_make_gbs) =
        match host_bandwidth(ctx, &dst, chunk, chunks, runs, &pattern)? {
            Some(t) => (
                Some(median(t.writes)),
                Some(median(t.copies)),
                Some(bytes as f64 / t.made.max(1e-9) / 1e9),
            ),
            None => (None, None, None),
        };
    Ok(UploadBandwidth {
        bytes,
        write_gbs: median(writes),
        copy_gbs: median(copies),
        host_write_gbs,
        host_copy_gbs,
        host_make_gbs,
    })
}

/// Seconds of the threads writing `chunks` host buffers of `chunk` bytes and of the GPU
/// copying them into `dst`, a warm-up run and `runs` more; `None` without such memory.
fn host_bandwidth(
    ctx: &GpuContext,
    dst: &wgpu::Buffer,
    chunk: u64,
    chunks: u64,
    runs: u32,
    pattern: &[u8],
) -> Result<Option<RunTimes>, GpuError> {
    use rayon::prelude::*;
    let Some(alloc) = ctx.direct_allocator() else {
        return Ok(None);
    };
    let mut staged = Vec::new();
    let making = web_time::Instant::now();
    for _ in 0..chunks {
        match alloc.host_buffer("host upload memory", chunk, wgpu::BufferUsages::COPY_SRC)? {
            Some(b) => staged.push(b),
            None => return Ok(None),
        }
    }
    let made = making.elapsed().as_secs_f64();
    let (mut writes, mut copies) = (Vec::new(), Vec::new());
    for _ in 0..runs.max(1) + 1 {
        let started = web_time::Instant::now();
        staged.par_iter_mut().for_each(|b| {
            b.bytes().par_chunks_mut(pattern.len()).for_each(|piece| {
                let len = piece.len();
                piece.copy_from_slice(&pattern[..len]);
            })
        });
        writes.push(started.elapsed().as_secs_f64());
        copies.push(copy_time(
            ctx,
            staged.iter().map(MappedBuffer::buffer),
            dst,
            chunk,
        )?);
    }
    Ok(Some(RunTimes {
        writes,
        copies,
        made,
    }))
}

/// Seconds of the GPU copying the first `chunk` bytes of each of `sources` into `dst`, from
/// submit to done.
fn copy_time<'a>(
    ctx: &GpuContext,
    sources: impl Iterator<Item = &'a wgpu::Buffer>,
    dst: &wgpu::Buffer,
    chunk: u64,
) -> Result<f64, GpuError> {
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    for b in sources {
        enc.copy_buffer_to_buffer(b, 0, dst, 0, chunk);
    }
    let started = web_time::Instant::now();
    ctx.queue.submit([enc.finish()]);
    ctx.wait()?;
    Ok(started.elapsed().as_secs_f64())
}

/// Seconds of each run's writes and copies, and of making the memory.
struct RunTimes {
    writes: Vec<f64>,
    copies: Vec<f64>,
    made: f64,
}
