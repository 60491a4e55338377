// Shared by the resolve passes: turn a rasterizer's per-pixel buffers into a colour image
// (alpha 255 where a point landed, 0 where empty) and a linear view-depth image (0 = empty).

struct Screen {
    size: vec2<u32>,
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> screen: Screen;
@group(0) @binding(1) var out_color: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(2) var out_depth: texture_storage_2d<r32float, write>;

// SPLAT_SIZES: the colour word's alpha byte holds the splat's side in pixels (1–32), kept as
// alpha = side / 255 for the screen passes (EDL on splats); otherwise alpha 1 (no splat size).
override SPLAT_SIZES: bool = false;

fn write_pixel(xy: vec2<u32>, rgba: u32, depth_bits: u32) {
    let c = unpack4x8unorm(rgba);
    textureStore(out_color, xy, vec4<f32>(c.rgb, select(1.0, c.a, SPLAT_SIZES)));
    textureStore(out_depth, xy, vec4<f32>(bitcast<f32>(depth_bits), 0.0, 0.0, 0.0));
}

fn write_empty(xy: vec2<u32>) {
    textureStore(out_color, xy, vec4<f32>(0.0));
    textureStore(out_depth, xy, vec4<f32>(0.0));
}

// Depth bits of an inverted depth word; splats' gap-filling rings clear its top bit (their lower
// tier, common.wgsl), which positive depths never set.
fn depth_bits_of(inv_depth: u32) -> u32 {
    return ~(inv_depth | 0x80000000u);
}
