//! Criterion benches of the accumulation estimator on the sphere-light fixture (160x120 receivers,
//! r = 1024, K = 10): the light-space build and the estimate for additive/exact x fixed/adaptive,
//! on the CPU and (feature `gpu`, when an adapter exists) the GPU, where the estimate is timed as
//! dispatches between one submit and one wait (no upload, no readback). Ids:
//! `accumulation/<backend>/<stage>/<variant>-<kernel>`. Run: `cargo bench -p accumulation`.
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
        Ok(ctx) => {
            let mut gpu = accumulation::GpuAccumulation::new(ctx).expect("gpu");
            for (variant, kernel) in MODES {
                gpu.set_param("variant", variant).expect("variant");
                gpu.set_param("kernel", kernel).expect("kernel");
                gpu.build(&scene, &receivers).expect("build");
                let ls = gpu.cpu().light_space().expect("light space").clone();
                let prep = gpu
                    .prepare(&ls, scene.light(), &receivers)
                    .expect("prepare");
                g.bench_function(format!("gpu/estimate/{variant}-{kernel}"), |b| {
                    b.iter_custom(|iters| {
                        let ms = gpu.dispatch(&prep, iters as u32).expect("dispatch");
                        std::time::Duration::from_secs_f64(ms * 1e-3)
                    })
                });
            }
        }
        Err(e) => eprintln!("accumulation bench: GPU rows SKIPPED, no adapter: {e}"),
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
