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
use test_support::{bench, fixtures::authored_fixture};

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
    let mut cpu = CpuAccumulation::new().expect("cpu");
    for (variant, kernel) in MODES {
        cpu.set_param("variant", variant).expect("variant");
        cpu.set_param("kernel", kernel).expect("kernel");
        bench::build_and_estimate(
            &mut g,
            &mut cpu,
            &format!("{variant}-{kernel}"),
            &scene,
            &receivers,
        );
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
    g: &mut bench::Group<'_>,
    ctx: &std::sync::Arc<shadow_map_core::gpu::GpuContext>,
    scene: &shadow_map_core::Scene,
    receivers: &shadow_map_core::Receivers,
) {
    use accumulation::AccumulationFrame;
    use test_support::fixtures::param_table;
    for (variant, kernel) in MODES {
        let params = param_table(
            accumulation::settings::SPECS,
            &[("variant", variant), ("kernel", kernel)],
        );
        let frame = AccumulationFrame::prepare(ctx.clone(), &params).expect("frame");
        bench::frame_row(
            g,
            ctx,
            &frame,
            &format!("{variant}-{kernel}"),
            scene,
            receivers,
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
