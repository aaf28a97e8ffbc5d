#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod settings;

pub use cpu::CpuAccumulation;
#[cfg(feature = "gpu")]
pub use gpu::AccumulationFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Shadow accumulation in the registry: `accumulation`, its CPU twin and its engine path (also its
/// GPU estimator, run by the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "accumulation",
        || Ok(Box::new(CpuAccumulation::new()?)),
        SWEEP,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| Ok(Box::new(AccumulationFrame::prepare(ctx, params)?)));
    d
};

/// The report's settings: the kernel size K (Aszodi section 3), the exact variant, a fixed
/// kernel, and the resolution.
const SWEEP: Sweep = Sweep {
    quick: &[&[("resolution", "256")], &[("variant", "exact")]],
    full: &[
        &[("k", "3")],
        &[("k", "5")],
        &[("k", "15")],
        &[("variant", "exact")],
        &[("kernel", "fixed")],
        &[("resolution", "256")],
        &[("resolution", "2048")],
    ],
};
