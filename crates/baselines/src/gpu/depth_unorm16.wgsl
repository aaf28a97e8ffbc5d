// The shadow map as packed 16-bit codes (`depth=unorm16`; shadow_map_core::precision): two codes
// per u32, texel k = j r + i in half k & 1. `depth_texel` is Unorm16Map::at for a texel inside the
// map: n + q s (s = est.depth_step, a power of two, so the product is exact), +inf for 0xffff.
@group(0) @binding(2) var<storage, read> depth_codes: array<u32>;

fn depth_texel(i: i32, j: i32) -> f32 {
    let k = u32(j) * view.r + u32(i);
    let q = (depth_codes[k >> 1u] >> ((k & 1u) * 16u)) & 0xffffu;
    if q == 0xffffu {
        return bitcast<f32>(0x7f800000u);
    }
    return view.n + f32(q) * est.depth_step;
}
