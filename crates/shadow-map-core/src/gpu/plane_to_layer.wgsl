// Copies one row-major `size x size` f32 plane (an MSSM level in a storage buffer, as
// `shadow_map_core::gpu::mssm` builds it) into layer `layer` of an R32Float texture array, the
// layout `backprojection.wgsl` reads: for sides that are not multiples of 64, whose rows
// `copy_buffer_to_texture` cannot copy (they must be 256-byte aligned; KernelMaps::record copies
// the others by transfer).
struct PlaneCopy {
    size: u32,
    layer: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> pc: PlaneCopy;
@group(0) @binding(1) var<storage, read> plane: array<f32>;
@group(0) @binding(2) var layers: texture_storage_2d_array<r32float, write>;

@compute @workgroup_size(16, 16, 1)
fn copy_plane(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= pc.size || g.y >= pc.size {
        return;
    }
    let z = plane[g.y * pc.size + g.x];
    textureStore(layers, vec2<i32>(i32(g.x), i32(g.y)), i32(pc.layer), vec4<f32>(z, 0.0, 0.0, 1.0));
}
