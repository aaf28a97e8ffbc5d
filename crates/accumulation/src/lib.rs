#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The modules (settings, math, cpu, gpu), the re-exports and `DESCRIPTOR`: see
// `shadow_map_core::method_crate!`.
shadow_map_core::method_crate! {
    /// Shadow accumulation in the registry: `accumulation`, its CPU twin and its engine path (also its
    /// GPU estimator, run by the core's `FrameTwin`).
    "accumulation": CpuAccumulation,
    AccumulationFrame = |ctx, params, _| AccumulationFrame::prepare(ctx, params),
    // The report's settings: the kernel size K (Aszodi section 3), the exact variant, a fixed
    // kernel, and the resolution.
    quick: "resolution=256; variant=exact",
    full: "k=3; k=5; k=15; variant=exact; kernel=fixed; resolution=256; resolution=2048",
}
