//! Backprojection's engine path ([`backprojection::BackprojectionFrame`], issue 20) through the
//! conformance suite's [`frames_match_the_cpu_twin`]: depth peeling, midpoints, the MSSM, the
//! layout copies and the kernel recorded into the caller's command encoder three frames running,
//! V read back once, against the CPU twin in the same view, on a rect light (bunny), a disk light
//! and a low sun; and bit for bit the GPU twin's ordinary `build` + `estimate` (the same view and
//! request but for the MSSM's level count, which the exact minimum query does not see).
#![cfg(feature = "gpu")]

use backprojection::{BackprojectionFrame, GpuBackprojection};
use shadow_map_core::{run, Params};
use test_support::{
    conformance::frames_match_the_cpu_twin, fixtures::bunny_under_three_lights,
    gate::context_for_tests,
};

#[test]
fn backprojection_frames_match_the_twins() {
    let Some(ctx) = context_for_tests("backprojection_frames_match_the_twins").unwrap() else {
        return;
    };
    let params = Params::new(backprojection::cpu::SPECS).unwrap();
    let frame = BackprojectionFrame::prepare(ctx.clone(), &params).unwrap();
    for (name, scene, rec) in bunny_under_three_lights(64, 48) {
        let label = format!("backprojection {name}");
        let c = frames_match_the_cpu_twin(&label, &ctx, &frame, &scene, &rec);
        let mut gpu = GpuBackprojection::new(ctx.clone()).unwrap();
        let (v_gpu, _) = run(&mut gpu, &scene, &rec).unwrap();
        let differ_gpu = (0..rec.len())
            .filter(|&k| rec.active()[k] && c.v[k] != v_gpu[k])
            .count();
        assert_eq!(differ_gpu, 0, "{label}: differs from the GPU twin's build");
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
