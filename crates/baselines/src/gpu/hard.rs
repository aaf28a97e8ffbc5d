//! The GPU side of [`crate::cpu::hard`]: the hard shadow map's binary test in `hard.wgsl`.
use super::map_estimator::GpuFilter;
use crate::settings::Hard;

/// WGSL of the hard test (`facing`, `visibility`).
pub const HARD_WGSL: &str = include_str!("hard.wgsl");

impl GpuFilter for Hard {
    const WGSL: &'static str = HARD_WGSL;
    const ACTIVE_LIST: bool = false;
    const FEW_TAPS: bool = true;
}
