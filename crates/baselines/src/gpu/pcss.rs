//! The GPU side of [`crate::cpu::pcss`]: blocker search, penumbra estimate and weighted PCF in
//! `pcss.wgsl`.
use super::map_estimator::GpuFilter;
use crate::settings::Pcss;
use shadow_map_core::gpu::EstimateUniform;

/// WGSL of PCSS (`facing`, `visibility`).
pub const PCSS_WGSL: &str = include_str!("pcss.wgsl");

impl GpuFilter for Pcss {
    const WGSL: &'static str = PCSS_WGSL;
    fn set_uniform(&self, u: &mut EstimateUniform) {
        u.max_taps = self.max_taps;
    }
}
