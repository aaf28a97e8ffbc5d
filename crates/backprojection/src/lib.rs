#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The modules (settings, math, cpu, gpu), the re-exports and `DESCRIPTOR`: see
// `shadow_map_core::method_crate!`.
shadow_map_core::method_crate! {
    /// Backprojection in the registry: `backprojection`, its CPU twin and its engine path, which
    /// is also its GPU estimator (the core's `FrameTwin`).
    "backprojection": CpuBackprojection,
    BackprojectionFrame = |ctx, params, _| BackprojectionFrame::prepare(ctx, params),
    // The report's settings: layers (Bavoil section 3), gap filling, occlusion, self-shadowing,
    // the kernel's sample cap, and the resolution.
    quick: "resolution=256; layers=1",
    full: "resolution=256; resolution=512; resolution=2048; layers=1; layers=2; gap_filling=false; occlusion=additive; self_shadow=bias; max_nspp=25; max_nspp=49",
}
