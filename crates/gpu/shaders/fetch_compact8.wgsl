// Point fetch, compact layout (Schütz et al. 2022 style): positions quantized relative to the
// page's bounding box. Coarse word: 3 × 10 bits plus RGBA8 = 8 bytes per point; pages seen so close
// that one coarse step exceeds half a pixel also read a fine word (another 3 × 10 bits), so
// positions carry 20 bits per axis where it is visible and distant pages move only 8 bytes.

@group(0) @binding(4) var<storage, read> points: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read> fine: array<u32>;

struct Sample {
    pos: vec3<f32>,
    color: u32,
}

fn unpack10(w: u32) -> vec3<u32> {
    return vec3<u32>(w & 0x3ffu, (w >> 10u) & 0x3ffu, (w >> 20u) & 0x3ffu);
}

fn load_point(info: DrawInfo, index: u32) -> Sample {
    let v = points[index];
    // Without the fine word, a point sits in the middle of its coarse cell.
    var q = vec3<f32>(unpack10(v.x) * 1024u) + vec3<f32>(512.0);
    if (info.flags & 1u) != 0u {
        q = vec3<f32>(unpack10(v.x) * 1024u + unpack10(fine[index])) + vec3<f32>(0.5);
    }
    return Sample(info.origin + q * info.step, v.y);
}
