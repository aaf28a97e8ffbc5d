//! Accumulation's engine path ([`accumulation::AccumulationFrame`]) through the
//! conformance suite's `frames_match_the_cpu_twin` ([`frames_over_settings`]): depth peeling,
//! the MSSM, the layout copies and the kernel recorded into the caller's command encoder three
//! frames running, V read back once, against the CPU twin in the same view and on the frame's
//! own maps, on a rect light (bunny), a disk light and a low sun, at the defaults and with the
//! exact variant's layers.
#![cfg(feature = "gpu")]

use super::maps::{judge_on_maps, run_frame};
use accumulation::AccumulationFrame;
use shadow_map_core::{gpu::GpuContext, Params};
use test_support::{
    conformance::{frames_over_settings, SettingsCase},
    fixtures::{bunny_under_three_lights, param_table},
    gpu,
};

#[test]
fn accumulation_frames_match_the_twins() {
    let Some(ctx) = gpu("accumulation_frames_match_the_twins") else {
        return;
    };
    let settings: &[&[(&str, &str)]] = &[
        &[],
        // Within lavapipe's loop budget (the frame path counts cut receivers, it does not redo
        // them).
        &[
            ("variant", "exact"),
            ("layers", "2"),
            ("k", "5"),
            ("bits", "4"),
        ],
    ];
    let prepare =
        |kv: &[(&str, &str)]| AccumulationFrame::prepare(ctx.clone(), &table(kv)).unwrap();
    let scenes = bunny_under_three_lights(64, 48);
    let check = |case: SettingsCase<'_, AccumulationFrame>| check_scene(&ctx, case);
    frames_over_settings(
        "accumulation",
        &ctx,
        settings,
        &scenes,
        None,
        prepare,
        check,
    );
}

/// `kv` over accumulation's defaults.
fn table(kv: &[(&str, &str)]) -> Params {
    param_table(accumulation::settings::SPECS, kv)
}

/// One scene through the conformance suite's two frames (`case`), then one more frame with
/// its maps read back, judged on those maps.
fn check_scene(ctx: &GpuContext, case: SettingsCase<'_, AccumulationFrame>) {
    let SettingsCase {
        label,
        kv,
        frame,
        scene,
        rec,
        c,
        ..
    } = case;
    let params = table(kv);
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
        judge_on_maps(&label, &again, scene, rec, &params).unwrap_or_else(|e| panic!("{e}"));
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
    c.assert_close(&label, 100, f64::INFINITY);
}
