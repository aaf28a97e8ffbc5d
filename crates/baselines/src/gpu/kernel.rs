//! What the baseline kernels add to the core's kernel layer ([`shadow_map_core::gpu::kernel`],
//! whose shader, pipeline and bind-group constructors are re-exported here): the depth-access
//! WGSL part per precision. Every baseline kernel binds 0 the light view (uniform), 1 the
//! [`EstimateUniform`](shadow_map_core::gpu::EstimateUniform) (uniform), 2 the depth map
//! (`texture_2d<f32>`, or the map pass's depth test, `texture_depth_2d`, under `depth=f32`;
//! read-only storage of packed 16-bit codes under
//! `depth=unorm16`), 3 the receivers, 4 and 5 read-write storage (V bits and counters, or
//! accumulator and V bits); the layout is read from the WGSL.
pub use shadow_map_core::gpu::kernel::{
    bind_group, compute_pipeline, shader_module, shader_source,
};
use shadow_map_core::DepthPrecision;

/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for an R32Float map (`depth=f32`).
pub const DEPTH_F32_WGSL: &str = include_str!("depth_f32.wgsl");
/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for a depth-only map's depth test
/// (`depth=f32`, [`map_is_depth_test`]).
pub const DEPTH_TEST_WGSL: &str = include_str!("depth_test.wgsl");
/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for packed 16-bit codes (`depth=unorm16`).
pub const DEPTH_UNORM16_WGSL: &str = include_str!("depth_unorm16.wgsl");

/// Whether a kernel of `taps` kind reads its map as the raster's depth test (a depth-only map
/// pass, no fragment stage): under `depth=f32`, for the kernels of one tap per receiver and map
/// (hard, multi-sample), where the faster pass outweighs the dearer tap (`n / z` inverted; a
/// kernel of many taps, PCF's and PCSS's, reads the fragment stage's linear layer instead).
pub const fn map_is_depth_test(depth: DepthPrecision, few_taps: bool) -> bool {
    few_taps && matches!(depth, DepthPrecision::F32)
}

/// The depth-access WGSL part for a precision, and for a kernel of few taps
/// ([`map_is_depth_test`]).
pub const fn depth_wgsl(depth: DepthPrecision, few_taps: bool) -> &'static str {
    match depth {
        DepthPrecision::F32 if few_taps => DEPTH_TEST_WGSL,
        DepthPrecision::F32 => DEPTH_F32_WGSL,
        DepthPrecision::Unorm16 => DEPTH_UNORM16_WGSL,
    }
}
