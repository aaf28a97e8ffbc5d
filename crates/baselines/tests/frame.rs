//! The engine path of hard, PCF and PCSS ([`baselines::gpu::MapFrame`], issue 20's first step):
//! frames recorded into the caller's command encoder from the caller's casters and receiver
//! buffer, V into the caller's buffer, read back once after the last frame, against the CPU
//! twin on the same view: a perspective view (bunny, rect light) and an orthographic one (the
//! bunny under a low sun).
//!
//! GPU tests run on the shared Vulkan context; with no adapter they print a loud skip, or fail
//! under `SOFTSHADOW_REQUIRE_GPU=1`.
#![cfg(feature = "gpu")]

use baselines::{
    gpu::{FrameInputs, GpuFilter, MapFrame, MultiSampleFrame, MultiSampleInputs},
    hard::Hard,
    map_estimator::{Filter, MapEstimator},
    pcf::Pcf,
    pcss::Pcss,
    MultiSample,
};
use glam::Vec3;
use shadow_map_core::{
    gpu::{context_for_tests, receivers::GpuReceivers, shared::CUT_BITS, GpuContext, GpuScene},
    run, Light, Params, Receivers, Scene, SceneBvh,
};
use std::sync::Arc;
use test_support::fixtures::fixture;

/// The bunny fixture at 64 x 48, and the same under a low 3-degree sun.
fn scenes() -> Vec<(&'static str, Scene, Receivers)> {
    let (bunny, rec) = fixture("bunny", 64, 48);
    let mut sun = bunny.clone();
    sun.light = Light::directional(Vec3::new(0.6, -0.5, 0.3), 3.0);
    let sun_rec = Receivers::from_camera(&sun, &SceneBvh::new(&sun));
    vec![("bunny", bunny, rec), ("sun-bunny", sun, sun_rec)]
}

/// Three frames of `F` through the frame API (each its own encoder and submit, nothing read
/// between them), V read back once at the end; it must equal the CPU twin's V on the same view
/// (the twins' tolerance: |dV| <= 1e-4 on 99.9% of the receivers, PCSS's compensated sums
/// differing in their last bits, and no |dV| above 1e-3) and the status must count no cut
/// receiver.
fn frames_match_the_cpu_twin<F: GpuFilter>(ctx: &Arc<GpuContext>) {
    for (name, scene, rec) in scenes() {
        let params = Params::new(F::SPECS).unwrap();
        let frame = MapFrame::<F>::prepare(ctx.clone(), &params).unwrap();
        let (view, _) = frame.fit_view(&scene, &rec).unwrap();
        let casters = GpuScene::upload(ctx, &scene).unwrap();
        let receivers = GpuReceivers::upload(ctx, &rec).unwrap();
        let v_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("caller's V"),
            size: 4 * rec.len() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let inputs = FrameInputs {
            casters: &casters,
            view: &view,
            light: &scene.light,
            receivers: &receivers.buffer,
            count: receivers.count,
            v: &v_buf,
        };
        for _ in 0..3 {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            frame.encode(&mut enc, &inputs).unwrap();
            ctx.queue.submit([enc.finish()]);
        }
        let bits: Vec<u32> = ctx.read_buffer(&v_buf, 4 * rec.len() as u64).unwrap();
        let status: Vec<u32> = ctx.read_buffer(frame.status(), 12).unwrap();
        assert_eq!(status[2], 0, "{} {name}: cut receivers {status:?}", F::NAME);
        let mut cpu = MapEstimator::<F>::new().unwrap();
        let (v_cpu, _) = run(&mut cpu, &scene, &rec).unwrap();
        assert_eq!(
            cpu.light_space().unwrap().view,
            view,
            "{} {name}: the CPU twin fitted another view",
            F::NAME
        );
        let (mut worst, mut beyond, mut active) = (0.0f32, 0usize, 0usize);
        for (k, (&b, &c)) in bits.iter().zip(&v_cpu).enumerate() {
            let g = f32::from_bits(b);
            if !rec.active[k] {
                assert!(g.is_nan() && c.is_nan(), "{} {name}: receiver {k}", F::NAME);
                continue;
            }
            assert!(
                b != CUT_BITS && g.is_finite(),
                "{} {name}: V[{k}] = {g}",
                F::NAME
            );
            worst = worst.max((g - c).abs());
            beyond += usize::from((g - c).abs() > 1e-4);
            active += 1;
        }
        println!(
            "{} {name}: frame API vs CPU twin, max |dV| {worst:.2e}",
            F::NAME
        );
        assert!(
            worst <= 1e-3 && beyond * 1000 <= active,
            "{} {name}: max |dV| {worst}, {beyond} of {active} beyond 1e-4",
            F::NAME
        );
    }
}

#[test]
fn hard_pcf_and_pcss_frames_match_their_cpu_twins() {
    let Some(ctx) = context_for_tests("hard_pcf_and_pcss_frames_match_their_cpu_twins").unwrap()
    else {
        return;
    };
    frames_match_the_cpu_twin::<Hard>(&ctx);
    frames_match_the_cpu_twin::<Pcf>(&ctx);
    frames_match_the_cpu_twin::<Pcss>(&ctx);
}

/// Multi-sample's S x S sub-light maps rendered in turn into one layer within each frame, three
/// frames, one readback: bit for bit the GPU twin's V, and the CPU twin's on the same views but
/// for depth ties (at most 0.1% of the receivers, one sub-light's test each).
#[test]
fn multi_sample_frames_match_the_cpu_twin() {
    let Some(ctx) = context_for_tests("multi_sample_frames_match_the_cpu_twin").unwrap() else {
        return;
    };
    for (name, scene, rec) in scenes() {
        let params = Params::new(baselines::multi_sample::SPECS).unwrap();
        let frame = MultiSampleFrame::prepare(ctx.clone(), &params, rec.len() as u32).unwrap();
        let views = frame.fit_views(&scene, &rec).unwrap();
        assert_eq!(views.len(), 16);
        let casters = GpuScene::upload(&ctx, &scene).unwrap();
        let receivers = GpuReceivers::upload(&ctx, &rec).unwrap();
        let v_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("caller's V"),
            size: 4 * rec.len() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let inputs = MultiSampleInputs {
            casters: &casters,
            views: &views,
            light: &scene.light,
            receivers: &receivers.buffer,
            count: receivers.count,
            v: &v_buf,
        };
        for _ in 0..3 {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            frame.encode(&mut enc, &inputs).unwrap();
            ctx.queue.submit([enc.finish()]);
        }
        let bits: Vec<u32> = ctx.read_buffer(&v_buf, 4 * rec.len() as u64).unwrap();
        let mut cpu = MultiSample::new().unwrap();
        let (v_cpu, _) = run(&mut cpu, &scene, &rec).unwrap();
        let mut gpu = baselines::GpuMultiSample::new(ctx.clone()).unwrap();
        let (v_gpu, _) = run(&mut gpu, &scene, &rec).unwrap();
        let mut worst = 0.0f32;
        let (mut differ, mut differ_gpu) = (0, 0);
        for (k, (&b, &c)) in bits.iter().zip(&v_cpu).enumerate() {
            let g = f32::from_bits(b);
            if !rec.active[k] {
                assert!(
                    g.is_nan() && c.is_nan(),
                    "multi-sample {name}: receiver {k}"
                );
                continue;
            }
            worst = worst.max((g - c).abs());
            differ += usize::from(g != c);
            differ_gpu += usize::from(g != v_gpu[k]);
        }
        println!("multi-sample {name}: frame API vs CPU twin, max |dV| {worst:.2e}, {differ} differ ({differ_gpu} from the GPU twin)");
        // Bit for bit the GPU twin's V (the same maps, the same kernels); against the CPU twin
        // a depth tie may flip one sub-light's test at a receiver (the twins' tolerance).
        assert_eq!(
            differ_gpu, 0,
            "multi-sample {name}: differs from the GPU twin"
        );
        let active = rec.active.iter().filter(|a| **a).count();
        assert!(
            differ * 1000 <= active && worst <= 1.0 / 16.0 + 1e-6,
            "multi-sample {name}: {differ} of {active} differ from the CPU twin, max |dV| {worst}"
        );
    }
}

/// Bad frames are refused with a typed error before anything is recorded: a view of another
/// resolution, a V buffer too small for the count, `depth=unorm16`.
#[test]
fn bad_frames_are_refused() {
    let Some(ctx) = context_for_tests("bad_frames_are_refused").unwrap() else {
        return;
    };
    let (scene, rec) = fixture("bunny", 16, 12);
    let mut params = Params::new(<Pcss as Filter>::SPECS).unwrap();
    let frame = MapFrame::<Pcss>::prepare(ctx.clone(), &params).unwrap();
    let (view, _) = frame.fit_view(&scene, &rec).unwrap();
    let casters = GpuScene::upload(&ctx, &scene).unwrap();
    let receivers = GpuReceivers::upload(&ctx, &rec).unwrap();
    let small = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("too small"),
        size: 4,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let inputs = FrameInputs {
        casters: &casters,
        view: &view,
        light: &scene.light,
        receivers: &receivers.buffer,
        count: receivers.count,
        v: &small,
    };
    let err = frame.encode(&mut enc, &inputs).unwrap_err().to_string();
    assert!(err.contains("V buffer"), "{err}");
    let mut half = view;
    half.r /= 2;
    let big = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("V"),
        size: 4 * rec.len() as u64,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let inputs = FrameInputs {
        view: &half,
        v: &big,
        ..inputs
    };
    let err = frame.encode(&mut enc, &inputs).unwrap_err().to_string();
    assert!(err.contains("resolution"), "{err}");
    params.set("depth", "unorm16").unwrap();
    let err = MapFrame::<Pcss>::prepare(ctx, &params)
        .err()
        .expect("unorm16 refused")
        .to_string();
    assert!(err.contains("depth"), "{err}");
}
