//! Deep-shadow's engine path ([`deep_shadow::DeepShadowFrame`]) through the
//! conformance suite's `frames_match_the_cpu_twin` (over tables of settings,
//! [`frames_over_settings`]): the core's raster pass, the head copy, the per-receiver queries
//! and lookups recorded into the caller's command encoder two frames
//! running, V read back once, against the CPU twin in the same views, on a rect light (bunny),
//! a disk light and a low sun; at the defaults (pcss, one view) and with 2 x 2 sub-lights and
//! each of the other filters; and on semi-transparent casters (lists), where a full element
//! buffer cuts the frame for a redo.
#![cfg(feature = "gpu")]

use crate::common::params;
use deep_shadow::DeepShadowFrame;
use shadow_map_core::{gpu::frame::FrameEstimator, run};
use test_support::{
    conformance::{frames_over_settings, SettingsCase},
    fixtures::{bunny_under_three_lights, fixture, note_as, semi_transparent_fixtures},
    gpu,
};

#[test]
fn deep_shadow_frames_match_the_cpu_twin() {
    let Some(ctx) = gpu("deep_shadow_frames_match_the_cpu_twin") else {
        return;
    };
    let settings: &[&[(&str, &str)]] = &[
        &[],
        &[("sublights", "2")],
        &[("filter", "pcf"), ("kernel", "5")],
        &[("filter", "edsm"), ("kernel", "3")],
        &[("filter", "none")],
        &[("filter", "first"), ("receiver_plane", "false")],
    ];
    let scenes = bunny_under_three_lights(64, 48);
    let prepare = |kv: &[(&str, &str)]| {
        let frame = DeepShadowFrame::prepare(ctx.clone(), &params(kv), 64 * 48).unwrap();
        assert_eq!(frame.name(), "deep-shadow");
        // Semi-transparent casters are modelled (lists), so no scene is refused for them.
        assert!(frame.models_opacity());
        let mut half = scenes[0].1.clone();
        half.set_mesh_opacity(0, 0.5).unwrap();
        assert_eq!(frame.refuses(&half), None);
        assert!(frame.scene_warnings(&half).is_empty());
        frame
    };
    let check = |case: SettingsCase<'_, DeepShadowFrame>| {
        let (label, c) = (&case.label, &case.c);
        assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);
        // The map is the hardware raster's (depth interpolated in f32 by the rasteriser), the
        // CPU twin's the core's CPU raster (1/z in f64): PCSS's blocker average moves by that
        // rounding, and V with it, by up to a few 1e-4 in sharp penumbrae; a tap whose depth
        // ties the caster test moves V by its weight. Bounds: 1% of the receivers beyond 1e-4,
        // RMSE a tenth of the engine path's 2e-3.
        c.assert_close(label, 100, 2e-4);
    };
    frames_over_settings("deep-shadow", &ctx, settings, &scenes, None, prepare, check);
}

/// Semi-transparent casters on the engine path: the lists built by the insert pass, `process`
/// and `link`, looked up per receiver, on the strands and the hair at every filter, against the
/// CPU twin's lists in the same views. The hardware rasteriser's sub-pixel snapping moves a
/// texel centre within 1/256 texel of a strand's edge in or out: a tap's transmittance over the
/// kernel's taps, or under PCSS a blocker depth in or out of the average, which moves many
/// receivers a little. Bounds: at most 10% of the receivers beyond 1e-4, none beyond 0.1, RMSE
/// within 2e-3. V is the semi-transparent scene's, not the opaque one's.
#[test]
fn deep_shadow_frames_build_lists_for_semi_transparent_casters() {
    let Some(ctx) = gpu("deep_shadow_frames_build_lists_for_semi_transparent_casters") else {
        return;
    };
    let settings: &[&[(&str, &str)]] = &[
        &[],
        &[("filter", "pcf"), ("kernel", "3")],
        &[("filter", "edsm"), ("kernel", "3")],
        &[("filter", "none"), ("traversal", "naive")],
    ];
    let scenes = semi_transparent_fixtures(64, 48);
    let prepare =
        |kv: &[(&str, &str)]| DeepShadowFrame::prepare(ctx.clone(), &params(kv), 64 * 48).unwrap();
    let check = |case: SettingsCase<'_, DeepShadowFrame>| {
        let (label, c) = (&case.label, &case.c);
        assert_eq!(c.status.left_nan, 0, "{label}: {:?}", c.status);
        c.assert_close(label, 10, 2e-3);
        assert!(c.max_dv <= 0.1, "{label}: max |dV| {}", c.max_dv);
        let apart = case.rmse_to_opaque();
        println!("{label}: RMSE to the opaque scene's CPU twin {apart:.3}");
        assert!(
            apart > 10.0 * c.rmse.max(1e-3),
            "{label}: V is the opaque scene's"
        );
    };
    frames_over_settings("deep-shadow", &ctx, settings, &scenes, None, prepare, check);
}

/// An element buffer too small for the frame's fragments loses none silently: the frame leaves
/// every active receiver NaN and counts it in the status's cut word, and deep-shadow's GPU
/// estimator (the engine path run by the core's `FrameTwin`) redoes them with the CPU twin in the
/// same views, noting how many (`frame_cpu_redo`).
#[test]
fn a_full_element_buffer_cuts_the_frame_for_a_redo() {
    let Some(ctx) = gpu("a_full_element_buffer_cuts_the_frame_for_a_redo") else {
        return;
    };
    let (scene, rec) = fixture("hair", 32, 24);
    let active = rec.active().iter().filter(|a| **a).count();
    let mut gpu = deep_shadow::DESCRIPTOR.gpu(ctx.clone()).unwrap().unwrap();
    gpu.set_param("capacity", "64").unwrap();
    let (v, report) = run(&mut *gpu, &scene, &rec).unwrap();
    assert_eq!(note_as::<String>(&report, "engine_path"), "frame twin");
    assert_eq!(
        note_as::<usize>(&report, "frame_cpu_redo"),
        active,
        "{report:?}"
    );
    let mut cpu = deep_shadow::DESCRIPTOR.cpu().unwrap();
    cpu.set_param("capacity", "64").unwrap();
    let (want, _) = run(&mut *cpu, &scene, &rec).unwrap();
    for k in 0..rec.len() {
        assert!(
            v[k] == want[k] || (v[k].is_nan() && want[k].is_nan()),
            "receiver {k}: {} against the CPU twin's {}",
            v[k],
            want[k]
        );
    }
}
