//! Backprojection's engine path ([`backprojection::BackprojectionFrame`]) through the
//! conformance suite's [`frames_match_the_cpu_twin`]: depth peeling, midpoints, the MSSM, the
//! layout copies and the kernel recorded into the caller's command encoder three frames running,
//! V read back once, against the CPU twin in the same view, on a rect light (bunny), a disk light
//! and a low sun; and bit for bit the registry's GPU estimator's `build` + `estimate` (the frame
//! run by the core's `FrameTwin`: receivers uploaded, one frame, V read back).
#![cfg(feature = "gpu")]

use crate::support::{cpu_on_maps, frame_maps};
use backprojection::BackprojectionFrame;
use shadow_map_core::{gpu::frame::FrameEstimator, run, Params};
use test_support::{
    conformance::frames_match_the_cpu_twin,
    fixtures::{bunny_under_three_lights, fixture},
    gate::context_for_tests,
    tolerance::Tolerance,
};

#[test]
fn backprojection_frames_match_the_twins() {
    let Some(ctx) = context_for_tests("backprojection_frames_match_the_twins").unwrap() else {
        return;
    };
    let params = Params::new(backprojection::settings::SPECS).unwrap();
    let frame = BackprojectionFrame::prepare(ctx.clone(), &params).unwrap();
    let mut gpu = backprojection::DESCRIPTOR
        .gpu(ctx.clone())
        .expect("a GPU estimator")
        .unwrap();
    for (name, scene, rec) in bunny_under_three_lights(64, 48) {
        let label = format!("backprojection {name}");
        let c = frames_match_the_cpu_twin(&label, &ctx, &frame, &scene, &rec);
        let (v_gpu, _) = run(&mut *gpu, &scene, &rec).unwrap();
        let differ_gpu = (0..rec.len())
            .filter(|&k| rec.active()[k] && c.v[k].to_bits() != v_gpu[k].to_bits())
            .count();
        assert_eq!(differ_gpu, 0, "{label}: differs from the GPU estimator's");
        assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);
        assert!(
            c.beyond * 1000 <= c.active,
            "{label}: {} of {} beyond 1e-4 of the CPU twin (max |dV| {})",
            c.beyond,
            c.active,
            c.max_dv
        );
    }
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
    let Some(ctx) =
        context_for_tests("backprojection_frame_models_semi_transparent_casters").unwrap()
    else {
        return;
    };
    let params = Params::new(backprojection::settings::SPECS).unwrap();
    let frame = BackprojectionFrame::prepare(ctx.clone(), &params).unwrap();
    assert!(frame.models_opacity());
    for name in ["strands", "hair"] {
        let (scene, rec) = fixture(name, 64, 48);
        assert!(!scene.is_opaque(), "{name}: a semi-transparent fixture");
        let label = format!("backprojection {name}");
        assert_eq!(frame.refuses(&scene), None, "{label}");
        assert!(frame.scene_warnings(&scene).is_empty(), "{label}");
        let c = frames_match_the_cpu_twin(&label, &ctx, &frame, &scene, &rec);
        assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);
        let views = frame.fit_views(&scene, &rec).unwrap();

        // The CPU twin (default parameters) on the frame's own maps.
        let ls = frame_maps(&ctx, &frame, &views).unwrap();
        assert_eq!(
            ls.opacity.len(),
            ls.layers.len(),
            "{label}: opacity planes read back"
        );
        let same_maps = cpu_on_maps(&ls, &scene, &rec, &Vec::new());
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
        let rms = |other: &[f32]| {
            let sq: f64 = active
                .iter()
                .map(|&k| ((c.v[k] - other[k]) as f64).powi(2))
                .sum();
            (sq / active.len() as f64).sqrt()
        };
        let opaque = frame.cpu_twin(&scene.opaque(), &rec, &views).unwrap();
        let apart = rms(&opaque);
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
    }
}
