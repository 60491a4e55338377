// Copies the renderer's RGBA8 image to the window, texel for texel (no filtering, so the window
// shows exactly the bytes `pointlet render` writes).

@group(0) @binding(0) var image: texture_2d<f32>;

// One triangle covering the viewport.
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u);
    let y = f32(i & 2u);
    return vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
}

fn texel(pos: vec4<f32>) -> vec4<f32> {
    let size = textureDimensions(image);
    let p = min(vec2<u32>(pos.xy), size - vec2<u32>(1u));
    return textureLoad(image, p, 0);
}

// Surfaces that store values as given (Rgba8Unorm, Bgra8Unorm).
@fragment
fn fs_plain(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return texel(pos);
}

fn to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

// sRGB surfaces encode what they are given: decode first so the stored bytes are the image's.
@fragment
fn fs_srgb(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let c = texel(pos);
    return vec4<f32>(to_linear(c.r), to_linear(c.g), to_linear(c.b), c.a);
}
