// Colour pass of the 32-bit fallback rasterizer (for adapters without 64-bit atomics, e.g. some
// WebGPU targets): after raster_depth.wgsl found the closest depth, points at exactly that depth
// race for the colour with a 32-bit atomicMax of ~rgba. Same image as the 64-bit path: the
// closest point, and on equal depth the smaller colour. With PICK the point's id (slot ·
// PAGE_SIZE + index in the page) is stored instead of its colour: picking reads the point.

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
