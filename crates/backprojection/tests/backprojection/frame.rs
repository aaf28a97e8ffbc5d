//! Backprojection's engine path ([`backprojection::BackprojectionFrame`]) through the
//! conformance suite's `frames_match_the_cpu_twin` ([`frames_over_settings`]): depth peeling,
//! midpoints, the MSSM, the layout copies and the kernel recorded into the caller's command
//! encoder two frames running, V read back once, against the CPU twin in the same view, on a
//! rect light (bunny), a disk light and a low sun; and bit for bit the registry's GPU estimator's
//! `build` + `estimate` (the frame run by the core's `FrameTwin`: receivers uploaded, one frame,
//! V read back).
#![cfg(feature = "gpu")]

use crate::support::{cpu_on_maps, frame_maps};
use backprojection::settings::SPECS;
use backprojection::BackprojectionFrame;
use shadow_map_core::{
    gpu::{frame::FrameEstimator, GpuContext},
    run,
};
use std::sync::Arc;
use test_support::{
    conformance::{frames_over_settings, SettingsCase},
    fixtures::{bunny_under_three_lights, param_table, semi_transparent_fixtures, NamedScene},
    gpu,
    tolerance::Tolerance,
};

#[test]
fn backprojection_frames_match_the_twins() {
    let Some(ctx) = gpu("backprojection_frames_match_the_twins") else {
        return;
    };
    let mut gpu = backprojection::DESCRIPTOR
        .gpu(ctx.clone())
        .expect("a GPU estimator")
        .unwrap();
    let scenes = bunny_under_three_lights(64, 48);
    let check = |case: SettingsCase<'_, BackprojectionFrame>| {
        let (label, rec, c) = (&case.label, case.rec, &case.c);
        let (v_gpu, _) = run(&mut *gpu, case.scene, rec).unwrap();
        let differ_gpu = (0..rec.len())
            .filter(|&k| rec.active()[k] && c.v[k].to_bits() != v_gpu[k].to_bits())
            .count();
        assert_eq!(differ_gpu, 0, "{label}: differs from the GPU estimator's");
        assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);
        c.assert_close(label, 1000, f64::INFINITY);
    };
    at_defaults(&ctx, &scenes, check);
}

/// Semi-transparent casters on the engine path: the peeling passes write each layer's opacity
/// plane from the caster buffer's w, and the kernel weights micropatches by it, as the CPU twin
/// does. On the strands (one mesh of opacity 0.4 over a ground) and the hair (four meshes of
/// opacity 0.2 to 0.5; held out while the frame was written):
///
/// - V is the CPU twin's on the very maps the frame rendered (read back, opacity planes
///   included) within the twin tolerance: the frame models opacity as the CPU does;
/// - against the CPU twin on its own maps, V differs where the GPU's snapped coverage of strands
///   thinner than a texel differs from the CPU's f64 coverage (the opaque scene shows the same
///   kind of difference), bounded by RMSE 3e-3;
/// - V is far from the CPU twin's on the scene made opaque (what a frame casting every caster
///   opaque would give).
#[test]
fn backprojection_frame_models_semi_transparent_casters() {
    let Some(ctx) = gpu("backprojection_frame_models_semi_transparent_casters") else {
        return;
    };
    let scenes = semi_transparent_fixtures(64, 48);
    let check = |case: SettingsCase<'_, BackprojectionFrame>| {
        let (label, rec, c) = (&case.label, case.rec, &case.c);
        assert!(case.frame.models_opacity());
        assert_eq!(case.frame.refuses(case.scene), None, "{label}");
        assert!(case.frame.scene_warnings(case.scene).is_empty(), "{label}");
        assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);

        // The CPU twin (default parameters) on the frame's own maps.
        let views = case.frame.fit_views(case.scene, rec).unwrap();
        let ls = frame_maps(&ctx, case.frame, &views).unwrap();
        assert_eq!(
            ls.opacity.len(),
            ls.layers.len(),
            "{label}: opacity planes read back"
        );
        let same_maps = cpu_on_maps(&ls, case.scene, rec, &Vec::new());
        let active: Vec<usize> = (0..rec.len()).filter(|&k| rec.active()[k]).collect();
        let beyond = active
            .iter()
            .filter(|&&k| (c.v[k] - same_maps[k]).abs() > Tolerance::TWIN.abs)
            .count();
        let allowed = Tolerance::TWIN.allowed_beyond(active.len());
        assert!(
            beyond <= allowed,
            "{label}: {beyond} of {} beyond {} of the CPU twin on the frame's maps (allowed \
             {allowed})",
            active.len(),
            Tolerance::TWIN.abs
        );

        // The CPU twin on its own maps, and on the scene made opaque.
        let apart = case.rmse_to_opaque();
        println!(
            "{label}: {beyond} of {} beyond 1e-4 of the CPU twin on the frame's maps; RMSE to \
             the CPU twin on its own maps {:.2e}, to the opaque scene's {apart:.3}",
            active.len(),
            c.rmse
        );
        assert!(c.rmse <= 3e-3, "{label}: RMSE {} to the CPU twin", c.rmse);
        assert!(
            apart > 10.0 * c.rmse.max(1e-4),
            "{label}: the frame is as close to the opaque scene ({apart}) as to the twin ({})",
            c.rmse
        );
    };
    at_defaults(&ctx, &scenes, check);
}

/// The engine path at the defaults on `scenes` ([`frames_over_settings`]; one frame), `check`
/// judging each comparison.
fn at_defaults(
    ctx: &Arc<GpuContext>,
    scenes: &[NamedScene],
    check: impl FnMut(SettingsCase<'_, BackprojectionFrame>),
) {
    let prepare = |kv: &[(&str, &str)]| {
        BackprojectionFrame::prepare(ctx.clone(), &param_table(SPECS, kv)).unwrap()
    };
    frames_over_settings("backprojection", ctx, &[&[]], scenes, None, prepare, check);
}
