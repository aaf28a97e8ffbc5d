// Receivers from a caller's depth and normal textures (depth_receivers.rs): one
// ReceiverGpu per pixel, receiver j * width + i for pixel (i, j), row 0 at the top. Appended
// after shared.wgsl (ReceiverGpu).

// Mirrors depth_receivers.rs DepthReceiversParams (checked by naga there).
struct DepthReceiversParams {
    // Clip (NDC x, y in [-1, 1], y up; depth in [0, 1]) to world.
    inv_view_proj: mat4x4<f32>,
    // The eye (world): normals are turned to face it.
    eye: vec3<f32>,
    // 1: reverse Z (depth 1 at the near plane, 0 the background).
    reverse_z: u32,
    width: u32,
    height: u32,
    // 1: the normal texture stores n * 0.5 + 0.5 (an unorm target, Bevy's normal prepass).
    unorm_normals: u32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> P: DepthReceiversParams;
@group(0) @binding(1) var depth_tex: texture_depth_2d;
@group(0) @binding(2) var normal_tex: texture_2d<f32>;
@group(0) @binding(3) var<storage, read_write> out_receivers: array<ReceiverGpu>;

fn finite3(v: vec3<f32>) -> bool {
    // Not NaN and not infinite, on the bits (a driver may fold x == x).
    let b = bitcast<vec3<u32>>(v) & vec3<u32>(0x7fffffffu);
    return all(b < vec3<u32>(0x7f800000u));
}

// One pixel per invocation: the pixel centre's clip position at the stored depth, carried to
// world by inv_view_proj; the normal decoded, normalised and turned towards the eye (the
// contract's receiver normal: on the side the receiver is seen from). The background (depth at
// the far end: 1, or 0 under reverse Z), a degenerate position or a zero normal is an inactive
// slot: origin, normal +Z, as the core's G-buffer writes it.
@compute @workgroup_size(8, 8)
fn depth_receivers(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= P.width || gid.y >= P.height {
        return;
    }
    let k = gid.y * P.width + gid.x;
    let ij = vec2<i32>(gid.xy);
    let d = textureLoad(depth_tex, ij, 0);
    var r: ReceiverGpu;
    r.position = vec3<f32>(0.0);
    r.normal = vec3<f32>(0.0, 0.0, 1.0);
    r.is_active = 0u;
    r._pad0 = 0.0;
    var background = d >= 1.0;
    if P.reverse_z != 0u {
        background = d <= 0.0;
    }
    let ndc = vec2<f32>(
        (f32(gid.x) + 0.5) / f32(P.width) * 2.0 - 1.0,
        1.0 - (f32(gid.y) + 0.5) / f32(P.height) * 2.0,
    );
    let h = P.inv_view_proj * vec4<f32>(ndc, d, 1.0);
    let p = h.xyz / h.w;
    var n = textureLoad(normal_tex, ij, 0).xyz;
    if P.unorm_normals != 0u {
        n = n * 2.0 - vec3<f32>(1.0);
    }
    let len = length(n);
    if background || !finite3(p) || !(len > 0.0) || !finite3(n) {
        out_receivers[k] = r;
        return;
    }
    n = n / len;
    if dot(n, P.eye - p) < 0.0 {
        n = -n;
    }
    r.position = p;
    r.normal = n;
    r.is_active = 1u;
    out_receivers[k] = r;
}
