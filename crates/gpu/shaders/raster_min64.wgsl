// Closest-point rasterization with one 64-bit atomic per point (compute-shader paper §3.1) and
// optionally the early depth test of §3.2. Variants: `atomic-min`, `early-z`.
// Key = ~depth_bits << 32 | ~rgba and atomicMax: the same winner as the paper's atomicMin of
// depth << 32 | colour (closest point; on equal depth the smaller colour), but an empty pixel is
// 0, so the framebuffer is cleared with a plain buffer clear instead of a fill pass.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;
override EARLY_Z: bool = false;

@group(1) @binding(0) var<storage, read_write> framebuffer: array<atomic<u64>>;

fn point_key(depth_bits: u32, color: u32) -> u64 {
    return (u64(~depth_bits) << 32u) | u64(~color);
}

@compute @workgroup_size(WG)
fn raster(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    for (var i = w.first + lid; i < w.end; i += WG) {
        let s = load_point(w.info, w.base + i);
        let hit = hit_of(s);
        if hit.pixel == NO_PIXEL {
            continue;
        }
        let key = point_key(hit.depth_bits, s.color);
        // A stale read is harmless: the stored key only grows, so we merely skip a useless atomic.
        if EARLY_Z && atomicLoad(&framebuffer[hit.pixel]) >= key {
            continue;
        }
        atomicMax(&framebuffer[hit.pixel], key);
    }
}
