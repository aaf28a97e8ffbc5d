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

pub use hard::HardShadow;
pub use multi_sample::MultiSample;
pub use pcf::PcfShadow;
pub use pcss::PcssShadow;
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Hard shadow mapping in the registry: `hard`.
pub const HARD: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "hard",
        || Ok(Box::new(HardShadow::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| {
        Ok(Box::new(gpu::MapFrame::<hard::Hard>::prepare(ctx, params)?))
    });
    d
};

/// Percentage-closer filtering in the registry: `pcf`.
pub const PCF: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "pcf",
        || Ok(Box::new(PcfShadow::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| {
        Ok(Box::new(gpu::MapFrame::<pcf::Pcf>::prepare(ctx, params)?))
    });
    d
};

/// Percentage-closer soft shadows in the registry: `pcss`.
pub const PCSS: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "pcss",
        || Ok(Box::new(PcssShadow::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| {
        Ok(Box::new(gpu::MapFrame::<pcss::Pcss>::prepare(ctx, params)?))
    });
    d
};

/// Hard shadow maps from points on the light, averaged, in the registry: `multi-sample`.
pub const MULTI_SAMPLE: MethodDescriptor = {
    let d = MethodDescriptor::new(
        "multi-sample",
        || Ok(Box::new(MultiSample::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d
        .with_frame(|ctx, params, n| Ok(Box::new(gpu::MultiSampleFrame::prepare(ctx, params, n)?)));
    d
};
