// GPU twin of crates/shadow-map-core/src/peeling.rs `midpoints` (Bavoil §4.2, after Woo 1992).
// Loaded by gpu/midpoint.rs.

override WG_X: u32;
override WG_Y: u32;

// Mirrors gpu::midpoint::MidpointParams (checked by tests/layouts.rs).
struct MidpointParams {
    size: u32,
    max_bias: f32,
    _pad0: u32,
    _pad1: u32,
}

// Largest finite f32: a depth above it is +inf (WGSL has no infinity literal).
const F32_MAX: f32 = 3.40282347e+38;

@group(0) @binding(0) var<uniform> params: MidpointParams;
@group(0) @binding(1) var layer_m: texture_2d<f32>;
@group(0) @binding(2) var layer_next: texture_2d<f32>;
@group(0) @binding(3) var midpoint_out: texture_storage_2d<r32float, write>;

// peeling::midpoint: min((a + b) / 2, a + max_bias); a + max_bias when b is empty; +inf when a is.
fn midpoint(a: f32, b: f32, max_bias: f32) -> f32 {
    if abs(a) > F32_MAX {
        return abs(a);
    }
    let clamp_depth = a + max_bias;
    if abs(b) > F32_MAX {
        return clamp_depth;
    }
    return min(0.5 * (a + b), clamp_depth);
}

@compute @workgroup_size(WG_X, WG_Y)
fn midpoint_layer(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size || id.y >= params.size {
        return;
    }
    let a = textureLoad(layer_m, id.xy, 0).x;
    let b = textureLoad(layer_next, id.xy, 0).x;
    textureStore(midpoint_out, id.xy, vec4<f32>(midpoint(a, b, params.max_bias), 0.0, 0.0, 1.0));
}
