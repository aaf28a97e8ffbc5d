// Casters from a caller's vertex and index buffers with per-instance transforms (casters.rs):
// one invocation per output triangle, written as the GpuScene layout every raster pass
// reads (three vec4 per triangle, non-indexed: the position, and the mesh's opacity in w).

// Mirrors casters.rs CasterParams (checked by naga there).
struct CasterParams {
    // Vertex stride and the position's offset in the caller's vertex buffer, in 4-byte words.
    vertex_stride_words: u32,
    position_offset_words: u32,
    // The mesh's first index (or first vertex when not indexed) and index count per instance.
    first_index: u32,
    index_count: u32,
    // Added to every index (wgpu's base_vertex).
    base_vertex: i32,
    // 0: not indexed, 1: u16 indices, 2: u32 indices.
    index_kind: u32,
    // Where this mesh's first output triangle goes.
    out_first_triangle: u32,
    // Instances in this dispatch (their transforms from the binding's start).
    instances: u32,
    // Invocations per row of the 2D dispatch (workgroups in x times the workgroup size).
    row: u32,
    // The mesh's opacity, each output vertex's w.
    opacity: f32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> P: CasterParams;
@group(0) @binding(1) var<storage, read> vertex_words: array<u32>;
@group(0) @binding(2) var<storage, read> index_words: array<u32>;
@group(0) @binding(3) var<storage, read> transforms: array<mat4x4<f32>>;
@group(0) @binding(4) var<storage, read_write> out_vertices: array<vec4<f32>>;

fn vertex_index(i: u32) -> u32 {
    if P.index_kind == 0u {
        return u32(i32(i) + P.base_vertex);
    }
    var v = 0u;
    if P.index_kind == 1u {
        let w = index_words[i >> 1u];
        v = select(w & 0xffffu, w >> 16u, (i & 1u) == 1u);
    } else {
        v = index_words[i];
    }
    return u32(i32(v) + P.base_vertex);
}

@compute @workgroup_size(64)
fn build_casters(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.y * P.row + gid.x;
    let per = P.index_count / 3u;
    if per == 0u || t >= per * P.instances {
        return;
    }
    let inst = t / per;
    let tri = t - inst * per;
    let m = transforms[inst];
    for (var c = 0u; c < 3u; c++) {
        let vi = vertex_index(P.first_index + 3u * tri + c);
        let o = vi * P.vertex_stride_words + P.position_offset_words;
        let p = vec3<f32>(
            bitcast<f32>(vertex_words[o]),
            bitcast<f32>(vertex_words[o + 1u]),
            bitcast<f32>(vertex_words[o + 2u]),
        );
        // An affine transform (the last row is not applied).
        let w = m * vec4<f32>(p, 1.0);
        out_vertices[3u * (P.out_first_triangle + t) + c] = vec4<f32>(w.xyz, P.opacity);
    }
}
