// Robust single-atomic high-quality shading, HQS1R (compute-shader paper §3.5.1, Listing 9):
// r, g, b and the count share one 64-bit word as 16-16-16-16 bits and one atomicAdd per point.
// The lane that sees the count reach 255 moves the word into the two 64-bit fallback words
// (r<<32|g, b<<32|count) and zeroes it; lanes that arrive while the count is ≥ 255 add themselves
// to the fallback directly. The spare count bits absorb lanes racing with the reset.
// SPLATS: blend_splats.wgsl.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> depth_buffer: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> packed: array<atomic<u64>>;
@group(1) @binding(2) var<storage, read_write> overflow: array<atomic<u64>>;

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
        if bitcast<f32>(hit.depth_bits) > closest * frame.blend_factor {
            continue;
        }
        let color = load_color(w.base + i);
        if class_hidden(color) {
            continue;
        }
        add_color(hit.pixel, color);
    }
}

// One atomicAdd of the packed word; past 255 adds the word and the colour go to the fallback.
fn add_color(pixel: u32, color: u32) {
    var r = u64(color & 0xffu);
    var g = u64((color >> 8u) & 0xffu);
    var b = u64((color >> 16u) & 0xffu);
    let old = atomicAdd(&packed[pixel], (r << 48u) | (g << 32u) | (b << 16u) | 1lu);
    let count = u32(old & 0xfffflu);
    if count >= 255u {
        var a = 1lu;
        if count == 255u {
            atomicExchange(&packed[pixel], 0lu);
            r += (old >> 48u) & 0xfffflu;
            g += (old >> 32u) & 0xfffflu;
            b += (old >> 16u) & 0xfffflu;
            a += 255lu;
        }
        atomicAdd(&overflow[pixel * 2u], (r << 32u) | g);
        atomicAdd(&overflow[pixel * 2u + 1u], (b << 32u) | a);
    }
}
