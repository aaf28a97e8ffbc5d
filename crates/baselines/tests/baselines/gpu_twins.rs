//! The baselines' GPU side against their CPU twins (one test binary): the conformance suite of
//! `test-support`, one module per baseline (`twin::hard`, `twin::pcf`, `twin::pcss`,
//! `twin::multi_sample`), with what is specific to the baselines here. The GPU side is each
//! method's frame ([`MapFrame`], [`MultiSampleFrame`]); the suite's estimator checks run it as the
//! registry's GPU estimator (the frame run by the core's `FrameTwin`).
//!
//! On random scenes the frame renders its own maps and the CPU twin runs on those very maps, read
//! back (`frame_maps.rs`), so the per-receiver kernels are compared alone: V must agree within
//! [`TWIN`] (`|dV| <= 1e-4` on 99.9% of the receivers), and every receiver beyond it must be a
//! depth-comparison tie ([`TIE_NUDGE_REL`]) or a sampling tie ([`SAMPLING_NUDGE_REL`]), each shown
//! by the CPU twin rerun on the same maps. The CLI path (`build` + `estimate`: the frame's raster
//! against the CPU's) is checked on a fixture by RMSE ([`CLI_RMSE_MAX`]).
//!
//! GPU tests run on the shared Vulkan context; with no adapter they print a loud skip, or fail
//! under `SOFTSHADOW_REQUIRE_GPU=1`. Random cases: 24 by default, `SOFTSHADOW_PROPTEST_CASES=N`
//! for more; failures persist in `gpu_twins.proptest-regressions`.
#![cfg(feature = "gpu")]

use super::frame_maps::{
    cpu_on_map, cpu_on_sub_light_maps, run_map_frame, run_multi_sample_frame, FrameRun,
};
use baselines::{
    cpu::Filter,
    gpu::{MapFrame, MultiSampleFrame},
    Hard, HardShadow, MultiSample, Pcf, PcfShadow, Pcss, PcssShadow,
};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::{frame::FrameStatus, receivers::GpuReceivers, GpuContext},
    light_space::point_frame,
    method::MethodDescriptor,
    run, Error, LightShape, ParamSpec, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use std::{collections::HashMap, sync::Arc};
use test_support::{
    conformance::{
        random_twins, table, BoxedEstimator, BoxedFrame, CliRun, FixedCase, Params, TwinPair,
    },
    fixtures::{fixture_path, note, note_as},
    frame_run::FrameRig,
    proptest_config,
    scenes::{arb_bias, arb_case, BoxSpec, LightSpec, SceneRanges, SceneSpec},
    tolerance::bias_nudge,
    CaseStats, Tolerance, Verdict,
};

/// Per-receiver twin tolerance on V (V is a fraction of the light's area in [0, 1]), and the
/// fraction of active receivers that must lie within it over the whole run; a single case may
/// have at most `ceil((1 - min_within) n)` of its n active receivers beyond it.
const TWIN: Tolerance = Tolerance::TWIN;
/// A receiver beyond [`TWIN`] is explained as a depth-comparison tie when moving the CPU twin's
/// depth threshold `z - eps` by this fraction of the receiver's depth (through the `bias`
/// parameter, up or down) either changes the CPU twin's V by more than the tolerance or brings it
/// within the tolerance of the frame's. f32 depths carry 6e-8 relative rounding, so 1e-5 is a
/// generous but still microscopic nudge. (Multi-sample: the bias change is the largest any
/// sub-light view needs for that.)
const TIE_NUDGE_REL: f32 = 1e-5;
/// How far a receiver is moved, relative to its distance from the origin, to show a sampling tie
/// (see `sampling_tie`): a few f32 ulps.
const SAMPLING_NUDGE_REL: f32 = 1e-6;
/// RMSE of V between the twins on the fixture through the CLI path (`build` + `estimate`).
const CLI_RMSE_MAX: f64 = 1e-3;

test_support::twin_suite! {
    hard [cli_path_matches_the_cpu_twin, frame_path_matches_the_cpu_twin] => Baseline(Which::Hard),
    pcf [cli_path_matches_the_cpu_twin, frame_path_matches_the_cpu_twin] => Baseline(Which::Pcf),
    pcss [
        cli_path_matches_the_cpu_twin,
        long_work_is_split_not_cut,
        frame_path_matches_the_cpu_twin,
    ] => Baseline(Which::Pcss),
    multi_sample [cli_path_matches_the_cpu_twin, frame_path_matches_the_cpu_twin]
        => Baseline(Which::MultiSample),
}

// ---------------------------------------------------------------------------------------------
// Random settings

#[derive(Debug, Clone)]
struct Settings {
    resolution: u32,
    bias: f32,
    slope_bias: f32,
    cull: &'static str,
    kernel: u32,
    max_taps: u32,
    sublights: u32,
    seed: u32,
    /// `depth` parameter: f32 or unorm16.
    depth: &'static str,
}

type Case = test_support::scenes::Case<Settings>;

fn arb_settings() -> impl Strategy<Value = Settings> {
    (
        16u32..=256,
        arb_bias(),
        prop_oneof![Just("none"), Just("back"), Just("front")],
        (1u32..=9, 1u32..=48),
        (
            1u32..=4,
            0u32..100,
            prop_oneof![2 => Just("f32"), 1 => Just("unorm16")],
        ),
    )
        .prop_map(
            |(
                resolution,
                (bias, slope_bias),
                cull,
                (kernel, max_taps),
                (sublights, seed, depth),
            )| {
                Settings {
                    resolution,
                    bias,
                    slope_bias,
                    cull,
                    kernel,
                    max_taps,
                    sublights,
                    seed,
                    depth,
                }
            },
        )
}

// ---------------------------------------------------------------------------------------------
// The four pairs

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Which {
    Hard,
    Pcf,
    Pcss,
    MultiSample,
}

const ALL: [Which; 4] = [Which::Hard, Which::Pcf, Which::Pcss, Which::MultiSample];

fn cpu_twin(w: Which) -> BoxedEstimator {
    let r = match w {
        Which::Hard => HardShadow::new().map(|e| Box::new(e) as BoxedEstimator),
        Which::Pcf => PcfShadow::new().map(|e| Box::new(e) as _),
        Which::Pcss => PcssShadow::new().map(|e| Box::new(e) as _),
        Which::MultiSample => MultiSample::new().map(|e| Box::new(e) as _),
    };
    match r {
        Ok(e) => e,
        Err(e) => panic!("{w:?}: {e}"),
    }
}

fn descriptor(w: Which) -> MethodDescriptor {
    match w {
        Which::Hard => baselines::HARD,
        Which::Pcf => baselines::PCF,
        Which::Pcss => baselines::PCSS,
        Which::MultiSample => baselines::MULTI_SAMPLE,
    }
}

fn specs(w: Which) -> &'static [ParamSpec] {
    match w {
        Which::Hard => <Hard as Filter>::SPECS,
        Which::Pcf => <Pcf as Filter>::SPECS,
        Which::Pcss => <Pcss as Filter>::SPECS,
        Which::MultiSample => baselines::settings::MULTI_SAMPLE_SPECS,
    }
}

/// The registry's GPU estimator: the method's frame run by the core's `FrameTwin`.
fn gpu_estimator(w: Which, ctx: &Arc<GpuContext>) -> BoxedEstimator {
    match descriptor(w).gpu(ctx.clone()) {
        Some(Ok(e)) => e,
        Some(Err(e)) => panic!("{w:?}: GPU estimator: {e}"),
        None => panic!("{w:?}: no GPU estimator in this build"),
    }
}

/// The method's frame prepared with `params` for at most `max_receivers`.
fn frame(w: Which, ctx: &Arc<GpuContext>, params: &Params, max_receivers: u32) -> BoxedFrame {
    match descriptor(w).frame(ctx.clone(), &table(specs(w), params), max_receivers) {
        Some(Ok(f)) => f,
        Some(Err(e)) => panic!("{w:?}: frame: {e}"),
        None => panic!("{w:?}: no frame in this build"),
    }
}

fn settings_kv(w: Which, s: &Settings, bias: f32) -> Params {
    let mut kv = test_support::params_of!(s; resolution, slope_bias, cull, depth; "bias" => bias);
    match w {
        Which::Pcf => kv.push(("kernel", s.kernel.to_string())),
        Which::Pcss => kv.push(("max_taps", s.max_taps.to_string())),
        Which::MultiSample => {
            kv.push(("sublights", s.sublights.to_string()));
            kv.push(("seed", s.seed.to_string()));
        }
        Which::Hard => {}
    }
    kv
}

/// A method's frame, prepared for one parameter table.
enum Prepared {
    Hard(MapFrame<Hard>),
    Pcf(MapFrame<Pcf>),
    Pcss(MapFrame<Pcss>),
    /// With the receivers it was prepared for.
    MultiSample(MultiSampleFrame, usize),
}

/// The frames of one method prepared so far, one per parameter table: random cases (and a
/// failing case's shrinking) that repeat a table reuse its frame instead of compiling again.
#[derive(Default)]
struct Frames(HashMap<String, Prepared>);

impl Frames {
    /// The frame of `w` prepared with `kv` (for at least `rec`'s receivers), one frame on the
    /// scene, its maps read back.
    fn run(
        &mut self,
        w: Which,
        ctx: &Arc<GpuContext>,
        scene: &Scene,
        rec: &Receivers,
        kv: &Params,
    ) -> Result<FrameRun, Error> {
        let key = format!("{kv:?}");
        let reusable = match self.0.get(&key) {
            Some(Prepared::MultiSample(_, n)) => *n >= rec.len(),
            other => other.is_some(),
        };
        if !reusable {
            let t = table(specs(w), kv);
            let c = ctx.clone();
            let prepared = match w {
                Which::Hard => Prepared::Hard(MapFrame::prepare(c, &t)?),
                Which::Pcf => Prepared::Pcf(MapFrame::prepare(c, &t)?),
                Which::Pcss => Prepared::Pcss(MapFrame::prepare(c, &t)?),
                Which::MultiSample => Prepared::MultiSample(
                    MultiSampleFrame::prepare(c, &t, rec.len() as u32)?,
                    rec.len(),
                ),
            };
            self.0.insert(key.clone(), prepared);
        }
        match &self.0[&key] {
            Prepared::Hard(f) => run_map_frame(ctx, f, scene, rec),
            Prepared::Pcf(f) => run_map_frame(ctx, f, scene, rec),
            Prepared::Pcss(f) => run_map_frame(ctx, f, scene, rec),
            Prepared::MultiSample(f, _) => run_multi_sample_frame(ctx, f, scene, rec),
        }
    }
}

/// The CPU twin of `w` with the settings `s` but the bias `bias`, on the frame's maps.
fn cpu_on_maps(
    w: Which,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    bias: f32,
    run: &FrameRun,
) -> Result<Vec<f32>, String> {
    let kv = settings_kv(w, s, bias);
    let maps = &run.maps;
    match w {
        Which::Hard => cpu_on_map::<Hard>(&kv, scene, rec, maps),
        Which::Pcf => cpu_on_map::<Pcf>(&kv, scene, rec, maps),
        Which::Pcss => cpu_on_map::<Pcss>(&kv, scene, rec, maps),
        Which::MultiSample => cpu_on_sub_light_maps(&kv, scene, rec, maps),
    }
    .map_err(|e| format!("{w:?}: CPU twin on the frame's maps (bias {bias}): {e}"))
}

// ---------------------------------------------------------------------------------------------
// Comparison

/// A sampling tie: the CPU twin itself (`cpu`, on the frame's maps) jumps by more than the
/// tolerance when receiver `k` moves by [`SAMPLING_NUDGE_REL`] of its distance from the origin.
/// PCSS samples its search and filter regions by `max_taps` equal cells when they span more
/// texels than that, and the texel a cell samples is `floor` of an f32 coordinate: an ulp of
/// difference between the backends (a fused multiply-add, a differently rounded intermediate)
/// moves it to the neighbouring texel.
fn sampling_tie(
    rec: &Receivers,
    k: usize,
    c: f32,
    cpu: impl Fn(&Receivers) -> Result<Vec<f32>, String>,
) -> Result<bool, String> {
    let p = rec.position()[k];
    let d = SAMPLING_NUDGE_REL * p.length().max(1.0);
    let mut pos = rec.position().to_vec();
    let mut nrm = rec.normal().to_vec();
    let extra = [
        glam::Vec3::X * d,
        -glam::Vec3::X * d,
        glam::Vec3::Z * d,
        -glam::Vec3::Z * d,
    ];
    for e in extra {
        pos.push(p + e);
        nrm.push(rec.normal()[k]);
    }
    let mut r2 = Receivers::from_points(pos, nrm).map_err(|e| e.to_string())?;
    r2.active_mut()[..rec.len()].copy_from_slice(rec.active());
    let v = cpu(&r2)?;
    Ok(v[rec.len()..].iter().any(|x| (x - c).abs() > TWIN.abs))
}

/// One random case: the frame's V against the CPU twin's on the frame's own maps.
fn check_case(
    w: Which,
    case: &Case,
    ctx: &Arc<GpuContext>,
    frames: &mut Frames,
) -> Result<Option<CaseStats>, String> {
    let (scene, rec) = case.scene.scene_and_receivers();
    let s = &case.settings;
    let what = format!("{w:?}");
    let run = frames
        .run(w, ctx, &scene, &rec, &settings_kv(w, s, s.bias))
        .map_err(|e| format!("{w:?} frame: {e}"))?;
    let cpu = |rec: &Receivers, bias: f32| cpu_on_maps(w, &scene, rec, s, bias, &run);
    let v_cpu = cpu(&rec, s.bias)?;
    let v_gpu = &run.v;
    // The bias change that moves `z - eps` by TIE_NUDGE_REL z in every view.
    let nudge = run
        .views
        .iter()
        .flatten()
        .map(|view| bias_nudge(view, TIE_NUDGE_REL))
        .fold(0.0f32, f32::max);
    let cmp = TWIN.compare(&what, rec.active(), &v_cpu, v_gpu)?;
    // Explain each receiver beyond the tolerance as a depth-comparison or a sampling tie.
    let st = TWIN.judge(&what, &cmp, &rec, &v_cpu, v_gpu, |beyond| {
        let nudged: Vec<Vec<f32>> = [s.bias + nudge, (s.bias - nudge).max(0.0)]
            .iter()
            .map(|&b| cpu(&rec, b))
            .collect::<Result<_, _>>()?;
        beyond
            .iter()
            .map(|&k| {
                let (c, g) = (v_cpu[k], v_gpu[k]);
                let flips = nudged.iter().any(|n| (n[k] - c).abs() > TWIN.abs);
                let reproduces = nudged.iter().any(|n| (n[k] - g).abs() <= TWIN.abs);
                let sampling =
                    !(flips || reproduces) && sampling_tie(&rec, k, c, |r2| cpu(r2, s.bias))?;
                Ok(Verdict::of(flips || reproduces, sampling)
                    .note(format!("nudged(+,-) {} {}", nudged[0][k], nudged[1][k])))
            })
            .collect()
    })?;
    Ok(Some(st))
}

// ---------------------------------------------------------------------------------------------
// The suite's pairs

/// A baseline's twins, as the conformance suite drives them.
struct Baseline(Which);

/// The fixed case: a rect light over one box, 300 ground receivers on a curve through its
/// shadow, a box top, a grazing receiver, one of each kind outside the frustum, every fifth
/// receiver inactive.
fn small_case() -> Case {
    Case {
        scene: SceneSpec {
            light: LightSpec::new(0, (0.8, 0.6), (0.1, 3.0, -0.2), (0.1, -0.05)),
            boxes: vec![BoxSpec::new(0.2, 0.1, 0.8, 0.6, 1.0, 0.3)],
            ground: (0..300)
                .map(|k| {
                    let t = k as f32 / 300.0;
                    (-3.0 + 6.0 * t, 2.5 * (13.0 * t).sin())
                })
                .collect(),
            tops: vec![(0, 0.3, 0.6)],
            grazing: vec![(0.5, 0.5, 0.01, 1.0)],
            outside: vec![(0, 0.3, 0.2), (1, 0.5, 0.1), (2, 0.1, 0.1)],
            inactive_every: Some(5),
            ground_near_boxes: false,
        },
        settings: Settings {
            resolution: 128,
            bias: 1.0,
            slope_bias: 1.0,
            cull: "none",
            kernel: 5,
            max_taps: 16,
            sublights: 3,
            seed: 7,
            depth: "f32",
        },
    }
}

impl TwinPair for Baseline {
    fn label(&self) -> String {
        format!("{:?}", self.0)
    }

    fn cpu(&self) -> BoxedEstimator {
        cpu_twin(self.0)
    }

    fn gpu(&self, ctx: &Arc<GpuContext>) -> BoxedEstimator {
        gpu_estimator(self.0, ctx)
    }

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        let n = self.fixed_case().receivers.len() as u32;
        Some(frame(self.0, ctx, params, n))
    }

    fn fixed_case(&self) -> FixedCase {
        let case = small_case();
        let s = &case.settings;
        FixedCase::new(&case.scene, settings_kv(self.0, s, s.bias))
    }

    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let w = self.0;
        let label = self.label();
        let mut frames = Frames::default();
        let st = random_twins(
            &label,
            proptest_config(source_file, 24),
            &arb_case(&SceneRanges::ALL, arb_settings()),
            &TWIN,
            |case| check_case(w, case, ctx, &mut frames),
        );
        // Hard is binary; every other baseline must also have met penumbrae.
        st.assert_met(&label, true, w != Which::Hard, true);
    }

    /// On parallel-squares at r = 256: V within [`CLI_RMSE_MAX`] RMSE of the CPU twin's; the
    /// report is the frame's (one frame in the views the CPU twin fits: one, or one per
    /// sub-light), with the CPU twin's warnings and light-space bytes.
    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let w = self.0;
        let scene = Scene::load(fixture_path("parallel-squares")).unwrap();
        let bvh = SceneBvh::new(&scene);
        let rec = Receivers::from_camera(&scene, &bvh);
        let mut cpu = cpu_twin(w);
        cpu.set_param("resolution", "256").unwrap();
        let mut gpu = gpu_estimator(w, ctx);
        gpu.set_param("resolution", "256").unwrap();
        let cli = CliRun::new(&self.label(), &mut *cpu, &mut *gpu, &scene, &rec);
        let (n, rmse, max) = cli.rmse(&self.label(), &rec);
        eprintln!(
            "{w:?} on parallel-squares @256: {n} receivers, RMSE {rmse:.3e}, max |dV| {max:.3e}"
        );
        assert!(n > 1000, "{w:?}: {n} active receivers");
        assert!(rmse <= CLI_RMSE_MAX, "{w:?}: RMSE {rmse} > {CLI_RMSE_MAX}");
        let (rc, rg) = (&cli.cpu_report, &cli.gpu_report);
        assert_eq!(note_as::<String>(rg, "engine_path"), "frame twin", "{w:?}");
        let views = match w {
            Which::MultiSample => note_as::<u32>(rc, "sublights"),
            _ => 1,
        };
        assert_eq!(note_as::<u32>(rg, "views"), views, "{w:?}");
        let sorted = |r: &shadow_map_core::Report| {
            let mut w: Vec<String> = r.warnings.iter().map(|w| format!("{w:?}")).collect();
            w.sort();
            w
        };
        assert_eq!(sorted(rg), sorted(rc), "{w:?}: warnings");
        assert_eq!(rc.light_space_bytes, rg.light_space_bytes, "{w:?}");
    }

    /// PCSS regions far past llvmpipe's loop budget (65,535 iterations per invocation):
    /// parallel-squares under a 6 x 6 light at r = 1024, with max_taps = 300 (search regions of
    /// up to 90,000 cells, which one invocation used to stop short of) on 32 x 24 receivers and
    /// with max_taps = 1,024 (up to 1,048,576 cells a region, 2 M taps a receiver) on 6 x 4.
    /// The first pass defers such receivers to the wide pass, a workgroup each, so on any device
    /// nothing is cut (the status' `left_nan` and the CPU redo are 0) and V equals the CPU twin's
    /// within the twins' tolerance, under both depth precisions.
    fn long_work_is_split_not_cut(&self, ctx: &Arc<GpuContext>) {
        assert_eq!(self.0, Which::Pcss, "the long-work case is PCSS's");
        for (max_taps, (w, h)) in [("300", (32, 24)), ("1024", (6, 4))] {
            let mut scene = Scene::load(fixture_path("parallel-squares")).expect("fixture");
            let mut light = *scene.light();
            light.shape = LightShape::Rect { size: [6.0, 6.0] };
            scene.set_light(light).unwrap();
            scene.set_resolution(w, h).unwrap();
            let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
            for depth in ["f32", "unorm16"] {
                let mut cpu = PcssShadow::new().unwrap();
                let mut gpu = gpu_estimator(Which::Pcss, ctx);
                for e in [&mut cpu as &mut dyn SoftShadowEstimator, &mut *gpu] {
                    e.set_param("resolution", "1024").unwrap();
                    e.set_param("max_taps", max_taps).unwrap();
                    e.set_param("depth", depth).unwrap();
                }
                let cli = CliRun::new(&self.label(), &mut cpu, &mut *gpu, &scene, &rec);
                let redone = note(&cli.gpu_report, "frame_cpu_redo");
                let status = note(&cli.gpu_report, "frame_status").expect("the frame's status");
                let case = format!("max_taps={max_taps} depth={depth}");
                assert!(
                    redone.is_none(),
                    "{case}: {redone:?} receivers redone on the CPU"
                );
                assert!(status.contains("left_nan: 0 }"), "{case}: status {status}");
                let mut worst = 0.0f32;
                let mut lit = 0;
                for (k, (a, b)) in cli.cpu.iter().zip(&cli.gpu).enumerate() {
                    if a.is_nan() || b.is_nan() {
                        assert!(
                            a.is_nan() && b.is_nan(),
                            "{case}: receiver {k}: CPU {a}, GPU {b}"
                        );
                        continue;
                    }
                    lit += usize::from(*a > 0.0 && *a < 1.0);
                    worst = worst.max((a - b).abs());
                }
                eprintln!(
                    "{case} on {}: {} receivers, {lit} in penumbra, max |dV| {worst:.2e}, {status}",
                    ctx.describe(),
                    rec.len()
                );
                assert!(lit > 0, "{case}: no receiver in penumbra");
                assert!(worst <= 1e-3, "{case}: max |dV| {worst}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Specific to the baselines

/// The shared GPU context (`None`: skipped, printed loudly) and [`small_case`] with its scene and
/// receivers.
fn small_case_on_gpu(test: &str) -> Option<(Arc<GpuContext>, Case, Scene, Receivers)> {
    let ctx = test_support::gpu(test)?;
    let case = small_case();
    let (scene, rec) = case.scene.scene_and_receivers();
    Some((ctx, case, scene, rec))
}

/// Every frame records a frame of zero receivers (in views fitted to the fixed case's
/// receivers) and counts nothing in its status.
#[test]
fn frames_take_zero_receivers() {
    let Some((ctx, case, scene, rec)) = small_case_on_gpu("frames_take_zero_receivers") else {
        return;
    };
    let none = Receivers::default();
    for w in ALL {
        let s = &case.settings;
        let f = frame(w, &ctx, &settings_kv(w, s, s.bias), 0);
        // The views fitted to the case's receivers; the frame recorded over none.
        let mut rig = FrameRig::new(&ctx, &*f, &scene, &rec).unwrap();
        rig.receivers = GpuReceivers::upload(&ctx, &none).unwrap();
        let out = rig.run(&ctx, &*f).unwrap_or_else(|e| panic!("{w:?}: {e}"));
        assert!(out.v.is_empty(), "{w:?}");
        if let Some(status) = out.status {
            assert_eq!(status, FrameStatus::default(), "{w:?}");
        }
    }
}

/// The GPU estimators warn as the CPU twins do: a semi-transparent mesh cast opaque (PCSS and
/// multi-sample), a receiver far outside the light view given its facing fraction (PCSS, whose
/// frame counts the receivers outside its view in its status). The multi-sample frame keeps no
/// status, so the receivers its sub-light fits leave out, which the CPU twin warns of, go
/// unwarned on the GPU: there its warnings are the CPU twin's but for that one.
#[test]
fn gpu_estimators_warn_as_the_cpu_twins() {
    use shadow_map_core::Warning;
    use test_support::fixtures::{camera, line_receivers, quad, rect_light};
    let Some(ctx) = test_support::gpu("gpu_estimators_warn_as_the_cpu_twins") else {
        return;
    };
    let meshes = vec![
        (quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0),
        (quad(-0.5, -0.5, 0.5, 0.5, 1.5), 0.5),
    ];
    let scene = Scene::from_meshes("half", camera(8, 8), rect_light(1.0, 3.0), meshes).unwrap();
    let mut pos = line_receivers().position().to_vec();
    pos.push(glam::Vec3::new(100.0, 0.0, 0.0));
    let n = pos.len();
    let rec = Receivers::from_points(pos, vec![glam::Vec3::Y; n]).unwrap();
    let outside = Warning::OutsideViews { receivers: 1 };
    let opaque = Warning::OpaqueCasters { meshes: 1 };
    let sorted = |mut w: Vec<Warning>| {
        w.sort_by_key(|w| format!("{w:?}"));
        w
    };
    let want = sorted(vec![outside, opaque]);
    for w in [Which::Pcss, Which::MultiSample] {
        let (mut cpu, mut gpu) = (cpu_twin(w), gpu_estimator(w, &ctx));
        let (_, rc) = run(cpu.as_mut(), &scene, &rec).unwrap();
        let (_, rg) = run(gpu.as_mut(), &scene, &rec).unwrap();
        assert_eq!(sorted(rc.warnings), want, "{w:?} cpu");
        let gpu_want = match w {
            Which::MultiSample => vec![opaque],
            _ => want.clone(),
        };
        assert_eq!(sorted(rg.warnings), gpu_want, "{w:?} gpu");
    }
}

/// The multi-sample frame's sub-light views are centred on the CPU twin's points, in its order
/// (stratified, jittered by `jitter` with the `seed` parameter).
#[test]
fn sub_light_views_are_the_cpu_twins_points() {
    let Some((ctx, _, scene, rec)) = small_case_on_gpu("sub_light_views_are_the_cpu_twins_points")
    else {
        return;
    };
    let kv = vec![("sublights", "3".to_string()), ("seed", "11".to_string())];
    let f = frame(Which::MultiSample, &ctx, &kv, rec.len() as u32);
    let views = f.fit_views(&scene, &rec).unwrap();
    let light = scene.light();
    let points = light.stratified_points(3, |k| baselines::math::jitter(11, k));
    assert_eq!(views.len(), points.len());
    for (k, (view, y)) in views.iter().zip(points).enumerate() {
        let view = view.unwrap_or_else(|| panic!("sub-light {k}: no view"));
        let want = point_frame(light, y).unwrap();
        assert_eq!(view.frame.origin, want.origin, "sub-light {k} at {y}");
    }
}
