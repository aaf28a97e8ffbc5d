//! The GPU side of [`crate::cpu::pcss`]: blocker search, penumbra estimate and weighted PCF in
//! `pcss.wgsl`.
use super::map_estimator::GpuFilter;
use crate::settings::Pcss;
use shadow_map_core::gpu::EstimateUniform;

/// WGSL of PCSS (`facing`, `visibility`).
pub const PCSS_WGSL: &str = include_str!("pcss.wgsl");

/// Cells a region of PCSS's may hold before its receiver goes to the wide pass (a workgroup per
/// receiver): a receiver whose two regions fit in 2 x 16,384 taps stays in the first pass, inside
/// lavapipe's 65,535 loop trips, where one invocation per receiver is the faster of the two
/// (docs/gpu.md, "PCSS's wide pass"); past it, each lane of the wide pass runs at most
/// ⌈max_taps² / 64⌉ taps a region (16,384 at the largest `max_taps`, 1,024).
pub const WIDE_CELLS: u32 = 16384;

impl GpuFilter for Pcss {
    const WGSL: &'static str = PCSS_WGSL;
    /// The wide pass only where `max_taps` lets a region pass [`WIDE_CELLS`].
    fn wide_cells(&self) -> Option<u32> {
        (self.max_taps.saturating_mul(self.max_taps) > WIDE_CELLS).then_some(WIDE_CELLS)
    }
    fn set_uniform(&self, u: &mut EstimateUniform) {
        u.max_taps = self.max_taps;
    }
}
