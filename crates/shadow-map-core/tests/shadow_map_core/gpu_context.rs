//! A user's device wrapped by `GpuContext::from_device` keeps the host renderer's device-lost
//! callback (wgpu keeps one per device, so installing ours would silently replace theirs), and a
//! loss the host forwards with `report_device_lost` comes back from every later call as
//! `Error::DeviceLost`.
#![cfg(feature = "gpu")]

use crate::common;

use common::context_for_tests;
use shadow_map_core::{gpu::GpuContext, Error};
use std::sync::{Arc, Mutex};

#[test]
fn from_device_keeps_the_hosts_device_lost_callback() {
    if context_for_tests("from_device_keeps_the_hosts_device_lost_callback")
        .unwrap()
        .is_none()
    {
        return;
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
    });
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .expect("an adapter (the shared context found one)");
    let (device, queue) =
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default())).unwrap();
    // The host's own callback, installed before ours would have been.
    let host: Arc<Mutex<Option<String>>> = Arc::new(Mutex::new(None));
    let h = host.clone();
    device.set_device_lost_callback(move |reason, msg| {
        *h.lock().unwrap() = Some(format!("{reason:?}: {msg}"));
    });
    let ctx = GpuContext::from_device(device.clone(), queue);
    ctx.check_lost().unwrap();
    ctx.scoped("before the loss", || ()).unwrap();
    device.destroy();
    let _ = device.poll(wgpu::PollType::wait_indefinitely());
    let seen = host.lock().unwrap().clone();
    assert!(
        seen.as_deref().is_some_and(|m| m.contains("Destroyed")),
        "the host's callback did not fire: {seen:?}"
    );
    // The host forwards the loss; from then on every call through the context says so.
    ctx.report_device_lost(seen.unwrap());
    let err = ctx.scoped("after the loss", || ()).unwrap_err();
    assert!(matches!(err, Error::DeviceLost(_)), "{err}");
    assert!(matches!(
        ctx.clone().check_lost(),
        Err(Error::DeviceLost(_))
    ));
}

/// `GpuContext::readbacks` counts every buffer mapped back (frame_loop's "no readback during the
/// frames" is this count, not a literal): one `read_buffer`, one more.
#[test]
fn readbacks_are_counted() {
    let Some(ctx) = context_for_tests("readbacks_are_counted").unwrap() else {
        return;
    };
    let ctx = GpuContext::from_device(ctx.device.clone(), ctx.queue.clone());
    let buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readbacks_are_counted"),
        size: 16,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    assert_eq!(ctx.readbacks(), 0);
    let words: Vec<u32> = ctx.read_buffer(&buf, 16).unwrap();
    assert_eq!(words, vec![0; 4]);
    assert_eq!(ctx.readbacks(), 1);
    let _: Vec<u32> = ctx.read_buffer(&buf, 16).unwrap();
    assert_eq!(ctx.readbacks(), 2);
}

/// The non-blocking status readback: one copy in flight at a time, the words of the copied
/// frame (not of later writes), each map counted as a readback.
#[test]
fn status_readback_takes_the_copied_words_without_waiting() {
    use shadow_map_core::gpu::frame::{status_buffer, StatusReadback};
    let Some(ctx) =
        context_for_tests("status_readback_takes_the_copied_words_without_waiting").unwrap()
    else {
        return;
    };
    let ctx = GpuContext::from_device(ctx.device.clone(), ctx.queue.clone());
    let status = status_buffer(&ctx, "status", 3);
    let rb = StatusReadback::new(&ctx, status.size());
    assert_eq!(rb.take(), None, "nothing copied yet");
    ctx.queue
        .write_buffer(&status, 0, bytemuck::cast_slice(&[7u32, 0, 55]));
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    assert!(rb.copy(&mut enc, &status));
    assert!(
        !rb.copy(&mut enc, &status),
        "a second copy while one is on its way"
    );
    ctx.queue.submit([enc.finish()]);
    rb.submitted(&ctx);
    assert_eq!(ctx.readbacks(), 1);
    // A later frame's counts do not reach the copy already made.
    ctx.queue
        .write_buffer(&status, 0, bytemuck::cast_slice(&[1u32, 1, 1]));
    ctx.wait().unwrap();
    assert_eq!(rb.take(), Some(vec![7, 0, 55]));
    assert_eq!(rb.take(), None, "taken once");
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    assert!(rb.copy(&mut enc, &status), "free again after the take");
    ctx.queue.submit([enc.finish()]);
    rb.submitted(&ctx);
    ctx.wait().unwrap();
    assert_eq!(rb.take(), Some(vec![1, 1, 1]));
    assert_eq!(ctx.readbacks(), 2);
}

/// A specialised kernel compiles one pipeline per combination of switches, at its first use, and
/// each pipeline takes its branch: the override decides, not the default in the WGSL.
#[test]
fn a_specialized_kernel_compiles_each_combination_once() {
    use shadow_map_core::gpu::{
        frame::compute_pass,
        kernel::{storage_buffer, SpecializedKernel},
    };
    let Some(ctx) =
        context_for_tests("a_specialized_kernel_compiles_each_combination_once").unwrap()
    else {
        return;
    };
    let wgsl = "override FLAG: bool = false;\noverride SCALE: u32 = 1u;\n\
        @group(0) @binding(0) var<storage, read_write> out: array<u32>;\n\
        @compute @workgroup_size(1) fn main() { if FLAG { out[0] = 7u * SCALE; } else { out[0] = 3u * SCALE; } }";
    let k = SpecializedKernel::new(&ctx, "switches", &[wgsl], "main", &[]).unwrap();
    assert_eq!(k.compiled(), 0, "nothing compiled before the first use");
    let buf = storage_buffer(&ctx, "out", 4);
    let group = shadow_map_core::gpu::kernel::bind_group(
        &ctx,
        "switches",
        &k.layout,
        &[buf.as_entire_binding()],
    );
    let run = |switches: &[(&str, f64)]| -> u32 {
        let p = k.pipeline(&ctx, switches).unwrap();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        compute_pass(&mut enc, "switches", &p, &group, [1, 1, 1]);
        ctx.queue.submit([enc.finish()]);
        ctx.read_buffer::<u32>(&buf, 4).unwrap()[0]
    };
    assert_eq!(run(&[("FLAG", 1.0), ("SCALE", 2.0)]), 14);
    assert_eq!(run(&[("FLAG", 0.0), ("SCALE", 2.0)]), 6);
    assert_eq!(run(&[("FLAG", 1.0), ("SCALE", 2.0)]), 14);
    assert_eq!(
        k.compiled(),
        2,
        "the repeated combination is the kept pipeline"
    );
}

/// A kernel's layout is what its WGSL declares in group 0, by binding number, whatever the order
/// of the declarations; a resource kind no kernel uses is a typed error naming the kernel.
#[test]
fn a_kernel_layout_is_read_from_its_wgsl() {
    use shadow_map_core::gpu::kernel::{bindings_of, Binding};
    let head =
        "struct U { a: u32 }\n@group(0) @binding(3) var<storage, read_write> rw: array<u32>;\n";
    let rest = "@group(0) @binding(0) var<uniform> u: U;\n\
        @group(0) @binding(1) var<storage, read> ro: array<f32>;\n\
        @group(0) @binding(2) var tex: texture_2d<f32>;\n\
        @group(0) @binding(5) var arr: texture_2d_array<f32>;\n\
        @group(0) @binding(6) var dep: texture_depth_2d;\n\
        @group(0) @binding(7) var out: texture_storage_2d<r32float, write>;\n\
        @group(0) @binding(8) var outs: texture_storage_2d_array<r32float, write>;\n\
        @group(1) @binding(0) var<uniform> other: U;\n";
    let got = bindings_of("layout", &[head, rest]).unwrap();
    assert_eq!(
        got,
        [
            (0, Binding::Uniform),
            (1, Binding::Storage),
            (2, Binding::Texture2d),
            (3, Binding::StorageRw),
            (5, Binding::Texture2dArray),
            (6, Binding::TextureDepth2d),
            (7, Binding::StorageTexture2dR32Write),
            (8, Binding::StorageTexture2dArrayR32Write),
        ]
    );
    let e = bindings_of("odd", &["@group(0) @binding(0) var s: sampler;\n"]).unwrap_err();
    assert!(e.to_string().contains("odd"), "{e}");
    let e = bindings_of("broken", &["@group(0) @binding(0) var<uniform> u: Nope;"]).unwrap_err();
    assert!(e.to_string().contains("broken"), "{e}");
}
