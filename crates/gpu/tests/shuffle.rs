//! The GPU shuffle pass against the CPU permutation: batches scattered into a shuffled
//! buffer land exactly where `ShufflePermutation::target` (or a store's `GroupRows`) puts
//! them, and the shader's 32-bit
//! modular arithmetic is exact up to primes just below 2^32. Batches go through the queue or
//! through upload memory (`StagedBatch`: made by Vulkan or mapped by wgpu), alternately.

mod common;

use pointlet_core::progressive::{prime_3_mod_4_at_most, GroupRows, ShufflePermutation, SlotOrder};
use pointlet_core::shuffle::SplitMix64;
use pointlet_gpu::shuffle::{
    bus_time, montgomery_constants, Dequantize, EncodedBatch, ShufflePass, ShuffledBuffer,
    ShuffledContents, StagedBatch, UploadMemory,
};
use pointlet_gpu::{encode_point, GpuContext, GpuError, PointEncoding};

/// Distinct pseudo-random streams for `n` points, in load order.
fn points(n: u32, encoding: PointEncoding, seed: u64) -> ShuffledContents {
    let mut rng = SplitMix64::new(seed);
    let mut word = || rng.next_u64() as u32;
    let words = (encoding.position_bytes() / 4) as usize;
    let compact = encoding == PointEncoding::Compact8;
    let mut out = ShuffledContents::default();
    for _ in 0..n {
        out.positions.extend((0..words).map(|_| word()));
        if compact {
            out.fine.push(word());
        }
        out.colors.push(word());
    }
    out
}

/// Where the CPU permutation puts every point.
fn reference(loaded: &ShuffledContents, n: u32, encoding: PointEncoding) -> ShuffledContents {
    let perm = SlotOrder::Permuted(ShufflePermutation::new(n as u64).unwrap());
    placed(loaded, perm, n, encoding)
}

/// Where `order` puts every point in a buffer of `slots` slots (those past them left out).
fn placed(
    loaded: &ShuffledContents,
    order: SlotOrder,
    slots: u32,
    encoding: PointEncoding,
) -> ShuffledContents {
    let words = (encoding.position_bytes() / 4) as usize;
    let compact = !loaded.fine.is_empty();
    let slots = slots as usize;
    let mut out = ShuffledContents {
        positions: vec![0; slots * words],
        fine: vec![0; if compact { slots } else { 0 }],
        colors: vec![0; slots],
    };
    for i in 0..loaded.colors.len() {
        let Some(t) = order.target(i as u64).map(|t| t as usize) else {
            continue;
        };
        if t >= slots {
            continue;
        }
        out.colors[t] = loaded.colors[i];
        out.positions[t * words..(t + 1) * words]
            .copy_from_slice(&loaded.positions[i * words..(i + 1) * words]);
        if !loaded.fine.is_empty() {
            out.fine[t] = loaded.fine[i];
        }
    }
    out
}

/// Upload memory made by Vulkan directly (lavapipe's memory, which the host sees) besides
/// the memory wgpu maps.
fn upload_memory(ctx: &GpuContext) -> UploadMemory {
    let upload = UploadMemory::new(ctx);
    assert!(
        upload.makes_directly(),
        "no upload memory made directly on Vulkan"
    );
    upload
}

/// Scatters `loaded` in batches of the given sizes (the last takes the rest): every other
/// one through a staged batch, those made by Vulkan and mapped by wgpu by turns.
fn scatter_in_batches(
    ctx: &GpuContext,
    pass: &mut ShufflePass,
    dst: &ShuffledBuffer,
    loaded: &ShuffledContents,
    sizes: &[usize],
    upload: &UploadMemory,
) {
    let words = (dst.encoding().position_bytes() / 4) as usize;
    let fine_words = usize::from(!loaded.fine.is_empty());
    let n = loaded.colors.len();
    let mut first = 0;
    for (k, size) in sizes.iter().enumerate() {
        let end = if k + 1 == sizes.len() {
            n
        } else {
            (first + size).min(n)
        };
        let batch = EncodedBatch {
            positions: &loaded.positions[first * words..end * words],
            fine: &loaded.fine[first * fine_words..end * fine_words],
            colors: &loaded.colors[first..end],
        };
        if k % 2 == 1 {
            scatter_staged(ctx, upload, k / 2 % 2 == 0, pass, dst, first as u32, batch);
        } else {
            pass.scatter(ctx, dst, first as u32, batch).unwrap();
        }
        first = end;
    }
}

/// `batch` written into a staged batch with room to spare (the regions' offsets follow from
/// the capacity), in memory Vulkan made or memory wgpu maps, and scattered.
fn scatter_staged(
    ctx: &GpuContext,
    upload: &UploadMemory,
    direct: bool,
    pass: &mut ShufflePass,
    dst: &ShuffledBuffer,
    first: u32,
    batch: EncodedBatch<'_>,
) {
    let mut staged = staged_batch(
        upload,
        direct,
        dst.encoding(),
        batch.colors.len() as u64 + 3,
    );
    write_staged(&mut staged, batch);
    pass.scatter_staged(ctx, dst, first, &staged).unwrap();
}

fn staged_batch(
    upload: &UploadMemory,
    direct: bool,
    encoding: PointEncoding,
    capacity: u64,
) -> StagedBatch {
    let staged = if direct {
        StagedBatch::direct(upload, encoding, capacity)
            .unwrap()
            .unwrap()
    } else {
        StagedBatch::new(upload, encoding, capacity).unwrap()
    };
    assert_eq!(staged.is_direct(), direct);
    staged
}

/// Writes `batch` into `staged`, each region in two halves as two threads would, and
/// finishes it.
fn write_staged(staged: &mut StagedBatch, batch: EncodedBatch<'_>) {
    let count = batch.colors.len();
    let mut view = staged.map().unwrap();
    let regions = view.regions();
    let half = count / 2;
    for (region, words) in [
        (regions.positions, batch.positions),
        (regions.fine, batch.fine),
        (regions.colors, batch.colors),
    ] {
        let per_point = words.len() / count.max(1);
        let (mut a, rest) = region.split_at(half * per_point * 4);
        let (mut b, _spare) = rest.split_at((count - half) * per_point * 4);
        a.write(&words[..half * per_point]).unwrap();
        b.write(&words[half * per_point..]).unwrap();
    }
    drop(view);
    staged.finish(count as u64);
}

#[test]
fn batches_land_where_the_cpu_permutation_puts_them() {
    let ctx = common::context();
    let upload = upload_memory(&ctx);
    let mut pass = ShufflePass::new(&ctx).unwrap();
    // Not a prime: the slots above P stay in place. Batch sizes cross chunk borders, and one
    // outgrows the first staging allocation.
    let n = 300_010u32;
    let sizes = [1, 4_999, 100_000, 37, 70_000, 0];
    for (encoding, chunk_slots) in [
        (PointEncoding::Full16, u32::MAX),
        (PointEncoding::Full16, 70_001),
        (PointEncoding::Compact8, 123_457),
    ] {
        let dst = ShuffledBuffer::with_chunk_slots(&ctx, encoding, n, chunk_slots).unwrap();
        let expected_chunks = if chunk_slots == u32::MAX {
            1
        } else {
            n.div_ceil(chunk_slots) as usize
        };
        assert_eq!(dst.chunk_count(), expected_chunks);
        let loaded = points(n, encoding, n as u64 ^ chunk_slots as u64);
        scatter_in_batches(&ctx, &mut pass, &dst, &loaded, &sizes, &upload);
        let got = dst.read(&ctx).unwrap();
        let want = reference(&loaded, n, encoding);
        assert_eq!(got.colors.len(), n as usize);
        let wrong = (0..n as usize)
            .filter(|&s| got.colors[s] != want.colors[s])
            .count();
        assert_eq!(
            wrong, 0,
            "{encoding:?} / {chunk_slots}: {wrong} slots differ"
        );
        assert!(
            got == want,
            "{encoding:?} / {chunk_slots}: the streams differ"
        );
    }
}

/// One staged batch of each kind carries a whole load: each batch comes back through
/// `recycle` once the GPU has copied it, and the next one is written into the same memory.
#[test]
fn a_recycled_staged_batch_carries_the_next_batch() {
    let ctx = common::context();
    let upload = upload_memory(&ctx);
    let mut pass = ShufflePass::new(&ctx).unwrap();
    let (n, size) = (50_000u32, 7_000usize);
    let loaded = points(n, PointEncoding::Full16, 11);
    let want = reference(&loaded, n, PointEncoding::Full16);
    for direct in [true, false] {
        let dst = ShuffledBuffer::new(&ctx, PointEncoding::Full16, n).unwrap();
        let (back, returned) = std::sync::mpsc::channel();
        let mut staged = Some(staged_batch(
            &upload,
            direct,
            PointEncoding::Full16,
            size as u64,
        ));
        for first in (0..n as usize).step_by(size) {
            let mut b = staged.take().unwrap_or_else(|| {
                ctx.wait().unwrap();
                returned
                    .recv_timeout(std::time::Duration::from_secs(10))
                    .expect("the batch came back once the GPU was done with it")
            });
            let end = (first + size).min(n as usize);
            let batch = EncodedBatch {
                positions: &loaded.positions[first * 3..end * 3],
                fine: &[],
                colors: &loaded.colors[first..end],
            };
            write_staged(&mut b, batch);
            pass.scatter_staged(&ctx, &dst, first as u32, &b).unwrap();
            let back = back.clone();
            b.recycle(move |b| {
                let _ = back.send(b);
            });
        }
        let got = dst.read(&ctx).unwrap();
        assert!(got == want, "made directly: {direct}: the streams differ");
    }
}

#[test]
fn the_bus_counts_what_its_writers_copy() {
    let ctx = common::context();
    let upload = upload_memory(&ctx);
    let n = 20_000u32;
    let loaded = points(n, PointEncoding::Full16, 5);
    let batch = EncodedBatch {
        positions: &loaded.positions,
        fine: &[],
        colors: &loaded.colors,
    };
    let bytes = 4 * (batch.positions.len() + batch.colors.len()) as u64;
    for direct in [true, false] {
        let mut staged = staged_batch(&upload, direct, PointEncoding::Full16, u64::from(n));
        let before = bus_time();
        write_staged(&mut staged, batch);
        // Other tests may copy meanwhile: this one's copies are at least in the counts.
        let added = bus_time().since(&before);
        assert!(
            added.bytes >= bytes,
            "{} of {bytes} bytes counted",
            added.bytes
        );
        assert!(
            added.busy > std::time::Duration::ZERO && added.writing > std::time::Duration::ZERO,
            "{added:?}"
        );
    }
}

#[test]
fn batches_of_interleaved_groups_land_row_by_row() {
    let ctx = common::context();
    let upload = upload_memory(&ctx);
    let mut pass = ShufflePass::new(&ctx).unwrap();
    // Groups with a short last group (300 010 = 292 · 1024 + 1 002); batches that
    // start and end inside groups, cross chunk borders and outgrow the first staging; a
    // buffer with every point and one with fewer slots (later rows left out), the order in
    // one chunk over buffers of any size or in the buffers' chunks (whole groups each,
    // slots left unused at their ends).
    let n = 300_010u32;
    let sizes = [1, 4_999, 100_000, 37, 70_000, 0];
    // Groups of 1 024 permute single groups in a row, groups of 16 blocks of groups.
    let rows = |group, max_slots| GroupRows::new(n as u64, group, max_slots).unwrap();
    let whole = |g: GroupRows| (SlotOrder::Interleaved(g), None);
    let chunked =
        |g: GroupRows, cs: u64| (SlotOrder::Interleaved(g.chunked(cs).unwrap()), Some(cs));
    for (encoding, (order, chunk_slots)) in [
        (PointEncoding::Full16, whole(rows(1024, u64::MAX))),
        (PointEncoding::Compact8, whole(rows(1024, u64::MAX))),
        (PointEncoding::Full16, whole(rows(1024, 123_456))),
        (PointEncoding::Full16, chunked(rows(16, u64::MAX), 70_000)),
        (PointEncoding::Full16, chunked(rows(1024, 123_456), 50_000)),
        (PointEncoding::Compact8, chunked(rows(16, 123_456), 40_000)),
        (PointEncoding::Full16, whole(rows(16, 123_456))),
    ] {
        let slots = order.physical_slots() as u32;
        // Unchunked orders over buffers split anyway (the order's one chunk spans them).
        let buffer_chunks = chunk_slots.unwrap_or(if encoding == PointEncoding::Full16 {
            70_001
        } else {
            u64::from(u32::MAX)
        });
        let mut dst =
            ShuffledBuffer::with_chunk_slots(&ctx, encoding, slots, buffer_chunks as u32).unwrap();
        dst.set_order(order).unwrap();
        assert_eq!((dst.slots(), dst.order()), (slots, order));
        assert_eq!(dst.placed(), order.placed());
        let loaded = points(n, encoding, 7 + slots as u64);
        scatter_in_batches(&ctx, &mut pass, &dst, &loaded, &sizes, &upload);
        let got = dst.read(&ctx).unwrap();
        let want = placed(&loaded, order, slots, encoding);
        let wrong = (0..slots as usize)
            .filter(|&s| got.colors[s] != want.colors[s])
            .count();
        assert_eq!(wrong, 0, "{encoding:?} / {order:?}: {wrong} slots differ");
        assert!(got == want, "{encoding:?} / {order:?}: the streams differ");
    }
    // An order that spans fewer slots than the buffer has is refused.
    let mut small = ShuffledBuffer::new(&ctx, PointEncoding::Full16, 1000).unwrap();
    let short = SlotOrder::Interleaved(GroupRows::new(999, 64, u64::MAX).unwrap());
    assert!(matches!(
        small.set_order(short),
        Err(GpuError::InvalidInput(_))
    ));
}

/// Distance between two floats in f32 steps at `at` (the larger of their magnitude and
/// `at`): near zero, a few steps of a tiny magnitude are not an error worth counting.
fn ulps(a: f32, b: f32, at: f32) -> f64 {
    let x = a.abs().max(b.abs()).max(at);
    let step = f32::from_bits(x.to_bits() + 1) - x;
    (a as f64 - b as f64).abs() / step as f64
}

#[test]
fn stored_positions_are_dequantized_on_the_gpu_within_an_ulp() {
    let ctx = common::context();
    let upload = UploadMemory::new(&ctx);
    let mut pass = ShufflePass::new(&ctx).unwrap();
    // A LAS-like quantization (mm, inexact in binary) far from the origin, and a coarse one.
    let cases = [
        (
            [0.001, 0.001, 0.001],
            [500_000.0, 4_000_000.0, 0.0],
            [503_210.125, 4_001_999.7, 88.3],
        ),
        ([0.25, 0.5, 0.01], [-7.0, 3.0, 1e6], [0.0, 0.0, 1e6 + 12.0]),
    ];
    let mut rng = SplitMix64::new(11);
    for (scale, offset, origin) in cases {
        let dq = Dequantize::new(scale, offset, origin);
        // Near the origin, within 2^24 steps of it, and anywhere in i32 (the split halves).
        let base = [0, 1, 2].map(|a| ((origin[a] - offset[a]) / scale[a]).round() as i64);
        let n = 20_000u32;
        let stored: Vec<[i32; 3]> = (0..n)
            .map(|i| {
                [0, 1, 2].map(|a| {
                    let r = rng.next_u64();
                    let q = match i % 3 {
                        0 => base[a] + (r % 2001) as i64 - 1000,
                        1 => base[a] + (r % (1 << 25)) as i64 - (1 << 24),
                        _ => r as u32 as i32 as i64,
                    };
                    q.clamp(i32::MIN as i64, i32::MAX as i64) as i32
                })
            })
            .collect();
        let dst = ShuffledBuffer::new(&ctx, PointEncoding::Full16, n).unwrap();
        let mut staged = StagedBatch::new(&upload, PointEncoding::Full16, n as u64).unwrap();
        let colors: Vec<u32> = (0..n).collect();
        let mut view = staged.map().unwrap();
        let regions = view.regions();
        let (mut p, mut c) = (regions.positions, regions.colors);
        p.write(&stored).unwrap();
        c.write(&colors).unwrap();
        drop(view);
        staged.finish(n as u64);
        staged.set_dequantize(dq).unwrap();
        pass.scatter_staged(&ctx, &dst, 0, &staged).unwrap();
        let got = dst.read(&ctx).unwrap();
        let perm = ShufflePermutation::new(n as u64).unwrap();
        // Worst distance from the f64 encoding, near the origin (within 2^24 steps) and far.
        let mut worst = [0.0f64, 0.0];
        for (i, q) in stored.iter().enumerate() {
            let t = perm.target(i as u64) as usize;
            assert_eq!(got.colors[t], i as u32);
            // The f64 encoding of the dequantized position loses ~1e-9 to the cancellation
            // of two large coordinates; measured from the grid point nearest the origin, it
            // does not.
            let p = [0, 1, 2].map(|a| q[a] as f64 * scale[a] + offset[a]);
            let cpu = encode_point(p, origin, [1.0; 3], PointEncoding::Full16);
            let mirror = dq.words(*q);
            for a in 0..3 {
                let g = f32::from_bits(got.positions[t * 3 + a]);
                let exact = (q[a] as i64 - base[a]) as f64 * scale[a]
                    + (base[a] as f64 * scale[a] + offset[a] - origin[a]);
                let w = exact as f32;
                let c = f32::from_bits(cpu[a]);
                assert!(
                    ulps(g, c, scale[a] as f32) <= 4.0,
                    "point {i} axis {a}: GPU {g}, CPU encoding {c}"
                );
                // The CPU mirror follows the shader's operations; the f64 encoding is the truth.
                let m = f32::from_bits(mirror[a]);
                assert!(
                    ulps(g, m, scale[a] as f32) <= 1.0,
                    "point {i} axis {a}: GPU {g}, CPU mirror {}",
                    m
                );
                let class = usize::from(i % 3 == 2);
                worst[class] = worst[class].max(ulps(g, w, scale[a] as f32));
            }
        }
        assert!(
            worst[0] <= 1.0 && worst[1] <= 4.0,
            "{scale:?}: {worst:?} ulps from the f64 encoding"
        );
    }
    // Compact8 batches keep 8 bytes a point: stored positions do not fit them.
    let mut compact = StagedBatch::new(&upload, PointEncoding::Compact8, 4).unwrap();
    assert!(compact
        .set_dequantize(Dequantize::new([1.0; 3], [0.0; 3], [0.0; 3]))
        .is_err());
}

#[test]
fn malformed_batches_are_refused() {
    let ctx = common::context();
    let mut pass = ShufflePass::new(&ctx).unwrap();
    let dst = ShuffledBuffer::new(&ctx, PointEncoding::Full16, 100).unwrap();
    let words = [0u32; 30];
    let colors = [0u32; 10];
    let batch = |positions, fine| EncodedBatch {
        positions,
        fine,
        colors: &colors,
    };
    let refused = |r: Result<(), GpuError>| matches!(r, Err(GpuError::InvalidInput(_)));
    assert!(refused(pass.scatter(&ctx, &dst, 91, batch(&words, &[]))));
    assert!(refused(pass.scatter(
        &ctx,
        &dst,
        0,
        batch(&words[..29], &[])
    )));
    assert!(refused(pass.scatter(&ctx, &dst, 0, batch(&words, &colors))));
    assert!(pass.scatter(&ctx, &dst, 90, batch(&words, &[])).is_ok());
}

/// A kernel calling shuffle.wgsl's arithmetic on given operands: (a, b, p, i) with p's
/// Montgomery constants → (a·b mod p, target(i) under p).
const CHECK_KERNEL: &str = "
struct Case {
    a: u32,
    b: u32,
    p: u32,
    i: u32,
    neg_inv: u32,
    r2: u32,
    pad0: u32,
    pad1: u32,
}
@group(0) @binding(10) var<storage, read> cases: array<Case>;
@group(0) @binding(11) var<storage, read_write> results: array<vec2<u32>>;

@compute @workgroup_size(64)
fn check(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= arrayLength(&cases) {
        return;
    }
    let c = cases[gid.x];
    let m = Modulus(c.p, c.neg_inv, c.r2);
    results[gid.x] = vec2<u32>(mul_mod(c.a, c.b, m), shuffle_target(c.i, m));
}
";

fn run_check_kernel(ctx: &GpuContext, cases: &[[u32; 8]]) -> Vec<[u32; 2]> {
    let device = &ctx.device;
    let source = format!(
        "{}\n{CHECK_KERNEL}",
        include_str!("../shaders/shuffle.wgsl")
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("shuffle arithmetic"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("shuffle arithmetic"),
        layout: None,
        module: &module,
        entry_point: Some("check"),
        compilation_options: Default::default(),
        cache: None,
    });
    let buffer = |size: u64, usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
    let input = buffer(cases.len() as u64 * 32, storage);
    let result_bytes = cases.len() as u64 * 8;
    let output = buffer(result_bytes, storage | wgpu::BufferUsages::COPY_SRC);
    let readback = buffer(
        result_bytes,
        wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
    );
    ctx.queue
        .write_buffer(&input, 0, bytemuck::cast_slice(cases));
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 10,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 11,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((cases.len() as u32).div_ceil(64), 1, 1);
    }
    enc.copy_buffer_to_buffer(&output, 0, &readback, 0, result_bytes);
    ctx.queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    readback
        .slice(..)
        .map_async(wgpu::MapMode::Read, move |r| tx.send(r).unwrap());
    ctx.wait().unwrap();
    rx.recv().unwrap().unwrap();
    let bytes = readback.slice(..).get_mapped_range().unwrap().to_vec();
    bytemuck::pod_collect_to_vec(&bytes)
}

#[test]
fn shader_arithmetic_is_exact_for_primes_near_2_32() {
    let ctx = common::context();
    let mut rng = SplitMix64::new(11);
    let mut cases = Vec::new();
    // The largest primes ≡ 3 (mod 4) below 2^32, 2^31 and 2^16, and the smallest ones.
    for limit in [u32::MAX as u64, 1 << 31, 1 << 16, 7, 3] {
        let p = prime_3_mod_4_at_most(limit).unwrap();
        let mut operands = vec![0, 1, 2, p / 2, p / 2 + 1, p - 2, p - 1];
        operands.extend([65_535, 65_536, 65_537, (1 << 31) - 1, 1 << 31]);
        operands.extend((0..8).map(|_| rng.below(p)));
        operands.retain(|&v| v < p);
        let (neg_inv, r2) = montgomery_constants(p as u32);
        for &a in &operands {
            for &b in &operands {
                cases.push([a as u32, b as u32, p as u32, b as u32, neg_inv, r2, 0, 0]);
            }
        }
    }
    let results = run_check_kernel(&ctx, &cases);
    assert_eq!(results.len(), cases.len());
    for (c, r) in cases.iter().zip(&results) {
        let [a, b, p, i, ..] = c.map(u64::from);
        let perm = ShufflePermutation::new(p).unwrap();
        assert_eq!(perm.prime(), p);
        let product = ((a as u128 * b as u128) % p as u128) as u64;
        assert_eq!(r[0] as u64, product, "{a}·{b} mod {p}");
        assert_eq!(r[1] as u64, perm.target(i), "target({i}) under {p}");
    }
}
