#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;

pub use cpu::CpuAccumulation;
#[cfg(feature = "gpu")]
pub use gpu::AccumulationFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{setting, MethodDescriptor, Setting};

/// Shadow accumulation in the registry: `accumulation`, its CPU twin and its engine path (also its
/// GPU estimator, run by the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "accumulation",
        || Ok(Box::new(CpuAccumulation::new()?)),
        sweep,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| Ok(Box::new(AccumulationFrame::prepare(ctx, params)?)));
    d
};

/// The report's settings: the kernel size K (Aszodi section 3), the exact variant, a fixed
/// kernel, and the resolution.
fn sweep(quick: bool) -> Vec<Setting> {
    if quick {
        return vec![
            setting(&[("resolution", "256")]),
            setting(&[("variant", "exact")]),
        ];
    }
    let mut s: Vec<Setting> = ["3", "5", "15"]
        .iter()
        .map(|k| setting(&[("k", k)]))
        .collect();
    s.extend([
        setting(&[("variant", "exact")]),
        setting(&[("kernel", "fixed")]),
        setting(&[("resolution", "256")]),
        setting(&[("resolution", "2048")]),
    ]);
    s
}
