// Colour keys beside progressive rendering's index keys (progressive-rendering paper §3.4):
// the Fill pass's framebuffer key holds the point's slot, for the Prepare pass; each point also
// offers the static path's key (~depth << 32 | ~rgba), kept over the frames while the view
// stays still, so that where points share the closest depth exactly the converged image shows
// the static path's colour (the smaller one), not the smaller slot's.

@group(1) @binding(1) var<storage, read_write> color_keys: array<atomic<u64>>;

fn keep_color_key(pixel: u32, key: u64) {
    atomicMax(&color_keys[pixel], key);
}
