//! The GPU twin of the deep shadow map against the CPU twin: the conformance suite of
//! `test-support` (`twin::deep_shadow`), with what is specific to deep shadow maps here.
//!
//! On random scenes (proptest): per texel, the processed lists as sorted sequences (depth within
//! `DEPTH_REL`, alpha and tau equal), the truncation points, the neighbour links (as ranks in the
//! neighbour's list: element indices depend on insertion order) and the filtered transmittance of
//! every filter mode and traversal (within `T_TOL`), on scenes of parallel sheets whose edges sit
//! a quarter texel off the texel centres, so the f32 (GPU) and f64 (CPU) edge tests cannot
//! disagree. Then the estimators on fixtures (the CLI path), capacity growth and the typed error.
//! Cases: 8 by default, `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]
use crate::common;
use common::*;
use deep_shadow::{
    cpu::{build_deep_map, sublight_view},
    dsm::{DeepShadowMap, Filter, LookupSettings, SoftLookup, Traversal},
    gpu::{pack_depth_query, GpuMap, PackedQuery},
    params::Settings,
    shared::{Node, NIL},
    CpuDeepShadow, GpuDeepShadow,
};
use glam::{Vec2, Vec3};
use proptest::{
    prelude::*,
    test_runner::{TestCaseError, TestRunner},
};
use shadow_map_core::{
    gpu::GpuContext, run, Error, LightFrame, LightView, Scene, SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::{
    conformance::{table, BoxedFrame, FixedCase, TwinPair},
    fixtures::note,
    proptest_config,
};

const DEPTH_REL: f32 = 2e-6;
const T_TOL: f32 = 2e-5;

test_support::twin_suite! {
    deep_shadow [
        cli_path_matches_the_cpu_twin,
        frame_path_matches_the_cpu_twin,
        loop_limit_is_detected_and_redone
    ] => DeepShadow,
}

/// A sheet: texel rectangle [a0, a1) x [b0, b1), depth index, alpha.
#[derive(Debug, Clone)]
struct Sheet {
    a: (u32, u32),
    b: (u32, u32),
    depth: u32,
    alpha: f32,
}

#[derive(Debug, Clone)]
struct Case {
    r: u32,
    sheets: Vec<Sheet>,
    ground: bool,
    epsilon: f32,
    queries: Vec<(f32, f32, f32)>,
}

fn arb_case() -> impl Strategy<Value = Case> {
    prop_oneof![Just(16u32), Just(32), Just(48)].prop_flat_map(|r| {
        let sheet = (
            0..r,
            1..r,
            0..r,
            1..r,
            0u32..12,
            prop_oneof![Just(1.0f32), 0.05f32..0.95],
        )
            .prop_map(move |(a0, da, b0, db, depth, alpha)| Sheet {
                a: (a0, (a0 + da).min(r)),
                b: (b0, (b0 + db).min(r)),
                depth,
                alpha,
            });
        (
            Just(r),
            prop::collection::vec(sheet, 1..14),
            any::<bool>(),
            prop_oneof![Just(0.0f32), Just(0.001), Just(0.05)],
            prop::collection::vec((0.0f32..1.0, 0.0f32..1.0, 0u32..26), 40),
        )
            .prop_map(|(r, sheets, ground, epsilon, q)| Case {
                r,
                sheets,
                ground,
                epsilon,
                // Query depths halfway between sheet depths (never a tie with a fragment).
                queries: q
                    .into_iter()
                    .map(|(u, v, k)| {
                        (
                            u * r as f32,
                            v * r as f32,
                            1.05 + 0.1 * k as f32 / 2.0 + 0.025,
                        )
                    })
                    .collect(),
            })
    })
}

/// Sheet depth k is at light-space z = 1.1 + 0.1 k; the ground at z = 2.5.
fn sheet_z(k: u32) -> f32 {
    1.1 + 0.1 * k as f32
}

/// The light view: centre of projection at (0, 3, 0) looking down, n = 1, window [-1, 1]^2.
fn view(r: u32) -> LightView {
    LightView {
        frame: LightFrame::new(Vec3::new(0.0, 3.0, 0.0), -Vec3::Y, Vec3::X).unwrap(),
        n: 1.0,
        far: 3.0,
        window_min: Vec2::splat(-1.0),
        w: 2.0,
        r,
        projection: Default::default(),
    }
}

fn scene_of(c: &Case) -> Scene {
    let v = view(c.r);
    let delta = v.w / c.r as f32;
    let mut meshes = Vec::new();
    if c.ground {
        meshes.push((quad(-5.0, -5.0, 5.0, 5.0, 0.5), 1.0));
    }
    for s in &c.sheets {
        let z = sheet_z(s.depth);
        // Light-space x = z (u delta - 1) at u = a + 1/4 (a quarter texel off the centres).
        let lx = |a: u32| z * ((a as f32 + 0.25) * delta - 1.0);
        let (x0, x1) = (lx(s.a.0), lx(s.a.1));
        let (y0, y1) = (lx(s.b.0), lx(s.b.1));
        // Light space (x, y, z) is world (x, 3 - z, y) for this frame (e_y = e_z x e_x = +Z).
        meshes.push((quad(x0, y0, x1, y1, 3.0 - z), s.alpha));
    }
    Scene::from_meshes("twin", camera(), rect_light(0.5), meshes).unwrap()
}

fn rank(d: &DeepShadowMap, t: usize, e: u32) -> Option<usize> {
    if e == NIL {
        return None;
    }
    d.list(t).iter().position(|x| *x == e)
}

/// A GPU map read back as the CPU twin's structure (the head buffer and the elements written).
fn read_map(ctx: &GpuContext, map: &GpuMap) -> DeepShadowMap {
    let head: Vec<u32> = ctx.read_buffer(&map.head, map.head.size()).unwrap();
    let mut nodes: Vec<Node> = ctx.read_buffer(&map.nodes, map.nodes.size()).unwrap();
    nodes.truncate(map.stats.fragments.min(map.stats.capacity) as usize);
    DeepShadowMap::from_parts(map.r, head, nodes, map.stats).unwrap()
}

fn compare_maps(c: &DeepShadowMap, g: &DeepShadowMap) -> Result<(), TestCaseError> {
    prop_assert_eq!(c.stats().fragments, g.stats().fragments, "fragments");
    let r = c.r() as usize;
    for t in 0..c.head().len() {
        let (lc, lg) = (c.list(t), g.list(t));
        prop_assert_eq!(lc.len(), lg.len(), "texel {}: truncation point / length", t);
        for (k, (&ec, &eg)) in lc.iter().zip(&lg).enumerate() {
            let (nc, ng) = (&c.nodes()[ec as usize], &g.nodes()[eg as usize]);
            prop_assert!(
                (nc.depth() - ng.depth()).abs() <= DEPTH_REL * nc.depth(),
                "texel {} #{}: depth {} vs {}",
                t,
                k,
                nc.depth(),
                ng.depth()
            );
            prop_assert_eq!(nc.alpha(), ng.alpha(), "texel {} #{}: alpha", t, k);
            prop_assert_eq!(nc.tau(), ng.tau(), "texel {} #{}: tau", t, k);
            prop_assert_eq!(
                rank(c, t, nc.prev()),
                rank(g, t, ng.prev()),
                "texel {} #{}: prev",
                t,
                k
            );
            let (i, j) = (t % r, t / r);
            if i + 1 < r {
                prop_assert_eq!(
                    rank(c, t + 1, nc.right()),
                    rank(g, t + 1, ng.right()),
                    "texel {} #{}: right",
                    t,
                    k
                );
            }
            if j + 1 < r {
                prop_assert_eq!(
                    rank(c, t + r, nc.upper()),
                    rank(g, t + r, ng.upper()),
                    "texel {} #{}: upper",
                    t,
                    k
                );
            }
            if k > 0 {
                prop_assert!(
                    g.nodes()[lg[k - 1] as usize].depth() <= ng.depth(),
                    "texel {}: GPU list unsorted",
                    t
                );
            }
        }
    }
    Ok(())
}

/// The estimators on a fixture: V within 1e-4 of the CPU twin's (and finite) at 99.5% of the
/// `n` active receivers. Coverage ties (texel centres within ~1e-6 texel of an edge, decided in
/// f32 on the GPU and f64 on the CPU) may flip a few.
fn assert_fixture_within(what: &str, vc: &[f32], vg: &[f32], n: usize) {
    let within = vc
        .iter()
        .zip(vg)
        .filter(|(a, b)| a.is_finite() && (*a - *b).abs() <= 1e-4)
        .count();
    assert!(
        within as f64 >= 0.995 * n as f64,
        "{what}: {within} of {n} within 1e-4"
    );
}

fn settings() -> Settings {
    Settings::from_params(CpuDeepShadow::new().unwrap().params()).unwrap()
}

/// The fixture `strands` at 32 x 24 with every seventh receiver inactive, `pcf` over 5 x 5.
fn strands_case() -> FixedCase {
    let (scene, mut receivers) = fixture("strands", 32, 24);
    for (k, a) in receivers.active_mut().iter_mut().enumerate() {
        if k % 7 == 6 {
            *a = false;
        }
    }
    let params = [("resolution", "128"), ("filter", "pcf"), ("kernel", "5")];
    FixedCase {
        scene,
        receivers,
        params: params.iter().map(|(k, v)| (*k, v.to_string())).collect(),
    }
}

/// The deep-shadow twins, as the conformance suite drives them.
struct DeepShadow;

impl TwinPair for DeepShadow {
    test_support::twin_constructors!(CpuDeepShadow, GpuDeepShadow, fixed = strands_case());

    /// The engine path on the strands (semi-transparent: the frame builds lists, as the CPU
    /// twin does).
    fn frame(
        &self,
        ctx: &Arc<GpuContext>,
        params: &test_support::conformance::Params,
    ) -> Option<BoxedFrame> {
        let t = table(deep_shadow::params::SPECS, params);
        Some(Box::new(
            deep_shadow::DeepShadowFrame::prepare(ctx.clone(), &t, 1 << 16).unwrap(),
        ))
    }

    /// The engine path renders its lists with the hardware rasteriser (fragments inserted by a
    /// fragment shader), whose sub-pixel vertex snapping (8 bits on lavapipe) can cover a texel
    /// centre within 1/256 texel of a strand's edge that the CPU's exact fill rule does not, or
    /// the reverse: on the strands (filter=pcf, 5 x 5) a receiver then moves by a tap's
    /// transmittance over 25. Checked: at most 1% of the receivers beyond 1e-4, none beyond
    /// 2 / 25 (two taps), RMSE within 3e-3; and V is the semi-transparent scene's, far from the
    /// CPU twin's on the scene made opaque.
    fn frame_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let case = strands_case();
        let frame = self.frame(ctx, &case.params).expect("engine path");
        assert!(frame.models_opacity());
        let c = test_support::conformance::frames_match_the_cpu_twin(
            "deep-shadow strands",
            ctx,
            &*frame,
            &case.scene,
            &case.receivers,
        );
        assert_eq!(c.status.left_nan, 0, "{:?}", c.status);
        assert!(
            c.active > 0 && c.beyond * 100 <= c.active && c.max_dv <= 2.0 / 25.0 && c.rmse <= 3e-3,
            "{} of {} beyond 1e-4, max |dV| {}, rmse {}",
            c.beyond,
            c.active,
            c.max_dv,
            c.rmse
        );
        let views = frame.fit_views(&case.scene, &case.receivers).unwrap();
        let opaque = frame
            .cpu_twin(&case.scene.opaque(), &case.receivers, &views)
            .unwrap();
        let apart = test_support::fixtures::rmse(&c.v, &opaque, case.receivers.active());
        println!("deep-shadow strands: frame RMSE to the opaque scene's CPU twin {apart:.3}");
        assert!(
            apart > 10.0 * c.rmse.max(1e-3),
            "V is the opaque scene's: {apart}"
        );
    }

    /// The lists, links and transmittance of the GPU twin's map against the CPU twin's.
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let g = GpuDeepShadow::new(ctx.clone()).unwrap();
        let mut runner = TestRunner::new(proptest_config(source_file, 8));
        runner
            .run(&arb_case(), |c| {
                let scene = scene_of(&c);
                let v = view(c.r);
                let mut s = settings();
                s.resolution = c.r;
                s.epsilon = c.epsilon;
                let cm = build_deep_map(&scene, &v, &s).unwrap();
                let gm = g.build_lists(&scene, &v, &s).unwrap();
                let gr = read_map(ctx, &gm);
                compare_maps(&cm, &gr)?;
                let queries: Vec<PackedQuery> = c
                    .queries
                    .iter()
                    .map(|q| pack_depth_query(Vec2::new(q.0, q.1), q.2))
                    .collect();
                // filter=pcss: a box light whose regions span whole texels, and a disk light
                // wide enough to be sampled by max_taps equal cells.
                let soft = |l: f32, max_taps: u32, disk: bool| SoftLookup {
                    light: Vec2::splat(l),
                    near: v.n,
                    to_texels: v.r as f32 / v.w,
                    max_taps,
                    disk,
                    ortho: false,
                };
                let filters = [
                    (Filter::First, SoftLookup::default()),
                    (Filter::None, SoftLookup::default()),
                    (Filter::Pcf, SoftLookup::default()),
                    (Filter::Edsm, SoftLookup::default()),
                    (Filter::Pcss, soft(0.4, 32, false)),
                    (Filter::Pcss, soft(1.5, 4, true)),
                ];
                for (filter, soft) in filters {
                    for kernel in [3, 7] {
                        for traversal in [Traversal::Linked, Traversal::Naive] {
                            let ls = LookupSettings {
                                filter,
                                kernel,
                                c_world: 30.0,
                                traversal,
                                soft,
                            };
                            let (tg, _, _) = g.lookup(&gm, &ls, &queries).unwrap();
                            for (q, t) in queries.iter().zip(&tg) {
                                let (tc, _) = cm.transmittance(Vec2::new(q[0], q[1]), q[2], &ls);
                                prop_assert!(
                                    (tc - t).abs() <= T_TOL,
                                    "{:?} at {:?}: CPU {} GPU {}",
                                    ls,
                                    q,
                                    tc,
                                    t
                                );
                            }
                        }
                    }
                }
                Ok(())
            })
            .unwrap();
    }

    /// Both estimators on the fixtures `hair`, `strands` and `bunny` through the CLI path, every
    /// filter mode: the same name, description and path, fragment counts within coverage ties,
    /// V within 1e-4 at 99.5% of the receivers.
    /// Lists long enough to spend llvmpipe's loop budget (65535 iterations per invocation):
    /// 1500 stacked sheets of opacity 0.002 over a ground, no truncation (`epsilon=0`), so
    /// every covered texel holds a list of 1500 elements, sorted by selection (past 64) in
    /// `process`, and the receivers on the ground under them walk whole lists at each of the
    /// 7 x 7 PCF taps (`traversal=naive`). Cut texels make the twin build that view's lists with
    /// the CPU twin and upload them, cut lookups are redone with the CPU twin's lookup on the
    /// same map: V must equal the CPU twin's on any device, and on llvmpipe both fallbacks must
    /// have happened (the probe is what found them).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let light = test_support::fixtures::rect_light(1.0, 3.0);
        let mut meshes = vec![(test_support::fixtures::quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0)];
        for k in 0..1500 {
            let y = 1.0 + k as f32 * 0.0004;
            meshes.push((test_support::fixtures::quad(-1.0, -1.0, 1.0, 1.0, y), 0.002));
        }
        let scene = Scene::from_meshes(
            "stacked sheets",
            test_support::fixtures::camera(8, 6),
            light,
            meshes,
        )
        .unwrap();
        let pos: Vec<Vec3> = (0..36)
            .map(|k| {
                Vec3::new(
                    -0.7 + 0.28 * (k % 6) as f32,
                    0.0,
                    -0.7 + 0.28 * (k / 6) as f32,
                )
            })
            .collect();
        let rec = test_support::fixtures::points(pos, Vec3::Y);
        let mut c = CpuDeepShadow::new().unwrap();
        let mut g = GpuDeepShadow::new(ctx.clone()).unwrap();
        for (k, v) in [
            ("resolution", "16"),
            ("filter", "pcf"),
            ("kernel", "7"),
            ("traversal", "naive"),
            ("epsilon", "0"),
        ] {
            c.set_param(k, v).unwrap();
            g.set_param(k, v).unwrap();
        }
        let (vc, _) = run(&mut c, &scene, &rec).unwrap();
        let (vg, rg) = run(&mut g, &scene, &rec).unwrap();
        let lookups = note(&rg, "loop_limit_cpu_fallbacks").unwrap_or_else(|| "0".into());
        let lists = note(&rg, "loop_limit_cpu_lists").unwrap_or_else(|| "0".into());
        eprintln!(
            "loop-limit CPU fallbacks on {}: {lookups} of {} lookups, {lists} texels' lists",
            ctx.describe(),
            rec.len()
        );
        for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
            assert!((a - b).abs() <= 1e-6, "receiver {k}: CPU {a}, GPU {b}");
        }
        assert!(
            vc.iter().any(|&v| v < 0.2),
            "the sheets should shadow: {vc:?}"
        );
        if ctx.describe().contains("llvmpipe") {
            assert!(lookups != "0" && lists != "0", "{lookups} / {lists}");
        }
    }

    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        for name in ["hair", "strands", "bunny"] {
            let (scene, rec) = fixture(name, 40, 30);
            for kv in [
                &[("filter", "none")][..],
                &[("filter", "pcf"), ("kernel", "5"), ("sublights", "2")][..],
                &[("filter", "edsm"), ("kernel", "7")][..],
                &[("filter", "first")][..],
                &[("filter", "pcss")][..],
                &[("filter", "pcss"), ("sublights", "2"), ("max_taps", "4")][..],
            ] {
                let mut c = CpuDeepShadow::new().unwrap();
                let mut g = GpuDeepShadow::new(ctx.clone()).unwrap();
                for (k, v) in kv.iter().chain(&[("resolution", "256")]) {
                    c.set_param(k, v).unwrap();
                    g.set_param(k, v).unwrap();
                }
                assert_eq!((c.name(), c.description()), (g.name(), g.description()));
                let (vc, rc) = run(&mut c, &scene, &rec).unwrap();
                let (vg, rg) = run(&mut g, &scene, &rec).unwrap();
                check_contract(&vg, &rec);
                assert_eq!(note(&rc, "path"), note(&rg, "path"));
                // Fragment counts agree up to coverage ties: texel centres within ~1e-6 texel of
                // an arbitrary edge, decided in f32 on the GPU and f64 on the CPU (1 in 2e5 on
                // hair).
                let frags = |r: &shadow_map_core::Report| -> i64 {
                    note(r, "fragments").map_or(0, |f| f.parse().unwrap())
                };
                let (fc, fg) = (frags(&rc), frags(&rg));
                assert!(
                    (fc - fg).abs() <= 2 + fc / 10_000,
                    "{name} {kv:?}: fragments {fc} vs {fg}"
                );
                // The truncation's notes (the GPU twin used to drop them): elements
                // kept and the longest list, up to the same ties.
                let num = |r: &shadow_map_core::Report, key| -> i64 {
                    note(r, key).map_or(-1, |f| f.parse().unwrap())
                };
                for key in ["elements_kept", "truncated", "max_list"] {
                    let (c, g) = (num(&rc, key), num(&rg, key));
                    assert!(
                        (c < 0) == (g < 0) && (c - g).abs() <= 2 + c / 10_000,
                        "{name} {kv:?}: {key} {c} vs {g}"
                    );
                }
                assert_fixture_within(&format!("{name} {kv:?}"), &vc, &vg, rec.active_count());
            }
        }
    }
}

#[test]
fn gpu_capacity_grows_or_fails_with_a_typed_error() {
    let Some(ctx) = test_support::gpu("gpu_capacity_grows_or_fails_with_a_typed_error") else {
        return;
    };
    let (scene, rec) = fixture("strands", 32, 24);
    let g = GpuDeepShadow::new(ctx.clone()).unwrap();
    let mut s = settings();
    s.resolution = 64;
    let (v, _) = sublight_view(&scene, &rec, Vec2::ZERO, 64, 0).unwrap();
    let full = g.build_map(&scene, &v, &s).unwrap();
    assert_eq!(full.stats.passes, 1);
    s.capacity = 8;
    let grown = g.build_map(&scene, &v, &s).unwrap();
    assert_eq!(grown.stats.passes, 2);
    assert_eq!(grown.stats.fragments, full.stats.fragments);
    compare_maps(&read_map(&ctx, &full), &read_map(&ctx, &grown)).unwrap();
    s.max_capacity = 100;
    match g.build_map(&scene, &v, &s) {
        Err(Error::Limit { requested, max, .. }) => {
            assert_eq!(requested, full.stats.fragments);
            assert_eq!(max, 100);
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(_) => panic!("expected a limit error"),
    }
}

/// Every `fit` x `nearfar` combination on a semi-transparent fixture (deep lists) and an opaque
/// one, through both estimators, with a filter margin (`pcf`/`edsm`, the stable fit's lattice
/// margin included): V in [0, 1] and finite for every active receiver, within 1e-4 of the CPU
/// twin at 99.5% of them (the fixture rule above), the same view (`near`, `far`,
/// `window_scale`) on both, and the choices reach the view (`fit=receivers` has window_scale 1
/// before the filter margin, `fit=stable` more).
#[test]
fn every_fit_and_nearfar_match_on_both_estimators() {
    let Some(ctx) = test_support::gpu("every_fit_and_nearfar_match_on_both_estimators") else {
        return;
    };
    for (name, kv) in [
        ("strands", &[("filter", "pcf"), ("kernel", "5")][..]),
        (
            "bunny",
            &[("filter", "edsm"), ("kernel", "7"), ("sublights", "2")][..],
        ),
    ] {
        let (scene, rec) = fixture(name, 32, 24);
        let n = rec.active_count();
        for fit in ["receivers", "scene", "stable"] {
            let mut planes = Vec::new();
            for nearfar in ["clipped", "aabb", "frustum"] {
                let mut c = CpuDeepShadow::new().unwrap();
                let mut g = GpuDeepShadow::new(ctx.clone()).unwrap();
                let all = [("resolution", "128"), ("fit", fit), ("nearfar", nearfar)];
                for (k, v) in kv.iter().chain(&all) {
                    c.set_param(k, v).unwrap();
                    g.set_param(k, v).unwrap();
                }
                let what = format!("{name} {kv:?} fit={fit} nearfar={nearfar}");
                let (vc, rc) = run(&mut c, &scene, &rec).unwrap();
                let (vg, rg) = run(&mut g, &scene, &rec).unwrap();
                check_contract(&vc, &rec);
                check_contract(&vg, &rec);
                for key in ["near", "far", "window_scale"] {
                    assert_eq!(note(&rc, key), note(&rg, key), "{what}: {key}");
                }
                assert_fixture_within(&what, &vc, &vg, n);
                let ws: f32 = note(&rc, "window_scale").unwrap().parse().unwrap();
                // The pcf/edsm margin widens a receivers window by r / (r - 2 margin).
                let widen = 128.0 / (128.0 - 2.0 * (kv[1].1.parse::<f32>().unwrap() / 2.0).floor());
                match fit {
                    "receivers" => assert!((ws - widen).abs() < 1e-3, "{what}: {ws}"),
                    // Power of two, 3-texel margins, a texel of snapping; the filter margin
                    // may double the side once more.
                    "stable" => {
                        let max = 4.0 * (1.0 + 6.0 / 128.0) * 128.0 / 127.0;
                        assert!(ws > 1.0 && ws <= max, "{what}: {ws}")
                    }
                    _ => assert!(ws >= widen - 1e-3, "{what}: {ws}"),
                }
                planes.push((note(&rc, "near"), note(&rc, "far")));
            }
            assert!(
                planes[0] != planes[1] || planes[0] != planes[2],
                "{name} fit={fit}: nearfar did not change the planes {planes:?}"
            );
        }
    }
}

/// The GPU twin settles or refuses receivers beyond the light view's reach as the CPU twin does
/// (`tests/cpu.rs` `receivers_beyond_the_view_are_settled_or_refused`).
#[test]
fn gpu_receivers_beyond_the_view_are_settled_or_refused() {
    let Some(ctx) = test_support::gpu("gpu_receivers_beyond_the_view_are_settled_or_refused")
    else {
        return;
    };
    let (open, rec) = beyond_reach(false);
    let mut g = GpuDeepShadow::new(ctx.clone()).unwrap();
    let (v, rep) = run(&mut g, &open, &rec).unwrap();
    let (vc, _) = run(&mut CpuDeepShadow::new().unwrap(), &open, &rec).unwrap();
    assert_eq!(v[1], vc[1]);
    assert!((v[0] - vc[0]).abs() <= 1e-4, "{} vs {}", v[0], vc[0]);
    assert_eq!(note(&rep, "settled_outside").as_deref(), Some("1"));
    let (walled, rec) = beyond_reach(true);
    assert!(matches!(
        run(&mut GpuDeepShadow::new(ctx).unwrap(), &walled, &rec),
        Err(Error::Receivers(_))
    ));
}
