// GPU twin of crates/shadow-map-core/src/precision.rs `encode`: one invocation per pair of texels,
// packing two 16-bit codes into one u32 (texel 2w in the low half, 2w + 1 in the high half).
// Loaded by gpu/precision.rs.

override WG: u32;

// Mirrors gpu::precision::EncodeParams.
struct EncodeParams {
    size: u32,
    near: f32,
    inv_step: f32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> params: EncodeParams;
@group(0) @binding(1) var depth_in: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> codes: array<u32>;

const MAX_CODE: f32 = 65534.0;
const EMPTY_CODE: u32 = 65535u;

// precision::encode: (z - n) * (1 / s) (exact power of two), round half to even, clamp at 0,
// empty at or beyond 65534.5 (and for +inf and NaN: the comparison is false).
fn encode(z: f32) -> u32 {
    let t = (z - params.near) * params.inv_step;
    if !(t < MAX_CODE + 0.5) {
        return EMPTY_CODE;
    }
    if !(t > 0.0) {
        return 0u;
    }
    return u32(round(t));
}

fn code_at(k: u32) -> u32 {
    let n = params.size * params.size;
    if k >= n {
        return EMPTY_CODE;
    }
    let i = k % params.size;
    let j = k / params.size;
    return encode(textureLoad(depth_in, vec2<u32>(i, j), 0).x);
}

@compute @workgroup_size(WG)
fn encode_unorm16(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    // Rows of workgroups when one dimension's limit is not enough.
    let w = id.x + id.y * groups.x * WG;
    if w >= arrayLength(&codes) {
        return;
    }
    codes[w] = code_at(2u * w) | (code_at(2u * w + 1u) << 16u);
}
