//! Estimate-stage speed of the accumulation twins, and taps per second: the speed case
//! (the bunny fixture with its light replaced by a sphere of the same size, K = 10) at a chosen
//! receiver count and map resolution.
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release -p accumulation --example speed -- \
//!     [--size 1920x1080] [--res 2048] [--reps 20] [--cpu]
//! ```
//!
//! GPU time: `reps` dispatches between one submit and one wait, divided by `reps` (no upload, no
//! readback). Taps: lexel fetches per receiver as the CPU twin counts them (same kernel), so
//! taps/s = taps / GPU time; compare with the texture-fetch ceiling in docs/methods.md §12.
use accumulation::{CpuAccumulation, GpuAccumulation};
use shadow_map_core::{
    gpu::GpuContext, run, LightShape, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use std::time::Instant;
use test_support::fixtures::note;

fn main() {
    let mut size = (320u32, 240u32);
    let mut res = 1024u32;
    let mut reps = 10u32;
    let mut cpu_time = false;
    let a: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < a.len() {
        let next = a.get(i + 1).cloned().unwrap_or_default();
        match a[i].as_str() {
            "--size" => {
                let p: Vec<u32> = next.split('x').filter_map(|x| x.parse().ok()).collect();
                size = (p[0], p[1]);
            }
            "--res" => res = next.parse().unwrap_or(res),
            "--reps" => reps = next.parse().unwrap_or(reps),
            "--cpu" => {
                cpu_time = true;
                i += 1;
                continue;
            }
            other => panic!("unknown argument {other}"),
        }
        i += 2;
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/bunny/bunny.toml"
    );
    let mut scene = Scene::load(path).expect("fixture loads");
    scene.set_resolution(size.0, size.1).unwrap();
    let mut light = *scene.light();
    let radius = 0.5 * light.diameter() / std::f32::consts::SQRT_2;
    light.shape = LightShape::Sphere { radius };
    scene.set_light(light).unwrap();
    let t = Instant::now();
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    eprintln!(
        "{}x{} receivers ({} active) in {:.1} s",
        size.0,
        size.1,
        rec.active_count(),
        t.elapsed().as_secs_f64()
    );
    let ctx = GpuContext::shared().expect("a Vulkan adapter");
    println!("device: {}", ctx.describe());
    println!("| variant | kernel | res | taps/receiver | GPU ms | G taps/s | CPU ms |");
    println!("|---|---|---|---|---|---|---|");
    for (variant, kernel) in [
        ("additive", "fixed"),
        ("additive", "adaptive"),
        ("exact", "fixed"),
        ("exact", "adaptive"),
    ] {
        let kv = [
            ("resolution", res.to_string()),
            ("k", "10".to_string()),
            ("variant", variant.to_string()),
            ("kernel", kernel.to_string()),
        ];
        let mut cpu = CpuAccumulation::new().unwrap();
        for (k, v) in &kv {
            cpu.set_param(k, v).unwrap();
        }
        let (_, report) = run(&mut cpu, &scene, &rec).expect("cpu run");
        let taps: f64 = note(&report, "taps_per_receiver")
            .and_then(|n| n.parse().ok())
            .unwrap_or(0.0);
        let cpu_ms = if cpu_time {
            format!("{:.1}", report.total_ms("estimate"))
        } else {
            "-".into()
        };
        let mut gpu = GpuAccumulation::new(ctx.clone()).unwrap();
        for (k, v) in &kv {
            gpu.set_param(k, v).unwrap();
        }
        let ls = cpu.light_space().unwrap().clone();
        let prep = gpu.prepare(&ls, scene.light(), &rec).expect("prepare");
        gpu.dispatch(&prep, 1).expect("warm-up");
        let ms = gpu.dispatch(&prep, reps).expect("dispatch") / reps as f64;
        let gtaps = taps * rec.active_count() as f64 / (ms * 1e-3) / 1e9;
        println!("| {variant} | {kernel} | {res} | {taps:.1} | {ms:.3} | {gtaps:.2} | {cpu_ms} |");
    }
}
