//! Criterion benchmarks of the deep shadow map stages on the hair fixture (320x240 receivers,
//! resolution 512): fragment rasterisation, list build, processing, linking, lookups with each
//! filter and traversal on the CPU, and on the GPU when an adapter exists one frame of the engine
//! path (encode, submit, wait; the casters and receivers uploaded once, nothing read back).
//! Ids: `deep-shadow/<backend>/<stage>`. Run: `cargo bench -p deep-shadow --bench deep_shadow`.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use deep_shadow::{
    cpu::{
        dsm::DeepShadowMap,
        raster::{fragments, prepare},
    },
    math::view::{lookup_settings, query, sublight_view, Query},
    settings::Settings,
    CpuDeepShadow,
};
use glam::Vec2;
use shadow_map_core::{Receivers, Scene, SoftShadowEstimator};
use std::hint::black_box;
use test_support::fixtures::fixture;

const R: u32 = 512;

fn setup() -> (Scene, Receivers) {
    fixture("hair", 320, 240)
}

fn bench(c: &mut Criterion) {
    let (scene, rec) = setup();
    let mut s = Settings::from_params(CpuDeepShadow::new().unwrap().params()).unwrap();
    s.resolution = R;
    s.kernel = 7;
    let (view, _) = sublight_view(&scene, &rec, Vec2::ZERO, R, 3).unwrap();
    let tris = prepare(&scene, &view);
    let frags = fragments(&tris, R);
    let mut g = c.benchmark_group("deep-shadow");
    g.sample_size(10);
    g.throughput(Throughput::Elements(frags.len() as u64));
    g.bench_function("cpu/raster", |b| b.iter(|| fragments(black_box(&tris), R)));
    g.bench_function("cpu/insert", |b| {
        b.iter(|| DeepShadowMap::build(black_box(&frags), R, 0, 1 << 26).unwrap())
    });
    let built = DeepShadowMap::build(&frags, R, 0, 1 << 26).unwrap();
    g.bench_function("cpu/process", |b| {
        b.iter(|| {
            let mut d = built.clone();
            d.process(black_box(0.001), 0.0);
            d
        })
    });
    let mut processed = built.clone();
    processed.process(0.001, 0.0);
    g.bench_function("cpu/link", |b| {
        b.iter(|| {
            let mut d = processed.clone();
            d.link();
            d
        })
    });
    let mut dsm = processed.clone();
    dsm.link();
    let looks: Vec<(Vec2, shadow_map_core::ReceiverPlane)> = (0..rec.len())
        .filter(|&k| rec.active()[k])
        .filter_map(
            |k| match query(&view, scene.light(), rec.position()[k], rec.normal()[k], &s) {
                Query::Look { uv, plane, .. } => Some((uv, plane)),
                Query::Fixed(_) => None,
            },
        )
        .collect();
    g.throughput(Throughput::Elements(looks.len() as u64));
    for (label, filter, kernel) in [
        ("none", "none", "1"),
        ("pcf3", "pcf", "3"),
        ("pcf7", "pcf", "7"),
        ("edsm7", "edsm", "7"),
        ("pcss", "pcss", "3"),
    ] {
        for traversal in ["linked", "naive"] {
            let mut p = CpuDeepShadow::new().unwrap();
            p.set_param("filter", filter).unwrap();
            p.set_param("kernel", kernel).unwrap();
            p.set_param("traversal", traversal).unwrap();
            let ls = lookup_settings(&view, scene.light(), &p.settings());
            g.bench_function(format!("cpu/lookup/{label}/{traversal}"), |b| {
                b.iter(|| {
                    looks
                        .iter()
                        .map(|(uv, plane)| dsm.transmittance_plane(*uv, plane, &ls).0)
                        .sum::<f32>()
                })
            });
        }
    }
    #[cfg(feature = "gpu")]
    if let Ok(ctx) = shadow_map_core::gpu::GpuContext::shared() {
        g.throughput(Throughput::Elements(rec.active_count() as u64));
        gpu_frame(&mut g, &ctx, &scene, &rec);
    } else {
        eprintln!("deep-shadow bench: no GPU adapter, GPU benchmark skipped");
    }
    g.finish();
}

/// `gpu/frame/edsm7`: one frame of the engine path at `edsm` 7 x 7 (lists: the hair is
/// semi-transparent), encoded into its own encoder, submitted and waited for.
#[cfg(feature = "gpu")]
fn gpu_frame(
    g: &mut test_support::bench::Group<'_>,
    ctx: &std::sync::Arc<shadow_map_core::gpu::GpuContext>,
    scene: &Scene,
    rec: &Receivers,
) {
    use deep_shadow::DeepShadowFrame;
    use test_support::fixtures::param_table;
    let params = param_table(
        deep_shadow::settings::SPECS,
        &[("resolution", "512"), ("filter", "edsm"), ("kernel", "7")],
    );
    let frame = DeepShadowFrame::prepare(ctx.clone(), &params, rec.len() as u32).unwrap();
    test_support::bench::frame_row(g, ctx, &frame, "edsm7", scene, rec);
}

criterion_group!(benches, bench);
criterion_main!(benches);
