// The shadow map at full precision (`depth=f32`) of a kernel with few taps per receiver (hard,
// multi-sample): the map pass's depth test itself (the pass has no fragment stage;
// GpuMapFrame::depth_only), n / z reversed or an orthographic view's 1 - (z - n) / s, 0 where
// empty. `depth_texel` is DepthMap::at for a texel inside the map: its
// linear light-space depth (the core's linear_depth), +inf where empty.
@group(0) @binding(2) var depth_map: texture_depth_2d;

fn depth_texel(i: i32, j: i32) -> f32 {
    return linear_depth(view, textureLoad(depth_map, vec2<i32>(i, j), 0));
}
