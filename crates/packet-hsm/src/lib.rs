#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod contour;
pub mod cpu;
pub mod fit;
#[cfg(feature = "gpu")]
pub mod frame;
#[cfg(feature = "gpu")]
pub mod gpu;

pub use cpu::CpuPacketHsm;
#[cfg(feature = "gpu")]
pub use frame::PacketHsmFrame;
#[cfg(feature = "gpu")]
pub use gpu::GpuPacketHsm;
pub use shadow_map_core::SoftShadowEstimator;
