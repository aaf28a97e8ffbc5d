#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;

pub use cpu::CpuBackprojection;
#[cfg(feature = "gpu")]
pub use gpu::BackprojectionFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{resolution_sweep, setting, MethodDescriptor, Setting};

/// Backprojection in the registry: `backprojection`, its CPU twin and its engine path, which
/// is also its GPU estimator (the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "backprojection",
        || Ok(Box::new(CpuBackprojection::new()?)),
        sweep,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| Ok(Box::new(BackprojectionFrame::prepare(ctx, params)?)));
    d
};

/// The report's settings: layers (Bavoil section 3), gap filling, occlusion, self-shadowing,
/// the kernel's sample cap, and the resolution.
fn sweep(quick: bool) -> Vec<Setting> {
    if quick {
        return vec![
            setting(&[("resolution", "256")]),
            setting(&[("layers", "1")]),
        ];
    }
    let mut s = resolution_sweep(false);
    s.extend([
        setting(&[("layers", "1")]),
        setting(&[("layers", "2")]),
        setting(&[("gap_filling", "false")]),
        setting(&[("occlusion", "additive")]),
        setting(&[("self_shadow", "bias")]),
        setting(&[("max_nspp", "25")]),
        setting(&[("max_nspp", "49")]),
    ]);
    s
}
