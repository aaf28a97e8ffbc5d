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

pub use shadow_map_core::method::{MethodDescriptor, Setting};

/// Calls the macro `$callback` with every registered method in listing order, as
/// `$(#[doc] ...)* Variant = DESCRIPTOR, frame = bool;` (`frame`: whether the method has an
/// engine path on the GPU), so that typed lists elsewhere are generated from this one list: the
/// registry [`METHODS`] here, Bevy's `Method` enum in `bevy-softshadow`. Adding a method is one
/// entry here, with its crate's descriptor.
#[macro_export]
macro_rules! for_each_method {
    ($callback:ident) => {
        $callback! {
            /// The ray-traced ground truth (`reference`; CPU only).
            Reference = $crate::reference::DESCRIPTOR, frame = false;
            /// A hard shadow map, one tap (`hard`).
            Hard = $crate::baselines::HARD, frame = true;
            /// Percentage-closer filtering with a fixed kernel (`pcf`).
            Pcf = $crate::baselines::PCF, frame = true;
            /// Percentage-closer soft shadows (`pcss`): blocker search, then a filter of the
            /// width the light's size and the blockers' depth give.
            Pcss = $crate::baselines::PCSS, frame = true;
            /// Many hard shadow maps from points on the light, averaged (`multi-sample`).
            MultiSample = $crate::baselines::MULTI_SAMPLE, frame = true;
            /// Backprojection of shadow-map micropatches onto the light (Bavoil 2008;
            /// `backprojection`).
            Backprojection = $crate::backprojection::DESCRIPTOR, frame = true;
            /// Shadow accumulation (Aszodi 2006; `accumulation`).
            Accumulation = $crate::accumulation::DESCRIPTOR, frame = true;
            /// Packet-based hierarchical shadow maps with MSSM (Yang 2009; `packet-hsm`).
            PacketHsm = $crate::packet_hsm::DESCRIPTOR, frame = true;
            /// Deep shadow maps with per-texel lists (Fuerst; `deep-shadow`).
            DeepShadow = $crate::deep_shadow::DESCRIPTOR, frame = true;
        }
    };
}

/// [`METHODS`] from [`for_each_method!`]'s list.
macro_rules! registry {
    ($($(#[$doc:meta])* $variant:ident = $descriptor:path, frame = $frame:literal;)*) => {
        /// Every registered method, in listing order: the one registry ([`for_each_method!`]'s
        /// list). [`ALGOS`], [`FRAME_ALGOS`], the CLI, the report's sweeps and the engines'
        /// constructors all come from it.
        pub const METHODS: &[MethodDescriptor] = &[$($descriptor),*];
    };
}
for_each_method!(registry);

/// Names of every registered estimator, in listing order.
pub const ALGOS: &[&str] = &names::<{ METHODS.len() }>(false);

/// The estimators with an engine path in this build ([`frame_estimator`]), in listing order.
pub const FRAME_ALGOS: &[&str] = &names::<{ frame_count() }>(true);

/// How many methods have an engine path in this build.
const fn frame_count() -> usize {
    let (mut i, mut n) = (0, 0);
    while i < METHODS.len() {
        if METHODS[i].has_frame() {
            n += 1;
        }
        i += 1;
    }
    n
}

/// The names of [`METHODS`] (only those with an engine path when `frames_only`), in order.
const fn names<const N: usize>(frames_only: bool) -> [&'static str; N] {
    let mut out = [""; N];
    let (mut i, mut k) = (0, 0);
    while i < METHODS.len() {
        if !frames_only || METHODS[i].has_frame() {
            out[k] = METHODS[i].name();
            k += 1;
        }
        i += 1;
    }
    out
}

/// The registered method called `name`, or a one-line error listing the known names.
pub fn method(name: &str) -> Result<&'static MethodDescriptor> {
    METHODS.iter().find(|m| m.name() == name).ok_or_else(|| {
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
        Backend::Cpu => m.cpu()?,
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
fn gpu_estimator(m: &MethodDescriptor) -> Result<Box<dyn SoftShadowEstimator>> {
    let cpu_only = || {
        Error::param(
            "backend",
            format!(
                "`{}` runs on the CPU only (the ray-traced reference); use --backend cpu",
                m.name()
            ),
        )
    };
    // Checked before the device is made: a CPU-only method needs none.
    if !m.has_gpu() {
        return Err(cpu_only());
    }
    m.gpu(core::gpu::GpuContext::shared()?)
        .unwrap_or_else(|| Err(cpu_only()))
}

#[cfg(not(feature = "gpu"))]
fn gpu_estimator(m: &MethodDescriptor) -> Result<Box<dyn SoftShadowEstimator>> {
    Err(Error::param(
        "backend",
        format!(
            "`{}`: this build has no GPU backend (cargo feature `gpu` is off)",
            m.name()
        ),
    ))
}

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
    method(name)?.frame(ctx, params, max_receivers).transpose()
}

/// The parameter table of `name`'s own estimator (without the cascade keys) holding every value
/// of `params` it declares: what [`frame_estimator`] takes from an [`estimator`]'s table.
pub fn own_params(name: &str, params: &core::Params) -> Result<core::Params> {
    let own = method(name)?.cpu()?;
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
        Ok(m) if m.has_gpu() => &["cpu", "gpu"],
        Ok(_) => &["cpu"],
        Err(_) => &[],
    }
}

/// Every registered CPU estimator with default parameters.
pub fn registry() -> Result<Vec<Box<dyn SoftShadowEstimator>>> {
    METHODS.iter().map(|m| with_cascades(m.cpu()?)).collect()
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

    /// The lists derived from the registry: every name once, the engine paths a subset in the
    /// same order, and (in a GPU build) every method but the reference with both GPU paths.
    #[test]
    fn the_derived_lists_follow_the_registry() {
        let names: Vec<&str> = METHODS.iter().map(|m| m.name()).collect();
        assert_eq!(names, ALGOS);
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "a name registered twice");
        let frames: Vec<&str> = METHODS
            .iter()
            .filter(|m| m.has_frame())
            .map(|m| m.name())
            .collect();
        assert_eq!(frames, FRAME_ALGOS);
        #[cfg(feature = "gpu")]
        {
            assert_eq!(FRAME_ALGOS.len(), ALGOS.len() - 1);
            for m in METHODS.iter().filter(|m| m.name() != "reference") {
                assert!(m.has_gpu() && m.has_frame(), "{}", m.name());
            }
            // for_each_method!'s `frame` flags say which have an engine path.
            macro_rules! frame_flags {
                ($($(#[$doc:meta])* $v:ident = $d:path, frame = $f:literal;)*) => {
                    [$(($d.name(), $f)),*]
                };
            }
            for (name, frame) in crate::for_each_method!(frame_flags) {
                assert_eq!(frame, FRAME_ALGOS.contains(&name), "{name}");
            }
        }
    }

    #[test]
    fn every_method_makes_its_own_cpu_twin() {
        for m in METHODS {
            let e = m.cpu().expect("defaults parse");
            assert_eq!(e.name(), m.name());
            assert_eq!(e.backend(), Backend::Cpu);
        }
    }
}
