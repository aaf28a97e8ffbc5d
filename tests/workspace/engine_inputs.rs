//! The engine path from a renderer's own inputs: every frame estimator
//! ([`softshadow::FRAME_ALGOS`]) fed, inside one command encoder, casters that
//! [`GpuCasterBuilder`] builds from an indexed mesh and receivers that [`GpuDepthReceivers`]
//! makes from a depth and a normal texture (reverse Z, unorm normals: a Bevy-style prepass), on
//! the bunny at 64x48. Checked per estimator, V read back once:
//! - V is bit for bit the V of the same frame fed `GpuScene::upload`'s casters (the builder's
//!   triangles are the upload's bits) and the same receiver buffer;
//! - the CPU twin on the receivers read back (in the same views) agrees within RMSE 2e-3,
//!   with NaN (loop-budget cuts) counted apart;
//! - the receivers are the ray-traced camera receivers within 1e-5 of their distance;
//! - the same with the views fitted to two boxes alone ([`bounds_stand_in`]: the casters' and
//!   the receivers' world bounds, no CPU work that grows with triangles or receivers).
#![cfg(feature = "gpu")]

use glam::Mat4;
use shadow_map_core::gpu::{
    casters::{CasterIndices, CasterInstance, CasterMesh, GpuCasterBuilder},
    depth_receivers::{
        depth_texture, normal_texture, DepthCamera, DepthConvention, GpuDepthReceivers,
        NormalEncoding,
    },
    frame::FrameInputs,
    shared::ReceiverGpu,
    GpuContext, GpuScene,
};
use shadow_map_core::light_view::{bounds_stand_in, receiver_bounds};
use softshadow::{frame_estimator, own_params, FRAME_ALGOS};
use test_support::frame_run::FrameRig;
use wgpu::util::DeviceExt;

fn storage(ctx: &GpuContext, usage: wgpu::BufferUsages, bytes: &[u8]) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("renderer's buffer"),
            contents: bytes,
            usage: usage | wgpu::BufferUsages::STORAGE,
        })
}

#[test]
fn frames_take_a_renderers_meshes_and_prepass() {
    let Some(ctx) =
        test_support::gate::context_for_tests("frames_take_a_renderers_meshes_and_prepass")
            .unwrap()
    else {
        return;
    };
    let (scene, rec) = test_support::fixtures::fixture("bunny", 64, 48);
    let (w, h) = (scene.camera().width, scene.camera().height);
    let n = rec.len();

    // The renderer's mesh: the scene's triangles as shared vertices (deduplicated) and u32
    // indices, one instance at identity.
    let mut verts: Vec<[f32; 4]> = Vec::new();
    let mut index: std::collections::HashMap<[u32; 3], u32> = Default::default();
    let mut indices: Vec<u32> = Vec::new();
    for t in scene.triangles() {
        for p in t {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            let k = *index.entry(key).or_insert_with(|| {
                verts.push([p.x, p.y, p.z, 0.0]);
                verts.len() as u32 - 1
            });
            indices.push(k);
        }
    }
    let vb = storage(
        &ctx,
        wgpu::BufferUsages::VERTEX,
        bytemuck::cast_slice(&verts),
    );
    let ib = storage(
        &ctx,
        wgpu::BufferUsages::INDEX,
        bytemuck::cast_slice(&indices),
    );
    let mesh = [CasterMesh {
        vertices: &vb,
        vertex_stride: 16,
        position_offset: 0,
        indices: CasterIndices::U32(&ib),
        first_index: 0,
        index_count: indices.len() as u32,
        base_vertex: 0,
        opacity: 1.0,
    }];
    let instance = [CasterInstance {
        mesh: 0,
        transform: Mat4::IDENTITY,
    }];
    let builder = GpuCasterBuilder::new(&ctx, 1, 1).unwrap();
    let mut casters = GpuScene::with_capacity(&ctx, scene.triangles().len() as u32).unwrap();
    let uploaded = GpuScene::upload(&ctx, &scene).unwrap();

    // The renderer's prepass: reverse-Z depth, unorm normals.
    let cam = DepthCamera::perspective(
        scene.camera(),
        0.05,
        f32::INFINITY,
        DepthConvention::ReverseZ,
        NormalEncoding::Unorm,
    )
    .unwrap();
    let (mut depth, mut normals) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let (d, nn) = if rec.active()[k] {
            let c = cam.view_proj * rec.position()[k].extend(1.0);
            (c.z / c.w, rec.normal()[k])
        } else {
            (0.0, glam::Vec3::Z)
        };
        depth.push(d);
        normals.push(nn);
    }
    let dt = depth_texture(&ctx, w, h, &depth).unwrap();
    let nt = normal_texture(&ctx, w, h, &normals, NormalEncoding::Unorm).unwrap();
    let rbuf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("receivers"),
        size: 32 * n as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let make_v = || v_buffer(&ctx, n);
    let prepass = GpuDepthReceivers::new(&ctx).unwrap();

    // The receivers the prepass gives, read back once for the CPU twin.
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    prepass
        .encode(&ctx, &mut enc, &cam, &dt, &nt, &rbuf)
        .unwrap();
    builder
        .encode(&ctx, &mut enc, &mesh, &instance, &mut casters)
        .unwrap();
    ctx.queue.submit([enc.finish()]);
    let got: Vec<ReceiverGpu> = ctx.read_buffer(&rbuf, rbuf.size()).unwrap();
    let (mut pos, mut nrm) = (rec.position().to_vec(), rec.normal().to_vec());
    for (k, g) in got.iter().enumerate() {
        assert_eq!(g.active == 1, rec.active()[k], "receiver {k} active");
        if rec.active()[k] {
            let d = (glam::Vec3::from(g.position) - rec.position()[k]).length()
                / (rec.position()[k] - scene.camera().eye).length();
            assert!(d <= 1e-5, "receiver {k}: {d} of its distance");
            pos[k] = g.position.into();
            nrm[k] = g.normal.into();
        }
    }
    let from_depth = shadow_map_core::Receivers::from_gbuffer(
        pos,
        nrm,
        rec.active().to_vec(),
        rec.view_depth().map(<[f32]>::to_vec),
        rec.layout(),
    )
    .unwrap();

    let mut failures = Vec::new();
    for &algo in FRAME_ALGOS {
        let frame = default_frame(&ctx, algo, n);
        let views = frame.fit_views(&scene, &from_depth).unwrap();
        let run = |c: &GpuScene, v: &wgpu::Buffer, views: &[Option<shadow_map_core::LightView>]| {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            // The renderer's frame: prepass receivers, casters, then the estimator.
            prepass
                .encode(&ctx, &mut enc, &cam, &dt, &nt, &rbuf)
                .unwrap();
            frame
                .encode(
                    &mut enc,
                    &FrameInputs {
                        casters: c,
                        views,
                        light: scene.light(),
                        receivers: &rbuf,
                        count: n as u32,
                        v,
                        timestamps: None,
                    },
                )
                .unwrap();
            ctx.queue.submit([enc.finish()]);
            ctx.read_buffer::<u32>(v, 4 * n as u64).unwrap()
        };
        let (v1, v2) = (make_v(), make_v());
        let built = run(&casters, &v1, &views);
        let up = run(&uploaded, &v2, &views);
        if built != up {
            failures.push(format!(
                "{algo}: built casters give another V than the upload"
            ));
        }
        // Views fitted to the casters' and the receivers' boxes alone.
        let (stand_scene, stand_rec) = bounds_stand_in(
            scene.light(),
            scene.camera(),
            &scene.bounds(),
            &receiver_bounds(&rec),
        )
        .unwrap();
        let boxed = frame.fit_views(&stand_scene, &stand_rec).unwrap();
        let from_boxes = run(&casters, &v1, &boxed);
        for (what, v, views) in [
            ("views from receivers", &built, &views),
            ("views from boxes", &from_boxes, &boxed),
        ] {
            let twin = frame.cpu_twin(&scene, &from_depth, views).unwrap();
            let (mut sq, mut m, mut cut) = (0.0f64, 0usize, 0usize);
            for k in 0..n {
                let g = f32::from_bits(v[k]);
                if !from_depth.active()[k] {
                    continue;
                }
                if g.is_nan() {
                    cut += 1;
                    continue;
                }
                sq += ((g - twin[k]) as f64).powi(2);
                m += 1;
            }
            let rmse = (sq / m.max(1) as f64).sqrt();
            println!("{algo}, {what}: frame from a renderer's mesh and prepass vs CPU twin RMSE {rmse:.2e} ({cut} cut of {})", m + cut);
            if rmse.is_nan() || rmse > 2e-3 || m < n / 4 {
                failures.push(format!("{algo}, {what}: RMSE {rmse} over {m} receivers"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A V buffer of `n` receivers.
fn v_buffer(ctx: &GpuContext, n: usize) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("V"),
        size: 4 * n as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// `algo`'s frame at its CPU twin's defaults, prepared for `n` receivers.
fn default_frame(
    ctx: &std::sync::Arc<GpuContext>,
    algo: &str,
    n: usize,
) -> Box<dyn shadow_map_core::gpu::frame::FrameEstimator> {
    let cpu = softshadow::estimator(algo, softshadow::Backend::Cpu).unwrap();
    let params = own_params(algo, cpu.params()).unwrap();
    frame_estimator(algo, ctx.clone(), &params, n as u32)
        .unwrap()
        .expect("every FRAME_ALGOS estimator has a frame")
}

/// One estimator records two frames into one encoder, each its own scene (casters, receivers,
/// light and views) and V buffer, as a renderer drawing two lights or two cameras does: one
/// submit gives each frame the V bits it gives submitted alone. The frames write their uniforms
/// in the encoder's order (`GpuContext::write_in`), so the second's do not overwrite the
/// first's.
#[test]
fn one_estimator_records_two_scenes_into_one_submit() {
    let Some(ctx) =
        test_support::gate::context_for_tests("one_estimator_records_two_scenes_into_one_submit")
            .unwrap()
    else {
        return;
    };
    let scenes = [
        test_support::fixtures::fixture("bunny", 48, 36),
        test_support::fixtures::fixture("stacked", 48, 36),
    ];
    let n = scenes[0].1.len();
    let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<u32>>();
    let mut failures = Vec::new();
    for &algo in FRAME_ALGOS {
        let frame = default_frame(&ctx, algo, n);
        let rigs: Vec<FrameRig> = scenes
            .iter()
            .map(|(scene, rec)| FrameRig::new(&ctx, &*frame, scene, rec).unwrap())
            .collect();
        let alone: Vec<Vec<u32>> = rigs
            .iter()
            .map(|rig| bits(rig.run(&ctx, &*frame).unwrap().v))
            .collect();
        // Both frames in one encoder, V into fresh buffers.
        let together: Vec<wgpu::Buffer> = rigs.iter().map(|_| v_buffer(&ctx, n)).collect();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for (k, (rig, v)) in rigs.iter().zip(&together).enumerate() {
            frame
                .encode(&mut enc, &FrameInputs { v, ..rig.inputs() })
                .unwrap_or_else(|e| panic!("{algo}, scene {k}: {e}"));
        }
        ctx.queue.submit([enc.finish()]);
        for (k, v) in together.iter().enumerate() {
            let got = ctx.read_buffer::<u32>(v, 4 * n as u64).unwrap();
            let differ = got.iter().zip(&alone[k]).filter(|(a, b)| a != b).count();
            println!("{algo}, scene {k} of 2 in one submit: {differ} of {n} V differ from alone");
            if differ > 0 {
                failures.push(format!("{algo}, scene {k}: {differ} of {n} V differ"));
            }
        }
        if alone[0] == alone[1] {
            failures.push(format!("{algo}: the two scenes give the same V"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A frame recorded again from the same buffers makes no bind group (each estimator keeps its
/// groups while what they bind stays the same); given another V buffer it makes new ones. On a
/// device of its own, so other tests' groups do not count.
#[test]
fn a_frame_recorded_again_from_the_same_buffers_makes_no_bind_group() {
    let name = "a_frame_recorded_again_from_the_same_buffers_makes_no_bind_group";
    if test_support::gate::context_for_tests(name)
        .unwrap()
        .is_none()
    {
        return;
    }
    let ctx = std::sync::Arc::new(GpuContext::new().unwrap());
    let (scene, rec) = test_support::fixtures::fixture("bunny", 48, 36);
    let n = rec.len();
    let mut failures = Vec::new();
    for &algo in FRAME_ALGOS {
        let frame = default_frame(&ctx, algo, n);
        let rig = FrameRig::new(&ctx, &*frame, &scene, &rec).unwrap();
        // Bind groups made by one encode into `v`, submitted.
        let made = |v: &wgpu::Buffer| {
            let before = ctx.bind_groups();
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            frame
                .encode(&mut enc, &FrameInputs { v, ..rig.inputs() })
                .unwrap_or_else(|e| panic!("{algo}: {e}"));
            ctx.queue.submit([enc.finish()]);
            ctx.bind_groups() - before
        };
        let (v1, v2) = (&rig.v, &v_buffer(&ctx, n));
        let counts = [made(v1), made(v1), made(v1), made(v2)];
        println!("{algo}: bind groups made by 4 encodes (V, V, V, another V): {counts:?}");
        if counts[0] == 0 || counts[1] != 0 || counts[2] != 0 || counts[3] == 0 {
            failures.push(format!("{algo}: {counts:?}"));
        }
        let (a, b) = (
            ctx.read_buffer::<u32>(v1, 4 * n as u64).unwrap(),
            ctx.read_buffer::<u32>(v2, 4 * n as u64).unwrap(),
        );
        if a != b {
            failures.push(format!("{algo}: V differs between the two buffers"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
