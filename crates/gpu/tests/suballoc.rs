//! The buffer suballocator on a real device: allocations of many sizes land in shared pages
//! without overlapping (each keeps the bytes written to it), freed ranges are reused, and
//! requests larger than a page get a page of their own.

mod common;
use common::context;
use pointlet_gpu::suballoc::{Suballocator, ALIGNMENT};

fn read(ctx: &pointlet_gpu::GpuContext, buffer: &wgpu::Buffer, offset: u64, len: u64) -> Vec<u8> {
    let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: len,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(buffer, offset, &rb, 0, len);
    ctx.queue.submit([enc.finish()]);
    let slice = rb.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    ctx.wait().expect("wait");
    let out = slice.get_mapped_range().expect("mapped").to_vec();
    rb.unmap();
    out
}

#[test]
fn allocations_share_pages_keep_their_bytes_and_come_back() {
    let ctx = context();
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let mut sub = Suballocator::new(1 << 20);
    let sizes = [1000u64, 256, 70_000, 4096, 300_000, 12, 500_000];
    let mut live = Vec::new();
    for (k, size) in sizes.iter().enumerate() {
        let a = sub.alloc(&ctx, usage, *size).expect("alloc");
        assert_eq!(a.offset % ALIGNMENT, 0);
        let bytes: Vec<u8> = (0..*size).map(|i| (i as u8) ^ (k as u8 * 37)).collect();
        // Buffer writes are whole words.
        let mut padded = bytes.clone();
        padded.resize(bytes.len().div_ceil(4) * 4, 0);
        ctx.queue.write_buffer(a.buffer(), a.offset, &padded);
        live.push((a, bytes));
    }
    assert_eq!(sub.stats().pages, 1, "all of them fit one 1 MiB page");
    for (a, bytes) in &live {
        let got = read(&ctx, a.buffer(), a.offset, (a.size.div_ceil(4) * 4).max(4));
        assert_eq!(
            &got[..bytes.len()],
            &bytes[..],
            "allocation at {}",
            a.offset
        );
    }
    // Freed ranges are reused before a new page is made.
    let (third, _) = live.remove(2);
    let offset = third.offset;
    sub.free(third);
    let again = sub.alloc(&ctx, usage, 60_000).expect("alloc");
    assert_eq!(again.offset, offset, "first fit takes the freed range");
    assert_eq!(sub.stats().pages, 1);
    // Larger than a page: a page of its own.
    let big = sub.alloc(&ctx, usage, 3 << 20).expect("alloc");
    assert_eq!(big.offset, 0);
    assert_eq!(sub.stats().pages, 2);
    sub.free(big);
    sub.free(again);
    for (a, _) in live {
        sub.free(a);
    }
    assert_eq!(sub.stats().used, 0);
    sub.trim();
    assert_eq!(sub.stats().pages, 0, "empty pages are released");
}

#[test]
fn an_allocation_beyond_the_largest_buffer_is_an_error() {
    let ctx = context();
    let mut sub = Suballocator::new(1 << 20);
    let too_big = ctx.caps.max_buffer + 1;
    let err = sub
        .alloc(&ctx, wgpu::BufferUsages::STORAGE, too_big)
        .expect_err("larger than any buffer");
    assert!(
        err.to_string().contains("exceeds the largest buffer"),
        "{err}"
    );
}
