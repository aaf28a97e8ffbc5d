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
