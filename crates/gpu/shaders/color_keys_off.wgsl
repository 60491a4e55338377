// Closest-point passes of the static path keep no separate colour key: their framebuffer key
// (~depth << 32 | ~rgba, compute-shader paper §3.1) already holds the colour.

fn keep_color_key(pixel: u32, key: u64) {}
