//! Deep-shadow's GPU estimator (its engine path, [`DeepShadowFrame`], run by the core's
//! `FrameTwin`) against the CPU twin: the conformance suite of `test-support`
//! (`twin::deep_shadow`), with what is specific to deep shadow maps here.
//!
//! On random scenes (proptest): the frame renders stacks of parallel sheets whose edges sit a
//! quarter texel off the texel centres (so the hardware rasteriser's sub-pixel snapping and the
//! CPU's exact fill rule cannot disagree) in a view made for them, then its map is read back and
//! compared with the CPU twin's build per texel: the processed lists as sorted sequences (depth
//! within `DEPTH_REL`, alpha and tau equal), the truncation points, the neighbour links (as ranks
//! in the neighbour's list: element indices depend on insertion order), or on the opaque path the
//! nearest depths; and the frame's V against the CPU twin's lookup on that same map, every filter
//! mode and traversal (within `T_TOL`, each receiver beyond it a tie the explainer shows). Then
//! the estimators on fixtures (the CLI path), every fit, the loop budget and the typed errors.
//! Cases: 8 by default, `SOFTSHADOW_PROPTEST_CASES=N` for more.
#![cfg(feature = "gpu")]
use crate::common;
use common::*;
use deep_shadow::{
    cpu::{build_deep_map, finish, lookup_settings, query, Query},
    dsm::{transmittance_opaque_plane, DeepShadowMap, LookupSettings},
    frame::FrameMap,
    params::{Settings, SPECS},
    shared::NIL,
    CpuDeepShadow, DeepShadowFrame,
};
use glam::{Vec2, Vec3};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::{
        frame::{FrameEstimator, FrameInputs, FrameStatus},
        receivers::GpuReceivers,
        GpuContext, GpuScene,
    },
    light_space::{LightSpace, LightSpaceRequest},
    light_view::FitReport,
    run, Error, Light, LightFrame, LightView, Params, ReceiverPlane, Receivers, Scene,
    SoftShadowEstimator, Warning,
};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, FixedCase, TwinPair},
    fixtures::note,
    proptest_config,
    tolerance::{CaseStats, RunStats, Tolerance, Verdict},
};

/// Depths of one fragment on both sides: the frame interpolates z in f32 in the rasteriser.
const DEPTH_REL: f32 = 2e-6;
/// V of one lookup on both sides: the same steps in f32 in another order.
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
    /// Receivers at texel coordinates (u, v) and light-space depth z.
    receivers: Vec<(f32, f32, f32)>,
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
                // Depths halfway between sheet depths (never a tie with a fragment).
                receivers: q
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

/// Light space (x, y, z) is world (x, 3 - z, y) for this frame (e_y = e_z x e_x = +Z); texel
/// coordinate u is at x = z (u delta - 1).
fn world(r: u32, u: f32, v: f32, z: f32) -> Vec3 {
    let delta = 2.0 / r as f32;
    Vec3::new(z * (u * delta - 1.0), 3.0 - z, z * (v * delta - 1.0))
}

fn scene_of(c: &Case, light: Light) -> Scene {
    let mut meshes = Vec::new();
    if c.ground {
        meshes.push((quad(-5.0, -5.0, 5.0, 5.0, 0.5), 1.0));
    }
    for s in &c.sheets {
        let z = sheet_z(s.depth);
        // A quarter texel off the centres.
        let lo = world(c.r, s.a.0 as f32 + 0.25, s.b.0 as f32 + 0.25, z);
        let hi = world(c.r, s.a.1 as f32 + 0.25, s.b.1 as f32 + 0.25, z);
        meshes.push((quad(lo.x, lo.z, hi.x, hi.z, lo.y), s.alpha));
    }
    Scene::from_meshes("twin", camera(), light, meshes).unwrap()
}

/// The case's receivers, facing the light; every ninth inactive.
fn receivers_of(c: &Case) -> Receivers {
    let pos: Vec<Vec3> = c
        .receivers
        .iter()
        .map(|&(u, v, z)| world(c.r, u, v, z))
        .collect();
    let mut rec = Receivers::from_points(pos.clone(), vec![Vec3::Y; pos.len()]).unwrap();
    for (k, a) in rec.active_mut().iter_mut().enumerate() {
        *a = k % 9 != 8;
    }
    rec
}

fn rank(d: &DeepShadowMap, t: usize, e: u32) -> Option<usize> {
    if e == NIL {
        return None;
    }
    d.list(t).iter().position(|x| *x == e)
}

fn compare_maps(c: &DeepShadowMap, g: &DeepShadowMap) -> Result<(), String> {
    let check = |ok: bool, what: String| if ok { Ok(()) } else { Err(what) };
    check(
        c.stats().fragments == g.stats().fragments,
        format!(
            "fragments {} vs {}",
            c.stats().fragments,
            g.stats().fragments
        ),
    )?;
    let r = c.r() as usize;
    for t in 0..c.head().len() {
        let (lc, lg) = (c.list(t), g.list(t));
        check(
            lc.len() == lg.len(),
            format!(
                "texel {t}: truncation point / length {} vs {}",
                lc.len(),
                lg.len()
            ),
        )?;
        for (k, (&ec, &eg)) in lc.iter().zip(&lg).enumerate() {
            let (nc, ng) = (&c.nodes()[ec as usize], &g.nodes()[eg as usize]);
            check(
                (nc.depth() - ng.depth()).abs() <= DEPTH_REL * nc.depth(),
                format!("texel {t} #{k}: depth {} vs {}", nc.depth(), ng.depth()),
            )?;
            check(
                nc.alpha() == ng.alpha() && nc.tau() == ng.tau(),
                format!(
                    "texel {t} #{k}: alpha, tau {} {} vs {} {}",
                    nc.alpha(),
                    nc.tau(),
                    ng.alpha(),
                    ng.tau()
                ),
            )?;
            check(
                rank(c, t, nc.prev()) == rank(g, t, ng.prev()),
                format!("texel {t} #{k}: prev"),
            )?;
            let (i, j) = (t % r, t / r);
            check(
                i + 1 >= r || rank(c, t + 1, nc.right()) == rank(g, t + 1, ng.right()),
                format!("texel {t} #{k}: right"),
            )?;
            check(
                j + 1 >= r || rank(c, t + r, nc.upper()) == rank(g, t + r, ng.upper()),
                format!("texel {t} #{k}: upper"),
            )?;
            check(
                k == 0 || g.nodes()[lg[k - 1] as usize].depth() <= ng.depth(),
                format!("texel {t}: the frame's list unsorted"),
            )?;
        }
    }
    Ok(())
}

/// The frame's nearest depths against the CPU raster's (the CPU twin's opaque path).
fn compare_depths(
    c: &shadow_map_core::DepthMap,
    g: &shadow_map_core::DepthMap,
) -> Result<(), String> {
    for (t, (zc, zg)) in c.depth.iter().zip(&g.depth).enumerate() {
        let same = if zc.is_finite() {
            (zc - zg).abs() <= DEPTH_REL * zc
        } else {
            zc == zg
        };
        if !same {
            return Err(format!("texel {t}: depth {zc} vs {zg}"));
        }
    }
    Ok(())
}

/// The transmittance the CPU twin's lookup reads in `map` at `uv` with the caster test `plane`.
fn lookup(map: &FrameMap, uv: Vec2, plane: &ReceiverPlane, ls: &LookupSettings) -> f32 {
    match map {
        FrameMap::Lists(d) => d.transmittance_plane(uv, plane, ls).0,
        FrameMap::Depths(m) => transmittance_opaque_plane(m, uv, plane, ls),
    }
}

/// The CPU twin's V in `view` read from `map` (the frame's, read back): the twin's queries, its
/// lookup, its `finish`.
fn cpu_on_map(
    map: &FrameMap,
    scene: &Scene,
    rec: &Receivers,
    view: &LightView,
    s: &Settings,
) -> Vec<f32> {
    let ls = lookup_settings(view, scene.light(), s);
    let acc: Vec<f32> = (0..rec.len())
        .map(|k| {
            if !rec.active()[k] {
                return 0.0;
            }
            match query(view, scene.light(), rec.position()[k], rec.normal()[k], s) {
                Query::Fixed(x) => x,
                Query::Look { uv, plane, facing } => facing * lookup(map, uv, &plane, &ls),
            }
        })
        .collect();
    let mut v = vec![0.0; rec.len()];
    finish(scene, rec, &acc, 1, &mut v);
    v
}

/// Why receiver `k` is beyond the tolerance: the CPU twin's lookup on the same map with the
/// query's texel coordinates moved by a few ulps (a texel or cell edge the GPU's own projection
/// falls on the other side of) or its depth by 1e-6 relative (a depth the GPU computes an ulp
/// away), against the CPU's V `cpu` and the frame's `gpu`.
#[allow(clippy::too_many_arguments)]
fn explain(
    tol: &Tolerance,
    map: &FrameMap,
    scene: &Scene,
    rec: &Receivers,
    view: &LightView,
    s: &Settings,
    k: usize,
    (cpu, gpu): (f32, f32),
) -> Verdict {
    let Query::Look { uv, plane, facing } =
        query(view, scene.light(), rec.position()[k], rec.normal()[k], s)
    else {
        return Verdict::of(false, false).note("no lookup");
    };
    let ls = lookup_settings(view, scene.light(), s);
    let at =
        |uv: Vec2, plane: &ReceiverPlane| (facing * lookup(map, uv, plane, &ls)).clamp(0.0, 1.0);
    let d = 8.0 * f32::EPSILON * view.r as f32;
    let sampling = [Vec2::X, -Vec2::X, Vec2::Y, -Vec2::Y]
        .iter()
        .any(|&e| tol.nudge_explains(at(uv + d * e, &plane), cpu, gpu));
    let depth = [1.0 + 1e-6f32, 1.0 - 1e-6].iter().any(|&f| {
        let p = ReceiverPlane {
            zp: plane.zp * f,
            c: plane.c * f,
            ..plane
        };
        tol.nudge_explains(at(uv, &p), cpu, gpu)
    });
    Verdict::of(depth, sampling)
}

/// One frame of `frame` in `views` over the scene's casters and the receivers, submitted and
/// waited for: V and the decoded status.
fn encode_once(
    ctx: &GpuContext,
    frame: &dyn FrameEstimator,
    scene: &Scene,
    casters: &GpuScene,
    rec: &GpuReceivers,
    views: &[Option<LightView>],
) -> (Vec<f32>, FrameStatus) {
    let n = rec.count as u64;
    let v = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("random scene V"),
        size: 4 * n.max(1),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    frame
        .encode(
            &mut enc,
            &FrameInputs {
                casters,
                views,
                light: scene.light(),
                receivers: &rec.buffer,
                count: rec.count,
                v: &v,
                timestamps: None,
            },
        )
        .unwrap();
    ctx.queue.submit([enc.finish()]);
    let v: Vec<f32> = ctx.read_buffer(&v, 4 * n).unwrap();
    (v, frame.read_status(ctx).unwrap().unwrap())
}

/// The lookups of the random scenes, as parameters: every filter, kernel 3 and 7 where the
/// filter has a kernel, both traversals where it walks lists from tap to tap; `filter=pcss` with
/// a box light whose regions span whole texels, and a disk light wide enough to be sampled by
/// `max_taps` equal cells (`shape` as [`test_support::fixtures::light_of_shape`]).
struct Lookup {
    params: &'static [(&'static str, &'static str)],
    shape: u8,
    l: f32,
}

const LOOKUPS: &[Lookup] = {
    const fn box_(params: &'static [(&'static str, &'static str)]) -> Lookup {
        Lookup {
            params,
            shape: 0,
            l: 0.5,
        }
    }
    &[
        box_(&[("filter", "first")]),
        box_(&[("filter", "none"), ("traversal", "linked")]),
        box_(&[("filter", "none"), ("traversal", "naive")]),
        box_(&[("filter", "pcf"), ("kernel", "3"), ("traversal", "linked")]),
        box_(&[("filter", "pcf"), ("kernel", "3"), ("traversal", "naive")]),
        box_(&[("filter", "pcf"), ("kernel", "7"), ("traversal", "linked")]),
        box_(&[("filter", "pcf"), ("kernel", "7"), ("traversal", "naive")]),
        box_(&[("filter", "edsm"), ("kernel", "3"), ("traversal", "linked")]),
        box_(&[("filter", "edsm"), ("kernel", "3"), ("traversal", "naive")]),
        box_(&[("filter", "edsm"), ("kernel", "7"), ("traversal", "linked")]),
        box_(&[("filter", "edsm"), ("kernel", "7"), ("traversal", "naive")]),
        Lookup {
            params: &[("filter", "pcss"), ("max_taps", "32")],
            shape: 0,
            l: 0.4,
        },
        Lookup {
            params: &[("filter", "pcss"), ("max_taps", "4")],
            shape: 1,
            l: 1.5,
        },
    ]
};

/// What one random case's frames measured besides V.
#[derive(Debug, Default)]
struct MapTally {
    /// Frames whose map was read back and compared (lists, nearest depths).
    lists: usize,
    depths: usize,
    /// Fragments in the compared lists.
    fragments: u64,
}

/// One random case: for each lookup of [`LOOKUPS`], on the case's scene (lists) and on the
/// scene made opaque (the opaque path), a frame prepared with the lookup's parameters (the
/// classic depth test without bias, as the receivers sit halfway between sheets; EDSM's
/// `c' = 30`), its map read back and compared with the CPU twin's, and its V with the CPU
/// twin's lookup on that map.
fn random_case(ctx: &Arc<GpuContext>, c: &Case, tally: &mut MapTally) -> Result<CaseStats, String> {
    let tol = Tolerance {
        abs: T_TOL,
        ..Tolerance::TWIN
    };
    let rec = receivers_of(c);
    let gpu_rec = GpuReceivers::upload(ctx, &rec).map_err(|e| e.to_string())?;
    let v = view(c.r);
    let views = [Some(v)];
    let mut all = CaseStats::default();
    for lk in LOOKUPS {
        let light = test_support::fixtures::light_of_shape(lk.shape, lk.l, 3.0);
        let semi = scene_of(c, light);
        for scene in [semi.opaque(), semi] {
            let mut params = Params::new(SPECS).unwrap();
            let r = c.r.to_string();
            let eps = c.epsilon.to_string();
            let fixed = [
                ("resolution", r.as_str()),
                ("epsilon", eps.as_str()),
                ("receiver_plane", "false"),
                ("bias", "0"),
                ("slope_bias", "0"),
                ("c", "60"),
            ];
            for (k, x) in fixed.iter().chain(lk.params) {
                params.set(k, x).unwrap();
            }
            let s = Settings::from_params(&params).unwrap();
            let what = format!("{:?} light shape {} l {}", lk.params, lk.shape, lk.l);
            let what = if scene.is_opaque() {
                format!("{what} (opaque)")
            } else {
                what
            };
            let frame = DeepShadowFrame::prepare(ctx.clone(), &params, rec.len() as u32)
                .map_err(|e| format!("{what}: {e}"))?;
            let casters = GpuScene::upload(ctx, &scene).map_err(|e| e.to_string())?;
            let (vg, status) = encode_once(ctx, &frame, &scene, &casters, &gpu_rec, &views);
            if status != FrameStatus::default() {
                return Err(format!("{what}: status {status:?}"));
            }
            let map = frame.read_map().map_err(|e| format!("{what}: {e}"))?;
            match &map {
                FrameMap::Lists(g) => {
                    let cm = build_deep_map(&scene, &v, &s).unwrap();
                    compare_maps(&cm, g).map_err(|e| format!("{what}: lists: {e}"))?;
                    tally.lists += 1;
                    tally.fragments += g.stats().fragments;
                }
                FrameMap::Depths(g) => {
                    let ls = LightSpace::try_build_in_view(
                        &scene,
                        v,
                        FitReport::default(),
                        &LightSpaceRequest::single(c.r),
                    )
                    .unwrap();
                    compare_depths(&ls.layers[0], g).map_err(|e| format!("{what}: depths: {e}"))?;
                    tally.depths += 1;
                }
            }
            if scene.is_opaque() != matches!(map, FrameMap::Depths(_)) {
                return Err(format!("{what}: the frame took the other path"));
            }
            let vc = cpu_on_map(&map, &scene, &rec, &v, &s);
            let cmp = tol.compare(&what, rec.active(), &vc, &vg)?;
            let st = tol.judge(&what, &cmp, &rec, &vc, &vg, |beyond| {
                Ok(beyond
                    .iter()
                    .map(|&k| explain(&tol, &map, &scene, &rec, &v, &s, k, (vc[k], vg[k])))
                    .collect())
            })?;
            all.receivers += st.receivers;
            all.beyond += st.beyond;
            all.ties += st.ties;
            all.max_dv = all.max_dv.max(st.max_dv);
            for (a, b) in all.classes.iter_mut().zip(st.classes) {
                *a += b;
            }
        }
    }
    Ok(all)
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

/// How far the GPU estimator's V may lie from the CPU twin's own build on a fixture, as
/// `(fraction of the active receivers beyond 1e-4, largest |dV|, RMSE)`. The frame's maps come
/// from the hardware rasteriser, whose sub-pixel vertex snapping (8 bits on lavapipe) covers a
/// texel centre within 1/256 texel of a caster's edge that the CPU's exact fill rule does not,
/// or the reverse: on an opaque fixture (bunny) that moved nothing here, and the bound is the
/// twins' own; on thin semi-transparent strands (hair, strands at 40 x 30, resolution 256) a
/// one-tap filter (`none`, `first`) moves a receiver by a fragment's whole opacity (measured: at
/// most 0.9% of the receivers, RMSE 0.029), a filter over many taps by a tap's share, or under
/// PCSS a blocker depth in or out of the average (measured: up to 13.7% of the receivers beyond
/// 1e-4, max 0.087, RMSE 2.6e-3 on hair under PCSS). [`frame_on_its_map`] shows that the maps
/// are the whole difference.
fn raster_bound(scene: &Scene, kv: &[(&str, &str)]) -> (f64, f32, f64) {
    let one_tap = kv
        .iter()
        .any(|&(k, v)| k == "filter" && (v == "none" || v == "first"));
    if scene.is_opaque() {
        (0.001, 1e-3, 1e-4)
    } else if one_tap {
        (0.015, 1.0, 0.04)
    } else {
        (0.15, 0.1, 3e-3)
    }
}

/// The estimators on a fixture, `what`: V of the GPU estimator against the CPU twin's over the
/// active receivers of `rec`, finite, within `(beyond, max, rmse)` ([`raster_bound`]).
fn assert_fixture_within(
    what: &str,
    vc: &[f32],
    vg: &[f32],
    rec: &Receivers,
    (beyond, max, rmse): (f64, f32, f64),
) {
    let n = rec.active_count();
    let (mut far, mut worst) = (0usize, 0.0f32);
    for k in 0..rec.len() {
        if rec.active()[k] {
            let d = (vc[k] - vg[k]).abs();
            assert!(
                d.is_finite(),
                "{what}: receiver {k}: {} vs {}",
                vc[k],
                vg[k]
            );
            far += usize::from(d > 1e-4);
            worst = worst.max(d);
        }
    }
    let e = test_support::fixtures::rmse(vc, vg, rec.active());
    println!(
        "{what}: {far} of {n} beyond 1e-4 of the CPU twin, max |dV| {worst:.2e}, rmse {e:.2e}"
    );
    assert!(
        far as f64 <= beyond * n as f64 && worst <= max && e <= rmse,
        "{what}: {far} of {n} beyond 1e-4, max |dV| {worst}, rmse {e}"
    );
}

/// The GPU estimator's V `vg` on a fixture, `what`, taken apart when its settings `kv` render
/// one view: the frame itself, prepared with `kv` in the views it fits, gives `vg` bit for bit
/// (but for receivers it left to the redo), and the CPU twin's lookup on the frame's own map
/// (read back) gives it within the twins' tolerance ([`Tolerance::TWIN`], each receiver beyond
/// a tie [`explain`] shows). Returns the comparison's counts, `None` for several views.
fn frame_on_its_map(
    what: &str,
    ctx: &Arc<GpuContext>,
    kv: &[(&str, &str)],
    scene: &Scene,
    rec: &Receivers,
    vg: &[f32],
) -> Option<CaseStats> {
    let mut params = Params::new(SPECS).unwrap();
    for (k, v) in kv {
        params.set(k, v).unwrap();
    }
    let s = Settings::from_params(&params).unwrap();
    let frame = DeepShadowFrame::prepare(ctx.clone(), &params, rec.len() as u32).unwrap();
    let views = frame.fit_views(scene, rec).unwrap();
    let [Some(view)] = views[..] else {
        return None;
    };
    let casters = GpuScene::upload(ctx, scene).unwrap();
    let gpu_rec = GpuReceivers::upload(ctx, rec).unwrap();
    let (mut vf, st) = encode_once(ctx, &frame, scene, &casters, &gpu_rec, &views);
    assert_eq!((st.outside, st.nonfinite), (0, 0), "{what}: {st:?}");
    let map = frame.read_map().unwrap();
    let vc = cpu_on_map(&map, scene, rec, &view, &s);
    let mut cut = 0;
    for k in 0..rec.len() {
        if rec.active()[k] && vf[k].is_nan() {
            // Left to the redo (the loop budget): the CPU twin's, out of the comparison.
            cut += 1;
            vf[k] = vc[k];
        } else {
            assert_eq!(vf[k].to_bits(), vg[k].to_bits(), "{what}: receiver {k}");
        }
    }
    assert_eq!(cut, st.left_nan as usize, "{what}: {st:?}");
    let tol = Tolerance::TWIN;
    let cmp = tol.compare(what, rec.active(), &vc, &vf).unwrap();
    let judged = tol.judge(what, &cmp, rec, &vc, &vf, |beyond| {
        Ok(beyond
            .iter()
            .map(|&k| explain(&tol, &map, scene, rec, &view, &s, k, (vc[k], vf[k])))
            .collect())
    });
    let st = judged.unwrap_or_else(|e| panic!("{e}"));
    let lists = match &map {
        FrameMap::Lists(d) => format!("{} fragments", d.stats().fragments),
        FrameMap::Depths(_) => "depths".into(),
    };
    println!(
        "{what}: frame vs the CPU twin on the frame's map ({lists}): max |dV| {:.2e}, {} of {} \
         beyond 1e-4 ({} ties), {cut} left to the redo",
        st.max_dv, st.beyond, st.receivers, st.ties
    );
    Some(st)
}

/// The deep-shadow twins, as the conformance suite drives them.
struct DeepShadow;

impl TwinPair for DeepShadow {
    test_support::twin_constructors!(
        CpuDeepShadow,
        descriptor = deep_shadow::DESCRIPTOR,
        fixed = strands_case()
    );

    /// The engine path on the strands (semi-transparent: the frame builds lists, as the CPU
    /// twin does).
    fn frame(
        &self,
        ctx: &Arc<GpuContext>,
        params: &test_support::conformance::Params,
    ) -> Option<BoxedFrame> {
        let t = table(SPECS, params);
        Some(Box::new(
            DeepShadowFrame::prepare(ctx.clone(), &t, 1 << 16).unwrap(),
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

    /// The frame's maps and V against the CPU twin's on random stacks of sheets
    /// ([`random_case`]).
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let mut tally = MapTally::default();
        let tol = Tolerance {
            abs: T_TOL,
            ..Tolerance::TWIN
        };
        let st = random_twins(
            "deep-shadow random sheets",
            proptest_config(source_file, 8),
            &arb_case(),
            &tol,
            |c| random_case(ctx, c, &mut tally).map(Some),
        );
        println!("deep-shadow random sheets: maps compared {tally:?}");
        assert!(
            tally.lists > 0 && tally.depths > 0 && tally.fragments > 0,
            "{tally:?}"
        );
        st.assert_met("deep-shadow random sheets", true, true, true);
    }

    /// Lists long enough to spend llvmpipe's loop budget (65535 iterations per invocation):
    /// 1500 stacked sheets of opacity 0.002 over a ground, no truncation (`epsilon=0`), so
    /// every covered texel holds a list of 1500 elements, sorted by selection (past 64) in
    /// `process`, and the receivers on the ground under them walk whole lists at each of the
    /// 7 x 7 PCF taps (`traversal=naive`). The frame leaves the receivers its cut `process` or
    /// lookups reach NaN and counts them (status word 2); the GPU estimator redoes them with the
    /// CPU twin in the same views (`frame_cpu_redo`): V must equal the CPU twin's on any device,
    /// and on llvmpipe the cut must have happened (the probe is what found it).
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
        let kv = [
            ("resolution", "16"),
            ("filter", "pcf"),
            ("kernel", "7"),
            ("traversal", "naive"),
            ("epsilon", "0"),
        ];
        let mut c = CpuDeepShadow::new().unwrap();
        let mut g = self.gpu(ctx);
        let mut params = Params::new(SPECS).unwrap();
        for (k, v) in kv {
            c.set_param(k, v).unwrap();
            g.set_param(k, v).unwrap();
            params.set(k, v).unwrap();
        }
        // The GPU estimator's V, then the CPU twin's.
        let (vg, rg) = run(&mut *g, &scene, &rec).unwrap();
        let (vc, _) = run(&mut c, &scene, &rec).unwrap();
        // The frame alone: the receivers it cuts are NaN and counted, the others the CPU's.
        let frame = DeepShadowFrame::prepare(ctx.clone(), &params, rec.len() as u32).unwrap();
        let views = frame.fit_views(&scene, &rec).unwrap();
        let casters = GpuScene::upload(ctx, &scene).unwrap();
        let gpu_rec = GpuReceivers::upload(ctx, &rec).unwrap();
        let (vf, st) = encode_once(ctx, &frame, &scene, &casters, &gpu_rec, &views);
        let cut = (0..rec.len()).filter(|&k| vf[k].is_nan()).count();
        assert_eq!(cut, st.left_nan as usize, "{st:?}");
        for k in (0..rec.len()).filter(|&k| !vf[k].is_nan()) {
            assert!(
                (vf[k] - vc[k]).abs() <= 1e-4,
                "receiver {k}: {} vs {}",
                vf[k],
                vc[k]
            );
        }
        // The GPU estimator: every cut receiver redone on the CPU.
        let redone = note(&rg, "frame_cpu_redo").unwrap_or_else(|| "0".into());
        eprintln!(
            "loop-limit CPU redo on {}: {redone} of {} receivers (the frame alone: {cut} cut)",
            ctx.describe(),
            rec.len(),
        );
        assert_eq!(redone, cut.to_string(), "{rg:?}");
        for (k, (a, b)) in vc.iter().zip(&vg).enumerate() {
            assert!((a - b).abs() <= 1e-6, "receiver {k}: CPU {a}, GPU {b}");
        }
        assert!(
            vc.iter().any(|&v| v < 0.2),
            "the sheets should shadow: {vc:?}"
        );
        if ctx.describe().contains("llvmpipe") {
            assert!(cut > 0, "no receiver cut on llvmpipe: {st:?}");
        }
    }

    /// Both estimators on the fixtures `hair`, `strands` and `bunny` through the CLI path, every
    /// filter mode: the same name and description, the same views, the GPU estimator's V within
    /// the contract and within [`raster_bound`] of the CPU twin's (the opaque bunny renders one
    /// depth map per view, the strands and the hair lists); with one view, the CPU twin's
    /// lookups on the frame's own map give the GPU estimator's V within the twins' tolerance
    /// ([`frame_on_its_map`]).
    fn cli_path_matches_the_cpu_twin(&self, ctx: &Arc<GpuContext>) {
        let mut on_map = RunStats::default();
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
                let mut g = self.gpu(ctx);
                let kv: Vec<(&str, &str)> =
                    kv.iter().chain(&[("resolution", "256")]).copied().collect();
                for (k, v) in &kv {
                    c.set_param(k, v).unwrap();
                    g.set_param(k, v).unwrap();
                }
                assert_eq!((c.name(), c.description()), (g.name(), g.description()));
                let (vc, rc) = run(&mut c, &scene, &rec).unwrap();
                let (vg, rg) = run(&mut *g, &scene, &rec).unwrap();
                check_contract(&vg, &rec);
                assert_eq!(note(&rg, "engine_path").as_deref(), Some("frame twin"));
                assert_eq!(note(&rc, "views"), note(&rg, "views"), "{name} {kv:?}");
                let what = format!("{name} {kv:?}");
                assert_fixture_within(&what, &vc, &vg, &rec, raster_bound(&scene, &kv));
                if let Some(st) = frame_on_its_map(&what, ctx, &kv, &scene, &rec, &vg) {
                    on_map.add(&st);
                }
            }
        }
        let label = "deep-shadow fixtures, frame vs the CPU twin on the frame's map";
        println!("{}", on_map.summary(label, &Tolerance::TWIN));
        on_map.assert_within(label, &Tolerance::TWIN);
    }
}

/// A `max_capacity` below the fragments one view needs is a typed error on the GPU estimator too:
/// the frame's element buffer takes at most `max_capacity` elements, the overflowing frame
/// leaves its receivers for the redo, and the CPU twin's build refuses with the need.
#[test]
fn gpu_max_capacity_below_the_need_is_a_typed_error() {
    let Some(ctx) = test_support::gpu("gpu_max_capacity_below_the_need_is_a_typed_error") else {
        return;
    };
    let (scene, rec) = fixture("strands", 32, 24);
    let kv = [("resolution", "64"), ("filter", "none")];
    let mut c = CpuDeepShadow::new().unwrap();
    let mut g = deep_shadow::DESCRIPTOR.gpu(ctx).unwrap().unwrap();
    for (k, v) in kv {
        c.set_param(k, v).unwrap();
        g.set_param(k, v).unwrap();
    }
    let (_, rc) = run(&mut c, &scene, &rec).unwrap();
    let need: u64 = note(&rc, "fragments").unwrap().parse().unwrap();
    g.set_param("max_capacity", "100").unwrap();
    match run(&mut *g, &scene, &rec) {
        Err(Error::Limit { requested, max, .. }) => {
            assert_eq!(requested, need);
            assert_eq!(max, 100);
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(_) => panic!("expected a limit error"),
    }
}

/// Every `fit` x `nearfar` combination on a semi-transparent fixture (deep lists) and an opaque
/// one, through both estimators, with a filter margin (`pcf`/`edsm`, the stable fit's lattice
/// margin included): V in [0, 1] and finite for every active receiver, within [`raster_bound`]
/// of the CPU twin's and with one view the CPU twin's on the frame's own map
/// ([`frame_on_its_map`]), the frame's views those of the CPU twin (`near`, `far`), and
/// the choices reach the view (`fit=receivers` has window_scale 1 before the filter margin,
/// `fit=stable` more).
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
        for fit in ["receivers", "scene", "stable"] {
            let mut planes = Vec::new();
            for nearfar in ["clipped", "aabb", "frustum"] {
                let mut c = CpuDeepShadow::new().unwrap();
                let mut g = deep_shadow::DESCRIPTOR.gpu(ctx.clone()).unwrap().unwrap();
                let mut params = Params::new(SPECS).unwrap();
                let all = [("resolution", "128"), ("fit", fit), ("nearfar", nearfar)];
                for (k, v) in kv.iter().chain(&all) {
                    c.set_param(k, v).unwrap();
                    g.set_param(k, v).unwrap();
                    params.set(k, v).unwrap();
                }
                let what = format!("{name} {kv:?} fit={fit} nearfar={nearfar}");
                let (vc, rc) = run(&mut c, &scene, &rec).unwrap();
                let (vg, _) = run(&mut *g, &scene, &rec).unwrap();
                check_contract(&vc, &rec);
                check_contract(&vg, &rec);
                let frame = DeepShadowFrame::prepare(ctx.clone(), &params, 1).unwrap();
                let views = frame.fit_views(&scene, &rec).unwrap();
                let n = views.iter().flatten().map(|v| v.n).fold(f32::MAX, f32::min);
                let far = views.iter().flatten().map(|v| v.far).fold(0.0, f32::max);
                assert_eq!(note(&rc, "near"), Some(n.to_string()), "{what}: near");
                assert_eq!(note(&rc, "far"), Some(far.to_string()), "{what}: far");
                let all: Vec<(&str, &str)> = kv.iter().chain(&all).copied().collect();
                assert_fixture_within(&what, &vc, &vg, &rec, raster_bound(&scene, &all));
                frame_on_its_map(&what, &ctx, &all, &scene, &rec, &vg);
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

/// Receivers beyond the light view's reach (`tests/cpu.rs`
/// `receivers_beyond_the_view_are_settled_or_refused`): the GPU estimator's frame looks the far
/// receiver up outside its map, counts it (`OutsideViews`, the status's first word) and gives it
/// its facing fraction, which on the open side is the CPU twin's settled V; on the walled side,
/// where the CPU twin refuses (no map defines its transmittance), the GPU estimator's report
/// warns of it. Settling or refusing without a map is the registry's caster-aware fitting's job
/// on the frame path.
#[test]
fn gpu_receivers_beyond_the_view_are_counted_outside() {
    let Some(ctx) = test_support::gpu("gpu_receivers_beyond_the_view_are_counted_outside") else {
        return;
    };
    let outside = |r: &shadow_map_core::Report| {
        r.warnings
            .iter()
            .find_map(|w| match w {
                Warning::OutsideViews { receivers } => Some(*receivers),
                _ => None,
            })
            .unwrap_or(0)
    };
    let (open, rec) = beyond_reach(false);
    let mut g = deep_shadow::DESCRIPTOR.gpu(ctx.clone()).unwrap().unwrap();
    let (v, rep) = run(&mut *g, &open, &rec).unwrap();
    let (vc, rc) = run(&mut CpuDeepShadow::new().unwrap(), &open, &rec).unwrap();
    assert_eq!(note(&rc, "settled_outside").as_deref(), Some("1"));
    assert!((v[0] - vc[0]).abs() <= 1e-4, "{} vs {}", v[0], vc[0]);
    assert!((v[1] - vc[1]).abs() <= 1e-6, "{} vs {}", v[1], vc[1]);
    assert_eq!(outside(&rep), 1, "{rep:?}");
    let (walled, rec) = beyond_reach(true);
    assert!(matches!(
        run(&mut CpuDeepShadow::new().unwrap(), &walled, &rec),
        Err(Error::Receivers(_))
    ));
    let (_, rep) = run(&mut *g, &walled, &rec).unwrap();
    assert_eq!(outside(&rep), 1, "{rep:?}");
}
