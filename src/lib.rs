//! # softshadow
//!
//! The umbrella crate: re-exports the member crates and keeps the registry of every estimator,
//! by name, as `softshadow render --algo NAME` and `softshadow algos` see them.
//!
//! | crate | job |
//! |---|---|
//! | [`core`] (`shadow-map-core`) | scene model, receivers, light view, rasteriser, peeling, midpoints, MSSM, the [`SoftShadowEstimator`] trait |
//! | [`reference`] | ray-traced ground truth and closed-form oracles |
//! | [`baselines`] | hard, PCF, PCSS, multi-sample |
pub use baselines;
pub use reference;
pub use shadow_map_core as core;
pub use shadow_map_core::{Backend, Error, Result, SoftShadowEstimator};

/// Names of every registered estimator, in listing order.
pub const ALGOS: &[&str] = &["reference", "hard", "pcf", "pcss", "multi-sample"];

/// A fresh estimator by registry name and backend, with default parameters.
pub fn estimator(name: &str, backend: Backend) -> Result<Box<dyn SoftShadowEstimator>> {
    if backend == Backend::Gpu {
        return Err(Error::param(
            "backend",
            format!("`{name}` has no gpu backend yet (the wgpu backends arrive with the GPU foundation); use --backend cpu"),
        ));
    }
    Ok(match name {
        "reference" => Box::new(reference::ReferenceEstimator::new()?),
        "hard" => Box::new(baselines::HardShadow::new()?),
        "pcf" => Box::new(baselines::PcfShadow::new()?),
        "pcss" => Box::new(baselines::PcssShadow::new()?),
        "multi-sample" => Box::new(baselines::MultiSample::new()?),
        other => {
            return Err(Error::param(
                "algo",
                format!("unknown estimator {other:?} (known: {})", ALGOS.join(", ")),
            ))
        }
    })
}

/// Every registered CPU estimator with default parameters.
pub fn registry() -> Result<Vec<Box<dyn SoftShadowEstimator>>> {
    ALGOS.iter().map(|n| estimator(n, Backend::Cpu)).collect()
}
