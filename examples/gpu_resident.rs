//! A GPU estimator inside a user's own wgpu device, with the receivers already in the user's GPU
//! buffer and V left in another one: nothing is read back until the user asks. The user's
//! G-buffer pass is simulated by packing a fixture's camera receivers into a plain storage buffer
//! (`pack_receivers`); the CPU knows only a box holding them, which fits the light view
//! (`build_resident`). At the end V is read back once, to print it against the ordinary path
//! (CPU receivers in, V read back).
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release --example gpu_resident
//! ```
use shadow_map_core::{
    gpu::{receivers::GpuReceivers, shared::pack_receivers, GpuContext},
    light_view::receiver_bounds,
    run, Receivers, Scene, SceneBvh, SoftShadowEstimator,
};
use softshadow::backprojection::GpuBackprojection;
use std::sync::Arc;
use wgpu::util::DeviceExt;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The user's device.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("my renderer"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    println!("adapter: {:?}", adapter.get_info().name);
    let ctx = Arc::new(GpuContext::from_device(device.clone(), queue.clone()));

    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/bunny/bunny.toml"
    ))?;
    // The user's G-buffer pass, simulated: receivers (32-byte `ReceiverGpu`s) in their buffer,
    // and a world-space box that holds them (a renderer knows one, e.g. its view frustum clipped
    // to the scene).
    let cpu_receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let bounds = receiver_bounds(&cpu_receivers);
    let count = cpu_receivers.len() as u32;
    let receiver_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("my G-buffer receivers"),
        contents: bytemuck::cast_slice(&pack_receivers(&cpu_receivers)),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let v_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("my V"),
        size: count as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });

    // The estimator on the user's buffers: light space built on the GPU, V written to `v_buffer`,
    // nothing read back.
    let receivers = GpuReceivers::from_buffer(receiver_buffer, count)?;
    let mut bp = GpuBackprojection::new(ctx.clone())?;
    bp.build_resident(&scene, &bounds)?;
    bp.estimate_resident(&scene, &receivers, &v_buffer)?;
    let report = bp.report();
    println!(
        "{} resident: {count} receivers, build {:.1} ms, estimate submitted in {:.1} ms",
        bp.name(),
        report.total_ms("build"),
        report.total_ms("estimate")
    );
    // ... the user's own passes would read `v_buffer` here, on the same queue ...

    // Only now, because the user asks: V back on the CPU, against the ordinary path.
    let v: Vec<f32> = ctx.read_buffer(&v_buffer, count as u64 * 4)?;
    let counters: Vec<u32> = match bp.resident_counters() {
        Some(c) => ctx.read_buffer(c, 8)?,
        None => vec![0, 0],
    };
    let (v_ordinary, _) = run(&mut GpuBackprojection::new(ctx)?, &scene, &cpu_receivers)?;
    let (mut sum, mut sq, mut n) = (0.0f64, 0.0f64, 0usize);
    for (a, b) in v.iter().zip(&v_ordinary) {
        if !a.is_nan() {
            sum += *a as f64;
            sq += ((a - b) as f64).powi(2);
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    println!(
        "mean V {:.4} over {n} active receivers; RMSE against the ordinary path {:.4}; \
         outside the light frustum {}, non-finite {}",
        sum / n,
        (sq / n).sqrt(),
        counters[0],
        counters[1]
    );
    Ok(())
}
