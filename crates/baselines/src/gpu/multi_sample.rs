//! The GPU side of [`crate::cpu::multi_sample`]: the kernels [`MultiSampleFrame`](super::MultiSampleFrame)
//! dispatches, `accumulate` after each sub-light's map (its hard test into a per-receiver count)
//! and `finalize` once at the end (the count divided by the number of sub-lights).
use super::kernel;
use shadow_map_core::{
    gpu::{
        estimate::{ESTIMATE_HEAD_WGSL, OVERRIDES},
        kernel::SpecializedKernel,
        receivers::ACTIVE_WGSL,
        upload_depth_map, GpuContext, GpuDepthMap, GpuUnorm16Map,
    },
    DepthMap, DepthPrecision, Result, Unorm16Map,
};

/// WGSL of the multi-sample kernels (`accumulate`, `finalize`).
pub const MULTI_SAMPLE_WGSL: &str = include_str!("multi_sample.wgsl");

/// The WGSL parts of the multi-sample kernels reading maps of precision `depth`, in order.
pub const fn shader_parts(depth: DepthPrecision) -> [&'static str; 4] {
    [
        ESTIMATE_HEAD_WGSL,
        kernel::depth_wgsl(depth),
        ACTIVE_WGSL,
        MULTI_SAMPLE_WGSL,
    ]
}

/// The kernels for one depth precision: one module, its entry points `accumulate` and
/// `finalize` specialised for the light's shape.
pub(crate) struct Kernels {
    pub(crate) kernel: SpecializedKernel,
    /// A 1x1 map bound where a kernel reads none (`finalize`).
    pub(crate) placeholder: Placeholder,
}

impl Kernels {
    pub(crate) fn new(ctx: &GpuContext, depth: DepthPrecision) -> Result<Self> {
        let label = "multi-sample";
        let kernel =
            SpecializedKernel::new(ctx, label, &shader_parts(depth), "accumulate", OVERRIDES)?;
        Ok(Kernels {
            kernel,
            placeholder: Placeholder::new(ctx, depth)?,
        })
    }
}

/// An empty 1x1 map in the binding a precision's kernels declare (binding 2): an R32Float
/// texture, or packed 16-bit codes.
pub(crate) enum Placeholder {
    F32(GpuDepthMap),
    Unorm16(GpuUnorm16Map),
}

impl Placeholder {
    fn new(ctx: &GpuContext, depth: DepthPrecision) -> Result<Self> {
        let empty = DepthMap::empty(1);
        Ok(match depth {
            DepthPrecision::F32 => Placeholder::F32(upload_depth_map(ctx, &empty)?),
            DepthPrecision::Unorm16 => Placeholder::Unorm16(GpuUnorm16Map::upload(
                ctx,
                &Unorm16Map::encode(&empty, 1.0, 2.0),
            )?),
        })
    }

    /// The binding of binding 2.
    pub(crate) fn binding(&self) -> wgpu::BindingResource<'_> {
        match self {
            Placeholder::F32(t) => wgpu::BindingResource::TextureView(&t.view),
            Placeholder::Unorm16(m) => m.buffer.as_entire_binding(),
        }
    }
}
