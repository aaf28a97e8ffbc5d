#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
pub mod dsm;
#[cfg(feature = "gpu")]
pub mod frame;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod params;
pub mod raster;
pub mod shared;

pub use cpu::CpuDeepShadow;
#[cfg(feature = "gpu")]
pub use frame::DeepShadowFrame;
#[cfg(feature = "gpu")]
pub use gpu::GpuDeepShadow;
pub use shadow_map_core::SoftShadowEstimator;
