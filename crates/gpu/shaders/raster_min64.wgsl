// Closest-point rasterization with one 64-bit atomic per point (compute-shader paper §3.1) and
// optionally the early depth test of §3.2. Variants: `atomic-min`, `early-z`.
// Key = ~depth_bits << 32 | ~rgba and atomicMax: the same winner as the paper's atomicMin of
// depth << 32 | colour (closest point; on equal depth the smaller colour), but an empty pixel is
// 0, so the framebuffer is cleared with a plain buffer clear instead of a fill pass.
// INDEX_KEYS (progressive rendering, progressive.rs) puts the point's id (its slot in the shuffled
// buffer) in the low word instead of the colour, so the Prepare pass can list the winners; the
// colour key goes to keep_color_key (color_keys_*.wgsl) for the tie rule.
// SPLATS: the same key written to every pixel of the point's splat (common.wgsl), the early depth
// test for one-pixel splats only (raster_subgroup.wgsl says why); the gap-filling ring writes
// its lower-tier keys.

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;
override EARLY_Z: bool = false;
override INDEX_KEYS: bool = false;

@group(1) @binding(0) var<storage, read_write> framebuffer: array<atomic<u64>>;

fn point_key(depth_bits: u32, color: u32) -> u64 {
    return (u64(~depth_bits) << 32u) | u64(~color);
}

@compute @workgroup_size(WG)
fn raster(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    for (var i = w.first + lid; i < w.end; i += WG) {
        if SPLATS {
            draw_splat(w, i);
            continue;
        }
        let hit = project(load_position(w.info, w.base + i));
        if hit.pixel == NO_PIXEL {
            continue;
        }
        // Depth alone decides most points: a strictly closer one is stored, skip (a stale read
        // is harmless, stored keys only grow). Equal depths fall through to the colour tie rule.
        if EARLY_Z && u32(atomicLoad(&framebuffer[hit.pixel]) >> 32u) > ~hit.depth_bits {
            continue;
        }
        let color = load_color(w.base + i);
        if class_hidden(color) {
            continue;
        }
        let low = select(color, w.slot * PAGE_SIZE + i, INDEX_KEYS);
        atomicMax(&framebuffer[hit.pixel], point_key(hit.depth_bits, low));
        keep_color_key(hit.pixel, point_key(hit.depth_bits, color));
    }
}

fn draw_splat(w: Work, i: u32) {
    let s = project_splat(load_position(w.info, w.base + i), w.info.spacing);
    if !s.valid {
        return;
    }
    var color = 0u;
    var fetched = false;
    let early_z = EARLY_Z && s.ring == 1u;
    for (var dy = 0u; dy < s.ring; dy++) {
        for (var dx = 0u; dx < s.ring; dx++) {
            let px = splat_pixel(s, vec2<u32>(dx, dy));
            if px.pixel == NO_PIXEL {
                continue;
            }
            let inv = tier_depth(~s.depth_bits, px.ring);
            if early_z && u32(atomicLoad(&framebuffer[px.pixel]) >> 32u) > inv {
                continue;
            }
            if !fetched {
                color = load_color(w.base + i);
                fetched = true;
                if class_hidden(color) {
                    return;
                }
            }
            let shown = splat_color_word(color, s);
            let low = select(shown, w.slot * PAGE_SIZE + i, INDEX_KEYS);
            atomicMax(&framebuffer[px.pixel], (u64(inv) << 32u) | u64(~low));
            keep_color_key(px.pixel, (u64(inv) << 32u) | u64(~shown));
        }
    }
}
