//! The GPU twins of the baselines against their CPU twins (one test binary): the conformance
//! suite of `test-support`, one module per baseline (`twin::hard`, `twin::pcf`, `twin::pcss`,
//! `twin::multi_sample`), with what is specific to the baselines here.
//!
//! Given identical light-space data (the CPU `LightSpace`), each GPU twin must reproduce its CPU
//! twin per receiver within [`TWIN`] (`|dV| <= 1e-4` on 99.9% of the receivers), and every
//! receiver beyond it must be a depth-comparison tie ([`TIE_NUDGE_REL`]) or a sampling tie
//! ([`SAMPLING_NUDGE_REL`]). The CLI path (`build` + `estimate`) is checked on a fixture by RMSE
//! ([`CLI_RMSE_MAX`]).
//!
//! GPU tests run on the shared Vulkan context; with no adapter they print a loud skip, or fail
//! under `SOFTSHADOW_REQUIRE_GPU=1`. Random cases: 24 by default, `SOFTSHADOW_PROPTEST_CASES=N`
//! for more; failures persist in `gpu_twins.proptest-regressions`.
#![cfg(feature = "gpu")]

use baselines::{
    gpu::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow},
    HardShadow, MultiSample, PcfShadow, PcssShadow,
};
use glam::Vec2;
use proptest::prelude::*;
use shadow_map_core::{
    gpu::GpuContext, light_space::LightSpace, run, Error, LightShape, Receivers, Scene, SceneBvh,
    SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, CliRun, FixedCase, Params, TwinPair},
    fixtures::{fixture_path, set_params},
    proptest_config,
    scenes::{arb_bias, arb_case, BoxSpec, LightSpec, SceneRanges, SceneSpec},
    CaseStats, Tolerance, Verdict,
};

/// Per-receiver twin tolerance on V (V is a fraction of the light's area in [0, 1]), and the
/// fraction of active receivers that must lie within it over the whole run; a single case may
/// have at most `ceil((1 - min_within) n)` of its n active receivers beyond it.
const TWIN: Tolerance = Tolerance::TWIN;
/// A receiver beyond [`TWIN`] is explained as a depth-comparison tie when moving the CPU twin's
/// depth threshold `z - eps` by this fraction of the receiver's depth (through the `bias`
/// parameter, up or down) either changes the CPU twin's V by more than the tolerance or brings it
/// within the tolerance of the GPU twin. f32 depths carry 6e-8 relative rounding, so 1e-5 is a
/// generous but still microscopic nudge. (Multi-sample: the bias change is the largest any
/// sub-light view needs for that.)
const TIE_NUDGE_REL: f32 = 1e-5;
/// How far a receiver is moved, relative to its distance from the origin, to show a sampling tie
/// (see `sampling_tie`): a few f32 ulps.
const SAMPLING_NUDGE_REL: f32 = 1e-6;
/// RMSE of V between the twins on the fixture through the CLI path (`build` + `estimate`).
const CLI_RMSE_MAX: f64 = 1e-3;

test_support::twin_suite! {
    hard [
        chunked_dispatch_equals_one_dispatch,
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
    ]
        => Baseline(Which::Hard),
    pcf [
        chunked_dispatch_equals_one_dispatch,
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
    ]
        => Baseline(Which::Pcf),
    pcss [
        chunked_dispatch_equals_one_dispatch,
        cli_path_matches_the_cpu_twin,
        loop_limit_is_detected_and_redone,
        frame_path_matches_the_cpu_twin,
    ] => Baseline(Which::Pcss),
    multi_sample [
        chunked_dispatch_equals_one_dispatch,
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
    ]
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

fn cpu_twin(w: Which) -> Box<dyn SoftShadowEstimator> {
    let r = match w {
        Which::Hard => HardShadow::new().map(|e| Box::new(e) as Box<dyn SoftShadowEstimator>),
        Which::Pcf => PcfShadow::new().map(|e| Box::new(e) as _),
        Which::Pcss => PcssShadow::new().map(|e| Box::new(e) as _),
        Which::MultiSample => MultiSample::new().map(|e| Box::new(e) as _),
    };
    match r {
        Ok(e) => e,
        Err(e) => panic!("{w:?}: {e}"),
    }
}

/// One GPU twin, compiled once per test.
enum GpuTwin {
    Hard(GpuHardShadow),
    Pcf(GpuPcfShadow),
    Pcss(GpuPcssShadow),
    MultiSample(GpuMultiSample),
}

impl GpuTwin {
    fn new(w: Which, ctx: &Arc<GpuContext>) -> Result<Self, Error> {
        Ok(match w {
            Which::Hard => GpuTwin::Hard(GpuHardShadow::new(ctx.clone())?),
            Which::Pcf => GpuTwin::Pcf(GpuPcfShadow::new(ctx.clone())?),
            Which::Pcss => GpuTwin::Pcss(GpuPcssShadow::new(ctx.clone())?),
            Which::MultiSample => GpuTwin::MultiSample(GpuMultiSample::new(ctx.clone())?),
        })
    }

    fn boxed(self) -> Box<dyn SoftShadowEstimator> {
        match self {
            GpuTwin::Hard(e) => Box::new(e),
            GpuTwin::Pcf(e) => Box::new(e),
            GpuTwin::Pcss(e) => Box::new(e),
            GpuTwin::MultiSample(e) => Box::new(e),
        }
    }

    fn get(&mut self) -> &mut dyn SoftShadowEstimator {
        match self {
            GpuTwin::Hard(e) => e,
            GpuTwin::Pcf(e) => e,
            GpuTwin::Pcss(e) => e,
            GpuTwin::MultiSample(e) => e,
        }
    }
}

fn gpu_twin(w: Which, ctx: &Arc<GpuContext>) -> GpuTwin {
    match GpuTwin::new(w, ctx) {
        Ok(t) => t,
        Err(e) => panic!("{w:?}: GPU twin: {e}"),
    }
}

fn settings_kv(w: Which, s: &Settings, bias: f32) -> Params {
    let mut kv = vec![
        ("resolution", s.resolution.to_string()),
        ("bias", format!("{bias}")),
        ("slope_bias", format!("{}", s.slope_bias)),
        ("cull", s.cull.to_string()),
        ("depth", s.depth.to_string()),
    ];
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

/// The CPU twin's V, and the light-space data it used (one per sub-light for multi-sample).
struct CpuRun {
    v: Vec<f32>,
    maps: Vec<Result<LightSpace, Error>>,
    /// The map estimators' 16-bit map under `depth=unorm16` (their layer 0 is then freed).
    q16: Option<shadow_map_core::Unorm16Map>,
    /// Bias change (in texel footprints) that moves `z - eps` by `TIE_NUDGE_REL z` in every map.
    nudge: f32,
}

fn run_cpu(
    w: Which,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    bias: f32,
) -> Result<CpuRun, Error> {
    let kv = settings_kv(w, s, bias);
    // A map estimator's own light-space data after `build`, and its V.
    macro_rules! map_twin {
        ($t:ty) => {{
            let mut e = <$t>::new()?;
            set_params(&mut e, &kv)?;
            let (v, _) = run(&mut e, scene, rec)?;
            let ls = e
                .light_space()
                .cloned()
                .ok_or_else(|| Error::LightView("no light space after build".into()))?;
            (v, vec![Ok(ls)], e.unorm16().cloned())
        }};
    }
    let (v, maps, q16) = match w {
        Which::Hard => map_twin!(HardShadow),
        Which::Pcf => map_twin!(PcfShadow),
        Which::Pcss => map_twin!(PcssShadow),
        Which::MultiSample => {
            let mut e = MultiSample::new()?;
            set_params(&mut e, &kv)?;
            let (v, _) = run(&mut e, scene, rec)?;
            // The same sub-light maps the CPU twin builds inside `estimate` (deterministic).
            let req = baselines::common::map_request(e.params())?;
            assert_eq!(req.resolution, s.resolution);
            let seed = s.seed as u64;
            let maps: Vec<Result<LightSpace, Error>> = scene
                .light()
                .stratified_points(s.sublights, |k| baselines::multi_sample::jitter(seed, k))
                .into_iter()
                .map(|y| LightSpace::build_point(scene, rec, y, &req))
                .collect();
            (v, maps, None)
        }
    };
    let nudge = maps
        .iter()
        .filter_map(|m| m.as_ref().ok())
        .map(|ls| test_support::tolerance::bias_nudge(&ls.view, TIE_NUDGE_REL))
        .fold(0.0f32, f32::max);
    Ok(CpuRun {
        v,
        maps,
        q16,
        nudge,
    })
}

fn run_gpu_with(
    twin: &mut GpuTwin,
    cpu: CpuRun,
    scene: &Scene,
    rec: &Receivers,
    kv: &Params,
) -> Result<Vec<f32>, Error> {
    let mut v = vec![0.5f32; rec.len()];
    set_params(twin.get(), kv)?;
    let light = scene.light();
    let mut maps = cpu.maps.into_iter();
    if let Some(q) = &cpu.q16 {
        // Identical 16-bit codes on both sides (the encoder itself is checked bit for bit in
        // shadow-map-core's gpu_precision test).
        let ls = first(&mut maps)?;
        match twin {
            GpuTwin::Hard(g) => g.estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            GpuTwin::Pcf(g) => g.estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            GpuTwin::Pcss(g) => g.estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            GpuTwin::MultiSample(_) => {
                return Err(Error::LightView("multi-sample keeps no 16-bit map".into()))
            }
        }
        return Ok(v);
    }
    match twin {
        GpuTwin::Hard(g) => g.estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        GpuTwin::Pcf(g) => g.estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        GpuTwin::Pcss(g) => g.estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        GpuTwin::MultiSample(g) => g.estimate_with(maps, light, rec, &mut v)?,
    }
    Ok(v)
}

fn first(maps: &mut impl Iterator<Item = Result<LightSpace, Error>>) -> Result<LightSpace, Error> {
    maps.next()
        .unwrap_or_else(|| Err(Error::LightView("no light space".into())))
}

// ---------------------------------------------------------------------------------------------
// Comparison

/// A sampling tie: the CPU twin itself jumps by more than the tolerance when receiver `k` moves by
/// [`SAMPLING_NUDGE_REL`] of its distance from the origin. PCSS samples its search and filter
/// regions by `max_taps` equal cells when they span more texels than that, and the texel a cell
/// samples is `floor` of an f32 coordinate: an ulp of difference between the backends (a fused
/// multiply-add, a differently rounded intermediate) moves it to the neighbouring texel.
fn sampling_tie(
    w: Which,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    k: usize,
    c: f32,
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
    let v = run_cpu(w, scene, &r2, s, s.bias)
        .map_err(|e| format!("{w:?}: nudged receiver run: {e}"))?
        .v;
    Ok(v[rec.len()..].iter().any(|x| (x - c).abs() > TWIN.abs))
}

fn check_case(w: Which, case: &Case, twin: &mut GpuTwin) -> Result<Option<CaseStats>, String> {
    let (scene, rec) = case.scene.scene_and_receivers();
    let s = &case.settings;
    let what = format!("{w:?}");
    let cpu = run_cpu(w, &scene, &rec, s, s.bias).map_err(|e| format!("{w:?} cpu: {e}"))?;
    let v_cpu = cpu.v.clone();
    let nudge = cpu.nudge;
    let v_gpu = run_gpu_with(twin, cpu, &scene, &rec, &settings_kv(w, s, s.bias))
        .map_err(|e| format!("{w:?} gpu: {e}"))?;
    let cmp = TWIN.compare(&what, rec.active(), &v_cpu, &v_gpu)?;
    // Explain each receiver beyond the tolerance as a depth-comparison or a sampling tie.
    let st = TWIN.judge(&what, &cmp, &rec, &v_cpu, &v_gpu, |beyond| {
        let nudged: Vec<Vec<f32>> = [s.bias + nudge, (s.bias - nudge).max(0.0)]
            .iter()
            .map(|&b| run_cpu(w, &scene, &rec, s, b).map(|r| r.v))
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{w:?}: nudged CPU run: {e}"))?;
        beyond
            .iter()
            .map(|&k| {
                let (c, g) = (v_cpu[k], v_gpu[k]);
                let flips = nudged.iter().any(|n| (n[k] - c).abs() > TWIN.abs);
                let reproduces = nudged.iter().any(|n| (n[k] - g).abs() <= TWIN.abs);
                let sampling = !(flips || reproduces) && sampling_tie(w, &scene, &rec, s, k, c)?;
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

    fn cpu(&self) -> Box<dyn SoftShadowEstimator> {
        cpu_twin(self.0)
    }

    fn gpu(&self, ctx: &Arc<GpuContext>) -> Box<dyn SoftShadowEstimator> {
        gpu_twin(self.0, ctx).boxed()
    }

    fn gpu_chunked(&self, ctx: &Arc<GpuContext>) -> Option<Box<dyn SoftShadowEstimator>> {
        let mut t = gpu_twin(self.0, ctx);
        match &mut t {
            GpuTwin::Hard(g) => g.set_max_chunk(64),
            GpuTwin::Pcf(g) => g.set_max_chunk(100),
            GpuTwin::Pcss(g) => g.set_max_chunk(7),
            GpuTwin::MultiSample(g) => g.set_max_chunk(65),
        }
        .expect("chunk cap");
        Some(t.boxed())
    }

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        use baselines::{gpu::MapFrame, hard::Hard, map_estimator::Filter, pcf::Pcf, pcss::Pcss};
        fn map<F: baselines::gpu::GpuFilter + 'static>(
            ctx: &Arc<GpuContext>,
            params: &Params,
        ) -> BoxedFrame {
            Box::new(
                MapFrame::<F>::prepare(ctx.clone(), &table(<F as Filter>::SPECS, params)).unwrap(),
            )
        }
        Some(match self.0 {
            Which::Hard => map::<Hard>(ctx, params),
            Which::Pcf => map::<Pcf>(ctx, params),
            Which::Pcss => map::<Pcss>(ctx, params),
            Which::MultiSample => {
                let t = table(baselines::multi_sample::SPECS, params);
                let n = self.fixed_case().receivers.len() as u32;
                Box::new(baselines::gpu::MultiSampleFrame::prepare(ctx.clone(), &t, n).unwrap())
            }
        })
    }

    fn fixed_case(&self) -> FixedCase {
        let case = small_case();
        let s = &case.settings;
        FixedCase::new(&case.scene, settings_kv(self.0, s, s.bias))
    }

    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let w = self.0;
        let label = self.label();
        let mut twin = gpu_twin(w, ctx);
        let st = random_twins(
            &label,
            proptest_config(source_file, 24),
            &arb_case(&SceneRanges::ALL, arb_settings()),
            &TWIN,
            |case| check_case(w, case, &mut twin),
        );
        // Hard is binary; every other baseline must also have met penumbrae.
        st.assert_met(&label, true, w != Which::Hard, true);
    }

    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let w = self.0;
        let scene = Scene::load(fixture_path("parallel-squares")).unwrap();
        let bvh = SceneBvh::new(&scene);
        let rec = Receivers::from_camera(&scene, &bvh);
        let mut cpu = cpu_twin(w);
        cpu.set_param("resolution", "256").unwrap();
        let mut gpu = gpu_twin(w, ctx);
        gpu.get().set_param("resolution", "256").unwrap();
        let cli = CliRun::new(&self.label(), &mut *cpu, gpu.get(), &scene, &rec);
        let (n, rmse, max) = cli.rmse(&self.label(), &rec);
        eprintln!(
            "{w:?} on parallel-squares @256: {n} receivers, RMSE {rmse:.3e}, max |dV| {max:.3e}"
        );
        assert!(n > 1000, "{w:?}: {n} active receivers");
        assert!(rmse <= CLI_RMSE_MAX, "{w:?}: RMSE {rmse} > {CLI_RMSE_MAX}");
        cli.assert_same_notes(
            &self.label(),
            &["out_of_frustum", "resolution", "sublights"],
        );
        assert_eq!(
            cli.cpu_report.light_space_bytes, cli.gpu_report.light_space_bytes,
            "{w:?}"
        );
    }

    /// A PCSS search wide enough to spend llvmpipe's loop budget (65535 iterations per
    /// invocation): parallel-squares under a 6 x 6 light at r = 1024 with max_taps = 300 (search
    /// regions of hundreds of texels, up to 90 000 cells). The kernel probes for the budget;
    /// receivers cut short are redone with the CPU filter on the map read back, so V equals the
    /// CPU twin's within the twins' tolerance on any device, and on lavapipe
    /// `loop_limit_cpu_fallbacks` counts them.
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        assert_eq!(self.0, Which::Pcss, "the loop-limit case is PCSS's");
        let mut scene = Scene::load(fixture_path("parallel-squares")).expect("fixture");
        let mut light = *scene.light();
        light.shape = LightShape::Rect { size: [6.0, 6.0] };
        scene.set_light(light).unwrap();
        scene.set_resolution(32, 24).unwrap();
        let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
        for depth in ["f32", "unorm16"] {
            let mut cpu = PcssShadow::new().unwrap();
            let mut gpu = GpuPcssShadow::new(ctx.clone()).unwrap();
            for e in [&mut cpu as &mut dyn SoftShadowEstimator, &mut gpu] {
                e.set_param("resolution", "1024").unwrap();
                e.set_param("max_taps", "300").unwrap();
                e.set_param("depth", depth).unwrap();
            }
            let cli = CliRun::new(&self.label(), &mut cpu, &mut gpu, &scene, &rec);
            eprintln!(
                "depth={depth}: loop-limit CPU fallbacks {} of {}",
                cli.loop_limit_fallbacks(),
                rec.len()
            );
            let mut worst = 0.0f32;
            for (k, (a, b)) in cli.cpu.iter().zip(&cli.gpu).enumerate() {
                if a.is_nan() || b.is_nan() {
                    assert!(a.is_nan() && b.is_nan(), "receiver {k}: CPU {a}, GPU {b}");
                    continue;
                }
                worst = worst.max((a - b).abs());
            }
            assert!(worst <= 1e-3, "depth={depth}: max |dV| {worst}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Specific to the baselines

/// `estimate_with` on zero receivers (light-space data from the fixed case's receivers): every
/// GPU twin accepts it.
#[test]
fn zero_receivers_through_estimate_with() {
    let Some(ctx) = test_support::gpu("zero_receivers_through_estimate_with") else {
        return;
    };
    let case = small_case();
    let (scene, rec) = case.scene.scene_and_receivers();
    let none = Receivers::default();
    for w in ALL {
        let cpu = run_cpu(w, &scene, &rec, &case.settings, case.settings.bias).unwrap();
        let mut v: Vec<f32> = Vec::new();
        let light = scene.light();
        let mut maps = cpu.maps.into_iter();
        match &mut gpu_twin(w, &ctx) {
            GpuTwin::Hard(g) => g.estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v),
            GpuTwin::Pcf(g) => g.estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v),
            GpuTwin::Pcss(g) => g.estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v),
            GpuTwin::MultiSample(g) => g.estimate_with(maps, light, &none, &mut v),
        }
        .unwrap();
    }
}

/// The GPU twins warn as the CPU twins do: a semi-transparent mesh cast opaque (PCSS and
/// multi-sample), a receiver far outside the light view given its facing fraction.
#[test]
fn gpu_twins_warn_as_the_cpu_twins() {
    use shadow_map_core::Warning;
    use test_support::fixtures::{camera, line_receivers, quad, rect_light};
    let Some(ctx) = test_support::gpu("gpu_twins_warn_as_the_cpu_twins") else {
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
    let want = vec![
        Warning::OutsideViews { receivers: 1 },
        Warning::OpaqueCasters { meshes: 1 },
    ];
    let sorted = |mut w: Vec<Warning>| {
        w.sort_by_key(|w| format!("{w:?}"));
        w
    };
    let want = sorted(want);
    let twins: [(Box<dyn SoftShadowEstimator>, Box<dyn SoftShadowEstimator>); 2] = [
        (
            Box::new(PcssShadow::new().unwrap()),
            Box::new(GpuPcssShadow::new(ctx.clone()).unwrap()),
        ),
        (
            Box::new(MultiSample::new().unwrap()),
            Box::new(GpuMultiSample::new(ctx.clone()).unwrap()),
        ),
    ];
    for (mut cpu, mut gpu) in twins {
        let (_, rc) = run(cpu.as_mut(), &scene, &rec).unwrap();
        let (_, rg) = run(gpu.as_mut(), &scene, &rec).unwrap();
        assert_eq!(sorted(rc.warnings), want, "{} cpu", cpu.name());
        assert_eq!(sorted(rg.warnings), want, "{} gpu", gpu.name());
    }
}

/// The GPU twin draws the same sub-light points (light-plane coordinates) as the CPU twin.
#[test]
fn sub_light_points_match_the_cpu_twin() {
    let Some(ctx) = test_support::gpu("sub_light_points_match_the_cpu_twin") else {
        return;
    };
    let case = small_case();
    let scene = case.scene.scene();
    let mut ms = GpuMultiSample::new(ctx).unwrap();
    ms.set_param("sublights", "3").unwrap();
    ms.set_param("seed", "11").unwrap();
    let want: Vec<Vec2> = scene
        .light()
        .stratified_points(3, |k| baselines::multi_sample::jitter(11, k));
    assert_eq!(ms.sub_light_points(scene.light()), want);
}
