//! Criterion benches of the accumulation estimator on the sphere-light fixture (160x120 receivers,
//! r = 1024, K = 10): the light-space build and the estimate for additive/exact x fixed/adaptive
//! on the CPU, and (feature `gpu`, when an adapter exists) one frame of the engine path on the
//! GPU: the layers (and MSSM) rasterised, laid out and the kernel run, recorded into one encoder,
//! submitted and waited for (the frame's inputs uploaded once per mode, test-support's
//! `FrameRig`; no readback). Ids: `accumulation/<backend>/<stage>/<variant>-<kernel>`.
//! Run: `cargo bench -p accumulation`.
use accumulation::CpuAccumulation;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shadow_map_core::SoftShadowEstimator;
use std::hint::black_box;
use test_support::fixtures::authored_fixture;

const MODES: [(&str, &str); 4] = [
    ("additive", "fixed"),
    ("additive", "adaptive"),
    ("exact", "fixed"),
    ("exact", "adaptive"),
];

fn bench(c: &mut Criterion) {
    let (scene, receivers) = authored_fixture("sphere-light");
    let mut g = c.benchmark_group("accumulation");
    g.sample_size(10);
    g.throughput(Throughput::Elements(receivers.active_count() as u64));
    let mut v = vec![0.0f32; receivers.len()];
    let mut cpu = CpuAccumulation::new().expect("cpu");
    for (variant, kernel) in MODES {
        cpu.set_param("variant", variant).expect("variant");
        cpu.set_param("kernel", kernel).expect("kernel");
        g.bench_function(format!("cpu/build/{variant}-{kernel}"), |b| {
            b.iter(|| cpu.build(black_box(&scene), &receivers).expect("build"))
        });
        cpu.build(&scene, &receivers).expect("build");
        g.bench_function(format!("cpu/estimate/{variant}-{kernel}"), |b| {
            b.iter(|| {
                cpu.estimate(&scene, &receivers, black_box(&mut v))
                    .expect("estimate")
            })
        });
    }
    #[cfg(feature = "gpu")]
    match shadow_map_core::gpu::GpuContext::shared() {
        Ok(ctx) => gpu_frames(&mut g, &ctx, &scene, &receivers),
        Err(e) => eprintln!("accumulation bench: GPU rows SKIPPED, no adapter: {e}"),
    }
    g.finish();
}

/// One frame of the engine path per iteration (encode, submit, wait), for each mode.
#[cfg(feature = "gpu")]
fn gpu_frames(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    ctx: &std::sync::Arc<shadow_map_core::gpu::GpuContext>,
    scene: &shadow_map_core::Scene,
    receivers: &shadow_map_core::Receivers,
) {
    use accumulation::AccumulationFrame;
    use test_support::{fixtures::param_table, frame_run::FrameRig};
    for (variant, kernel) in MODES {
        let params = param_table(
            accumulation::settings::SPECS,
            &[("variant", variant), ("kernel", kernel)],
        );
        let frame = AccumulationFrame::prepare(ctx.clone(), &params).expect("frame");
        let rig = FrameRig::new(ctx, &frame, scene, receivers).expect("rig");
        g.bench_function(format!("gpu/frame/{variant}-{kernel}"), |b| {
            b.iter(|| {
                black_box(&rig).submit(ctx, &frame).expect("frame");
                ctx.wait().expect("wait");
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
