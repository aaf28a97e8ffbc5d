//! Criterion benches of the backprojection estimator at fixture settings (the bunny under its rect
//! light, 320x240 receivers, r = 1024), 1 and 3 layers. On the CPU: the light-space build and the
//! estimate. On the GPU (feature `gpu`, when an adapter exists): the registry's GPU estimator
//! (the engine path run by the core's `FrameTwin`: `build` fits the view, `estimate` uploads the
//! receivers, records one frame, submits it and reads V back), and the frame alone as a
//! renderer runs it (`frame`: encode, submit, wait; casters and receivers already on the
//! device, nothing read back). Ids: `backprojection/<backend>/<stage>/layers-<k>`. Run:
//! `cargo bench -p backprojection`.
use backprojection::CpuBackprojection;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shadow_map_core::SoftShadowEstimator;
use test_support::{bench, fixtures::authored_fixture};

fn bench(c: &mut Criterion) {
    let (scene, receivers) = authored_fixture("bunny");
    let mut g = c.benchmark_group("backprojection");
    g.sample_size(10);
    g.throughput(Throughput::Elements(receivers.active_count() as u64));
    let mut estimators: Vec<Box<dyn SoftShadowEstimator>> =
        vec![Box::new(CpuBackprojection::new().expect("cpu"))];
    #[cfg(feature = "gpu")]
    let ctx = match shadow_map_core::gpu::GpuContext::shared() {
        Ok(ctx) => {
            estimators.push(
                backprojection::DESCRIPTOR
                    .gpu(ctx.clone())
                    .expect("a GPU estimator")
                    .expect("gpu"),
            );
            Some(ctx)
        }
        Err(e) => {
            eprintln!("backprojection bench: GPU rows SKIPPED, no adapter: {e}");
            None
        }
    };
    for e in &mut estimators {
        for k in [1, 3] {
            e.set_param("layers", &k.to_string()).expect("layers");
            bench::build_and_estimate(
                &mut g,
                e.as_mut(),
                &format!("layers-{k}"),
                &scene,
                &receivers,
            );
        }
    }
    #[cfg(feature = "gpu")]
    if let Some(ctx) = ctx {
        frame_rows(&mut g, &ctx, &scene, &receivers);
    }
    g.finish();
}

/// `gpu/frame/layers-<k>`: one frame recorded, submitted and waited for (the inputs uploaded
/// once, outside the timed loop).
#[cfg(feature = "gpu")]
fn frame_rows(
    g: &mut bench::Group<'_>,
    ctx: &std::sync::Arc<shadow_map_core::gpu::GpuContext>,
    scene: &shadow_map_core::Scene,
    receivers: &shadow_map_core::Receivers,
) {
    use test_support::fixtures::param_table;
    for k in [1, 3] {
        let params = param_table(
            backprojection::settings::SPECS,
            &[("layers", k.to_string())],
        );
        let frame =
            backprojection::BackprojectionFrame::prepare(ctx.clone(), &params).expect("frame");
        bench::frame_row(g, ctx, &frame, &format!("layers-{k}"), scene, receivers);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
