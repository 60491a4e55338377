// Prepare pass of progressive rendering (progressive-rendering paper §3.4, pass 3): appends the
// slot of every pixel's closest point (the low word of its ~depth << 32 | ~slot key) to the list
// the next frame's Reproject pass draws, with an atomic counter. The paper's Reproject buffer
// holds copies of the points; ours holds only slots (the points stay in the shuffled buffer).
// One dispatch per point-buffer chunk, each listing the pixels whose slot lies in its chunk.
// SPLATS: a point wins many pixels; a bit per slot (set here, cleared by the next Reproject
// pass as it draws the slot) lists it once.
// One entry per lit pixel at most: the list never outgrows the pixel count.

override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> keys: array<u64>;
@group(1) @binding(1) var<storage, read_write> list: array<u32>;
@group(1) @binding(2) var<storage, read_write> list_len: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> listed: array<atomic<u32>>;

@compute @workgroup_size(8, 8)
fn prepare(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.size.x || id.y >= frame.size.y {
        return;
    }
    let pixel = id.y * frame.size.x + id.x;
    let key = keys[pixel];
    if key == 0lu {
        return;
    }
    let slot = ~u32(key & 0xfffffffflu);
    if !in_chunk(slot) {
        return;
    }
    if SPLATS {
        let bit = 1u << (slot & 31u);
        if (atomicOr(&listed[slot >> 5u], bit) & bit) != 0u {
            return;
        }
    }
    list[atomicAdd(&list_len[0], 1u)] = slot;
}
