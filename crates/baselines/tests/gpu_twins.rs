//! The GPU twins of the baselines against their CPU twins (one test binary).
//!
//! Given identical light-space data (the CPU `LightSpace`), each GPU twin must reproduce its CPU
//! twin per receiver within [`TWIN_TOL`] on at least [`TWIN_MIN_WITHIN`] of the receivers, and
//! every receiver beyond it must be a depth-comparison tie ([`TIE_NUDGE_REL`]). The CLI path
//! (`build` + `estimate`) is checked on a fixture by RMSE ([`CLI_RMSE_MAX`]).
//!
//! GPU tests run on the shared Vulkan context; with no adapter they print a loud skip, or fail
//! under `SOFTSHADOW_REQUIRE_GPU=1`. Random cases: 24 by default, `SOFTSHADOW_PROPTEST_CASES=N`
//! for more.
#![cfg(feature = "gpu")]

use baselines::{
    gpu::{GpuHardShadow, GpuMultiSample, GpuPcfShadow, GpuPcssShadow},
    HardShadow, MultiSample, PcfShadow, PcssShadow,
};
use glam::{Vec2, Vec3};
use proptest::{
    prelude::*,
    test_runner::{FileFailurePersistence, TestCaseError, TestRunner},
};
use shadow_map_core::{
    gpu::{context_for_tests, GpuContext},
    light::default_tangent,
    light_space::LightSpace,
    run, Backend, Camera, Error, Light, LightShape, Receivers, Scene, SceneBvh,
    SoftShadowEstimator,
};
use std::{cell::RefCell, sync::Arc};

/// Per-receiver twin tolerance on V (V is a fraction of the light's area in [0, 1]).
const TWIN_TOL: f32 = 1e-4;
/// Fraction of active receivers that must lie within [`TWIN_TOL`] over the whole run; a single
/// case may have at most `ceil((1 - TWIN_MIN_WITHIN) n)` of its n active receivers beyond it.
const TWIN_MIN_WITHIN: f64 = 0.999;
/// A receiver beyond [`TWIN_TOL`] is explained as a depth-comparison tie when moving the CPU
/// twin's depth threshold `z - eps` by this fraction of the receiver's depth (through the `bias`
/// parameter, up or down) either changes the CPU twin's V by more than [`TWIN_TOL`] or brings it
/// within [`TWIN_TOL`] of the GPU twin. f32 depths carry 6e-8 relative rounding, so 1e-5 is a
/// generous but still microscopic nudge. (Multi-sample: the bias change is the largest any
/// sub-light view needs for that.)
const TIE_NUDGE_REL: f32 = 1e-5;
/// How far a receiver is moved, relative to its distance from the origin, to show a sampling tie
/// (see `sampling_tie`): a few f32 ulps.
const SAMPLING_NUDGE_REL: f32 = 1e-6;
/// RMSE of V between the twins on the fixture through the CLI path (`build` + `estimate`).
const CLI_RMSE_MAX: f64 = 1e-3;

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The shared context; `None` only after the loud skip (no adapter, GPU not required).
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
        .unwrap_or(24)
}

// ---------------------------------------------------------------------------------------------
// Random scenes

#[derive(Debug, Clone)]
struct LightSpec {
    /// 0 rect, 1 disk, 2 sphere.
    shape: u8,
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

#[derive(Debug, Clone)]
struct Case {
    light: LightSpec,
    boxes: Vec<BoxSpec>,
    /// Ground points (x, z), normal +y.
    ground: Vec<(f32, f32)>,
    /// Points on box tops: (box index, u, v) in [0, 1]^2 of the top face.
    tops: Vec<(usize, f32, f32)>,
    /// Ground points with a normal nearly perpendicular to the direction to the light:
    /// (x, z, tilt towards the light, angle around it).
    grazing: Vec<(f32, f32, f32, f32)>,
    /// 0: above the light plane (behind it), 1: far out (outside the frustum), 2: under the
    /// ground facing down.
    outside: Vec<(u8, f32, f32)>,
    /// Every m-th receiver inactive.
    inactive_every: Option<usize>,
    settings: Settings,
}

fn arb_light() -> impl Strategy<Value = LightSpec> {
    (
        prop_oneof![Just(0u8), Just(1u8), Just(2u8)],
        (0.05f32..1.5, 0.05f32..1.5),
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
        (0.0f32..1.5, 0.05f32..0.8),
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
        16u32..=256,
        // A quarter of the cases in the acne regime (almost no bias), where depth ties abound.
        (
            prop_oneof![1 => 0.0f32..0.02, 3 => 0.2f32..3.0],
            prop_oneof![1 => Just(0.0f32), 3 => 0.0f32..3.0],
        ),
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

fn arb_case() -> impl Strategy<Value = Case> {
    (
        arb_light(),
        prop::collection::vec(arb_box(), 0..4),
        prop::collection::vec((-3.5f32..3.5, -3.5f32..3.5), 1..160),
        prop::collection::vec((0usize..4, 0.0f32..1.0, 0.0f32..1.0), 0..12),
        prop::collection::vec(
            (-3.5f32..3.5, -3.5f32..3.5, -0.05f32..0.05, 0.0f32..6.3),
            0..16,
        ),
        prop::collection::vec((0u8..3, -1.0f32..1.0, -1.0f32..1.0), 0..6),
        prop::option::of(2usize..8),
        arb_settings(),
    )
        .prop_map(
            |(light, boxes, ground, tops, grazing, outside, inactive_every, settings)| Case {
                light,
                boxes,
                ground,
                tops,
                grazing,
                outside,
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
    let center = Vec3::new(l.center.0, l.center.1, l.center.2);
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
            default_tangent(normal),
        ),
        _ => (
            LightShape::Sphere {
                radius: 0.5 * l.size.0,
            },
            default_tangent(normal),
        ),
    };
    Light {
        shape,
        center,
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

fn receivers_of(case: &Case, light: &Light) -> Receivers {
    let mut pos = Vec::new();
    let mut nrm = Vec::new();
    for &(x, z) in &case.ground {
        pos.push(Vec3::new(x, 0.0, z));
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
    for &(x, z, s, a) in &case.grazing {
        let p = Vec3::new(x, 0.0, z);
        let d = (light.center - p).normalize();
        let t1 = default_tangent(d);
        let t2 = d.cross(t1);
        let q = t1 * a.cos() + t2 * a.sin();
        pos.push(p);
        nrm.push((q + s * d).normalize());
    }
    for &(kind, x, z) in &case.outside {
        match kind {
            0 => {
                pos.push(light.center + Vec3::new(x, 0.5 + z.abs(), z));
                nrm.push(if x > 0.0 { Vec3::Y } else { -Vec3::Y });
            }
            1 => {
                pos.push(Vec3::new(
                    x.signum() * (60.0 + 140.0 * x.abs()),
                    0.0,
                    50.0 * z,
                ));
                nrm.push(Vec3::Y);
            }
            _ => {
                pos.push(Vec3::new(3.0 * x, -0.5, 3.0 * z));
                nrm.push(-Vec3::Y);
            }
        }
    }
    let mut r = match Receivers::from_points(pos, nrm) {
        Ok(r) => r,
        Err(e) => panic!("receivers: {e}"),
    };
    if let Some(m) = case.inactive_every {
        for (k, a) in r.active.iter_mut().enumerate() {
            // Keep the first receiver (a ground point) active so the light view can be fitted.
            if k > 0 && k % m == m - 1 {
                *a = false;
            }
        }
    }
    r
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

/// The GPU twins, compiled once per test.
struct GpuTwins {
    hard: GpuHardShadow,
    pcf: GpuPcfShadow,
    pcss: GpuPcssShadow,
    ms: GpuMultiSample,
}

impl GpuTwins {
    fn new(ctx: &Arc<GpuContext>) -> Result<Self, Error> {
        Ok(GpuTwins {
            hard: GpuHardShadow::new(ctx.clone())?,
            pcf: GpuPcfShadow::new(ctx.clone())?,
            pcss: GpuPcssShadow::new(ctx.clone())?,
            ms: GpuMultiSample::new(ctx.clone())?,
        })
    }
    fn get(&mut self, w: Which) -> &mut dyn SoftShadowEstimator {
        match w {
            Which::Hard => &mut self.hard,
            Which::Pcf => &mut self.pcf,
            Which::Pcss => &mut self.pcss,
            Which::MultiSample => &mut self.ms,
        }
    }
}

fn settings_kv(w: Which, s: &Settings, bias: f32) -> Vec<(&'static str, String)> {
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

fn set_all(est: &mut dyn SoftShadowEstimator, kv: &[(&'static str, String)]) -> Result<(), Error> {
    for (k, v) in kv {
        est.set_param(k, v)?;
    }
    Ok(())
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
            set_all(&mut e, &kv)?;
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
            set_all(&mut e, &kv)?;
            let (v, _) = run(&mut e, scene, rec)?;
            // The same sub-light maps the CPU twin builds inside `estimate` (deterministic).
            let req = baselines::common::map_request(e.params());
            assert_eq!(req.resolution, s.resolution);
            let seed = s.seed as u64;
            let maps: Vec<Result<LightSpace, Error>> = scene
                .light
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
        .map(|ls| TIE_NUDGE_REL * ls.view.n * ls.view.r as f32 / ls.view.w)
        .fold(0.0f32, f32::max);
    Ok(CpuRun {
        v,
        maps,
        q16,
        nudge,
    })
}

fn run_gpu_with(
    twins: &mut GpuTwins,
    w: Which,
    cpu: CpuRun,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
) -> Result<Vec<f32>, Error> {
    let mut v = vec![0.5f32; rec.len()];
    set_all(twins.get(w), &settings_kv(w, s, s.bias))?;
    let light = &scene.light;
    let mut maps = cpu.maps.into_iter();
    if let Some(q) = &cpu.q16 {
        // Identical 16-bit codes on both sides (the encoder itself is checked bit for bit in
        // shadow-map-core's gpu_precision test).
        let ls = first(&mut maps)?;
        match w {
            Which::Hard => twins
                .hard
                .estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            Which::Pcf => twins
                .pcf
                .estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            Which::Pcss => twins
                .pcss
                .estimate_with_unorm16(&ls, q, light, rec, &mut v)?,
            Which::MultiSample => {
                return Err(Error::LightView("multi-sample keeps no 16-bit map".into()))
            }
        }
        return Ok(v);
    }
    match w {
        Which::Hard => twins
            .hard
            .estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        Which::Pcf => twins
            .pcf
            .estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        Which::Pcss => twins
            .pcss
            .estimate_with(&first(&mut maps)?, light, rec, &mut v)?,
        Which::MultiSample => twins.ms.estimate_with(maps, light, rec, &mut v)?,
    }
    Ok(v)
}

fn first(maps: &mut impl Iterator<Item = Result<LightSpace, Error>>) -> Result<LightSpace, Error> {
    maps.next()
        .unwrap_or_else(|| Err(Error::LightView("no light space".into())))
}

// ---------------------------------------------------------------------------------------------
// Comparison

/// Per-baseline statistics over a run.
#[derive(Debug, Default, Clone, Copy)]
struct Stats {
    receivers: usize,
    beyond: usize,
    max_dv: f32,
    /// CPU V == 0, 0 < V < 1, V == 1: the run must visit umbra, penumbra and lit receivers.
    classes: [usize; 3],
}

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
    let p = rec.position[k];
    let d = SAMPLING_NUDGE_REL * p.length().max(1.0);
    let mut pos = rec.position.clone();
    let mut nrm = rec.normal.clone();
    let extra = [
        glam::Vec3::X * d,
        -glam::Vec3::X * d,
        glam::Vec3::Z * d,
        -glam::Vec3::Z * d,
    ];
    for e in extra {
        pos.push(p + e);
        nrm.push(rec.normal[k]);
    }
    let mut r2 = Receivers::from_points(pos, nrm).map_err(|e| e.to_string())?;
    r2.active[..rec.len()].copy_from_slice(&rec.active);
    let v = run_cpu(w, scene, &r2, s, s.bias)
        .map_err(|e| format!("{w:?}: nudged receiver run: {e}"))?
        .v;
    Ok(v[rec.len()..].iter().any(|x| (x - c).abs() > TWIN_TOL))
}

fn compare(
    w: Which,
    scene: &Scene,
    rec: &Receivers,
    s: &Settings,
    v_cpu: &[f32],
    v_gpu: &[f32],
    nudge: f32,
) -> Result<Stats, String> {
    let mut st = Stats::default();
    let mut beyond = Vec::new();
    for k in 0..rec.len() {
        let (c, g) = (v_cpu[k], v_gpu[k]);
        if !rec.active[k] {
            if !(c.is_nan() && g.is_nan()) {
                return Err(format!(
                    "{w:?}: inactive receiver {k}: cpu {c}, gpu {g} (want NaN)"
                ));
            }
            continue;
        }
        if !(0.0..=1.0).contains(&g) {
            return Err(format!(
                "{w:?}: receiver {k}: gpu V = {g} outside [0, 1] (cpu {c})"
            ));
        }
        st.receivers += 1;
        st.classes[if c <= 0.0 {
            0
        } else if c < 1.0 {
            1
        } else {
            2
        }] += 1;
        let d = (c - g).abs();
        st.max_dv = st.max_dv.max(d);
        if d > TWIN_TOL {
            beyond.push(k);
        }
    }
    st.beyond = beyond.len();
    if beyond.is_empty() {
        return Ok(st);
    }
    // Explain each receiver beyond the tolerance as a depth-comparison tie.
    let nudged: Vec<Vec<f32>> = [s.bias + nudge, (s.bias - nudge).max(0.0)]
        .iter()
        .map(|&b| run_cpu(w, scene, rec, s, b).map(|r| r.v))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{w:?}: nudged CPU run: {e}"))?;
    let mut unexplained = Vec::new();
    let mut lines = Vec::new();
    beyond.sort_by(|&a, &b| {
        (v_cpu[b] - v_gpu[b])
            .abs()
            .total_cmp(&(v_cpu[a] - v_gpu[a]).abs())
    });
    for &k in &beyond {
        let (c, g) = (v_cpu[k], v_gpu[k]);
        let flips = nudged.iter().any(|n| (n[k] - c).abs() > TWIN_TOL);
        let reproduces = nudged.iter().any(|n| (n[k] - g).abs() <= TWIN_TOL);
        let sampling = !(flips || reproduces) && sampling_tie(w, scene, rec, s, k, c)?;
        if !(flips || reproduces || sampling) {
            unexplained.push(k);
        }
        if lines.len() < 12 {
            lines.push(format!(
                "  #{k}: p {:?} n {:?} cpu {c} gpu {g} |dV| {:.3e} nudged(+,-) {} {} -> {}",
                rec.position[k],
                rec.normal[k],
                (c - g).abs(),
                nudged[0][k],
                nudged[1][k],
                if flips || reproduces {
                    "tie"
                } else if sampling {
                    "sampling tie"
                } else {
                    "NOT A TIE"
                }
            ));
        }
    }
    let within = 1.0 - st.beyond as f64 / st.receivers.max(1) as f64;
    let allowed = ((1.0 - TWIN_MIN_WITHIN) * st.receivers as f64).ceil() as usize;
    if !unexplained.is_empty() || st.beyond > allowed {
        return Err(format!(
            "{w:?}: {} of {} receivers beyond |dV| {TWIN_TOL} ({:.4}% within, {} allowed), {} not \
             depth or sampling ties; worst:\n{}",
            st.beyond,
            st.receivers,
            100.0 * within,
            allowed,
            unexplained.len(),
            lines.join("\n")
        ));
    }
    Ok(st)
}

fn check_case(case: &Case, twins: &mut GpuTwins, stats: &mut [Stats; 4]) -> Result<(), String> {
    let scene = scene_of(case);
    let rec = receivers_of(case, &scene.light);
    for (i, w) in ALL.into_iter().enumerate() {
        let s = &case.settings;
        let cpu = run_cpu(w, &scene, &rec, s, s.bias).map_err(|e| format!("{w:?} cpu: {e}"))?;
        let v_cpu = cpu.v.clone();
        let nudge = cpu.nudge;
        let v_gpu =
            run_gpu_with(twins, w, cpu, &scene, &rec, s).map_err(|e| format!("{w:?} gpu: {e}"))?;
        let st = compare(w, &scene, &rec, s, &v_cpu, &v_gpu, nudge)?;
        stats[i].receivers += st.receivers;
        stats[i].beyond += st.beyond;
        stats[i].max_dv = stats[i].max_dv.max(st.max_dv);
        for (a, b) in stats[i].classes.iter_mut().zip(st.classes) {
            *a += b;
        }
    }
    Ok(())
}

#[test]
fn gpu_twins_match_cpu_twins_on_random_scenes() {
    let Some(ctx) = gpu("gpu_twins_match_cpu_twins_on_random_scenes") else {
        return;
    };
    let twins = match GpuTwins::new(&ctx) {
        Ok(t) => RefCell::new(t),
        Err(e) => panic!("GPU twins: {e}"),
    };
    let stats = RefCell::new([Stats::default(); 4]);
    let mut runner = TestRunner::new(ProptestConfig {
        cases: cases(),
        source_file: Some(file!()),
        // Enough to shrink a failure down to a scene of a few receivers and no boxes.
        max_shrink_iters: 4096,
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource("regressions"))),
        ..ProptestConfig::default()
    });
    let result = runner.run(&arb_case(), |case| {
        check_case(&case, &mut twins.borrow_mut(), &mut stats.borrow_mut())
            .map_err(TestCaseError::fail)
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    for (w, st) in ALL.iter().zip(stats.borrow().iter()) {
        let frac = st.beyond as f64 / st.receivers.max(1) as f64;
        eprintln!(
            "{w:?}: {} receivers (V = 0: {}, 0 < V < 1: {}, V = 1: {}), max |dV| {:.3e}, beyond \
             {TWIN_TOL}: {} ({:.5}%)",
            st.receivers,
            st.classes[0],
            st.classes[1],
            st.classes[2],
            st.max_dv,
            st.beyond,
            100.0 * frac
        );
        assert!(
            1.0 - frac >= TWIN_MIN_WITHIN,
            "{w:?}: {:.5}% beyond",
            100.0 * frac
        );
        // Hard is binary; every other baseline must also have met penumbrae.
        let partial_needed = *w != Which::Hard;
        assert!(
            st.classes[0] > 0 && st.classes[2] > 0 && (st.classes[1] > 0 || !partial_needed),
            "{w:?}: a vacuous run: {:?}",
            st.classes
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Fixed cases

fn small_case() -> Case {
    Case {
        light: LightSpec {
            shape: 0,
            size: (0.8, 0.6),
            center: (0.1, 3.0, -0.2),
            tilt: (0.1, -0.05),
        },
        boxes: vec![BoxSpec {
            x: 0.2,
            z: 0.1,
            sx: 0.8,
            sz: 0.6,
            y0: 1.0,
            h: 0.3,
        }],
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

#[test]
fn inactive_receivers_are_nan_on_gpu() {
    let Some(ctx) = gpu("inactive_receivers_are_nan_on_gpu") else {
        return;
    };
    let case = small_case();
    let scene = scene_of(&case);
    let rec = receivers_of(&case, &scene.light);
    assert!(rec.active.iter().any(|a| !a));
    let mut twins = GpuTwins::new(&ctx).unwrap();
    for w in ALL {
        let est = twins.get(w);
        set_all(est, &settings_kv(w, &case.settings, case.settings.bias)).unwrap();
        let (v, _) = run(est, &scene, &rec).unwrap();
        for (k, (x, a)) in v.iter().zip(&rec.active).enumerate() {
            if *a {
                assert!((0.0..=1.0).contains(x), "{w:?} #{k}: {x}");
            } else {
                assert!(x.is_nan(), "{w:?} #{k}: {x} for an inactive receiver");
            }
        }
    }
}

#[test]
fn zero_receivers_work_like_the_cpu_twins() {
    let Some(ctx) = gpu("zero_receivers_work_like_the_cpu_twins") else {
        return;
    };
    let case = small_case();
    let scene = scene_of(&case);
    let rec = receivers_of(&case, &scene.light);
    let none = Receivers::default();
    let mut twins = GpuTwins::new(&ctx).unwrap();
    for w in ALL {
        // estimate_with: light-space data from the usual receivers, then zero receivers.
        let cpu = run_cpu(w, &scene, &rec, &case.settings, case.settings.bias).unwrap();
        let mut v: Vec<f32> = Vec::new();
        let light = &scene.light;
        let mut maps = cpu.maps.into_iter();
        match w {
            Which::Hard => {
                twins
                    .hard
                    .estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v)
            }
            Which::Pcf => twins
                .pcf
                .estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v),
            Which::Pcss => {
                twins
                    .pcss
                    .estimate_with(&first(&mut maps).unwrap(), light, &none, &mut v)
            }
            Which::MultiSample => twins.ms.estimate_with(maps, light, &none, &mut v),
        }
        .unwrap();
        // The CLI path: both twins succeed or fail alike (no receiver to fit a view to).
        let mut c = cpu_twin(w);
        let cpu_out = run(&mut *c, &scene, &none);
        let gpu_out = run(twins.get(w), &scene, &none);
        match (cpu_out, gpu_out) {
            (Ok((a, _)), Ok((b, _))) => assert!(a.is_empty() && b.is_empty(), "{w:?}"),
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{w:?}"),
            (a, b) => panic!(
                "{w:?}: cpu {:?} vs gpu {:?}",
                a.map(|x| x.0),
                b.map(|x| x.0)
            ),
        }
        // A wrong output length is refused.
        let mut short = vec![0.0f32; 1];
        assert!(
            twins.get(w).estimate(&scene, &rec, &mut short).is_err(),
            "{w:?}"
        );
    }
}

#[test]
fn chunked_dispatch_equals_one_dispatch() {
    let Some(ctx) = gpu("chunked_dispatch_equals_one_dispatch") else {
        return;
    };
    let case = small_case();
    let scene = scene_of(&case);
    let rec = receivers_of(&case, &scene.light);
    let mut whole = GpuTwins::new(&ctx).unwrap();
    let mut chunked = GpuTwins::new(&ctx).unwrap();
    chunked.hard.set_max_chunk(64);
    chunked.pcf.set_max_chunk(100);
    chunked.pcss.set_max_chunk(7);
    chunked.ms.set_max_chunk(65);
    for w in ALL {
        let kv = settings_kv(w, &case.settings, case.settings.bias);
        set_all(whole.get(w), &kv).unwrap();
        set_all(chunked.get(w), &kv).unwrap();
        let (a, _) = run(whole.get(w), &scene, &rec).unwrap();
        let (b, _) = run(chunked.get(w), &scene, &rec).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b), "{w:?}");
    }
}

#[test]
fn twins_share_name_description_and_parameters() {
    let Some(ctx) = gpu("twins_share_name_description_and_parameters") else {
        return;
    };
    let mut twins = GpuTwins::new(&ctx).unwrap();
    for w in ALL {
        let cpu = cpu_twin(w);
        let gpu = twins.get(w);
        assert_eq!(gpu.backend(), Backend::Gpu);
        assert_eq!(cpu.backend(), Backend::Cpu);
        assert_eq!(gpu.name(), cpu.name());
        assert_eq!(gpu.description(), cpu.description());
        assert_eq!(gpu.params().specs(), cpu.params().specs());
        assert_eq!(gpu.params(), cpu.params());
        assert!(gpu.set_param("no_such_key", "1").is_err());
    }
}

#[test]
fn cli_path_matches_cpu_twin_on_parallel_squares() {
    let Some(ctx) = gpu("cli_path_matches_cpu_twin_on_parallel_squares") else {
        return;
    };
    let scene = Scene::load(fixture("parallel-squares/parallel-squares.toml")).unwrap();
    let bvh = SceneBvh::new(&scene);
    let rec = Receivers::from_camera(&scene, &bvh);
    let mut twins = GpuTwins::new(&ctx).unwrap();
    for w in ALL {
        let mut cpu = cpu_twin(w);
        cpu.set_param("resolution", "256").unwrap();
        let gpu = twins.get(w);
        gpu.set_param("resolution", "256").unwrap();
        let (a, ra) = run(&mut *cpu, &scene, &rec).unwrap();
        let (b, rb) = run(gpu, &scene, &rec).unwrap();
        let (mut se, mut n, mut max) = (0.0f64, 0usize, 0.0f32);
        for k in 0..rec.len() {
            if !rec.active[k] {
                assert!(a[k].is_nan() && b[k].is_nan(), "{w:?} #{k}");
                continue;
            }
            let d = a[k] - b[k];
            se += (d as f64).powi(2);
            n += 1;
            max = max.max(d.abs());
        }
        let rmse = (se / n.max(1) as f64).sqrt();
        eprintln!(
            "{w:?} on parallel-squares @256: {n} receivers, RMSE {rmse:.3e}, max |dV| {max:.3e}"
        );
        assert!(n > 1000, "{w:?}: {n} active receivers");
        assert!(rmse <= CLI_RMSE_MAX, "{w:?}: RMSE {rmse} > {CLI_RMSE_MAX}");
        let note = |r: &shadow_map_core::Report, key: &str| {
            r.notes
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.clone())
        };
        for key in ["out_of_frustum", "resolution", "sublights"] {
            assert_eq!(note(&ra, key), note(&rb, key), "{w:?}: note {key}");
        }
        assert_eq!(ra.light_space_bytes, rb.light_space_bytes, "{w:?}");
    }
}

/// The GPU twin draws the same sub-light points (light-plane coordinates) as the CPU twin.
#[test]
fn sub_light_points_match_the_cpu_twin() {
    let Some(ctx) = gpu("sub_light_points_match_the_cpu_twin") else {
        return;
    };
    let case = small_case();
    let scene = scene_of(&case);
    let mut ms = GpuMultiSample::new(ctx).unwrap();
    ms.set_param("sublights", "3").unwrap();
    ms.set_param("seed", "11").unwrap();
    let want: Vec<Vec2> = scene
        .light
        .stratified_points(3, |k| baselines::multi_sample::jitter(11, k));
    assert_eq!(ms.sub_light_points(&scene.light), want);
}

/// A PCSS search wide enough to spend llvmpipe's loop budget (65535 iterations per invocation):
/// parallel-squares under a 6 x 6 light at r = 1024 with max_taps = 300 (search regions of
/// hundreds of texels, up to 90 000 cells). The kernel probes for the budget; receivers cut short
/// are redone with the CPU filter on the map read back, so V equals the CPU twin's within the
/// twins' tolerance on any device, and on lavapipe `loop_limit_cpu_fallbacks` counts them.
#[test]
fn loop_limit_is_detected_and_redone_not_truncated() {
    let Some(ctx) = gpu("loop_limit_is_detected_and_redone_not_truncated") else {
        return;
    };
    let mut scene =
        Scene::load(fixture("parallel-squares/parallel-squares.toml")).expect("fixture");
    scene.light.shape = LightShape::Rect { size: [6.0, 6.0] };
    scene.camera.width = 32;
    scene.camera.height = 24;
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    for depth in ["f32", "unorm16"] {
        let mut cpu = PcssShadow::new().unwrap();
        let mut gpu = GpuPcssShadow::new(ctx.clone()).unwrap();
        for e in [&mut cpu as &mut dyn SoftShadowEstimator, &mut gpu] {
            e.set_param("resolution", "1024").unwrap();
            e.set_param("max_taps", "300").unwrap();
            e.set_param("depth", depth).unwrap();
        }
        let (vc, _) = run(&mut cpu, &scene, &rec).unwrap();
        let (vg, report) = run(&mut gpu, &scene, &rec).unwrap();
        let fallbacks = report
            .notes
            .iter()
            .find(|(k, _)| k == "loop_limit_cpu_fallbacks")
            .map_or("0".to_string(), |(_, v)| v.clone());
        eprintln!(
            "depth={depth}: loop-limit CPU fallbacks {fallbacks} of {}",
            rec.len()
        );
        let mut worst = 0.0f32;
        for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
            if a.is_nan() || b.is_nan() {
                assert!(a.is_nan() && b.is_nan(), "receiver {k}: CPU {a}, GPU {b}");
                continue;
            }
            worst = worst.max((a - b).abs());
        }
        assert!(worst <= 1e-3, "depth={depth}: max |dV| {worst}");
    }
}
