//! What the baseline kernels add to the core's kernel layer ([`shadow_map_core::gpu::kernel`],
//! whose shader, pipeline and bind-group constructors are re-exported here): the depth-access
//! WGSL part per precision. Every baseline kernel binds 0 the light view (uniform), 1 the
//! [`EstimateUniform`](shadow_map_core::gpu::EstimateUniform) (uniform), 2 the depth map
//! (`texture_2d<f32>` under `depth=f32`, read-only storage of packed 16-bit codes under
//! `depth=unorm16`), 3 the receivers, 4 and 5 read-write storage (V bits and counters, or
//! accumulator and V bits); the layout is read from the WGSL.
pub use shadow_map_core::gpu::kernel::{
    bind_group, compute_pipeline, shader_module, shader_source,
};
use shadow_map_core::DepthPrecision;

/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for an R32Float map (`depth=f32`).
pub const DEPTH_F32_WGSL: &str = include_str!("depth_f32.wgsl");
/// WGSL of binding 2 and `fn depth_texel(i, j) -> f32` for packed 16-bit codes (`depth=unorm16`).
pub const DEPTH_UNORM16_WGSL: &str = include_str!("depth_unorm16.wgsl");

/// The depth-access WGSL part for a precision.
pub const fn depth_wgsl(depth: DepthPrecision) -> &'static str {
    match depth {
        DepthPrecision::F32 => DEPTH_F32_WGSL,
        DepthPrecision::Unorm16 => DEPTH_UNORM16_WGSL,
    }
}
