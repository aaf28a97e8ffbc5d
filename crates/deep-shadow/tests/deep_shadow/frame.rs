//! Deep-shadow's engine path ([`deep_shadow::DeepShadowFrame`]) through the
//! conformance suite's [`frames_match_the_cpu_twin`]: the core's raster pass, the head copy, the
//! per-receiver queries and lookups recorded into the caller's command encoder three frames
//! running, V read back once, against the CPU twin in the same views, on a rect light (bunny),
//! a disk light and a low sun; at the defaults (pcss, one view) and with 2 x 2 sub-lights and
//! each of the other filters.
#![cfg(feature = "gpu")]

use deep_shadow::DeepShadowFrame;
use shadow_map_core::{gpu::frame::FrameEstimator, Params};
use test_support::{
    conformance::frames_match_the_cpu_twin, fixtures::bunny_under_three_lights,
    gate::context_for_tests,
};

#[test]
fn deep_shadow_frames_match_the_cpu_twin() {
    let Some(ctx) = context_for_tests("deep_shadow_frames_match_the_cpu_twin").unwrap() else {
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
    for kv in settings {
        let mut params = Params::new(deep_shadow::params::SPECS).unwrap();
        for (k, v) in *kv {
            params.set(k, v).unwrap();
        }
        let frame = DeepShadowFrame::prepare(ctx.clone(), &params, 64 * 48).unwrap();
        assert_eq!(frame.name(), "deep-shadow");
        // The frame's casters are opaque: a semi-transparent scene is refused (the twin path
        // models it), an opaque one taken.
        let mut half = scenes[0].1.clone();
        assert!(frame.refuses(&half).is_none());
        half.set_mesh_opacity(0, 0.5).unwrap();
        let why = frame.refuses(&half).unwrap_or_default();
        assert!(why.contains("semi-transparent"), "{why}");
        for (name, scene, rec) in &scenes {
            let label = format!("deep-shadow {name} {kv:?}");
            let c = frames_match_the_cpu_twin(&label, &ctx, &frame, scene, rec);
            assert_eq!(c.status.nonfinite, 0, "{label}: {:?}", c.status);
            // The map is the hardware raster's (depth interpolated in f32 by the rasteriser),
            // the CPU twin's the core's CPU raster (1/z in f64): PCSS's blocker average moves by
            // that rounding, and V with it, by up to a few 1e-4 in sharp penumbrae; a tap whose
            // depth ties the caster test moves V by its weight. Bounds: 1% of the receivers
            // beyond 1e-4, RMSE a tenth of the engine path's 2e-3.
            assert!(
                c.beyond * 100 <= c.active && c.rmse <= 2e-4,
                "{label}: {} of {} beyond 1e-4 of the CPU twin (max |dV| {}, rmse {})",
                c.beyond,
                c.active,
                c.max_dv,
                c.rmse
            );
        }
    }
}
