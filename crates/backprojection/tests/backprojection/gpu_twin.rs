//! The GPU twin of the backprojection estimator against the CPU twin: the conformance suite of
//! `test-support` (`twin::backprojection`), with what is specific to backprojection here.
//!
//! Given the CPU twin's own light-space data (layers, midpoints, MSSM), V must agree per
//! receiver within [`TWIN`] (`|dV| <= 1e-4` on 99.9% of the receivers); each receiver beyond
//! must be a depth tie (bias mode or receiver plane: nudging the depth threshold or the plane by
//! [`TIE_NUDGE_REL`] of the depth changes the CPU's V or reproduces the GPU's; midpoint mode
//! without the plane has no tie to explain). Random
//! scenes with rect, disk and sphere lights, no grazing or outside receivers. Cases: 12 by default,
//! `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]

use backprojection::{CpuBackprojection, GpuBackprojection};
use proptest::prelude::*;
use shadow_map_core::{gpu::GpuContext, run, Backend, Receivers, Scene, SoftShadowEstimator};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, FixedCase, Params, TwinPair},
    fixtures::configure,
    proptest_config,
    scenes::{arb_bias, arb_case, BoxSpec, LightSpec, SceneRanges, SceneSpec, Shapes},
    CaseStats, Tolerance, Verdict,
};

const TWIN: Tolerance = Tolerance::TWIN;
const TIE_NUDGE_REL: f32 = 1e-5;

test_support::twin_suite! {
    backprojection [
        chunked_dispatch_equals_one_dispatch,
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
        loop_limit_is_detected_and_redone,
    ] => Backprojection,
}

/// Rect, disk and sphere lights, no grazing or outside receivers.
const RANGES: SceneRanges = SceneRanges {
    shapes: Shapes::OneOf,
    grazing: false,
    outside: false,
    ..SceneRanges::ALL
};

#[derive(Debug, Clone)]
struct Settings {
    resolution: u32,
    layers: u32,
    midpoint: bool,
    gap_filling: bool,
    bias: f32,
    slope_bias: f32,
    max_nspp: u32,
    receiver_plane: bool,
    first_nonzero: bool,
    /// `occlusion=bitmask` with this grid side; `None`: additive.
    bits: Option<u32>,
}

type Case = test_support::scenes::Case<Settings>;

fn arb_settings() -> impl Strategy<Value = Settings> {
    (
        16u32..=128,
        1u32..=4,
        any::<bool>(),
        any::<bool>(),
        arb_bias(),
        prop_oneof![Just(121u32), 1u32..=64, 100u32..=400],
        (any::<bool>(), any::<bool>()),
        prop_oneof![Just(None), (2u32..=16).prop_map(Some)],
    )
        .prop_map(
            |(
                resolution,
                layers,
                midpoint,
                gap_filling,
                (bias, slope_bias),
                max_nspp,
                (receiver_plane, first_nonzero),
                bits,
            )| Settings {
                resolution,
                layers,
                midpoint,
                gap_filling,
                bias,
                slope_bias,
                max_nspp,
                receiver_plane,
                first_nonzero,
                bits,
            },
        )
}

fn settings_kv(s: &Settings, bias: f32) -> Params {
    vec![
        ("resolution", s.resolution.to_string()),
        ("layers", s.layers.to_string()),
        (
            "self_shadow",
            if s.midpoint { "midpoint" } else { "bias" }.to_string(),
        ),
        ("gap_filling", s.gap_filling.to_string()),
        ("bias", bias.to_string()),
        ("slope_bias", s.slope_bias.to_string()),
        ("max_nspp", s.max_nspp.to_string()),
        ("receiver_plane", s.receiver_plane.to_string()),
        (
            "layer_rule",
            if s.first_nonzero {
                "first_nonzero"
            } else {
                "deepest"
            }
            .to_string(),
        ),
        (
            "occlusion",
            if s.bits.is_some() {
                "bitmask"
            } else {
                "additive"
            }
            .to_string(),
        ),
        ("bits", s.bits.unwrap_or(8).to_string()),
    ]
}

/// The CPU twin's V and its light-space data.
fn run_cpu(
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    bias: f32,
) -> (Vec<f32>, CpuBackprojection) {
    let mut e = CpuBackprojection::new().expect("cpu twin");
    configure(&mut e, &settings_kv(s, bias));
    let (v, _) = run(&mut e, scene, rec).expect("cpu run");
    (v, e)
}

fn check_case(case: &Case, gpu: &mut GpuBackprojection) -> Result<Option<CaseStats>, String> {
    let (scene, rec) = case.scene.scene_and_receivers();
    let s = &case.settings;
    let (v_cpu, cpu) = run_cpu(&scene, &rec, s, s.bias);
    let ls = cpu.light_space().ok_or("no light space")?;
    configure(gpu, &settings_kv(s, s.bias));
    let mut v_gpu = vec![0.5f32; rec.len()];
    gpu.estimate_with(ls, scene.light(), &rec, &mut v_gpu)
        .map_err(|e| format!("gpu: {e}"))?;
    let cmp = TWIN.compare("backprojection", rec.active(), &v_cpu, &v_gpu)?;
    let st = TWIN.judge("backprojection", &cmp, &rec, &v_cpu, &v_gpu, |beyond| {
        // Depth ties: in bias mode, move z - eps by TIE_NUDGE_REL z (through `bias`, in texel
        // footprints) both ways; with the receiver plane (either mode), `bias` is the plane's
        // tolerance and moves the plane by TIE_NUDGE_REL z the same way. A tie changes the
        // CPU's V or reproduces the GPU's.
        let nudge = test_support::tolerance::bias_nudge(&ls.view, TIE_NUDGE_REL);
        let nudged: Vec<Vec<f32>> = if s.midpoint && !s.receiver_plane {
            Vec::new()
        } else {
            [s.bias + nudge, (s.bias - nudge).max(0.0)]
                .iter()
                .map(|&b| run_cpu(&scene, &rec, s, b).0)
                .collect()
        };
        Ok(beyond
            .iter()
            .map(|&k| {
                let (c, g) = (v_cpu[k], v_gpu[k]);
                let tie = nudged.iter().any(|v| TWIN.nudge_explains(v[k], c, g));
                Verdict::of(tie, false)
            })
            .collect())
    })?;
    Ok(Some(st))
}

/// The fixed case: a rect light over one box, a line of 200 ground receivers through its
/// shadow, a box top, every seventh receiver inactive; 3 layers, midpoints, gap filling.
fn fixed_case() -> Case {
    Case {
        scene: SceneSpec {
            light: LightSpec::new(0, (0.8, 0.6), (0.2, 3.0, -0.1), (0.1, -0.05)),
            boxes: vec![BoxSpec::new(0.0, 0.0, 0.8, 0.6, 0.5, 0.3)],
            ground: (0..200)
                .map(|k| (-2.0 + 0.02 * k as f32, -1.0 + 0.01 * k as f32))
                .collect(),
            tops: vec![(0, 0.5, 0.5)],
            grazing: vec![],
            outside: vec![],
            inactive_every: Some(7),
            ground_near_boxes: false,
        },
        settings: Settings {
            resolution: 64,
            layers: 3,
            midpoint: true,
            gap_filling: true,
            bias: 1.0,
            slope_bias: 1.0,
            max_nspp: 121,
            receiver_plane: true,
            first_nonzero: true,
            bits: None,
        },
    }
}

/// The backprojection twins, as the conformance suite drives them.
struct Backprojection;

impl TwinPair for Backprojection {
    test_support::twin_constructors!(
        CpuBackprojection,
        GpuBackprojection,
        chunk = 13,
        fixed = {
            let case = fixed_case();
            FixedCase::new(&case.scene, settings_kv(&case.settings, 1.0))
        }
    );

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        let t = table(backprojection::cpu::SPECS, params);
        Some(Box::new(
            backprojection::BackprojectionFrame::prepare(ctx.clone(), &t).unwrap(),
        ))
    }

    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let mut twin = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
        let st = random_twins(
            "backprojection",
            proptest_config(source_file, 12),
            &arb_case(&RANGES, arb_settings()),
            &TWIN,
            |case| check_case(case, &mut twin),
        );
        // Every case compares its receivers (none refused), and the run met every class.
        assert_eq!(st.refused, 0, "backprojection: cases refused");
        assert!(
            st.receivers >= st.cases,
            "backprojection: {} receivers over {} cases",
            st.receivers,
            st.cases
        );
        st.assert_met("backprojection", true, true, true);
    }

    /// The fixed case through the CLI path, with the light space rendered on the GPU (the
    /// default) and with the CPU's uploaded: each within the tolerance of the CPU twin at every
    /// receiver, NaN at inactive ones, and some umbra or penumbra.
    /// A kernel heavy enough to spend llvmpipe's loop budget (65535 iterations per invocation):
    /// up to 4096 samples per receiver (`max_nspp`) over 4 layers with 8 x 8
    /// occlusion bits, on the stacked fixture at r = 1024. Flagged receivers are redone with the
    /// CPU twin: on the CPU's light-space data (`set_light_space_on_cpu`) V must equal the CPU
    /// twin's exactly on any device, and on the GPU-rendered maps no active receiver may be left
    /// NaN; on llvmpipe the report's `loop_limit_cpu_fallbacks` must be non-zero (printed).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let mut scene = Scene::load(test_support::fixtures::fixture_path("stacked")).unwrap();
        scene.set_resolution(40, 30).unwrap();
        let rec = Receivers::from_camera(&scene, &shadow_map_core::SceneBvh::new(&scene));
        let kv = [
            ("resolution", "1024"),
            ("max_nspp", "4096"),
            ("layers", "4"),
            ("occlusion", "bitmask"),
            ("bits", "8"),
        ];
        let mut c = CpuBackprojection::new().unwrap();
        let mut g = GpuBackprojection::new(ctx.clone()).unwrap();
        for (k, v) in kv {
            c.set_param(k, v).unwrap();
            g.set_param(k, v).unwrap();
        }
        let (vc, _) = run(&mut c, &scene, &rec).unwrap();
        g.set_light_space_on_cpu(true);
        let (vg, rg) = run(&mut g, &scene, &rec).unwrap();
        let fallbacks = |r: &shadow_map_core::Report| {
            r.notes
                .iter()
                .find(|n| n.0 == "loop_limit_cpu_fallbacks")
                .map_or(0, |n| n.1.parse::<usize>().unwrap())
        };
        eprintln!(
            "loop-limit CPU fallbacks on {}: {} of {} receivers",
            ctx.describe(),
            fallbacks(&rg),
            rec.len()
        );
        for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
            assert!(
                a.to_bits() == b.to_bits() || (a - b).abs() <= 1e-5,
                "receiver {k}: CPU {a}, GPU {b}"
            );
        }
        g.set_light_space_on_cpu(false);
        let (vr, rr) = run(&mut g, &scene, &rec).unwrap();
        for (k, x) in vr.iter().enumerate() {
            assert_eq!(rec.active()[k], x.is_finite(), "receiver {k}: {x}");
        }
        if ctx.describe().contains("llvmpipe") {
            assert!(fallbacks(&rg) > 0 && fallbacks(&rr) > 0);
        }
    }

    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let case = fixed_case();
        let (scene, rec) = case.scene.scene_and_receivers();
        let (v_cpu, _) = run_cpu(&scene, &rec, &case.settings, 1.0);
        let mut g = GpuBackprojection::new(ctx.clone()).expect("gpu twin");
        assert_eq!(g.backend(), Backend::Gpu);
        assert_eq!(g.name(), "backprojection");
        configure(&mut g, &settings_kv(&case.settings, 1.0));
        let (v1, _) = run(&mut g, &scene, &rec).expect("gpu run");
        // The light space rendered on the GPU (the default) against the CPU's, uploaded (in
        // chunks: chunking itself is `chunked_dispatch_equals_one_dispatch`).
        assert!(matches!(
            g.set_max_chunk(0),
            Err(shadow_map_core::Error::Param { .. })
        ));
        g.set_max_chunk(13).unwrap();
        g.set_light_space_on_cpu(true);
        let (v3, report) = run(&mut g, &scene, &rec).expect("gpu run, CPU light space");
        assert!(report.stages.iter().any(|s| s.0 == "upload"), "{report:?}");
        let mut umbra_pen = 0;
        for k in 0..rec.len() {
            if !rec.active()[k] {
                assert!(v1[k].is_nan());
                continue;
            }
            assert!(
                (v1[k] - v3[k]).abs() <= TWIN.abs,
                "#{k}: GPU-rendered maps {} vs CPU-built maps {}",
                v1[k],
                v3[k]
            );
            assert!(
                (v1[k] - v_cpu[k]).abs() <= TWIN.abs,
                "#{k}: {} vs {}",
                v1[k],
                v_cpu[k]
            );
            if v_cpu[k] < 1.0 {
                umbra_pen += 1;
            }
        }
        assert!(umbra_pen > 0, "the fixed case casts no shadow");
    }
}

/// The GPU twin of `accuracy.rs`'s `grazing_plane_is_not_self_shadowed`: an
/// unoccluded plane lit at 85 degrees from its normal, at the defaults (receiver-plane
/// rejection on), keeps V >= facing - 0.02 at every receiver, with midpoints and with the bias.
#[test]
fn gpu_grazing_plane_is_not_self_shadowed() {
    let Some(ctx) = test_support::gpu("gpu_grazing_plane_is_not_self_shadowed") else {
        return;
    };
    let (s, r, facing) = test_support::fixtures::tilted_plane(85.0, 1.0, (30, -1.0, 0.066));
    let mut g = GpuBackprojection::new(ctx).unwrap();
    for ss in ["midpoint", "bias"] {
        g.set_param("self_shadow", ss).unwrap();
        let worst = test_support::fixtures::most_below(&run(&mut g, &s, &r).unwrap().0, &facing);
        eprintln!("gpu 85 deg plane, self_shadow={ss}: most below facing {worst:.4}");
        assert!(worst <= 0.02, "self_shadow={ss}: V below facing by {worst}");
    }
}

/// A semi-transparent scene (the fixed case's occluders at opacity 0.35): the GPU twin's ordinary
/// build (its light space then comes from the CPU, with the layers' opacity) and estimate within
/// [`TWIN`] of the CPU twin, additive occlusion, with penumbra and no umbra left.
#[test]
fn gpu_weights_semi_transparent_micropatches_as_the_cpu() {
    let Some(ctx) = test_support::gpu("gpu_weights_semi_transparent_micropatches_as_the_cpu")
    else {
        return;
    };
    let mut g = GpuBackprojection::new(ctx).unwrap();
    let mut case = fixed_case();
    case.settings.bits = None;
    let (mut scene, rec) = case.scene.scene_and_receivers();
    for k in 1..scene.meshes().len() {
        scene.set_mesh_opacity(k, 0.35).unwrap();
    }
    assert!(!scene.is_opaque());
    let (v_cpu, _) = run_cpu(&scene, &rec, &case.settings, 1.0);
    configure(&mut g, &settings_kv(&case.settings, 1.0));
    let (v_gpu, report) = run(&mut g, &scene, &rec).unwrap();
    assert!(report
        .notes
        .iter()
        .any(|(k, v)| k == "light_space" && v.contains("semi-transparent")));
    let mut worst = 0.0f32;
    let mut lowest = 1.0f32;
    for k in 0..rec.len() {
        if rec.active()[k] {
            worst = worst.max((v_cpu[k] - v_gpu[k]).abs());
            lowest = lowest.min(v_cpu[k]);
        }
    }
    eprintln!("semi-transparent: most |dV| {worst}, lowest V {lowest}");
    assert!(worst <= TWIN.abs, "GPU and CPU differ by {worst}");
    assert!(lowest > 0.0 && lowest < 1.0, "lowest V {lowest}");
}

/// `occlusion=bitmask` on the fixed case with a rect, a disk and a sphere light, B = 8 and 16,
/// with and without gap filling: the GPU twin within [`TWIN`] of the CPU twin on the CPU's light
/// space (the random scenes draw bitmask in about half of the cases; this covers every shape
/// every run), and some receivers strictly between umbra and full light.
#[test]
fn gpu_bitmask_matches_cpu_on_every_light() {
    let Some(ctx) = test_support::gpu("gpu_bitmask_matches_cpu_on_every_light") else {
        return;
    };
    let mut g = GpuBackprojection::new(ctx).unwrap();
    for shape in 0u8..3 {
        let mut case = fixed_case();
        case.scene.light.shape = shape;
        for (bits, gap) in [(8u32, true), (16, false)] {
            case.settings.bits = Some(bits);
            case.settings.gap_filling = gap;
            let (scene, rec) = case.scene.scene_and_receivers();
            let (v_cpu, cpu) = run_cpu(&scene, &rec, &case.settings, 1.0);
            let ls = cpu.light_space().unwrap();
            configure(&mut g, &settings_kv(&case.settings, 1.0));
            let mut v_gpu = vec![0.5f32; rec.len()];
            g.estimate_with(ls, scene.light(), &rec, &mut v_gpu)
                .unwrap();
            let mut worst = 0.0f32;
            let mut penumbra = 0;
            for k in 0..rec.len() {
                if !rec.active()[k] {
                    continue;
                }
                worst = worst.max((v_cpu[k] - v_gpu[k]).abs());
                if v_cpu[k] > 0.0 && v_cpu[k] < 1.0 {
                    penumbra += 1;
                }
            }
            eprintln!(
                "bitmask shape={shape} B={bits} gap={gap}: most |dV| {worst}, penumbra {penumbra}"
            );
            assert!(
                worst <= TWIN.abs,
                "shape={shape} B={bits}: GPU and CPU differ by {worst}"
            );
            assert!(penumbra > 0, "shape={shape}: no penumbra");
        }
    }
}
