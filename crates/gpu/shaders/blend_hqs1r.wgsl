// HQS1R's pixel buffers (compute-shader paper §3.5.1): the 16-16-16-16 word plus the fallback
// words; the pixel is the average of what they add up to.

@group(1) @binding(0) var<storage, read> depth_buffer: array<u32>;
@group(1) @binding(1) var<storage, read> packed: array<u64>;
@group(1) @binding(2) var<storage, read> overflow: array<u64>;

struct Blended {
    lit: bool,
    rgb: u32,
    // Inverted depth word (either splat tier).
    inv_depth: u32,
}

fn blended_pixel(p: u32) -> Blended {
    let w = packed[p];
    let rg = overflow[p * 2u];
    let ba = overflow[p * 2u + 1u];
    let n = u32(w & 0xfffflu) + u32(ba & 0xfffffffflu);
    if n == 0u {
        return Blended(false, 0u, 0u);
    }
    let r = (u32((w >> 48u) & 0xfffflu) + u32(rg >> 32u)) / n;
    let g = (u32((w >> 32u) & 0xfffflu) + u32(rg & 0xfffffffflu)) / n;
    let b = (u32((w >> 16u) & 0xfffflu) + u32(ba >> 32u)) / n;
    return Blended(true, r | (g << 8u) | (b << 16u), depth_buffer[p]);
}
