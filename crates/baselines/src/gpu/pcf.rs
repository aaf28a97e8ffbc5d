//! GPU twin of [`crate::pcf`]: the N x N percentage-closer block in `pcf.wgsl`.
use super::map_estimator::{GpuFilter, GpuMapEstimator};
use crate::{map_estimator::Filter, pcf::Pcf};
use shadow_map_core::gpu::EstimateUniform;
use shadow_map_core::Params;

/// WGSL of PCF (`facing`, `visibility`).
pub const PCF_WGSL: &str = include_str!("pcf.wgsl");

/// PCF on the GPU (twin of [`PcfShadow`](crate::PcfShadow)).
pub type GpuPcfShadow = GpuMapEstimator<Pcf>;

impl GpuFilter for Pcf {
    const WGSL: &'static str = PCF_WGSL;
    fn set_uniform(p: &Params, u: &mut EstimateUniform) {
        u.kernel_half = Pcf::from_params(p).half();
    }
}
