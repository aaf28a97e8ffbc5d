// The shadow map as an R32Float texture (`depth=f32`): linear light-space depth per texel, +inf
// where empty. `depth_texel` is DepthMap::at for a texel inside the map.
@group(0) @binding(2) var depth_map: texture_2d<f32>;

fn depth_texel(i: i32, j: i32) -> f32 {
    return textureLoad(depth_map, vec2<i32>(i, j), 0).x;
}
