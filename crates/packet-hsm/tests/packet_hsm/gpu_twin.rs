//! Packet HSM's GPU path against its CPU twin: the conformance suite of `test-support`
//! (`twin::packet_hsm`, the GPU side the registry's estimator, the frame run by the core's
//! `FrameTwin`), with what is specific to packet HSM here.
//!
//! The kernel is compared in isolation ([`on_frame_maps`]): the frame renders its maps, and the
//! CPU twin runs on those very maps read back (every view's, each recorded again alone and
//! checked bit for bit against the frame's where a whole frame leaves them), so hardware raster
//! ties do not count. On random scenes (rect, disk or sphere light) with random resolution,
//! hierarchy, sub-lights, self-shadow, receiver-plane and light-view (`fit`, `nearfar`)
//! settings; packet size and coherence are random too, though the frame has no packets
//! (receivers in a buffer carry no image layout) and the CPU side is the per-pixel path they
//! must not change.
//!
//! Tolerance: the GPU does the set-up, the light-plane geometry and the edge sum in f32 (the CPU
//! the geometry and sum in f64). Per receiver `|dV| <= 1e-4` on at least 99.9% of the active
//! receivers, and every receiver within 0.05 ([`TWIN`]; rare f32 ties: a receiver's projection
//! within an f32 ulp of a cell boundary is nudged on one side only, or a sample almost at the
//! receiver's depth backprojects to a huge scale whose f32 and f64 clips differ). Receivers the
//! device's loop budget cut short are left NaN by the frame, counted in its status, and left out
//! of the comparison (the registry's estimator redoes them on the CPU:
//! `loop_limit_is_detected_and_redone`).
#![cfg(feature = "gpu")]
use crate::common;
use common::*;
use glam::Vec3;
use packet_hsm::{CpuPacketHsm, PacketHsmFrame, DESCRIPTOR};
use proptest::prelude::*;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, GpuContext},
    run, LightSpace, LightView, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use std::sync::Arc;
use test_support::{
    conformance::{random_twins, table, BoxedFrame, FixedCase, Params, TwinPair},
    frame_run::run_frame,
    proptest_config, CaseStats, Tolerance,
};

/// `|dV| <= 1e-4` on 99.9% of the active receivers, every one within 0.05.
const TWIN: Tolerance = Tolerance::TWIN.with_max(0.05);

test_support::twin_suite! {
    packet_hsm [loop_limit_is_detected_and_redone, frame_path_matches_the_cpu_twin] => PacketHsm,
}

fn scene(light: f32, height: f32, squares: &[(f32, f32, f32, f32)]) -> Scene {
    shaped_scene(light, height, squares, 0)
}

/// [`scene`] under a rect light of side `light` (`shape` 0), or a disk (1) or sphere (2) light of
/// diameter `light`.
fn shaped_scene(light: f32, height: f32, squares: &[(f32, f32, f32, f32)], shape: u8) -> Scene {
    let mut meshes = vec![
        (quad(-4.0, -4.0, 4.0, 4.0, 0.0), 1.0),
        (quad(SQUARE.0, SQUARE.1, SQUARE.2, SQUARE.3, SQUARE.4), 1.0),
    ];
    for &(x, z, s, y) in squares {
        meshes.push((quad(x, z, x + s, z + s, y), 1.0));
    }
    // A tilted triangle for non-constant depths.
    meshes.push((
        vec![[
            Vec3::new(-1.6, 0.4, 1.0),
            Vec3::new(-0.4, 1.6, 1.3),
            Vec3::new(-1.0, 1.0, 0.2),
        ]],
        1.0,
    ));
    let l = light_of_shape(shape, light, height);
    Scene::from_meshes("twin", camera(32, 24), l, meshes).unwrap()
}

/// A report note's value, "" when absent.
fn note(r: &shadow_map_core::Report, key: &str) -> String {
    test_support::fixtures::note(r, key).unwrap_or_default()
}

/// The registry's GPU estimator (the frame run by `FrameTwin`) with the parameters `kv`.
fn gpu_estimator(ctx: &Arc<GpuContext>, kv: &[(&str, &str)]) -> Box<dyn SoftShadowEstimator> {
    let mut g = DESCRIPTOR.gpu(ctx.clone()).expect("a frame").expect("gpu");
    for (k, v) in kv {
        g.set_param(k, v).unwrap();
    }
    g
}

/// One frame against the CPU twin on the frame's own maps ([`on_frame_maps`]).
struct OnMaps {
    /// The frame's V, NaN where the device's loop budget cut a receiver short.
    gpu: Vec<f32>,
    /// The CPU twin's V on the maps the frame rendered, in its views.
    cpu: Vec<f32>,
    /// The views the frame fitted.
    views: Vec<Option<LightView>>,
    /// Active receivers the frame left NaN (cut), as many as its status counts.
    cut: Vec<usize>,
    /// Receivers outside some view (summed over views), from the frame's status.
    outside: u32,
}

impl OnMaps {
    /// The two outputs with the cut receivers left out (made inactive, NaN on both), for
    /// [`Tolerance::compare`]: `(active, cpu, gpu)`.
    fn compared(&self, rec: &Receivers) -> (Vec<bool>, Vec<f32>, Vec<f32>) {
        let (mut active, mut cpu, mut gpu) =
            (rec.active().to_vec(), self.cpu.clone(), self.gpu.clone());
        for &k in &self.cut {
            active[k] = false;
            cpu[k] = f32::NAN;
            gpu[k] = f32::NAN;
        }
        (active, cpu, gpu)
    }

    /// [`Tolerance::assert_twins`] under [`TWIN`] over the receivers not cut: the fraction
    /// within 1e-4 and the largest |dV|.
    fn assert_twins(&self, rec: &Receivers, what: &str) -> (f64, f32) {
        let (active, cpu, gpu) = self.compared(rec);
        TWIN.assert_twins(what, &active, &cpu, &gpu)
    }
}

/// Packet-hsm's frame prepared with `kv` for up to `max_receivers` receivers.
fn prepared(ctx: &Arc<GpuContext>, kv: &[(&str, &str)], max_receivers: usize) -> PacketHsmFrame {
    PacketHsmFrame::prepare(ctx.clone(), &table_of(kv), max_receivers.max(1) as u32)
        .unwrap_or_else(|e| panic!("{kv:?}: prepare: {e}"))
}

/// [`on_frame_maps`] with a frame prepared for `kv` and `rec` alone.
fn on_new_frame_maps(
    ctx: &Arc<GpuContext>,
    kv: &[(&str, &str)],
    scene: &Scene,
    rec: &Receivers,
    what: &str,
) -> OnMaps {
    on_frame_maps(ctx, &prepared(ctx, kv, rec.len()), scene, rec, what)
}

/// `frame` on `scene` and `rec`: one frame as a renderer records it ([`run_frame`]), V and the
/// status read back; then each view's maps recorded again alone
/// ([`PacketHsmFrame::encode_view_maps`]) and read back, the last view's checked bit for bit
/// against what the whole frame left; the CPU twin on those maps
/// ([`PacketHsmFrame::cpu_twin_in_maps`]). Panics (naming `what`) on an error, an active
/// receiver NaN without the status counting it, or an inactive one not NaN on both.
fn on_frame_maps(
    ctx: &Arc<GpuContext>,
    frame: &PacketHsmFrame,
    scene: &Scene,
    rec: &Receivers,
    what: &str,
) -> OnMaps {
    let (rig, out) =
        run_frame(ctx, frame, scene, rec).unwrap_or_else(|e| panic!("{what}: frame: {e}"));
    let (gpu, views, inputs) = (out.v, &rig.views, rig.inputs());
    let status = out.status.expect("a status buffer");
    assert_eq!(status.nonfinite, 0, "{what}: non-finite V ({status:?})");
    let read = |view: &LightView| frame.light_space(view).to_cpu(ctx).unwrap();
    let last = views.last().copied().flatten().expect("a view");
    let whole_frame = read(&last);
    let maps: Vec<LightSpace> = (0..views.len())
        .map(|slot| {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            frame
                .encode_view_maps(&mut enc, &inputs, slot)
                .unwrap_or_else(|e| panic!("{what}: view {slot}'s maps: {e}"));
            ctx.queue.submit([enc.finish()]);
            read(&views[slot].expect("every view"))
        })
        .collect();
    let bits = |ls: &LightSpace| {
        let planes = ls.layers.iter().chain(&ls.midpoints);
        planes
            .flat_map(|m| m.depth.iter().map(|x| x.to_bits()))
            .collect::<Vec<_>>()
    };
    assert!(
        bits(&whole_frame) == bits(maps.last().unwrap()),
        "{what}: the last view's maps recorded alone differ from the frame's"
    );
    let cpu = frame
        .cpu_twin_in_maps(scene, rec, maps)
        .unwrap_or_else(|e| panic!("{what}: CPU twin on the frame's maps: {e}"));
    let mut cut = Vec::new();
    for k in 0..rec.len() {
        if !rec.active()[k] {
            assert!(gpu[k].is_nan() && cpu[k].is_nan(), "{what}: inactive #{k}");
        } else if gpu[k].is_nan() {
            cut.push(k);
        }
    }
    assert_eq!(
        cut.len(),
        status.left_nan as usize,
        "{what}: active receivers left NaN against the status' count ({status:?})"
    );
    OnMaps {
        gpu,
        cpu,
        views: views.clone(),
        cut,
        outside: status.outside,
    }
}

/// The fixed case: the random scenes' scene with one square, the camera's receivers with every
/// seventh one inactive, resolution 64.
fn fixed_case() -> FixedCase {
    let scene = scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1)]);
    let mut receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    for (k, a) in receivers.active_mut().iter_mut().enumerate() {
        if k % 7 == 6 {
            *a = false;
        }
    }
    FixedCase {
        scene,
        receivers,
        params: vec![("resolution", "64".to_string())],
    }
}

/// Packet HSM's twins, as the conformance suite drives them.
struct PacketHsm;

impl TwinPair for PacketHsm {
    test_support::twin_constructors!(CpuPacketHsm, descriptor = DESCRIPTOR, fixed = fixed_case());

    fn frame(&self, ctx: &Arc<GpuContext>, params: &Params) -> Option<BoxedFrame> {
        let params = table(packet_hsm::settings::SPECS, params);
        let frame = PacketHsmFrame::prepare(ctx.clone(), &params, 1 << 12).expect("frame");
        Some(Box::new(frame))
    }

    /// Random scenes, resolutions, hierarchy, sub-lights, self-shadow, receiver planes and light
    /// views (packet sizes and coherence too, which the frame does not read): the frame against
    /// the CPU twin on the frame's own maps ([`on_frame_maps`]).
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let strat = (
            0.3f32..2.0,
            2.5f32..4.0,
            prop::collection::vec(
                (-1.5f32..1.0, -1.5f32..1.0, 0.2f32..1.0, 0.05f32..2.0),
                0..3,
            ),
            prop::sample::select(vec![32u32, 64, 128]),
            any::<bool>(),
            (any::<bool>(), any::<bool>()),
            (prop::sample::select(vec!["1", "2"]), any::<bool>()),
            prop::sample::select(vec!["1x1", "2x2", "3x3", "4x2", "8x8"]),
            (
                prop::sample::select(vec!["receivers", "scene", "stable"]),
                prop::sample::select(vec!["clipped", "aabb", "frustum"]),
            ),
            0u8..3,
        );
        let mut cut = 0usize;
        let st = random_twins(
            "packet-hsm frame on its maps",
            proptest_config(source_file, 8),
            &strat,
            &TWIN,
            |(
                light,
                height,
                squares,
                res,
                hier,
                (bias, plane),
                (sl, coh),
                packet,
                (fit, nearfar),
                shape,
            )| {
                // Disk and sphere lights are one view (sublights=1; the frame refuses others).
                let sl = if *shape != 0 { "1" } else { sl };
                let s = shaped_scene(*light, *height, squares, *shape);
                let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
                let (res, hier, coh, plane) = (
                    res.to_string(),
                    hier.to_string(),
                    coh.to_string(),
                    plane.to_string(),
                );
                let ss = if *bias { "bias" } else { "midpoint" };
                let kv = [
                    ("coherence", coh.as_str()),
                    ("resolution", res.as_str()),
                    ("hierarchy", hier.as_str()),
                    ("self_shadow", ss),
                    ("sublights", sl),
                    ("packet", *packet),
                    ("fit", *fit),
                    ("nearfar", *nearfar),
                    ("receiver_plane", plane.as_str()),
                ];
                let what = format!("shape {shape} {kv:?}");
                let m = on_new_frame_maps(ctx, &kv, &s, &rec, &what);
                let n: usize = sl.parse().unwrap();
                if m.views.len() != n * n {
                    return Err(format!("{what}: {} views", m.views.len()));
                }
                cut += m.cut.len();
                let (active, cpu, gpu) = m.compared(&rec);
                let cmp = TWIN.compare(&what, &active, &cpu, &gpu)?;
                let allowed = TWIN.allowed_beyond(cmp.receivers);
                if cmp.receivers == 0 || cmp.beyond.len() > allowed {
                    return Err(format!(
                        "{what}: {} of {} receivers beyond {} ({allowed} allowed), max |dV| {}",
                        cmp.beyond.len(),
                        cmp.receivers,
                        TWIN.abs,
                        cmp.max_dv
                    ));
                }
                eprintln!(
                    "{what}: {} of {} beyond 1e-4, max |dV| {:.2e}, {} cut",
                    cmp.beyond.len(),
                    cmp.receivers,
                    cmp.max_dv,
                    m.cut.len()
                );
                Ok(Some(CaseStats {
                    receivers: cmp.receivers,
                    beyond: cmp.beyond.len(),
                    ties: 0,
                    max_dv: cmp.max_dv,
                    classes: cmp.classes,
                }))
            },
        );
        eprintln!("packet-hsm frame on its maps: {cut} receivers cut (left out)");
        st.assert_met("packet-hsm frame on its maps", true, true, true);
    }

    /// Large kernels without the hierarchy (an occluder near the light, a large light): on
    /// lavapipe a flat scan exceeds llvmpipe's 65535 loop iterations per invocation (on the
    /// raised receivers at r = 88, for some receivers and not others). The kernel
    /// must flag those receivers (the frame leaves them NaN and counts them; the rest agrees with
    /// the CPU twin on the frame's maps), and the registry's estimator must redo exactly those on
    /// the CPU (its report's `frame_cpu_redo`): there V is the frame's CPU twin's in the same
    /// views, elsewhere the frame's.
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let s = scene_with(
            rect_light(2.0, 3.0),
            &[(-0.5, -0.5, 0.5, 0.5, 2.6), SQUARE],
            8,
            8,
        );
        let line = line_receivers();
        // The line, and the line raised halfway to the occluder (smaller kernels): at r = 88 a
        // flat scan of the first is cut on lavapipe, of the second not.
        let raised = {
            let p = line.position();
            let up = p.iter().map(|p| *p + 1.5 * Vec3::Y);
            let pos: Vec<Vec3> = p.iter().copied().chain(up).collect();
            Receivers::from_points(pos, vec![Vec3::Y; 2 * p.len()]).unwrap()
        };
        for (res, p, h, r) in [
            ("256", "1x1", "false", &line),
            ("256", "8x8", "false", &line),
            ("256", "1x1", "true", &line),
            ("88", "1x1", "false", &raised),
        ] {
            let kv = [("resolution", res), ("packet", p), ("hierarchy", h)];
            let what = format!("large kernels {kv:?} ({} receivers)", r.len());
            let frame = prepared(ctx, &kv, r.len());
            let m = on_frame_maps(ctx, &frame, &s, r, &what);
            let active = r.active().iter().filter(|a| **a).count();
            // Every receiver may be cut (a flat scan of the line on lavapipe).
            let worst = if m.cut.len() < active {
                m.assert_twins(r, &what).1
            } else {
                0.0
            };
            let mut g = gpu_estimator(ctx, &kv);
            let (vg, rep) = run(&mut *g, &s, r).unwrap();
            let redo = note(&rep, "frame_cpu_redo");
            let expected = if m.cut.is_empty() {
                String::new()
            } else {
                m.cut.len().to_string()
            };
            assert_eq!(redo, expected, "{what}: receivers redone on the CPU");
            let cpu = frame.cpu_twin(&s, r, &m.views).unwrap();
            for k in 0..r.len() {
                let want = if m.cut.contains(&k) { cpu[k] } else { m.gpu[k] };
                assert!(
                    vg[k].to_bits() == want.to_bits(),
                    "{what}: #{k} {} from the estimator, want {want} (cut: {})",
                    vg[k],
                    m.cut.contains(&k)
                );
            }
            eprintln!(
                "{what}: worst {worst:e} on the frame's maps, {} of {active} cut and redone on \
                 the CPU",
                m.cut.len()
            );
        }
    }
}

/// Disk and sphere lights (docs/methods.md §3 "Disk lights", "Sphere lights") through the frame,
/// hierarchy on and off: V in [0, 1], within the twin tolerance of the CPU twin on the frame's
/// maps, and in shadow somewhere.
#[test]
fn frame_disk_and_sphere_lights_match_the_cpu_twin() {
    let Some(ctx) = test_support::gpu("frame_disk_and_sphere_lights_match_the_cpu_twin") else {
        return;
    };
    let scenes: Vec<(u8, Scene, Receivers)> = [1u8, 2]
        .into_iter()
        .map(|shape| {
            let s = shaped_scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1)], shape);
            let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
            (shape, s, rec)
        })
        .collect();
    for (p, h) in [("3x3", "true"), ("1x1", "false"), ("4x4", "false")] {
        let kv = [("resolution", "128"), ("packet", p), ("hierarchy", h)];
        // One frame per table, reused across the scenes.
        let most = scenes
            .iter()
            .map(|(_, _, rec)| rec.len())
            .max()
            .unwrap_or(1);
        let frame = prepared(&ctx, &kv, most);
        for (shape, s, rec) in &scenes {
            let what = format!("shape {shape} {kv:?}");
            let m = on_frame_maps(&ctx, &frame, s, rec, &what);
            assert!(m.cpu.iter().any(|&v| v < 0.5), "{what}: no shadow");
            let (f, worst) = m.assert_twins(rec, &what);
            eprintln!(
                "{what}: within {f:.4}, worst {worst:e}, {} cut",
                m.cut.len()
            );
        }
    }
}

/// A semi-transparent occluder (two opacity levels): one view per level, within the twin
/// tolerance of the CPU twin on the frame's maps, partly in shadow.
#[test]
fn frame_opacity_levels_match_the_cpu_twin() {
    let Some(ctx) = test_support::gpu("frame_opacity_levels_match_the_cpu_twin") else {
        return;
    };
    let mut s = shaped_scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1)], 1);
    s.set_mesh_opacity(1, 0.35).unwrap();
    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
    let kv = [("resolution", "128"), ("packet", "3x3")];
    let m = on_new_frame_maps(&ctx, &kv, &s, &rec, "opacity levels");
    assert_eq!(m.views.len(), 2, "one view per opacity level");
    assert!(
        m.cpu.iter().any(|&v| v < 0.9 && v > 0.5),
        "no partial shadow"
    );
    let (f, worst) = m.assert_twins(&rec, "opacity levels");
    eprintln!("frame opacity levels: within {f:.4}, worst {worst:e}");
}

/// Hard cases: huge kernels (an occluder almost at the light), a touching occluder; V valid
/// through the registry's estimator, and the frame within the twin tolerance of the CPU twin
/// on its maps.
#[test]
fn frame_hard_cases_stay_finite() {
    let Some(ctx) = test_support::gpu("frame_hard_cases_stay_finite") else {
        return;
    };
    let kv = [("resolution", "128")];
    let mut g = gpu_estimator(&ctx, &kv);
    let r = line_receivers();
    let frame = prepared(&ctx, &kv, r.len());
    for occ in [
        (-0.5, -0.5, 0.5, 0.5, 3.0 - 1e-4),
        (-0.5, -0.5, 0.5, 0.5, 1e-5),
    ] {
        let s = scene_with(rect_light(1.0, 3.0), &[occ], 8, 8);
        let vg = run(&mut *g, &s, &r).unwrap().0;
        assert_valid(&vg, "gpu hard case");
        let what = format!("hard case {occ:?}");
        let m = on_frame_maps(&ctx, &frame, &s, &r, &what);
        let (_, worst) = m.assert_twins(&r, &what);
        eprintln!("{what}: worst {worst:e}, {} cut", m.cut.len());
    }
}

/// Every `fit` x `nearfar` combination on one scene, 1 and 2 x 2 sub-lights: the frame's views
/// span the CPU twin's planes (its `near` and `far` notes), V in [0, 1] and within the twin
/// tolerance of the CPU twin on the frame's maps, and the choices reach the views (`nearfar`
/// moves the planes, `fit=stable` widens the window).
#[test]
fn every_fit_and_nearfar_match_on_the_frame() {
    let Some(ctx) = test_support::gpu("every_fit_and_nearfar_match_on_the_frame") else {
        return;
    };
    // The second square is above the light (behind it) and out of the camera's view: only the
    // scene's bounding box sees it, so nearfar=aabb puts n at its floor.
    let s = scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1), (3.0, -3.0, 0.5, 3.5)]);
    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
    for sl in ["1", "2"] {
        let mut planes = std::collections::HashMap::new();
        let mut scales = std::collections::HashMap::new();
        for fit in ["receivers", "scene", "stable"] {
            for nearfar in ["clipped", "aabb", "frustum"] {
                let kv = [
                    ("resolution", "64"),
                    ("sublights", sl),
                    ("fit", fit),
                    ("nearfar", nearfar),
                ];
                let what = format!("{kv:?}");
                let (vc, rc) = run(&mut hsm(&kv), &s, &rec).unwrap();
                let m = on_new_frame_maps(&ctx, &kv, &s, &rec, &what);
                let views: Vec<LightView> = m.views.iter().flatten().copied().collect();
                let near = views.iter().map(|v| v.n).fold(f32::INFINITY, f32::min);
                let far = views.iter().map(|v| v.far).fold(0.0, f32::max);
                assert_eq!(note(&rc, "near"), near.to_string(), "{what}: near");
                assert_eq!(note(&rc, "far"), far.to_string(), "{what}: far");
                for (k, x) in vc.iter().enumerate() {
                    assert!(
                        !rec.active()[k] || (0.0..=1.0).contains(x),
                        "{what}: cpu #{k} {x}"
                    );
                }
                let (f, worst) = m.assert_twins(&rec, &what);
                let ws: f32 = note(&rc, "window_scale").parse().unwrap();
                eprintln!(
                    "{what}: within {f:.4}, worst {worst:e}, near {near} far {far} window_scale \
                     {ws}, {} outside on the frame, out_of_frustum {} on the CPU",
                    m.outside,
                    note(&rc, "out_of_frustum")
                );
                planes.insert((fit, nearfar), (near, far));
                scales.insert((fit, nearfar), ws);
            }
        }
        for fit in ["receivers", "scene", "stable"] {
            let p = |nf| planes[&(fit, nf)];
            assert!(
                p("clipped") != p("aabb") && p("clipped") != p("frustum"),
                "sublights {sl} fit={fit}: nearfar did not move the planes"
            );
        }
        for nearfar in ["clipped", "aabb", "frustum"] {
            let (r, st) = (
                scales[&("receivers", nearfar)],
                scales[&("stable", nearfar)],
            );
            assert!((r - 1.0).abs() < 1e-4, "sublights {sl} {nearfar}: {r}");
            // At most 2 (power of two) x the 3-texel margins x one texel of snapping.
            let max = 2.0 * (1.0 + 6.0 / 64.0) * 64.0 / 63.0;
            assert!(st > 1.0 && st <= max, "sublights {sl} {nearfar}: {st}");
        }
    }
}

/// The GPU side of `accuracy.rs`'s `grazing_plane_is_not_self_shadowed`: an unoccluded plane lit
/// at 85 degrees from its normal, at the defaults (receiver-plane rejection on), keeps
/// V >= facing - 0.02 at every receiver through the registry's estimator, with midpoints and
/// with the bias.
#[test]
fn gpu_grazing_plane_is_not_self_shadowed() {
    let Some(ctx) = test_support::gpu("gpu_grazing_plane_is_not_self_shadowed") else {
        return;
    };
    let (s, r, facing) = test_support::fixtures::tilted_plane(85.0, 1.0, (30, -1.0, 0.066));
    for ss in ["midpoint", "bias"] {
        let mut g = gpu_estimator(&ctx, &[("self_shadow", ss)]);
        let worst = test_support::fixtures::most_below(&run(&mut *g, &s, &r).unwrap().0, &facing);
        eprintln!("gpu 85 deg plane, self_shadow={ss}: most below facing {worst:.4}");
        assert!(worst <= 0.02, "self_shadow={ss}: V below facing by {worst}");
    }
}
