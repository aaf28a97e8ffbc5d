//! The engine path of the four baselines (cargo feature `gpu`, on by default): each method's one
//! GPU implementation is its frame ([`FrameEstimator`]), recorded into the caller's command
//! encoder; the registry runs it as the method's GPU estimator through the core's `FrameTwin`.
//!
//! | CPU twin | frame | kernel |
//! |---|---|---|
//! | [`HardShadow`](crate::HardShadow) | [`MapFrame`]`<Hard>` | `map_estimator.wgsl` + `hard.wgsl` |
//! | [`PcfShadow`](crate::PcfShadow) | [`MapFrame`]`<Pcf>` | `map_estimator.wgsl` + `pcf.wgsl` |
//! | [`PcssShadow`](crate::PcssShadow) | [`MapFrame`]`<Pcss>` | `map_estimator.wgsl` + `pcss.wgsl` |
//! | [`MultiSample`](crate::MultiSample) | [`MultiSampleFrame`] | `multi_sample.wgsl` |
//!
//! A frame renders its maps with the core's raster (views fitted on the CPU, as the CPU twin
//! fits them), encodes them to 16-bit codes under `depth=unorm16`, then runs compute kernels,
//! one invocation per receiver
//! ([`WORKGROUP_SIZE`](shadow_map_core::gpu::estimate::WORKGROUP_SIZE) per workgroup), reading
//! receivers as the core's `ReceiverGpu` and the map as an R32Float texture (or packed codes),
//! and writing V into the caller's buffer.
//!
//! The WGSL repeats the CPU math in f32 in the same operation order (glam's dot/cross order written
//! out). Differences that remain on the same map, each far below the twin tolerance of
//! `tests/baselines/gpu_twins.rs`: `front_fraction` clips and integrates in f64 on the CPU and in
//! f32 here; PCSS sums its weights with the same compensated f32 sum on both sides; the driver may
//! fuse a multiply and an add (WGSL does not forbid it), which moves a transform or a bias by an
//! ulp and can flip a depth comparison that is a tie to within f32 rounding.
pub mod frame;
pub mod hard;
pub mod kernel;
pub mod map_estimator;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;

pub use frame::{FrameEstimator, FrameInputs, MapFrame, MultiSampleFrame};
pub use map_estimator::GpuFilter;

use crate::settings::{Hard, Pcf, Pcss};

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
