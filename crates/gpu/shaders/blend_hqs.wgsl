// HQS's pixel buffers (compute-shader paper §3.5, Listing 8): the closest depth and the r, g, b
// sums and count of the points within the tolerance; the pixel is their average.

@group(1) @binding(0) var<storage, read> depth_buffer: array<u32>;
@group(1) @binding(1) var<storage, read> sums: array<u32>;

struct Blended {
    lit: bool,
    rgb: u32,
    // Inverted depth word (either splat tier).
    inv_depth: u32,
}

fn blended_pixel(p: u32) -> Blended {
    let n = sums[p * 4u + 3u];
    if n == 0u {
        return Blended(false, 0u, 0u);
    }
    let r = sums[p * 4u] / n;
    let g = sums[p * 4u + 1u] / n;
    let b = sums[p * 4u + 2u] / n;
    return Blended(true, r | (g << 8u) | (b << 16u), depth_buffer[p]);
}
