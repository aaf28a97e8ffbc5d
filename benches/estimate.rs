//! CPU benchmarks of the baselines on a fixture, with the in-run ceiling they are measured
//! against: a plain Rust loop doing the same depth-map taps as PCF (N x N per receiver).
//!
//! Ids: `<algo>/cpu/<stage>/<fixture>`; throughput in receivers. Run:
//! `cargo bench --bench estimate` (set `SOFTSHADOW_BENCH_FIXTURE` to another scene file).
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shadow_map_core::{LightSpace, LightSpaceRequest, Receivers, Scene, SceneBvh};
use softshadow::{estimator, Backend};
use std::hint::black_box;

fn fixture() -> (String, Scene, Receivers) {
    let path = std::env::var("SOFTSHADOW_BENCH_FIXTURE").unwrap_or_else(|_| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bunny/bunny.toml").to_string()
    });
    let scene = Scene::load(&path).expect("fixture loads");
    let bvh = SceneBvh::new(&scene);
    let receivers = Receivers::from_camera(&scene, &bvh);
    let name = std::path::Path::new(&path)
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    (name, scene, receivers)
}

fn bench(c: &mut Criterion) {
    let (name, scene, receivers) = fixture();
    let n = receivers.active_count() as u64;
    let mut g = c.benchmark_group("cpu");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n));
    let req = LightSpaceRequest::single(1024);
    g.bench_function(format!("shadow-map/cpu/build/{name}"), |b| {
        b.iter(|| LightSpace::build(black_box(&scene), &receivers, &req).expect("build"))
    });
    for algo in ["hard", "pcf", "pcss", "multi-sample"] {
        let mut e = estimator(algo, Backend::Cpu).expect("registered");
        e.build(&scene, &receivers).expect("build");
        let mut v = vec![0.0f32; receivers.len()];
        g.bench_function(format!("{algo}/cpu/estimate/{name}"), |b| {
            b.iter(|| {
                e.estimate(&scene, &receivers, black_box(&mut v))
                    .expect("estimate")
            })
        });
    }
    // Ceiling: 5 x 5 taps per receiver from the same map with nothing else, the most a PCF of that
    // size can do on this machine.
    let ls = LightSpace::build(&scene, &receivers, &req).expect("build");
    let d = &ls.layers[0];
    let uv: Vec<(i32, i32, f32)> = receivers
        .position()
        .iter()
        .zip(receivers.active())
        .filter(|(_, a)| **a)
        .map(|(p, _)| {
            let q = ls.view.frame.to_light(*p);
            let t = ls.view.project(q);
            (t.x as i32, t.y as i32, q.z)
        })
        .collect();
    g.bench_function(format!("ceiling/cpu/taps-5x5/{name}"), |b| {
        b.iter(|| {
            use rayon::prelude::*;
            uv.par_iter()
                .map(|&(i, j, z)| {
                    let mut s = 0.0f32;
                    for dj in -2..=2 {
                        for di in -2..=2 {
                            s += (d.at(i + di, j + dj) >= z) as u32 as f32;
                        }
                    }
                    s
                })
                .sum::<f32>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
