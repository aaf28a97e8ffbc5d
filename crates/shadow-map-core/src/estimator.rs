//! The one trait every soft-shadow estimator implements, CPU and GPU backends alike.
use crate::{cancel::Cancel, params::Params, receivers::Receivers, scene::Scene, Result};
use std::time::Instant;

/// Where an estimator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// On the CPU (rayon).
    Cpu,
    /// Through wgpu.
    Gpu,
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
        })
    }
}

/// Something an estimator could not model and approximated instead, with how many receivers
/// (or meshes) it touched: V there is not what the method would give on a scene it models.
/// Collected in [`Report::warnings`] (one entry per kind, counts merged) and printed by the CLI on
/// every run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Warning {
    /// Receivers whose V came out NaN or infinite and was written as 0 (fully shadowed).
    NonFiniteV {
        /// Receivers replaced.
        receivers: usize,
    },
    /// Lit receivers outside every light view, given their facing fraction (lit, as if nothing
    /// stood between them and the light).
    OutsideViews {
        /// Receivers outside.
        receivers: usize,
    },
    /// Semi-transparent meshes (opacity below 1) cast shadows as if opaque: V too low behind them.
    OpaqueCasters {
        /// Meshes of opacity below 1.
        meshes: usize,
    },
    /// The scene needs more opacity levels than the estimator's cap allows, so every mesh was
    /// treated as opaque (packet-hsm's `opacity_levels`): V too low behind semi-transparent meshes.
    OpacityLevelsCapped {
        /// Levels the scene needs.
        needed: usize,
        /// Levels the setting allows.
        allowed: usize,
    },
    /// A sphere light's kernel reaches beyond the light view's window and was clipped at its
    /// edge: casters beyond it are missed, V too high.
    KernelClipped {
        /// Receivers whose kernel was clipped.
        receivers: usize,
    },
    /// Receivers the engine path left NaN (cut by the device's loop budget): no V, which a
    /// composite draws as fully lit.
    FrameLeftNan {
        /// Receivers left NaN.
        receivers: usize,
    },
}

impl Warning {
    /// A short snake-case name of the warning's kind (`frame_left_nan`, ...), for tables.
    pub fn kind(&self) -> &'static str {
        match self {
            Warning::NonFiniteV { .. } => "non_finite_v",
            Warning::OutsideViews { .. } => "outside_views",
            Warning::OpaqueCasters { .. } => "opaque_casters",
            Warning::OpacityLevelsCapped { .. } => "opacity_levels_capped",
            Warning::KernelClipped { .. } => "kernel_clipped",
            Warning::FrameLeftNan { .. } => "frame_left_nan",
        }
    }

    /// The number this warning counts (receivers, meshes or levels needed).
    pub fn count(&self) -> usize {
        match *self {
            Warning::NonFiniteV { receivers }
            | Warning::OutsideViews { receivers }
            | Warning::KernelClipped { receivers }
            | Warning::FrameLeftNan { receivers } => receivers,
            Warning::OpaqueCasters { meshes } => meshes,
            Warning::OpacityLevelsCapped { needed, .. } => needed,
        }
    }

    /// The opaque-casters warning for `scene` (`None` when every mesh is opaque), for an
    /// estimator that treats every caster as opaque.
    pub fn opaque_casters(scene: &Scene) -> Option<Warning> {
        let meshes = scene.semi_transparent_meshes();
        (meshes > 0).then_some(Warning::OpaqueCasters { meshes })
    }

    /// The same warning with `other`'s count added (`None` when they are of different kinds).
    fn merged(self, other: Warning) -> Option<Warning> {
        use Warning::*;
        Some(match (self, other) {
            (NonFiniteV { receivers: a }, NonFiniteV { receivers: b }) => {
                NonFiniteV { receivers: a + b }
            }
            (OutsideViews { receivers: a }, OutsideViews { receivers: b }) => {
                OutsideViews { receivers: a + b }
            }
            (KernelClipped { receivers: a }, KernelClipped { receivers: b }) => {
                KernelClipped { receivers: a + b }
            }
            (FrameLeftNan { receivers: a }, FrameLeftNan { receivers: b }) => {
                FrameLeftNan { receivers: a + b }
            }
            // Per scene, not per receiver: the same meshes, counted once.
            (OpaqueCasters { meshes: a }, OpaqueCasters { meshes: b }) => {
                OpaqueCasters { meshes: a.max(b) }
            }
            (OpacityLevelsCapped { needed: a, allowed }, OpacityLevelsCapped { needed: b, .. }) => {
                OpacityLevelsCapped {
                    needed: a.max(b),
                    allowed,
                }
            }
            _ => return None,
        })
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Warning::NonFiniteV { receivers } => write!(
                f,
                "{receivers} receivers had a non-finite V, written as 0 (fully shadowed)"
            ),
            Warning::OutsideViews { receivers } => write!(
                f,
                "{receivers} receivers lie outside every light view and were given their facing fraction (lit, casters ignored)"
            ),
            Warning::OpaqueCasters { meshes } => write!(
                f,
                "{meshes} semi-transparent meshes were treated as opaque (V too low behind them; backprojection, packet-hsm and deep-shadow model opacity)"
            ),
            Warning::OpacityLevelsCapped { needed, allowed } => write!(
                f,
                "the scene needs {needed} opacity levels, opacity_levels={allowed} allows fewer: every mesh treated as opaque (V too low behind semi-transparent meshes)"
            ),
            Warning::KernelClipped { receivers } => write!(
                f,
                "{receivers} receivers had their sphere-light kernel clipped at the light view's edge (casters beyond missed, V too high)"
            ),
            Warning::FrameLeftNan { receivers } => write!(
                f,
                "{receivers} receivers were left NaN by the engine path's loop budget (no V; drawn as fully lit unless redone)"
            ),
        }
    }
}

/// What the last `build` + `estimate` did: stage times, light-space memory, notes (which path
/// was taken, ...; printed by `--stats`) and warnings (what it could not model; printed always).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Report {
    /// `(stage, milliseconds)` in execution order.
    pub stages: Vec<(String, f64)>,
    /// Bytes of light-space data held at the peak.
    pub light_space_bytes: usize,
    /// `(key, value)` diagnostics.
    pub notes: Vec<(String, String)>,
    /// What the estimator approximated, one entry per kind ([`warn`](Self::warn) merges counts).
    pub warnings: Vec<Warning>,
}

impl Report {
    /// Times `f` as stage `name`.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.stages
            .push((name.to_string(), t.elapsed().as_secs_f64() * 1e3));
        out
    }
    /// Adds a note.
    pub fn note(&mut self, key: &str, value: impl ToString) {
        self.notes.push((key.to_string(), value.to_string()));
    }
    /// Adds `n` to the count noted under `key` (a new note when there is none, or when the
    /// note there is not a count).
    pub fn add_count(&mut self, key: &str, n: usize) {
        match self.notes.iter_mut().find(|(k, _)| k == key) {
            Some((_, v)) if v.parse::<usize>().is_ok() => {
                *v = (v.parse::<usize>().unwrap_or(0) + n).to_string();
            }
            _ => self.note(key, n),
        }
    }
    /// Adds a warning, merged into one of the same kind when there is one; a zero count adds
    /// nothing.
    pub fn warn(&mut self, w: Warning) {
        if w.count() == 0 {
            return;
        }
        for x in &mut self.warnings {
            if let Some(m) = x.merged(w) {
                *x = m;
                return;
            }
        }
        self.warnings.push(w);
    }
    /// Adds every warning of `ws` ([`warn`](Self::warn)).
    pub fn warn_all(&mut self, ws: impl IntoIterator<Item = Warning>) {
        for w in ws {
            self.warn(w);
        }
    }
    /// The warning of the same kind as `like` (its count ignored), when there is one.
    pub fn warning(&self, like: Warning) -> Option<Warning> {
        self.warnings
            .iter()
            .copied()
            .find(|w| std::mem::discriminant(w) == std::mem::discriminant(&like))
    }
    /// Total milliseconds of the stages whose name starts with `prefix`.
    pub fn total_ms(&self, prefix: &str) -> f64 {
        self.stages
            .iter()
            .filter(|s| s.0.starts_with(prefix))
            .map(|s| s.1)
            .sum()
    }
}

/// A soft-shadow estimator: computes V, the visible fraction of the light's area, for receivers.
///
/// The life of a frame:
/// 1. [`build`](Self::build) the light-space data from the scene (shadow maps, layers, MSSM...),
///    fitted to the receivers; estimators keep it inside themselves, holding only what they need.
/// 2. [`estimate`](Self::estimate) V for the receivers into a slice of the same length (NaN for
///    inactive receivers, [0, 1] for every active one, never NaN or inf there).
///    Multi-view estimators (sub-lights, multi-sample) build one view at a time inside `estimate`
///    so only one is alive at once; their `build` only validates.
/// 3. [`report`](Self::report) says what it cost.
///
/// Parameters are declared as a table (`params().specs()`), listed by `softshadow algos` and set
/// with [`set_param`](Self::set_param) from strings.
///
/// The CPU and GPU backends of one algorithm implement the same trait over the same [`Params`], so
/// one test can run both on the same scene and compare V.
///
/// ```
/// use shadow_map_core::{Receivers, Scene, SoftShadowEstimator, run};
/// # fn demo(scene: &Scene, receivers: &Receivers, est: &mut dyn SoftShadowEstimator)
/// #     -> shadow_map_core::Result<()> {
/// est.set_param("resolution", "512")?;
/// let (v, report) = run(est, scene, receivers)?;
/// assert_eq!(v.len(), receivers.len());
/// println!("{} took {:.2} ms", est.name(), report.total_ms(""));
/// # Ok(()) }
/// ```
///
/// A complete, runnable example that loads a scene, computes the camera's receivers and runs an
/// estimator is in the `baselines` crate documentation.
pub trait SoftShadowEstimator: Send {
    /// Registry name (`--algo NAME`).
    fn name(&self) -> &'static str;
    /// One-line description.
    fn description(&self) -> &'static str;
    /// Where it runs.
    fn backend(&self) -> Backend;
    /// Current parameters (and their declarations).
    fn params(&self) -> &Params;
    /// Sets one parameter from a string; errors name the key.
    fn set_param(&mut self, key: &str, value: &str) -> Result<()>;
    /// Builds the light-space data for this frame.
    fn build(&mut self, scene: &Scene, receivers: &Receivers) -> Result<()>;
    /// Estimates V for every receiver into `v` (`v.len() == receivers.len()`).
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()>;
    /// What the last build and estimate cost.
    fn report(&self) -> Report;
    /// Takes the cancellation token later calls check ([`Cancel`]): once it is cancelled (from
    /// any thread), a running or later `estimate` stops between chunks of receivers or between
    /// views and returns [`Error::Cancelled`](crate::Error::Cancelled), V then incomplete. The
    /// estimator stays usable: give it a fresh token to render again. A GPU twin hands the token
    /// to its CPU twin (fallbacks, redone receivers) and checks it between its own dispatches
    /// or views where it has several. An estimator starts with a token nobody cancels.
    fn set_cancel(&mut self, cancel: Cancel);
}

/// What an estimator's `build` left (`slot`, its light-space data), or the one-line error of an
/// `estimate` called before any `build`.
///
/// ```
/// let none: Option<u32> = None;
/// assert_eq!(shadow_map_core::estimator::built(Some(3)).unwrap(), 3);
/// assert!(shadow_map_core::estimator::built(none).unwrap_err().to_string().contains("before build"));
/// ```
pub fn built<T>(slot: Option<T>) -> Result<T> {
    slot.ok_or_else(|| crate::Error::param("build", "estimate called before build"))
}

/// Sets every parameter of `params` on `est` (by `set_param`, each value as its canonical
/// text): an estimator configured from a table, e.g. an engine path's CPU twin. Errors: a key
/// `est` does not declare, or a value it refuses.
pub fn configure(est: &mut dyn SoftShadowEstimator, params: &crate::Params) -> Result<()> {
    for (key, value) in params.iter() {
        est.set_param(key, &value.to_string())?;
    }
    Ok(())
}

/// Builds and estimates in one call, returning V and the report.
pub fn run(
    est: &mut dyn SoftShadowEstimator,
    scene: &Scene,
    receivers: &Receivers,
) -> Result<(Vec<f32>, Report)> {
    est.build(scene, receivers)?;
    let mut v = vec![f32::NAN; receivers.len()];
    est.estimate(scene, receivers, &mut v)?;
    Ok((v, est.report()))
}

/// The identity half of a [`SoftShadowEstimator`] impl (`name`, `description`, `backend`,
/// `params`, and in the `config` and twin forms `set_param` and `set_cancel`), written once:
///
/// - `estimator_identity!(NAME, DESCRIPTION, Cpu, config: config, cancel: cancel)`: the
///   estimator keeps its table and typed settings in the field `config` (a
///   [`Configured`](crate::Configured)), which `set_param` sets, and its token in the field
///   `cancel`, which `set_cancel` replaces; append `, check: f` to refuse settings that
///   `f(&settings) -> Result<()>` refuses ([`Configured::set_checked`](crate::Configured::set_checked));
/// - `estimator_identity!(NAME, DESCRIPTION, Cpu, params)`: the estimator owns its [`Params`]
///   in the field `params` (`set_param` and `set_cancel` are left to the impl);
/// - `estimator_identity!(twin of cpu, Gpu)`: a GPU twin that keeps its CPU twin in the field
///   `cpu` and shares its name, description, parameter table and cancellation token
///   (`set_cancel` hands it to the CPU twin).
#[macro_export]
macro_rules! estimator_identity {
    (@fixed $name:expr, $description:expr, $backend:ident) => {
        fn name(&self) -> &'static str {
            $name
        }
        fn description(&self) -> &'static str {
            $description
        }
        fn backend(&self) -> $crate::Backend {
            $crate::Backend::$backend
        }
    };
    ($name:expr, $description:expr, $backend:ident, config: $config:ident, cancel: $cancel:ident) => {
        $crate::estimator_identity!(
            $name, $description, $backend, config: $config, cancel: $cancel,
            check: |_| ::std::result::Result::Ok(())
        );
    };
    (
        $name:expr, $description:expr, $backend:ident,
        config: $config:ident, cancel: $cancel:ident, check: $check:expr
    ) => {
        $crate::estimator_identity!(@fixed $name, $description, $backend);
        fn params(&self) -> &$crate::Params {
            self.$config.params()
        }
        fn set_param(&mut self, key: &str, value: &str) -> $crate::Result<()> {
            self.$config.set_checked(key, value, $check)
        }
        fn set_cancel(&mut self, cancel: $crate::Cancel) {
            self.$cancel = cancel;
        }
    };
    ($name:expr, $description:expr, $backend:ident, $params:ident) => {
        $crate::estimator_identity!(@fixed $name, $description, $backend);
        fn params(&self) -> &$crate::Params {
            &self.$params
        }
    };
    (twin of $cpu:ident, $backend:ident) => {
        fn name(&self) -> &'static str {
            self.$cpu.name()
        }
        fn description(&self) -> &'static str {
            self.$cpu.description()
        }
        fn backend(&self) -> $crate::Backend {
            $crate::Backend::$backend
        }
        fn params(&self) -> &$crate::Params {
            self.$cpu.params()
        }
        fn set_param(&mut self, key: &str, value: &str) -> $crate::Result<()> {
            self.$cpu.set_param(key, value)
        }
        fn set_cancel(&mut self, cancel: $crate::Cancel) {
            self.$cpu.set_cancel(cancel)
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Warnings of one kind merge (receiver counts add, per-scene counts do not), zero counts
    /// add nothing, and each prints as one line.
    #[test]
    fn warnings_merge_by_kind() {
        let mut r = Report::default();
        r.warn(Warning::OutsideViews { receivers: 2 });
        r.warn(Warning::OutsideViews { receivers: 3 });
        r.warn(Warning::NonFiniteV { receivers: 0 });
        r.warn(Warning::OpaqueCasters { meshes: 2 });
        r.warn(Warning::OpaqueCasters { meshes: 2 });
        assert_eq!(
            r.warnings,
            [
                Warning::OutsideViews { receivers: 5 },
                Warning::OpaqueCasters { meshes: 2 }
            ]
        );
        assert_eq!(
            r.warning(Warning::OutsideViews { receivers: 0 }),
            Some(Warning::OutsideViews { receivers: 5 })
        );
        assert_eq!(r.warning(Warning::NonFiniteV { receivers: 0 }), None);
        for w in &r.warnings {
            assert!(!w.to_string().contains('\n'), "{w}");
        }
    }
}
