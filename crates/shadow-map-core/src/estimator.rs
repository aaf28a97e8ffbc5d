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

/// What the last `build` + `estimate` did: stage times, light-space memory, and notes (which path
/// was taken, how many receivers fell outside the light frustum, ...). Printed by `--stats`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Report {
    /// `(stage, milliseconds)` in execution order.
    pub stages: Vec<(String, f64)>,
    /// Bytes of light-space data held at the peak.
    pub light_space_bytes: usize,
    /// `(key, value)` diagnostics.
    pub notes: Vec<(String, String)>,
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
/// `params`, and for a twin `set_param` and `set_cancel`), written once:
///
/// - `estimator_identity!(NAME, DESCRIPTION, Cpu, params)`: the estimator owns its [`Params`]
///   in the field `params` (`set_param` is left to the impl, which may refresh typed settings);
/// - `estimator_identity!(twin of cpu, Gpu)`: a GPU twin that keeps its CPU twin in the field
///   `cpu` and shares its name, description, parameter table and cancellation token
///   (`set_cancel` hands it to the CPU twin).
#[macro_export]
macro_rules! estimator_identity {
    ($name:expr, $description:expr, $backend:ident, $params:ident) => {
        fn name(&self) -> &'static str {
            $name
        }
        fn description(&self) -> &'static str {
            $description
        }
        fn backend(&self) -> $crate::Backend {
            $crate::Backend::$backend
        }
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
