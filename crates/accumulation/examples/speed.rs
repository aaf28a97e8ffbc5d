//! Speed of accumulation's engine path against the CPU twin's estimate, and taps per second:
//! the speed case (the bunny fixture with its light replaced by a sphere of the same size,
//! K = 10) at a chosen receiver count and map resolution.
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release -p accumulation --example speed -- \
//!     [--size 1920x1080] [--res 2048] [--reps 20] [--cpu]
//! ```
//!
//! Frame ms: `reps` frames of [`AccumulationFrame`] (layers, MSSM, layout copies and kernel),
//! each recorded and submitted, one wait after the last, divided by `reps` (the frame's inputs
//! uploaded once per mode, test-support's `FrameRig`; no readback). Maps ms: the same frames
//! over no receivers (the kernel is not dispatched). Kernel ms: their difference, wall-clock on
//! any adapter (lavapipe's timestamps do not time its compute work). Taps: lexel fetches per
//! receiver as the CPU twin counts them (same kernel), so taps/s = taps / kernel time; compare
//! with the texture-fetch ceiling in docs/methods.md §12.
use accumulation::{AccumulationFrame, CpuAccumulation};
use shadow_map_core::{
    gpu::{
        frame::{FrameEstimator, FrameInputs},
        GpuContext,
    },
    run, LightShape, Params, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use std::time::Instant;
use test_support::{fixtures::note, frame_run::FrameRig};

mod common;

fn main() {
    let mut size = (320u32, 240u32);
    let mut res = 1024u32;
    let mut reps = 10u32;
    let mut cpu_time = false;
    for (flag, value) in common::flags(&["--cpu"]) {
        match flag.as_str() {
            "--size" => size = common::size(&value),
            "--res" => res = value.parse().unwrap_or(res),
            "--reps" => reps = value.parse().unwrap_or(reps),
            "--cpu" => cpu_time = true,
            other => panic!("unknown argument {other}"),
        }
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
    println!(
        "| variant | kernel | res | taps/receiver | frame ms | maps ms | kernel ms | G taps/s | CPU ms |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
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
        let mut params = Params::new(accumulation::settings::SPECS).unwrap();
        for (k, v) in &kv {
            cpu.set_param(k, v).unwrap();
            params.set(k, v).unwrap();
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
        let frame = AccumulationFrame::prepare(ctx.clone(), &params).expect("frame");
        let rig = FrameRig::new(&ctx, &frame, &scene, &rec).expect("frame inputs");
        let inputs = rig.inputs();
        let count = inputs.count;
        let frames = |n: u32, count: u32| {
            let t = Instant::now();
            for _ in 0..n {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let inputs = FrameInputs { count, ..inputs };
                frame.encode(&mut enc, &inputs).expect("encode");
                ctx.queue.submit([enc.finish()]);
            }
            ctx.wait().expect("wait");
            t.elapsed().as_secs_f64() * 1e3 / n as f64
        };
        frames(1, count);
        let frame_ms = frames(reps.max(1), count);
        let maps_ms = frames(reps.max(1), 0);
        let kernel_ms = (frame_ms - maps_ms).max(f64::MIN_POSITIVE);
        let gtaps = taps * rec.active_count() as f64 / (kernel_ms * 1e-3) / 1e9;
        println!(
            "| {variant} | {kernel} | {res} | {taps:.1} | {frame_ms:.3} | {maps_ms:.3} | \
             {kernel_ms:.3} | {gtaps:.3} | {cpu_ms} |"
        );
    }
}
