#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
pub mod dsm;
#[cfg(feature = "gpu")]
pub mod frame;
pub mod params;
pub mod raster;
pub mod shared;

pub use cpu::CpuDeepShadow;
#[cfg(feature = "gpu")]
pub use frame::DeepShadowFrame;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{setting, MethodDescriptor, Setting};

/// Deep shadow maps in the registry: `deep-shadow`, its CPU twin and engine path (which is also
/// its GPU estimator, the core's `FrameTwin`).
pub const DESCRIPTOR: MethodDescriptor = {
    let d = MethodDescriptor::new("deep-shadow", || Ok(Box::new(CpuDeepShadow::new()?)), sweep);
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, n| Ok(Box::new(DeepShadowFrame::prepare(ctx, params, n)?)));
    d
};

/// The report's settings: the filters (none, PCF, EDSM; Fuerst's lookups), the tap cap,
/// sub-lights and the resolution.
fn sweep(quick: bool) -> Vec<Setting> {
    if quick {
        return vec![
            setting(&[("resolution", "256")]),
            setting(&[("sublights", "2")]),
        ];
    }
    vec![
        setting(&[("filter", "none")]),
        setting(&[("max_taps", "16")]),
        setting(&[("filter", "pcf"), ("kernel", "5")]),
        setting(&[("filter", "edsm"), ("kernel", "5")]),
        setting(&[("sublights", "2")]),
        setting(&[("sublights", "3")]),
        setting(&[("sublights", "2"), ("filter", "pcf"), ("kernel", "3")]),
        setting(&[("resolution", "256")]),
        setting(&[("resolution", "512")]),
    ]
}
