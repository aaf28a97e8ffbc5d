// Ceilings of the GPU bench (benches/gpu.rs; embedded by benches/gpu/ceilings.rs): the most
// this adapter does of the three kinds of work the softshadow stages are made of, each measured
// as the plain kernel with nothing else around it.
//
//   taps_kernel    K x K `textureLoad` taps per receiver from an R32Float map, counting the
//                  texels at or behind the receiver (a PCF / blocker-search kernel).
//   tri_vs         pass-through vertex shader for random small triangles rendered depth-only
//                  into a Depth32Float target (no fragment shader).
//   atomic_insert  one linked-list insert per thread: atomicAdd on a global node counter, an
//                  atomicExchange on a list head, one node written (an A-buffer / deep-shadow
//                  insert).
//
// Every resource has its own binding number, so each entry point's automatic layout holds only
// the bindings it uses. Sizes come in as override constants and uniforms set from Rust.

// Kernel side (odd): K x K taps per receiver.
override K: i32 = 15;
// Workgroup side of taps_kernel (WG x WG receivers).
override WG: u32 = 8;
// Workgroup size of atomic_insert.
override WG_LINEAR: u32 = 256;

// PCG hash (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering", JCGT 9(3), pcg).
// benches/gpu/ceilings.rs has the same function (`pcg_hash`) for the CPU twin of taps_kernel.
fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Depth of receiver k in [0, 1): 24 hash bits, exact in f32 on both sides.
fn receiver_z(k: u32) -> f32 {
    return f32(pcg_hash(k) >> 8u) / 16777216.0;
}

// ---- taps_kernel -------------------------------------------------------------------------------

// Mirrors `TapsParams` in benches/gpu/ceilings.rs.
struct TapsParams {
    // Receivers form a width x height grid (a G-buffer); receiver (x, y) sits over texel
    // (x * size / width, y * size / height) of the size x size map.
    width: u32,
    height: u32,
    size: u32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> taps_params: TapsParams;
@group(0) @binding(1) var taps_depth: texture_2d<f32>;
// Lit-tap count per receiver (so nothing is optimised away, and the CPU twin can check it).
@group(0) @binding(2) var<storage, read_write> taps_out: array<u32>;

@compute @workgroup_size(WG, WG)
fn taps_kernel(@builtin(global_invocation_id) id: vec3<u32>) {
    let p = taps_params;
    if id.x >= p.width || id.y >= p.height {
        return;
    }
    let k = id.y * p.width + id.x;
    let c = vec2<i32>(i32(id.x * p.size / p.width), i32(id.y * p.size / p.height));
    let z = receiver_z(k);
    let hi = vec2<i32>(i32(p.size) - 1);
    let r = K / 2;
    var lit = 0u;
    for (var dj = -r; dj <= r; dj += 1) {
        for (var di = -r; di <= r; di += 1) {
            let t = clamp(c + vec2<i32>(di, dj), vec2<i32>(0), hi);
            lit += select(0u, 1u, textureLoad(taps_depth, t, 0).x >= z);
        }
    }
    taps_out[k] = lit;
}

// ---- tri_vs ------------------------------------------------------------------------------------

// Vertices are already in clip space (w = 1); the pipeline has no fragment stage.
@vertex
fn tri_vs(@location(0) position: vec4<f32>) -> @builtin(position) vec4<f32> {
    return position;
}

// ---- atomic_insert -----------------------------------------------------------------------------

// Mirrors `InsertParams` in benches/gpu/ceilings.rs.
struct InsertParams {
    // Inserts (threads doing work).
    count: u32,
    // List heads; insert t goes to list t % heads (neighbouring threads, neighbouring lists, as
    // fragments of one triangle land in neighbouring texels).
    heads: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(3) var<uniform> insert_params: InsertParams;
// Next free node; cleared to 0 before each pass.
@group(0) @binding(4) var<storage, read_write> node_counter: atomic<u32>;
// Head of each list: index + 1 of its first node, 0 = empty; cleared before each pass.
@group(0) @binding(5) var<storage, read_write> list_heads: array<atomic<u32>>;
// Nodes: (payload, index + 1 of the next node).
@group(0) @binding(6) var<storage, read_write> nodes: array<vec2<u32>>;

@compute @workgroup_size(WG_LINEAR)
fn atomic_insert(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let t = id.y * groups.x * WG_LINEAR + id.x;
    if t >= insert_params.count {
        return;
    }
    let node = atomicAdd(&node_counter, 1u);
    let next = atomicExchange(&list_heads[t % insert_params.heads], node + 1u);
    nodes[node] = vec2<u32>(pcg_hash(t), next);
}
