//! The GPU side of [`crate::cpu::multi_sample`]: the kernels [`MultiSampleFrame`](super::MultiSampleFrame)
//! dispatches, `accumulate` after each sub-light's map (its hard test into a per-receiver count)
//! and `finalize` once at the end (the count divided by the number of sub-lights).
use super::kernel;
use shadow_map_core::{
    gpu::{
        estimate::{ESTIMATE_HEAD_WGSL, OVERRIDES},
        kernel::SpecializedKernel,
        receivers::ACTIVE_WGSL,
        GpuContext,
    },
    DepthPrecision, Result,
};

/// WGSL of the multi-sample kernels (`accumulate`, `finalize`).
pub const MULTI_SAMPLE_WGSL: &str = include_str!("multi_sample.wgsl");

/// The WGSL parts of the multi-sample kernels reading maps of precision `depth`, in order.
pub const fn shader_parts(depth: DepthPrecision) -> [&'static str; 4] {
    [
        ESTIMATE_HEAD_WGSL,
        kernel::depth_wgsl(depth, true),
        ACTIVE_WGSL,
        MULTI_SAMPLE_WGSL,
    ]
}

/// The kernels for one depth precision: one module, its entry points `accumulate` and
/// `finalize` specialised for the light's shape.
pub(crate) struct Kernels {
    pub(crate) kernel: SpecializedKernel,
}

impl Kernels {
    pub(crate) fn new(ctx: &GpuContext, depth: DepthPrecision) -> Result<Self> {
        let label = "multi-sample";
        let kernel =
            SpecializedKernel::new(ctx, label, &shader_parts(depth), "accumulate", OVERRIDES)?;
        Ok(Kernels { kernel })
    }
}
