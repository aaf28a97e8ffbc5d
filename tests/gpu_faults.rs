//! Faults a renderer meets, over every GPU estimator: the eight engine paths
//! (`FRAME_ALGOS`, made by `frame_estimator`) and the eight GPU twins (`METHODS`' `gpu`).
//!
//! * **Device loss**: a private device (`GpuContext::new`, never the shared one) is destroyed
//!   for real (`Device::destroy`; wgpu reports it at the device's next poll, which the test
//!   makes, as a renderer's loop does); from then on `encode`, `fit_views`, `prepare`, the
//!   uploads, readbacks and a twin's `build`/`estimate` give `Error::DeviceLost`, never a panic.
//!   Recovery: on a recreated device, a freshly prepared estimator gives exactly what one on a
//!   device that never saw a loss gives. (`GpuContext::shared` replacing a lost device is
//!   tests/gpu_shared_loss.rs, its own binary.)
//! * **Limits**: on a device requested with lowered limits (cheap to exceed without allocating
//!   anything large), a resolution past `max_texture_dimension_2d`, receiver counts past
//!   `max_storage_buffer_binding_size` and layers past `max_texture_array_layers` give
//!   `Error::Limit` whose `what` names the limit, never a wgpu validation panic or
//!   `Error::Gpu`.
#![cfg(feature = "gpu")]

use shadow_map_core::{
    gpu::{
        frame::{FrameEstimator, FrameInputs, Views},
        receivers::GpuReceivers,
        GpuContext, GpuScene,
    },
    run, Error, Params, Receivers, Result, Scene, SoftShadowEstimator,
};
use softshadow::{MethodDescriptor, FRAME_ALGOS, METHODS};
use std::{
    panic::{catch_unwind, AssertUnwindSafe},
    sync::Arc,
};
use test_support::{fixtures::configure, gate::gpu};

/// The parallel-squares fixture at a small image, and its camera receivers.
fn scene() -> (Scene, Receivers) {
    test_support::fixtures::fixture("parallel-squares", 16, 12)
}

/// `algo`'s own parameter table with `resolution` set.
fn params(algo: &str, resolution: u32) -> Params {
    let mut p = softshadow::method(algo)
        .unwrap()
        .cpu()
        .unwrap()
        .params()
        .clone();
    p.set("resolution", &resolution.to_string()).unwrap();
    p
}

/// `algo`'s engine path on `ctx`.
fn frame(
    algo: &str,
    ctx: &Arc<GpuContext>,
    p: &Params,
    max_receivers: u32,
) -> Result<Box<dyn FrameEstimator>> {
    Ok(softshadow::frame_estimator(algo, ctx.clone(), p, max_receivers)?.expect("an engine path"))
}

/// `m`'s GPU twin on `ctx` with every `(key, value)` of `kv` set.
fn twin(
    m: &MethodDescriptor,
    ctx: &Arc<GpuContext>,
    kv: &[(&str, &str)],
) -> Box<dyn SoftShadowEstimator> {
    let mut e = m.gpu(ctx.clone()).expect("a GPU twin").unwrap();
    configure(e.as_mut(), kv);
    e
}

/// The GPU twin of the method `algo` on `ctx` ([`twin`]).
fn twin_of(algo: &str, ctx: &Arc<GpuContext>, kv: &[(&str, &str)]) -> Box<dyn SoftShadowEstimator> {
    twin(softshadow::method(algo).unwrap(), ctx, kv)
}

/// `f()`, with a panic turned into a test failure naming `what`.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|_| panic!("{what}: panicked"))
}

fn assert_lost<T: std::fmt::Debug>(what: &str, r: Result<T>) {
    match r {
        Err(Error::DeviceLost(_)) => {}
        other => panic!("{what}: expected Error::DeviceLost, got {other:?}"),
    }
}

/// The caller's side of a frame: casters, receivers and V on `ctx`.
struct Caller {
    casters: GpuScene,
    receivers: GpuReceivers,
    v: wgpu::Buffer,
}

impl Caller {
    fn new(ctx: &GpuContext, scene: &Scene, rec: &Receivers) -> Result<Self> {
        Ok(Caller {
            casters: GpuScene::upload(ctx, scene)?,
            receivers: GpuReceivers::upload(ctx, rec)?,
            v: v_buffer(ctx, rec.len() as u64),
        })
    }

    fn inputs<'a>(&'a self, scene: &'a Scene, views: &'a Views) -> FrameInputs<'a> {
        FrameInputs {
            casters: &self.casters,
            views,
            light: scene.light(),
            receivers: &self.receivers.buffer,
            count: self.receivers.count,
            v: &self.v,
            timestamps: None,
        }
    }
}

fn v_buffer(ctx: &GpuContext, n: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("caller's V"),
        size: 4 * n.max(1),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// Two frames of `algo` on `ctx` (fresh estimator, views fitted to `rec`), V read back.
fn frame_v(algo: &str, ctx: &Arc<GpuContext>, scene: &Scene, rec: &Receivers) -> Vec<u32> {
    frame_v_at(algo, ctx, scene, rec, 128)
}

/// [`frame_v`] with the maps at `resolution`.
fn frame_v_at(
    algo: &str,
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    rec: &Receivers,
    resolution: u32,
) -> Vec<u32> {
    let f = frame(algo, ctx, &params(algo, resolution), rec.len() as u32).unwrap();
    let views = f.fit_views(scene, rec).unwrap();
    let caller = Caller::new(ctx, scene, rec).unwrap();
    for _ in 0..2 {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        f.encode(&mut enc, &caller.inputs(scene, &views))
            .unwrap_or_else(|e| panic!("{algo}: {e}"));
        ctx.queue.submit([enc.finish()]);
    }
    ctx.read_buffer(&caller.v, 4 * rec.len() as u64).unwrap()
}

/// Destroys `ctx`'s device and polls it once, which is when wgpu reports an explicit destroy
/// (a real loss is reported as it happens).
fn lose(ctx: &GpuContext) {
    ctx.device.destroy();
    let _ = ctx.device.poll(wgpu::PollType::Poll);
}

#[test]
fn device_loss_is_a_typed_error_and_a_new_device_works_in_every_frame_estimator() {
    let Some(shared) =
        gpu("device_loss_is_a_typed_error_and_a_new_device_works_in_every_frame_estimator")
    else {
        return;
    };
    let (scene, rec) = scene();
    for algo in FRAME_ALGOS {
        let ctx = Arc::new(GpuContext::new().unwrap());
        let f = frame(algo, &ctx, &params(algo, 128), rec.len() as u32).unwrap();
        let views = f.fit_views(&scene, &rec).unwrap();
        let caller = Caller::new(&ctx, &scene, &rec).unwrap();
        let inputs = caller.inputs(&scene, &views);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        f.encode(&mut enc, &inputs).unwrap();
        ctx.queue.submit([enc.finish()]);
        ctx.wait().unwrap();

        ctx.device.destroy();
        // Before wgpu reports the destroy (at the next poll), recording is harmless: no panic.
        no_panic(&format!("{algo}: encode right after destroy"), || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            let r = f.encode(&mut enc, &inputs);
            assert!(
                matches!(r, Ok(()) | Err(Error::DeviceLost(_))),
                "{algo}: {r:?}"
            );
            ctx.queue.submit([enc.finish()]);
        });
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        no_panic(algo, || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            assert_lost(&format!("{algo}: encode"), f.encode(&mut enc, &inputs));
            drop(enc);
            assert_lost(&format!("{algo}: fit_views"), f.fit_views(&scene, &rec));
            assert_lost(
                &format!("{algo}: prepare on the lost device"),
                frame(algo, &ctx, &params(algo, 128), rec.len() as u32).map(|_| ()),
            );
            assert_lost(
                &format!("{algo}: casters upload"),
                GpuScene::upload(&ctx, &scene).map(|_| ()),
            );
            assert_lost(
                &format!("{algo}: receivers upload"),
                GpuReceivers::upload(&ctx, &rec).map(|_| ()),
            );
            assert_lost(
                &format!("{algo}: V readback"),
                ctx.read_buffer::<u32>(&caller.v, 4),
            );
            if let Some(status) = f.status() {
                assert_lost(
                    &format!("{algo}: status readback"),
                    ctx.read_buffer::<u32>(status, status.size()),
                );
            }
            assert_lost(&format!("{algo}: wait"), ctx.wait());
        });

        // The caller recreates the device and prepares the estimator again on it.
        let new = Arc::new(GpuContext::new().unwrap());
        let after = frame_v(algo, &new, &scene, &rec);
        let never_lost = frame_v(algo, &shared, &scene, &rec);
        assert!(
            after == never_lost,
            "{algo}: V on the recreated device differs from a device that never saw a loss"
        );
        println!(
            "{algo}: DeviceLost after the loss; on a new device V bit for bit that of a device never lost"
        );
    }
}

#[test]
fn device_loss_is_a_typed_error_and_a_new_device_works_in_every_gpu_twin() {
    let Some(shared) = gpu("device_loss_is_a_typed_error_and_a_new_device_works_in_every_gpu_twin")
    else {
        return;
    };
    let (scene, rec) = scene();
    let res = [("resolution", "128")];
    for m in METHODS {
        if !m.has_gpu() {
            continue;
        }
        let ctx = Arc::new(GpuContext::new().unwrap());
        let mut e = twin(m, &ctx, &res);
        run(e.as_mut(), &scene, &rec).unwrap_or_else(|err| panic!("{}: {err}", m.name()));
        // Built on the device, then lost before the estimate.
        e.build(&scene, &rec)
            .unwrap_or_else(|err| panic!("{}: {err}", m.name()));
        lose(&ctx);
        no_panic(m.name(), || {
            let mut v = vec![0.0; rec.len()];
            assert_lost(
                &format!("{}: estimate", m.name()),
                e.estimate(&scene, &rec, &mut v),
            );
            assert_lost(
                &format!("{}: build", m.name()),
                run(e.as_mut(), &scene, &rec).map(|_| ()),
            );
            assert_lost(
                &format!("{}: a new twin on the lost device", m.name()),
                m.gpu(ctx.clone()).unwrap().and_then(|mut fresh| {
                    fresh.set_param("resolution", "128")?;
                    run(fresh.as_mut(), &scene, &rec).map(|_| ())
                }),
            );
        });
        let new = Arc::new(GpuContext::new().unwrap());
        let after = run(twin(m, &new, &res).as_mut(), &scene, &rec).unwrap().0;
        let never_lost = run(twin(m, &shared, &res).as_mut(), &scene, &rec)
            .unwrap()
            .0;
        let mut worst = 0.0f32;
        for (k, (a, b)) in after.iter().zip(&never_lost).enumerate() {
            assert_eq!(
                a.is_nan(),
                b.is_nan(),
                "{}: receiver {k}: {a} / {b}",
                m.name()
            );
            if a.is_finite() {
                worst = worst.max((a - b).abs());
            }
        }
        // Within 1e-5, as tests/workspace/threads.rs: the twins' atomics may order ties differently.
        assert!(worst <= 1e-5, "{}: {worst}", m.name());
        println!(
            "{}: twin DeviceLost after the loss; on a new device max |dV| {worst:.1e} against a device never lost",
            m.name()
        );
    }
}

/// A context on a device of the first Vulkan adapter with the adapter's limits lowered by
/// `lower` (so a test exceeds them without allocating anything large).
fn limited(lower: impl FnOnce(&mut wgpu::Limits)) -> Arc<GpuContext> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
    });
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .expect("an adapter (the shared context found one)");
    let mut limits = adapter.limits();
    lower(&mut limits);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("limited"),
        required_limits: limits,
        ..Default::default()
    }))
    .unwrap();
    Arc::new(GpuContext::from_device(device, queue))
}

/// The start of a limits test: on a device with the limits `lower` lowers ([`limited`]), the
/// small scene and its receivers; `None` after the GPU gate's loud skip.
fn limited_case(
    test: &str,
    lower: impl FnOnce(&mut wgpu::Limits),
) -> Option<(Arc<GpuContext>, Scene, Receivers)> {
    gpu(test)?;
    let (scene, rec) = scene();
    Some((limited(lower), scene, rec))
}

/// `r` is `Error::Limit` naming `limit` (and no panic got here).
fn assert_limit<T: std::fmt::Debug>(what: &str, limit: &str, r: Result<T>) {
    match r {
        Err(Error::Limit {
            what: w,
            requested,
            max,
        }) if w.contains(limit) && requested > max => {
            println!("{what}: {w}: requested {requested}, maximum {max}")
        }
        other => panic!("{what}: expected Error::Limit naming {limit}, got {other:?}"),
    }
}

#[test]
fn resolution_past_max_texture_dimension_2d_is_a_limit_error() {
    let Some((ctx, scene, rec)) = limited_case(
        "resolution_past_max_texture_dimension_2d_is_a_limit_error",
        |l| l.max_texture_dimension_2d = 256,
    ) else {
        return;
    };
    let r = ctx.limits().max_texture_dimension_2d + 1;
    for algo in FRAME_ALGOS {
        let what = format!("{algo}: frame prepare at resolution {r}");
        let p = params(algo, r);
        no_panic(&what, || {
            assert_limit(
                &what,
                "max_texture_dimension_2d",
                frame(algo, &ctx, &p, rec.len() as u32).map(|_| ()),
            )
        });
    }
    for m in METHODS {
        if !m.has_gpu() {
            continue;
        }
        let what = format!("{}: twin at resolution {r}", m.name());
        no_panic(&what, || {
            let mut e = twin(m, &ctx, &[("resolution", &r.to_string())]);
            let out = run(e.as_mut(), &scene, &rec).map(|_| ());
            assert_limit(&what, "max_texture_dimension_2d", out);
        });
    }
    assert!(ctx.check_lost().is_ok());
}

#[test]
fn receivers_past_max_storage_buffer_binding_size_are_a_limit_error() {
    const BINDING: u64 = 1 << 20;
    let Some((ctx, scene, rec)) = limited_case(
        "receivers_past_max_storage_buffer_binding_size_are_a_limit_error",
        |l| {
            l.max_storage_buffer_binding_size = BINDING;
            l.max_buffer_size = 8 * BINDING;
        },
    ) else {
        return;
    };
    let limit = "max_storage_buffer_binding_size";
    // Frames bind their receivers a range at a time (the next test): no count is refused for
    // the binding. Per-receiver buffers allocated at prepare, past the binding for 4 bytes a
    // receiver, are.
    for algo in FRAME_ALGOS {
        let p = params(algo, 64);
        if ["multi-sample", "deep-shadow", "packet-hsm"].contains(algo) {
            let m = (BINDING / 4 + 1) as u32;
            let what = format!("{algo}: frame prepare for {m} receivers");
            no_panic(&what, || {
                assert_limit(&what, limit, frame(algo, &ctx, &p, m).map(|_| ()))
            });
        }
    }
    // Packet-hsm's and deep-shadow's maps are storage buffers too, refused past the binding:
    // packet-hsm's MSSM of a 256 x 256 map (2.4 MB),
    // deep-shadow's head buffer of a 513 x 513 map (1.05 MB).
    for (algo, r) in [("packet-hsm", 256), ("deep-shadow", 513)] {
        let what = format!("{algo} twin at resolution {r}");
        no_panic(&what, || {
            let mut e = twin_of(algo, &ctx, &[("resolution", &r.to_string())]);
            assert_limit(&what, limit, run(e.as_mut(), &scene, &rec).map(|_| ()));
        });
    }
    // deep-shadow's list elements: on a device whose storage binding holds 128 of them, the
    // lists of a 32 x 32 map over the two squares made translucent need more. The frame's
    // element buffer stops at the binding; the fragments past it are not lost: the frame marks
    // its receivers cut, and the GPU estimator redoes them with the CPU twin, noting how many.
    let tiny = limited(|l| l.max_storage_buffer_binding_size = 4096);
    let translucent = Scene::from_meshes(
        "translucent squares",
        *scene.camera(),
        *scene.light(),
        vec![(scene.triangles().to_vec(), 0.5)],
    )
    .unwrap();
    // The fixture's 192 receivers take two ranges of the binding's 128.
    let what = "deep-shadow: list elements past the binding";
    no_panic(what, || {
        let mut e = twin_of("deep-shadow", &tiny, &[("resolution", "32")]);
        let (v, report) =
            run(e.as_mut(), &translucent, &rec).unwrap_or_else(|e| panic!("{what}: {e}"));
        let active = rec.active().iter().filter(|a| **a).count();
        let redone: usize = test_support::fixtures::note_as(&report, "frame_cpu_redo");
        assert_eq!(redone, active, "{what}: {report:?}");
        assert!(
            v.iter().zip(rec.active()).all(|(x, a)| !a || x.is_finite()),
            "{what}: an active receiver left non-finite"
        );
    });
    assert!(ctx.check_lost().is_ok());
}

/// A frame that binds its receivers a range at a time gives, on a device whose storage binding
/// holds 128 receivers (two ranges of the fixture's 192), the V bits it gives on the adapter's
/// own limits (one range). Packet-hsm binds 96-byte elements of its own a range at a time:
/// that device's binding holds no aligned range of them (a limit error at `prepare`), one
/// holding 128 of them takes the fixture in two ranges.
#[test]
fn frames_past_one_binding_of_receivers_run_in_ranges() {
    const BINDING: u64 = 128 * 32;
    let Some((small, scene, rec)) =
        limited_case("frames_past_one_binding_of_receivers_run_in_ranges", |l| {
            l.max_storage_buffer_binding_size = BINDING
        })
    else {
        return;
    };
    let full = test_support::gate::context_for_tests("ranges")
        .unwrap()
        .unwrap();
    assert!(rec.len() as u64 > BINDING / 32, "{} receivers", rec.len());
    let wider = limited(|l| l.max_storage_buffer_binding_size = 128 * 96);
    let mut ran = 0;
    for algo in FRAME_ALGOS {
        let what = format!("{algo}: {} receivers, {BINDING}-byte bindings", rec.len());
        let mut small = &small;
        if *algo == "packet-hsm" {
            no_panic(&what, || {
                let f = frame(algo, small, &params(algo, 16), rec.len() as u32);
                assert_limit(&what, "max_storage_buffer_binding_size", f.map(|_| ()));
            });
            small = &wider;
        }
        let ranged = frame_v_at(algo, small, &scene, &rec, 16);
        let whole = frame_v_at(algo, &full, &scene, &rec, 16);
        let differ = ranged.iter().zip(&whole).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{what}: V bits differ from one range's");
        ran += 1;
    }
    assert_eq!(ran, FRAME_ALGOS.len());
    println!("{ran} frames: V identical in 2 ranges and in 1");
}

#[test]
fn layers_past_max_texture_array_layers_are_a_limit_error() {
    let Some((ctx, scene, rec)) = limited_case(
        "layers_past_max_texture_array_layers_are_a_limit_error",
        |l| l.max_texture_array_layers = 2,
    ) else {
        return;
    };
    let limit = "max_texture_array_layers";
    for (algo, extra) in [
        ("backprojection", &[("layers", "3")][..]),
        ("accumulation", &[("variant", "exact"), ("layers", "3")][..]),
    ] {
        let mut p = params(algo, 64);
        for (k, v) in extra {
            p.set(k, v).unwrap();
        }
        let what = format!("{algo}: frame with 3 layers");
        no_panic(&what, || {
            assert_limit(&what, limit, frame(algo, &ctx, &p, 16).map(|_| ()))
        });
        let what = format!("{algo}: twin with 3 layers");
        no_panic(&what, || {
            let kv = [&[("resolution", "64")][..], extra].concat();
            let mut e = twin_of(algo, &ctx, &kv);
            assert_limit(&what, limit, run(e.as_mut(), &scene, &rec).map(|_| ()));
        });
    }
    assert!(ctx.check_lost().is_ok());
}
