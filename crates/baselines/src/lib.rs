#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
// `!(a > b)` is deliberate: true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod settings;

pub use cpu::{HardShadow, MultiSample, PcfShadow, PcssShadow};
#[cfg(feature = "gpu")]
pub use gpu::{MapFrame, MultiSampleFrame};
pub use settings::{Hard, Pcf, Pcss};
pub use shadow_map_core::SoftShadowEstimator;

use shadow_map_core::method::{MethodDescriptor, Sweep};

/// Hard shadow mapping in the registry: `hard`.
pub const HARD: MethodDescriptor = map_method::<Hard>();

/// Percentage-closer filtering in the registry: `pcf`.
pub const PCF: MethodDescriptor = map_method::<Pcf>();

/// Percentage-closer soft shadows in the registry: `pcss`.
pub const PCSS: MethodDescriptor = map_method::<Pcss>();

/// Hard shadow maps from points on the light, averaged, in the registry: `multi-sample`.
pub const MULTI_SAMPLE: MethodDescriptor = {
    let d = MethodDescriptor::new(
        settings::MULTI_SAMPLE_NAME,
        || Ok(Box::new(MultiSample::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, n| Ok(Box::new(MultiSampleFrame::prepare(ctx, params, n)?)));
    d
};

#[cfg(not(feature = "gpu"))]
use cpu::Filter as MapFilter;
/// What a single-map filter must be to enter the registry: a CPU [`cpu::Filter`], and with the
/// `gpu` feature a [`gpu::GpuFilter`] too.
#[cfg(feature = "gpu")]
use gpu::GpuFilter as MapFilter;

/// The descriptor of the single-map baseline `F` (hard, PCF or PCSS): its name, its CPU twin
/// ([`cpu::MapEstimator`]), its frame ([`MapFrame`], feature `gpu`) and the resolution sweep.
const fn map_method<F: MapFilter + 'static>() -> MethodDescriptor {
    let d = MethodDescriptor::new(
        F::NAME,
        || Ok(Box::new(cpu::MapEstimator::<F>::new()?)),
        Sweep::RESOLUTIONS,
    );
    #[cfg(feature = "gpu")]
    let d = d.with_frame(|ctx, params, _| Ok(Box::new(MapFrame::<F>::prepare(ctx, params)?)));
    d
}
