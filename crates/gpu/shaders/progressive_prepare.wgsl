// Prepare pass of progressive rendering (progressive-rendering paper §3.4, pass 3): appends the
// slot of every pixel's closest point (the low word of its ~depth << 32 | ~slot key) to the list
// the next frame's Reproject pass draws, with an atomic counter. The paper's Reproject buffer
// holds copies of the points; ours holds only slots (the points stay in the shuffled buffer).
// One dispatch per point-buffer chunk, each listing the pixels whose slot lies in its chunk.
// SPLATS: a point wins many pixels; it is listed once, from the pixel holding its centre (a
// point whose centre pixel another point won is left to the Fill pass).
// One entry per lit pixel at most: the list never outgrows the pixel count.

override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> keys: array<u64>;
@group(1) @binding(1) var<storage, read_write> list: array<u32>;
@group(1) @binding(2) var<storage, read_write> list_len: array<atomic<u32>>;

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
    let first = dispatch.first_slot * PAGE_SIZE;
    if SPLATS {
        let s = project_splat(load_position(infos[0], slot - first), infos[0].spacing);
        if !s.valid || any((s.q >> vec2<u32>(8u)) != vec2<i32>(id.xy)) {
            return;
        }
    }
    list[atomicAdd(&list_len[0], 1u)] = slot;
}
