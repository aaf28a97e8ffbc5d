// The provided composite pass: the view's colour scaled by V, `colour * mix(1, V, strength)`.
// Pixels without a V (background, NaN) are left as they are.
struct Composite {
    strength: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

@group(0) @binding(0) var source: texture_2d<f32>;
@group(0) @binding(1) var visibility: texture_2d<f32>;
@group(0) @binding(2) var<uniform> params: Composite;

@vertex
fn vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen.
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fragment(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let xy = vec2<i32>(p.xy);
    let c = textureLoad(source, xy, 0);
    var v = textureLoad(visibility, xy, 0).r;
    if !(v >= 0.0 && v <= 1.0) {
        v = 1.0;
    }
    return vec4<f32>(c.rgb * mix(1.0, v, params.strength), c.a);
}
