//! The CPU-vs-GPU conformance suite.
//!
//! Every method's GPU twin must be its CPU twin on another backend: the same V on the same
//! light-space data (random scenes, within a [`Tolerance`]), NaN for inactive receivers, the
//! same answer to no receivers at all, V independent of how receivers are chunked into
//! dispatches, the same name, description and parameter table, and agreement through the CLI
//! path (`build` + `estimate`), kernels cut short by a device's loop budget redone rather than
//! truncated. A method implements [`TwinPair`] in its twin test file and instantiates the
//! suite with [`twin_suite!`](crate::twin_suite); the checks are also callable one by one.

use crate::{
    fixtures::{check_contract, note, param_table, rmse, set_params, NamedScene},
    scenes::SceneSpec,
    tolerance::{CaseStats, RunStats, Tolerance},
};
use proptest::{
    strategy::Strategy,
    test_runner::{Config, TestCaseError, TestRunner},
};
use shadow_map_core::{run, Backend, Receivers, Report, Scene, SoftShadowEstimator};
use std::{cell::RefCell, fmt::Debug, sync::Arc};

/// The GPU context the twins run on (re-exported for [`twin_constructors!`]).
pub use shadow_map_core::gpu::GpuContext;

/// A boxed estimator, as [`TwinPair`] hands out its twins.
pub type BoxedEstimator = Box<dyn SoftShadowEstimator>;

/// Parameters for both twins: `(key, value)`.
pub type Params = Vec<(&'static str, String)>;

/// [`Params`] from the fields of a settings value, each keyed by its field name and written with
/// `Display`, then any `key => value` pairs:
/// `params_of!(s; resolution, k; "bias" => bias)`.
#[macro_export]
macro_rules! params_of {
    ($s:expr; $($field:ident),* $(; $($key:literal => $value:expr),* $(,)?)?) => {
        vec![
            $((stringify!($field), $s.$field.to_string()),)*
            $($(($key, $value.to_string()),)*)?
        ]
    };
}

/// A boxed engine path, as [`TwinPair::frame`] hands it out.
pub type BoxedFrame = Box<dyn shadow_map_core::gpu::frame::FrameEstimator>;

/// `params` set on a table of `specs` (a method's parameter table for its engine path's
/// `prepare`); panics on a key or value the table refuses (a test's bug).
pub fn table(
    specs: &'static [shadow_map_core::ParamSpec],
    params: &Params,
) -> shadow_map_core::Params {
    param_table(specs, params)
}

/// The fixed case of the focused checks: a scene, its receivers (some inactive) and the
/// parameters both twins are given.
pub struct FixedCase {
    /// The scene.
    pub scene: Scene,
    /// The receivers; at least one inactive.
    pub receivers: Receivers,
    /// Parameters for both twins.
    pub params: Params,
}

impl FixedCase {
    /// The scene and receivers of `spec`, and `params`.
    pub fn new(spec: &SceneSpec, params: Params) -> FixedCase {
        let (scene, receivers) = spec.scene_and_receivers();
        FixedCase {
            scene,
            receivers,
            params,
        }
    }
}

/// One method's CPU and GPU twins, as the conformance suite drives them.
///
/// The methods named like tests are the suite's optional checks: [`twin_suite!`] generates a
/// test of that name for each one listed after the pair; their default bodies panic (not part
/// of this method's suite) unless the method gives one.
///
/// [`twin_suite!`]: crate::twin_suite
pub trait TwinPair {
    /// The label of messages: the twins' name by default.
    fn label(&self) -> String {
        self.cpu().name().to_string()
    }

    /// A new CPU twin, default parameters.
    fn cpu(&self) -> Box<dyn SoftShadowEstimator>;

    /// A new GPU twin on `ctx`, default parameters.
    fn gpu(&self, ctx: &Arc<GpuContext>) -> Box<dyn SoftShadowEstimator>;

    /// The focused checks' case.
    fn fixed_case(&self) -> FixedCase;

    /// CPU vs GPU on random scenes, each method with its own scenes, settings and tie
    /// explainer (usually through [`random_twins`]); failures persist beside `source_file`.
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str);

    /// Check: [`same_name_description_and_parameters`] on new twins.
    fn same_name_description_and_parameters(&self, ctx: &Arc<GpuContext>) {
        let (cpu, mut gpu) = (self.cpu(), self.gpu(ctx));
        same_name_description_and_parameters(&self.label(), &*cpu, &mut *gpu);
    }

    /// Check: [`inactive_receivers_are_nan`] on the fixed case.
    fn inactive_receivers_are_nan_on_gpu(&self, ctx: &Arc<GpuContext>) {
        let case = self.fixed_case();
        inactive_receivers_are_nan(&self.label(), &mut *self.gpu(ctx), &case);
    }

    /// Check: [`zero_receivers_work_alike`] on the fixed case.
    fn zero_receivers_work_like_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let case = self.fixed_case();
        let (mut cpu, mut gpu) = (self.cpu(), self.gpu(ctx));
        zero_receivers_work_alike(&self.label(), &mut *cpu, &mut *gpu, &case);
    }

    /// The GPU twin's engine path on `ctx`, prepared with `params` (the fixed case's), if the
    /// method has one.
    fn frame(&self, _ctx: &Arc<GpuContext>, _params: &Params) -> Option<BoxedFrame> {
        None
    }

    /// Check: the engine path on the fixed case, two frames in the caller's encoder and
    /// buffers ([`frames_match_the_cpu_twin`]), within [`Tolerance::TWIN`] of the CPU twin in
    /// the same views.
    fn frame_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let label = self.label();
        let case = self.fixed_case();
        let Some(frame) = self.frame(ctx, &case.params) else {
            panic!("{label}: the GPU twin has no engine path");
        };
        let c = frames_match_the_cpu_twin(&label, ctx, &*frame, &case.scene, &case.receivers);
        let allowed = Tolerance::TWIN.allowed_beyond(c.active);
        assert!(
            c.active > 0 && c.beyond <= allowed,
            "{label}: {} of {} active receivers beyond {} of the CPU twin (allowed {allowed}), \
             max |dV| {}",
            c.beyond,
            c.active,
            Tolerance::TWIN.abs,
            c.max_dv
        );
    }

    /// Check: the CLI path (`build` + `estimate` on both twins) agrees, the method's way.
    fn cli_path_matches_the_cpu_twin(&self, _ctx: &Arc<GpuContext>) {
        panic!("{}: no CLI-path check in this method's suite", self.label());
    }

    /// Check: work past a device's loop budget is detected and redone, not truncated.
    fn loop_limit_is_detected_and_redone(&self, _ctx: &Arc<GpuContext>) {
        panic!(
            "{}: no loop-limit check in this method's suite",
            self.label()
        );
    }

    /// Check: work that one invocation could not finish within a device's loop budget is split
    /// across invocations, never cut: nothing left for the CPU to redo, V as the CPU twin's.
    fn long_work_is_split_not_cut(&self, _ctx: &Arc<GpuContext>) {
        panic!(
            "{}: no long-work check in this method's suite",
            self.label()
        );
    }
}

/// Instantiates the conformance suite for each `algorithm => pair` (a [`TwinPair`]): a module
/// `twin::<algorithm>` with the tests
///
/// - `gpu_matches_cpu_on_random_scenes` ([`TwinPair::random_scenes`]),
/// - `same_name_description_and_parameters` ([`same_name_description_and_parameters`]),
/// - `inactive_receivers_are_nan_on_gpu` ([`inactive_receivers_are_nan`], fixed case),
/// - `zero_receivers_work_like_the_cpu_twin` ([`zero_receivers_work_alike`], fixed case),
///
/// and one test per optional check listed in brackets after the algorithm, named as the
/// [`TwinPair`] method it calls (`cli_path_matches_the_cpu_twin`,
/// `loop_limit_is_detected_and_redone`, `long_work_is_split_not_cut`,
/// `frame_path_matches_the_cpu_twin`). Each test passes the
/// GPU gate first ([`gpu`](crate::gpu)). Needs the `gpu` feature; the invoking file must see
/// every name that the pair expressions use.
///
/// ```ignore
/// test_support::twin_suite! {
///     pcss [cli_path_matches_the_cpu_twin] => Baseline(Which::Pcss),
///     hard [frame_path_matches_the_cpu_twin] => Baseline(Which::Hard),
/// }
/// ```
#[macro_export]
macro_rules! twin_suite {
    (@check $pair:expr, $check:ident) => {
        #[test]
        fn $check() {
            let Some(ctx) = ctx(stringify!($check)) else {
                return;
            };
            $crate::conformance::TwinPair::$check(&$pair, &ctx);
        }
    };
    ($($algo:ident $([$($check:ident),* $(,)?])? => $pair:expr),+ $(,)?) => {
        /// The CPU-vs-GPU conformance suite, one module per algorithm.
        mod twin {
            $(
                mod $algo {
                    #[allow(unused_imports)]
                    use super::super::*;
                    #[allow(unused_imports)]
                    use $crate::conformance::TwinPair as _;

                    fn ctx(test: &str) -> ::std::option::Option<$crate::gate::SharedContext> {
                        $crate::gate::gpu(&::std::format!("{}::{test}", ::std::module_path!()))
                    }

                    #[test]
                    fn gpu_matches_cpu_on_random_scenes() {
                        let Some(ctx) = ctx("gpu_matches_cpu_on_random_scenes") else {
                            return;
                        };
                        $crate::conformance::TwinPair::random_scenes(&$pair, &ctx, file!());
                    }

                    $crate::twin_suite!(@check $pair, same_name_description_and_parameters);
                    $crate::twin_suite!(@check $pair, inactive_receivers_are_nan_on_gpu);
                    $crate::twin_suite!(@check $pair, zero_receivers_work_like_the_cpu_twin);
                    $($($crate::twin_suite!(@check $pair, $check);)*)?
                }
            )+
        }
    };
}

/// The constructors of a [`TwinPair`] inside its `impl` block: [`TwinPair::cpu`] is
/// `<$cpu>::new()`, [`TwinPair::gpu`] the registry's GPU estimator of the descriptor `D` (its
/// frame run by `FrameTwin`), both with default parameters (a failure to build panics); with
/// `fixed = EXPR` also [`TwinPair::fixed_case`]: `EXPR`.
///
/// ```ignore
/// impl TwinPair for Accumulation {
///     test_support::twin_constructors!(CpuAccumulation, descriptor = accumulation::DESCRIPTOR);
///     // random_scenes, ...
/// }
/// ```
#[macro_export]
macro_rules! twin_constructors {
    ($cpu:ty, descriptor = $desc:expr $(, fixed = $fixed:expr)? $(,)?) => {
        fn cpu(&self) -> $crate::conformance::BoxedEstimator {
            ::std::boxed::Box::new(<$cpu>::new().expect("cpu twin"))
        }

        fn gpu(
            &self,
            ctx: &::std::sync::Arc<$crate::conformance::GpuContext>,
        ) -> $crate::conformance::BoxedEstimator {
            $desc
                .gpu(ctx.clone())
                .expect("the method has a frame")
                .expect("gpu estimator")
        }

        $(
            fn fixed_case(&self) -> $crate::conformance::FixedCase {
                $fixed
            }
        )?
    };
}

/// Runs a random twin test: `config` ([`proptest_config`](crate::proptest_config)), cases from
/// `strategy`, each compared by `check` (`Ok(None)`: both twins refused the case alike), the
/// counts summed and printed; then at least [`Tolerance::min_within`] of all receivers must
/// be within the tolerance. Returns the counts for the method's own whole-run checks (say
/// [`RunStats::assert_met`]). Panics, naming `label`, on the first failing case (shrunk).
pub fn random_twins<S>(
    label: &str,
    config: Config,
    strategy: &S,
    tol: &Tolerance,
    check: impl FnMut(&S::Value) -> Result<Option<CaseStats>, String>,
) -> RunStats
where
    S: Strategy,
    S::Value: Debug,
{
    let stats = RefCell::new(RunStats::default());
    let check = RefCell::new(check);
    let mut runner = TestRunner::new(config);
    let result = runner.run(strategy, |case| {
        let st = (check.borrow_mut())(&case).map_err(TestCaseError::fail)?;
        let mut all = stats.borrow_mut();
        match st {
            Some(st) => all.add(&st),
            None => all.refused += 1,
        }
        Ok(())
    });
    let st = stats.into_inner();
    eprintln!("{}", st.summary(label, tol));
    if let Err(e) = result {
        panic!("{label}: {e}");
    }
    st.assert_within(label, tol);
    st
}

/// Both twins give the same name, description and parameter table (specs and values), each
/// reports its backend, and the GPU twin refuses an unknown key.
pub fn same_name_description_and_parameters(
    label: &str,
    cpu: &dyn SoftShadowEstimator,
    gpu: &mut dyn SoftShadowEstimator,
) {
    assert_eq!(gpu.backend(), Backend::Gpu, "{label}");
    assert_eq!(cpu.backend(), Backend::Cpu, "{label}");
    assert_eq!(gpu.name(), cpu.name(), "{label}");
    assert_eq!(gpu.description(), cpu.description(), "{label}");
    assert_eq!(gpu.params().specs(), cpu.params().specs(), "{label}");
    assert_eq!(gpu.params(), cpu.params(), "{label}");
    assert!(gpu.set_param("no_such_key", "1").is_err(), "{label}");
}

/// Through the CLI path on the fixed case (which must have an inactive receiver): every active
/// V in [0, 1], every inactive one NaN.
pub fn inactive_receivers_are_nan(
    label: &str,
    gpu: &mut dyn SoftShadowEstimator,
    case: &FixedCase,
) {
    let rec = &case.receivers;
    assert!(
        rec.active().iter().any(|a| !a),
        "{label}: the fixed case has no inactive receiver"
    );
    if let Err(e) = set_params(gpu, &case.params) {
        panic!("{label}: {e}");
    }
    let (v, _) = match run(gpu, &case.scene, rec) {
        Ok(x) => x,
        Err(e) => panic!("{label}: {e}"),
    };
    for (k, (x, a)) in v.iter().zip(rec.active()).enumerate() {
        if *a {
            assert!((0.0..=1.0).contains(x), "{label} #{k}: {x}");
        } else {
            assert!(x.is_nan(), "{label} #{k}: {x} for an inactive receiver");
        }
    }
}

/// With no receivers at all, both twins (as given: default parameters in the suite) succeed
/// with an empty output or fail alike (the same message) through the CLI path; then a GPU
/// output slice of the wrong length for the fixed case's receivers is refused.
pub fn zero_receivers_work_alike(
    label: &str,
    cpu: &mut dyn SoftShadowEstimator,
    gpu: &mut dyn SoftShadowEstimator,
    case: &FixedCase,
) {
    let none = Receivers::default();
    let scene = &case.scene;
    match (run(cpu, scene, &none), run(gpu, scene, &none)) {
        (Ok((a, _)), Ok((b, _))) => assert!(a.is_empty() && b.is_empty(), "{label}"),
        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{label}"),
        (a, b) => panic!(
            "{label}: cpu {:?} vs gpu {:?}",
            a.map(|x| x.0),
            b.map(|x| x.0)
        ),
    }
    let mut short = vec![0.0f32; 1];
    assert!(
        gpu.estimate(scene, &case.receivers, &mut short).is_err(),
        "{label}: a wrong output length was not refused"
    );
}

/// Both twins through the CLI path (`build` + `estimate`) on the same scene and receivers.
#[derive(Debug, Clone)]
pub struct CliRun {
    /// The CPU twin's V.
    pub cpu: Vec<f32>,
    /// The GPU twin's V.
    pub gpu: Vec<f32>,
    /// The CPU twin's report.
    pub cpu_report: Report,
    /// The GPU twin's report.
    pub gpu_report: Report,
}

impl CliRun {
    /// Runs both twins (configured by the caller) on `scene` and `rec`; an error panics,
    /// naming `label`.
    pub fn new(
        label: &str,
        cpu: &mut dyn SoftShadowEstimator,
        gpu: &mut dyn SoftShadowEstimator,
        scene: &Scene,
        rec: &Receivers,
    ) -> CliRun {
        let (cpu, cpu_report) = match run(cpu, scene, rec) {
            Ok(x) => x,
            Err(e) => panic!("{label}: cpu: {e}"),
        };
        let (gpu, gpu_report) = match run(gpu, scene, rec) {
            Ok(x) => x,
            Err(e) => panic!("{label}: gpu: {e}"),
        };
        CliRun {
            cpu,
            gpu,
            cpu_report,
            gpu_report,
        }
    }

    /// Over the active receivers of `rec` (every inactive one NaN on both twins, asserted):
    /// how many, the RMSE of `V_cpu - V_gpu`, and the largest `|dV|`.
    pub fn rmse(&self, label: &str, rec: &Receivers) -> (usize, f64, f32) {
        let (mut se, mut n, mut max) = (0.0f64, 0usize, 0.0f32);
        for k in 0..rec.len() {
            let (a, b) = (self.cpu[k], self.gpu[k]);
            if !rec.active()[k] {
                assert!(a.is_nan() && b.is_nan(), "{label} #{k}");
                continue;
            }
            let d = a - b;
            se += (d as f64).powi(2);
            n += 1;
            max = max.max(d.abs());
        }
        (n, (se / n.max(1) as f64).sqrt(), max)
    }

    /// Both reports have the same value (or none) for each note of `keys`.
    pub fn assert_same_notes(&self, label: &str, keys: &[&str]) {
        for key in keys {
            assert_eq!(
                note(&self.cpu_report, key),
                note(&self.gpu_report, key),
                "{label}: note {key}"
            );
        }
    }

    /// Both outputs keep the estimator contract ([`check_contract`]).
    pub fn check_contract(&self, rec: &Receivers) {
        check_contract(&self.cpu, rec);
        check_contract(&self.gpu, rec);
    }
}

/// What [`frames_match_the_cpu_twin`] measured.
#[derive(Debug, Clone)]
pub struct FrameComparison {
    /// Largest |dV| over the active receivers.
    pub max_dv: f32,
    /// Active receivers with |dV| beyond [`Tolerance::TWIN`]'s `abs`.
    pub beyond: usize,
    /// Active receivers.
    pub active: usize,
    /// Root mean square of dV over the active receivers (what `frame_loop`'s `rmse_vs_cpu`
    /// bounds).
    pub rmse: f64,
    /// The estimator's status after the last frame, decoded (zeros when it keeps none).
    pub status: shadow_map_core::gpu::frame::FrameStatus,
    /// Active receivers the frame left NaN as cut short by the device's loop budget (only with
    /// [`frames_match_the_cpu_twin_with_cuts`]; excluded from the figures above).
    pub cut: usize,
    /// The last frame's V.
    pub v: Vec<f32>,
}

impl FrameComparison {
    /// Asserts, naming `label`, that more receivers were compared than left cut, at most one in
    /// `per` of those compared beyond [`Tolerance::TWIN`]'s `abs`, and the RMSE at most `rmse`
    /// (`f64::INFINITY` for no bound on it).
    pub fn assert_close(&self, label: &str, per: usize, rmse: f64) {
        assert!(
            self.active > self.cut && self.beyond * per <= self.active && self.rmse <= rmse,
            "{label}: {} of {} beyond {} of the CPU twin (max |dV| {}, rmse {})",
            self.beyond,
            self.active,
            Tolerance::TWIN.abs,
            self.max_dv,
            self.rmse
        );
    }
}

/// The engine path against the CPU twin: the views `frame` fits for `receivers`, then two
/// frames through [`FrameEstimator::encode`](shadow_map_core::gpu::frame::FrameEstimator)
/// (each its own encoder and submit, nothing read between them) from a caller's casters,
/// receiver buffer and V buffer; V read back once after the last. Panics (naming `label`) unless
/// every inactive receiver is NaN on both and every active GPU V is finite in [0, 1]; returns
/// the comparison with [`FrameEstimator::cpu_twin`] in the same views for the caller's bound.
pub fn frames_match_the_cpu_twin(
    label: &str,
    ctx: &GpuContext,
    frame: &dyn shadow_map_core::gpu::frame::FrameEstimator,
    scene: &Scene,
    receivers: &Receivers,
) -> FrameComparison {
    frames_compared(label, ctx, frame, scene, receivers, None)
}

/// One comparison of [`frames_over_settings`], for the caller's bounds.
pub struct SettingsCase<'a, F> {
    /// `<method> <scene> <settings>`, for messages.
    pub label: String,
    /// The settings over the defaults.
    pub kv: &'a [(&'a str, &'a str)],
    /// The frame, prepared for these settings.
    pub frame: &'a F,
    /// The scene's name.
    pub name: &'static str,
    /// The scene.
    pub scene: &'a Scene,
    /// Its receivers.
    pub rec: &'a Receivers,
    /// The frames against the CPU twin.
    pub c: FrameComparison,
}

impl<F: shadow_map_core::gpu::frame::FrameEstimator> SettingsCase<'_, F> {
    /// The RMSE of the frame's V to its CPU twin on the scene made opaque (every caster cast
    /// opaque), in the views the frame fits, over the active receivers: how far a frame that
    /// ignored opacity would be.
    pub fn rmse_to_opaque(&self) -> f64 {
        let (scene, rec, label) = (self.scene, self.rec, &self.label);
        let views = self
            .frame
            .fit_views(scene, rec)
            .unwrap_or_else(|e| panic!("{label}: {e}"));
        let opaque = self
            .frame
            .cpu_twin(&scene.opaque(), rec, &views)
            .unwrap_or_else(|e| panic!("{label}: CPU twin: {e}"));
        rmse(&self.c.v, &opaque, rec.active())
    }
}

/// The engine path over a table of settings: for each `kv` of `settings` one frame from
/// `prepare` (reused across the scenes), then on every scene of `scenes`
/// [`frames_match_the_cpu_twin`] (or, with `cut_word`,
/// [`frames_match_the_cpu_twin_with_cuts`]) labelled `<method> <scene> <kv>`, its comparison
/// handed to `check` for the method's bounds.
pub fn frames_over_settings<F: shadow_map_core::gpu::frame::FrameEstimator>(
    method: &str,
    ctx: &GpuContext,
    settings: &[&[(&str, &str)]],
    scenes: &[NamedScene],
    cut_word: Option<usize>,
    prepare: impl Fn(&[(&str, &str)]) -> F,
    mut check: impl FnMut(SettingsCase<'_, F>),
) {
    for &kv in settings {
        let frame = prepare(kv);
        for (name, scene, rec) in scenes {
            let label = format!("{method} {name} {kv:?}");
            let c = frames_compared(&label, ctx, &frame, scene, rec, cut_word);
            check(SettingsCase {
                label,
                kv,
                frame: &frame,
                name,
                scene,
                rec,
                c,
            });
        }
    }
}

/// [`frames_match_the_cpu_twin`] for an engine path that leaves receivers cut short by the
/// device's loop budget NaN and counts them in status word `cut_word` (for the caller to redo,
/// as the CLI does): an active NaN is allowed only there, their number must equal that word, and
/// they are left out of the comparison ([`FrameComparison::cut`]).
pub fn frames_match_the_cpu_twin_with_cuts(
    label: &str,
    ctx: &GpuContext,
    frame: &dyn shadow_map_core::gpu::frame::FrameEstimator,
    scene: &Scene,
    receivers: &Receivers,
    cut_word: usize,
) -> FrameComparison {
    frames_compared(label, ctx, frame, scene, receivers, Some(cut_word))
}

/// One more frame with [`FrameTimestamps`](shadow_map_core::gpu::frame::FrameTimestamps)
/// written between its passes: V bit for bit `bits` (the timestamps change nothing), at least one
/// stage, every stage's GPU ms finite and >= 0, no mark dropped. Adapters without timestamp
/// queries print a loud skip of this part only.
fn timestamped_frame_matches(
    label: &str,
    ctx: &GpuContext,
    frame: &dyn shadow_map_core::gpu::frame::FrameEstimator,
    inputs: &shadow_map_core::gpu::frame::FrameInputs<'_>,
    bits: &[u32],
) {
    use shadow_map_core::gpu::frame::{FrameInputs, FrameTimestamps};
    let Some(ts) = FrameTimestamps::new(ctx, FrameTimestamps::FRAME_CAPACITY)
        .unwrap_or_else(|e| panic!("{label}: {e}"))
    else {
        eprintln!("SKIPPED (no timestamp queries on this adapter): {label}: frame timestamps");
        return;
    };
    ts.reset();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    frame
        .encode(
            &mut enc,
            &FrameInputs {
                timestamps: Some(&ts),
                ..*inputs
            },
        )
        .unwrap_or_else(|e| panic!("{label}: encode with timestamps: {e}"));
    ts.resolve(&mut enc);
    ctx.queue.submit([enc.finish()]);
    let again: Vec<u32> = ctx
        .read_buffer(inputs.v, 4 * inputs.count as u64)
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    assert_eq!(again, bits, "{label}: V changed under timestamps");
    let stages = ts.read(ctx).unwrap_or_else(|e| panic!("{label}: {e}"));
    assert_eq!(ts.dropped(), 0, "{label}: timestamps dropped");
    if inputs.count > 0 {
        assert!(!stages.is_empty(), "{label}: no stage timed");
    }
    for (stage, ms) in &stages {
        assert!(
            ms.is_finite() && *ms >= 0.0,
            "{label}: stage {stage}: {ms} ms"
        );
    }
    println!("{label}: GPU ms per stage {stages:?}");
}

fn frames_compared(
    label: &str,
    ctx: &GpuContext,
    frame: &dyn shadow_map_core::gpu::frame::FrameEstimator,
    scene: &Scene,
    receivers: &Receivers,
    cut_word: Option<usize>,
) -> FrameComparison {
    let rig = crate::frame_run::FrameRig::new(ctx, frame, scene, receivers)
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let (views, inputs, n) = (&rig.views, rig.inputs(), receivers.len() as u64);
    for _ in 0..2 {
        rig.submit(ctx, frame)
            .unwrap_or_else(|e| panic!("{label}: encode: {e}"));
    }
    let bits: Vec<u32> = ctx
        .read_buffer(&rig.v, 4 * n)
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    timestamped_frame_matches(label, ctx, frame, &inputs, &bits);
    let words: Vec<u32> = match frame.status() {
        Some(b) => ctx
            .read_buffer(b, b.size())
            .unwrap_or_else(|e| panic!("{label}: {e}")),
        None => Vec::new(),
    };
    let status = frame.decode_status(&words);
    let cpu = frame
        .cpu_twin(scene, receivers, views)
        .unwrap_or_else(|e| panic!("{label}: CPU twin: {e}"));
    let (mut max_dv, mut beyond, mut active, mut sq) = (0.0f32, 0usize, 0usize, 0.0f64);
    let mut cut = 0usize;
    for (k, (&b, &c)) in bits.iter().zip(&cpu).enumerate() {
        let g = f32::from_bits(b);
        if !receivers.active()[k] {
            assert!(
                g.is_nan() && c.is_nan(),
                "{label}: inactive receiver {k}: {g} / {c}"
            );
            continue;
        }
        if g.is_nan() && cut_word.is_some() {
            cut += 1;
            continue;
        }
        assert!(
            g.is_finite() && (0.0..=1.0).contains(&g),
            "{label}: V[{k}] = {g} (bits {b:#x})"
        );
        let d = (g - c).abs();
        sq += d as f64 * d as f64;
        max_dv = max_dv.max(d);
        beyond += usize::from(d > Tolerance::TWIN.abs);
        active += 1;
    }
    if let Some(w) = cut_word {
        assert_eq!(
            words.get(w).copied().unwrap_or(0) as usize,
            cut,
            "{label}: active receivers left NaN against the status' cut count (word {w})"
        );
    }
    assert!(active > 0, "{label}: no active receiver compared");
    let rmse = (sq / active.max(1) as f64).sqrt();
    println!(
        "{label}: frame API vs CPU twin, max |dV| {max_dv:.2e}, rmse {rmse:.2e}, {beyond} of {active} beyond {:.0e}, {cut} cut, status {status:?}",
        Tolerance::TWIN.abs
    );
    FrameComparison {
        max_dv,
        beyond,
        active,
        rmse,
        status,
        cut,
        v: bits.into_iter().map(f32::from_bits).collect(),
    }
}
