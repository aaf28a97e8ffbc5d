//! Backprojection's GPU estimator against the CPU twin: the conformance suite of `test-support`
//! (`twin::backprojection`), the GPU side being the registry's (`backprojection::DESCRIPTOR`: the
//! engine path, [`BackprojectionFrame`], run by the core's `FrameTwin`), with what is specific to
//! backprojection here.
//!
//! Random scenes isolate the kernel: a frame renders the case's maps (peeled layers, midpoints,
//! MSSM) and runs the kernel, the maps are read back and the CPU twin estimates on those very
//! maps. V must agree per receiver within [`TWIN`] (`|dV| <= 1e-4` on 99.9% of the receivers);
//! each receiver beyond must be a depth tie (bias mode or receiver plane: nudging the depth
//! threshold or the plane by [`TIE_NUDGE_REL`] of the depth changes the CPU's V on the same maps
//! or reproduces the GPU's; midpoint mode without the plane has no tie to explain). Receivers the
//! device's loop budget cut short (left NaN by the frame) are no kernel result: their number must
//! be the frame's status count, and they are left out (counted and printed). Random scenes with
//! rect, disk and sphere lights, no grazing or outside receivers. Cases: 12 by default,
//! `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]

use crate::support::{cpu_on_maps, frame_once, prepare, prepare_and_run, FrameRun};
use backprojection::{BackprojectionFrame, CpuBackprojection};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, GpuContext},
    run, Backend, Receivers, Report, Scene,
};
use std::{collections::HashMap, sync::Arc};
use test_support::{
    conformance::{random_twins, BoxedFrame, FixedCase, Params, TwinPair},
    fixtures::configure,
    proptest_config,
    scenes::{arb_bias, arb_case, BoxSpec, LightSpec, SceneRanges, SceneSpec, Shapes},
    CaseStats, Tolerance, Verdict,
};

const TWIN: Tolerance = Tolerance::TWIN;
const TIE_NUDGE_REL: f32 = 1e-5;

test_support::twin_suite! {
    backprojection [
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
    let pick = |c: bool, a: &'static str, b: &'static str| if c { a } else { b };
    test_support::params_of!(s; resolution, layers, gap_filling, slope_bias, max_nspp,
        receiver_plane;
        "self_shadow" => pick(s.midpoint, "midpoint", "bias"),
        "bias" => bias,
        "layer_rule" => pick(s.first_nonzero, "first_nonzero", "deepest"),
        "occlusion" => pick(s.bits.is_some(), "bitmask", "additive"),
        "bits" => s.bits.unwrap_or(8))
}

/// The CPU twin's V on its own build.
fn run_cpu(scene: &Scene, rec: &Receivers, s: &Settings, bias: f32) -> Vec<f32> {
    let mut e = CpuBackprojection::new().expect("cpu twin");
    configure(&mut e, &settings_kv(s, bias));
    run(&mut e, scene, rec).expect("cpu run").0
}

/// Frames prepared so far, one per parameter table: a random case whose table an earlier case
/// drew (or a shrink step that keeps it) reuses its frame instead of compiling the pipelines
/// again (a frame is reusable across scenes and receivers).
#[derive(Default)]
struct Frames(HashMap<Params, BackprojectionFrame>);

impl Frames {
    /// The frame prepared for `params`, prepared now if no earlier case drew them.
    fn get(
        &mut self,
        ctx: &Arc<GpuContext>,
        params: &Params,
    ) -> Result<&BackprojectionFrame, String> {
        if !self.0.contains_key(params) {
            self.0.insert(params.clone(), prepare(ctx, params)?);
        }
        Ok(&self.0[params])
    }
}

/// Two V of receiver `k`, each named, are the same bits.
fn assert_same_bits(k: usize, (a_name, a): (&str, f32), (b_name, b): (&str, f32)) {
    assert_eq!(
        a.to_bits(),
        b.to_bits(),
        "receiver {k}: {a_name} {a}, {b_name} {b}"
    );
}

/// A note of `report` as a count (0 when absent).
fn note_count(report: &Report, key: &str) -> usize {
    report
        .notes
        .iter()
        .find(|n| n.0 == key)
        .map_or(0, |n| n.1.parse::<usize>().unwrap())
}

/// The frame (from `frames`) on the case's scene against the CPU twin on the frame's own maps;
/// `cuts` adds the receivers the loop budget cut.
fn check_case(
    ctx: &Arc<GpuContext>,
    frames: &mut Frames,
    case: &Case,
    cuts: &mut usize,
) -> Result<Option<CaseStats>, String> {
    let (scene, rec) = case.scene.scene_and_receivers();
    let s = &case.settings;
    let kv = settings_kv(s, s.bias);
    let fr = frame_once(ctx, frames.get(ctx, &kv)?, &scene, &rec)?;
    let v_cpu = cpu_on_maps(&fr.maps, &scene, &rec, &kv);
    let cut = fr.cut(&rec);
    if cut.len() != fr.status.left_nan as usize {
        return Err(format!(
            "{} active receivers left NaN, status {:?}",
            cut.len(),
            fr.status
        ));
    }
    *cuts += cut.len();
    // Cut receivers are no kernel result: out of the comparison.
    let mut active = rec.active().to_vec();
    let mut v_cmp = v_cpu.clone();
    for &k in &cut {
        active[k] = false;
        v_cmp[k] = f32::NAN;
    }
    let v_gpu = &fr.v;
    let cmp = TWIN.compare("backprojection", &active, &v_cmp, v_gpu)?;
    let st = TWIN.judge("backprojection", &cmp, &rec, &v_cmp, v_gpu, |beyond| {
        // Depth ties: in bias mode, move z - eps by TIE_NUDGE_REL z (through `bias`, in texel
        // footprints) both ways; with the receiver plane (either mode), `bias` is the plane's
        // tolerance and moves the plane by TIE_NUDGE_REL z the same way. A tie changes the
        // CPU's V on the same maps or reproduces the GPU's.
        let nudge = test_support::tolerance::bias_nudge(&fr.maps.view, TIE_NUDGE_REL);
        let nudged: Vec<Vec<f32>> = if s.midpoint && !s.receiver_plane {
            Vec::new()
        } else {
            [s.bias + nudge, (s.bias - nudge).max(0.0)]
                .iter()
                .map(|&b| cpu_on_maps(&fr.maps, &scene, &rec, &settings_kv(s, b)))
                .collect()
        };
        Ok(beyond
            .iter()
            .map(|&k| {
                let (c, g) = (v_cmp[k], v_gpu[k]);
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

/// The CPU twin and the registry's GPU estimator, as the conformance suite drives them.
struct Backprojection;

impl TwinPair for Backprojection {
    test_support::twin_constructors!(
        CpuBackprojection,
        descriptor = backprojection::DESCRIPTOR,
        fixed = {
            let case = fixed_case();
            FixedCase::new(&case.scene, settings_kv(&case.settings, 1.0))
        }
    );

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        Some(Box::new(prepare(ctx, params).unwrap()))
    }

    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let mut cuts = 0;
        let mut frames = Frames::default();
        let st = random_twins(
            "backprojection",
            proptest_config(source_file, 12),
            &arb_case(&RANGES, arb_settings()),
            &TWIN,
            |case| check_case(ctx, &mut frames, case, &mut cuts),
        );
        eprintln!(
            "backprojection: {cuts} receivers cut by the loop budget, left out; {} frames \
             prepared",
            frames.0.len()
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

    /// A kernel heavy enough to spend llvmpipe's loop budget (65535 iterations per invocation):
    /// up to 4096 samples per receiver (`max_nspp`) over 4 layers with 8 x 8 occlusion bits, on
    /// the stacked fixture at r = 1024, through the registry's GPU estimator. The frame leaves
    /// the cut receivers NaN and counts them in its status; the estimator must redo exactly
    /// those (`frame_cpu_redo`, and `frame_status` in its report), each bit for bit the CPU
    /// twin's in the same view, and give every other receiver the frame's own V bit for bit;
    /// the kernel's V of the receivers not cut is within [`TWIN`] of the CPU twin on the maps
    /// the frame rendered. On llvmpipe some receiver must be cut (printed).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let mut scene = Scene::load(test_support::fixtures::fixture_path("stacked")).unwrap();
        scene.set_resolution(40, 30).unwrap();
        let rec = Receivers::from_camera(&scene, &shadow_map_core::SceneBvh::new(&scene));
        let kv: Params = [
            ("resolution", "1024"),
            ("max_nspp", "4096"),
            ("layers", "4"),
            ("occlusion", "bitmask"),
            ("bits", "8"),
        ]
        .iter()
        .map(|&(k, v)| (k, v.to_string()))
        .collect();
        let mut g = self.gpu(ctx);
        configure(&mut *g, &kv);
        let (vg, rg) = run(&mut *g, &scene, &rec).unwrap();
        let redone = note_count(&rg, "frame_cpu_redo");

        let frame = prepare(ctx, &kv).unwrap();
        let fr = frame_once(ctx, &frame, &scene, &rec).unwrap();
        let cut = fr.cut(&rec);
        eprintln!(
            "loop-limit: {} of {} receivers cut on {}, {redone} redone by the CPU twin",
            cut.len(),
            rec.len(),
            ctx.describe()
        );
        assert_eq!(cut.len(), fr.status.left_nan as usize, "{:?}", fr.status);
        assert_eq!(redone, cut.len(), "{:?}", rg.notes);
        if !cut.is_empty() {
            let status = format!("left_nan: {}", cut.len());
            assert!(
                rg.notes
                    .iter()
                    .any(|(k, v)| k == "frame_status" && v.contains(&status)),
                "{:?}",
                rg.notes
            );
        }
        let twin = frame.cpu_twin(&scene, &rec, &fr.views).unwrap();
        for k in 0..rec.len() {
            if !rec.active()[k] {
                assert!(vg[k].is_nan(), "inactive receiver {k}: {}", vg[k]);
            } else if cut.contains(&k) {
                assert_same_bits(k, ("redone", vg[k]), ("CPU twin", twin[k]));
            } else {
                assert_same_bits(k, ("estimator", vg[k]), ("frame", fr.v[k]));
            }
        }
        let on_maps = cpu_on_maps(&fr.maps, &scene, &rec, &kv);
        let kept: Vec<usize> = (0..rec.len())
            .filter(|&k| rec.active()[k] && !cut.contains(&k))
            .collect();
        let beyond = kept
            .iter()
            .filter(|&&k| (fr.v[k] - on_maps[k]).abs() > TWIN.abs)
            .count();
        let worst = kept
            .iter()
            .map(|&k| (fr.v[k] - on_maps[k]).abs())
            .fold(0.0f32, f32::max);
        eprintln!(
            "loop-limit: kernel vs CPU twin on the frame's maps: max |dV| {worst:.2e}, {beyond} \
             of {} beyond {}",
            kept.len(),
            TWIN.abs
        );
        assert!(!kept.is_empty() && beyond <= TWIN.allowed_beyond(kept.len()));
        if ctx.describe().contains("llvmpipe") {
            assert!(!cut.is_empty(), "llvmpipe cut no receiver");
        }
    }

    /// The fixed case through the CLI path (`build` + `estimate` of the registry's GPU
    /// estimator): bit for bit one frame recorded by hand, within the tolerance of the CPU twin
    /// at every active receiver, NaN at inactive ones, and some umbra or penumbra.
    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let case = fixed_case();
        let (scene, rec) = case.scene.scene_and_receivers();
        let kv = settings_kv(&case.settings, 1.0);
        let v_cpu = run_cpu(&scene, &rec, &case.settings, 1.0);
        let mut g = self.gpu(ctx);
        assert_eq!(g.backend(), Backend::Gpu);
        assert_eq!(g.name(), "backprojection");
        configure(&mut *g, &kv);
        let (v1, report) = run(&mut *g, &scene, &rec).expect("gpu run");
        assert!(
            report
                .notes
                .iter()
                .any(|(k, v)| k == "engine_path" && v == "frame twin"),
            "{report:?}"
        );
        let fr = prepare_and_run(ctx, &scene, &rec, &kv).unwrap();
        assert!(fr.cut(&rec).is_empty(), "{:?}", fr.status);
        let mut umbra_pen = 0;
        for k in 0..rec.len() {
            if !rec.active()[k] {
                assert!(v1[k].is_nan());
                continue;
            }
            assert_same_bits(k, ("CLI path", v1[k]), ("frame", fr.v[k]));
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

/// The GPU side of `accuracy.rs`'s `grazing_plane_is_not_self_shadowed`: an
/// unoccluded plane lit at 85 degrees from its normal, at the defaults (receiver-plane
/// rejection on), keeps V >= facing - 0.02 at every receiver, with midpoints and with the bias.
#[test]
fn gpu_grazing_plane_is_not_self_shadowed() {
    let Some(ctx) = test_support::gpu("gpu_grazing_plane_is_not_self_shadowed") else {
        return;
    };
    let (s, r, facing) = test_support::fixtures::tilted_plane(85.0, 1.0, (30, -1.0, 0.066));
    let mut g = Backprojection.gpu(&ctx);
    for ss in ["midpoint", "bias"] {
        g.set_param("self_shadow", ss).unwrap();
        let worst = test_support::fixtures::most_below(&run(&mut *g, &s, &r).unwrap().0, &facing);
        eprintln!("gpu 85 deg plane, self_shadow={ss}: most below facing {worst:.4}");
        assert!(worst <= 0.02, "self_shadow={ss}: V below facing by {worst}");
    }
}

/// The frame's V against the CPU twin's on the frame's own maps: the largest |dV| over the
/// active receivers not cut, and how many were cut.
fn worst_on_maps(fr: &FrameRun, on_maps: &[f32], rec: &Receivers) -> (f32, usize) {
    let cut = fr.cut(rec);
    let worst = (0..rec.len())
        .filter(|&k| rec.active()[k] && !cut.contains(&k))
        .map(|k| (fr.v[k] - on_maps[k]).abs())
        .fold(0.0f32, f32::max);
    (worst, cut.len())
}

/// A semi-transparent scene (the fixed case's occluders at opacity 0.35), additive occlusion:
/// the frame writes each layer's opacity plane (read back) and its V is within [`TWIN`] of the
/// CPU twin on those maps at every receiver; through the CLI path (the registry's GPU
/// estimator, no opaque-casters warning) V is within [`TWIN`] of the CPU twin on its own maps;
/// with penumbra and no umbra left.
#[test]
fn gpu_weights_semi_transparent_micropatches_as_the_cpu() {
    let Some(ctx) = test_support::gpu("gpu_weights_semi_transparent_micropatches_as_the_cpu")
    else {
        return;
    };
    let mut case = fixed_case();
    case.settings.bits = None;
    let kv = settings_kv(&case.settings, 1.0);
    let (mut scene, rec) = case.scene.scene_and_receivers();
    for k in 1..scene.meshes().len() {
        scene.set_mesh_opacity(k, 0.35).unwrap();
    }
    assert!(!scene.is_opaque());

    let fr = prepare_and_run(&ctx, &scene, &rec, &kv).unwrap();
    assert_eq!(
        fr.maps.opacity.len(),
        fr.maps.layers.len(),
        "opacity planes"
    );
    let on_maps = cpu_on_maps(&fr.maps, &scene, &rec, &kv);
    let (worst_maps, cut) = worst_on_maps(&fr, &on_maps, &rec);

    let v_cpu = run_cpu(&scene, &rec, &case.settings, 1.0);
    let mut g = Backprojection.gpu(&ctx);
    configure(&mut *g, &kv);
    let (v_gpu, report) = run(&mut *g, &scene, &rec).unwrap();
    assert!(
        !report
            .warnings
            .iter()
            .any(|w| matches!(w, shadow_map_core::Warning::OpaqueCasters { .. })),
        "{report:?}"
    );
    let mut worst = 0.0f32;
    let mut lowest = 1.0f32;
    for k in 0..rec.len() {
        if rec.active()[k] {
            worst = worst.max((v_cpu[k] - v_gpu[k]).abs());
            lowest = lowest.min(v_cpu[k]);
        }
    }
    eprintln!(
        "semi-transparent: most |dV| {worst_maps} on the frame's maps ({cut} cut), {worst} \
         through the CLI path; lowest V {lowest}"
    );
    assert_eq!(cut, 0);
    assert!(
        worst_maps <= TWIN.abs,
        "the frame and the CPU on its maps differ by {worst_maps}"
    );
    assert!(worst <= TWIN.abs, "GPU and CPU differ by {worst}");
    assert!(lowest > 0.0 && lowest < 1.0, "lowest V {lowest}");
}

/// `occlusion=bitmask` on the fixed case with a rect, a disk and a sphere light, B = 8 and 16,
/// with and without gap filling: the frame within [`TWIN`] of the CPU twin on the frame's own
/// maps at every receiver (the random scenes draw bitmask in about half of the cases; this
/// covers every shape every run), and some receivers strictly between umbra and full light.
#[test]
fn gpu_bitmask_matches_cpu_on_every_light() {
    let Some(ctx) = test_support::gpu("gpu_bitmask_matches_cpu_on_every_light") else {
        return;
    };
    // One frame per parameter table, across the three lights (the shape is the scene's).
    for (bits, gap) in [(8u32, true), (16, false)] {
        let mut case = fixed_case();
        case.settings.bits = Some(bits);
        case.settings.gap_filling = gap;
        let kv = settings_kv(&case.settings, 1.0);
        let frame = prepare(&ctx, &kv).unwrap();
        for shape in 0u8..3 {
            case.scene.light.shape = shape;
            let (scene, rec) = case.scene.scene_and_receivers();
            let fr = frame_once(&ctx, &frame, &scene, &rec).unwrap();
            let on_maps = cpu_on_maps(&fr.maps, &scene, &rec, &kv);
            let (worst, cut) = worst_on_maps(&fr, &on_maps, &rec);
            let penumbra = (0..rec.len())
                .filter(|&k| rec.active()[k] && on_maps[k] > 0.0 && on_maps[k] < 1.0)
                .count();
            eprintln!(
                "bitmask shape={shape} B={bits} gap={gap}: most |dV| {worst}, penumbra \
                 {penumbra}, {cut} cut"
            );
            assert_eq!(cut, 0, "shape={shape} B={bits}: receivers cut");
            assert!(
                worst <= TWIN.abs,
                "shape={shape} B={bits}: GPU and CPU differ by {worst}"
            );
            assert!(penumbra > 0, "shape={shape}: no penumbra");
        }
    }
}
