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

/// A GPU twin's constructor: the estimator on a given device.
#[cfg(feature = "gpu")]
pub type GpuConstructor =
    fn(std::sync::Arc<core::gpu::GpuContext>) -> Result<Box<dyn SoftShadowEstimator>>;

/// One registered method: its name, its CPU twin and, in builds with the `gpu` feature, its GPU
/// twin (`None` for the CPU-only reference).
pub struct Method {
    /// Registry name (`--algo NAME`).
    pub name: &'static str,
    /// A fresh CPU estimator with default parameters.
    pub cpu: fn() -> Result<Box<dyn SoftShadowEstimator>>,
    /// A fresh GPU estimator on a device, with default parameters.
    #[cfg(feature = "gpu")]
    pub gpu: Option<GpuConstructor>,
}

/// The one list of methods: [`METHODS`] and [`ALGOS`] are both made from it, so a method is
/// added in one place.
macro_rules! methods {
    ($($name:literal => $cpu:path $(, gpu $gpu:path)?;)*) => {
        /// Every registered method, in listing order.
        pub const METHODS: &[Method] = &[$(Method {
            name: $name,
            cpu: || Ok(Box::new(<$cpu>::new()?)),
            #[cfg(feature = "gpu")]
            gpu: methods!(@gpu $($gpu)?),
        }),*];
        /// Names of every registered estimator, in listing order.
        pub const ALGOS: &[&str] = &[$($name),*];
    };
    (@gpu $gpu:path) => { Some(|ctx| Ok(Box::new(<$gpu>::new(ctx)?))) };
    (@gpu) => { None };
}

methods! {
    "reference" => reference::ReferenceEstimator;
    "hard" => baselines::HardShadow, gpu baselines::gpu::GpuHardShadow;
    "pcf" => baselines::PcfShadow, gpu baselines::gpu::GpuPcfShadow;
    "pcss" => baselines::PcssShadow, gpu baselines::gpu::GpuPcssShadow;
    "multi-sample" => baselines::MultiSample, gpu baselines::gpu::GpuMultiSample;
    "backprojection" => backprojection::CpuBackprojection, gpu backprojection::GpuBackprojection;
    "accumulation" => accumulation::CpuAccumulation, gpu accumulation::GpuAccumulation;
    "packet-hsm" => packet_hsm::CpuPacketHsm, gpu packet_hsm::GpuPacketHsm;
    "deep-shadow" => deep_shadow::CpuDeepShadow, gpu deep_shadow::GpuDeepShadow;
}

/// The registered method called `name`, or a one-line error listing the known names.
pub fn method(name: &str) -> Result<&'static Method> {
    METHODS.iter().find(|m| m.name == name).ok_or_else(|| {
        Error::param(
            "algo",
            format!("unknown estimator {name:?} (known: {})", ALGOS.join(", ")),
        )
    })
}

/// A fresh estimator by registry name and backend, with default parameters. The GPU backend uses
/// the process-wide [`core::gpu::GpuContext::shared`] device (Vulkan only).
///
/// Every estimator with a shadow map (a `resolution` parameter) comes wrapped in
/// [`core::cascades::Cascaded`], which adds the `cascades`, `cascade_lambda` and `cascade_blend`
/// parameters (one view set per camera-depth slice; at the default `cascades=0`, one slice unless
/// the receivers span a camera-depth ratio above 8 and one view's texel density p95 exceeds 2
/// pixels per texel) and `tiles`, `tile_span` (views by direction from the light centre per
/// slice, [`core::cascades::direction_tiles`]; at the default `tiles=0`, one view unless the
/// receivers span more than `tile_span` in tan space and one view's texel density p95 exceeds 2).
pub fn estimator(name: &str, backend: Backend) -> Result<Box<dyn SoftShadowEstimator>> {
    let m = method(name)?;
    with_cascades(match backend {
        Backend::Cpu => (m.cpu)()?,
        Backend::Gpu => gpu_estimator(m)?,
    })
}

/// `e` wrapped in [`core::cascades::Cascaded`] when it has a shadow map, else `e`.
fn with_cascades(e: Box<dyn SoftShadowEstimator>) -> Result<Box<dyn SoftShadowEstimator>> {
    if e.params().get(core::light_view::RESOLUTION.key).is_none() {
        return Ok(e);
    }
    Ok(Box::new(core::cascades::Cascaded::new(e)?))
}

#[cfg(feature = "gpu")]
fn gpu_estimator(m: &Method) -> Result<Box<dyn SoftShadowEstimator>> {
    let Some(gpu) = m.gpu else {
        return Err(Error::param(
            "backend",
            format!(
                "`{}` runs on the CPU only (the ray-traced reference); use --backend cpu",
                m.name
            ),
        ));
    };
    gpu(core::gpu::GpuContext::shared()?)
}

#[cfg(not(feature = "gpu"))]
fn gpu_estimator(m: &Method) -> Result<Box<dyn SoftShadowEstimator>> {
    Err(Error::param(
        "backend",
        format!(
            "`{}`: this build has no GPU backend (cargo feature `gpu` is off)",
            m.name
        ),
    ))
}

/// The estimators with an engine path ([`frame_estimator`]), in listing order.
pub const FRAME_ALGOS: &[&str] = &[
    "hard",
    "pcf",
    "pcss",
    "multi-sample",
    "backprojection",
    "accumulation",
    "deep-shadow",
    "packet-hsm",
];

/// The engine path of the estimator `name` on `ctx` ([`core::gpu::frame::FrameEstimator`]),
/// prepared with the parameters `params` (a table of the method's own specs, without the cascade
/// keys), for at most `max_receivers` receivers a frame; `None` for a method that has none yet
/// (not in [`FRAME_ALGOS`]). Errors: an unknown name, the parameters' own, device limits.
#[cfg(feature = "gpu")]
pub fn frame_estimator(
    name: &str,
    ctx: std::sync::Arc<core::gpu::GpuContext>,
    params: &core::Params,
    max_receivers: u32,
) -> Result<Option<Box<dyn core::gpu::frame::FrameEstimator>>> {
    use baselines::gpu::{MapFrame, MultiSampleFrame};
    method(name)?;
    Ok(Some(match name {
        "hard" => Box::new(MapFrame::<baselines::hard::Hard>::prepare(ctx, params)?),
        "pcf" => Box::new(MapFrame::<baselines::pcf::Pcf>::prepare(ctx, params)?),
        "pcss" => Box::new(MapFrame::<baselines::pcss::Pcss>::prepare(ctx, params)?),
        "multi-sample" => Box::new(MultiSampleFrame::prepare(ctx, params, max_receivers)?),
        "backprojection" => Box::new(backprojection::BackprojectionFrame::prepare(ctx, params)?),
        "accumulation" => Box::new(accumulation::AccumulationFrame::prepare(ctx, params)?),
        "deep-shadow" => Box::new(deep_shadow::DeepShadowFrame::prepare(
            ctx,
            params,
            max_receivers,
        )?),
        "packet-hsm" => Box::new(packet_hsm::PacketHsmFrame::prepare(
            ctx,
            params,
            max_receivers,
        )?),
        _ => return Ok(None),
    }))
}

/// The parameter table of `name`'s own estimator (without the cascade keys) holding every value
/// of `params` it declares: what [`frame_estimator`] takes from an [`estimator`]'s table.
pub fn own_params(name: &str, params: &core::Params) -> Result<core::Params> {
    let own = (method(name)?.cpu)()?;
    let mut p = own.params().clone();
    for s in p.clone().specs() {
        if let Some(v) = params.get(s.key) {
            p.set(s.key, &v.to_string())?;
        }
    }
    Ok(p)
}

/// The backends each registered estimator has (none for an unknown name).
pub fn backends(name: &str) -> &'static [&'static str] {
    match method(name) {
        #[cfg(feature = "gpu")]
        Ok(m) if m.gpu.is_some() => &["cpu", "gpu"],
        Ok(_) => &["cpu"],
        Err(_) => &[],
    }
}

/// Every registered CPU estimator with default parameters.
pub fn registry() -> Result<Vec<Box<dyn SoftShadowEstimator>>> {
    METHODS.iter().map(|m| with_cascades((m.cpu)()?)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_names_are_errors_not_a_fallback() {
        for backend in [Backend::Cpu, Backend::Gpu] {
            let Err(e) = estimator("multi-samples", backend) else {
                panic!("an unknown name made an estimator");
            };
            assert!(e.to_string().contains("unknown estimator"), "{e}");
        }
        assert!(backends("nope").is_empty());
    }

    #[test]
    fn every_method_makes_its_own_cpu_twin() {
        for m in METHODS {
            let e = (m.cpu)().expect("defaults parse");
            assert_eq!(e.name(), m.name);
            assert_eq!(e.backend(), Backend::Cpu);
        }
    }
}
