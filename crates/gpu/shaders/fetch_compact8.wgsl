// Point fetch, compact layout (Schütz et al. 2022 style): positions quantized relative to the
// draw box. Coarse word: 3 × 10 bits, plus the RGBA8 colour (alpha = ASPRS class) = 8 bytes per
// point; boxes seen so close that one coarse step exceeds half a pixel also read a fine word
// (another 3 × 10 bits), so positions carry 20 bits per axis where it is visible and distant
// boxes move only 8 bytes. Colours are their own stream: recolouring uploads only them.

@group(0) @binding(4) var<storage, read> coarse: array<u32>;
@group(0) @binding(5) var<storage, read> fine: array<u32>;
@group(0) @binding(7) var<storage, read> colors: array<u32>;

fn unpack10(w: u32) -> vec3<u32> {
    return vec3<u32>(w & 0x3ffu, (w >> 10u) & 0x3ffu, (w >> 20u) & 0x3ffu);
}

// Position and colour load separately: most points fail the early depth test and never need
// their colour.
fn load_position(info: DrawInfo, index: u32) -> vec3<f32> {
    let c = unpack10(coarse[index]) * 1024u;
    // Without the fine word, a point sits in the middle of its coarse cell.
    var q = vec3<f32>(c) + vec3<f32>(512.0);
    if (info.flags & 1u) != 0u {
        q = vec3<f32>(c + unpack10(fine[index])) + vec3<f32>(0.5);
    }
    return info.origin + q * info.step;
}

fn load_color(index: u32) -> u32 {
    return colors[index];
}
