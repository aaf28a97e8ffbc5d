//! Accumulation's engine path ([`accumulation::AccumulationFrame`]) through the
//! conformance suite's [`frames_match_the_cpu_twin`]: depth peeling, the MSSM, the layout copies
//! and the kernel recorded into the caller's command encoder three frames running, V read back
//! once, against the CPU twin in the same view and on the frame's own maps, on a rect light
//! (bunny), a disk light and a low sun, at the defaults and with the exact variant's layers.
#![cfg(feature = "gpu")]

use super::maps::{judge_on_maps, run_frame};
use accumulation::AccumulationFrame;
use shadow_map_core::{gpu::GpuContext, Params, Receivers, Scene};
use test_support::{
    conformance::frames_match_the_cpu_twin, fixtures::bunny_under_three_lights,
    gate::context_for_tests,
};

#[test]
fn accumulation_frames_match_the_twins() {
    let Some(ctx) = context_for_tests("accumulation_frames_match_the_twins").unwrap() else {
        return;
    };
    let defaults = Params::new(accumulation::settings::SPECS).unwrap();
    let mut exact = defaults.clone();
    exact.set("variant", "exact").unwrap();
    exact.set("layers", "2").unwrap();
    // Within lavapipe's loop budget (the frame path counts cut receivers, it does not redo them).
    exact.set("k", "5").unwrap();
    exact.set("bits", "4").unwrap();
    // One frame per parameter table, reused across the scenes (a frame is reusable across
    // scenes and receivers).
    for params in [&defaults, &exact] {
        let frame = AccumulationFrame::prepare(ctx.clone(), params).unwrap();
        for (name, scene, rec) in bunny_under_three_lights(64, 48) {
            check_scene(&ctx, &frame, params, name, &scene, &rec);
        }
    }
}

/// One scene through `frame` (prepared with `params`): the conformance suite's three frames,
/// one more with its maps read back, judged on those maps.
fn check_scene(
    ctx: &GpuContext,
    frame: &AccumulationFrame,
    params: &Params,
    name: &str,
    scene: &Scene,
    rec: &Receivers,
) {
    let name = format!("{name} variant={}", params.choice("variant").unwrap());
    let label = format!("accumulation {name}");
    let c = frames_match_the_cpu_twin(&label, ctx, frame, scene, rec);
    assert_eq!(
        c.status,
        shadow_map_core::gpu::frame::FrameStatus::default(),
        "{label}"
    );
    // One more frame, its maps read back: the same V, and the CPU twin on those very maps
    // within the twins' tolerance, every receiver beyond it a tie, receivers with no
    // occlusion bit in front of their plane by their own rule (maps.rs).
    let again = run_frame(ctx, frame, scene, rec).unwrap();
    for k in 0..rec.len() {
        assert_eq!(
            c.v[k].to_bits(),
            again.v[k].to_bits(),
            "{label}: #{k} again"
        );
    }
    let (_, st, left) =
        judge_on_maps(&label, &again, scene, rec, params).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{label}: on the frame's own maps max |dV| {:.2e}, {} of {} beyond 1e-4 ({} ties), \
         {} outside, {} cut, {} with no bit in front ({} differ)",
        st.max_dv,
        st.beyond,
        st.receivers,
        st.ties,
        left.outside,
        left.cut,
        left.no_front_bit,
        left.no_front_bit_differ
    );
    // Against the CPU twin's own rasterisation, the peeled layers differ at texels whose
    // centre lies on an edge to within f32 (shadow-map-core's gpu_maps.rs): at most 1% of
    // the receivers beyond 1e-4.
    assert!(
        c.beyond * 100 <= c.active,
        "{label}: {} of {} beyond 1e-4 of the CPU twin (max |dV| {})",
        c.beyond,
        c.active,
        c.max_dv
    );
}
