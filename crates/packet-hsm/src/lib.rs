#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod settings;

pub use cpu::CpuPacketHsm;
#[cfg(feature = "gpu")]
pub use gpu::PacketHsmFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Packet-based hierarchical soft shadow mapping in the registry: `packet-hsm`, its CPU twin
/// and its engine path (also its GPU estimator, through the core's frame twin).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new("packet-hsm", || Ok(Box::new(CpuPacketHsm::new()?)), SWEEP);
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, n| Ok(Box::new(PacketHsmFrame::prepare(ctx, params, n)?)));
    d
};

/// The report's settings: sub-lights (Yang section 5), packet sizes (Algorithm 2) and the
/// resolution; hierarchy and coherence change only the time, so the report runs their defaults.
const SWEEP: Sweep = Sweep {
    quick: &[&[("resolution", "256")], &[("sublights", "2")]],
    full: &[
        &[("sublights", "2")],
        &[("sublights", "4")],
        &[("packet", "1x1")],
        &[("packet", "4x4")],
        &[("resolution", "256")],
        &[("resolution", "512")],
    ],
};
