// The camera G-buffer (GPU twin of receivers.rs `Receivers::from_camera`).
// Prepended by shared.wgsl (Frame, ReceiverGpu). Loaded by gpu/gbuffer.rs.
//
// Pass 1 (render, vs_main + fs_main): every triangle is one instance of three vertices, its three
// corners instance attributes (GpuScene's vertex buffer read with a 48-byte instance stride), so
// each vertex computes the face normal cross(v1 - v0, v2 - v0) exactly as bvh.rs does and passes
// it flat. The fragment shader intersects the contract's ray through its pixel centre with the
// triangle's plane and writes (unit normal facing the camera, ray distance t) and the triangle
// index; the depth test (reversed, infinite far: compare Greater, clear 0) compares NEAR / Z of
// that exact intersection.
// Pass 2 (compute, resolve): one thread per pixel writes ReceiverGpu, view depth Z and the
// triangle index into storage buffers in image layout (j * width + i), a chunk of pixels at a time.

// Mirrors gpu::gbuffer::GBufferCamera (checked by tests/gpu_gbuffer.rs). The eye and the basis
// are one Frame (shared.wgsl): origin = eye, ex = right, ey = true_up, ez = forward.
struct GBufferCamera {
    frame: Frame,
    t: f32,
    aspect: f32,
    near: f32,
    width: f32,
    height: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

// Mirrors gpu::gbuffer::ResolveParams (checked by tests/gpu_gbuffer.rs).
struct ResolveParams {
    width: u32,
    first: u32,
    count: u32,
    background_z: f32,
}

// Largest finite f32: anything above it is +inf (WGSL has no infinity literal).
const F32_MAX: f32 = 3.40282347e+38;
// Triangle index of a background pixel (the clear value of the index target).
const NO_TRIANGLE: u32 = 0xffffffffu;
// Threads per resolve workgroup (gpu::gbuffer::RESOLVE_WORKGROUP).
const RESOLVE_WG: u32 = 64u;

@group(0) @binding(0) var<uniform> cam: GBufferCamera;
@group(0) @binding(1) var<uniform> resolve: ResolveParams;
@group(0) @binding(2) var normal_t: texture_2d<f32>;
@group(0) @binding(3) var triangle_id: texture_2d<u32>;
@group(0) @binding(4) var<storage, read_write> receivers: array<ReceiverGpu>;
@group(0) @binding(5) var<storage, read_write> view_depth: array<f32>;
@group(0) @binding(6) var<storage, read_write> triangles: array<u32>;

// camera.rs Camera::ray_dir for the pixel centre (px, py) = (i + 0.5, j + 0.5), in the CPU's
// order of operations (t and aspect computed on the CPU exactly as ray_dir computes them).
fn ray_dir(px: f32, py: f32) -> vec3<f32> {
    let ndc_x = px / cam.width * 2.0 - 1.0;
    let ndc_y = 1.0 - py / cam.height * 2.0;
    return normalize(cam.frame.ez + ndc_x * cam.t * cam.aspect * cam.frame.ex
        + ndc_y * cam.t * cam.frame.ey);
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    // Face normal cross(v1 - v0, v2 - v0) (not normalised), the same at all three vertices.
    @location(0) @interpolate(flat) face: vec3<f32>,
    // First corner: a point of the triangle's plane.
    @location(1) @interpolate(flat) v0: vec3<f32>,
    @location(2) @interpolate(flat) tri: u32,
}

// View coordinates x = (p - eye).right, y = (p - eye).true_up, z = (p - eye).forward (cam.frame's
// origin, ex, ey, ez);
//   clip = (x / (t aspect), y / t, NEAR, z)
// so NDC (x / (z t aspect), y / (z t)) is the contract's (ndc_x, ndc_y) of the ray through p, wgpu's
// framebuffer row 0 is NDC y = +1 (row 0 at the top, as the contract's j), the depth is NEAR / z
// (reversed, infinite far) and the clip volume 0 <= clip.z <= clip.w keeps z >= NEAR.
@vertex
fn vs_main(
    @builtin(vertex_index) vi: u32,
    @builtin(instance_index) tri: u32,
    @location(0) a: vec4<f32>,
    @location(1) b: vec4<f32>,
    @location(2) c: vec4<f32>,
) -> VsOut {
    var p = a.xyz;
    if vi == 1u {
        p = b.xyz;
    } else if vi == 2u {
        p = c.xyz;
    }
    let d = p - cam.frame.origin;
    let x = dot(d, cam.frame.ex);
    let y = dot(d, cam.frame.ey);
    let z = dot(d, cam.frame.ez);
    var out: VsOut;
    out.clip = vec4<f32>(x / (cam.t * cam.aspect), y / cam.t, cam.near, z);
    out.face = cross(b.xyz - a.xyz, c.xyz - a.xyz);
    out.v0 = a.xyz;
    out.tri = tri;
    return out;
}

struct FsOut {
    // Unit geometric normal facing the camera, and the ray distance t of the hit.
    @location(0) normal_t: vec4<f32>,
    @location(1) tri: u32,
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let d = ray_dir(in.clip.x, in.clip.y);
    let t = dot(in.v0 - cam.frame.origin, in.face) / dot(d, in.face);
    let z = t * dot(d, cam.frame.ez);
    // Edge-on triangles (the ray parallel to the plane) and hits behind the eye are misses.
    if !(t > 0.0) || t > F32_MAX || !(z > 0.0) {
        discard;
    }
    var n = normalize(in.face);
    if dot(n, d) > 0.0 {
        n = -n;
    }
    var out: FsOut;
    out.normal_t = vec4<f32>(n, t);
    out.tri = in.tri;
    out.depth = clamp(cam.near / z, 0.0, 1.0);
    return out;
}

// One thread per pixel of the chunk [first, first + count): pixel k = j * width + i.
@compute @workgroup_size(RESOLVE_WG)
fn resolve_main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let local = (wg.y * groups.x + wg.x) * RESOLVE_WG + lid;
    if local >= resolve.count {
        return;
    }
    let k = resolve.first + local;
    let i = k % resolve.width;
    let j = k / resolve.width;
    let tri = textureLoad(triangle_id, vec2<u32>(i, j), 0).x;
    var r: ReceiverGpu;
    if tri == NO_TRIANGLE {
        // Receivers::from_camera's background slot: position 0, normal +Z, Z = +inf.
        r.position = vec3<f32>(0.0, 0.0, 0.0);
        r.is_active = 0u;
        r.normal = vec3<f32>(0.0, 0.0, 1.0);
        r._pad0 = 0.0;
        receivers[local] = r;
        view_depth[local] = resolve.background_z;
        triangles[local] = NO_TRIANGLE;
        return;
    }
    let nt = textureLoad(normal_t, vec2<u32>(i, j), 0);
    // The same ray as the fragment that won the depth test (identical arithmetic).
    let d = ray_dir(f32(i) + 0.5, f32(j) + 0.5);
    r.position = cam.frame.origin + d * nt.w;
    r.is_active = 1u;
    r.normal = nt.xyz;
    r._pad0 = 0.0;
    receivers[local] = r;
    view_depth[local] = nt.w * dot(d, cam.frame.ez);
    triangles[local] = tri;
}
