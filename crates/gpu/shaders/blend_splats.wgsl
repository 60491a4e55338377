// Blending of splats (Botsch et al. as in the WebGPU-engine paper §6.2), the accumulation pass
// of both high-quality variants (raster_hqs.wgsl, raster_hqs1r.wgsl, each defining
// `add_color(pixel, color)` its own way): every pixel of a splat whose depth is within the
// tolerance of the pixel's closest, and of the same tier (a ring only where no splat covers
// the pixel, common.wgsl), adds the point's colour.

fn splat_accumulate(w: Work, i: u32) {
    let s = project_splat(load_position(w.info, w.base + i), w.info.spacing);
    if !s.valid {
        return;
    }
    var color = 0u;
    var fetched = false;
    let depth = bitcast<f32>(s.depth_bits);
    for (var dy = 0u; dy < s.ring; dy++) {
        for (var dx = 0u; dx < s.ring; dx++) {
            let px = splat_pixel(s, vec2<u32>(dx, dy));
            if px.pixel == NO_PIXEL {
                continue;
            }
            let stored = atomicLoad(&depth_buffer[px.pixel]);
            let same_tier = (stored & TIER_BIT) == (tier_depth(~s.depth_bits, px.ring) & TIER_BIT);
            if !same_tier || depth > bitcast<f32>(untier(stored)) * frame.blend_factor {
                continue;
            }
            if !fetched {
                color = load_color(w.base + i);
                fetched = true;
                if class_hidden(color) {
                    return;
                }
            }
            add_color(px.pixel, color);
        }
    }
}

