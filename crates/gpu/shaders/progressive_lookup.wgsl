// Colour lookup of progressive rendering (progressive-rendering paper §3.4: the Reproject and
// Fill passes write point indices, the image shows their colours): turns each pixel's
// ~depth << 32 | ~slot key into the ~depth << 32 | ~rgba key the existing 64-bit resolve reads
// (resolve_min64.wgsl). One dispatch per point-buffer chunk, each converting the pixels whose
// slot lies in its chunk; empty pixels stay 0 (the colour keys are cleared first). Where the
// colour keys the Fill and Reproject passes kept (color_keys_kept.wgsl) are at the same depth,
// their colour wins: among points at exactly the closest depth, the smaller colour, as in the
// static path. SPLATS: the colour carries the splat's side (splat_color_word).

override PAGE_SIZE: u32 = 4096u;

@group(1) @binding(0) var<storage, read_write> indexed: array<u64>;
@group(1) @binding(1) var<storage, read_write> keys: array<u64>;
@group(1) @binding(2) var<storage, read_write> color_keys: array<u64>;

@compute @workgroup_size(8, 8)
fn lookup(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.size.x || id.y >= frame.size.y {
        return;
    }
    let pixel = id.y * frame.size.x + id.x;
    let key = indexed[pixel];
    if key == 0lu {
        return;
    }
    let slot = ~u32(key & 0xfffffffflu);
    if !in_chunk(slot) {
        return;
    }
    let first = dispatch.first_slot * PAGE_SIZE;
    let depth = key & 0xffffffff00000000lu;
    let kept = color_keys[pixel];
    if (kept & 0xffffffff00000000lu) == depth {
        keys[pixel] = kept;
    } else if SPLATS {
        let s = project_splat(load_position(infos[0], slot - first), infos[0].spacing);
        keys[pixel] = depth | u64(~splat_color_word(load_color(slot - first), s));
    } else {
        keys[pixel] = depth | u64(~load_color(slot - first));
    }
}
