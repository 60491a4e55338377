// Colour pass of the 32-bit fallback rasterizer (for adapters without 64-bit atomics, e.g. some
// WebGPU targets): after raster_depth.wgsl found the closest depth, points at exactly that depth
// race for the colour with a 32-bit atomicMax of ~rgba. Same image as the 64-bit path: the
// closest point, and on equal depth the smaller colour. With PICK the point's id (slot ·
// PAGE_SIZE + index in the page) is stored instead of its colour: picking reads the point.
// SPLATS: every pixel of the splat whose stored depth word (tier included) is the splat's.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;
override PICK: bool = false;

@group(1) @binding(0) var<storage, read_write> depth_buffer: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> color_buffer: array<atomic<u32>>;

@compute @workgroup_size(WG)
fn color_pass(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    for (var i = w.first + lid; i < w.end; i += WG) {
        if SPLATS {
            splat_color(w, i);
            continue;
        }
        let hit = project(load_position(w.info, w.base + i));
        if hit.pixel == NO_PIXEL {
            continue;
        }
        if atomicLoad(&depth_buffer[hit.pixel]) == ~hit.depth_bits {
            let color = load_color(w.base + i);
            if class_hidden(color) {
                continue;
            }
            let value = select(color, w.slot * PAGE_SIZE + i, PICK);
            atomicMax(&color_buffer[hit.pixel], ~value);
        }
    }
}

fn splat_color(w: Work, i: u32) {
    let s = project_splat(load_position(w.info, w.base + i), w.info.spacing);
    if !s.valid {
        return;
    }
    var value = 0u;
    var fetched = false;
    for (var dy = 0u; dy < s.ring; dy++) {
        for (var dx = 0u; dx < s.ring; dx++) {
            let px = splat_pixel(s, vec2<u32>(dx, dy));
            if px.pixel == NO_PIXEL
                || atomicLoad(&depth_buffer[px.pixel]) != tier_depth(~s.depth_bits, px.ring) {
                continue;
            }
            if !fetched {
                let color = load_color(w.base + i);
                if class_hidden(color) {
                    return;
                }
                value = select(splat_color_word(color, s), w.slot * PAGE_SIZE + i, PICK);
                fetched = true;
            }
            atomicMax(&color_buffer[px.pixel], ~value);
        }
    }
}
