//! The GPU twin of packet-based HSM against the CPU twin: the conformance suite of
//! `test-support` (`twin::packet_hsm`), with what is specific to packet HSM here.
//!
//! On random scenes (rect, disk or sphere light), both with the same random packet size,
//! hierarchy, coherence, sub-lights, self-shadow and light-view (`fit`, `nearfar`) settings (both
//! build the same light-space data on the CPU). Besides V, the packet counters must agree: the
//! same packets (same penumbra pixels) and, without the coherence test (f32 on the GPU, f64 on
//! the CPU), the same coherent and diverging packets; and the GPU packets pass must have run.
//!
//! Tolerance: the GPU does the light-plane geometry and the edge sum in f32 (the CPU in f64).
//! Per receiver `|dV| <= 1e-4` on at least 99.9% of the active receivers, and every receiver
//! within 0.05 ([`TWIN`]; rare f32 ties: a receiver's projection within an f32 ulp of
//! a cell boundary is nudged on one side only, or a sample almost at the receiver's depth
//! backprojects to a huge scale whose f32 and f64 clips differ).
#![cfg(feature = "gpu")]
use crate::common;
use common::*;
use glam::Vec3;
use packet_hsm::{CpuPacketHsm, GpuPacketHsm};
use proptest::{prelude::*, test_runner::TestRunner};
use shadow_map_core::{gpu::GpuContext, run, Receivers, Scene, SceneBvh, SoftShadowEstimator};
use std::{cell::RefCell, sync::Arc};
use test_support::{
    conformance::{FixedCase, TwinPair},
    proptest_config, Tolerance,
};

/// `|dV| <= 1e-4` on 99.9% of the active receivers, every one within 0.05.
const TWIN: Tolerance = Tolerance::TWIN.with_max(0.05);

test_support::twin_suite! {
    packet_hsm [loop_limit_is_detected_and_redone] => PacketHsm,
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

/// The twins' outputs under [`TWIN`] ([`Tolerance::assert_twins`]): the fraction within 1e-4
/// and the largest |dV|.
fn compare(cpu: &[f32], gpu: &[f32], rec: &Receivers, what: &str) -> (f64, f32) {
    TWIN.assert_twins(what, rec.active(), cpu, gpu)
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

/// The packet-HSM twins, as the conformance suite drives them.
struct PacketHsm;

impl TwinPair for PacketHsm {
    test_support::twin_constructors!(CpuPacketHsm, GpuPacketHsm, fixed = fixed_case());

    /// Random scenes, packet sizes, hierarchy, coherence, sub-lights, self-shadow and light
    /// views, through the CLI path on both twins: V and the packet counters.
    fn random_scenes(&self, ctx: &Arc<GpuContext>, source_file: &'static str) {
        let g = RefCell::new(GpuPacketHsm::new(ctx.clone()).unwrap());
        let gpu_packets = RefCell::new(0u64);
        let mut runner = TestRunner::new(proptest_config(source_file, 8));
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
        runner
            .run(
                &strat,
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
                    // Disk and sphere lights are one view (sublights=1).
                    let sl = if shape != 0 { "1" } else { sl };
                    let s = shaped_scene(light, height, &squares, shape);
                    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
                    let res = res.to_string();
                    let hier = hier.to_string();
                    let ss = if bias { "bias" } else { "midpoint" };
                    let coh = coh.to_string();
                    let plane = plane.to_string();
                    let kv = [
                        ("coherence", coh.as_str()),
                        ("resolution", res.as_str()),
                        ("hierarchy", hier.as_str()),
                        ("self_shadow", ss),
                        ("sublights", sl),
                        ("packet", packet),
                        ("fit", fit),
                        ("nearfar", nearfar),
                        ("receiver_plane", plane.as_str()),
                    ];
                    let mut g = g.borrow_mut();
                    for (k, v) in kv {
                        g.set_param(k, v).unwrap();
                    }
                    let (vg, rg) = run(&mut *g, &s, &rec).unwrap();
                    let (vc, rc) = run(&mut hsm(&kv), &s, &rec).unwrap();
                    // Same penumbra pixels, so the same packets; without the (f32 vs f64) coherence
                    // test the same packets go packet-wise and the same ones diverge.
                    assert_eq!(note(&rg, "packets"), note(&rc, "packets"));
                    // Packets that hit llvmpipe's loop limit (65535 iterations per invocation) are
                    // redone pixel-wise (same V) and so counted differently: compare the counters
                    // only where the GPU finished every packet itself.
                    let cut = note(&rg, "packets_loop_limit").parse::<u64>().unwrap_or(0)
                        + note(&rg, "loop_limit_cpu_fallbacks")
                            .parse::<u64>()
                            .unwrap_or(0);
                    if coh == "false" && cut == 0 {
                        assert_eq!(note(&rg, "packets_coherent"), note(&rc, "packets_coherent"));
                        assert_eq!(note(&rg, "packets_diverged"), note(&rc, "packets_diverged"));
                    }
                    *gpu_packets.borrow_mut() +=
                        note(&rg, "packets_coherent").parse::<u64>().unwrap();
                    let (f, worst) = compare(&vc, &vg, &rec, &format!("{kv:?}"));
                    eprintln!("gpu twin {kv:?}: within {f:.4}, worst {worst:e}");
                    Ok(())
                },
            )
            .unwrap();
    }

    /// Large kernels without the hierarchy (an occluder near the light, a large light): on lavapipe a
    /// flat scan exceeds llvmpipe's 65535 loop iterations per invocation; the kernel must flag those
    /// receivers and the twin must redo them, so V still matches the CPU (the count is reported).
    fn loop_limit_is_detected_and_redone(&self, ctx: &Arc<GpuContext>) {
        let s = scene_with(
            rect_light(2.0, 3.0),
            &[(-0.5, -0.5, 0.5, 0.5, 2.6), SQUARE],
            8,
            8,
        );
        let r = line_receivers();
        for (p, h) in [("1x1", "false"), ("8x8", "false"), ("1x1", "true")] {
            let kv = [("resolution", "256"), ("packet", p), ("hierarchy", h)];
            let mut g = GpuPacketHsm::new(ctx.clone()).unwrap();
            for (k, v) in kv {
                g.set_param(k, v).unwrap();
            }
            let (vg, rep) = run(&mut g, &s, &r).unwrap();
            let vc = run(&mut hsm(&kv), &s, &r).unwrap().0;
            let (_, worst) = compare(&vc, &vg, &r, "large kernels");
            let fb = rep
                .notes
                .iter()
                .find(|n| n.0 == "loop_limit_cpu_fallbacks")
                .map(|n| n.1.clone())
                .unwrap();
            eprintln!("large kernels {kv:?}: worst {worst:e}, CPU fallbacks {fb}");
        }
    }
}

/// Disk and sphere lights (docs/methods.md §3 "Disk lights", "Sphere lights") through both twins,
/// packets and per pixel, hierarchy on and off: within the twin tolerance, and in shadow
/// somewhere.
#[test]
fn gpu_disk_and_sphere_lights_match_the_cpu_twin() {
    let Some(ctx) = test_support::gpu("gpu_disk_and_sphere_lights_match_the_cpu_twin") else {
        return;
    };
    let mut g = GpuPacketHsm::new(ctx).unwrap();
    for shape in [1u8, 2] {
        let s = shaped_scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1)], shape);
        let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
        for (p, h) in [("3x3", "true"), ("1x1", "false"), ("4x4", "false")] {
            let kv = [("resolution", "128"), ("packet", p), ("hierarchy", h)];
            for (k, v) in kv {
                g.set_param(k, v).unwrap();
            }
            let vg = run(&mut g, &s, &rec).unwrap().0;
            let vc = run(&mut hsm(&kv), &s, &rec).unwrap().0;
            for (k, x) in vg.iter().enumerate() {
                assert!(
                    !rec.active()[k] || (0.0..=1.0).contains(x),
                    "shape {shape} {kv:?}: gpu #{k} {x}"
                );
            }
            assert!(
                vc.iter().any(|&v| v < 0.5),
                "shape {shape} {kv:?}: no shadow"
            );
            let (f, worst) = compare(&vc, &vg, &rec, &format!("shape {shape} {kv:?}"));
            eprintln!("gpu shape {shape} {kv:?}: within {f:.4}, worst {worst:e}");
        }
    }
}

/// A semi-transparent occluder (two opacity levels) through both twins: within the twin
/// tolerance, with the levels run on both.
#[test]
fn gpu_opacity_levels_match_the_cpu_twin() {
    let Some(ctx) = test_support::gpu("gpu_opacity_levels_match_the_cpu_twin") else {
        return;
    };
    let mut g = GpuPacketHsm::new(ctx).unwrap();
    let mut s = shaped_scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1)], 1);
    s.set_mesh_opacity(1, 0.35).unwrap();
    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
    let kv = [("resolution", "128"), ("packet", "3x3")];
    for (k, v) in kv {
        g.set_param(k, v).unwrap();
    }
    let (vg, rep) = run(&mut g, &s, &rec).unwrap();
    let vc = run(&mut hsm(&kv), &s, &rec).unwrap().0;
    assert_eq!(note(&rep, "opacity_levels_run"), "2");
    assert!(vc.iter().any(|&v| v < 0.9 && v > 0.5), "no partial shadow");
    let (f, worst) = compare(&vc, &vg, &rec, "opacity levels");
    eprintln!("gpu opacity levels: within {f:.4}, worst {worst:e}");
}

/// Hard cases on the GPU: huge kernels, touching occluder, receivers behind the light; finite.
#[test]
fn gpu_hard_cases_stay_finite() {
    let Some(ctx) = test_support::gpu("gpu_hard_cases_stay_finite") else {
        return;
    };
    let mut g = GpuPacketHsm::new(ctx).unwrap();
    g.set_param("resolution", "128").unwrap();
    let r = line_receivers();
    for occ in [
        (-0.5, -0.5, 0.5, 0.5, 3.0 - 1e-4),
        (-0.5, -0.5, 0.5, 0.5, 1e-5),
    ] {
        let s = scene_with(rect_light(1.0, 3.0), &[occ], 8, 8);
        let vg = run(&mut g, &s, &r).unwrap().0;
        assert_valid(&vg, "gpu hard case");
        let vc = run(&mut hsm(&[("resolution", "128")]), &s, &r).unwrap().0;
        compare(&vc, &vg, &r, "hard case");
    }
}

/// Every `fit` x `nearfar` combination on one scene, 1 and 2 x 2 sub-lights, through both twins:
/// V in [0, 1] and within the twin tolerance of the CPU twin ([`compare`]), the same views on both
/// (`near`, `far`, `window_scale`, `out_of_frustum` notes), and the choices reach the views (`nearfar` moves the
/// planes, `fit=stable` widens the window).
#[test]
fn every_fit_and_nearfar_match_on_both_twins() {
    let Some(ctx) = test_support::gpu("every_fit_and_nearfar_match_on_both_twins") else {
        return;
    };
    // The second square is above the light (behind it) and out of the camera's view: only the
    // scene's bounding box sees it, so nearfar=aabb puts n at its floor.
    let s = scene(1.2, 3.0, &[(-1.2, 0.3, 0.6, 1.1), (3.0, -3.0, 0.5, 3.5)]);
    let rec = Receivers::from_camera(&s, &SceneBvh::new(&s));
    let mut g = GpuPacketHsm::new(ctx).unwrap();
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
                for (k, v) in kv {
                    g.set_param(k, v).unwrap();
                }
                let (vg, rg) = run(&mut g, &s, &rec).unwrap();
                let (vc, rc) = run(&mut hsm(&kv), &s, &rec).unwrap();
                for key in ["near", "far", "window_scale", "out_of_frustum"] {
                    assert_eq!(note(&rc, key), note(&rg, key), "{kv:?}: {key}");
                }
                for (k, x) in vc.iter().enumerate() {
                    assert!(
                        !rec.active()[k] || (0.0..=1.0).contains(x),
                        "{kv:?}: cpu #{k} {x}"
                    );
                }
                let (f, worst) = compare(&vc, &vg, &rec, &format!("{kv:?}"));
                let ws: f32 = note(&rc, "window_scale").parse().unwrap();
                eprintln!(
                    "{kv:?}: within {f:.4}, worst {worst:e}, near {} far {} window_scale {ws}",
                    note(&rc, "near"),
                    note(&rc, "far")
                );
                planes.insert((fit, nearfar), (note(&rc, "near"), note(&rc, "far")));
                scales.insert((fit, nearfar), ws);
            }
        }
        for fit in ["receivers", "scene", "stable"] {
            let p = |nf| &planes[&(fit, nf)];
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

/// The GPU twin of `accuracy.rs`'s `grazing_plane_is_not_self_shadowed`: an
/// unoccluded plane lit at 85 degrees from its normal, at the defaults (receiver-plane
/// rejection on), keeps V >= facing - 0.02 at every receiver, with midpoints and with the bias.
#[test]
fn gpu_grazing_plane_is_not_self_shadowed() {
    let Some(ctx) = test_support::gpu("gpu_grazing_plane_is_not_self_shadowed") else {
        return;
    };
    let (s, r, facing) = test_support::fixtures::tilted_plane(85.0, 1.0, (30, -1.0, 0.066));
    let mut g = GpuPacketHsm::new(ctx).unwrap();
    for ss in ["midpoint", "bias"] {
        g.set_param("self_shadow", ss).unwrap();
        let worst = test_support::fixtures::most_below(&run(&mut g, &s, &r).unwrap().0, &facing);
        eprintln!("gpu 85 deg plane, self_shadow={ss}: most below facing {worst:.4}");
        assert!(worst <= 0.02, "self_shadow={ss}: V below facing by {worst}");
    }
}
