// Point fetch, 16-byte layout: f32 xyz relative to the draw origin (12 bytes) and an RGBA8
// colour whose alpha byte holds the ASPRS class (4 bytes, its own stream so recolouring uploads
// only colours) — compute-shader paper §3.1's 16-byte points.
// SKIP_EMPTY (progressive rendering's Fill pass): a slot of the shuffled buffer that no point has
// been loaded into yet holds EMPTY_SLOT (a NaN pattern no encoded point has) in its x word and is
// placed at the eye, which never projects (clip w = 0).

@group(0) @binding(4) var<storage, read> positions: array<f32>;
@group(0) @binding(7) var<storage, read> colors: array<u32>;

override SKIP_EMPTY: bool = false;
const EMPTY_SLOT: u32 = 0xffffffffu;

// `index` counts points from the start of this dispatch's point buffers. Position and colour
// load separately: most points fail the early depth test and never need their colour.
fn load_position(info: DrawInfo, index: u32) -> vec3<f32> {
    if SKIP_EMPTY && bitcast<u32>(positions[index * 3u]) == EMPTY_SLOT {
        return vec3<f32>(0.0);
    }
    let p = vec3<f32>(positions[index * 3u], positions[index * 3u + 1u], positions[index * 3u + 2u]);
    return info.origin + p;
}

fn load_color(index: u32) -> u32 {
    return colors[index];
}
