#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod common;
pub mod hard;
pub mod map_estimator;
pub mod multi_sample;
pub mod pcf;
pub mod pcss;

#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "gpu")]
pub use gpu::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow};

pub use hard::HardShadow;
pub use multi_sample::MultiSample;
pub use pcf::PcfShadow;
pub use pcss::PcssShadow;
pub use shadow_map_core::SoftShadowEstimator;
