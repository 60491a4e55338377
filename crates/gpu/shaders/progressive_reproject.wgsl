// Reproject pass of progressive rendering (progressive-rendering paper §3.4, pass 1): draws the
// points the previous frame showed, listed by slot in the shuffled buffer by the Prepare pass,
// with this frame's camera, keyed like the Fill pass (~depth << 32 | ~slot, atomicMax: see
// raster_min64.wgsl with INDEX_KEYS). The paper copies the points into its Reproject buffer; we
// keep only their slots and fetch each point from the shuffled buffer by index.
// The colour key goes to color_keys as in the Fill pass (color_keys_kept.wgsl), for the tie rule.
// One thread per list entry; one dispatch per point-buffer chunk, each drawing the entries whose
// slot lies in its chunk. Every page of a shuffled buffer shares one origin: infos[0].
// SPLATS: the point's whole splat (common.wgsl), each pixel keyed as the Fill pass keys it.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> framebuffer: array<atomic<u64>>;
@group(1) @binding(1) var<storage, read_write> list: array<u32>;
// Entries of `list` (the Prepare pass's counter).
@group(1) @binding(2) var<storage, read_write> list_len: array<u32>;
@group(1) @binding(3) var<storage, read_write> color_keys: array<atomic<u64>>;
// SPLATS: the Prepare pass's bit per listed slot, cleared here for the next Prepare.
@group(1) @binding(4) var<storage, read_write> listed: array<atomic<u32>>;

@compute @workgroup_size(WG)
fn reproject(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = gid.x + gid.y * nwg.x * WG;
    if k >= list_len[0] {
        return;
    }
    let slot = list[k];
    if !in_chunk(slot) {
        return;
    }
    let first = dispatch.first_slot * PAGE_SIZE;
    let index = slot - first;
    if SPLATS {
        atomicAnd(&listed[slot >> 5u], ~(1u << (slot & 31u)));
        reproject_splat(slot, index);
        return;
    }
    let hit = project(load_position(infos[0], index));
    if hit.pixel == NO_PIXEL {
        return;
    }
    // Classes hidden since the previous frame drop out here.
    let color = load_color(index);
    if class_hidden(color) {
        return;
    }
    atomicMax(&framebuffer[hit.pixel], (u64(~hit.depth_bits) << 32u) | u64(~slot));
    atomicMax(&color_keys[hit.pixel], (u64(~hit.depth_bits) << 32u) | u64(~color));
}

fn reproject_splat(slot: u32, index: u32) {
    let s = project_splat(load_position(infos[0], index), infos[0].spacing);
    if !s.valid {
        return;
    }
    let color = load_color(index);
    if class_hidden(color) {
        return;
    }
    for (var dy = 0u; dy < s.ring; dy++) {
        for (var dx = 0u; dx < s.ring; dx++) {
            let px = splat_pixel(s, vec2<u32>(dx, dy));
            if px.pixel == NO_PIXEL {
                continue;
            }
            let high = u64(tier_depth(~s.depth_bits, px.ring)) << 32u;
            atomicMax(&framebuffer[px.pixel], high | u64(~slot));
            atomicMax(&color_keys[px.pixel], high | u64(~splat_color_word(color, s)));
        }
    }
}
