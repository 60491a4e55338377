// High-quality shading, accumulation pass (compute-shader paper §3.5, after Botsch et al.):
// every point within `blend_factor` (1 %) of the closest depth found by raster_depth.wgsl adds
// its colour and a count with four 32-bit atomicAdds; the resolve pass divides. 32-bit atomics
// only, so HQS also runs where 64-bit atomics are missing.
// SPLATS: blend_splats.wgsl.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> depth_buffer: array<atomic<u32>>;
// r, g, b sums and the count, four words per pixel.
@group(1) @binding(1) var<storage, read_write> sums: array<atomic<u32>>;

@compute @workgroup_size(WG)
fn accumulate(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    for (var i = w.first + lid; i < w.end; i += WG) {
        if SPLATS {
            splat_accumulate(w, i);
            continue;
        }
        let hit = project(load_position(w.info, w.base + i));
        if hit.pixel == NO_PIXEL {
            continue;
        }
        let closest = bitcast<f32>(~atomicLoad(&depth_buffer[hit.pixel]));
        if bitcast<f32>(hit.depth_bits) <= closest * frame.blend_factor {
            let color = load_color(w.base + i);
            if class_hidden(color) {
                continue;
            }
            add_color(hit.pixel, color);
        }
    }
}

// The colour's r, g, b and a count, four 32-bit atomicAdds.
fn add_color(pixel: u32, color: u32) {
    let at = pixel * 4u;
    atomicAdd(&sums[at], color & 0xffu);
    atomicAdd(&sums[at + 1u], (color >> 8u) & 0xffu);
    atomicAdd(&sums[at + 2u], (color >> 16u) & 0xffu);
    atomicAdd(&sums[at + 3u], 1u);
}

