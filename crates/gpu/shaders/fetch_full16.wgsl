// Point fetch, 16-byte layout: f32 xyz relative to the draw origin and an RGBA8 colour,
// one 16-byte load per point (compute-shader paper §3.1's layout).

@group(0) @binding(4) var<storage, read> points: array<vec4<u32>>;

struct Sample {
    pos: vec3<f32>,
    color: u32,
}

// `index` counts points from the start of this dispatch's point buffer.
fn load_point(info: DrawInfo, index: u32) -> Sample {
    let v = points[index];
    return Sample(info.origin + bitcast<vec3<f32>>(v.xyz), v.w);
}
