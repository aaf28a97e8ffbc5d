//! The accumulation estimator's GPU path against the CPU twin: the conformance suite of
//! `test-support` (`twin::accumulation`), whose GPU estimator is the registry's (the engine path,
//! [`AccumulationFrame`], run by the core's `FrameTwin`), with what is specific to accumulation
//! here.
//!
//! On random scenes the frame runs once and its maps are read back; the CPU twin on those very
//! maps must agree per receiver within [`TWIN`] (`|dV| <= 1e-4` on 99.9% of the receivers), each
//! receiver beyond a tie ([`maps`](super::maps): a depth-threshold or receiver-position nudge
//! explains it). Rect, disk and sphere lights; additive and exact; fixed, adaptive and lexels
//! kernels; every light-view `fit` and `nearfar` choice. Cases: 16 by default,
//! `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]

use super::maps::{judge_on_maps, run_frame, Left};
use accumulation::{AccumulationFrame, CpuAccumulation, DESCRIPTOR};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, GpuContext},
    run, Backend, Error, Receivers, Scene, SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, CliRun, FixedCase, Params, TwinPair},
    fixtures::{configure, fixture_path, note},
    proptest_config,
    scenes::{arb_bias, arb_case, BoxSpec, LightSpec, SceneRanges, SceneSpec, Shapes},
    CaseStats, Tolerance,
};

const TWIN: Tolerance = Tolerance::TWIN;

test_support::twin_suite! {
    accumulation [
        cli_path_matches_the_cpu_twin,
        loop_limit_is_detected_and_redone,
        frame_path_matches_the_cpu_twin,
    ] => Accumulation,
}

/// Every light shape (a uniform draw), sides up to 1.2, boxes at most 0.8 up and 0.5 high, no
/// grazing receivers, up to 5 outside the light's frustum (the frame's settle passes), every
/// other ground receiver near a box's shadow (within 1.5 box sides of its centre), so penumbrae
/// are well represented.
const RANGES: SceneRanges = SceneRanges {
    shapes: Shapes::Uniform,
    light_size: 0.05..1.2,
    box_bottom: 0.0..0.8,
    box_height: 0.05..0.5,
    grazing: false,
    outside: true,
    ground_near_boxes: true,
};

#[derive(Debug, Clone)]
struct Settings {
    resolution: u32,
    k: u32,
    variant: &'static str,
    kernel: &'static str,
    bits: u32,
    layers: u32,
    sphere: &'static str,
    coverage: &'static str,
    bias: f32,
    slope_bias: f32,
    fit: &'static str,
    nearfar: &'static str,
}

const FITS: [&str; 3] = ["receivers", "scene", "stable"];
const NEARFARS: [&str; 3] = ["clipped", "aabb", "frustum"];

type Case = test_support::scenes::Case<Settings>;

fn arb_settings() -> impl Strategy<Value = Settings> {
    (
        (16u32..=128, 1u32..=15),
        prop_oneof![Just("additive"), Just("exact")],
        prop_oneof![Just("fixed"), Just("adaptive"), Just("lexels")],
        (2u32..=16, 1u32..=4),
        (
            prop_oneof![Just("contract"), Just("paper")],
            prop_oneof![Just("overlap"), Just("centre")],
        ),
        arb_bias(),
        (
            prop::sample::select(FITS.to_vec()),
            prop::sample::select(NEARFARS.to_vec()),
        ),
    )
        .prop_map(
            |(
                (resolution, k),
                variant,
                kernel,
                (bits, layers),
                (sphere, coverage),
                (bias, slope_bias),
                (fit, nearfar),
            )| {
                Settings {
                    resolution,
                    k,
                    variant,
                    kernel,
                    bits,
                    layers,
                    sphere,
                    coverage,
                    bias,
                    slope_bias,
                    fit,
                    nearfar,
                }
            },
        )
}

fn settings_kv(s: &Settings, bias: f32) -> Params {
    test_support::params_of!(s; resolution, k, variant, kernel, bits, layers, sphere, coverage,
        slope_bias, fit, nearfar; "bias" => bias)
}

/// What the random run saw besides the judged comparison.
#[derive(Default)]
struct Seen {
    /// Outside and cut receivers left out.
    left: Left,
    /// Receivers compared, and those beyond 1e-4 of the CPU twin's own build (its CPU-rasterised
    /// maps, not the frame's).
    own: (usize, usize),
}

/// One random case: the frame on the scene, judged against the CPU twin on the frame's maps
/// ([`judge_on_maps`]). A scene the CPU twin refuses (lit receivers outside the one frustum
/// with geometry towards the light) the registry's GPU estimator must refuse the same way.
fn check_case(
    case: &Case,
    ctx: &Arc<GpuContext>,
    seen: &mut Seen,
) -> Result<Option<CaseStats>, String> {
    let (scene, rec) = case.scene.scene_and_receivers();
    let s = &case.settings;
    let kv = settings_kv(s, s.bias);
    let mut cpu = CpuAccumulation::new().expect("cpu twin");
    configure(&mut cpu, &kv);
    let v_own = match run(&mut cpu, &scene, &rec) {
        Ok((v, _)) => v,
        Err(Error::Receivers(msg)) => {
            let mut gpu = Accumulation.gpu(ctx);
            configure(&mut *gpu, &kv);
            return match run(&mut *gpu, &scene, &rec) {
                Err(Error::Receivers(_)) => Ok(None),
                Err(e) => Err(format!("cpu refused ({msg}), gpu: {e}")),
                Ok(_) => Err(format!("cpu refused ({msg}), gpu did not")),
            };
        }
        Err(e) => return Err(format!("cpu: {e}")),
    };
    let params = table(accumulation::settings::SPECS, &kv);
    let frame =
        AccumulationFrame::prepare(ctx.clone(), &params).map_err(|e| format!("prepare: {e}"))?;
    let fr = run_frame(ctx, &frame, &scene, &rec).map_err(|e| format!("frame: {e}"))?;
    let own_view = cpu.light_space().ok_or("no light space")?.view;
    if fr.view != own_view {
        return Err(format!(
            "the frame's view {:?} is not the CPU twin's {own_view:?}",
            fr.view
        ));
    }
    let (_, st, left) = judge_on_maps("accumulation", &fr, &scene, &rec, &params)?;
    seen.left.outside += left.outside;
    seen.left.unsettled += left.unsettled;
    seen.left.unsettled_gpu_only += left.unsettled_gpu_only;
    seen.left.cut += left.cut;
    seen.left.no_front_bit += left.no_front_bit;
    seen.left.no_front_bit_differ += left.no_front_bit_differ;
    for ((&g, &c), &a) in fr.v.iter().zip(&v_own).zip(rec.active()) {
        if a && !g.is_nan() {
            seen.own.0 += 1;
            seen.own.1 += usize::from((g - c).abs() > TWIN.abs);
        }
    }
    Ok(Some(st))
}

/// The fixed scene of the focused tests: a sphere light over two boxes, a line of ground
/// receivers through their shadows, two box tops, every seventh receiver inactive.
fn fixed_case() -> Case {
    Case {
        scene: SceneSpec {
            light: LightSpec::new(2, (0.8, 0.8), (0.2, 3.0, -0.1), (0.1, -0.05)),
            boxes: vec![
                BoxSpec::new(0.0, 0.0, 0.8, 0.6, 0.5, 0.3),
                BoxSpec::new(0.3, 0.2, 0.5, 0.5, 1.2, 0.1),
            ],
            ground: (0..200)
                .map(|k| (-2.0 + 0.02 * k as f32, -1.0 + 0.01 * k as f32))
                .collect(),
            tops: vec![(0, 0.5, 0.5), (0, 0.1, 0.9)],
            grazing: vec![],
            outside: vec![],
            inactive_every: Some(7),
            ground_near_boxes: true,
        },
        settings: Settings {
            resolution: 96,
            k: 7,
            variant: "additive",
            kernel: "fixed",
            bits: 16,
            layers: 2,
            sphere: "contract",
            coverage: "overlap",
            bias: 1.0,
            slope_bias: 1.0,
            fit: "receivers",
            nearfar: "clipped",
        },
    }
}

/// The accumulation twins, as the conformance suite drives them.
struct Accumulation;

impl TwinPair for Accumulation {
    test_support::twin_constructors!(
        CpuAccumulation,
        descriptor = DESCRIPTOR,
        fixed = {
            let case = fixed_case();
            FixedCase::new(&case.scene, settings_kv(&case.settings, 1.0))
        }
    );

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        Some(Box::new(frame_for(ctx, params)))
    }

    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let mut seen = Seen::default();
        let st = random_twins(
            "accumulation",
            proptest_config(source_file, 16),
            &arb_case(&RANGES, arb_settings()),
            &TWIN,
            |case| check_case(case, ctx, &mut seen),
        );
        let l = &seen.left;
        eprintln!(
            "accumulation: {} outside ({} left NaN, {} of them settled by the CPU's test) and {} \
             cut receivers left to the caller, {} with no bit in front ({} differ); against the \
             CPU twin's own maps {} of {} beyond {} (texels whose centre lies on a caster's edge)",
            l.outside,
            l.unsettled,
            l.unsettled_gpu_only,
            l.cut,
            l.no_front_bit,
            l.no_front_bit_differ,
            seen.own.1,
            seen.own.0,
            TWIN.abs
        );
        assert!(st.classes[1] > 0, "no penumbra receiver was compared");
    }

    /// Every variant x kernel combination on the fixed scene with a sphere light, through the
    /// CLI path (`build` + `estimate` of the registry's GPU estimator): V bit for bit the engine
    /// path's own (one frame recorded here), the same again from a second `estimate`, and
    /// within the tolerance of the CPU twin (at most one tie).
    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let mut case = fixed_case();
        let mut g = self.gpu(ctx);
        assert_eq!(g.backend(), Backend::Gpu);
        assert_eq!(g.name(), "accumulation");
        assert_eq!(g.params(), CpuAccumulation::new().unwrap().params());
        let (scene, rec) = case.scene.scene_and_receivers();
        let mut penumbra = 0;
        for variant in ["additive", "exact"] {
            for kernel in ["fixed", "adaptive", "lexels"] {
                case.settings.variant = variant;
                case.settings.kernel = kernel;
                let kv = settings_kv(&case.settings, 1.0);
                let mut cpu = CpuAccumulation::new().unwrap();
                configure(&mut cpu, &kv);
                let (v_cpu, _) = run(&mut cpu, &scene, &rec).expect("cpu run");
                configure(&mut *g, &kv);
                let (v1, _) = run(&mut *g, &scene, &rec).expect("gpu run");
                let mut v2 = vec![0.0; rec.len()];
                g.estimate(&scene, &rec, &mut v2)
                    .expect("gpu estimate again");
                let fr = run_frame(ctx, &frame_for(ctx, &kv), &scene, &rec).expect("frame");
                for k in 0..rec.len() {
                    if !rec.active()[k] {
                        assert!(v1[k].is_nan() && v2[k].is_nan());
                        continue;
                    }
                    assert_eq!(v1[k].to_bits(), v2[k].to_bits(), "estimate again: #{k}");
                    assert_eq!(v1[k].to_bits(), fr.v[k].to_bits(), "frame path: #{k}");
                    if v_cpu[k] > 0.0 && v_cpu[k] < 1.0 {
                        penumbra += 1;
                    }
                }
                at_most_one_beyond(&format!("{variant}/{kernel}"), &rec, &v_cpu, &v1);
            }
        }
        assert!(
            penumbra > 50,
            "the scene should have penumbrae ({penumbra})"
        );
    }

    /// A kernel heavy enough to spend llvmpipe's loop budget (65535 iterations per
    /// invocation): `variant=exact`, K = 32 fixed taps, 3 layers, 16 x 16 bits on the stacked
    /// fixture. Before the kernel probed for it, lavapipe silently returned truncated bit counts
    /// here (RMSE 0.268 against the CPU twin, 68% of receivers off by more than 0.1, at
    /// 160 x 120). Now the frame flags them (`CUT_BITS`, counted in its status) and the
    /// registry's GPU estimator redoes them with the CPU twin in the same view: its report's
    /// `frame_cpu_redo` counts exactly the receivers the frame left NaN (printed; on llvmpipe
    /// some must be), those receivers get the CPU twin's V bit for bit, the others the frame's,
    /// which agrees with the CPU twin on the frame's own maps (ties explained).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let mut scene = Scene::load(fixture_path("stacked")).unwrap();
        scene.set_resolution(40, 30).unwrap();
        let rec = Receivers::from_camera(&scene, &shadow_map_core::SceneBvh::new(&scene));
        let kv: Params = [
            ("resolution", "512"),
            ("variant", "exact"),
            ("kernel", "fixed"),
            ("k", "32"),
            ("layers", "3"),
        ]
        .iter()
        .map(|(k, v)| (*k, v.to_string()))
        .collect();
        let mut cpu = CpuAccumulation::new().unwrap();
        let mut gpu = self.gpu(ctx);
        configure(&mut cpu, &kv);
        configure(&mut *gpu, &kv);
        let cli = CliRun::new("accumulation", &mut cpu, &mut *gpu, &scene, &rec);
        let redone: usize =
            note(&cli.gpu_report, "frame_cpu_redo").map_or(0, |n| n.parse().unwrap());
        let fr = run_frame(ctx, &frame_for(ctx, &kv), &scene, &rec).expect("frame");
        let params = table(accumulation::settings::SPECS, &kv);
        let (_, st, left) = judge_on_maps("accumulation loop limit", &fr, &scene, &rec, &params)
            .unwrap_or_else(|e| panic!("{e}"));
        eprintln!(
            "loop limit: {} of {} receivers cut and redone on the CPU ({} outside); the rest \
             against the CPU twin on the frame's maps: max |dV| {:.2e}, {} beyond {}",
            left.cut,
            rec.len(),
            left.outside,
            st.max_dv,
            st.beyond,
            TWIN.abs
        );
        assert_eq!(redone, left.cut + left.unsettled, "frame_cpu_redo");
        if ctx.describe().contains("llvmpipe") {
            assert!(left.cut > 0, "llvmpipe's loop budget cut no receiver");
        }
        for k in 0..rec.len() {
            let (c, g, f) = (cli.cpu[k], cli.gpu[k], fr.v[k]);
            if !rec.active()[k] {
                assert!(c.is_nan() && g.is_nan(), "inactive receiver {k}");
            } else if f.is_nan() {
                assert_eq!(
                    g.to_bits(),
                    c.to_bits(),
                    "receiver {k} redone: CPU {c}, GPU {g}"
                );
            } else {
                assert_eq!(g.to_bits(), f.to_bits(), "receiver {k}: frame {f}, GPU {g}");
            }
        }
    }
}

/// At most one active receiver (a tie) where `gpu` is beyond [`TWIN`] of `cpu`: the count
/// printed under `label`, then asserted.
fn at_most_one_beyond(label: &str, rec: &Receivers, cpu: &[f32], gpu: &[f32]) {
    let beyond = (0..rec.len())
        .filter(|&k| rec.active()[k] && (gpu[k] - cpu[k]).abs() > TWIN.abs)
        .count();
    println!("{label}: {beyond} receivers beyond {}", TWIN.abs);
    assert!(
        beyond <= 1,
        "{label}: {beyond} receivers beyond {}",
        TWIN.abs
    );
}

/// The engine path prepared with the parameters `kv`.
fn frame_for(ctx: &Arc<GpuContext>, kv: &Params) -> AccumulationFrame {
    AccumulationFrame::prepare(ctx.clone(), &table(accumulation::settings::SPECS, kv))
        .expect("frame")
}

/// Every `fit` x `nearfar` combination on the fixed scene, through the CLI path on the CPU twin
/// and the registry's GPU estimator: V in [0, 1] for every active receiver (NaN for inactive
/// ones), the GPU within the tolerance of the CPU twin (at most one tie, as above), the engine
/// path fits the CPU twin's very view, and the choices reach the view: `nearfar` changes the
/// near/far notes, `fit` the window (`window_scale` 1 for `receivers`, up to 2 times the stable
/// fit's margins for `stable`).
#[test]
fn every_fit_and_nearfar_match_on_both_twins() {
    let Some(ctx) = test_support::gpu("every_fit_and_nearfar_match_on_both_twins") else {
        return;
    };
    let mut case = fixed_case();
    let (scene, rec) = case.scene.scene_and_receivers();
    let mut g = Accumulation.gpu(&ctx);
    let keys: Vec<&str> = g.params().specs().iter().map(|s| s.key).collect();
    assert!(
        keys.contains(&"fit") && keys.contains(&"nearfar"),
        "{keys:?}"
    );
    let mut planes = std::collections::HashMap::new();
    let mut scales = std::collections::HashMap::new();
    for (m, fit) in FITS.iter().enumerate() {
        for (j, nearfar) in NEARFARS.iter().enumerate() {
            case.settings.fit = fit;
            case.settings.nearfar = nearfar;
            // Both variants and the adaptive and fixed kernels, in turn.
            case.settings.variant = ["additive", "exact"][(m + j) % 2];
            case.settings.kernel = ["adaptive", "fixed", "lexels"][j];
            let kv = settings_kv(&case.settings, 1.0);
            let mut cpu = CpuAccumulation::new().unwrap();
            configure(&mut cpu, &kv);
            configure(&mut *g, &kv);
            let cli = CliRun::new("accumulation", &mut cpu, &mut *g, &scene, &rec);
            let (v_cpu, v_gpu, rc) = (&cli.cpu, &cli.gpu, &cli.cpu_report);
            for k in 0..rec.len() {
                let (c, x) = (v_cpu[k], v_gpu[k]);
                if !rec.active()[k] {
                    assert!(c.is_nan() && x.is_nan(), "{fit}/{nearfar}: inactive #{k}");
                    continue;
                }
                assert!(
                    (0.0..=1.0).contains(&c) && (0.0..=1.0).contains(&x),
                    "{fit}/{nearfar}: #{k} cpu {c} gpu {x}"
                );
            }
            at_most_one_beyond(&format!("{fit}/{nearfar}"), &rec, v_cpu, v_gpu);
            let own = cpu.light_space().expect("built").view;
            let views = frame_for(&ctx, &kv).fit_views(&scene, &rec).unwrap();
            assert_eq!(
                views,
                [Some(own)],
                "{fit}/{nearfar}: the engine path's view"
            );
            let ws: f32 = note(rc, "window_scale").unwrap().parse().unwrap();
            match *fit {
                "receivers" => assert!((ws - 1.0).abs() < 1e-4, "{fit}/{nearfar}: {ws}"),
                // At most 2 (power of two) x the 3-texel margins x one texel of snapping.
                "stable" => {
                    let r = case.settings.resolution as f32;
                    let max = 2.0 * (1.0 + 6.0 / r) * r / (r - 1.0);
                    assert!((1.0..=max).contains(&ws), "{fit}/{nearfar}: {ws}")
                }
                _ => assert!(ws >= 1.0 - 1e-4, "{fit}/{nearfar}: {ws}"),
            }
            planes.insert((m, j), (note(rc, "near"), note(rc, "far")));
            scales.insert((m, j), ws);
            println!(
                "{fit}/{nearfar}: near {:?} far {:?} window_scale {ws}",
                note(rc, "near"),
                note(rc, "far")
            );
        }
    }
    for m in 0..3 {
        assert!(
            planes[&(m, 0)] != planes[&(m, 1)] && planes[&(m, 0)] != planes[&(m, 2)],
            "nearfar did not change the planes ({})",
            FITS[m]
        );
    }
    for j in 0..3 {
        assert!(
            scales[&(2, j)] > scales[&(0, j)],
            "fit=stable did not change the window ({})",
            NEARFARS[j]
        );
    }
}

/// On the CPU twin and the registry's GPU estimator, receivers whose tangent plane cuts the light (a disk light centred in
/// their ground plane, a wall hiding the upper part of its front half; a rect light over a plane
/// tilted 85 degrees), so the front clipping of the casters' images, the exact variant's bits
/// behind the plane and the receiver-plane test all run; every variant and kernel, and
/// `receiver_plane=false`. The two agree within 2e-3 on all but 2% of the receivers.
#[test]
fn grazing_receivers_match_on_both_twins() {
    let Some(ctx) = test_support::gpu("grazing_receivers_match_on_both_twins") else {
        return;
    };
    let s1 = test_support::fixtures::grazing_wall(8, 8);
    let r1 = test_support::fixtures::ground_grid(12, 6, (-0.9, 0.08), (-0.5, 0.2));
    let (s2, r2, _) = test_support::fixtures::tilted_plane(85.0, 1.0, (10, -0.9, 0.18));
    let mut g = Accumulation.gpu(&ctx);
    for (name, scene, rec) in [("grazing", &s1, &r1), ("tilted", &s2, &r2)] {
        for variant in ["additive", "exact"] {
            for kernel in ["adaptive", "fixed"] {
                for plane in ["true", "false"] {
                    let kv = [
                        ("variant", variant),
                        ("kernel", kernel),
                        ("receiver_plane", plane),
                        ("resolution", "512"),
                    ];
                    let mut cpu = CpuAccumulation::new().unwrap();
                    configure(&mut cpu, &kv);
                    configure(&mut *g, &kv);
                    let (vc, _) = run(&mut cpu, scene, rec).unwrap();
                    let (vg, _) = run(&mut *g, scene, rec).unwrap();
                    let beyond = vc
                        .iter()
                        .zip(&vg)
                        .filter(|(a, b)| (**a - **b).abs() > 2e-3)
                        .count();
                    let worst = vc
                        .iter()
                        .zip(&vg)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0f32, f32::max);
                    println!("{name} {kv:?}: {beyond} beyond 2e-3, worst {worst:.2e}");
                    assert!(
                        beyond * 50 <= rec.len(),
                        "{name} {kv:?}: {beyond} of {} beyond 2e-3 (worst {worst})",
                        rec.len()
                    );
                }
            }
        }
    }
}
