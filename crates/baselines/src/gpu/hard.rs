//! GPU twin of [`crate::hard`]: the hard shadow map's binary test in `hard.wgsl`.
use super::map_estimator::{GpuFilter, GpuMapEstimator};
use crate::hard::Hard;

/// WGSL of the hard test (`facing`, `visibility`).
pub const HARD_WGSL: &str = include_str!("hard.wgsl");

/// The hard shadow map on the GPU (twin of [`HardShadow`](crate::HardShadow)).
pub type GpuHardShadow = GpuMapEstimator<Hard>;

impl GpuFilter for Hard {
    const WGSL: &'static str = HARD_WGSL;
}
