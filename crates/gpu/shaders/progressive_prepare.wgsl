// Prepare pass of progressive rendering (progressive-rendering paper §3.4, pass 3): appends the
// slot of every pixel's closest point (the low word of its ~depth << 32 | ~slot key) to the list
// the next frame's Reproject pass draws, with an atomic counter. The paper's Reproject buffer
// holds copies of the points; ours holds only slots (the points stay in the shuffled buffer).
// One entry per lit pixel at most: the list never outgrows the pixel count.

struct Size {
    size: vec2<u32>,
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> screen: Size;
@group(0) @binding(1) var<storage, read> keys: array<u64>;
@group(0) @binding(2) var<storage, read_write> list: array<u32>;
@group(0) @binding(3) var<storage, read_write> list_len: array<atomic<u32>>;

@compute @workgroup_size(8, 8)
fn prepare(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let key = keys[id.y * screen.size.x + id.x];
    if key == 0lu {
        return;
    }
    list[atomicAdd(&list_len[0], 1u)] = ~u32(key & 0xfffffffflu);
}
