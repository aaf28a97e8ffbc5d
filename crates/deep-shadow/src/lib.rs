#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod settings;

pub use cpu::CpuDeepShadow;
#[cfg(feature = "gpu")]
pub use gpu::DeepShadowFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Deep shadow maps in the registry: `deep-shadow`, its CPU twin and engine path (which is also
/// its GPU estimator, the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new("deep-shadow", || Ok(Box::new(CpuDeepShadow::new()?)), SWEEP);
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, n| Ok(Box::new(DeepShadowFrame::prepare(ctx, params, n)?)));
    d
};

/// The report's settings: the filters (none, PCF, EDSM; Fuerst's lookups), the tap cap,
/// sub-lights and the resolution.
const SWEEP: Sweep = Sweep {
    quick: &[&[("resolution", "256")], &[("sublights", "2")]],
    full: &[
        &[("filter", "none")],
        &[("max_taps", "16")],
        &[("filter", "pcf"), ("kernel", "5")],
        &[("filter", "edsm"), ("kernel", "5")],
        &[("sublights", "2")],
        &[("sublights", "3")],
        &[("sublights", "2"), ("filter", "pcf"), ("kernel", "3")],
        &[("resolution", "256")],
        &[("resolution", "512")],
    ],
};
