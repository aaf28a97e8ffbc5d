//! The GPU side of [`crate::cpu::pcf`]: the N x N percentage-closer block in `pcf.wgsl`.
use super::map_estimator::GpuFilter;
use crate::settings::Pcf;
use shadow_map_core::gpu::EstimateUniform;

/// WGSL of PCF (`facing`, `visibility`).
pub const PCF_WGSL: &str = include_str!("pcf.wgsl");

impl GpuFilter for Pcf {
    const WGSL: &'static str = PCF_WGSL;
    fn set_uniform(&self, u: &mut EstimateUniform) {
        u.kernel_half = self.half();
    }
}
