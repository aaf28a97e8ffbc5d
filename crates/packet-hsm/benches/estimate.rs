//! Criterion bench of the estimate stage: per-pixel GBP07 (flat) vs hierarchy vs packets +
//! hierarchy, on the bunny fixture at 160x120, r = 512, under the fixture's light and a 2x light.
//! `cargo bench -p packet-hsm --bench estimate`
use criterion::{criterion_group, criterion_main, Criterion};
use packet_hsm::CpuPacketHsm;
use shadow_map_core::SoftShadowEstimator;
use test_support::fixtures::fixture;

fn bench(c: &mut Criterion) {
    let (mut scene, rec) = fixture("bunny", 160, 120);
    let base = *scene.light();
    let mut g = c.benchmark_group("packet-hsm estimate");
    g.sample_size(10);
    for scale in [1.0f32, 2.0] {
        scene.set_light(base.scaled(scale)).unwrap();
        for (label, kv) in [
            (
                "gbp07",
                [
                    ("packet", "1x1"),
                    ("hierarchy", "false"),
                    ("coherence", "false"),
                ],
            ),
            (
                "hierarchy",
                [
                    ("packet", "1x1"),
                    ("hierarchy", "true"),
                    ("coherence", "true"),
                ],
            ),
            (
                "packets+hierarchy",
                [
                    ("packet", "3x3"),
                    ("hierarchy", "true"),
                    ("coherence", "true"),
                ],
            ),
        ] {
            let mut e = CpuPacketHsm::new().expect("new");
            e.set_param("resolution", "512").expect("res");
            for (k, v) in kv {
                e.set_param(k, v).expect("param");
            }
            let mut v = vec![0.0f32; rec.len()];
            g.bench_function(format!("{label} light x{scale}"), |b| {
                b.iter(|| {
                    e.build(&scene, &rec).expect("build");
                    e.estimate(&scene, &rec, &mut v).expect("estimate");
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
