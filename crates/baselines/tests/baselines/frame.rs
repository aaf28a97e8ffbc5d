//! The engine path of hard, PCF, PCSS ([`baselines::gpu::MapFrame`]) and multi-sample
//! ([`baselines::gpu::MultiSampleFrame`]) through the conformance suite's
//! [`frames_match_the_cpu_twin`]: frames recorded into the caller's command encoder from the
//! caller's casters and receiver buffer, V into the caller's buffer, read back once after the
//! last frame, against the CPU twin in the same views: perspective views (the bunny under its rect
//! light and a disk light) and an orthographic one (under a low sun). Then against the CPU twin
//! on the very maps the frame rendered (read back, `frame_maps.rs`).
//!
//! GPU tests run on the shared Vulkan context; with no adapter they print a loud skip, or fail
//! under `SOFTSHADOW_REQUIRE_GPU=1`.
#![cfg(feature = "gpu")]

use super::frame_maps::{
    cpu_on_map, cpu_on_sub_light_maps, run_map_frame, run_multi_sample_frame, FrameRun,
};
use baselines::{
    cpu::Filter,
    gpu::{FrameEstimator, FrameInputs, GpuFilter, MapFrame, MultiSampleFrame},
    Hard, Pcf, Pcss,
};
use shadow_map_core::{gpu::GpuContext, Params, Receivers};
use std::sync::Arc;
use test_support::gate::context_for_tests;
use test_support::{
    conformance::{frames_match_the_cpu_twin, FrameComparison},
    fixtures::{bunny_under_three_lights, fixture},
    frame_run::FrameRig,
    Tolerance,
};

/// One more frame with its maps read back ([`FrameRun`]): V bit for bit that of the frames
/// before it (`c`), and within the twins' tolerance of `cpu`, the CPU twin on those maps (at
/// most 0.1% of the active receivers beyond 1e-4: depth ties the FMA of one backend flips).
fn matches_on_its_own_maps(
    label: &str,
    rec: &Receivers,
    c: &FrameComparison,
    run: &FrameRun,
    cpu: &[f32],
) {
    let active: Vec<usize> = (0..rec.len()).filter(|&k| rec.active()[k]).collect();
    let again = active
        .iter()
        .filter(|&&k| run.v[k].to_bits() != c.v[k].to_bits())
        .count();
    assert_eq!(again, 0, "{label}: V changed from one frame to the next");
    let (beyond, max) = active.iter().fold((0, 0.0f32), |(n, m), &k| {
        let d = (run.v[k] - cpu[k]).abs();
        (
            n + usize::from(d.is_nan() || d > Tolerance::TWIN.abs),
            m.max(d),
        )
    });
    let allowed = Tolerance::TWIN.allowed_beyond(active.len());
    println!(
        "{label}: on its own maps, max |dV| {max:.2e}, {beyond} of {} beyond 1e-4",
        active.len()
    );
    assert!(
        beyond <= allowed,
        "{label}: {beyond} of {} beyond 1e-4 of the CPU twin on the frame's maps (allowed \
         {allowed}), max |dV| {max}",
        active.len()
    );
}

/// Hard, PCF or PCSS with shadow-map depth `depth`, on the bunny under rect, disk and sun (one
/// frame prepared for the three): the twins' tolerance (|dV| <= 1e-4 on 99.9% of the receivers,
/// PCSS's compensated sums differing in their last bits, and no |dV| above 1e-3), against the CPU
/// twin's own map and against the CPU twin on the frame's map; the status counts no receiver cut
/// by the loop budget.
fn map_frames_match<F: GpuFilter>(ctx: &Arc<GpuContext>, depth: &str) {
    let kv = [("depth", depth.to_string())];
    let mut params = Params::new(F::SPECS).unwrap();
    params.set("depth", depth).unwrap();
    let frame = MapFrame::<F>::prepare(ctx.clone(), &params).unwrap();
    for (name, scene, rec) in bunny_under_three_lights(64, 48) {
        let label = format!("{} depth={depth} {name}", F::NAME);
        let c = frames_match_the_cpu_twin(&label, ctx, &frame, &scene, &rec);
        let run = run_map_frame(ctx, &frame, &scene, &rec).unwrap();
        let cpu = cpu_on_map::<F>(&kv, &scene, &rec, &run.maps).unwrap();
        matches_on_its_own_maps(&label, &rec, &c, &run, &cpu);
        assert_eq!(
            c.status.left_nan, 0,
            "{label}: cut receivers {:?}",
            c.status
        );
        assert!(
            c.max_dv <= 1e-3 && c.beyond * 1000 <= c.active,
            "{label}: max |dV| {}, {} of {} beyond 1e-4",
            c.max_dv,
            c.beyond,
            c.active
        );
    }
}

#[test]
fn hard_pcf_and_pcss_frames_match_their_cpu_twins() {
    let Some(ctx) = context_for_tests("hard_pcf_and_pcss_frames_match_their_cpu_twins").unwrap()
    else {
        return;
    };
    map_frames_match::<Hard>(&ctx, "f32");
    map_frames_match::<Pcf>(&ctx, "f32");
    map_frames_match::<Pcss>(&ctx, "f32");
}

/// Multi-sample's S x S sub-light maps rendered in turn into one layer within each frame: the
/// CPU twin's V on the same views and on the frame's own maps but for depth ties (at most 0.1% of
/// the receivers, one sub-light's test each).
#[test]
fn multi_sample_frames_match_the_cpu_twin() {
    let Some(ctx) = context_for_tests("multi_sample_frames_match_the_cpu_twin").unwrap() else {
        return;
    };
    multi_sample_frames_match(&ctx, "f32");
}

/// Bad frames are refused with a typed error before anything is recorded: a view of another
/// resolution, two views for a single-view method, a V buffer too small for the count.
#[test]
fn bad_frames_are_refused() {
    let Some(ctx) = context_for_tests("bad_frames_are_refused").unwrap() else {
        return;
    };
    let (scene, rec) = fixture("bunny", 16, 12);
    let params = Params::new(<Pcss as Filter>::SPECS).unwrap();
    let frame = MapFrame::<Pcss>::prepare(ctx.clone(), &params).unwrap();
    let rig = FrameRig::new(&ctx, &frame, &scene, &rec).unwrap();
    let views = &rig.views;
    let buffer = |size| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("V"),
            size,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    let small = buffer(4);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let inputs = FrameInputs {
        v: &small,
        ..rig.inputs()
    };
    let err = frame.encode(&mut enc, &inputs).unwrap_err().to_string();
    assert!(err.contains("V buffer"), "{err}");
    let big = buffer(4 * rec.len() as u64);
    let mut half = views.clone();
    if let Some(v) = half[0].as_mut() {
        v.r /= 2;
    }
    let err = frame
        .encode(
            &mut enc,
            &FrameInputs {
                views: &half,
                v: &big,
                ..inputs
            },
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("resolution"), "{err}");
    let two = [views[0], views[0]];
    let err = frame
        .encode(
            &mut enc,
            &FrameInputs {
                views: &two,
                v: &big,
                ..inputs
            },
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("one light view"), "{err}");
}

/// `depth=unorm16` on the engine path: each layer encoded into 16-bit codes within the frame
/// ([`shadow_map_core::gpu::GpuUnorm16Frame`]). V is within the twins' tolerance of the CPU
/// twin's own 16-bit map, and of the CPU twin on the frame's f32 layers read back and encoded on
/// the CPU (codes the GPU encoder matches bit for bit, checked in shadow-map-core's
/// `gpu_precision` test), for hard, PCF, PCSS and multi-sample (whose S x S sub-light views each
/// get their own code step) under the rect, disk and sun lights.
#[test]
fn unorm16_frames_match_the_cpu_twin() {
    let Some(ctx) = context_for_tests("unorm16_frames_match_the_cpu_twin").unwrap() else {
        return;
    };
    map_frames_match::<Hard>(&ctx, "unorm16");
    map_frames_match::<Pcf>(&ctx, "unorm16");
    map_frames_match::<Pcss>(&ctx, "unorm16");
    multi_sample_frames_match(&ctx, "unorm16");
}

/// Multi-sample's engine path with shadow-map depth `depth` against the CPU twin in the same
/// views and on the frame's own sub-light maps: the CPU twin's V but for depth ties (at most 0.1%
/// of the receivers, one sub-light's test each), on the bunny under rect, disk and sun (one frame
/// prepared for the three).
fn multi_sample_frames_match(ctx: &Arc<GpuContext>, depth: &str) {
    let kv = [("depth", depth.to_string())];
    let scenes = bunny_under_three_lights(64, 48);
    let mut params = Params::new(baselines::settings::MULTI_SAMPLE_SPECS).unwrap();
    params.set("depth", depth).unwrap();
    let max_receivers = scenes
        .iter()
        .map(|(_, _, rec)| rec.len())
        .max()
        .unwrap_or(0);
    let frame = MultiSampleFrame::prepare(ctx.clone(), &params, max_receivers as u32).unwrap();
    for (name, scene, rec) in scenes {
        assert_eq!(frame.fit_views(&scene, &rec).unwrap().len(), 16);
        let label = format!("multi-sample depth={depth} {name}");
        let c = frames_match_the_cpu_twin(&label, ctx, &frame, &scene, &rec);
        assert!(
            c.beyond * 1000 <= c.active && c.max_dv <= 1.0 / 16.0 + 1e-6,
            "{label}: {} of {} differ from the CPU twin, max |dV| {}",
            c.beyond,
            c.active,
            c.max_dv
        );
        let run = run_multi_sample_frame(ctx, &frame, &scene, &rec).unwrap();
        assert_eq!(run.maps.iter().flatten().count(), 16, "{label}");
        let cpu = cpu_on_sub_light_maps(&kv, &scene, &rec, &run.maps).unwrap();
        matches_on_its_own_maps(&label, &rec, &c, &run, &cpu);
    }
}
