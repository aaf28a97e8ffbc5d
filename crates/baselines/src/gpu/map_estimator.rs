//! The GPU side of [`crate::cpu::map_estimator`]: the per-receiver kernel that
//! [`MapFrame`](super::MapFrame) dispatches after rendering its map (`map_estimator.wgsl` + the
//! filter's WGSL, one invocation per receiver), and [`GpuFilter`], what each of hard, PCF and
//! PCSS adds to it.
use super::kernel;
use crate::cpu::Filter;
use shadow_map_core::{
    gpu::{
        estimate::{EstimateUniform, ESTIMATE_HEAD_WGSL},
        receivers::RECEIVERS_WGSL,
    },
    DepthPrecision,
};

/// WGSL of the kernel shared by hard, PCF and PCSS (bindings, `estimate_receiver`).
pub const MAP_ESTIMATOR_WGSL: &str = include_str!("map_estimator.wgsl");

pub use shadow_map_core::gpu::estimate::CELLS_WGSL;

/// The GPU side of a [`Filter`]: WGSL defining `fn facing(p_world, n_world) -> f32` and
/// `fn visibility(r: ReceiverSample) -> f32` exactly as the CPU filter computes them, and the
/// filter's settings in the uniform.
pub trait GpuFilter: Filter {
    /// The filter's WGSL (appended after [`MAP_ESTIMATOR_WGSL`]).
    const WGSL: &'static str;
    /// Whether the frame lists the active receivers first and runs over them only
    /// (`ActiveLists`). A filter whose per-receiver work is about what listing a slot costs
    /// (the hard test's one tap) runs over every slot instead (the core's `estimate_slots`).
    const ACTIVE_LIST: bool = true;
    /// Whether the filter takes few taps per receiver, so that its map is best read as the
    /// raster's depth test under `depth=f32` ([`kernel::map_is_depth_test`]).
    const FEW_TAPS: bool = false;
    /// When the filter's WGSL has a wide pass and its settings may need it: the override
    /// `WIDE_CELLS`, past which `visibility` defers (-2) a receiver whose region holds more
    /// cells, and the entry point `estimate_wide` runs it with a whole workgroup
    /// (`ListKind::DeferredWide`).
    fn wide_cells(&self) -> Option<u32> {
        None
    }
    /// Writes the filter's settings (as the CPU filter's own `from_params` read them).
    fn set_uniform(&self, _u: &mut EstimateUniform) {}
}

/// The WGSL parts of the kernel of filter `F` reading a map of precision `depth`, in order.
pub const fn shader_parts<F: GpuFilter>(depth: DepthPrecision) -> [&'static str; 6] {
    [
        ESTIMATE_HEAD_WGSL,
        RECEIVERS_WGSL,
        kernel::depth_wgsl(depth, F::FEW_TAPS),
        CELLS_WGSL,
        MAP_ESTIMATOR_WGSL,
        F::WGSL,
    ]
}
