//! A GPU estimator inside a user's own wgpu device: the user creates the instance, adapter,
//! device and queue (here headless, as a renderer would before creating its surface), wraps them
//! in a `GpuContext` without giving up ownership of anything else, and runs the GPU estimators of
//! PCSS and backprojection on it (the registry's: each method's engine path run by the core's
//! `FrameTwin`). Receivers come from the CPU here and V is read back; for receivers already in
//! the user's GPU buffers, with V left there, see the frame API in `examples/frame_loop.rs`.
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release --example gpu_own_device
//! ```
use shadow_map_core::{gpu::GpuContext, run, Receivers, Scene, SceneBvh};
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The user's device.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("my renderer"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    println!("adapter: {:?}", adapter.get_info().name);
    let ctx = Arc::new(GpuContext::from_device(device.clone(), queue.clone()));
    // The renderer keeps its own device-lost callback and forwards losses to the context (a weak
    // handle: the device holding a callback that holds the device would never be freed).
    let weak = Arc::downgrade(&ctx);
    device.set_device_lost_callback(move |reason, msg| {
        eprintln!("my renderer: device lost ({reason:?}: {msg})");
        if let Some(c) = weak.upgrade() {
            c.report_device_lost(format!("{reason:?}: {msg}"));
        }
    });

    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/parallel-squares/parallel-squares.toml"
    );
    let scene = Scene::load(path)?;
    let receivers = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let methods = [
        softshadow::baselines::PCSS,
        softshadow::backprojection::DESCRIPTOR,
    ];
    for method in methods {
        let Some(e) = method.gpu(ctx.clone()) else {
            println!("{}: no GPU estimator in this build", method.name());
            continue;
        };
        let mut e = e?;
        let (v, report) = run(e.as_mut(), &scene, &receivers)?;
        let lit: Vec<f32> = v.into_iter().filter(|x| !x.is_nan()).collect();
        println!(
            "{} on the user's device: mean V {:.4}, prepare {:.1} ms (once: pipelines, maps), \
             frame {:.1} ms (receivers up, V back)",
            e.name(),
            lit.iter().sum::<f32>() / lit.len().max(1) as f32,
            report.total_ms("prepare"),
            report.total_ms("estimate")
        );
    }
    // The device is still the user's: keep using it.
    device.poll(wgpu::PollType::wait_indefinitely())?;
    Ok(())
}
