//! One method as the rest of the workspace sees it: a [`MethodDescriptor`] holds its registry
//! name, its CPU constructor, its engine path's constructor (in builds with the `gpu` feature:
//! the method's one GPU implementation, also its GPU estimator through
//! [`FrameTwin`](crate::gpu::frame_twin::FrameTwin)) and the settings `softshadow report` sweeps. Each method crate exports its
//! descriptor(s); the umbrella crate's list of descriptors is the one registry the CLI, the
//! report, the engines and the tests read (adding a method is its crate and one line there).
use crate::{Result, SoftShadowEstimator};

/// One report setting: `(key, value)` overrides of a method's defaults.
pub type Setting = Vec<(&'static str, String)>;

/// The settings `softshadow report` runs besides a method's defaults, as data: settings
/// separated by `;`, each `key=value` overrides separated by spaces as `--param` takes them
/// (checked against the method's table when the report runs).
#[derive(Debug, Clone, Copy)]
pub struct Sweep {
    /// The small set CI runs (`report --quick`).
    pub quick: &'static str,
    /// The full report's set.
    pub full: &'static str,
}

impl Sweep {
    /// No settings besides the defaults (a method without a sweep: the reference).
    pub const NONE: Sweep = Sweep {
        quick: "",
        full: "",
    };

    /// The shadow-map resolutions: 256 (quick), or 256, 512 and 2048 (full).
    pub const RESOLUTIONS: Sweep = Sweep {
        quick: "resolution=256",
        full: "resolution=256; resolution=512; resolution=2048",
    };
}

/// A fresh CPU estimator with default parameters.
pub type CpuConstructor = fn() -> Result<Box<dyn SoftShadowEstimator>>;

/// The engine path prepared on a device with the method's own parameters (a table of its own
/// specs, without the cascade keys) for at most `max_receivers` receivers a frame.
#[cfg(feature = "gpu")]
pub type FrameConstructor = fn(
    std::sync::Arc<crate::gpu::GpuContext>,
    &crate::Params,
    u32,
) -> Result<Box<dyn crate::gpu::frame::FrameEstimator>>;

/// What the registry knows of one method (see the module's documentation). Made in a `const`:
/// [`new`](Self::new), then [`with_frame`](Self::with_frame) under the method crate's own `gpu`
/// feature.
#[derive(Clone, Copy)]
pub struct MethodDescriptor {
    name: &'static str,
    cpu: CpuConstructor,
    sweep: Sweep,
    #[cfg(feature = "gpu")]
    frame: Option<FrameConstructor>,
}

impl std::fmt::Debug for MethodDescriptor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MethodDescriptor")
            .field("name", &self.name)
            .field("gpu", &self.has_gpu())
            .field("frame", &self.has_frame())
            .finish()
    }
}

impl MethodDescriptor {
    /// A CPU-only method called `name` (`--algo NAME`) whose report runs `sweep` besides its
    /// defaults.
    pub const fn new(name: &'static str, cpu: CpuConstructor, sweep: Sweep) -> MethodDescriptor {
        MethodDescriptor {
            name,
            cpu,
            sweep,
            #[cfg(feature = "gpu")]
            frame: None,
        }
    }

    /// The same with an engine path.
    #[cfg(feature = "gpu")]
    pub const fn with_frame(mut self, frame: FrameConstructor) -> MethodDescriptor {
        self.frame = Some(frame);
        self
    }

    /// The registry name.
    pub const fn name(&self) -> &'static str {
        self.name
    }

    /// A fresh CPU estimator with default parameters.
    pub fn cpu(&self) -> Result<Box<dyn SoftShadowEstimator>> {
        (self.cpu)()
    }

    /// The settings the report runs besides the defaults (`quick`: CI's small set).
    pub fn sweep(&self, quick: bool) -> Vec<Setting> {
        let set = if quick {
            self.sweep.quick
        } else {
            self.sweep.full
        };
        set.split(';')
            .filter(|line| !line.trim().is_empty())
            .map(parse_setting)
            .collect()
    }

    /// Whether this build has the method on the GPU (its engine path, run as an estimator by
    /// [`FrameTwin`](crate::gpu::frame_twin::FrameTwin)).
    pub const fn has_gpu(&self) -> bool {
        self.has_frame()
    }

    /// Whether this build has the method's engine path.
    pub const fn has_frame(&self) -> bool {
        #[cfg(feature = "gpu")]
        {
            self.frame.is_some()
        }
        #[cfg(not(feature = "gpu"))]
        {
            false
        }
    }

    /// The method's GPU estimator on `ctx`: its engine path as an estimator
    /// ([`FrameTwin`](crate::gpu::frame_twin::FrameTwin)); `None` for a CPU-only method.
    #[cfg(feature = "gpu")]
    pub fn gpu(
        &self,
        ctx: std::sync::Arc<crate::gpu::GpuContext>,
    ) -> Option<Result<Box<dyn SoftShadowEstimator>>> {
        self.frame.map(|f| {
            self.cpu().map(|cpu| {
                Box::new(crate::gpu::frame_twin::FrameTwin::new(ctx, cpu, f))
                    as Box<dyn SoftShadowEstimator>
            })
        })
    }

    /// The engine path on `ctx` with the method's own `params`, for at most `max_receivers`
    /// receivers a frame; `None` for a method without one.
    #[cfg(feature = "gpu")]
    pub fn frame(
        &self,
        ctx: std::sync::Arc<crate::gpu::GpuContext>,
        params: &crate::Params,
        max_receivers: u32,
    ) -> Option<Result<Box<dyn crate::gpu::frame::FrameEstimator>>> {
        self.frame.map(|f| f(ctx, params, max_receivers))
    }
}

/// `(key, value)` pairs as one [`Setting`].
pub fn setting(pairs: &[(&'static str, &str)]) -> Setting {
    pairs.iter().map(|(k, v)| (*k, v.to_string())).collect()
}

/// One setting of a sweep, `key=value` pairs separated by white space, as one [`Setting`]; a word without
/// `=` sets its key to the empty value, which the method's table then refuses by name.
fn parse_setting(line: &'static str) -> Setting {
    line.split_whitespace()
        .map(|kv| {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            (k, v.to_string())
        })
        .collect()
}

/// A method crate's root, the same in every method crate (docs/layout.md): its modules
/// `settings` (typed parameters), `math` (pure, paper-cited), `cpu` (the CPU twin) and, with
/// the crate's `gpu` feature, `gpu` (the frame); the re-exports of its CPU estimator and frame;
/// and its registry entry `DESCRIPTOR`: the name, the CPU estimator's `new`, the frame's
/// constructor `(ctx, params, max_receivers)` and the report's [`Sweep`], given as an
/// expression or as its `quick:` and `full:` strings.
///
/// ```ignore
/// shadow_map_core::method_crate! {
///     /// Shadow accumulation in the registry.
///     "accumulation": CpuAccumulation,
///     AccumulationFrame = |ctx, params, _| AccumulationFrame::prepare(ctx, params),
///     quick: "resolution=256",
///     full: "k=3; k=5",
/// }
/// ```
#[macro_export]
macro_rules! method_crate {
    (
        $(#[$meta:meta])*
        $name:literal: $cpu:ident,
        $frame:ident = $prepare:expr,
        $sweep:expr $(,)?
    ) => {
        $crate::method_crate!(@emit $(#[$meta])* $name: $cpu, $frame = $prepare, $sweep);
    };
    (
        $(#[$meta:meta])*
        $name:literal: $cpu:ident,
        $frame:ident = $prepare:expr,
        quick: $quick:literal,
        full: $full:literal $(,)?
    ) => {
        $crate::method_crate!(
            @emit $(#[$meta])* $name: $cpu, $frame = $prepare,
            $crate::method::Sweep { quick: $quick, full: $full }
        );
    };
    (
        @emit $(#[$meta:meta])* $name:literal: $cpu:ident, $frame:ident = $prepare:expr, $sweep:expr
    ) => {
        pub mod cpu;
        #[cfg(feature = "gpu")]
        pub mod gpu;
        pub mod math;
        pub mod settings;

        pub use cpu::$cpu;
        #[cfg(feature = "gpu")]
        pub use gpu::$frame;
        pub use $crate::SoftShadowEstimator;

        $(#[$meta])*
        pub const DESCRIPTOR: $crate::method::MethodDescriptor = {
            let d = $crate::method::MethodDescriptor::new(
                $name,
                || Ok(Box::new($cpu::new()?)),
                $sweep,
            );
            #[cfg(feature = "gpu")]
            let d = d.with_frame(|ctx, params, n| Ok(Box::new(($prepare)(ctx, params, n)?)));
            d
        };
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn none() -> Result<Box<dyn SoftShadowEstimator>> {
        Err(crate::Error::Receivers("no estimator".into()))
    }

    #[test]
    fn a_sweep_reads_settings_separated_by_semicolons() {
        let sweep = Sweep {
            quick: "resolution=256",
            full: " k=3; filter=pcf kernel=5 ;; flag",
        };
        let d = MethodDescriptor::new("toy", none, sweep);
        assert_eq!(d.sweep(true), vec![vec![("resolution", "256".to_string())]]);
        assert_eq!(
            d.sweep(false),
            vec![
                vec![("k", "3".to_string())],
                vec![("filter", "pcf".to_string()), ("kernel", "5".to_string())],
                vec![("flag", String::new())],
            ]
        );
        assert!(MethodDescriptor::new("toy", none, Sweep::NONE)
            .sweep(false)
            .is_empty());
    }
}
