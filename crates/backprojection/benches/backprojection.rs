//! Criterion benches of the backprojection estimator at fixture settings (the bunny under its rect
//! light, 320x240 receivers, r = 1024): the light-space build and the estimate, 1 and 3 layers, on
//! the CPU and (feature `gpu`, when an adapter exists) the GPU. Ids:
//! `backprojection/<backend>/<stage>/layers-<k>`. Run: `cargo bench -p backprojection`.
use backprojection::CpuBackprojection;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shadow_map_core::SoftShadowEstimator;
use std::hint::black_box;
use test_support::fixtures::authored_fixture;

fn bench(c: &mut Criterion) {
    let (scene, receivers) = authored_fixture("bunny");
    let mut g = c.benchmark_group("backprojection");
    g.sample_size(10);
    g.throughput(Throughput::Elements(receivers.active_count() as u64));
    let mut estimators: Vec<Box<dyn SoftShadowEstimator>> =
        vec![Box::new(CpuBackprojection::new().expect("cpu"))];
    #[cfg(feature = "gpu")]
    match shadow_map_core::gpu::GpuContext::shared() {
        Ok(ctx) => estimators.push(Box::new(
            backprojection::GpuBackprojection::new(ctx).expect("gpu"),
        )),
        Err(e) => eprintln!("backprojection bench: GPU rows SKIPPED, no adapter: {e}"),
    }
    let mut v = vec![0.0f32; receivers.len()];
    for e in &mut estimators {
        let backend = e.backend();
        for k in [1, 3] {
            e.set_param("layers", &k.to_string()).expect("layers");
            g.bench_function(format!("{backend}/build/layers-{k}"), |b| {
                b.iter(|| e.build(black_box(&scene), &receivers).expect("build"))
            });
            e.build(&scene, &receivers).expect("build");
            g.bench_function(format!("{backend}/estimate/layers-{k}"), |b| {
                b.iter(|| {
                    e.estimate(&scene, &receivers, black_box(&mut v))
                        .expect("estimate")
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
