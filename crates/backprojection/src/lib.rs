#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod settings;

pub use cpu::CpuBackprojection;
#[cfg(feature = "gpu")]
pub use gpu::BackprojectionFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Backprojection in the registry: `backprojection`, its CPU twin and its engine path, which
/// is also its GPU estimator (the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "backprojection",
        || Ok(Box::new(CpuBackprojection::new()?)),
        SWEEP,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| Ok(Box::new(BackprojectionFrame::prepare(ctx, params)?)));
    d
};

/// The report's settings: layers (Bavoil section 3), gap filling, occlusion, self-shadowing,
/// the kernel's sample cap, and the resolution.
const SWEEP: Sweep = Sweep {
    quick: &[&[("resolution", "256")], &[("layers", "1")]],
    full: &[
        &[("resolution", "256")],
        &[("resolution", "512")],
        &[("resolution", "2048")],
        &[("layers", "1")],
        &[("layers", "2")],
        &[("gap_filling", "false")],
        &[("occlusion", "additive")],
        &[("self_shadow", "bias")],
        &[("max_nspp", "25")],
        &[("max_nspp", "49")],
    ],
};
