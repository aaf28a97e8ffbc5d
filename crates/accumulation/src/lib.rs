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
pub use gpu::{AccumulationFrame, GpuAccumulation};
pub use shadow_map_core::SoftShadowEstimator;
