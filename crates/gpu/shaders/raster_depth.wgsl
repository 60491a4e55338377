// Depth pre-pass with 32-bit atomics: the closest view depth per pixel. Used by the 32-bit
// fallback rasterizer (adapters without 64-bit atomics) and by both high-quality variants
// (compute-shader paper §3.5: "the depth pass ... with simple 32bit atomic operations").
// Stores ~depth_bits with atomicMax so a cleared (zero) buffer means empty.
// SPLATS: every pixel of the splat, the gap-filling ring at its lower tier (common.wgsl).

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> depth_buffer: array<atomic<u32>>;

// True when point `index` of the dispatch's buffers belongs to a hidden class. The colour is
// loaded whatever the classes: a branch on a uniform alone is recompiled by lavapipe at every
// bind (Mesa 22.3 specialises shaders on such uniforms and keeps each copy).
fn index_hidden(index: u32) -> bool {
    return class_hidden(load_color(index));
}


@compute @workgroup_size(WG)
fn depth_pass(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    for (var i = w.first + lid; i < w.end; i += WG) {
        if SPLATS {
            splat_depth(w, i);
            continue;
        }
        let hit = project(load_position(w.info, w.base + i));
        if hit.pixel == NO_PIXEL {
            continue;
        }
        let inv = ~hit.depth_bits;
        if atomicLoad(&depth_buffer[hit.pixel]) < inv && !index_hidden(w.base + i) {
            atomicMax(&depth_buffer[hit.pixel], inv);
        }
    }
}

fn splat_depth(w: Work, i: u32) {
    let s = project_splat(load_position(w.info, w.base + i), w.info.spacing);
    if !s.valid || index_hidden(w.base + i) {
        return;
    }
    for (var dy = 0u; dy < s.ring; dy++) {
        for (var dx = 0u; dx < s.ring; dx++) {
            let px = splat_pixel(s, vec2<u32>(dx, dy));
            if px.pixel == NO_PIXEL {
                continue;
            }
            let inv = tier_depth(~s.depth_bits, px.ring);
            // Splats wider than a pixel skip the test load (raster_subgroup.wgsl says why).
            if s.ring > 1u || atomicLoad(&depth_buffer[px.pixel]) < inv {
                atomicMax(&depth_buffer[px.pixel], inv);
            }
        }
    }
}
