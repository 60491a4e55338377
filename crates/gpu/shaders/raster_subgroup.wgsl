// Closest-point rasterization with subgroup reduction (compute-shader paper §3.3–3.4).
// MODE 0 (`reduce`): if every lane of the subgroup hits the same pixel only the closest writes;
// otherwise neighbouring lane pairs merge (the paper's clustered xor/min of size 2).
// MODE 1 (`dedup`): WGSL has no subgroupPartitionNV, so lanes are partitioned by pixel in rounds:
// each round takes the smallest pending pixel id, its closest lane writes, its lanes retire;
// after DEDUP_ROUNDS rounds the remaining lanes write directly (bounded cost on close-ups).
// EARLY_Z adds §3.2's early depth test. Keys as in raster_min64.wgsl (atomicMax of complements),
// with the point id instead of the colour under INDEX_KEYS (color_keys_*.wgsl).
// SPLATS: every lane walks its splat's pixels (common.wgsl) in step with the others, as many
// steps as the largest splat of the subgroup, and each step reduces like single pixels. Only
// one-pixel splats take the early depth test: on a larger splat it would put a memory round
// trip on every step of the walk, while its atomic writes need no answer (measured on the 1 G
// orbit, docs/BENCHMARKS.md: raster 0.77 → 0.62 ms).

override WG: u32 = 256u;
override PAGE_SIZE: u32 = 4096u;
override EARLY_Z: bool = false;
override INDEX_KEYS: bool = false;
override MODE: u32 = 0u;
override DEDUP_ROUNDS: u32 = 4u;

@group(1) @binding(0) var<storage, read_write> framebuffer: array<atomic<u64>>;

// Equal depths all write: the tie rule (smaller colour, or smaller slot) is the atomic's.
fn write_key(pixel: u32, inv_depth: u32, low: u32, color: u32) {
    atomicMax(&framebuffer[pixel], (u64(inv_depth) << 32u) | u64(~low));
    keep_color_key(pixel, (u64(inv_depth) << 32u) | u64(~color));
}

@compute @workgroup_size(WG)
fn raster(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let w = work_for(wg, nwg);
    if !w.valid {
        return;
    }
    // Every lane runs every round (no early exit) so subgroup operations see the whole subgroup.
    let rounds = (w.end - w.first + WG - 1u) / WG;
    for (var k = 0u; k < rounds; k++) {
        let i = w.first + k * WG + lid;
        if SPLATS {
            raster_splat(w, i);
            continue;
        }
        var pixel = NO_PIXEL;
        var inv_depth = 0u;
        var color = 0u;
        var low = 0u;
        if i < w.end {
            let hit = project(load_position(w.info, w.base + i));
            // Early depth test on depth alone; surviving lanes fetch their colour.
            if hit.pixel != NO_PIXEL
                && !(EARLY_Z && u32(atomicLoad(&framebuffer[hit.pixel]) >> 32u) > ~hit.depth_bits) {
                color = load_color(w.base + i);
                // Hidden points must not win the reduction over visible ones.
                if !class_hidden(color) {
                    pixel = hit.pixel;
                    inv_depth = ~hit.depth_bits;
                    low = select(color, w.slot * PAGE_SIZE + i, INDEX_KEYS);
                }
            }
        }
        reduce_and_write(pixel, inv_depth, low, color);
    }
}

// One point per lane (or none): lanes walk their splat's pixels in step, as many steps as the
// largest splat of the subgroup. As for single pixels, a lane fetches its colour only once a
// pixel passes the early depth test (most do not, in a dense view).
fn raster_splat(w: Work, i: u32) {
    var s: Splat;
    s.valid = false;
    if i < w.end {
        s = project_splat(load_position(w.info, w.base + i), w.info.spacing);
    }
    let n = select(0u, s.ring * s.ring, s.valid);
    let steps = subgroupMax(n);
    let early_z = EARLY_Z && n == 1u;
    var fetched = false;
    var hidden = false;
    var shown = 0u;
    var low = 0u;
    var d = vec2<u32>(0u);
    for (var j = 0u; j < steps; j++) {
        var pixel = NO_PIXEL;
        var inv_depth = 0u;
        if j < n && !hidden {
            let px = splat_pixel(s, d);
            let inv = tier_depth(~s.depth_bits, px.ring);
            if px.pixel != NO_PIXEL
                && !(early_z && u32(atomicLoad(&framebuffer[px.pixel]) >> 32u) > inv) {
                if !fetched {
                    let color = load_color(w.base + i);
                    fetched = true;
                    hidden = class_hidden(color);
                    shown = splat_color_word(color, s);
                    low = select(shown, w.slot * PAGE_SIZE + i, INDEX_KEYS);
                }
                if !hidden {
                    pixel = px.pixel;
                    inv_depth = inv;
                }
            }
            d.x += 1u;
            if d.x == s.ring {
                d = vec2<u32>(0u, d.y + 1u);
            }
        }
        reduce_and_write(pixel, inv_depth, low, shown);
    }
}

// The lanes' candidates (NO_PIXEL: none) reduced across the subgroup, then written. Called in
// uniform control flow.
fn reduce_and_write(pixel: u32, inv_depth: u32, low: u32, color: u32) {
    if MODE == 0u {
        let first = subgroupBroadcastFirst(pixel);
        var best = inv_depth;
        if subgroupAll(pixel == first) {
            best = subgroupMax(inv_depth);
        } else {
            let other_pixel = subgroupShuffleXor(pixel, 1u);
            let other_depth = subgroupShuffleXor(inv_depth, 1u);
            if other_pixel == pixel {
                best = max(inv_depth, other_depth);
            }
        }
        if pixel != NO_PIXEL && inv_depth == best {
            write_key(pixel, inv_depth, low, color);
        }
    } else {
        var pending = pixel != NO_PIXEL;
        for (var round = 0u; round < DEDUP_ROUNDS; round++) {
            if !subgroupAny(pending) {
                break;
            }
            let leader = subgroupMin(select(NO_PIXEL, pixel, pending));
            let mine = pending && pixel == leader;
            let best = subgroupMax(select(0u, inv_depth, mine));
            if mine {
                pending = false;
                if inv_depth == best {
                    write_key(pixel, inv_depth, low, color);
                }
            }
        }
        if pending {
            write_key(pixel, inv_depth, low, color);
        }
    }
}
