//! # softshadow
//!
//! The umbrella crate: re-exports the member crates and keeps the registry of every estimator,
//! by name, as `softshadow render --algo NAME` and `softshadow algos` see them.
//!
//! | crate | job |
//! |---|---|
//! | [`core`] (`shadow-map-core`) | scene model, receivers, light view, rasteriser, peeling, midpoints, MSSM, the [`SoftShadowEstimator`] trait |
//! | [`reference`](mod@reference) | ray-traced ground truth and closed-form oracles |
//! | [`baselines`] | hard, PCF, PCSS, multi-sample, with wgpu twins (feature `gpu`) |
//! | [`backprojection`] | micropatch backprojection with depth-peeled layers and midpoints, with a wgpu twin |
//! | [`accumulation`] | shadow accumulation over a KxK kernel of elementary casters (additive and exact occlusion bits), with a wgpu twin |
//! | [`packet_hsm`] | packet-based hierarchical soft shadow mapping (contour backprojection over the dual-grid MSSM, packets, sub-lights), with a wgpu twin |
//! | [`deep_shadow`] | deep shadow maps (per-texel lists, PCF and exponential filtering, sub-lights), with a wgpu twin |
pub use accumulation;
pub use backprojection;
pub use baselines;
pub use deep_shadow;
pub use packet_hsm;
pub use reference;
pub use shadow_map_core as core;
pub use shadow_map_core::{Backend, Error, Result, SoftShadowEstimator};

/// Names of every registered estimator, in listing order.
pub const ALGOS: &[&str] = &[
    "reference",
    "hard",
    "pcf",
    "pcss",
    "multi-sample",
    "backprojection",
    "accumulation",
    "packet-hsm",
    "deep-shadow",
];

/// A fresh estimator by registry name and backend, with default parameters. The GPU backend uses
/// the process-wide [`core::gpu::GpuContext::shared`] device (Vulkan only).
pub fn estimator(name: &str, backend: Backend) -> Result<Box<dyn SoftShadowEstimator>> {
    if !ALGOS.contains(&name) {
        return Err(Error::param(
            "algo",
            format!("unknown estimator {name:?} (known: {})", ALGOS.join(", ")),
        ));
    }
    match backend {
        Backend::Cpu => Ok(match name {
            "reference" => Box::new(reference::ReferenceEstimator::new()?),
            "hard" => Box::new(baselines::HardShadow::new()?),
            "pcf" => Box::new(baselines::PcfShadow::new()?),
            "pcss" => Box::new(baselines::PcssShadow::new()?),
            "backprojection" => Box::new(backprojection::CpuBackprojection::new()?),
            "accumulation" => Box::new(accumulation::CpuAccumulation::new()?),
            "packet-hsm" => Box::new(packet_hsm::CpuPacketHsm::new()?),
            "deep-shadow" => Box::new(deep_shadow::CpuDeepShadow::new()?),
            _ => Box::new(baselines::MultiSample::new()?),
        }),
        Backend::Gpu => gpu_estimator(name),
    }
}

#[cfg(feature = "gpu")]
fn gpu_estimator(name: &str) -> Result<Box<dyn SoftShadowEstimator>> {
    use baselines::gpu::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow};
    if name == "reference" {
        return Err(Error::param(
            "backend",
            "the ray-traced reference runs on the CPU only; use --backend cpu",
        ));
    }
    let ctx = core::gpu::GpuContext::shared()?;
    Ok(match name {
        "hard" => Box::new(GpuHardShadow::new(ctx)?),
        "pcf" => Box::new(GpuPcfShadow::new(ctx)?),
        "pcss" => Box::new(GpuPcssShadow::new(ctx)?),
        "backprojection" => Box::new(backprojection::GpuBackprojection::new(ctx)?),
        "accumulation" => Box::new(accumulation::GpuAccumulation::new(ctx)?),
        "packet-hsm" => Box::new(packet_hsm::GpuPacketHsm::new(ctx)?),
        "deep-shadow" => Box::new(deep_shadow::GpuDeepShadow::new(ctx)?),
        _ => Box::new(GpuMultiSample::new(ctx)?),
    })
}

#[cfg(not(feature = "gpu"))]
fn gpu_estimator(name: &str) -> Result<Box<dyn SoftShadowEstimator>> {
    Err(Error::param(
        "backend",
        format!("`{name}`: this build has no GPU backend (cargo feature `gpu` is off)"),
    ))
}

/// The backends each registered estimator has.
pub fn backends(name: &str) -> &'static [&'static str] {
    match name {
        "reference" => &["cpu"],
        _ if cfg!(feature = "gpu") => &["cpu", "gpu"],
        _ => &["cpu"],
    }
}

/// Every registered CPU estimator with default parameters.
pub fn registry() -> Result<Vec<Box<dyn SoftShadowEstimator>>> {
    ALGOS.iter().map(|n| estimator(n, Backend::Cpu)).collect()
}
