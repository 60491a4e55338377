// Point fetch, 16-byte layout: f32 xyz relative to the draw origin (12 bytes) and an RGBA8
// colour whose alpha byte holds the ASPRS class (4 bytes, its own stream so recolouring uploads
// only colours) — compute-shader paper §3.1's 16-byte points.

@group(0) @binding(4) var<storage, read> positions: array<f32>;
@group(0) @binding(7) var<storage, read> colors: array<u32>;

struct Sample {
    pos: vec3<f32>,
    color: u32,
}

// `index` counts points from the start of this dispatch's point buffers.
fn load_point(info: DrawInfo, index: u32) -> Sample {
    let p = vec3<f32>(positions[index * 3u], positions[index * 3u + 1u], positions[index * 3u + 2u]);
    return Sample(info.origin + p, colors[index]);
}
