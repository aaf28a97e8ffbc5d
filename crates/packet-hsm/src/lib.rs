#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The modules (settings, math, cpu, gpu), the re-exports and `DESCRIPTOR`: see
// `shadow_map_core::method_crate!`.
shadow_map_core::method_crate! {
    /// Packet-based hierarchical soft shadow mapping in the registry: `packet-hsm`, its CPU twin
    /// and its engine path (also its GPU estimator, through the core's frame twin).
    "packet-hsm": CpuPacketHsm,
    PacketHsmFrame = PacketHsmFrame::prepare,
    // The report's settings: sub-lights (Yang section 5), packet sizes (Algorithm 2) and the
    // resolution; hierarchy and coherence change only the time, so the report runs their defaults.
    quick: "resolution=256; sublights=2",
    full: "sublights=2; sublights=4; packet=1x1; packet=4x4; resolution=256; resolution=512",
}
