//! Accumulation's engine path ([`accumulation::AccumulationFrame`]) through the
//! conformance suite's [`frames_match_the_cpu_twin`]: depth peeling, the MSSM, the layout copies
//! and the kernel recorded into the caller's command encoder three frames running, V read back
//! once, against the CPU twin in the same view and on the frame's own maps, on a rect light
//! (bunny), a disk light and a low sun, at the defaults and with the exact variant's layers; and
//! within the twins' tolerance of the GPU twin's ordinary `build` + `estimate` (whose maps are
//! rasterised on the CPU).
#![cfg(feature = "gpu")]

use accumulation::{AccumulationFrame, GpuAccumulation};
use shadow_map_core::{gpu::frame::FrameEstimator, run, Params};
use test_support::{
    conformance::frames_match_the_cpu_twin, fixtures::bunny_under_three_lights,
    gate::context_for_tests,
};

#[test]
fn accumulation_frames_match_the_twins() {
    let Some(ctx) = context_for_tests("accumulation_frames_match_the_twins").unwrap() else {
        return;
    };
    let defaults = Params::new(accumulation::cpu::SPECS).unwrap();
    let mut exact = defaults.clone();
    exact.set("variant", "exact").unwrap();
    exact.set("layers", "2").unwrap();
    // Within lavapipe's loop budget (the frame path counts cut receivers, it does not redo them).
    exact.set("k", "5").unwrap();
    exact.set("bits", "4").unwrap();
    for (params, (name, scene, rec)) in [&defaults, &exact].into_iter().flat_map(|p| {
        bunny_under_three_lights(64, 48)
            .into_iter()
            .map(move |s| (p, s))
    }) {
        let frame = AccumulationFrame::prepare(ctx.clone(), params).unwrap();
        let name = format!("{name} variant={}", params.choice("variant").unwrap());
        let label = format!("accumulation {name}");
        let c = frames_match_the_cpu_twin(&label, &ctx, &frame, &scene, &rec);
        let mut gpu = GpuAccumulation::new(ctx.clone()).unwrap();
        shadow_map_core::estimator::configure(&mut gpu, params).unwrap();
        let (v_gpu, _) = run(&mut gpu, &scene, &rec).unwrap();
        // The GPU twin's build rasterises on the CPU and uploads; the frame path rasterises on
        // the GPU: the twins' tolerance between the two.
        let beyond_gpu = (0..rec.len())
            .filter(|&k| rec.active()[k] && (c.v[k] - v_gpu[k]).abs() > 1e-4)
            .count();
        assert!(
            beyond_gpu * 1000 <= c.active,
            "{label}: {beyond_gpu} of {} beyond 1e-4 of the GPU twin's build",
            c.active
        );
        assert_eq!(
            c.status,
            shadow_map_core::gpu::frame::FrameStatus::default(),
            "{label}"
        );
        // The CPU twin on the maps the frame rendered (read back after the frames): the twins'
        // tolerance. Against the CPU twin's own rasterisation, the peeled layers differ at
        // texels whose centre lies on an edge to within f32 (shadow-map-core's gpu_maps.rs):
        // at most 1% of the receivers beyond 1e-4.
        let views = frame.fit_views(&scene, &rec).unwrap();
        let view = views[0].unwrap();
        let ls = frame.light_space(&view).to_cpu(&ctx).unwrap();
        let mut cpu = accumulation::CpuAccumulation::new().unwrap();
        shadow_map_core::estimator::configure(&mut cpu, params).unwrap();
        let mut v_same = vec![0.0; rec.len()];
        cpu.estimate_with(&ls, &scene, &rec, &mut v_same).unwrap();
        accumulation::cpu::settle_outside(&scene, &rec, &mut v_same).unwrap();
        let beyond_same = (0..rec.len())
            .filter(|&k| rec.active()[k] && (c.v[k] - v_same[k]).abs() > 1e-4)
            .count();
        println!("{label}: {beyond_same} beyond 1e-4 of the CPU twin on the frame's own maps");
        let mut cpu_own = accumulation::CpuAccumulation::new().unwrap();
        shadow_map_core::estimator::configure(&mut cpu_own, params).unwrap();
        let (v_cpu_own, _) = run(&mut cpu_own, &scene, &rec).unwrap();
        let gpu_vs_cpu = (0..rec.len())
            .filter(|&k| rec.active()[k] && (v_cpu_own[k] - v_gpu[k]).abs() > 1e-4)
            .count();
        println!("{label}: GPU twin's build vs CPU twin: {gpu_vs_cpu} beyond 1e-4");
        // The exact variant's GPU twin itself differs from the CPU twin at a few receivers (a
        // bit point on a caster square's edge, a tie within f32: gpu_twin.rs explains them):
        // the frame may differ where the GPU twin's build does, plus the twins' 0.1%.
        let allowed = gpu_vs_cpu + c.active.div_ceil(1000);
        assert!(
            beyond_same <= allowed,
            "{label}: {beyond_same} of {} beyond 1e-4 of the CPU twin on the same maps \
             (allowed {allowed})",
            c.active
        );
        assert!(
            c.beyond * 100 <= c.active,
            "{label}: {} of {} beyond 1e-4 of the CPU twin (max |dV| {})",
            c.beyond,
            c.active,
            c.max_dv
        );
    }
}
