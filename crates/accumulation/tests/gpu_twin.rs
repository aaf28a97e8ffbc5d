//! The GPU twin of the accumulation estimator against the CPU twin: given the CPU twin's own
//! light-space data (layers, MSSM), V must agree per receiver within [`TWIN_TOL`] on at least
//! [`TWIN_MIN_WITHIN`] of the receivers (the rule of `crates/baselines/tests/gpu_twins.rs`); each
//! receiver beyond must be a tie: nudging the depth threshold by [`TIE_NUDGE_REL`] of the depth
//! (through `bias`) or moving the receiver by [`SAMPLING_NUDGE_REL`] of its distance from the origin
//! changes the CPU's V or reproduces the GPU's (a caster centre on the footprint's edge, a bit on a
//! caster square's edge, a kernel bound on a texel edge). Rect, disk and sphere lights; additive
//! and exact; fixed, adaptive and lexels kernels; every light-view `fit` and `nearfar` choice.
//! Cases: 16 by default, `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]

use accumulation::{CpuAccumulation, GpuAccumulation};
use glam::Vec3;
use proptest::{
    prelude::*,
    test_runner::{TestCaseError, TestRunner},
};
use shadow_map_core::{
    gpu::{context_for_tests, GpuContext},
    light_space::LightSpace,
    run, Backend, Camera, Error, Light, LightShape, Receivers, Scene, SceneBvh,
    SoftShadowEstimator,
};
use std::{cell::RefCell, sync::Arc};

const TWIN_TOL: f32 = 1e-4;
const TWIN_MIN_WITHIN: f64 = 0.999;
const TIE_NUDGE_REL: f32 = 1e-5;
const SAMPLING_NUDGE_REL: f32 = 1e-6;

fn gpu(test: &str) -> Option<Arc<GpuContext>> {
    match context_for_tests(test) {
        Ok(c) => c,
        Err(e) => panic!("{test}: {e}"),
    }
}

fn cases() -> u32 {
    std::env::var("SOFTSHADOW_PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(16)
}

#[derive(Debug, Clone)]
struct LightSpec {
    shape: u32,
    size: (f32, f32),
    center: (f32, f32, f32),
    tilt: (f32, f32),
}

/// An axis-aligned box: centre (x, z) on the ground plane, sides, bottom height, height.
#[derive(Debug, Clone)]
struct BoxSpec {
    x: f32,
    z: f32,
    sx: f32,
    sz: f32,
    y0: f32,
    h: f32,
}

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

#[derive(Debug, Clone)]
struct Case {
    light: LightSpec,
    boxes: Vec<BoxSpec>,
    ground: Vec<(f32, f32)>,
    tops: Vec<(usize, f32, f32)>,
    inactive_every: Option<usize>,
    settings: Settings,
}

fn arb_light() -> impl Strategy<Value = LightSpec> {
    (
        0u32..3,
        (0.05f32..1.2, 0.05f32..1.2),
        (-1.0f32..1.0, 2.5f32..5.0, -1.0f32..1.0),
        (-0.4f32..0.4, -0.4f32..0.4),
    )
        .prop_map(|(shape, size, center, tilt)| LightSpec {
            shape,
            size,
            center,
            tilt,
        })
}

fn arb_box() -> impl Strategy<Value = BoxSpec> {
    (
        (-2.0f32..2.0, -2.0f32..2.0),
        (0.1f32..1.2, 0.1f32..1.2),
        (0.0f32..0.8, 0.05f32..0.5),
    )
        .prop_map(|((x, z), (sx, sz), (y0, h))| BoxSpec {
            x,
            z,
            sx,
            sz,
            y0,
            h,
        })
}

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
        (
            prop_oneof![1 => 0.0f32..0.02, 3 => 0.2f32..3.0],
            prop_oneof![1 => Just(0.0f32), 3 => 0.0f32..3.0],
        ),
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

fn arb_case() -> impl Strategy<Value = Case> {
    (
        arb_light(),
        prop::collection::vec(arb_box(), 0..4),
        prop::collection::vec((-3.5f32..3.5, -3.5f32..3.5), 1..160),
        prop::collection::vec((0usize..4, 0.0f32..1.0, 0.0f32..1.0), 0..12),
        prop::option::of(2usize..8),
        arb_settings(),
    )
        .prop_map(
            |(light, boxes, ground, tops, inactive_every, settings)| Case {
                light,
                boxes,
                ground,
                tops,
                inactive_every,
                settings,
            },
        )
}

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 5.0, 8.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 8,
        height: 8,
    }
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [[Vec3; 3]; 2] {
    [[a, b, c], [a, c, d]]
}

fn box_triangles(b: &BoxSpec) -> Vec<[Vec3; 3]> {
    let lo = Vec3::new(b.x - 0.5 * b.sx, b.y0, b.z - 0.5 * b.sz);
    let hi = Vec3::new(b.x + 0.5 * b.sx, b.y0 + b.h, b.z + 0.5 * b.sz);
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    // Outward-facing (counter-clockwise seen from outside) faces.
    let faces = [
        quad(
            p(false, true, false),
            p(false, true, true),
            p(true, true, true),
            p(true, true, false),
        ),
        quad(
            p(false, false, false),
            p(true, false, false),
            p(true, false, true),
            p(false, false, true),
        ),
        quad(
            p(false, false, false),
            p(false, false, true),
            p(false, true, true),
            p(false, true, false),
        ),
        quad(
            p(true, false, false),
            p(true, true, false),
            p(true, true, true),
            p(true, false, true),
        ),
        quad(
            p(false, false, false),
            p(false, true, false),
            p(true, true, false),
            p(true, false, false),
        ),
        quad(
            p(false, false, true),
            p(true, false, true),
            p(true, true, true),
            p(false, true, true),
        ),
    ];
    faces.into_iter().flatten().collect()
}

fn light_of(l: &LightSpec) -> Light {
    let normal = Vec3::new(l.tilt.0, -1.0, l.tilt.1).normalize();
    let (shape, tangent) = match l.shape {
        0 => (
            LightShape::Rect {
                size: [l.size.0, l.size.1],
            },
            (Vec3::X - Vec3::X.dot(normal) * normal).normalize(),
        ),
        1 => (
            LightShape::Disk {
                radius: 0.5 * l.size.0,
            },
            shadow_map_core::light::default_tangent(normal),
        ),
        _ => (
            LightShape::Sphere {
                radius: 0.5 * l.size.0,
            },
            shadow_map_core::light::default_tangent(normal),
        ),
    };
    Light {
        shape,
        center: Vec3::new(l.center.0, l.center.1, l.center.2),
        normal,
        tangent,
    }
}

fn scene_of(case: &Case) -> Scene {
    let ground = quad(
        Vec3::new(-4.0, 0.0, -4.0),
        Vec3::new(-4.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, -4.0),
    )
    .to_vec();
    let mut meshes = vec![(ground, 1.0)];
    for b in &case.boxes {
        meshes.push((box_triangles(b), 1.0));
    }
    match Scene::from_meshes("gpu-twins", camera(), light_of(&case.light), meshes) {
        Ok(s) => s,
        Err(e) => panic!("scene: {e}"),
    }
}

fn receivers_of(case: &Case) -> Receivers {
    let mut pos = Vec::new();
    let mut nrm = Vec::new();
    // Every other ground receiver near a box's shadow (within 1.5 box sides of its centre), so
    // penumbrae are well represented.
    for (i, &(x, z)) in case.ground.iter().enumerate() {
        let p = if i % 2 == 1 && !case.boxes.is_empty() {
            let b = &case.boxes[(i / 2) % case.boxes.len()];
            Vec3::new(b.x + x / 3.5 * 1.5 * b.sx, 0.0, b.z + z / 3.5 * 1.5 * b.sz)
        } else {
            Vec3::new(x, 0.0, z)
        };
        pos.push(p);
        nrm.push(Vec3::Y);
    }
    if !case.boxes.is_empty() {
        for &(k, u, v) in &case.tops {
            let b = &case.boxes[k % case.boxes.len()];
            pos.push(Vec3::new(
                b.x + (u - 0.5) * b.sx,
                b.y0 + b.h,
                b.z + (v - 0.5) * b.sz,
            ));
            nrm.push(Vec3::Y);
        }
    }
    let mut r = match Receivers::from_points(pos, nrm) {
        Ok(r) => r,
        Err(e) => panic!("receivers: {e}"),
    };
    if let Some(m) = case.inactive_every {
        for (k, a) in r.active.iter_mut().enumerate() {
            if k > 0 && k % m == m - 1 {
                *a = false;
            }
        }
    }
    r
}

fn settings_kv(s: &Settings, bias: f32) -> Vec<(&'static str, String)> {
    vec![
        ("resolution", s.resolution.to_string()),
        ("k", s.k.to_string()),
        ("variant", s.variant.to_string()),
        ("kernel", s.kernel.to_string()),
        ("bits", s.bits.to_string()),
        ("layers", s.layers.to_string()),
        ("sphere", s.sphere.to_string()),
        ("coverage", s.coverage.to_string()),
        ("bias", bias.to_string()),
        ("slope_bias", s.slope_bias.to_string()),
        ("fit", s.fit.to_string()),
        ("nearfar", s.nearfar.to_string()),
    ]
}

fn configured<E: SoftShadowEstimator + ?Sized>(e: &mut E, kv: &[(&'static str, String)]) {
    for (k, v) in kv {
        if let Err(err) = e.set_param(k, v) {
            panic!("set {k}={v}: {err}");
        }
    }
}

/// The CPU twin's V on given light-space data, with the depth bias `bias`.
fn cpu_on(ls: &LightSpace, scene: &Scene, rec: &Receivers, s: &Settings, bias: f32) -> Vec<f32> {
    let mut e = CpuAccumulation::new().expect("cpu twin");
    configured(&mut e, &settings_kv(s, bias));
    let mut v = vec![0.5; rec.len()];
    e.estimate_with(ls, scene, rec, &mut v)
        .expect("cpu estimate");
    v
}

/// True when moving receiver k by a few f32 ulps (four directions) changes the CPU's V by more
/// than the tolerance or brings it within the tolerance of the GPU's.
fn sampling_tie(
    ls: &LightSpace,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    k: usize,
    c: f32,
    g: f32,
) -> bool {
    let p = rec.position[k];
    let d = SAMPLING_NUDGE_REL * p.length().max(1.0);
    let pos: Vec<Vec3> = [Vec3::X, -Vec3::X, Vec3::Z, -Vec3::Z, Vec3::Y, -Vec3::Y]
        .iter()
        .map(|e| p + *e * d)
        .collect();
    let r2 = Receivers::from_points(pos, vec![rec.normal[k]; 6]).expect("nudged receivers");
    cpu_on(ls, scene, &r2, s, s.bias)
        .iter()
        .any(|v| (v - c).abs() > TWIN_TOL || (v - g).abs() <= TWIN_TOL)
}

#[derive(Debug, Default, Clone, Copy)]
struct Stats {
    receivers: usize,
    beyond: usize,
    ties: usize,
    max_dv: f32,
    classes: [usize; 3],
}

fn check_case(case: &Case, gpu: &mut GpuAccumulation, stats: &mut Stats) -> Result<(), String> {
    let scene = scene_of(case);
    let rec = receivers_of(case);
    let s = &case.settings;
    let mut cpu = CpuAccumulation::new().expect("cpu twin");
    configured(&mut cpu, &settings_kv(s, s.bias));
    let (v_cpu, _) = match run(&mut cpu, &scene, &rec) {
        Ok(x) => x,
        // The documented refusal (lit receivers outside the one frustum): the GPU twin must
        // refuse the same scene the same way.
        Err(Error::Receivers(msg)) => {
            configured(gpu, &settings_kv(s, s.bias));
            return match run(gpu, &scene, &rec) {
                Err(Error::Receivers(_)) => Ok(()),
                Err(e) => Err(format!("cpu refused ({msg}), gpu: {e}")),
                Ok(_) => Err(format!("cpu refused ({msg}), gpu did not")),
            };
        }
        Err(e) => return Err(format!("cpu: {e}")),
    };
    let ls = cpu.light_space().ok_or("no light space")?;
    configured(gpu, &settings_kv(s, s.bias));
    let mut v_gpu = vec![0.5f32; rec.len()];
    gpu.estimate_with(ls, &scene, &rec, &mut v_gpu)
        .map_err(|e| format!("gpu: {e}"))?;
    let mut beyond = Vec::new();
    let mut n = 0usize;
    for k in 0..rec.len() {
        let (c, g) = (v_cpu[k], v_gpu[k]);
        if !rec.active[k] {
            if !(c.is_nan() && g.is_nan()) {
                return Err(format!("inactive receiver {k}: cpu {c}, gpu {g}"));
            }
            continue;
        }
        if !(0.0..=1.0).contains(&g) {
            return Err(format!("receiver {k}: gpu V {g} outside [0, 1]"));
        }
        n += 1;
        stats.classes[if c <= 0.0 {
            0
        } else if c < 1.0 {
            1
        } else {
            2
        }] += 1;
        let d = (c - g).abs();
        stats.max_dv = stats.max_dv.max(d);
        if d > TWIN_TOL {
            beyond.push(k);
        }
    }
    stats.receivers += n;
    stats.beyond += beyond.len();
    if beyond.is_empty() {
        return Ok(());
    }
    let view = ls.view;
    let nudge = TIE_NUDGE_REL * view.n * view.r as f32 / view.w;
    let nudged: Vec<Vec<f32>> = [s.bias + nudge, (s.bias - nudge).max(0.0)]
        .iter()
        .map(|&b| cpu_on(ls, &scene, &rec, s, b))
        .collect();
    let mut unexplained = Vec::new();
    for &k in &beyond {
        let (c, g) = (v_cpu[k], v_gpu[k]);
        let tie = nudged
            .iter()
            .any(|v| (v[k] - c).abs() > TWIN_TOL || (v[k] - g).abs() <= TWIN_TOL)
            || sampling_tie(ls, &scene, &rec, s, k, c, g);
        if tie {
            stats.ties += 1;
        } else {
            unexplained.push(format!(
                "#{k}: p {:?} cpu {c} gpu {g} |dV| {:.3e}",
                rec.position[k],
                (c - g).abs()
            ));
        }
    }
    let allowed = ((1.0 - TWIN_MIN_WITHIN) * n as f64).ceil() as usize;
    if !unexplained.is_empty() || beyond.len() > allowed {
        return Err(format!(
            "{} of {n} receivers beyond |dV| {TWIN_TOL} ({allowed} allowed), not ties:\n{}",
            beyond.len(),
            unexplained.join("\n")
        ));
    }
    Ok(())
}

#[test]
fn gpu_twin_matches_cpu_twin_on_random_scenes() {
    let Some(ctx) = gpu("gpu_twin_matches_cpu_twin_on_random_scenes") else {
        return;
    };
    let twin = RefCell::new(GpuAccumulation::new(ctx).expect("gpu twin"));
    let stats = RefCell::new(Stats::default());
    let mut runner = TestRunner::new(ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    });
    let result = runner.run(&arb_case(), |case| {
        let mut st = Stats::default();
        check_case(&case, &mut twin.borrow_mut(), &mut st).map_err(TestCaseError::fail)?;
        let mut all = stats.borrow_mut();
        all.receivers += st.receivers;
        all.beyond += st.beyond;
        all.ties += st.ties;
        all.max_dv = all.max_dv.max(st.max_dv);
        for (a, b) in all.classes.iter_mut().zip(st.classes) {
            *a += b;
        }
        Ok(())
    });
    let st = *stats.borrow();
    println!(
        "accumulation twin: {} receivers, {} beyond {TWIN_TOL} ({} ties), max |dV| {:.3e}, \
         classes (umbra, penumbra, lit) {:?}",
        st.receivers, st.beyond, st.ties, st.max_dv, st.classes
    );
    if let Err(e) = result {
        panic!("{e}");
    }
    let within = 1.0 - st.beyond as f64 / st.receivers.max(1) as f64;
    assert!(within >= TWIN_MIN_WITHIN, "{within}");
    assert!(st.classes[1] > 0, "no penumbra receiver was compared");
}

/// The fixed scene of the focused tests: a sphere light over two boxes, a line of ground
/// receivers through their shadows, two box tops, every seventh receiver inactive.
fn fixed_case() -> Case {
    Case {
        light: LightSpec {
            shape: 2,
            size: (0.8, 0.8),
            center: (0.2, 3.0, -0.1),
            tilt: (0.1, -0.05),
        },
        boxes: vec![
            BoxSpec {
                x: 0.0,
                z: 0.0,
                sx: 0.8,
                sz: 0.6,
                y0: 0.5,
                h: 0.3,
            },
            BoxSpec {
                x: 0.3,
                z: 0.2,
                sx: 0.5,
                sz: 0.5,
                y0: 1.2,
                h: 0.1,
            },
        ],
        ground: (0..200)
            .map(|k| (-2.0 + 0.02 * k as f32, -1.0 + 0.01 * k as f32))
            .collect(),
        tops: vec![(0, 0.5, 0.5), (0, 0.1, 0.9)],
        inactive_every: Some(7),
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

/// Every variant x kernel combination on one fixed scene with a sphere light, through the CLI
/// path (`build` + `estimate`), chunked and not: bit-identical across chunking, within the
/// tolerance of the CPU twin.
#[test]
fn cli_path_every_mode_and_chunking_match() {
    let Some(ctx) = gpu("cli_path_every_mode_and_chunking_match") else {
        return;
    };
    let mut case = fixed_case();
    let mut g = GpuAccumulation::new(ctx).expect("gpu twin");
    assert_eq!(g.backend(), Backend::Gpu);
    assert_eq!(g.name(), "accumulation");
    assert_eq!(g.params(), CpuAccumulation::new().unwrap().params());
    let scene = scene_of(&case);
    let rec = receivers_of(&case);
    let mut penumbra = 0;
    for variant in ["additive", "exact"] {
        for kernel in ["fixed", "adaptive", "lexels"] {
            case.settings.variant = variant;
            case.settings.kernel = kernel;
            let kv = settings_kv(&case.settings, 1.0);
            let mut cpu = CpuAccumulation::new().unwrap();
            configured(&mut cpu, &kv);
            let (v_cpu, _) = run(&mut cpu, &scene, &rec).expect("cpu run");
            configured(&mut g, &kv);
            g.set_max_chunk(usize::MAX);
            let (v1, _) = run(&mut g, &scene, &rec).expect("gpu run");
            g.set_max_chunk(13);
            let (v2, _) = run(&mut g, &scene, &rec).expect("gpu run chunked");
            let mut beyond = 0;
            for k in 0..rec.len() {
                if !rec.active[k] {
                    assert!(v1[k].is_nan() && v2[k].is_nan());
                    continue;
                }
                assert_eq!(v1[k].to_bits(), v2[k].to_bits(), "chunking changed #{k}");
                if (v1[k] - v_cpu[k]).abs() > TWIN_TOL {
                    beyond += 1;
                }
                if v_cpu[k] > 0.0 && v_cpu[k] < 1.0 {
                    penumbra += 1;
                }
            }
            assert!(
                beyond <= 1,
                "{variant}/{kernel}: {beyond} receivers beyond {TWIN_TOL}"
            );
        }
    }
    assert!(
        penumbra > 50,
        "the scene should have penumbrae ({penumbra})"
    );
}

/// A report note's value.
fn note(r: &shadow_map_core::Report, key: &str) -> Option<String> {
    r.notes.iter().find(|n| n.0 == key).map(|n| n.1.clone())
}

/// Every `fit` x `nearfar` combination on the fixed scene, through the CLI path on both twins:
/// V in [0, 1] for every active receiver (NaN for inactive ones), the GPU twin within
/// [`TWIN_TOL`] of the CPU twin (at most one tie, as above), and the choices reach the view:
/// `nearfar` changes the near/far notes, `fit` the window (`window_scale` 1 for `receivers`, up to
/// 2 times the stable fit's margins for `stable`).
#[test]
fn every_fit_and_nearfar_match_on_both_twins() {
    let Some(ctx) = gpu("every_fit_and_nearfar_match_on_both_twins") else {
        return;
    };
    let mut case = fixed_case();
    let scene = scene_of(&case);
    let rec = receivers_of(&case);
    let mut g = GpuAccumulation::new(ctx).expect("gpu twin");
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
            configured(&mut cpu, &kv);
            let (v_cpu, rc) = run(&mut cpu, &scene, &rec).expect("cpu run");
            configured(&mut g, &kv);
            let (v_gpu, rg) = run(&mut g, &scene, &rec).expect("gpu run");
            let mut beyond = 0;
            for k in 0..rec.len() {
                let (c, x) = (v_cpu[k], v_gpu[k]);
                if !rec.active[k] {
                    assert!(c.is_nan() && x.is_nan(), "{fit}/{nearfar}: inactive #{k}");
                    continue;
                }
                assert!(
                    (0.0..=1.0).contains(&c) && (0.0..=1.0).contains(&x),
                    "{fit}/{nearfar}: #{k} cpu {c} gpu {x}"
                );
                if (c - x).abs() > TWIN_TOL {
                    beyond += 1;
                }
            }
            assert!(
                beyond <= 1,
                "{fit}/{nearfar}: {beyond} receivers beyond {TWIN_TOL}"
            );
            for key in ["near", "far", "window_scale"] {
                assert_eq!(note(&rc, key), note(&rg, key), "{fit}/{nearfar}: {key}");
            }
            let ws: f32 = note(&rc, "window_scale").unwrap().parse().unwrap();
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
            planes.insert((m, j), (note(&rc, "near"), note(&rc, "far")));
            scales.insert((m, j), ws);
            println!(
                "{fit}/{nearfar}: near {:?} far {:?} window_scale {ws}",
                note(&rc, "near"),
                note(&rc, "far")
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

/// A kernel heavy enough to spend llvmpipe's loop budget (65535 iterations per invocation):
/// `variant=exact`, K = 32 fixed taps, 3 layers, 16 x 16 bits on the stacked fixture. Before the
/// kernel probed for it, lavapipe silently returned truncated bit counts here (RMSE 0.268 against
/// the CPU twin, 68% of receivers off by more than 0.1, at 160 x 120). Now flagged receivers are
/// redone with the CPU code: V must equal the CPU twin's exactly, on any device; on lavapipe the
/// report's `loop_limit_cpu_fallbacks` counts them (printed).
#[test]
fn loop_limit_is_detected_and_redone_not_truncated() {
    let Some(ctx) = gpu("loop_limit_is_detected_and_redone_not_truncated") else {
        return;
    };
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/stacked/stacked.toml"
    );
    let mut scene = Scene::load(path).unwrap();
    scene.camera.width = 40;
    scene.camera.height = 30;
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut cpu = CpuAccumulation::new().unwrap();
    let mut gpu = GpuAccumulation::new(ctx).unwrap();
    for (k, v) in [
        ("resolution", "512"),
        ("variant", "exact"),
        ("kernel", "fixed"),
        ("k", "32"),
        ("layers", "3"),
    ] {
        cpu.set_param(k, v).unwrap();
        gpu.set_param(k, v).unwrap();
    }
    let (vc, _) = shadow_map_core::run(&mut cpu, &scene, &rec).unwrap();
    let (vg, report) = shadow_map_core::run(&mut gpu, &scene, &rec).unwrap();
    let fallbacks = report
        .notes
        .iter()
        .find(|(k, _)| k == "loop_limit_cpu_fallbacks")
        .map(|(_, v)| v.clone())
        .unwrap_or_else(|| "0".into());
    eprintln!(
        "loop-limit CPU fallbacks: {fallbacks} of {} receivers",
        rec.len()
    );
    for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
        assert!(
            a.to_bits() == b.to_bits() || (a - b).abs() <= 1e-6,
            "receiver {k}: CPU {a}, GPU {b}"
        );
    }
}
