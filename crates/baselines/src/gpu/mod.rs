//! wgpu twins of the four baselines (cargo feature `gpu`, on by default).
//!
//! | CPU twin | GPU twin | kernel |
//! |---|---|---|
//! | [`HardShadow`](crate::HardShadow) | [`GpuHardShadow`] | `map_estimator.wgsl` + `hard.wgsl` |
//! | [`PcfShadow`](crate::PcfShadow) | [`GpuPcfShadow`] | `map_estimator.wgsl` + `pcf.wgsl` |
//! | [`PcssShadow`](crate::PcssShadow) | [`GpuPcssShadow`] | `map_estimator.wgsl` + `pcss.wgsl` |
//! | [`MultiSample`](crate::MultiSample) | [`GpuMultiSample`] | `multi_sample.wgsl` |
//!
//! Each implements [`SoftShadowEstimator`](shadow_map_core::SoftShadowEstimator) with
//! `backend() == Backend::Gpu` and the CPU twin's name, description and parameter table, and
//! offers `estimate_with`, which takes the light-space data as input (so both twins can see
//! identical data), and `set_max_chunk`, a cap on the receivers of one dispatch. The per-receiver stage is a compute kernel (one invocation per receiver,
//! [`WORKGROUP_SIZE`](shadow_map_core::gpu::estimate::WORKGROUP_SIZE) per workgroup, receivers in chunks that fit the device's limits) reading
//! receivers as the core's `ReceiverGpu`, the shadow map as an R32Float texture, and writing V
//! to a storage buffer that is read back.
//!
//! The WGSL repeats the CPU math in f32 in the same operation order (glam's dot/cross order written
//! out). Differences that remain, each far below the twin tolerance of `tests/gpu_twins.rs`:
//! `front_fraction` clips and integrates in f64 on the CPU and in f32 here; PCSS sums its weights
//! with the same compensated f32 sum on both sides; the driver may fuse a multiply and an add
//! (WGSL does not forbid it), which moves a transform or a bias by an ulp and can flip a depth
//! comparison that is a tie to within f32 rounding.
//!
//! Light-space data come from [`MapBuilder`]: the view fitted on the CPU, the map rasterised on the
//! GPU by the core's `GpuShadowMapper` (or CPU maps given to `estimate_with`).
pub mod frame;
pub mod hard;
pub mod kernel;
pub mod map_estimator;
pub mod maps;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;

pub use frame::{FrameEstimator, FrameInputs, MapFrame, MultiSampleFrame};
pub use hard::GpuHardShadow;
pub use map_estimator::{GpuFilter, GpuMapEstimator};
pub use maps::{DepthTexture, GpuMaps, MapBuilder, MapDepth, MapOrigin};
pub use multi_sample::GpuMultiSample;
pub use pcf::GpuPcfShadow;
pub use pcss::GpuPcssShadow;

use crate::{hard::Hard, pcf::Pcf, pcss::Pcss};

/// Every shader of the crate as `(name, parts in order)`; [`kernel::shader_source`] joins them.
/// A unit test validates each with naga, so a WGSL error fails CPU-only CI.
pub const SHADERS: &[(&str, &[&str])] = &[
    ("hard", &map_estimator::shader_parts::<Hard>(F32)),
    ("pcf", &map_estimator::shader_parts::<Pcf>(F32)),
    ("pcss", &map_estimator::shader_parts::<Pcss>(F32)),
    ("multi-sample", &multi_sample::shader_parts(F32)),
    ("hard unorm16", &map_estimator::shader_parts::<Hard>(U16)),
    ("pcf unorm16", &map_estimator::shader_parts::<Pcf>(U16)),
    ("pcss unorm16", &map_estimator::shader_parts::<Pcss>(U16)),
    ("multi-sample unorm16", &multi_sample::shader_parts(U16)),
];
const F32: shadow_map_core::DepthPrecision = shadow_map_core::DepthPrecision::F32;
const U16: shadow_map_core::DepthPrecision = shadow_map_core::DepthPrecision::Unorm16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_validates_with_naga() {
        test_support::wgsl::assert_shaders_valid(
            SHADERS
                .iter()
                .map(|(name, parts)| (*name, kernel::shader_source(parts))),
        );
    }
}
