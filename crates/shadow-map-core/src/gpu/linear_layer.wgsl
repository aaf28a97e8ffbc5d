// A depth-only map pass's depth test as a linear layer (GpuMapFrame::fill_layer, for read-back):
// each texel's linear light-space depth (shared.wgsl's linear_depth, what the kernels reading the
// depth test compute), +inf where empty. One invocation per texel.

@group(0) @binding(0) var<uniform> view: LightViewUniform;
@group(0) @binding(1) var depth_test: texture_depth_2d;
@group(0) @binding(2) var layer: texture_storage_2d<r32float, write>;

@compute @workgroup_size(8, 8)
fn linear_layer(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = textureDimensions(layer);
    if id.x >= r.x || id.y >= r.y {
        return;
    }
    let d = textureLoad(depth_test, vec2<u32>(id.xy), 0);
    textureStore(layer, vec2<u32>(id.xy), vec4<f32>(linear_depth(view, d), 0.0, 0.0, 0.0));
}
