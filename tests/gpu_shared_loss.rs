//! `GpuContext::shared` after its device is lost (one of the faults a renderer meets): the
//! next `shared()` hands out a fresh context, so the registry's GPU twins (and the CLI) work
//! again, while estimators made on the lost one give `Error::DeviceLost`. Its own test binary:
//! it destroys the process-wide device, which every other test of a binary would share.
#![cfg(feature = "gpu")]

use shadow_map_core::{gpu::GpuContext, run, Error};
use softshadow::{estimator, Backend};
use std::sync::Arc;
use test_support::gpu;

#[test]
fn shared_context_is_replaced_once_its_device_is_lost() {
    let Some(first) = gpu("shared_context_is_replaced_once_its_device_is_lost") else {
        return;
    };
    let (scene, rec) = test_support::fixtures::fixture("parallel-squares", 16, 12);
    let make = || {
        let mut e = estimator("pcf", Backend::Gpu).unwrap();
        e.set_param("resolution", "128").unwrap();
        e
    };
    let mut before = make();
    let v0 = run(before.as_mut(), &scene, &rec).unwrap().0;
    assert!(Arc::ptr_eq(&first, &GpuContext::shared().unwrap()));

    // Lost: destroyed, not even polled (shared() polls it without blocking).
    first.device.destroy();
    let second = GpuContext::shared().unwrap();
    assert!(
        !Arc::ptr_eq(&first, &second),
        "shared() still hands out the lost device"
    );
    assert!(matches!(first.check_lost(), Err(Error::DeviceLost(_))));
    second.check_lost().unwrap();
    assert!(Arc::ptr_eq(&second, &GpuContext::shared().unwrap()));

    // The estimator made on the lost context says so; one made now works and agrees.
    match run(before.as_mut(), &scene, &rec) {
        Err(Error::DeviceLost(_)) => {}
        other => panic!("an estimator on the lost device: {:?}", other.map(|_| ())),
    }
    let v1 = run(make().as_mut(), &scene, &rec).unwrap().0;
    assert_eq!(v0.len(), v1.len());
    for (k, (a, b)) in v0.iter().zip(&v1).enumerate() {
        assert!(
            a.to_bits() == b.to_bits() || (a - b).abs() <= 1e-5,
            "receiver {k}: {a} / {b}"
        );
    }
}
