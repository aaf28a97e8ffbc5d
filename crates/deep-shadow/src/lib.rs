#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The modules (settings, math, cpu, gpu), the re-exports and `DESCRIPTOR`: see
// `shadow_map_core::method_crate!`.
shadow_map_core::method_crate! {
    /// Deep shadow maps in the registry: `deep-shadow`, its CPU twin and engine path (which is also
    /// its GPU estimator, the core's `FrameTwin`).
    "deep-shadow": CpuDeepShadow,
    DeepShadowFrame = DeepShadowFrame::prepare,
    // The report's settings: the filters (none, PCF, EDSM; Fuerst's lookups), the tap cap,
    // sub-lights and the resolution.
    quick: "resolution=256; sublights=2",
    full: "filter=none; max_taps=16; filter=pcf kernel=5; filter=edsm kernel=5; sublights=2; sublights=3; sublights=2 filter=pcf kernel=3; resolution=256; resolution=512",
}
